//! Shell construction, step 1 of 2 (`shaders/shell_vertices.wgsl`): the base
//! surface as drawn this frame and its offset copy along the normals.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::shaders;

/// Parameters of [`ShellVertexPass`] (`ShellVertexParams` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ShellVertexParams {
    /// [`Self::MESH`] or [`Self::SNOW`].
    pub mode: u32,
    /// Vertices.
    pub count: u32,
    /// Snow: vertices per side of the patch.
    pub side: u32,
    /// Snow: window texels between neighbouring vertices.
    pub stride: u32,
    /// Snow: window-local texel (column, row) of vertex 0.
    pub origin: [i32; 2],
    /// Snow: window texels per side.
    pub resolution: u32,
    /// Padding.
    pub _pad0: u32,
    /// Snow: world (x, z) of the window's corner.
    pub corner: [f32; 2],
    /// Snow: texel size (m).
    pub texel_m: f32,
    /// Snow: rest depth of fresh snow (m).
    pub depth_m: f32,
    /// Shell thickness over undisturbed snow (m).
    pub thickness_m: f32,
    /// Snow: pressing (m below rest) that flattens the shell to `min_fraction`.
    pub flatten_m: f32,
    /// Snow: the thinnest the shell gets, as a fraction of `thickness_m`.
    pub min_fraction: f32,
    /// Snow: world size of one repeat of the detail texture (m).
    pub tile_m: f32,
}

impl ShellVertexParams {
    /// Vertices from a mesh (positions, normals and texture coordinates given).
    pub const MESH: u32 = 0;
    /// Vertices on the displayed snow surface of the deformation window.
    pub const SNOW: u32 = 1;
}

/// A base-mesh vertex for mesh mode (`BaseVertex` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BaseVertex {
    /// Position xyz; w: texture u.
    pub position: [f32; 4],
    /// Unit normal xyz; w: texture v.
    pub normal: [f32; 4],
}

/// A shell vertex (`ShellVertex` in `shared/shell.wgsl`): the base vertex
/// and its offset copy.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ShellVertex {
    /// On the surface; w: texture u.
    pub base: [f32; 4],
    /// Offset along the normal by the local thickness; w: texture v.
    pub top: [f32; 4],
}

/// What the vertex pass reads of the snow (window-local buffers of the deformation).
pub struct SnowSurface<'a> {
    /// Displayed height and packed normal per texel.
    pub surface: &'a wgpu::Buffer,
    /// Terrain heightmap samples.
    pub heightmap: &'a wgpu::Buffer,
    /// Terrain parameters (uniform).
    pub terrain_params: &'a wgpu::Buffer,
    /// The terrain kind the pipeline is built for
    /// (`DeformResources::terrain_constants`).
    pub terrain_constants: [(&'static str, f64); 1],
}

/// Transforms the base surface and builds the offset surface, one invocation per vertex.
pub struct ShellVertexPass {
    /// One pipeline per [`ShellVertexParams::mode`] in use.
    pass: ComputePass<ShellVertexParams>,
}

impl ShellVertexPass {
    /// The pass reading `base` (mesh mode; any non-empty storage buffer in
    /// snow mode) and `snow`, writing `vertices`.
    #[must_use]
    pub fn new(device: &wgpu::Device, base: &wgpu::Buffer, snow: &SnowSurface<'_>, vertices: &wgpu::Buffer) -> Self {
        let shape = PassShape {
            label: "shell vertices",
            source: shaders::SHELL_VERTICES,
            slots: &[Slot::Read, Slot::Read, Slot::Read, Slot::Uniform, Slot::ReadWrite],
            specialise_on: Some("SHELL_MODE"),
            constants: &snow.terrain_constants,
            window: None,
        };
        let mut pass = ComputePass::new(device, &shape, None);
        pass.bind(
            device,
            &[
                base.as_entire_binding(),
                snow.surface.as_entire_binding(),
                snow.heightmap.as_entire_binding(),
                snow.terrain_params.as_entire_binding(),
                vertices.as_entire_binding(),
            ],
        );
        Self { pass }
    }

    /// Records the pass over `params.count` vertices.
    pub fn record(&self, cx: &mut FrameContext<'_>, params: &ShellVertexParams) {
        self.pass.record(cx, None, params, params.mode, (layout::groups(params.count, 64), 1));
    }
}
