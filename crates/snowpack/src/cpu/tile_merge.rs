//! CPU twin of `tile_merge.wgsl`.

use crate::TerrainSource;
use crate::deform::snow_word::press_quanta;
use crate::replicate::gather::PACKED_PLANES;
use crate::replicate::merge::TileMergeParams;

use super::stamp::{STAMP_EMPTY, height};
use super::window::{storage_index, texel_ground};

/// Folds the packed `tiles` at `keys` (the first `p.count`) into the
/// window's toroidal `snow`, `stamps` and `fallen` over `terrain`.
pub fn merge(p: &TileMergeParams, keys: &[[i32; 2]], tiles: &[u32], terrain: &TerrainSource, snow: &mut [u32], stamps: &mut [u32], fallen: &mut [f32]) {
    let side = p.side as usize;
    let area = side * side;
    let r = p.resolution as i32;
    for (t, key) in keys.iter().enumerate().take(p.count as usize) {
        for y in 0..side {
            for x in 0..side {
                let g = [key[0] * p.side as i32 + x as i32, key[1] * p.side as i32 + y as i32];
                let local = [g[0] - p.origin[0], g[1] - p.origin[1]];
                if !(0..r).contains(&local[0]) || !(0..r).contains(&local[1]) {
                    continue;
                }
                let s = storage_index(p.origin, p.resolution, local[1] as u32, local[0] as u32);
                let k = t * PACKED_PLANES * area + y * side + x;
                let ground = texel_ground(terrain, g, p.texel_m);
                let mut lying = 0.0;
                if p.flags & TileMergeParams::USE_FALLEN != 0 {
                    lying = fallen[s].max(f32::from_bits(tiles[k + 2 * area]));
                    fallen[s] = lying;
                }
                let rest = ground + p.depth_m + lying;
                let word = snow[s];
                let deficit = (word & 0xffff).max(tiles[k]).min(press_quanta(rest, ground, ground));
                snow[s] = (word & 0xffff_0000) | deficit;
                if p.flags & TileMergeParams::HAS_STAMPS != 0 {
                    let incoming = tiles[k + area];
                    if incoming < stamps[s] {
                        stamps[s] = if height(incoming & 0xffff, p.low_m, p.high_m) >= rest { STAMP_EMPTY } else { incoming };
                    }
                }
            }
        }
    }
}
