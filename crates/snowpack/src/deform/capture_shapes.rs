//! The capture's analytic shapes by compute (`capture_shapes.wgsl`): every
//! sphere swept over the frame (a capsule), tyre pose and box, ray cast
//! from below at each window texel's centre, without a rasteriser or a
//! depth target.
//!
//! The shapes go up as one list, five `vec4` each: the bounds of the texels
//! the shape can reach (window-local metres, half a texel wider than the
//! shape), then its data. Each workgroup takes a 16×16-texel tile, keeps
//! the shapes whose bounds reach it, 128 at a time, in workgroup memory, and
//! each invocation ray casts its two texels against that list only: the
//! cost is the window's texels times the shapes over them, not times all
//! shapes. The result is the capture depth's 16-bit code, two texels a word
//! (`res.capture_shapes`), the same code the depth target holds for the
//! meshes; the update reads the lower of both.
//!
//! A box is ray cast against its inverse model matrix, inverted here on the
//! CPU (as the twin does), so a box is exact too.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec4};

use crate::frame::FrameContext;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::shaders;

use super::resources::DeformResources;

/// Uniforms of `capture_shapes.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ShapeParams {
    /// Texel size (m).
    pub texel_m: f32,
    /// World height at depth 0 (m).
    pub low_m: f32,
    /// World height at depth 1 (m).
    pub high_m: f32,
    /// Texels per window side (a multiple of 16).
    pub resolution: u32,
    /// Capsules first in the list.
    pub capsules: u32,
    /// Tyre poses after them.
    pub wheels: u32,
    /// Boxes last.
    pub boxes: u32,
    /// Padding to 16 bytes.
    pub _pad: u32,
}

/// A frame's analytic shapes, window-local, as
/// [`super::capture::CaptureInstances`] lists them.
#[derive(Clone, Copy, Debug)]
pub struct Shapes<'a> {
    /// Per sphere swept over the frame: `[ax, ay, az, radius, bx, by, bz, 0]`.
    pub capsules: &'a [[f32; 8]],
    /// Per tyre pose: [`super::wheel::instance`].
    pub wheels: &'a [[f32; 16]],
    /// Per box pose: its column-major model matrix (of the unit cube).
    pub boxes: &'a [[f32; 16]],
}

impl Shapes<'_> {
    /// How many shapes there are.
    #[must_use]
    pub fn count(&self) -> usize {
        self.capsules.len() + self.wheels.len() + self.boxes.len()
    }
}

/// `vec4`s a shape takes in the list: its bounds, then four of data.
const SHAPE_VEC4S: usize = 5;

/// Texels per side of the tile a workgroup ray casts.
const TILE: u32 = 16;

/// The list `capture_shapes.wgsl` reads for `inst`: per
/// shape its bounds (x0, z0, x1, z1, half a texel wider than the shape),
/// then a capsule's two ends, a tyre's instance or a box's inverse matrix;
/// capsules, then tyres, then boxes. Appended to `out` (cleared first).
pub fn shape_list(inst: Shapes<'_>, texel_m: f32, out: &mut Vec<[f32; 4]>) {
    out.clear();
    out.reserve(SHAPE_VEC4S * inst.count());
    let pad = 0.5 * texel_m;
    let bounds = |x0: f32, z0: f32, x1: f32, z1: f32| [x0 - pad, z0 - pad, x1 + pad, z1 + pad];
    for c in inst.capsules {
        let r = c[3];
        out.push(bounds(c[0].min(c[4]) - r, c[2].min(c[6]) - r, c[0].max(c[4]) + r, c[2].max(c[6]) + r));
        out.extend([[c[0], c[1], c[2], c[3]], [c[4], c[5], c[6], c[7]], [0.0; 4], [0.0; 4]]);
    }
    for w in inst.wheels {
        let reach = w[3].hypot(w[7]);
        out.push(bounds(w[0] - reach, w[2] - reach, w[0] + reach, w[2] + reach));
        out.extend([[w[0], w[1], w[2], w[3]], [w[4], w[5], w[6], w[7]], [w[8], w[9], w[10], w[11]], [w[12], w[13], w[14], w[15]]]);
    }
    for m in inst.boxes {
        let model = Mat4::from_cols_array(m);
        // The unit cube's shadow: the centre plus each axis's reach.
        let (c, [a, b, d]) = (model.w_axis, [model.x_axis, model.y_axis, model.z_axis]);
        let reach = |k: usize| a[k].abs() + b[k].abs() + d[k].abs();
        out.push(bounds(c.x - reach(0), c.z - reach(2), c.x + reach(0), c.z + reach(2)));
        let inv = model.inverse();
        out.extend([inv.x_axis, inv.y_axis, inv.z_axis, inv.w_axis].map(|v: Vec4| v.to_array()));
    }
}

/// Ray casts the capture's analytic shapes into `res.capture_shapes` by
/// compute: see the module documentation.
pub struct ShapeCapturePass {
    pass: ComputePass<ShapeParams>,
    /// The shape list, grown to the largest frame's.
    shapes: wgpu::Buffer,
    /// This frame's list, kept for its memory.
    list: Vec<[f32; 4]>,
    /// The capture buffer the pass is bound to (a window's resources).
    bound: Option<wgpu::Buffer>,
}

impl ShapeCapturePass {
    /// Compiles the shader; binds on the first record.
    #[must_use]
    pub fn new(device: &wgpu::Device) -> Self {
        let shape = PassShape {
            label: "capture",
            source: shaders::CAPTURE_SHAPES,
            // the shape list, the capture
            slots: &[Slot::Read, Slot::ReadWrite],
            specialise_on: None,
            constants: &[],
            window: None,
        };
        Self { pass: ComputePass::new(device, &shape, None), shapes: shape_buffer(device, 256 * 80), list: Vec::new(), bound: None }
    }

    /// Records the ray cast of `inst` over the window of `res`, its depth
    /// linear in height from `low_m` (0) to `high_m` (1); returns whether it
    /// did (`false`: no shapes, nothing written or to read).
    pub fn record(&mut self, cx: &mut FrameContext<'_>, res: &DeformResources, [low_m, high_m]: [f32; 2], inst: Shapes<'_>) -> bool {
        if inst.count() == 0 {
            return false;
        }
        let texel_m = res.texel_m;
        let mut list = std::mem::take(&mut self.list);
        shape_list(inst, texel_m, &mut list);
        let bytes: &[u8] = bytemuck::cast_slice(&list);
        let grown = bytes.len() as u64 > self.shapes.size();
        if grown {
            self.shapes = shape_buffer(cx.device(), (bytes.len() as u64).next_power_of_two());
        }
        cx.queue().write_buffer(&self.shapes, 0, bytes);
        self.list = list;
        if grown || self.bound.as_ref() != Some(&res.capture_shapes) {
            self.pass.bind(cx.device(), &[self.shapes.as_entire_binding(), res.capture_shapes.as_entire_binding()]);
            self.bound = Some(res.capture_shapes.clone());
        }
        let u = ShapeParams {
            texel_m,
            low_m,
            high_m,
            resolution: res.resolution,
            capsules: inst.capsules.len() as u32,
            wheels: inst.wheels.len() as u32,
            boxes: inst.boxes.len() as u32,
            _pad: 0,
        };
        let groups = res.resolution / TILE;
        self.pass.record(cx, None, &u, 0, (groups, groups));
        true
    }
}

fn shape_buffer(device: &wgpu::Device, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("capture shapes list"),
        size: bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}
