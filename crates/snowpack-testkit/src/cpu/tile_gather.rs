//! CPU twin of `tile_gather.wgsl`.

use snowpack::low_level::replicate::gather::{PACKED_PLANES, TileGatherParams};

use super::stamp::STAMP_EMPTY;
use super::window::storage_index;

/// The packed tiles of `keys` (`[column, row]`, the first `p.count`) from
/// the window's toroidal `snow`, `stamps`, `fallen` and `packed` (two
/// texels a word; it goes into the deficit word's high half).
#[must_use]
pub fn gather(p: &TileGatherParams, keys: &[[i32; 2]], snow: &[u32], stamps: &[u32], (fallen, packed): (&[f32], &[u32])) -> Vec<u32> {
    let side = p.side as usize;
    let area = side * side;
    let r = p.resolution as i32;
    let keys = &keys[..keys.len().min(p.count as usize)];
    let mut out = vec![0; keys.len() * area * PACKED_PLANES];
    for (t, key) in keys.iter().enumerate() {
        for y in 0..side {
            for x in 0..side {
                let g = [key[0] * p.side as i32 + x as i32, key[1] * p.side as i32 + y as i32];
                let local = [g[0] - p.origin[0], g[1] - p.origin[1]];
                let (mut deficit, mut stamp, mut lying) = (0, STAMP_EMPTY, 0.0f32);
                if (0..r).contains(&local[0]) && (0..r).contains(&local[1]) {
                    let s = storage_index(p.origin, p.resolution, local[1] as u32, local[0] as u32);
                    deficit = (snow[s] & 0xffff) | (snowpack::low_level::deform::packed_snow::get(packed, s) << 16);
                    if p.flags & TileGatherParams::HAS_STAMPS != 0 {
                        stamp = stamps[s];
                    }
                    if p.flags & TileGatherParams::USE_FALLEN != 0 {
                        lying = fallen[s];
                    }
                }
                let k = t * PACKED_PLANES * area + y * side + x;
                out[k] = deficit;
                out[k + area] = stamp;
                out[k + 2 * area] = lying.to_bits();
            }
        }
    }
    out
}
