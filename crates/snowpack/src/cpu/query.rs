//! CPU twin of `query.wgsl`.

use crate::deform::query::{QueryParams, RawSample};

use super::window::storage_index;

fn bilerp(a: f32, b: f32, c: f32, d: f32, f: [f32; 2]) -> f32 {
    let ab = a + (b - a) * f[0];
    let cd = c + (d - c) * f[0];
    ab + (cd - ab) * f[1]
}

fn unpack_normal(bits: u32) -> [f32; 3] {
    let snorm = |b: u32| (f32::from(b as u16 as i16) / 32767.0).clamp(-1.0, 1.0);
    let (x, z) = (snorm(bits & 0xffff), snorm(bits >> 16));
    [x, (1.0 - x * x - z * z).max(0.0).sqrt(), z]
}

/// The samples `query.wgsl` writes for `points` (m from the window's
/// corner), from toroidal `terrain`, `snow`, `fallen` and window-local `surface`.
#[must_use]
pub fn query(params: &QueryParams, points: &[[f32; 2]], terrain: &[f32], snow: &[f32], fallen: &[f32], surface: &[[u32; 2]]) -> Vec<RawSample> {
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
            let (s00, s01, s10, s11) = (s(0, 0), s(0, 1), s(1, 0), s(1, 1));
            out.height_m = bilerp(snow[s00], snow[s01], snow[s10], snow[s11], f);
            out.terrain_m = bilerp(terrain[s00], terrain[s01], terrain[s10], terrain[s11], f);
            let fallen_m = if params.use_fallen != 0 { bilerp(fallen[s00], fallen[s01], fallen[s10], fallen[s11], f) } else { 0.0 };
            out.rest_m = out.terrain_m + params.depth_m + fallen_m;
            let w = |di: u32, dj: u32| surface[((i + di) * res + j + dj) as usize];
            let (w00, w01, w10, w11) = (w(0, 0), w(0, 1), w(1, 0), w(1, 1));
            let h = |t: [u32; 2]| f32::from_bits(t[0]);
            out.surface_m = bilerp(h(w00), h(w01), h(w10), h(w11), f);
            let n = [w00, w01, w10, w11].map(|t| glam::Vec3::from(unpack_normal(t[1])));
            let n = n[0].lerp(n[1], f[0]).lerp(n[2].lerp(n[3], f[0]), f[1]).normalize();
            out.normal = n.to_array();
            out.inside = 1.0;
            out
        })
        .collect()
}
