//! Rim pass: Hanák's cubic remap, or rims from the points' stored foot
//! heights, into the displayed height (`rim.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::gpu::{GpuTimer, layout};
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
    /// Rim strength: blend of the cubic remap (mode 0), or rim height scale (modes 1, 2).
    pub elevation: f32,
    /// 0 Hanák's remap, 1 MS16 point rims, 2 rounded point rims ([`RimParams::mode_for`]).
    pub mode: u32,
    /// Height of stamp code 0 (m).
    pub low_m: f32,
    /// Height of stamp code 65535 (m).
    pub high_m: f32,
    /// 1 when the rest depth includes the `fallen` buffer (snowfall so far).
    pub use_fallen: u32,
    /// Texel size (m): where the terrain is evaluated.
    pub texel_m: f32,
}

impl RimParams {
    /// The rim mode of a technique: rims from points where points are stamped.
    #[must_use]
    pub fn mode_for(technique: crate::Technique, style: crate::RimStyle) -> u32 {
        use crate::{RimStyle, Technique};
        match (technique, style) {
            (Technique::Depth | Technique::Decals, _) => 0,
            (Technique::Points | Technique::Combined, RimStyle::Ms16) => 1,
            (Technique::Points | Technique::Combined, RimStyle::Rounded) => 2,
        }
    }
}

/// Writes the displayed height (before blur) in window-local order.
pub struct RimPass {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

impl RimPass {
    /// Builds the pipeline and binds it to `res` (output: the height words of `res.surface`).
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
                layout::storage(4, true),
                layout::storage(5, true),
                layout::uniform(6, wgpu::ShaderStages::COMPUTE),
            ],
        );
        let params = layout::uniform_buffer::<RimParams>(device, "rim params");
        let bind_group = layout::bind_group(
            device,
            "rim",
            &bgl,
            &[
                params.as_entire_binding(),
                res.heightmap.as_entire_binding(),
                res.snow.as_entire_binding(),
                res.surface.as_entire_binding(),
                res.stamps.as_entire_binding(),
                res.fallen.as_entire_binding(),
                res.terrain_params.as_entire_binding(),
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
