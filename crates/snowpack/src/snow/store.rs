//! The tiles plug-in's front: the tiles kept while the window is away
//! ([`TileStreaming`], which owns the resident tiles and their passes), in
//! memory by default or in an attached store, the store's attaching (with
//! the save it holds) and the save of the whole snow into it, for
//! `StoredWindow` (`stored_window.rs`: `SnowDeformation`'s calls, feature
//! `store`). Its frame steps (the move, the weather) are in [`super::steps`].

use crate::error::SnowError;
use crate::gpu::GpuContext;
use crate::persist::{StoreError, TileStreamer};
use crate::tiles::TileStreaming;

use super::clock::SnowTime;
use super::core_window::CoreWindow;
use super::saved::{STATE_NAME, SavedWindow};
use crate::persist::streamer::TileStreamerExt;

/// Attaches `streamer` to `core`'s window in place of `tiles` (the memory
/// keeper it was created with, or none): from now on texels leaving the
/// window are kept through it. Returns the save the store holds, when it
/// holds one, checked against the window (a save of another resolution,
/// tile side, texel, depth or footprint range is an error naming the state
/// file, and `tiles` stays as it was).
pub(super) fn attach(
    ctx: &GpuContext,
    core: &CoreWindow,
    tiles: &mut Option<TileStreaming>,
    mut streamer: TileStreamer,
) -> Result<Option<SavedWindow>, crate::SnowError> {
    let side = streamer.side();
    let saved = match streamer.read_state(STATE_NAME)? {
        Some(bytes) => Some(SavedWindow::decode(&bytes, &streamer.dir().join(STATE_NAME))?),
        None => None,
    };
    // Tiles given up from now on belong to the next save: a crash leaves the last one whole.
    streamer.begin_saves();
    if let Some(s) = &saved {
        check_saved(core, s, side, &streamer.dir().join(STATE_NAME))?;
    }
    let p = core.params();
    // The memory keeper's resident tiles go first: two rings need not coexist.
    *tiles = None;
    *tiles = Some(TileStreaming::new(ctx, core.res(), streamer, (p.depth_m, p.keeps_lying_snow()))?);
    Ok(saved)
}

/// Whether save `s` (tiles of `side`, read from `path`) fits `core`'s window.
fn check_saved(core: &CoreWindow, s: &SavedWindow, side: u32, path: &std::path::Path) -> Result<(), SnowError> {
    let (low, high, _) = core.stamp_range();
    let p = core.params();
    let mismatch = |why: String| SnowError::Store(StoreError::Mismatch { path: path.to_path_buf(), why });
    if s.resolution != p.resolution || s.tile_side != side {
        return Err(mismatch(format!("saved with resolution {} and tiles of {}, the window has {} and {side}", s.resolution, s.tile_side, p.resolution)));
    }
    if s.texel_m != p.texel_m() || s.depth_m != p.depth_m || s.stamp_range_m != [low, high] {
        return Err(mismatch(format!(
            "saved with texel {} m, depth {} m, footprint range {:?}; the window has {} m, {} m, {:?} (extent_m, depth_m, terrain or snowfall max_m changed)",
            s.texel_m,
            s.depth_m,
            s.stamp_range_m,
            p.texel_m(),
            p.depth_m,
            [low, high]
        )));
    }
    Ok(())
}

/// Saves the whole snow into the disk store of `tiles`: every tile (`core`'s
/// window's texels included), then the window's state (its position,
/// `time` and `frame`, the frames recorded) in the save's one atomic
/// commit. Blocking. Without a disk store it is an error naming `store`.
pub(super) fn save(ctx: &GpuContext, core: &CoreWindow, tiles: Option<&mut TileStreaming>, (time, frame): (&SnowTime, u64)) -> Result<(), crate::SnowError> {
    let (low, high, _) = core.stamp_range();
    let origin = core.window_origin();
    let Some(tiles) = tiles.filter(|t| !t.is_memory_only()) else {
        return Err(SnowError::InvalidParameter {
            field: "store",
            why: "saving needs a disk store (attach_store with a TileStreamer over a TileStore); tiles are kept in memory only or not at all".into(),
        }
        .into());
    };
    if let Some(origin) = origin {
        tiles.checkpoint(ctx, core.res(), origin, time.clock)?;
    }
    let p = core.params();
    let state = SavedWindow {
        resolution: p.resolution,
        tile_side: tiles.grid().side(),
        texel_m: p.texel_m(),
        depth_m: p.depth_m,
        stamp_range_m: [low, high],
        origin: origin.unwrap_or_default(),
        center: core.center(),
        clock: time.clock,
        fallen_m: time.fallen_m,
        stamp_carry_m: 0.0,
        frame,
    };
    let streamer = tiles.streamer();
    streamer.flush()?;
    // The state goes last, in the save's one atomic commit: a save is
    // complete, every tile with it, once it is there.
    streamer.commit_save(STATE_NAME, state.encode())?;
    Ok(())
}
