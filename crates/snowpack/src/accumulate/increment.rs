//! Increment pass: hits to depth per atlas texel (`shaders/increment.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::shaders;

/// Uniforms of `increment.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct IncrementParams {
    /// Atlas texels per side.
    pub atlas_resolution: u32,
    /// Snow one occlusion pixel receives this frame: rate * dt * pixel area (m³).
    pub volume_m3: f32,
    /// Padding to 16 bytes.
    pub _pad: [u32; 2],
}

/// Turns the frame's hits into a depth increment and clears them.
pub struct IncrementPass {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

impl IncrementPass {
    /// Builds the pipeline over the atlas buffers.
    #[must_use]
    pub fn new(device: &wgpu::Device, normal_area: &wgpu::Buffer, hits: &wgpu::Buffer, fresh: &wgpu::Buffer) -> Self {
        let (pipeline, bgl) = layout::compute_pipeline(
            device,
            "increment",
            shaders::INCREMENT,
            &[layout::uniform(0, wgpu::ShaderStages::COMPUTE), layout::storage(1, true), layout::storage(2, false), layout::storage(3, false)],
        );
        let params = layout::uniform_buffer::<IncrementParams>(device, "increment params");
        let bind_group = layout::bind_group(
            device,
            "increment",
            &bgl,
            &[params.as_entire_binding(), normal_area.as_entire_binding(), hits.as_entire_binding(), fresh.as_entire_binding()],
        );
        Self { pipeline, params, bind_group }
    }

    /// Records the increment.
    /// Only the first `rows` atlas rows are dispatched: charts are packed from
    /// row 0 up ([`super::AtlasLayout::used_rows`]), and the rows above hold nothing.
    pub fn record(&self, cx: &mut FrameContext<'_>, rows: u32, params: &IncrementParams) {
        let (queue, encoder, timer) = (cx.queue(), &mut *cx.encoder, &mut *cx.timer);
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let g = layout::groups(params.atlas_resolution, 16);
        let gy = layout::groups(rows.min(params.atlas_resolution), 16);
        layout::dispatch(encoder, timer, "increment", &self.pipeline, &self.bind_group, (g, gy));
    }
}
