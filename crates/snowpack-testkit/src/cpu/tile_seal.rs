//! CPU twin of `tile_seal.wgsl`.

use snowpack::TerrainSource;
use snowpack::low_level::tiles::seal::SealParams;
use snowpack::low_level::tiles::streaming::{PLANE_FALLEN, PLANE_SNOW};

use super::window::texel_ground;

/// Seals the snow plane of each entry's slot (`[col, row, slot, 0]`): its
/// bits XOR those of the rest height (ground + (depth + snowfall)).
pub fn seal(p: &SealParams, entries: &[[i32; 4]], terrain: &TerrainSource, tiles: &mut [u32]) {
    let side = p.side as i32;
    let area = (p.side * p.side) as usize;
    let planes = p.planes as usize;
    for e in entries {
        let base = e[2] as usize * planes * area;
        for k in 0..area {
            let g = [e[0] * side + (k as i32 % side), e[1] * side + (k as i32 / side)];
            let ground = texel_ground(terrain, g, p.texel_m);
            let lying = if p.flags & SealParams::USE_FALLEN != 0 { f32::from_bits(tiles[base + PLANE_FALLEN * area + k]) } else { 0.0 };
            tiles[base + PLANE_SNOW * area + k] ^= (ground + (p.depth_m + lying)).to_bits();
        }
    }
}
