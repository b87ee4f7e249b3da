//! CPU twin of `shaders/shell_vertices.wgsl`: the base surface and its offset copy.

use snowpack::TerrainSource;
use snowpack::low_level::render::shell::vertices::{BaseVertex, ShellVertex, ShellVertexParams};

/// cos and sin of the texture's turn against the world axes (0.5 rad), as in the shader.
const TILE_COS: f32 = 0.877_582_56;
const TILE_SIN: f32 = 0.479_425_54;

fn unpack_normal(bits: u32) -> [f32; 3] {
    // unpack2x16snorm: low half first, each max(v / 32767, -1).
    let half = |h: u32| (f32::from(h as u16 as i16) / 32767.0).max(-1.0);
    let (x, z) = (half(bits & 0xffff), half(bits >> 16));
    [x, (1.0 - (x * x + z * z)).max(0.0).sqrt(), z]
}

/// The shell vertices for `params`: from `base` in mesh mode, from the
/// window-local `surface` (height bits, packed normal) and `terrain` in snow mode.
#[must_use]
pub fn shell_vertices(params: &ShellVertexParams, base: &[BaseVertex], surface: &[[u32; 2]], terrain: &TerrainSource) -> Vec<ShellVertex> {
    (0..params.count)
        .map(|k| {
            if params.mode == ShellVertexParams::MESH {
                let v = base[k as usize];
                let top = [0, 1, 2].map(|i| v.position[i] + v.normal[i] * params.thickness_m);
                return ShellVertex { base: v.position, top: [top[0], top[1], top[2], v.normal[3]] };
            }
            let last = params.resolution as i32 - 1;
            let col = (params.origin[0] + ((k % params.side) * params.stride) as i32).clamp(0, last);
            let row = (params.origin[1] + ((k / params.side) * params.stride) as i32).clamp(0, last);
            let texel = surface[(row as u32 * params.resolution + col as u32) as usize];
            let x = params.corner[0] + (col as f32 + 0.5) * params.texel_m;
            let z = params.corner[1] + (row as f32 + 0.5) * params.texel_m;
            let y = f32::from_bits(texel[0]);
            let n = unpack_normal(texel[1]);
            let rest = terrain.height_at(x, z) + params.depth_m;
            let pressed = (rest - y).max(0.0);
            let fraction = (1.0 - pressed / params.flatten_m).clamp(params.min_fraction, 1.0);
            let t = params.thickness_m * fraction;
            let u = (x * TILE_COS + z * TILE_SIN) / params.tile_m;
            let v = (z * TILE_COS - x * TILE_SIN) / params.tile_m;
            ShellVertex { base: [x, y, z, u], top: [x + n[0] * t, y + n[1] * t, z + n[2] * t, v] }
        })
        .collect()
}
