//! CPU twin of `query.wgsl`.

use snowpack::low_level::deform::packed_snow;
use snowpack::low_level::deform::query::{QueryParams, RawSample};
use snowpack::low_level::deform::snow_word;
use snowpack::low_level::deform::snow_word::SNOW_QUANTUM_M;

use super::window::storage_index;

fn bilerp(a: f32, b: f32, c: f32, d: f32, f: [f32; 2]) -> f32 {
    let ab = a + (b - a) * f[0];
    let cd = c + (d - c) * f[0];
    ab + (cd - ab) * f[1]
}

/// Displayed height of window-local texel (i, j), clamped into the window.
fn shown_at(params: &QueryParams, terrain: &[f32], snow: &[u32], i: i32, j: i32) -> f32 {
    let last = params.resolution as i32 - 1;
    let s = storage_index(params.origin, params.resolution, i.clamp(0, last) as u32, j.clamp(0, last) as u32);
    snow_word::shown(snow[s], terrain[s])
}

fn texel_normal(params: &QueryParams, terrain: &[f32], snow: &[u32], i: i32, j: i32) -> glam::Vec3 {
    let h = |i, j| shown_at(params, terrain, snow, i, j);
    glam::Vec3::new(-(h(i, j + 1) - h(i, j - 1)), 2.0 * params.texel_m, -(h(i + 1, j) - h(i - 1, j))).normalize()
}

/// The samples `query.wgsl` writes for `points` (m from the window's
/// corner), from toroidal `terrain`, snow words, `fallen` and packed snow
/// (two texels a word, [`snowpack::low_level::deform::packed_snow`]).
#[must_use]
pub fn query(params: &QueryParams, points: &[[f32; 2]], terrain: &[f32], (snow, fallen, packed): (&[u32], &[f32], &[u32])) -> Vec<RawSample> {
    let res = params.resolution;
    let r = res as i32;
    points
        .iter()
        .map(|p| {
            let uv = [p[0] / params.texel_m - 0.5, p[1] / params.texel_m - 0.5];
            let cell = [uv[0].floor(), uv[1].floor()];
            let f = [uv[0] - cell[0], uv[1] - cell[1]];
            let mut out = RawSample { normal: [0.0, 1.0, 0.0], ..RawSample::default() };
            let last = (r - 2) as f32;
            if cell[0] < 0.0 || cell[1] < 0.0 || cell[0] > last || cell[1] > last {
                return out;
            }
            let (j, i) = (cell[0] as u32, cell[1] as u32);
            let s = |di: u32, dj: u32| storage_index(params.origin, res, i + di, j + dj);
            let taps = [s(0, 0), s(0, 1), s(1, 0), s(1, 1)];
            let t = taps.map(|s| terrain[s]);
            let l = taps.map(|s| if params.use_fallen != 0 { fallen[s] } else { 0.0 });
            out.terrain_m = bilerp(t[0], t[1], t[2], t[3], f);
            out.rest_m = out.terrain_m + params.depth_m + bilerp(l[0], l[1], l[2], l[3], f);
            let h: [f32; 4] = std::array::from_fn(|k| snow_word::column_height(snow[taps[k]], t[k], params.depth_m + l[k]));
            out.height_m = bilerp(h[0], h[1], h[2], h[3], f);
            let shown: [f32; 4] = std::array::from_fn(|k| snow_word::shown(snow[taps[k]], t[k]));
            out.surface_m = bilerp(shown[0], shown[1], shown[2], shown[3], f);
            let q = taps.map(|s| packed_snow::get(packed, s) as f32 * SNOW_QUANTUM_M);
            out.packed_m = bilerp(q[0], q[1], q[2], q[3], f);
            let (ii, jj) = (i as i32, j as i32);
            let n = [(0, 0), (0, 1), (1, 0), (1, 1)].map(|(di, dj)| texel_normal(params, terrain, snow, ii + di, jj + dj));
            out.normal = n[0].lerp(n[1], f[0]).lerp(n[2].lerp(n[3], f[0]), f[1]).normalize().to_array();
            out.inside = 1.0;
            out
        })
        .collect()
}
