//! Atlas surface pass: dilation and Scharr slopes of the accumulation, for
//! drawing (`shaders/atlas_surface.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
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
    pass: ComputePass<SurfaceParams>,
}

impl AtlasSurfacePass {
    /// Builds the pipeline reading `objects`, `owner` and `acc`, writing `surface`.
    #[must_use]
    pub fn new(device: &wgpu::Device, objects: &wgpu::Buffer, owner: &wgpu::Buffer, acc: &wgpu::Buffer, surface: &wgpu::Buffer) -> Self {
        let mut pass = ComputePass::new(
            device,
            &PassShape {
                label: "atlas surface",
                source: shaders::ATLAS_SURFACE,
                slots: &[Slot::Read, Slot::Read, Slot::Read, Slot::ReadWrite],
                specialise_on: None,
                constants: &[],
                window: None,
            },
            None,
        );
        pass.bind(device, &[objects.as_entire_binding(), owner.as_entire_binding(), acc.as_entire_binding(), surface.as_entire_binding()]);
        Self { pass }
    }

    /// Records the surface.
    /// Only the first `rows` atlas rows are dispatched: charts are packed from
    /// row 0 up ([`super::AtlasLayout::used_rows`]), and the rows above hold nothing.
    pub fn record(&self, cx: &mut FrameContext<'_>, rows: u32, params: &SurfaceParams) {
        let g = layout::groups(params.atlas_resolution, 16);
        let gy = layout::groups(rows.min(params.atlas_resolution), 16);
        self.pass.record(cx, None, params, 0, (g, gy));
    }
}
