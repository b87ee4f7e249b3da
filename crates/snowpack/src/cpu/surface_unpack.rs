//! CPU twin of `surface_unpack.wgsl`: the displayed heights and their packed
//! normals.

pub use crate::deform::display::normals_of;
use crate::deform::snow_word;

use super::window::storage_index;

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
