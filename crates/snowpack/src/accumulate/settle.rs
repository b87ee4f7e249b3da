//! Settle pass: blur of the increment, accumulation and slope stability
//! (`shaders/settle.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::shaders;

/// Uniforms of `settle.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SettleParams {
    /// Atlas texels per side.
    pub atlas_resolution: u32,
    /// Most snow a flat surface holds (m; Dinh's `m`).
    pub max_m: f32,
    /// Cosine of the angle of repose.
    pub cos_repose: f32,
    /// Fraction of the snow above capacity that falls off this frame (Dinh's `f`).
    pub falloff: f32,
    /// Cosine of 10 degrees less than the angle of repose: all new snow sticks from there up.
    pub cos_full: f32,
    /// Padding to 32 bytes.
    pub _pad: [u32; 3],
}

/// The atlas buffers the settle pass reads and writes.
#[derive(Clone, Copy, Debug)]
pub struct SettleBuffers<'a> {
    /// `ObjectGpu` per object.
    pub objects: &'a wgpu::Buffer,
    /// Baked normal and area per texel.
    pub normal_area: &'a wgpu::Buffer,
    /// Owner per texel.
    pub owner: &'a wgpu::Buffer,
    /// This frame's increment per texel.
    pub fresh: &'a wgpu::Buffer,
    /// The accumulation per texel (m), persistent.
    pub acc: &'a wgpu::Buffer,
}

/// Adds the blurred increment and lets snow beyond a surface's capacity fall off.
pub struct SettlePass {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

impl SettlePass {
    /// Builds the pipeline over `b`.
    #[must_use]
    pub fn new(device: &wgpu::Device, b: &SettleBuffers<'_>) -> Self {
        let (pipeline, bgl) = layout::compute_pipeline(
            device,
            "settle",
            shaders::SETTLE,
            &[
                layout::uniform(0, wgpu::ShaderStages::COMPUTE),
                layout::storage(1, true),
                layout::storage(2, true),
                layout::storage(3, true),
                layout::storage(4, true),
                layout::storage(5, false),
            ],
        );
        let params = layout::uniform_buffer::<SettleParams>(device, "settle params");
        let bind_group = layout::bind_group(
            device,
            "settle",
            &bgl,
            &[
                params.as_entire_binding(),
                b.objects.as_entire_binding(),
                b.normal_area.as_entire_binding(),
                b.owner.as_entire_binding(),
                b.fresh.as_entire_binding(),
                b.acc.as_entire_binding(),
            ],
        );
        Self { pipeline, params, bind_group }
    }

    /// Records the settle.
    /// Only the first `rows` atlas rows are dispatched: charts are packed from
    /// row 0 up ([`super::AtlasLayout::used_rows`]), and the rows above hold nothing.
    pub fn record(&self, cx: &mut FrameContext<'_>, rows: u32, params: &SettleParams) {
        let (queue, encoder, timer) = (cx.queue(), &mut *cx.encoder, &mut *cx.timer);
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let g = layout::groups(params.atlas_resolution, 16);
        let gy = layout::groups(rows.min(params.atlas_resolution), 16);
        layout::dispatch(encoder, timer, "settle", &self.pipeline, &self.bind_group, (g, gy));
    }
}
