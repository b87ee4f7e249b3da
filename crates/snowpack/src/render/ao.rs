//! Ambient occlusion of the displayed snow from its height field (`shaders/ao.wgsl`).

use crate::frame::FrameContext;
use crate::gpu::layout;
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
    params: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
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
        let (pipeline, bgl) = layout::compute_pipeline(
            device,
            "ao",
            shaders::AO,
            &[layout::uniform(0, wgpu::ShaderStages::COMPUTE), layout::storage(1, true), layout::storage(2, false)],
        );
        let params = layout::uniform_buffer::<AoParams>(device, "ao params");
        let bind_group = layout::bind_group(device, "ao", &bgl, &[params.as_entire_binding(), surface.as_entire_binding(), ao.as_entire_binding()]);
        Self { ao, params, pipeline, bind_group, resolution }
    }

    /// Records the pass with `params`.
    pub fn record(&self, cx: &mut FrameContext<'_>, params: AoParams) {
        let (queue, encoder, timer) = (cx.queue(), &mut *cx.encoder, &mut *cx.timer);
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let g = layout::groups(self.resolution, 8);
        layout::dispatch(encoder, timer, "ao", &self.pipeline, &self.bind_group, (g, g));
    }
}
