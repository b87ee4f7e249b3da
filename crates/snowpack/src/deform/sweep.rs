//! Swept deformers: each deformer presses the snow over its whole motion since
//! the last frame, not only where it stands now, so a trail does not depend on
//! the frame rate (a fast ball leaves a continuous trench, not a chain of
//! dimples).
//!
//! Deformers are identified across frames by an id: the caller's
//! ([`crate::SnowFrame::with_ids`]: a stable number per body, for lists whose
//! length or order changes, such as feet that are down) or, without ids,
//! their index in the frame's list (`deformers[k]` is the same body every
//! frame, as for the decal ring). The pair (previous, current) of a body is
//! swept when both are the same kind of shape of the same size and it moved
//! at most [`SnowParams::teleport_m`]; otherwise (a new body, a teleport, a
//! different shape) only the current pose presses.
//!
//! How each kind is swept:
//! - spheres: the capsule around the centre's segment, exactly (an analytic
//!   impostor, `capture_sphere.wgsl`);
//! - boxes: sub-steps, centre interpolated linearly and rotation by slerp, as
//!   many as make consecutive poses' corners move at most [`SWEEP_STEP_TEXELS`]
//!   texels ([`steps_for`], [`box_poses`]);
//! - meshes (skinned characters, caller meshes): the same sub-steps, each
//!   vertex interpolated linearly between its two positions
//!   (`capture_mesh.wgsl`, `vs_swept`);
//! - wheels: sub-steps of centre, axle and roll, as many as keep the tyre
//!   and its tread at the contact within a texel between consecutive poses
//!   ([`super::wheel::wheel_travel`], [`super::wheel::wheel_poses`]); each
//!   pose an exact impostor (`capture_wheel.wgsl`);
//! - contact points (the points technique): segments; the footprint is the
//!   lowest of the paraboloids along the segment, found in closed form
//!   (`stamp.wgsl`).
//!
//! [`SnowParams::teleport_m`]: super::params::SnowParams::teleport_m

use glam::{Mat3, Quat, Vec3};

use crate::Deformer;

/// Largest motion (texels) between consecutive sub-steps of a swept box or
/// mesh: one texel, so consecutive poses overlap to within a texel centre and
/// every texel the body crossed sees it at one sub-step or another. Spheres
/// and points are swept exactly and need no sub-steps.
pub const SWEEP_STEP_TEXELS: f32 = 1.0;

/// Most sub-steps one box or mesh is drawn with in a frame (plus its current
/// pose). With the default 4 m teleport distance and 6.25 cm texels a sweep
/// never needs more; beyond it the steps are spaced wider than a texel.
pub const MAX_SWEEP_STEPS: u32 = 64;

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
pub fn box_travel(a: (Vec3, Vec3, Quat), b: (Vec3, Vec3, Quat)) -> f32 {
    let corner = |(c, h, q): (Vec3, Vec3, Quat), s: Vec3| c + q * (h * s);
    let mut most = 0.0_f32;
    for k in 0..8 {
        let s = Vec3::new(if k & 1 == 0 { -1.0 } else { 1.0 }, if k & 2 == 0 { -1.0 } else { 1.0 }, if k & 4 == 0 { -1.0 } else { 1.0 });
        most = most.max(corner(a, s).distance(corner(b, s)));
    }
    most
}

/// The poses a box swept from `a` to `b` is drawn in: `steps` evenly spaced
/// poses after `a` up to and including `b`, plus `a` itself (which the last
/// frame drew already; drawn again so the sweep does not depend on it).
#[must_use]
pub fn box_poses(a: (Vec3, Vec3, Quat), b: (Vec3, Vec3, Quat), steps: u32) -> Vec<(Vec3, Vec3, Quat)> {
    let n = steps.max(1);
    (0..=n)
        .map(|k| {
            let t = k as f32 / n as f32;
            (a.0.lerp(b.0, t), a.1.lerp(b.1, t), a.2.slerp(b.2, t).normalize())
        })
        .collect()
}

/// Where a deformer is, for the teleport test: its centre (or point).
fn anchor(d: &Deformer) -> Vec3 {
    match *d {
        Deformer::Sphere { center, .. } | Deformer::Box { center, .. } | Deformer::Wheel { center, .. } => center,
        Deformer::Point { position, .. } => position,
    }
}

/// Whether `prev` and `cur` are the same body moved (same kind and size).
fn same_body(prev: &Deformer, cur: &Deformer) -> bool {
    match (prev, cur) {
        (Deformer::Sphere { radius: a, .. }, Deformer::Sphere { radius: b, .. }) => a == b,
        (Deformer::Box { half_extents: a, .. }, Deformer::Box { half_extents: b, .. }) => a == b,
        (Deformer::Point { scale_per_m: a, .. }, Deformer::Point { scale_per_m: b, .. }) => a == b,
        (Deformer::Wheel { radius: r0, half_width: w0, tread: t0, .. }, Deformer::Wheel { radius: r1, half_width: w1, tread: t1, .. }) => {
            r0 == r1 && w0 == w1 && t0 == t1
        }
        _ => false,
    }
}

/// The deformers of the last frame, by id, to sweep this frame's from.
#[derive(Clone, Debug, Default)]
pub struct DeformerHistory {
    previous: std::collections::HashMap<u64, Deformer>,
}

/// The id of deformer `k`: `ids[k]` when the caller gave one per deformer, else `k`.
fn id_of(ids: &[u64], count: usize, k: usize) -> u64 {
    if ids.len() == count { ids[k] } else { k as u64 }
}

impl DeformerHistory {
    /// A history with no previous frame (nothing sweeps on the next one).
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// For each of `current`, the pose to sweep it from: `Some` where the
    /// body with its id (`ids[k]`, or k when `ids` does not have one per
    /// deformer) existed last frame as the same shape and moved at most
    /// `teleport_m` (`teleport_m <= 0` sweeps nothing).
    #[must_use]
    pub fn sweeps(&self, current: &[Deformer], ids: &[u64], teleport_m: f32) -> Vec<Option<Deformer>> {
        current
            .iter()
            .enumerate()
            .map(|(k, cur)| {
                let prev = self.previous.get(&id_of(ids, current.len(), k))?;
                (teleport_m > 0.0 && same_body(prev, cur) && anchor(prev).distance(anchor(cur)) <= teleport_m).then_some(*prev)
            })
            .collect()
    }

    /// Keeps `current` (with `ids` as in [`Self::sweeps`]) as the previous
    /// frame's deformers; a repeated id keeps its last deformer.
    pub fn remember(&mut self, current: &[Deformer], ids: &[u64]) {
        self.previous.clear();
        self.previous.extend(current.iter().enumerate().map(|(k, d)| (id_of(ids, current.len(), k), *d)));
    }

    /// Moves every remembered deformer by `delta` (m): the floating origin
    /// moved by `-delta`, so positions relative to it shift by `delta`.
    pub fn shift(&mut self, delta: Vec3) {
        for d in self.previous.values_mut() {
            match d {
                Deformer::Sphere { center, .. } | Deformer::Box { center, .. } | Deformer::Wheel { center, .. } => *center += delta,
                Deformer::Point { position, .. } => *position += delta,
            }
        }
    }

    /// Forgets the previous frame (the next frame sweeps nothing).
    pub fn clear(&mut self) {
        self.previous.clear();
    }
}

/// Upper bound on how far any vertex of a linear-blend-skinned mesh moves
/// between two poses: each vertex is a convex combination of its joints'
/// transforms of a bind position `v` with `|v| <= radius`, so it moves at most
/// the largest `|ΔT_j| + |ΔA_j| radius` over the joints (ΔT the change of the
/// joint's world translation, ΔA of its linear part, Frobenius norm).
/// `previous` and `current` are the joints' world matrices (model x joint).
#[must_use]
pub fn skinned_travel(previous: &[glam::Mat4], current: &[glam::Mat4], radius: f32) -> f32 {
    previous
        .iter()
        .zip(current)
        .map(|(a, b)| {
            let d = *b - *a;
            let linear = Mat3::from_mat4(d);
            let frob = (linear.x_axis.length_squared() + linear.y_axis.length_squared() + linear.z_axis.length_squared()).sqrt();
            d.w_axis.truncate().length() + frob * radius
        })
        .fold(0.0, f32::max)
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

    #[test]
    fn history_sweeps_the_same_body_and_not_a_teleport() {
        let ball = |x: f32, r: f32| Deformer::Sphere { center: Vec3::new(x, 0.2, 0.0), radius: r };
        let mut h = DeformerHistory::new();
        assert_eq!(h.sweeps(&[ball(0.0, 0.2)], &[], 4.0), vec![None], "first frame");
        h.remember(&[ball(0.0, 0.2)], &[]);
        assert_eq!(h.sweeps(&[ball(0.5, 0.2), ball(1.0, 0.2)], &[], 4.0), vec![Some(ball(0.0, 0.2)), None]);
        assert_eq!(h.sweeps(&[ball(5.0, 0.2)], &[], 4.0), vec![None], "teleport");
        assert_eq!(h.sweeps(&[ball(0.5, 0.3)], &[], 4.0), vec![None], "another body");
        assert_eq!(h.sweeps(&[ball(0.5, 0.2)], &[], 0.0), vec![None], "sweeping off");
        h.shift(Vec3::new(-1.0, 0.0, 0.0));
        assert_eq!(h.sweeps(&[ball(0.0, 0.2)], &[], 4.0), vec![Some(ball(-1.0, 0.2))]);
        // With ids, a body is found wherever it is in the list.
        h.remember(&[ball(0.0, 0.2), ball(2.0, 0.2)], &[7, 9]);
        assert_eq!(h.sweeps(&[ball(2.1, 0.2), ball(3.0, 0.2)], &[9, 11], 4.0), vec![Some(ball(2.0, 0.2)), None]);
    }

    #[test]
    fn skinned_travel_bounds_every_vertex() {
        let a = [glam::Mat4::from_rotation_y(0.0), glam::Mat4::from_translation(Vec3::X)];
        let b = [glam::Mat4::from_rotation_y(0.3), glam::Mat4::from_translation(Vec3::new(1.0, 0.0, 0.5))];
        let bound = skinned_travel(&a, &b, 2.0);
        let v = Vec3::new(2.0, 0.0, 0.0);
        for (p, q) in a.iter().zip(&b) {
            assert!(p.transform_point3(v).distance(q.transform_point3(v)) <= bound + 1e-6);
        }
        assert!(bound < 1.2, "{bound}");
    }
}
