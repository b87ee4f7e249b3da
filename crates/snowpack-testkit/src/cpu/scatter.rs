//! CPU twin of `scatter.wgsl`.

use snowpack::low_level::accumulate::ScatterParams;

/// One whole occlusion pixel of snow in hit units.
pub const HIT_UNIT: f32 = 65536.0;

/// The scatter's per-pixel hash in [0, 1).
#[must_use]
pub fn hash(x: u32, y: u32, frame: u32) -> f32 {
    let mut h = x.wrapping_mul(0x8da6_b343) ^ y.wrapping_mul(0xd816_3841) ^ frame.wrapping_mul(0xcb1a_b31f);
    h = (h ^ (h >> 16)).wrapping_mul(0x7feb_352d);
    h = (h ^ (h >> 15)).wrapping_mul(0x846c_a68b);
    h ^= h >> 16;
    (h >> 8) as f32 / 16_777_216.0
}

/// Adds every footprint rectangle (`[x0, y0, x1, y1]`, x0 = `u16::MAX` for
/// none; one per occlusion pixel, row-major) into `hits` (one per atlas texel).
pub fn scatter(p: &ScatterParams, footprint: &[[u16; 4]], hits: &mut [u32]) {
    for y in 0..p.resolution {
        for x in 0..p.resolution {
            let r = footprint[(y * p.resolution + x) as usize];
            if r[0] == u16::MAX {
                continue;
            }
            let [x0, y0, x1, y1] = r.map(u32::from);
            let n = (x1 - x0 + 1) * (y1 - y0 + 1);
            let noise = 1.0 + p.noise * (2.0 * hash(x, y, p.frame) - 1.0);
            let w = (HIT_UNIT * noise / n as f32 + 0.5).floor() as u32;
            for ty in y0..=y1 {
                for tx in x0..=x1 {
                    let k = (ty * p.atlas_resolution + tx) as usize;
                    hits[k] = hits[k].wrapping_add(w);
                }
            }
        }
    }
}
