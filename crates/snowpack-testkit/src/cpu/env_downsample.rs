//! CPU twin of `shaders/env_downsample.wgsl`: the environment map box-averaged
//! to the size the prefilter reads.

use glam::Vec3;

/// Box-averages `src` (`sw` x `sh`) into `dw` x `dh`, each texel's luminance clamped to `clamp_luminance`.
#[must_use]
pub fn downsample(src: &[[f32; 4]], sw: u32, sh: u32, dw: u32, dh: u32, clamp_luminance: f32) -> Vec<[f32; 4]> {
    let mut out = Vec::with_capacity((dw * dh) as usize);
    for y in 0..dh {
        for x in 0..dw {
            let (x0, x1) = (x * sw / dw, (x + 1) * sw / dw);
            let (y0, y1) = (y * sh / dh, (y + 1) * sh / dh);
            let mut sum = Vec3::ZERO;
            for sy in y0..y1 {
                for sx in x0..x1 {
                    let t = src[(sy * sw + sx) as usize];
                    let c = Vec3::new(t[0], t[1], t[2]);
                    let lum = c.dot(Vec3::new(0.2126, 0.7152, 0.0722));
                    sum += c * (clamp_luminance / lum.max(1e-6)).min(1.0);
                }
            }
            let n = ((x1 - x0) * (y1 - y0)) as f32;
            let c = sum / n;
            out.push([c.x, c.y, c.z, 1.0]);
        }
    }
    out
}
