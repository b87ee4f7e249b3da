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
//! - spheres: the capsule around the centre's segment, exactly (ray cast by
//!   `capture_shapes.wgsl`);
//! - boxes: sub-steps, centre interpolated linearly and rotation by slerp, as
//!   many as make consecutive poses' corners move at most one texel
//!   (`snowpack_share::replicate::press::sweep`);
//! - meshes (skinned characters, caller meshes): the same sub-steps, each
//!   vertex interpolated linearly between its two positions
//!   (`capture_mesh.wgsl`, `vs_swept`);
//! - wheels: sub-steps of centre, axle and roll, as many as keep the tyre
//!   and its tread at the contact within a texel between consecutive poses
//!   (`snowpack_share::replicate::press::wheel`); each
//!   pose ray cast exactly (`capture_shapes.wgsl`);
//! - contact points (the points technique): segments; the footprint is the
//!   lowest of the paraboloids along the segment, found in closed form
//!   (`stamp.wgsl`).
//!
//! [`SnowParams::teleport_m`]: super::params::SnowParams::teleport_m
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use glam::{Mat3, Vec3};

use crate::Deformer;

pub use snowpack_share::replicate::press::sweep::steps_for;

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

/// Hashes a deformer id with one multiplication (ids are the caller's
/// numbers or indices, not chosen by an adversary): looking thousands of
/// deformers up each frame costs a few nanoseconds each, not SipHash's tens.
#[derive(Clone, Copy, Debug, Default)]
pub struct IdHasher(u64);

impl std::hash::Hasher for IdHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u64(&mut self, id: u64) {
        // Fibonacci hashing: the high bits, which the table uses, depend on every bit of the id.
        self.0 = (self.0.rotate_left(5) ^ id).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

/// The deformers of the last frame, by id, to sweep this frame's from.
#[derive(Clone, Debug, Default)]
pub struct DeformerHistory {
    /// Last frame's deformers when it gave them ids ([`id_of`]).
    previous: std::collections::HashMap<u64, Deformer, std::hash::BuildHasherDefault<IdHasher>>,
    /// Last frame's deformers when it gave no ids: deformer k has id k, so
    /// they are kept by index (no hashing); `previous` is then empty.
    by_index: Vec<Deformer>,
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
    #[cfg(test)]
    #[must_use]
    pub fn sweeps(&self, current: &[Deformer], ids: &[u64], teleport_m: f32) -> Vec<Option<Deformer>> {
        let mut out = Vec::new();
        self.sweeps_into(current, ids, teleport_m, &mut out);
        out
    }

    /// The sweeps (`sweeps` in the tests) into `out` (cleared first), reusing its memory.
    pub fn sweeps_into(&self, current: &[Deformer], ids: &[u64], teleport_m: f32, out: &mut Vec<Option<Deformer>>) {
        out.clear();
        out.extend(current.iter().enumerate().map(|(k, cur)| {
            let id = id_of(ids, current.len(), k);
            let prev = match usize::try_from(id) {
                Ok(index) if self.previous.is_empty() => self.by_index.get(index)?,
                _ => self.previous.get(&id)?,
            };
            (teleport_m > 0.0 && same_body(prev, cur) && anchor(prev).distance(anchor(cur)) <= teleport_m).then_some(*prev)
        }));
    }

    /// Keeps `current` (with `ids` as in [`Self::sweeps`]) as the previous
    /// frame's deformers; a repeated id keeps its last deformer.
    pub fn remember(&mut self, current: &[Deformer], ids: &[u64]) {
        self.previous.clear();
        self.by_index.clear();
        if ids.len() == current.len() && !current.is_empty() {
            self.previous.extend(current.iter().enumerate().map(|(k, d)| (id_of(ids, current.len(), k), *d)));
        } else {
            self.by_index.extend_from_slice(current);
        }
    }

    /// Moves every remembered deformer by `delta` (m): the floating origin
    /// moved by `-delta`, so positions relative to it shift by `delta`.
    pub fn shift(&mut self, delta: Vec3) {
        for d in self.previous.values_mut().chain(&mut self.by_index) {
            match d {
                Deformer::Sphere { center, .. } | Deformer::Box { center, .. } | Deformer::Wheel { center, .. } => *center += delta,
                Deformer::Point { position, .. } => *position += delta,
            }
        }
    }
}

/// The bind positions one joint of a skin moves, as a sphere: the centre and
/// radius (mesh space) around every vertex with a weight on that joint.
/// A joint that moves no vertex has radius `-1` and is left out of
/// [`skinned_travel`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointReach {
    /// Centre of the sphere (mesh space).
    pub center: Vec3,
    /// Radius of the sphere; negative when the joint moves no vertex.
    pub radius: f32,
}

impl JointReach {
    /// Per joint of a skin of `joint_count` joints, the sphere around the
    /// bind positions it moves (a weight above zero).
    #[must_use]
    pub fn of_skin(positions: &[Vec3], joints: &[[u16; 4]], weights: &[[f32; 4]], joint_count: usize) -> Vec<Self> {
        // The joints a vertex's weights give a share of its position.
        fn moved_by<'a>(ids: &'a [u16; 4], w: &'a [f32; 4]) -> impl Iterator<Item = usize> + 'a {
            ids.iter().zip(w).filter(|(_, w)| **w != 0.0).map(|(j, _)| usize::from(*j))
        }
        let mut boxes = vec![(Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)); joint_count];
        for ((p, ids), w) in positions.iter().zip(joints).zip(weights) {
            for j in moved_by(ids, w) {
                if let Some(b) = boxes.get_mut(j) {
                    *b = (b.0.min(*p), b.1.max(*p));
                }
            }
        }
        let mut reach: Vec<Self> = boxes.iter().map(|b| Self { center: (b.0 + b.1) * 0.5, radius: if b.0.x <= b.1.x { 0.0 } else { -1.0 } }).collect();
        for ((p, ids), w) in positions.iter().zip(joints).zip(weights) {
            for j in moved_by(ids, w) {
                if let Some(r) = reach.get_mut(j) {
                    r.radius = r.radius.max(p.distance(r.center));
                }
            }
        }
        reach
    }
}

/// Upper bound on how far any vertex of a linear-blend-skinned mesh moves
/// between two poses. A vertex is a convex combination of its joints'
/// transforms of its bind position `v`, so it moves at most as far as `v`
/// does under the joint that moves it most. Under joint `j`, with `v = c + u`
/// inside the joint's [`JointReach`] sphere (`|u| <= r`), that is at most
/// `|ΔM c| + |ΔA| r`: the travel of the sphere's centre plus the change of
/// the joint's linear part (Frobenius norm) times the radius. Measured from
/// each joint's own vertices, not the whole mesh's, the bound stays near the
/// true travel: a fox's swinging paw no longer counts as its whole body
/// swinging, which drew a walking fox 16 to 28 times a frame instead of 2 to 5.
/// `previous` and `current` are the joints' world matrices (model x joint).
#[must_use]
pub fn skinned_travel(previous: &[glam::Mat4], current: &[glam::Mat4], reach: &[JointReach]) -> f32 {
    previous
        .iter()
        .zip(current)
        .zip(reach)
        .filter(|(_, r)| r.radius >= 0.0)
        .map(|((a, b), r)| {
            let d = *b - *a;
            let linear = Mat3::from_mat4(d);
            let frob = (linear.x_axis.length_squared() + linear.y_axis.length_squared() + linear.z_axis.length_squared()).sqrt();
            // The centre's travel, ΔA c + ΔT (d is not affine: its last row is 0).
            (linear * r.center + d.w_axis.truncate()).length() + frob * r.radius
        })
        .fold(0.0, f32::max)
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let v = Vec3::new(2.0, 0.0, 0.0);
        let reach = JointReach::of_skin(&[v], &[[0, 1, 0, 0]], &[[0.5, 0.5, 0.0, 0.0]], 2);
        let bound = skinned_travel(&a, &b, &reach);
        for (p, q) in a.iter().zip(&b) {
            assert!(p.transform_point3(v).distance(q.transform_point3(v)) <= bound + 1e-6);
        }
        assert!(bound < 1.2, "{bound}");
    }

    /// Random skins and pose changes: no vertex moves farther than the bound,
    /// and a joint far from the vertices it moves does not inflate it.
    #[test]
    fn skinned_travel_bounds_random_skins() {
        let mut seed = 0x9e37_79b9_u32;
        let mut rand = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        };
        let mut rvec = |s: f32| Vec3::new(rand() - 0.5, rand() - 0.5, rand() - 0.5) * 2.0 * s;
        for _ in 0..50 {
            let joint_count = 5;
            let positions: Vec<Vec3> = (0..40).map(|_| rvec(3.0)).collect();
            let joints: Vec<[u16; 4]> = (0..40).map(|k| [(k % 4) as u16, ((k / 4) % 4) as u16, 0, 4]).collect();
            let weights: Vec<[f32; 4]> = (0..40).map(|k| if k % 3 == 0 { [1.0, 0.0, 0.0, 0.0] } else { [0.6, 0.3, 0.1, 0.0] }).collect();
            let pose = |r: &mut dyn FnMut(f32) -> Vec3| -> Vec<glam::Mat4> {
                (0..joint_count)
                    .map(|_| glam::Mat4::from_scale_rotation_translation(Vec3::ONE + r(0.05), glam::Quat::from_scaled_axis(r(0.4)), r(2.0)))
                    .collect()
            };
            let (a, b) = (pose(&mut rvec), pose(&mut rvec));
            let reach = JointReach::of_skin(&positions, &joints, &weights, joint_count);
            assert!(reach[4].radius < 0.0, "joint 4 has only zero weights");
            let bound = skinned_travel(&a, &b, &reach);
            let skin = |m: &[glam::Mat4], k: usize| -> Vec3 {
                joints[k].iter().zip(weights[k]).map(|(j, w)| m[usize::from(*j)].transform_point3(positions[k]) * w).sum()
            };
            for k in 0..positions.len() {
                let moved = skin(&a, k).distance(skin(&b, k));
                assert!(moved <= bound * (1.0 + 1e-5) + 1e-5, "vertex {k} moved {moved} > bound {bound}");
            }
        }
        // One vertex far from the origin, on a joint that turns about it: the
        // bound is its own small motion, not the turn times the mesh's radius.
        let far = Vec3::new(100.0, 0.0, 0.0);
        let reach = JointReach::of_skin(&[far], &[[0, 0, 0, 0]], &[[1.0, 0.0, 0.0, 0.0]], 1);
        let turn = glam::Mat4::from_translation(far) * glam::Mat4::from_rotation_y(0.1) * glam::Mat4::from_translation(-far);
        assert!(skinned_travel(&[glam::Mat4::IDENTITY], &[turn], &reach) < 1e-3);
    }
}
