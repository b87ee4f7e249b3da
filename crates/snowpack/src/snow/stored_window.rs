//! [`StoredWindow`]: [`SnowDeformation`]'s calls for trails kept on disk
//! and saves (feature `store`), over the tiles plug-in's front
//! ([`super::store`]).

use crate::error::SnowError;
use crate::gpu::GpuContext;
use crate::persist::TileStreamer;
use crate::tiles::TileStreaming;

use super::deformation::SnowDeformation;
use super::store::{attach, save};

/// Trails kept in a tile store on disk, and saves of the whole snow
/// (feature `store`): [`SnowDeformation`]'s calls for a game that keeps its
/// snow between sessions, imported with the trait
/// (`use snowpack::StoredWindow;`). Without a store attached, trails are
/// kept in memory while the window is away ([`crate::SnowParams::tile_memory_bytes`]).
pub trait StoredWindow {
    /// Attaches a tile store: from now on texels leaving the window are kept
    /// through `streamer` (in memory, then on disk; or in memory alone for
    /// `TileStreamer::in_memory`) and come back when the window returns,
    /// brought up to the time then. It replaces the memory keeper the window
    /// was created with ([`crate::SnowParams::tile_memory_bytes`]). Call before the
    /// first frame, once. When the store holds a save ([`Self::save`]), the
    /// window's clock, snowfall and position are loaded from it and `true`
    /// returned.
    fn attach_store(&mut self, ctx: &GpuContext, streamer: TileStreamer) -> Result<bool, crate::SnowError>;

    /// The blocking step of a loading screen: loads from the attached store
    /// every tile the window needs at its centre (`SnowDeformation::set_center`),
    /// after [`Self::attach_store`] or a teleport, so that the first frame
    /// there shows the stored snow. Frames never wait for the disk: without
    /// it, fresh snow stands in for the tiles the disk has not given yet
    /// (the save not shown in the first frame after attaching, the trails
    /// missing a few frames after a jump), and each stored tile is merged
    /// in live as it arrives, nearest the centre first, with what the window
    /// pressed there meanwhile (`TileStats::merged_live`).
    ///
    /// A disk that fails or does not answer within
    /// `StreamerConfig::wait_limit` is not an error here: as in a
    /// frame, fresh snow stands in for those tiles, their stored versions
    /// are merged in later, and [`Self::take_store_errors`] reports it.
    /// Without a store it returns at once.
    fn preload(&mut self, ctx: &GpuContext) -> Result<(), crate::SnowError>;

    /// Saves the whole snow state into the attached store: every tile (the
    /// window's texels included) and the window's clock and position; when
    /// it returns `Ok`, the store directory is a complete save that
    /// [`Self::attach_store`] loads. Blocking (a save point, not a frame).
    /// Saving needs a disk store: with tiles kept in memory only (the
    /// default) or not at all it is an error naming `store`.
    fn save(&mut self, ctx: &GpuContext) -> Result<(), crate::SnowError>;

    /// Store errors since the last call (disk full, read-only, corrupt tiles
    /// replaced by fresh snow): the frame goes on; the game decides what to tell.
    fn take_store_errors(&mut self) -> Vec<crate::error::front::StoreError>;
}

impl StoredWindow for SnowDeformation {
    fn attach_store(&mut self, ctx: &GpuContext, streamer: TileStreamer) -> Result<bool, crate::SnowError> {
        ctx.guarded(|| {
            if self.frame > 0 || self.store_attached {
                return Err(SnowError::InvalidParameter { field: "store", why: "a tile store is attached before the first frame, once".into() }.into());
            }
            let saved = attach(ctx, &self.core, &mut self.tiles, streamer)?;
            self.store_attached = true;
            let Some(s) = saved else { return Ok(false) };
            self.time.resume(s.clock, s.fallen_m);
            self.core.set_center(s.center);
            self.frame = s.frame;
            Ok(true)
        })
    }

    fn preload(&mut self, ctx: &GpuContext) -> Result<(), crate::SnowError> {
        let Some(tiles) = &mut self.tiles else { return Ok(()) };
        let (current, desired) = (self.core.window_origin(), self.core.desired_origin());
        ctx.guarded(|| {
            tiles.preload(ctx, current, desired);
            Ok(())
        })
    }

    fn save(&mut self, ctx: &GpuContext) -> Result<(), crate::SnowError> {
        ctx.guarded(|| save(ctx, &self.core, self.tiles.as_mut(), (&self.time, self.frame)))
    }

    fn take_store_errors(&mut self) -> Vec<crate::error::front::StoreError> {
        self.tiles.as_mut().map(TileStreaming::take_errors).unwrap_or_default().into_iter().map(Into::into).collect()
    }
}
