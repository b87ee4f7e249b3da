//! Ambient occlusion of the displayed snow from its height field (`shaders/ao.wgsl`).

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::shaders;

/// Parameters of the AO pass (`AoParams` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct AoParams {
    /// Texels per side.
    pub resolution: u32,
    /// March distances 1, 2, 4 ... 2^(steps-1) texels.
    pub steps: u32,
    /// Texel size (m).
    pub texel_m: f32,
    /// 0 off, 1 full.
    pub strength: f32,
}

/// Marches the horizon in 8 directions per texel of the window's surface.
pub struct AoPass {
    /// AO per texel, window-local (1 open).
    pub ao: wgpu::Buffer,
    pass: ComputePass<AoParams>,
    resolution: u32,
}

impl AoPass {
    /// Default march steps: out to 32 texels (2 m at 6.25 cm).
    pub const STEPS: u32 = 6;

    /// Builds the pass over a `resolution`² window-local `surface` buffer
    /// (packed height and normal, as [`crate::render::surface::SurfaceUnpackPass::surface`]).
    #[must_use]
    pub fn new(device: &wgpu::Device, surface: &wgpu::Buffer, resolution: u32) -> Self {
        let r = u64::from(resolution);
        let ao = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ambient occlusion"),
            size: r * r * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let shape = PassShape { label: "ao", source: shaders::AO, slots: &[Slot::Read, Slot::ReadWrite], specialise_on: None, constants: &[], window: None };
        let mut pass = ComputePass::new(device, &shape, None);
        pass.bind(device, &[surface.as_entire_binding(), ao.as_entire_binding()]);
        Self { ao, pass, resolution }
    }

    /// Records the pass with `params`.
    pub fn record(&self, cx: &mut FrameContext<'_>, params: AoParams) {
        let g = layout::groups(self.resolution, 8);
        self.pass.record(cx, None, &params, 0, (g, g));
    }
}
