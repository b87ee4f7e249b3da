//! After step 2 of each peeling pass (`shaders/peel_count.wgsl`): the pixels
//! the pass will shade, counted and marked for the debug view.

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::shaders;

/// Parameters of [`PeelCountPass`] (`CountParams` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct CountParams {
    /// Peeling pass, from 0 (which also clears the mask).
    pub pass_index: u32,
    /// Pixels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Padding.
    pub _pad: u32,
}

/// Most peeling passes a frame may have (bits of the per-pixel mask).
pub const MAX_PASSES: u32 = 16;

/// Counts and marks the pixels with a layer in the peel depth.
pub struct PeelCountPass {
    params: Vec<wgpu::Buffer>,
    pipeline: wgpu::ComputePipeline,
    bind_groups: Vec<wgpu::BindGroup>,
}

impl PeelCountPass {
    /// The pass reading `peel_depth`, adding to `counts` (one u32 per pass)
    /// and writing `shaded` (one u32 mask per pixel).
    #[must_use]
    pub fn new(device: &wgpu::Device, peel_depth: &wgpu::TextureView, counts: &wgpu::Buffer, shaded: &wgpu::Buffer) -> Self {
        let (pipeline, bgl) = layout::compute_pipeline(
            device,
            "peel count",
            shaders::PEEL_COUNT,
            &[layout::uniform(0, wgpu::ShaderStages::COMPUTE), layout::depth_texture(1), layout::storage(2, false), layout::storage(3, false)],
        );
        // One uniform buffer per pass: all passes are recorded before the
        // queue's writes land, so they cannot share one.
        let params: Vec<wgpu::Buffer> = (0..MAX_PASSES).map(|_| layout::uniform_buffer::<CountParams>(device, "peel count params")).collect();
        let bind_groups = params
            .iter()
            .map(|p| {
                layout::bind_group(
                    device,
                    "peel count",
                    &bgl,
                    &[p.as_entire_binding(), wgpu::BindingResource::TextureView(peel_depth), counts.as_entire_binding(), shaded.as_entire_binding()],
                )
            })
            .collect();
        Self { params, pipeline, bind_groups }
    }

    /// Writes the parameters of every pass for a `size` target (once per size, before recording).
    pub fn prepare(&self, queue: &wgpu::Queue, size: (u32, u32)) {
        for (k, buffer) in self.params.iter().enumerate() {
            let p = CountParams { pass_index: k as u32, width: size.0, height: size.1, _pad: 0 };
            queue.write_buffer(buffer, 0, bytemuck::bytes_of(&p));
        }
    }

    /// Records the count of pass `pass_index` over a `size` target.
    pub fn record(&self, cx: &mut FrameContext<'_>, pass_index: u32, size: (u32, u32)) {
        let (encoder, timer) = (&mut *cx.encoder, &mut *cx.timer);
        let k = pass_index as usize;
        layout::dispatch(encoder, timer, "peel count", &self.pipeline, &self.bind_groups[k], (layout::groups(size.0, 8), layout::groups(size.1, 8)));
    }
}
