//! Rim pass: Hanák's cubic remap into the displayed height (`rim.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::gpu::{layout, GpuTimer};
use crate::shaders;

use super::resources::DeformResources;

/// Uniforms of `rim.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RimParams {
    /// Global texel index of local (0, 0): `[column, row]`.
    pub origin: [i32; 2],
    /// Texels per side.
    pub resolution: u32,
    /// Rest depth of snow (m).
    pub depth_m: f32,
    /// Blend of the cubic remap: 0 = none, 1 = Hanák's curve.
    pub elevation: f32,
    /// Padding.
    pub _pad: [u32; 3],
}

/// Writes the displayed height (before blur) in window-local order.
pub struct RimPass {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

impl RimPass {
    /// Builds the pipeline and binds it to `res` (output: `res.shown`).
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        let (pipeline, bgl) = layout::compute_pipeline(
            device,
            "rim",
            shaders::RIM,
            &[
                layout::uniform(0, wgpu::ShaderStages::COMPUTE),
                layout::storage(1, true),
                layout::storage(2, true),
                layout::storage(3, false),
            ],
        );
        let params = layout::uniform_buffer::<RimParams>(device, "rim params");
        let bind_group = layout::bind_group(
            device,
            "rim",
            &bgl,
            &[
                params.as_entire_binding(),
                res.terrain.as_entire_binding(),
                res.snow.as_entire_binding(),
                res.shown.as_entire_binding(),
            ],
        );
        Self { pipeline, params, bind_group }
    }

    /// Records the remap for this frame.
    pub fn record(&self, queue: &wgpu::Queue, encoder: &mut wgpu::CommandEncoder, timer: &mut GpuTimer, params: &RimParams) {
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let g = layout::groups(params.resolution, 16);
        layout::dispatch(encoder, timer, "rim", &self.pipeline, &self.bind_group, (g, g));
    }
}
