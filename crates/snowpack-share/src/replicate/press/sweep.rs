//! How a swept shape is cut into sub-steps: boxes and wheels are ray cast
//! in poses spaced at most [`SWEEP_STEP_TEXELS`] apart between last
//! frame's pose and this frame's (snowpack's `deform::sweep` describes each
//! kind; skinned meshes use the same spacing). Every machine that presses
//! a [`super::ShapeSweep`] cuts it here, so the poses are the same bit for bit.

use glam::{Quat, Vec3};

/// Largest motion (texels) between consecutive sub-steps of a swept box or
/// mesh: one texel, so consecutive poses overlap to within a texel centre and
/// every texel the body crossed sees it at one sub-step or another. Spheres
/// and points are swept exactly and need no sub-steps.
pub const SWEEP_STEP_TEXELS: f32 = 1.0;

/// Most sub-steps one box or mesh is drawn with in a frame (plus its current
/// pose). With the default 4 m teleport distance and 6.25 cm texels a sweep
/// never needs more; beyond it the steps are spaced wider than a texel.
pub const MAX_SWEEP_STEPS: u32 = 64;

/// A box's pose: centre, half extents, rotation.
pub type BoxPose = (Vec3, Vec3, Quat);

/// Sub-steps for a motion of `travel_m` at `texel_m` (0: not swept).
#[must_use]
pub fn steps_for(travel_m: f32, texel_m: f32) -> u32 {
    if !(travel_m.is_finite() && travel_m > 0.0 && texel_m > 0.0) {
        return 0;
    }
    ((travel_m / (texel_m * SWEEP_STEP_TEXELS)).ceil() as u32).clamp(1, MAX_SWEEP_STEPS)
}

/// Farthest any corner of a box moves between two poses (m).
#[must_use]
pub fn box_travel(a: BoxPose, b: BoxPose) -> f32 {
    let corner = |(c, h, q): BoxPose, s: Vec3| c + q * (h * s);
    let mut most = 0.0_f32;
    for k in 0..8 {
        let s = Vec3::new(if k & 1 == 0 { -1.0 } else { 1.0 }, if k & 2 == 0 { -1.0 } else { 1.0 }, if k & 4 == 0 { -1.0 } else { 1.0 });
        most = most.max(corner(a, s).distance(corner(b, s)));
    }
    most
}

/// Pose `k` (0 ..= `steps`, 0 being `a`, the last `b`) of a box swept from
/// `a` to `b` in `steps` steps.
#[must_use]
pub fn box_pose(a: BoxPose, b: BoxPose, k: u32, steps: u32) -> BoxPose {
    let t = k as f32 / steps.max(1) as f32;
    (a.0.lerp(b.0, t), a.1.lerp(b.1, t), a.2.slerp(b.2, t).normalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_follow_the_motion_in_texels() {
        assert_eq!(steps_for(0.0, 0.0625), 0);
        assert_eq!(steps_for(0.01, 0.0625), 1);
        assert_eq!(steps_for(0.2, 0.0625), 4);
        assert_eq!(steps_for(100.0, 0.0625), MAX_SWEEP_STEPS);
    }
}
