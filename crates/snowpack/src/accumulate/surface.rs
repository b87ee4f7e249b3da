//! Atlas surface pass: dilation and Scharr slopes of the accumulation, for
//! drawing (`shaders/atlas_surface.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::shaders;

/// Uniforms of `atlas_surface.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SurfaceParams {
    /// Atlas texels per side.
    pub atlas_resolution: u32,
    /// Padding to 16 bytes.
    pub _pad: [u32; 3],
}

/// Writes (height, slope x, slope y, owned) per atlas texel.
pub struct AtlasSurfacePass {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

impl AtlasSurfacePass {
    /// Builds the pipeline reading `objects`, `owner` and `acc`, writing `surface`.
    #[must_use]
    pub fn new(device: &wgpu::Device, objects: &wgpu::Buffer, owner: &wgpu::Buffer, acc: &wgpu::Buffer, surface: &wgpu::Buffer) -> Self {
        let (pipeline, bgl) = layout::compute_pipeline(
            device,
            "atlas surface",
            shaders::ATLAS_SURFACE,
            &[
                layout::uniform(0, wgpu::ShaderStages::COMPUTE),
                layout::storage(1, true),
                layout::storage(2, true),
                layout::storage(3, true),
                layout::storage(4, false),
            ],
        );
        let params = layout::uniform_buffer::<SurfaceParams>(device, "atlas surface params");
        let bind_group = layout::bind_group(
            device,
            "atlas surface",
            &bgl,
            &[params.as_entire_binding(), objects.as_entire_binding(), owner.as_entire_binding(), acc.as_entire_binding(), surface.as_entire_binding()],
        );
        Self { pipeline, params, bind_group }
    }

    /// Records the surface.
    /// Only the first `rows` atlas rows are dispatched: charts are packed from
    /// row 0 up ([`super::AtlasLayout::used_rows`]), and the rows above hold nothing.
    pub fn record(&self, cx: &mut FrameContext<'_>, rows: u32, params: &SurfaceParams) {
        let (queue, encoder, timer) = (cx.queue(), &mut *cx.encoder, &mut *cx.timer);
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let g = layout::groups(params.atlas_resolution, 16);
        let gy = layout::groups(rows.min(params.atlas_resolution), 16);
        layout::dispatch(encoder, timer, "atlas surface", &self.pipeline, &self.bind_group, (g, gy));
    }
}
