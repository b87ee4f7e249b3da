//! Increment pass: hits to depth per atlas texel (`shaders/increment.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
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
    pass: ComputePass<IncrementParams>,
}

impl IncrementPass {
    /// Builds the pipeline over the atlas buffers.
    #[must_use]
    pub fn new(device: &wgpu::Device, normal_area: &wgpu::Buffer, hits: &wgpu::Buffer, fresh: &wgpu::Buffer) -> Self {
        let mut pass = ComputePass::new(
            device,
            &PassShape {
                label: "increment",
                source: shaders::INCREMENT,
                slots: &[Slot::Read, Slot::ReadWrite, Slot::ReadWrite],
                specialise_on: None,
                constants: &[],
                window: None,
            },
            None,
        );
        pass.bind(device, &[normal_area.as_entire_binding(), hits.as_entire_binding(), fresh.as_entire_binding()]);
        Self { pass }
    }

    /// Records the increment.
    /// Only the first `rows` atlas rows are dispatched: charts are packed from
    /// row 0 up ([`super::AtlasLayout::used_rows`]), and the rows above hold nothing.
    pub fn record(&self, cx: &mut FrameContext<'_>, rows: u32, params: &IncrementParams) {
        let g = layout::groups(params.atlas_resolution, 16);
        let gy = layout::groups(rows.min(params.atlas_resolution), 16);
        self.pass.record(cx, None, params, 0, (g, gy));
    }
}
