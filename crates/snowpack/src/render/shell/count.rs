//! After step 2 of each peeling pass (`shaders/peel_count.wgsl`): the pixels
//! the pass will shade, counted and marked for the debug view.

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
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
    /// One pass per peel (the same pipeline, a uniform each): all peels are
    /// recorded before the queue's writes land, so they cannot share one.
    passes: Vec<ComputePass<CountParams>>,
}

impl PeelCountPass {
    /// The pass reading `peel_depth`, adding to `counts` (one u32 per pass)
    /// and writing `shaded` (one u32 mask per pixel).
    #[must_use]
    pub fn new(device: &wgpu::Device, peel_depth: &wgpu::TextureView, counts: &wgpu::Buffer, shaded: &wgpu::Buffer) -> Self {
        let shape = PassShape {
            label: "peel count",
            source: shaders::PEEL_COUNT,
            slots: &[Slot::Depth, Slot::ReadWrite, Slot::ReadWrite],
            specialise_on: None,
            constants: &[],
            window: None,
        };
        let first = ComputePass::new(device, &shape, None);
        let mut passes: Vec<ComputePass<CountParams>> = (1..MAX_PASSES).map(|_| first.sibling(device)).collect();
        passes.insert(0, first);
        for pass in &mut passes {
            pass.bind(device, &[wgpu::BindingResource::TextureView(peel_depth), counts.as_entire_binding(), shaded.as_entire_binding()]);
        }
        Self { passes }
    }

    /// Records the count of pass `pass_index` over a `size` target (nothing
    /// for an index past `MAX_PASSES`).
    pub fn record(&self, cx: &mut FrameContext<'_>, pass_index: u32, size: (u32, u32)) {
        let Some(pass) = self.passes.get(pass_index as usize) else { return };
        let p = CountParams { pass_index, width: size.0, height: size.1, _pad: 0 };
        pass.record(cx, None, &p, 0, (layout::groups(size.0, 8), layout::groups(size.1, 8)));
    }
}
