//! Scatter pass: occlusion pixels to atlas hits (`shaders/scatter.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::shaders;

/// Uniforms of `scatter.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ScatterParams {
    /// Occlusion pixels per side.
    pub resolution: u32,
    /// Atlas texels per side.
    pub atlas_resolution: u32,
    /// Frame number, seeding the noise.
    pub frame: u32,
    /// Noise amplitude (0..1).
    pub noise: f32,
}

/// Adds each occlusion pixel's snow to the atlas texels of its footprint.
pub struct ScatterPass {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

impl ScatterPass {
    /// Builds the pipeline reading `footprint` and adding into `hits` (u32 per atlas texel).
    #[must_use]
    pub fn new(device: &wgpu::Device, footprint: &wgpu::TextureView, hits: &wgpu::Buffer) -> Self {
        let (pipeline, bgl) = layout::compute_pipeline(
            device,
            "scatter",
            shaders::SCATTER,
            &[
                layout::uniform(0, wgpu::ShaderStages::COMPUTE),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Uint,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                layout::storage(2, false),
            ],
        );
        let params = layout::uniform_buffer::<ScatterParams>(device, "scatter params");
        let bind_group =
            layout::bind_group(device, "scatter", &bgl, &[params.as_entire_binding(), wgpu::BindingResource::TextureView(footprint), hits.as_entire_binding()]);
        Self { pipeline, params, bind_group }
    }

    /// Records the scatter of this frame's occlusion.
    pub fn record(&self, cx: &mut FrameContext<'_>, params: &ScatterParams) {
        let (queue, encoder, timer) = (cx.queue(), &mut *cx.encoder, &mut *cx.timer);
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let g = layout::groups(params.resolution, 16);
        layout::dispatch(encoder, timer, "scatter", &self.pipeline, &self.bind_group, (g, g));
    }
}
