//! Scatter pass: occlusion pixels to atlas hits (`shaders/scatter.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
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
    pass: ComputePass<ScatterParams>,
}

impl ScatterPass {
    /// Builds the pipeline reading `footprint` and adding into `hits` (u32 per atlas texel).
    #[must_use]
    pub fn new(device: &wgpu::Device, footprint: &wgpu::TextureView, hits: &wgpu::Buffer) -> Self {
        let mut pass = ComputePass::new(
            device,
            &PassShape {
                label: "scatter",
                source: shaders::SCATTER,
                slots: &[Slot::UintTexture, Slot::ReadWrite],
                specialise_on: None,
                constants: &[],
                window: None,
            },
            None,
        );
        pass.bind(device, &[wgpu::BindingResource::TextureView(footprint), hits.as_entire_binding()]);
        Self { pass }
    }

    /// Records the scatter of this frame's occlusion.
    pub fn record(&self, cx: &mut FrameContext<'_>, params: &ScatterParams) {
        let g = layout::groups(params.resolution, 16);
        self.pass.record(cx, None, params, 0, (g, g));
    }
}
