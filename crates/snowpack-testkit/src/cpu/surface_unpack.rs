//! CPU twin of `surface_unpack.wgsl`: the displayed heights and their packed
//! normals.

pub use snowpack::low_level::deform::display::normals_of;
use snowpack::low_level::deform::snow_word;

use super::window::storage_index;
use snowpack::low_level::render::surface::UnpackParams;

/// WGSL's `pack2x16snorm`.
#[must_use]
pub fn pack2x16snorm(a: f32, b: f32) -> u32 {
    let q = |v: f32| ((0.5 + 32767.0 * v.clamp(-1.0, 1.0)).floor() as i32 as i16 as u16) as u32;
    q(a) | (q(b) << 16)
}

/// The displayed heights, window-local, from the toroidal snow words and terrain.
#[must_use]
pub fn shown_heights(snow: &[u32], terrain: &[f32], origin: [i32; 2], resolution: u32) -> Vec<f32> {
    let mut out = Vec::with_capacity(snow.len());
    for i in 0..resolution {
        for j in 0..resolution {
            let s = storage_index(origin, resolution, i, j);
            out.push(snow_word::shown(snow[s], terrain[s]));
        }
    }
    out
}

/// Packed (height bits, normal) per texel, window-local, from the toroidal
/// snow words and terrain.
#[must_use]
pub fn normals(snow: &[u32], terrain: &[f32], origin: [i32; 2], resolution: u32, texel_m: f32) -> Vec<[u32; 2]> {
    let height = shown_heights(snow, terrain, origin, resolution);
    normals_of(&height, resolution, texel_m).iter().zip(&height).map(|(n, h)| [h.to_bits(), pack2x16snorm(n[0], n[2])]).collect()
}

/// What the surface of a texel with snow word `word`, packed snow `q`
/// (quanta) and `column_m` of snow above the terrain shows of its packing:
/// `[packed snow m, density from fresh (0) to final (1); 1 where a press
/// left no column]`, faded out under
/// the fresh snow refill laid over it (about `q − deficit`, fresh from 3 cm;
/// `surface_packing` in `surface_unpack.wgsl`).
#[must_use]
pub fn surface_packing(word: u32, q: u32, column_m: f32, pack_ratio: f32) -> [f32; 2] {
    let cover = (q - q.min(word & 0xffff)) as f32 * snow_word::SNOW_QUANTUM_M;
    let t = ((cover - 0.005) / (0.03 - 0.005)).clamp(0.0, 1.0);
    let fade = 1.0 - t * t * (3.0 - 2.0 * t);
    let q_m = q as f32 * snow_word::SNOW_QUANTUM_M;
    let cap_m = column_m * pack_ratio;
    let density = if cap_m < 1e-4 && word & 0xffff > 0 { 1.0 } else { (q_m / cap_m.max(1e-6)).clamp(0.0, 1.0) };
    [q_m * fade, density * fade]
}

/// What each texel's surface shows of its packing, window-local, from the
/// toroidal snow words, packed snow, terrain and lying snow (read with
/// [`UnpackParams::use_fallen`]), tent-filtered over 3×3 with the window's
/// edge texels repeated.
#[must_use]
pub fn packing(p: &UnpackParams, (snow, packed): (&[u32], &[u32]), (terrain, fallen): (&[f32], &[f32])) -> Vec<[f32; 2]> {
    let (resolution, origin) = (p.resolution, p.origin);
    let mut raw = Vec::with_capacity(snow.len());
    for i in 0..resolution {
        for j in 0..resolution {
            let s = storage_index(origin, resolution, i, j);
            let lying = if p.use_fallen != 0 { fallen[s] } else { 0.0 };
            let column = snow_word::column_height(snow[s], terrain[s], p.depth_m + lying) - terrain[s];
            raw.push(surface_packing(snow[s], snowpack::low_level::deform::packed_snow::get(packed, s), column, p.pack_ratio));
        }
    }
    let r = resolution as i32;
    let at = |i: i32, j: i32| raw[(i.clamp(0, r - 1) * r + j.clamp(0, r - 1)) as usize];
    let mut out = Vec::with_capacity(raw.len());
    for i in 0..r {
        for j in 0..r {
            let mut sum = [0.0f32; 2];
            // The shader's order: centre, edges, corners.
            let (c, e, k) =
                (at(i, j), [at(i, j - 1), at(i, j + 1), at(i - 1, j), at(i + 1, j)], [at(i - 1, j - 1), at(i - 1, j + 1), at(i + 1, j - 1), at(i + 1, j + 1)]);
            for (n, out) in sum.iter_mut().enumerate() {
                let edges = e[0][n] + e[1][n] + e[2][n] + e[3][n];
                let corners = k[0][n] + k[1][n] + k[2][n] + k[3][n];
                *out = (4.0 * c[n] + 2.0 * edges + corners) / 16.0;
            }
            out.push(sum);
        }
    }
    out
}
