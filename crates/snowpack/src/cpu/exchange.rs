//! CPU twin of `exchange.wgsl` and `tile_index` in `shared/tiles.wgsl`.

use crate::deform::window::TexelRect;
use crate::tiles::exchange::ExchangeParams;
use crate::tiles::streaming::{PLANE_FALLEN, PLANE_SNOW, PLANE_TERRAIN, plane_stamps};

use super::window::storage_index;

/// Index into the resident tiles (`planes` planes a slot) of global texel
/// `g` (`[column, row]`), plane `plane`.
#[must_use]
pub fn tile_index(g: [i32; 2], side: u32, n: u32, planes: usize, plane: usize) -> usize {
    let s = side as i32;
    let (tc, tr) = (g[0].div_euclid(s), g[1].div_euclid(s));
    let (lx, ly) = ((g[0] - tc * s) as usize, (g[1] - tr * s) as usize);
    let slot = (tr.rem_euclid(n as i32) * n as i32 + tc.rem_euclid(n as i32)) as usize;
    (slot * planes + plane) * (side * side) as usize + ly * side as usize + lx
}

/// The window's toroidal buffers the exchange reads and writes.
#[derive(Debug)]
pub struct WindowBuffers<'a> {
    /// The terrain's source: a stashed tile's terrain plane is evaluated from it.
    pub terrain: &'a crate::TerrainSource,
    /// Snow height.
    pub snow: &'a mut [f32],
    /// Packed footprints.
    pub stamps: &'a mut [u32],
    /// Snowfall so far (one texel without snowfall).
    pub fallen: &'a mut [f32],
}

/// Stashes (with [`ExchangeParams::STASH`]) or loads the texels of `rects`.
pub fn exchange(p: &ExchangeParams, rects: &[TexelRect], tiles: &mut [u32], w: &mut WindowBuffers<'_>) {
    let res = p.resolution as i32;
    let use_fallen = p.flags & ExchangeParams::USE_FALLEN != 0;
    let has_stamps = p.flags & ExchangeParams::HAS_STAMPS != 0;
    let (side, n, planes) = (p.side, p.slots_per_side, p.planes as usize);
    for rect in rects.iter().take(2) {
        for i in rect[0]..rect[0] + rect[2] {
            for j in rect[1]..rect[1] + rect[3] {
                let s = storage_index(p.origin, p.resolution, i, j);
                if p.flags & ExchangeParams::STASH != 0 {
                    let (sj, si) = ((s % p.resolution as usize) as i32, (s / p.resolution as usize) as i32);
                    let o = p.old_origin;
                    let g = [o[0] + (sj - o[0]).rem_euclid(res), o[1] + (si - o[1]).rem_euclid(res)];
                    tiles[tile_index(g, side, n, planes, PLANE_SNOW)] = w.snow[s].to_bits();
                    if has_stamps {
                        tiles[tile_index(g, side, n, planes, plane_stamps(planes))] = w.stamps[s];
                    }
                    tiles[tile_index(g, side, n, planes, PLANE_TERRAIN)] = super::window::texel_ground(w.terrain, g, p.texel_m).to_bits();
                    if use_fallen {
                        tiles[tile_index(g, side, n, planes, PLANE_FALLEN)] = w.fallen[s].to_bits();
                    }
                } else {
                    let g = [p.origin[0] + j as i32, p.origin[1] + i as i32];
                    w.snow[s] = f32::from_bits(tiles[tile_index(g, side, n, planes, PLANE_SNOW)]);
                    if has_stamps {
                        w.stamps[s] = tiles[tile_index(g, side, n, planes, plane_stamps(planes))];
                    }
                    if use_fallen {
                        w.fallen[s] = f32::from_bits(tiles[tile_index(g, side, n, planes, PLANE_FALLEN)]);
                    }
                }
            }
        }
    }
}
