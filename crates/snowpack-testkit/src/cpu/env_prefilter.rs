//! CPU twin of `shaders/env_prefilter.wgsl`, with the equirect mapping it
//! shares with the sky (`shared/frame.wgsl`'s `equirect_dir`, `dir_equirect`).

use glam::Vec3;

pub use snowpack::low_level::render::environment::{dir_equirect, equirect_dir};

/// Level 0: irradiance / pi; level k: GGX-prefiltered radiance for roughness
/// k / (levels - 1); each `dw` x `dh`, level-major.
#[must_use]
pub fn prefilter(src: &[[f32; 4]], sw: u32, sh: u32, dw: u32, dh: u32, levels: u32) -> Vec<[f32; 4]> {
    use std::f32::consts::PI;
    let mut out = Vec::with_capacity((dw * dh * levels) as usize);
    let texel_angle = (2.0 * PI / sw as f32) * (PI / sh as f32);
    for level in 0..levels {
        let roughness = level as f32 / (levels - 1) as f32;
        let a = roughness * roughness;
        let a2 = a * a;
        for y in 0..dh {
            for x in 0..dw {
                let n = equirect_dir((x as f32 + 0.5) / dw as f32, (y as f32 + 0.5) / dh as f32);
                let mut sum = Vec3::ZERO;
                let mut weight = 0.0f32;
                for sy in 0..sh {
                    let v = (sy as f32 + 0.5) / sh as f32;
                    let solid_angle = texel_angle * (v * PI).sin();
                    for sx in 0..sw {
                        let l = equirect_dir((sx as f32 + 0.5) / sw as f32, v);
                        let n_l = n.dot(l);
                        if n_l <= 0.0 {
                            continue;
                        }
                        let mut w = n_l * solid_angle;
                        if level > 0 {
                            let dd = n_l * n_l * (a2 - 1.0) + 1.0;
                            w *= a2 / (PI * dd * dd);
                        }
                        let t = src[(sy * sw + sx) as usize];
                        sum += Vec3::new(t[0], t[1], t[2]) * w;
                        weight += w;
                    }
                }
                let c = if level > 0 { sum / weight.max(1e-12) } else { sum / PI };
                out.push([c.x, c.y, c.z, 1.0]);
            }
        }
    }
    out
}
