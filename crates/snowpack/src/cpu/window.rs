//! CPU twin of `window.wgsl`.

use crate::deform::window::{TexelRect, WindowParams};
use crate::TerrainSource;

/// Toroidal storage index of window-local texel (i, j).
#[must_use]
pub fn storage_index(origin: [i32; 2], res: u32, i: u32, j: u32) -> usize {
    let r = res as i32;
    let si = (origin[1] + i as i32).rem_euclid(r) as usize;
    let sj = (origin[0] + j as i32).rem_euclid(r) as usize;
    si * res as usize + sj
}

/// Writes terrain and fresh snow (with the snowfall so far) into the texels
/// of `rects` and clears their footprints.
pub fn expose(
    p: &WindowParams,
    rects: &[TexelRect],
    terrain_src: &TerrainSource,
    terrain: &mut [f32],
    snow: &mut [f32],
    stamps: &mut [u32],
    fallen: &mut [f32],
) {
    for rect in rects.iter().take(2) {
        for i in rect[0]..rect[0] + rect[2] {
            for j in rect[1]..rect[1] + rect[3] {
                let s = storage_index(p.origin, p.resolution, i, j);
                let x = ((p.origin[0] + j as i32) as f32 + 0.5) * p.texel_m;
                let z = ((p.origin[1] + i as i32) as f32 + 0.5) * p.texel_m;
                let ground = terrain_src.height_at(x, z);
                terrain[s] = ground;
                snow[s] = ground + p.depth_m + p.fallen_m;
                if p.flags & WindowParams::WRITE_STAMPS != 0 {
                    stamps[s] = super::stamp::STAMP_EMPTY;
                }
                if p.flags & WindowParams::WRITE_FALLEN != 0 {
                    fallen[s] = p.fallen_m;
                }
            }
        }
    }
}
