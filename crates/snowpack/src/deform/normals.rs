//! Normals pass: central differences from workgroup memory of the heights in
//! `surface`, written beside them (`normals.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::gpu::{GpuTimer, layout};
use crate::shaders;

use super::resources::DeformResources;

/// Uniforms of `normals.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct NormalParams {
    /// Texels per side.
    pub resolution: u32,
    /// Texel size (m).
    pub texel_m: f32,
    /// Padding.
    pub _pad: [u32; 2],
}

/// Packs height and normal for the renderer.
pub struct NormalPass {
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    resolution: u32,
}

impl NormalPass {
    /// Builds the pipeline reading and writing `res.surface`.
    #[must_use]
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, res: &DeformResources, texel_m: f32) -> Self {
        let (pipeline, bgl) =
            layout::compute_pipeline(device, "normals", shaders::NORMALS, &[layout::uniform(0, wgpu::ShaderStages::COMPUTE), layout::storage(1, false)]);
        let params = layout::uniform_buffer::<NormalParams>(device, "normal params");
        let p = NormalParams { resolution: res.resolution, texel_m, _pad: [0; 2] };
        queue.write_buffer(&params, 0, bytemuck::bytes_of(&p));
        let bind_group = layout::bind_group(device, "normals", &bgl, &[params.as_entire_binding(), res.surface.as_entire_binding()]);
        Self { pipeline, bind_group, resolution: res.resolution }
    }

    /// Records the pass.
    pub fn record(&self, encoder: &mut wgpu::CommandEncoder, timer: &mut GpuTimer) {
        let g = layout::groups(self.resolution, 16);
        layout::dispatch(encoder, timer, "normals", &self.pipeline, &self.bind_group, (g, g));
    }
}

/// Unpacks one `surface` texel into (height, unit normal).
#[must_use]
pub fn unpack_surface(texel: [u32; 2]) -> (f32, [f32; 3]) {
    let snorm = |bits: u32| (f32::from(bits as u16 as i16) / 32767.0).max(-1.0);
    let (nx, nz) = (snorm(texel[1] & 0xffff), snorm(texel[1] >> 16));
    let ny = (1.0 - nx * nx - nz * nz).max(0.0).sqrt();
    (f32::from_bits(texel[0]), [nx, ny, nz])
}
