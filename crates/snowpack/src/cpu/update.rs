//! CPU twin of `update.wgsl`.

use crate::deform::update::UpdateParams;

use super::window::storage_index;

/// Updates the toroidal `snow` in place from window-local `capture_depth`.
pub fn update(p: &UpdateParams, capture_depth: &[f32], terrain: &[f32], snow: &mut [f32]) {
    let r = p.resolution;
    for i in 0..r {
        for j in 0..r {
            let s = storage_index(p.origin, r, i, j);
            let ground = terrain[s];
            let rest = ground + p.depth_m;
            let mut h = (snow[s] + p.refill_m).min(rest);
            let d = capture_depth[(i * r + j) as usize];
            if d < 1.0 {
                let actor = p.low_m + d * (p.high_m - p.low_m);
                h = h.min(ground.max(actor));
            }
            snow[s] = h.max(ground);
        }
    }
}
