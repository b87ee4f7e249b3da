//! CPU twin of `stamp.wgsl` and `shared/stamp.wgsl`: footprint packing,
//! quantisation and the per-point footprint square.

use snowpack::low_level::deform::stamp::StampParams;

use super::window::storage_index;

pub use snowpack::low_level::deform::stamp::STAMP_EMPTY;

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
/// `points` are as [`snowpack::low_level::deform::stamp::contact_points`] returns them:
/// (window-local x, foot height, window-local z, scale) where the point is
/// now, then (x, foot, z, 0) where it was swept from.
pub fn stamp(p: &StampParams, points: &[[f32; 8]], stamps: &mut [u32]) {
    stamp_flagged(p, points, stamps, &mut []);
}

/// [`stamp`] that also sets, when `p.share_side > 0`, the changed-tile flag
/// (`flags`, [`snowpack::low_level::replicate::flags::ShareGrid`]) of every texel whose
/// footprint it lowered.
pub fn stamp_flagged(p: &StampParams, points: &[[f32; 8]], stamps: &mut [u32], flags: &mut [u32]) {
    let grid = snowpack::low_level::replicate::flags::ShareGrid { side: p.share_side.max(1), keys: p.share_keys };
    let share = p.share_side != 0 && !flags.is_empty();
    let res = p.resolution as i32;
    let range = p.range_texels as i32;
    for pt in points.iter().take(p.count as usize) {
        let (p1, p0, scale) = ([pt[0], pt[1], pt[2]], [pt[4], pt[5], pt[6]], pt[3]);
        let i0 = (p0[2].min(p1[2]) / p.texel_m).floor() as i32 - range / 2;
        let j0 = (p0[0].min(p1[0]) / p.texel_m).floor() as i32 - range / 2;
        let i1 = (p0[2].max(p1[2]) / p.texel_m).floor() as i32 - range / 2 + range;
        let j1 = (p0[0].max(p1[0]) / p.texel_m).floor() as i32 - range / 2 + range;
        let travel = [p1[0] - p0[0], p1[2] - p0[2]];
        let climb = p1[1] - p0[1];
        let qa = scale * (travel[0] * travel[0] + travel[1] * travel[1]);
        for i in (i0..i1).filter(|i| (0..res).contains(i)) {
            let qz = (i as f32 + 0.5) * p.texel_m;
            for j in (j0..j1).filter(|j| (0..res).contains(j)) {
                let qx = (j as f32 + 0.5) * p.texel_m;
                let qb = climb - 2.0 * scale * ((qx - p0[0]) * travel[0] + (qz - p0[2]) * travel[1]);
                let t = if qa > 1e-12 {
                    (-qb / (2.0 * qa)).clamp(0.0, 1.0)
                } else if qb > 0.0 {
                    0.0
                } else {
                    1.0
                };
                let (ax, az) = (p0[0] + t * travel[0], p0[2] + t * travel[1]);
                let foot = p0[1] + t * climb;
                let (dx, dz) = (qx - ax, qz - az);
                let h = foot + (dx * dx + dz * dz) * scale;
                let packed = (quantise(h, p.low_m, p.high_m) << 16) | quantise(foot, p.low_m, p.high_m);
                let s = storage_index(p.origin, p.resolution, i as u32, j as u32);
                if share && packed < stamps[s] {
                    flags[grid.slot([i64::from(p.origin[0]) + i64::from(j), i64::from(p.origin[1]) + i64::from(i)])] = 1;
                }
                stamps[s] = stamps[s].min(packed);
            }
        }
    }
}
