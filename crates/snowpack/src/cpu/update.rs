//! CPU twin of `update.wgsl`.

use crate::deform::update::UpdateParams;

use super::stamp::{height, STAMP_EMPTY};
use super::window::storage_index;

/// Updates the toroidal `snow` (and refills `stamps`) in place from
/// window-local `capture_depth`.
pub fn update(p: &UpdateParams, capture_depth: &[f32], terrain: &[f32], snow: &mut [f32], stamps: &mut [u32]) {
    let r = p.resolution;
    for i in 0..r {
        for j in 0..r {
            let s = storage_index(p.origin, r, i, j);
            let ground = terrain[s];
            let rest = ground + p.depth_m;
            let mut h = (snow[s] + p.refill_m).min(rest);
            if p.flags & UpdateParams::USE_CAPTURE != 0 {
                let d = capture_depth[(i * r + j) as usize];
                if d < 1.0 {
                    let actor = p.low_m + d * (p.high_m - p.low_m);
                    h = h.min(ground.max(actor));
                }
            }
            let st = stamps[s];
            if st != STAMP_EMPTY {
                let (hq, fq) = (st >> 16, st & 0xffff);
                if p.flags & UpdateParams::USE_STAMPS != 0 {
                    h = h.min(ground.max(height(hq, p.low_m, p.high_m)));
                }
                if p.refill_quanta > 0 {
                    let foot = fq + p.refill_quanta;
                    stamps[s] = if foot > 65535 || height(foot, p.low_m, p.high_m) >= rest {
                        STAMP_EMPTY
                    } else {
                        ((hq + p.refill_quanta).min(65535) << 16) | foot
                    };
                }
            }
            snow[s] = h.max(ground);
        }
    }
}
