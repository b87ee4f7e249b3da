//! [`SharedWindow`]: [`SnowDeformation`]'s calls for shared snow, a
//! game's client side (feature `share`), over the shared-snow plug-in's
//! front ([`super::share`]).

use crate::accumulate::SnowAccumulation;
use crate::gpu::GpuContext;
use crate::replicate::WorldIdentity;
use crate::replicate::sharing::Sharing;

use super::deformation::SnowDeformation;
use super::share::{enable, world_identity, world_identity_for};

/// Shared snow, a game's client side (feature `share`): the window as a
/// replica of a world other machines press too, through a
/// [`crate::replicate::SnowPeer`] (`docs/multiplayer.md`). Imported with the
/// trait (`use snowpack::SharedWindow;`).
pub trait SharedWindow {
    /// Shares this window's snow in tiles of `tile_side` texels (8..=256) on
    /// the global grid: from the next frame the stamp and update passes flag
    /// the tiles presses change, changed tiles are gathered at most every
    /// `interval_s` of world time (0.25 s is a good default) for a
    /// `SnowPeer` to send, and the tiles it receives are folded in. Calling
    /// it again changes the side and the interval and forgets pending tiles.
    fn enable_sharing(&mut self, ctx: &GpuContext, tile_side: u32, interval_s: f64) -> Result<(), crate::SnowError>;

    /// Lets the next frame gather the changed tiles whatever the interval,
    /// so a program about to stop sends its last changes without letting
    /// world time pass.
    fn flush_changed_tiles(&mut self);

    /// Changed tiles flagged and not gathered yet (0 without sharing).
    #[must_use]
    fn dirty_tiles(&self) -> usize;

    /// Tiles given to the shared snow (`SnowPeer::update`) and not merged yet (ahead
    /// of the clock, or beyond a frame's upload).
    #[must_use]
    fn waiting_tiles(&self) -> usize;

    /// The settings another machine must share for its snow to merge with
    /// this window's; the tile side is the sharing one
    /// ([`Self::enable_sharing`]), or the default tile side before.
    #[must_use]
    fn world_identity(&self) -> WorldIdentity;

    /// The world identity a window of `params` over `terrain` has once it
    /// shares tiles of `tile_side`², found without a GPU: what a dedicated
    /// server (`snowpack server --scene`) serves and checks its peers
    /// against. Equal, field for field, to [`Self::world_identity`] of such
    /// a window after [`Self::enable_sharing`] with that side.
    #[must_use]
    fn world_identity_for(params: &crate::SnowParams, terrain: &crate::TerrainSource, tile_side: u32) -> WorldIdentity
    where
        Self: Sized;
}

impl SharedWindow for SnowDeformation {
    fn enable_sharing(&mut self, ctx: &GpuContext, tile_side: u32, interval_s: f64) -> Result<(), crate::SnowError> {
        let sky = self.accumulation.as_ref().map(SnowAccumulation::sky_view);
        ctx.guarded(|| enable(ctx, &mut self.core, sky, &mut self.sharing, (tile_side, interval_s)))
    }

    fn flush_changed_tiles(&mut self) {
        if let Some(sharing) = &mut self.sharing {
            sharing.gather_now();
        }
    }

    fn dirty_tiles(&self) -> usize {
        self.sharing.as_ref().map_or(0, Sharing::dirty_tiles)
    }

    fn waiting_tiles(&self) -> usize {
        self.sharing.as_ref().map_or(0, Sharing::waiting_tiles)
    }

    fn world_identity(&self) -> WorldIdentity {
        world_identity(&self.core, self.sharing.as_ref())
    }

    fn world_identity_for(params: &crate::SnowParams, terrain: &crate::TerrainSource, tile_side: u32) -> WorldIdentity {
        world_identity_for(params, terrain, tile_side)
    }
}
