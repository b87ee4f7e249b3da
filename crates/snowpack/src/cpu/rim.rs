//! CPU twin of `rim.wgsl`.

use crate::deform::rim::RimParams;

use super::window::storage_index;

/// Hanák 2021, eq. 4.1: `f(x) = -3.4766x^3 + 6.508x^2 - 2.231x + 0.215`.
#[must_use]
pub fn hanak_cubic(x: f32) -> f32 {
    ((-3.4766 * x + 6.508) * x - 2.231) * x + 0.215
}

/// Displayed height (window-local) from toroidal terrain and snow.
#[must_use]
pub fn rim(p: &RimParams, terrain: &[f32], snow: &[f32]) -> Vec<f32> {
    let r = p.resolution;
    let mut shown = vec![0.0; (r * r) as usize];
    for i in 0..r {
        for j in 0..r {
            let s = storage_index(p.origin, r, i, j);
            let ground = terrain[s];
            let x = ((snow[s] - ground) / p.depth_m).clamp(0.0, 1.0);
            let remapped = x + p.elevation * (hanak_cubic(x) - x);
            shown[(i * r + j) as usize] = ground + p.depth_m * remapped.max(0.0);
        }
    }
    shown
}
