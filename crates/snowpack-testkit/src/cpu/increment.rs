//! CPU twin of `increment.wgsl`.

use snowpack::low_level::accumulate::IncrementParams;

use super::scatter::HIT_UNIT;

/// The frame's depth increment per atlas texel from `hits`, which it clears.
pub fn increment(p: &IncrementParams, normal_area: &[[f32; 4]], hits: &mut [u32], fresh: &mut [f32]) {
    for k in 0..(p.atlas_resolution * p.atlas_resolution) as usize {
        let area = normal_area[k][3];
        fresh[k] = if area > 0.0 { hits[k] as f32 / HIT_UNIT * p.volume_m3 / area } else { 0.0 };
        hits[k] = 0;
    }
}
