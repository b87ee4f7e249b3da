//! CPU twin of `rim.wgsl`.

use crate::deform::rim::RimParams;
use crate::deform::technique::RIM_PEAK;

use super::stamp::{STAMP_EMPTY, height};
use super::window::storage_index;

/// Snow within this of the rest height counts as undisturbed (grows rims).
const UNDISTURBED_M: f32 = 0.001;

/// Hanák 2021, eq. 4.1: `f(x) = -3.4766x^3 + 6.508x^2 - 2.231x + 0.215`.
#[must_use]
pub fn hanak_cubic(x: f32) -> f32 {
    ((-3.4766 * x + 6.508) * x - 2.231) * x + 0.215
}

/// Rim height (m) a packed footprint raises over undisturbed snow at `rest`.
#[must_use]
pub fn point_rim(p: &RimParams, packed: u32, rest: f32) -> f32 {
    if packed == STAMP_EMPTY {
        return 0.0;
    }
    let h = height(packed >> 16, p.low_m, p.high_m);
    let foot = height(packed & 0xffff, p.low_m, p.high_m);
    if foot >= rest || h <= rest {
        return 0.0;
    }
    let m = (rest - foot).sqrt();
    let r = ((h - foot).sqrt() - m) / m;
    let t = if p.mode == 1 { 0.5 - 2.0 * r } else { 2.0 * r - 1.0 };
    (1.0 - t * t).max(0.0) * p.elevation * RIM_PEAK * (rest - foot)
}

/// Displayed height (window-local) from toroidal terrain, snow, stamps and snowfall.
#[must_use]
pub fn rim(p: &RimParams, terrain: &[f32], snow: &[f32], stamps: &[u32], fallen: &[f32]) -> Vec<f32> {
    let r = p.resolution;
    let mut shown = vec![0.0; (r * r) as usize];
    for i in 0..r {
        for j in 0..r {
            let s = storage_index(p.origin, r, i, j);
            let ground = terrain[s];
            let depth = if p.use_fallen != 0 { p.depth_m + fallen[s] } else { p.depth_m };
            shown[(i * r + j) as usize] = if depth <= 0.0 {
                // Bare ground (depth_m 0, no snowfall yet): no snow to remap
                // or to push into rims.
                snow[s]
            } else if p.mode == 0 {
                let x = ((snow[s] - ground) / depth).clamp(0.0, 1.0);
                let remapped = x + p.elevation * (hanak_cubic(x) - x);
                ground + depth * remapped.max(0.0)
            } else {
                let rest = ground + depth;
                let mut out = snow[s];
                if out >= rest - UNDISTURBED_M {
                    out += point_rim(p, stamps[s], rest);
                }
                out
            };
        }
    }
    shown
}
