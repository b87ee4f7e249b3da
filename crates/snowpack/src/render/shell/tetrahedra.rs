//! Shell construction, step 2 of 2 (`shaders/shell_tetrahedra.wgsl`): each
//! face's prism split into three tetrahedra by the vertex-index rule, with
//! their affine maps and the vertex-data indices that draw them.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::shaders;

/// Parameters of [`ShellTetraPass`] (`TetraParams` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct TetraParams {
    /// Faces (triangles) of the base mesh.
    pub faces: u32,
    /// Vertices of the base mesh.
    pub count: u32,
    /// Padding.
    pub _pad: [u32; 2],
}

/// A shell tetrahedron (`Tetra` in `shared/shell.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Tetra {
    /// Corner 0 (world); w: 1, or 0 if too flat for an accurate map
    /// ([`MAX_SHAPE_RATIO`]): then the map is zero and nothing is drawn.
    pub origin: [f32; 4],
    /// Rows of the map world → barycentric λ1..λ3, relative to `origin` (xyz; w unused).
    pub bary: [[f32; 4]; 3],
    /// Texture coordinates (u, v, w) of the four corners (w: 0 base, 1 top).
    pub tex: [[f32; 4]; 4],
}

/// Largest shape ratio of a drawn tetrahedron: the longest edge from corner
/// 0, cubed, over |det(e1, e2, e3)| (six times the volume). The ratio bounds
/// the f32 error of the world → barycentric map at points inside the
/// tetrahedron by 45 u × ratio (u = 2⁻²⁴; see `docs/shell.md`): at 4096,
/// 1.1 % of the tetrahedron. Flatter ones, exactly flat or slivers about
/// 1/4096 of their edges thin, are marked (`origin[3] = 0`) and not drawn.
pub const MAX_SHAPE_RATIO: f32 = 4096.0;

/// Indices per tetrahedron in the corner buffer: four faces of three.
pub const CORNERS_PER_TETRA: u32 = 12;

/// Builds the tetrahedra, one invocation per face.
pub struct ShellTetraPass {
    pass: ComputePass<TetraParams>,
}

impl ShellTetraPass {
    /// The pass reading `faces` (three vertex indices each) and `vertices`
    /// (from the vertex pass), writing `tetras` (three per face) and
    /// `corners` ([`CORNERS_PER_TETRA`] per tetrahedron).
    #[must_use]
    pub fn new(device: &wgpu::Device, faces: &wgpu::Buffer, vertices: &wgpu::Buffer, tetras: &wgpu::Buffer, corners: &wgpu::Buffer) -> Self {
        let shape = PassShape {
            label: "shell tetrahedra",
            source: shaders::SHELL_TETRAHEDRA,
            slots: &[Slot::Read, Slot::Read, Slot::ReadWrite, Slot::ReadWrite],
            specialise_on: None,
            constants: &[],
            window: None,
        };
        let mut pass = ComputePass::new(device, &shape, None);
        pass.bind(device, &[faces.as_entire_binding(), vertices.as_entire_binding(), tetras.as_entire_binding(), corners.as_entire_binding()]);
        Self { pass }
    }

    /// Records the pass over `params.faces` faces.
    pub fn record(&self, cx: &mut FrameContext<'_>, params: &TetraParams) {
        self.pass.record(cx, None, params, 0, (layout::groups(params.faces, 64), 1));
    }
}
