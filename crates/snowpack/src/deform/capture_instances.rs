//! What the capture captures in one frame: its range ([`CaptureParams`]),
//! the analytic shapes of the frame's deformers, window-local and swept over
//! their motion ([`CaptureInstances`]), and the world-space meshes
//! ([`SweptMesh`]). [`super::capture::CapturePass`] records them.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use bytemuck::{Pod, Zeroable};
use glam::{DVec2, Mat4, Vec3};

use crate::Deformer;
use crate::deform::shape::DeformerExt;

/// What a capture covers: the window, its texels and the height range of
/// its depth (`capture_mesh.wgsl`'s uniforms; [`super::capture_shapes::ShapeParams`] carries the same).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct CaptureParams {
    /// Side of the window (m).
    pub extent_m: f32,
    /// Texel size (m).
    pub texel_m: f32,
    /// World height at depth 0 (m).
    pub low_m: f32,
    /// World height at depth 1 (m).
    pub high_m: f32,
}

impl CaptureParams {
    /// World height of a captured depth value; `None` for the cleared value 1.
    #[must_use]
    pub fn height_of_depth(&self, depth: f32) -> Option<f32> {
        (depth < 1.0).then_some(self.low_m + depth * (self.high_m - self.low_m))
    }
}

/// Instances prepared for one frame, in window-local coordinates.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CaptureInstances {
    /// Per sphere, swept from `a` (last frame) to `b` (this frame):
    /// `[ax, ay, az, radius, bx, by, bz, 0]`, x and z relative to the
    /// window's corner; `a == b` for a sphere that is not swept.
    pub capsules: Vec<[f32; 8]>,
    /// Column-major model matrix per box (and per sub-step of a swept box),
    /// mapping the unit cube to window-local space.
    pub boxes: Vec<[f32; 16]>,
    /// Per wheel pose (and per sub-step of a swept wheel), window-local:
    /// see [`super::wheel::instance`].
    pub wheels: Vec<[f32; 16]>,
    /// World (x, z) of the window's corner (window-local 0, 0), relative to
    /// the floating origin, for meshes given in world space.
    pub corner_m: [f32; 2],
    /// Sub-steps of each world-space mesh drawn with
    /// [`super::capture::CapturePass::record`], in order (0: its current pose only).
    pub mesh_steps: Vec<u32>,
}

/// A triangle mesh already in world space this frame (a skinned character in
/// pose, from [`crate::skin::skinning::SkinningPass`]), drawn into the capture.
#[derive(Clone, Copy, Debug)]
pub struct CaptureMesh<'a> {
    /// World positions, packed xyz f32 (12 bytes a vertex), with `VERTEX` usage.
    pub vertices: &'a wgpu::Buffer,
    /// Triangle list, u32 indices, with `INDEX` usage.
    pub indices: &'a wgpu::Buffer,
    /// Number of indices to draw.
    pub index_count: u32,
    /// Number of vertices, each also drawn as a point (`capture_draw.rs`).
    pub vertex_count: u32,
}

/// A world-space mesh with the positions its vertices had last frame: drawn
/// at `steps` sub-steps between them (see `crate::deform::sweep`), plus
/// this frame's pose.
#[derive(Clone, Copy, Debug)]
pub struct SweptMesh<'a> {
    /// This frame's mesh.
    pub mesh: CaptureMesh<'a>,
    /// Last frame's positions of the same vertices (same layout); `None`
    /// draws only this frame's pose.
    pub previous: Option<&'a wgpu::Buffer>,
}

impl CaptureInstances {
    /// Window-local instances of the deformers that can touch the window:
    /// footprint overlapping it and lowest point below `high_m`. Nothing is
    /// swept.
    #[must_use]
    pub fn new(deformers: &[Deformer], window_corner_m: DVec2, params: &CaptureParams) -> Self {
        Self::swept(deformers, &[], window_corner_m, params)
    }

    /// Like [`Self::new`], sweeping deformer k from `previous[k]` where it is
    /// `Some` (see `crate::deform::sweep::DeformerHistory::sweeps`): spheres
    /// as capsules, boxes in sub-steps.
    #[must_use]
    pub fn swept(deformers: &[Deformer], previous: &[Option<Deformer>], window_corner_m: DVec2, params: &CaptureParams) -> Self {
        let mut out = Self::default();
        out.fill_swept(deformers, previous, window_corner_m, params);
        out
    }

    /// [`Self::swept`] into `self`, reusing its lists' memory (a frame
    /// after the first allocates nothing unless it has more instances);
    /// `mesh_steps` is left as it was.
    pub fn fill_swept(&mut self, deformers: &[Deformer], previous: &[Option<Deformer>], window_corner_m: DVec2, params: &CaptureParams) {
        self.corner_m = [window_corner_m.x as f32, window_corner_m.y as f32];
        self.capsules.clear();
        self.boxes.clear();
        self.wheels.clear();
        let out = self;
        let extent = f64::from(params.extent_m);
        let local = |c: Vec3| Vec3::new((f64::from(c.x) - window_corner_m.x) as f32, c.y, (f64::from(c.z) - window_corner_m.y) as f32);
        // Whether the square of half-side `reach` around the segment a..b misses the window.
        let outside = |a: Vec3, b: Vec3, reach: f32| {
            let reach = f64::from(reach);
            let (x0, x1) = (f64::from(a.x.min(b.x)) - reach, f64::from(a.x.max(b.x)) + reach);
            let (z0, z1) = (f64::from(a.z.min(b.z)) - reach, f64::from(a.z.max(b.z)) + reach);
            x1 < 0.0 || x0 > extent || z1 < 0.0 || z0 > extent
        };
        for (k, d) in deformers.iter().enumerate() {
            let prev = previous.get(k).copied().flatten();
            if d.lowest_point().min(prev.map_or(f32::INFINITY, |p| p.lowest_point())) >= params.high_m {
                continue;
            }
            match (*d, prev) {
                (Deformer::Sphere { center, radius }, prev) => {
                    let b = local(center);
                    let a = match prev {
                        Some(Deformer::Sphere { center, .. }) => local(center),
                        _ => b,
                    };
                    if !outside(a, b, radius) && radius > 0.0 {
                        out.capsules.push([a.x, a.y, a.z, radius, b.x, b.y, b.z, 0.0]);
                    }
                }
                (Deformer::Box { center, half_extents, rotation }, prev) => {
                    let now = (local(center), half_extents, rotation);
                    // From `then` in `steps` sub-steps (see `box_poses`), or `now` alone.
                    let (then, steps) = match prev {
                        Some(Deformer::Box { center, half_extents, rotation }) => {
                            let then = (local(center), half_extents, rotation);
                            (then, super::sweep::steps_for(super::sweep::box_travel(then, now), params.texel_m))
                        }
                        _ => (now, 0),
                    };
                    let first = if steps == 0 { now } else { super::sweep::box_pose(then, now, 0, steps) };
                    let reach = half_extents.length();
                    if !outside(first.0, now.0, reach) {
                        let matrix = |(c, h, q): (Vec3, Vec3, glam::Quat)| Mat4::from_scale_rotation_translation(h, q, c).to_cols_array();
                        if steps == 0 {
                            out.boxes.push(matrix(now));
                        } else {
                            out.boxes.extend((0..=steps).map(|k| matrix(super::sweep::box_pose(then, now, k, steps))));
                        }
                    }
                }
                (Deformer::Wheel { center, axle, radius, half_width, tread, roll_m }, prev) => {
                    use super::wheel;
                    let now = (local(center), axle, roll_m);
                    // From `then` in `steps` sub-steps (see `wheel_poses`), or `now` alone.
                    let (then, steps) = match prev.as_ref().and_then(Deformer::wheel_pose) {
                        Some((c, a, roll)) => {
                            let then = (local(c), a, roll);
                            (then, super::sweep::steps_for(wheel::wheel_travel(then, now, radius, half_width), params.texel_m))
                        }
                        None => (now, 0),
                    };
                    let first = if steps == 0 { now } else { wheel::wheel_pose(then, now, 0, steps) };
                    let reach = radius.hypot(half_width);
                    if !outside(first.0, now.0, reach) && radius > 0.0 && half_width > 0.0 {
                        let instance = |(c, a, roll): wheel::WheelPose| wheel::instance(c, a, radius, half_width, &tread, f64::from(roll));
                        if steps == 0 {
                            out.wheels.push(instance(now));
                        } else {
                            out.wheels.extend((0..=steps).map(|k| instance(wheel::wheel_pose(then, now, k, steps))));
                        }
                    }
                }
                // Points have no surface to draw; only the stamp pass uses them.
                (Deformer::Point { .. }, _) => {}
            }
        }
    }
}
