//! [`SnowDeformation`] as a replica of a shared world: its world clock, its
//! identity, and [`SharedSnow`] over the GPU's changed-tile flags, gather
//! and merge passes (`replicate::sharing`).

use crate::deform::params::default_tile_texels;
use crate::deform::stamp::StampPass;
use crate::deform::update::UpdatePass;
use crate::error::SnowError;
use crate::gpu::GpuContext;
use crate::replicate::flags::ShareGrid;
use crate::replicate::sharing::{ShareWindow, Sharing};
use crate::replicate::world::{WorldSettings, WorldSnow, WorldSnowfall, WorldTerrain};
use crate::replicate::{CatchUp, ShareClock, SharedSnow, SharedTile, WorldIdentity, terrain_identity};
use snowpack_share::replicate::WorldIdentityExt;

use super::SnowDeformation;
use super::clock::{RefillBase, SnowTime};
use super::core_window::CoreWindow;
use crate::gpu::context::GpuContextExt;
use crate::snow::inspect::SnowInspect;

/// Tile sides [`SnowDeformation::enable_sharing`] accepts (texels).
pub const SHARE_TILE_SIDES: std::ops::RangeInclusive<u32> = 8..=256;

impl SnowDeformation {
    /// Shares this window's snow in tiles of `tile_side` texels (8..=256) on
    /// the global grid: from the next frame the stamp and update passes flag
    /// the tiles presses change, changed tiles are gathered at most every
    /// `interval_s` of world time (0.25 s is a good default) for a
    /// [`crate::SnowPeer`] to send, and the tiles it receives are folded in. Calling it again changes the side and
    /// the interval and forgets pending tiles.
    pub fn enable_sharing(&mut self, ctx: &GpuContext, tile_side: u32, interval_s: f64) -> Result<(), crate::SnowError> {
        ctx.guarded(|| self.enable_sharing_unguarded(ctx, tile_side, interval_s))
    }

    fn enable_sharing_unguarded(&mut self, ctx: &GpuContext, tile_side: u32, interval_s: f64) -> Result<(), crate::SnowError> {
        if !SHARE_TILE_SIDES.contains(&tile_side) {
            return Err(SnowError::InvalidParameter { field: "tile_side", why: format!("{tile_side} is outside 8..=256 texels") }.into());
        }
        if !interval_s.is_finite() || interval_s < 0.0 {
            return Err(SnowError::InvalidParameter { field: "interval_s", why: format!("{interval_s} is not a time of 0 s or more") }.into());
        }
        let device = &ctx.device;
        let grid = ShareGrid::new(self.core.params.resolution, tile_side);
        ctx.capturing(|| {
            self.core.res.allocate_share_flags(device, grid.slots());
            // The stamp and update passes write the flags: bind the new buffer.
            self.core.stamp_pass = StampPass::new(device, &self.core.res);
            self.core.update_pass = UpdatePass::new(device, &self.core.res);
            self.core.update_pass.bind_sky(device, &self.core.res, self.accumulation.as_ref().map(crate::accumulate::SnowAccumulation::sky_view));
            self.core.bind_displace_flags(device);
            self.sharing = Some(Sharing::new(device, &self.core.res, tile_side, interval_s));
        });
        ctx.check("enabling shared snow")
    }

    /// Lets the next frame gather the changed tiles whatever the interval,
    /// so a program about to stop sends its last changes without letting
    /// world time pass.
    pub fn flush_changed_tiles(&mut self) {
        if let Some(sharing) = &mut self.sharing {
            sharing.gather_now();
        }
    }

    /// Changed tiles flagged and not gathered yet (0 without sharing).
    #[must_use]
    pub fn dirty_tiles(&self) -> usize {
        self.sharing.as_ref().map_or(0, Sharing::dirty_tiles)
    }

    /// Tiles given to the shared snow (`SnowPeer::update`) and not merged yet (ahead
    /// of the clock, or beyond a frame's upload).
    #[must_use]
    pub fn waiting_tiles(&self) -> usize {
        self.sharing.as_ref().map_or(0, Sharing::waiting_tiles)
    }

    /// The settings another machine must share for its snow to merge with
    /// this window's; the tile side is the sharing one
    /// ([`Self::enable_sharing`]), or the default tile side before.
    #[must_use]
    pub fn world_identity(&self) -> WorldIdentity {
        let (low, high, _) = self.stamp_range();
        let snowfall = self.core.params.snowfall.as_ref();
        WorldIdentity::from_settings(WorldSettings {
            texel_m: self.core.params.texel_m(),
            tile_side: self.sharing.as_ref().map_or_else(|| default_tile_texels(self.core.params.resolution), |s| s.grid().side),
            terrain: terrain_identity(&self.core.terrain),
            depth_m: self.core.params.depth_m,
            refill_m_per_s: self.core.params.refill_m_per_s,
            snowfall_m_per_s: snowfall.map_or(0.0, |s| s.rate_m_per_s),
            max_fallen_m: snowfall.map_or(0.0, |s| s.max_m),
            has_snowfall: self.core.params.keeps_lying_snow(),
            stamp_range_m: [low, high],
        })
    }

    /// The world identity a window of `params` over `terrain` has once it
    /// shares tiles of `tile_side`², found without a GPU: what a dedicated
    /// server (`snowpack server --scene`) serves and checks its peers
    /// against. Equal, field for field, to [`Self::world_identity`] of such
    /// a window after [`Self::enable_sharing`] with that side.
    #[must_use]
    pub fn world_identity_for(params: &crate::SnowParams, terrain: &crate::TerrainSource, tile_side: u32) -> WorldIdentity {
        let snow = WorldSnow {
            texel_m: params.texel_m(),
            depth_m: params.depth_m,
            refill_m_per_s: params.refill_m_per_s,
            snowfall: params.snowfall.as_ref().map(|s| WorldSnowfall { rate_m_per_s: s.rate_m_per_s, max_m: s.max_m }),
            displace: params.displace,
        };
        WorldIdentity::new(&snow, &WorldTerrain::described(terrain_identity(terrain), terrain.height_bounds()), tile_side)
    }
}

impl SnowTime {
    /// The world clock now: time, refill and footprint quanta, snowfall.
    pub(super) fn share_clock(&self) -> ShareClock {
        ShareClock { time_s: self.clock.time_s, refill_quanta: self.snow_quanta, stamp_quanta: self.clock.stamp_quanta, fallen_m: self.fallen_m }
    }
}

impl CoreWindow {
    /// How tiles are caught up in this world.
    pub(super) fn catch_up_rule(&self) -> CatchUp {
        CatchUp { max_fallen_m: self.params.snowfall.as_ref().map_or(0.0, |s| s.max_m) }
    }

    /// The window a frame's sharing steps work on, at `origin`.
    pub(super) fn share_window(&self, origin: [i64; 2]) -> ShareWindow {
        ShareWindow { origin, resolution: self.params.resolution, has_stamps: self.res.has_stamps(), use_fallen: self.params.keeps_lying_snow() }
    }
}

impl SharedSnow for SnowDeformation {
    /// The world clock now: time, refill and footprint quanta, snowfall.
    fn share_clock(&self) -> ShareClock {
        self.time.share_clock()
    }

    /// Sets the world clock (joining a world): time, refill counters and
    /// snowfall; the frames after it go on from there. When the counters are
    /// the world's own at that time (its refill from time 0), they keep
    /// being counted from the world's beginning, as on every other machine.
    fn join_clock(&mut self, clock: ShareClock) {
        let world = self.world_identity().clock_at(clock.time_s);
        self.time.clock.time_s = clock.time_s;
        self.time.clock.stamp_quanta = clock.stamp_quanta;
        self.time.clock.refill_m = f64::from(self.core.params.refill_m_per_s) * clock.time_s;
        self.time.clock.fallen_m = f64::from(clock.fallen_m);
        self.time.snow_quanta = clock.refill_quanta;
        self.time.fallen_m = clock.fallen_m;
        self.time.refill_base = if world.refill_quanta == clock.refill_quanta && world.stamp_quanta == clock.stamp_quanta {
            RefillBase::default()
        } else {
            RefillBase { time_s: clock.time_s, snow_quanta: clock.refill_quanta, stamp_quanta: clock.stamp_quanta }
        };
    }

    fn window(&self) -> Option<([i64; 2], u32)> {
        self.core.window.origin().map(|o| (o, self.core.params.resolution))
    }

    /// The tiles gathered since the last call (empty without sharing):
    /// whole tiles as the GPU had them at the frame gathered, stamped with
    /// that frame's clock.
    fn take_changed_tiles(&mut self) -> Vec<SharedTile> {
        self.sharing.as_mut().map(Sharing::take_outbox).unwrap_or_default()
    }

    /// Queues `tiles`; frames merge them (a bounded number each) once the
    /// clock reaches theirs. Without sharing enabled, or of another tile
    /// side, they are dropped with a warning.
    fn merge_tiles(&mut self, tiles: &[SharedTile]) {
        match &mut self.sharing {
            Some(sharing) => sharing.queue(tiles),
            None if !tiles.is_empty() => tracing::warn!("{} shared tiles dropped: sharing is not enabled (enable_sharing)", tiles.len()),
            None => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::deform::snow_word::SNOW_QUANTUM_M;

    #[test]
    fn refill_counters_match_the_world_clock() {
        let base = RefillBase::default();
        let rate = 0.013_f32;
        let world = WorldIdentity::from_settings(WorldSettings {
            texel_m: 0.0625,
            tile_side: 16,
            terrain: String::new(),
            depth_m: 0.5,
            refill_m_per_s: rate,
            snowfall_m_per_s: 0.0,
            max_fallen_m: 0.0,
            has_snowfall: false,
            stamp_range_m: [-1.0, 3.0],
        });
        for k in 0..2000 {
            let t = f64::from(k) * 0.0173;
            let c = world.clock_at(t);
            assert_eq!(base.quanta_at(0, t, rate, SNOW_QUANTUM_M), c.refill_quanta, "{t}");
            assert_eq!(base.quanta_at(0, t, rate, world.stamp_quantum_m()), c.stamp_quanta, "{t}");
        }
    }
}
