//! CPU twin of `display.wgsl`: the rim, the clamped 5x5 Gaussian, the
//! displayed height into the upper half of each snow word.

use snowpack::low_level::deform::display::DisplayParams;
use snowpack::low_level::deform::snow_word;
use snowpack::low_level::deform::technique::RIM_PEAK;

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
pub fn point_rim(p: &DisplayParams, packed: u32, rest: f32) -> f32 {
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

/// The rimmed (unblurred) height, window-local, from the toroidal terrain,
/// snow words, stamps and snowfall.
#[must_use]
pub fn rim(p: &DisplayParams, terrain: &[f32], snow: &[u32], stamps: &[u32], fallen: &[f32]) -> Vec<f32> {
    let r = p.resolution;
    let mut shown = vec![0.0; (r * r) as usize];
    for i in 0..r {
        for j in 0..r {
            let s = storage_index(p.origin, r, i, j);
            let ground = terrain[s];
            let lying = if p.use_fallen != 0 { fallen[s] } else { 0.0 };
            let depth = p.depth_m + lying;
            let snow_h = snow_word::column_height(snow[s], ground, depth);
            shown[(i * r + j) as usize] = if depth <= 0.0 {
                // Bare ground (depth_m 0, no snowfall yet): no snow to remap
                // or to push into rims.
                snow_h
            } else if p.mode == 0 {
                let base = p.depth_m + lying.min(p.open_fallen_m);
                let x = if base > 0.0 { ((snow_h - ground) / base).clamp(0.0, 1.0) } else { 0.0 };
                let remapped = x + p.elevation * (hanak_cubic(x) - x);
                let above = if lying > p.open_fallen_m { (snow_h - ground - base).max(0.0) } else { 0.0 };
                ground + base * remapped.max(0.0) + above
            } else {
                let rest = ground + depth;
                let mut out = snow_h;
                if out >= rest - UNDISTURBED_M {
                    out += point_rim(p, stamps[s], rest);
                }
                out
            };
        }
    }
    shown
}

/// One axis of the (1 4 6 4 1)/16 Gaussian over window-local `src`, clamped
/// at the edges (0: along x, 1: along z).
#[must_use]
pub fn blur_axis(src: &[f32], resolution: u32, axis: u32) -> Vec<f32> {
    let r = resolution as i32;
    let at = |along: i32, across: i32| {
        let a = along.clamp(0, r - 1);
        if axis == 0 { src[(across * r + a) as usize] } else { src[(a * r + across) as usize] }
    };
    let mut dst = vec![0.0; src.len()];
    for across in 0..r {
        for along in 0..r {
            let sum = at(along - 2, across) + 4.0 * at(along - 1, across) + 6.0 * at(along, across) + 4.0 * at(along + 1, across) + at(along + 2, across);
            let out = if axis == 0 { across * r + along } else { along * r + across };
            dst[out as usize] = sum * (1.0 / 16.0);
        }
    }
    dst
}

/// The displayed height, window-local: the rim, blurred x then z when `p.blur` is set.
#[must_use]
pub fn shown(p: &DisplayParams, terrain: &[f32], snow: &[u32], stamps: &[u32], fallen: &[f32]) -> Vec<f32> {
    let rimmed = rim(p, terrain, snow, stamps, fallen);
    if p.blur == 0 {
        return rimmed;
    }
    blur_axis(&blur_axis(&rimmed, p.resolution, 0), p.resolution, 1)
}

/// Writes the displayed height into the upper half of every toroidal snow word.
pub fn display(p: &DisplayParams, terrain: &[f32], snow: &mut [u32], stamps: &[u32], fallen: &[f32]) {
    let shown = shown(p, terrain, snow, stamps, fallen);
    let r = p.resolution;
    for i in 0..r {
        for j in 0..r {
            let s = storage_index(p.origin, r, i, j);
            snow[s] = snow_word::with_shown(snow[s], shown[(i * r + j) as usize] - terrain[s]);
        }
    }
}
