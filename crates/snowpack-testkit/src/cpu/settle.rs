//! CPU twin of `settle.wgsl`.

use glam::{Mat4, Vec3};

use snowpack::low_level::accumulate::SettleParams;
use snowpack::low_level::accumulate::atlas::NO_OWNER;

/// Dinh's Gaussian weights for offsets 0, 1 and 2.
const WEIGHTS: [f32; 3] = [0.227_027_03, 0.194_594_6, 0.121_621_62];

/// Adds the blurred increment `fresh` to `acc` and applies the slope
/// stability; `rotations` are the objects' rotations.
pub fn settle(p: &SettleParams, rotations: &[Mat4], normal_area: &[[f32; 4]], owner: &[u32], fresh: &[f32], acc: &mut [f32]) {
    let n = p.atlas_resolution as i32;
    for y in 0..n {
        for x in 0..n {
            let k = (y * n + x) as usize;
            let own = owner[k];
            if own == NO_OWNER {
                acc[k] = 0.0;
                continue;
            }
            let (mut sum, mut weight) = (0.0f32, 0.0f32);
            for dy in -2i32..=2 {
                for dx in -2i32..=2 {
                    let (sx, sy) = (x + dx, y + dy);
                    if sx < 0 || sy < 0 || sx >= n || sy >= n {
                        continue;
                    }
                    let m = (sy * n + sx) as usize;
                    if owner[m] != own {
                        continue;
                    }
                    let w = WEIGHTS[dx.unsigned_abs() as usize] * WEIGHTS[dy.unsigned_abs() as usize];
                    sum += w * fresh[m];
                    weight += w;
                }
            }
            let [nx, ny, nz, _] = normal_area[k];
            let up = rotations[own as usize].transform_vector3(Vec3::new(nx, ny, nz)).y;
            let mut a = 0.0;
            if up >= p.cos_repose {
                let t = ((up - p.cos_repose) / (p.cos_full - p.cos_repose).max(1e-6)).clamp(0.0, 1.0);
                a = acc[k] + t * sum / weight;
                let cap = p.max_m * up;
                if a > cap {
                    a -= (a - cap) * p.falloff;
                }
            }
            acc[k] = a.max(0.0);
        }
    }
}
