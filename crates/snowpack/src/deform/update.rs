//! Update pass: the persistent snow height with linear refill, lowered by the
//! captured actors and the stamped footprints (`update.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::gpu::{layout, GpuTimer};
use crate::shaders;

use super::resources::DeformResources;

/// Uniforms of `update.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct UpdateParams {
    /// Global texel index of local (0, 0): `[column, row]`.
    pub origin: [i32; 2],
    /// Texels per side.
    pub resolution: u32,
    /// Rest depth of snow (m).
    pub depth_m: f32,
    /// Refill this frame: `refill_m_per_s * dt` (m).
    pub refill_m: f32,
    /// Capture depth 0 height (m).
    pub low_m: f32,
    /// Capture depth 1 height (m).
    pub high_m: f32,
    /// [`UpdateParams::USE_CAPTURE`] | [`UpdateParams::USE_STAMPS`].
    pub flags: u32,
    /// Footprint refill this frame, in whole stamp quanta.
    pub refill_quanta: u32,
    /// Padding to 48 bytes (the WGSL struct aligns to its `vec2<i32>`).
    pub _pad: [u32; 3],
}

impl UpdateParams {
    /// Apply the captured actors.
    pub const USE_CAPTURE: u32 = 1;
    /// Apply the stamped footprints.
    pub const USE_STAMPS: u32 = 2;
}

/// Applies refill and the captured actors to the persistent snow.
pub struct UpdatePass {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

impl UpdatePass {
    /// Builds the pipeline and binds it to `res`.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        let (pipeline, bgl) = layout::compute_pipeline(
            device,
            "update",
            shaders::UPDATE,
            &[
                layout::uniform(0, wgpu::ShaderStages::COMPUTE),
                layout::depth_texture(1),
                layout::storage(2, true),
                layout::storage(3, false),
                layout::storage(4, false),
            ],
        );
        let params = layout::uniform_buffer::<UpdateParams>(device, "update params");
        let bind_group = layout::bind_group(
            device,
            "update",
            &bgl,
            &[
                params.as_entire_binding(),
                wgpu::BindingResource::TextureView(&res.capture_view),
                res.terrain.as_entire_binding(),
                res.snow.as_entire_binding(),
                res.stamps.as_entire_binding(),
            ],
        );
        Self { pipeline, params, bind_group }
    }

    /// Records the update for this frame.
    pub fn record(&self, queue: &wgpu::Queue, encoder: &mut wgpu::CommandEncoder, timer: &mut GpuTimer, params: &UpdateParams) {
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let g = layout::groups(params.resolution, 16);
        layout::dispatch(encoder, timer, "update", &self.pipeline, &self.bind_group, (g, g));
    }
}
