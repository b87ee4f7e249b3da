//! The tiles plug-in's front: the tiles kept while the window is away
//! ([`TileStreaming`], which owns the resident tiles and their passes), in
//! memory by default or in an attached store, and the save of the whole
//! snow into that store. Its frame steps (the move, the weather) are in
//! [`super::steps`].

use crate::deform::snow_word::SNOW_QUANTUM_M;
use crate::error::SnowError;
use crate::gpu::GpuContext;
use crate::persist::{StoreError, TileStreamer};
use crate::tiles::TileStreaming;

use super::SnowDeformation;
use super::clock::RefillBase;
use super::saved::{STATE_NAME, SavedWindow};
use crate::persist::streamer::TileStreamerExt;
use crate::snow::inspect::SnowInspect;

impl SnowDeformation {
    /// Attaches a tile store: from now on texels leaving the window are kept
    /// through `streamer` (in memory, then on disk; or in memory alone for
    /// `TileStreamer::in_memory`) and come back when the window returns,
    /// brought up to the time then. It replaces the memory keeper the window
    /// was created with ([`crate::SnowParams::tile_memory_bytes`]). Call before the
    /// first frame, once. When the store holds a save ([`Self::save`]), the
    /// window's clock, snowfall and position are loaded from it and `true`
    /// returned.
    pub fn attach_store(&mut self, ctx: &GpuContext, streamer: TileStreamer) -> Result<bool, crate::SnowError> {
        ctx.guarded(|| self.attach_store_unguarded(ctx, streamer))
    }

    fn attach_store_unguarded(&mut self, ctx: &GpuContext, mut streamer: TileStreamer) -> Result<bool, crate::SnowError> {
        if self.frame > 0 || self.store_attached {
            return Err(SnowError::InvalidParameter { field: "store", why: "a tile store is attached before the first frame, once".into() }.into());
        }
        let side = streamer.side();
        let saved = match streamer.read_state(STATE_NAME)? {
            Some(bytes) => Some(SavedWindow::decode(&bytes, &streamer.dir().join(STATE_NAME))?),
            None => None,
        };
        // Tiles given up from now on belong to the next save: a crash leaves the last one whole.
        streamer.begin_saves();
        let (low, high, _) = self.stamp_range();
        if let Some(s) = &saved {
            let path = streamer.dir().join(STATE_NAME);
            let mismatch = |why: String| SnowError::Store(StoreError::Mismatch { path: path.clone(), why });
            if s.resolution != self.core.params.resolution || s.tile_side != side {
                return Err(mismatch(format!(
                    "saved with resolution {} and tiles of {}, the window has {} and {side}",
                    s.resolution, s.tile_side, self.core.params.resolution
                ))
                .into());
            }
            if s.texel_m != self.core.params.texel_m() || s.depth_m != self.core.params.depth_m || s.stamp_range_m != [low, high] {
                return Err(mismatch(format!(
                    "saved with texel {} m, depth {} m, footprint range {:?}; the window has {} m, {} m, {:?} (extent_m, depth_m, terrain or snowfall max_m changed)",
                    s.texel_m,
                    s.depth_m,
                    s.stamp_range_m,
                    self.core.params.texel_m(),
                    self.core.params.depth_m,
                    [low, high]
                )).into());
            }
        }
        // The memory keeper's resident tiles go first: two rings need not coexist.
        self.tiles = None;
        self.tiles = Some(TileStreaming::new(ctx, &self.core.res, streamer, (self.core.params.depth_m, self.core.params.keeps_lying_snow()))?);
        self.store_attached = true;
        if let Some(s) = saved {
            self.time.clock = s.clock;
            self.time.fallen_m = s.fallen_m;
            // The refill counters go on from the saved clock.
            self.time.snow_quanta = (s.clock.refill_m / f64::from(SNOW_QUANTUM_M)).floor() as u64;
            self.time.refill_base = RefillBase { time_s: s.clock.time_s, snow_quanta: self.time.snow_quanta, stamp_quanta: s.clock.stamp_quanta };
            self.core.center = s.center;
            self.frame = s.frame;
            return Ok(true);
        }
        Ok(false)
    }

    /// Saves the whole snow state into the attached store: every tile (the
    /// window's texels included) and the window's clock and position; when
    /// it returns `Ok`, the store directory is a complete save that
    /// [`Self::attach_store`] loads. Blocking (a save point, not a frame).
    /// Saving needs a disk store: with tiles kept in memory only (the
    /// default) or not at all it is an error naming `store`.
    pub fn save(&mut self, ctx: &GpuContext) -> Result<(), crate::SnowError> {
        ctx.guarded(|| self.save_unguarded(ctx))
    }

    fn save_unguarded(&mut self, ctx: &GpuContext) -> Result<(), crate::SnowError> {
        let (low, high, _) = self.stamp_range();
        let origin = self.core.window.origin();
        let Some(tiles) = self.tiles.as_mut().filter(|t| !t.is_memory_only()) else {
            return Err(SnowError::InvalidParameter {
                field: "store",
                why: "saving needs a disk store (attach_store with a TileStreamer over a TileStore); tiles are kept in memory only or not at all".into(),
            }
            .into());
        };
        if let Some(origin) = origin {
            tiles.checkpoint(ctx, &self.core.res, origin, self.time.clock)?;
        }
        let state = SavedWindow {
            resolution: self.core.params.resolution,
            tile_side: tiles.grid().side(),
            texel_m: self.core.params.texel_m(),
            depth_m: self.core.params.depth_m,
            stamp_range_m: [low, high],
            origin: origin.unwrap_or_default(),
            center: self.core.center,
            clock: self.time.clock,
            fallen_m: self.time.fallen_m,
            stamp_carry_m: 0.0,
            frame: self.frame,
        };
        let streamer = tiles.streamer();
        streamer.flush()?;
        // The state goes last, in the save's one atomic commit: a save is
        // complete, every tile with it, once it is there.
        streamer.commit_save(STATE_NAME, state.encode())?;
        Ok(())
    }

    /// Store errors since the last call (disk full, read-only, corrupt tiles
    /// replaced by fresh snow): the frame goes on; the game decides what to tell.
    pub fn take_store_errors(&mut self) -> Vec<crate::StoreError> {
        self.tiles.as_mut().map(TileStreaming::take_errors).unwrap_or_default().into_iter().map(Into::into).collect()
    }
}
