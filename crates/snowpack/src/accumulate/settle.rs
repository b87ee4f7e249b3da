//! Settle pass: blur of the increment, accumulation and slope stability
//! (`shaders/settle.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
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
    pass: ComputePass<SettleParams>,
}

impl SettlePass {
    /// Builds the pipeline over `b`.
    #[must_use]
    pub fn new(device: &wgpu::Device, b: &SettleBuffers<'_>) -> Self {
        let mut pass = ComputePass::new(
            device,
            &PassShape {
                label: "settle",
                source: shaders::SETTLE,
                slots: &[Slot::Read, Slot::Read, Slot::Read, Slot::Read, Slot::ReadWrite],
                specialise_on: None,
                constants: &[],
                window: None,
            },
            None,
        );
        pass.bind(
            device,
            &[
                b.objects.as_entire_binding(),
                b.normal_area.as_entire_binding(),
                b.owner.as_entire_binding(),
                b.fresh.as_entire_binding(),
                b.acc.as_entire_binding(),
            ],
        );
        Self { pass }
    }

    /// Records the settle.
    /// Only the first `rows` atlas rows are dispatched: charts are packed from
    /// row 0 up ([`super::AtlasLayout::used_rows`]), and the rows above hold nothing.
    pub fn record(&self, cx: &mut FrameContext<'_>, rows: u32, params: &SettleParams) {
        let g = layout::groups(params.atlas_resolution, 16);
        let gy = layout::groups(rows.min(params.atlas_resolution), 16);
        self.pass.record(cx, None, params, 0, (g, gy));
    }
}
