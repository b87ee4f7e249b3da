//! The shared-snow plug-in's front: the window as a replica of a shared
//! world (its identity, the flags' allocation) over `Sharing`, the GPU's
//! changed-tile flags, gather and merge passes (`replicate::sharing`).
//! `SharedWindow` (`shared_window.rs`: `SnowDeformation`'s calls for
//! shared snow, feature `share`) and its [`crate::replicate::SharedSnow`]
//! impl delegate here; its frame steps (merge, flags) are in
//! [`super::steps`].

use crate::deform::params::default_tile_texels;
use crate::error::SnowError;
use crate::gpu::GpuContext;
use crate::replicate::flags::ShareGrid;
use crate::replicate::sharing::{ShareWindow, Sharing};
use crate::replicate::world::{WorldSettings, WorldSnow, WorldSnowfall, WorldTerrain};
use crate::replicate::{CatchUp, WorldIdentity, terrain_identity};
use snowpack_share::replicate::WorldIdentityExt;

use super::core_window::CoreWindow;
use crate::gpu::context::GpuContextExt;

/// Tile sides [`super::SnowDeformation::enable_sharing`] accepts (texels).
pub const SHARE_TILE_SIDES: std::ops::RangeInclusive<u32> = 8..=256;

/// Shares `core`'s snow in tiles of `tile_side` texels (8..=256) on the
/// global grid, gathered at most every `interval_s` of world time
/// (`SnowDeformation::enable_sharing`): allocates the changed-tile flags,
/// binds them to the passes that write them (the update with the objects'
/// occlusion map `sky`) and makes `sharing` anew. A side or interval out of
/// range is an error naming it, and nothing changes.
#[cfg_attr(not(feature = "share"), expect(dead_code, reason = "for `SharedWindow`'s calls (feature `share`)"))]
pub(super) fn enable(
    ctx: &GpuContext,
    core: &mut CoreWindow,
    sky: Option<&wgpu::TextureView>,
    sharing: &mut Option<Sharing>,
    (tile_side, interval_s): (u32, f64),
) -> Result<(), crate::SnowError> {
    if !SHARE_TILE_SIDES.contains(&tile_side) {
        return Err(SnowError::InvalidParameter { field: "tile_side", why: format!("{tile_side} is outside 8..=256 texels") }.into());
    }
    if !interval_s.is_finite() || interval_s < 0.0 {
        return Err(SnowError::InvalidParameter { field: "interval_s", why: format!("{interval_s} is not a time of 0 s or more") }.into());
    }
    let device = &ctx.device;
    let grid = ShareGrid::new(core.params().resolution, tile_side);
    ctx.capturing(|| {
        core.set_shape_capture(crate::deform::capture::ShapeCapture::for_shared_snow());
        core.allocate_share_flags(device, grid.slots(), sky);
        *sharing = Some(Sharing::new(device, core.res(), tile_side, interval_s));
    });
    ctx.check("enabling shared snow")
}

/// The settings another machine must share for its snow to merge with
/// `core`'s; the tile side is `sharing`'s, or the default tile side before
/// (`SnowDeformation::world_identity`).
pub(super) fn world_identity(core: &CoreWindow, sharing: Option<&Sharing>) -> WorldIdentity {
    let (low, high, _) = core.stamp_range();
    let p = core.params();
    let snowfall = p.snowfall.as_ref();
    let world = WorldIdentity::from_settings(WorldSettings {
        texel_m: p.texel_m(),
        tile_side: sharing.map_or_else(|| default_tile_texels(p.resolution), |s| s.grid().side),
        terrain: terrain_identity(core.terrain()),
        depth_m: p.depth_m,
        refill_m_per_s: p.refill_m_per_s,
        snowfall_m_per_s: snowfall.map_or(0.0, |s| s.rate_m_per_s),
        max_fallen_m: snowfall.map_or(0.0, |s| s.max_m),
        has_snowfall: p.keeps_lying_snow(),
        stamp_range_m: [low, high],
    });
    match held_grid(core.terrain()) {
        Some(grid) => world.holding(grid),
        None => world,
    }
}

/// The heightmap a world's identity holds, so presses travel over it: a
/// heightmap terrain's. A mesh's grid is drawn on the GPU, which the CPU
/// does not repeat bit for bit: its world shares tiles.
fn held_grid(terrain: &crate::TerrainSource) -> Option<std::sync::Arc<snowpack_share::replicate::press::ground::HeightGrid>> {
    match terrain {
        crate::TerrainSource::Heightmap(h) => Some(std::sync::Arc::clone(h.shared_grid())),
        _ => None,
    }
}

/// The world identity of a window of `params` over `terrain` sharing
/// tiles of `tile_side`², found without a GPU
/// (`SnowDeformation::world_identity_for`).
#[cfg_attr(not(feature = "share"), expect(dead_code, reason = "for `SharedWindow`'s calls (feature `share`)"))]
pub(super) fn world_identity_for(params: &crate::SnowParams, terrain: &crate::TerrainSource, tile_side: u32) -> WorldIdentity {
    let snow = WorldSnow {
        texel_m: params.texel_m(),
        depth_m: params.depth_m,
        refill_m_per_s: params.refill_m_per_s,
        snowfall: params.snowfall.as_ref().map(|s| WorldSnowfall { rate_m_per_s: s.rate_m_per_s, max_m: s.max_m }),
        displace: params.displace,
    };
    let ground = match held_grid(terrain) {
        Some(grid) => WorldTerrain::heightmap(grid),
        None => WorldTerrain::described(terrain_identity(terrain), terrain.height_bounds()),
    };
    WorldIdentity::new(&snow, &ground, tile_side)
}

/// How tiles are caught up in `core`'s world.
pub(super) fn catch_up_rule(core: &CoreWindow) -> CatchUp {
    CatchUp { max_fallen_m: core.params().snowfall.as_ref().map_or(0.0, |s| s.max_m) }
}

/// The window a frame's sharing steps work on: `core`'s, at `origin`.
pub(super) fn share_window(core: &CoreWindow, origin: [i64; 2]) -> ShareWindow {
    let p = core.params();
    ShareWindow { origin, resolution: p.resolution, has_stamps: core.res().has_stamps(), use_fallen: p.keeps_lying_snow() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::deform::snow_word::SNOW_QUANTUM_M;
    use crate::snow::clock::RefillBase;

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
