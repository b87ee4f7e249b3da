//! What the capture captures in one frame: its range ([`CaptureParams`]),
//! the analytic shapes of the frame's deformers, window-local and swept over
//! their motion ([`CaptureInstances`]), and the world-space meshes
//! ([`SweptMesh`]). [`super::capture::CapturePass`] records them.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use bytemuck::{Pod, Zeroable};
use glam::{DVec2, Vec3};
use snowpack_share::replicate::press::{ShapeInstances, ShapeSweep};

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
    /// The analytic shapes' motions the lists above were cut from, in
    /// order: what shared snow sends instead of the snow they pressed
    /// ([`snowpack_share::replicate::press::PressFrame`]).
    pub sweeps: Vec<ShapeSweep>,
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
        let mut shapes =
            ShapeInstances { capsules: std::mem::take(&mut self.capsules), boxes: std::mem::take(&mut self.boxes), wheels: std::mem::take(&mut self.wheels) };
        shapes.clear();
        self.sweeps.clear();
        let local = |c: Vec3| Vec3::new((f64::from(c.x) - window_corner_m.x) as f32, c.y, (f64::from(c.z) - window_corner_m.y) as f32);
        for (k, d) in deformers.iter().enumerate() {
            let prev = previous.get(k).copied().flatten();
            if d.lowest_point().min(prev.map_or(f32::INFINITY, |p| p.lowest_point())) >= params.high_m {
                continue;
            }
            let Some(sweep) = shape_sweep(d, prev.as_ref(), local) else { continue };
            if sweep.touches_window(params.extent_m, params.texel_m) {
                sweep.expand_into(params.texel_m, &mut shapes);
                self.sweeps.push(sweep);
            }
        }
        (self.capsules, self.boxes, self.wheels) = (shapes.capsules, shapes.boxes, shapes.wheels);
    }
}

/// Deformer `d`'s motion from `prev` (last frame's pose of the same body,
/// when swept), window-local by `local`: `None` for a point, which has no
/// surface to capture (only the stamp pass uses it).
fn shape_sweep(d: &Deformer, prev: Option<&Deformer>, local: impl Fn(Vec3) -> Vec3) -> Option<ShapeSweep> {
    Some(match *d {
        Deformer::Sphere { center, radius } => {
            let b = local(center);
            let a = match prev {
                Some(Deformer::Sphere { center, .. }) => local(*center),
                _ => b,
            };
            ShapeSweep::Capsule { a, b, radius }
        }
        Deformer::Box { center, half_extents, rotation } => {
            let then = match prev {
                Some(Deformer::Box { center, half_extents, rotation }) => Some((local(*center), *half_extents, *rotation)),
                _ => None,
            };
            ShapeSweep::Box { then, now: (local(center), half_extents, rotation) }
        }
        Deformer::Wheel { center, axle, radius, half_width, tread, roll_m } => {
            let then = prev.and_then(Deformer::wheel_pose).map(|(c, a, roll)| (local(c), a, roll));
            ShapeSweep::Wheel { then, now: (local(center), axle, roll_m), radius, half_width, tread }
        }
        Deformer::Point { .. } => return None,
    })
}
