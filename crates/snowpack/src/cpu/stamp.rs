//! CPU twin of `stamp.wgsl` and `shared/stamp.wgsl`: footprint packing,
//! quantisation and the per-point footprint square.

use crate::deform::stamp::StampParams;

use super::window::storage_index;

/// A texel no footprint has touched.
pub const STAMP_EMPTY: u32 = u32::MAX;

/// Height (m) to its 16-bit code over `[low, high]`, rounded to nearest.
#[must_use]
pub fn quantise(h: f32, low: f32, high: f32) -> u32 {
    let t = ((h - low) / (high - low)).clamp(0.0, 1.0);
    (t * 65535.0 + 0.5) as u32
}

/// A 16-bit code back to metres.
#[must_use]
pub fn height(q: u32, low: f32, high: f32) -> f32 {
    low + q as f32 / 65535.0 * (high - low)
}

/// `(footprint height, foot height)` in metres of a packed texel; `None` when empty.
#[must_use]
pub fn unpack(packed: u32, low: f32, high: f32) -> Option<(f32, f32)> {
    (packed != STAMP_EMPTY).then(|| (height(packed >> 16, low, high), height(packed & 0xffff, low, high)))
}

/// Writes every point's footprint into the toroidal `stamps` with a minimum.
/// `points` are (window-local x, foot height, window-local z, scale).
pub fn stamp(p: &StampParams, points: &[[f32; 4]], stamps: &mut [u32]) {
    let res = p.resolution as i32;
    let range = p.range_texels as i32;
    for pt in points.iter().take(p.count as usize) {
        let i0 = (pt[2] / p.texel_m).floor() as i32 - range / 2;
        let j0 = (pt[0] / p.texel_m).floor() as i32 - range / 2;
        let foot = quantise(pt[1], p.low_m, p.high_m);
        for i in (i0..i0 + range).filter(|i| (0..res).contains(i)) {
            let dz = (i as f32 + 0.5) * p.texel_m - pt[2];
            for j in (j0..j0 + range).filter(|j| (0..res).contains(j)) {
                let dx = (j as f32 + 0.5) * p.texel_m - pt[0];
                let h = pt[1] + (dx * dx + dz * dz) * pt[3];
                let packed = (quantise(h, p.low_m, p.high_m) << 16) | foot;
                let s = storage_index(p.origin, p.resolution, i as u32, j as u32);
                stamps[s] = stamps[s].min(packed);
            }
        }
    }
}
