//! CPU twin of `shaders/ao.wgsl`: height-field ambient occlusion.

/// The 8 march directions (column, row steps), as in the shader.
const DIRS: [(i32, i32); 8] = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)];

/// Ambient occlusion (1 open, lower occluded) per texel of a `res`² height
/// field (row-major, row = +z), marching `steps` distances of 2^k texels.
#[must_use]
pub fn ambient_occlusion(heights: &[f32], res: u32, steps: u32, texel_m: f32, strength: f32) -> Vec<f32> {
    let r = res as i32;
    let at = |i: i32, j: i32| heights[(i.clamp(0, r - 1) * r + j.clamp(0, r - 1)) as usize];
    let mut out = vec![0.0; heights.len()];
    for i in 0..r {
        for j in 0..r {
            let h0 = at(i, j);
            let mut occluded = 0.0f32;
            for &(dx, dy) in &DIRS {
                let unit = if dx != 0 && dy != 0 { std::f32::consts::SQRT_2 } else { 1.0 } * texel_m;
                let mut slope = 0.0f32;
                for k in 0..steps {
                    let step = 1i32 << k;
                    let rise = at(i + dy * step, j + dx * step) - h0;
                    slope = slope.max(rise / (step as f32 * unit));
                }
                occluded += slope * slope / (1.0 + slope * slope);
            }
            out[(i * r + j) as usize] = 1.0 - strength * occluded / 8.0;
        }
    }
    out
}
