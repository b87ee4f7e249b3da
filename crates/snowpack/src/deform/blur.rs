//! Blur pass: the separable 5x5 Gaussian in workgroup memory (`blur.wgsl`),
//! in place in `surface`: its height words -> its normal words (scratch until
//! the normals pass) along x, then back along z.

use bytemuck::{Pod, Zeroable};

use crate::gpu::{GpuTimer, layout};
use crate::shaders;

use super::resources::DeformResources;

/// Uniforms of `blur.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BlurParams {
    /// Texels per side.
    pub resolution: u32,
    /// 0: along x (rows), 1: along z (columns).
    pub axis: u32,
    /// Word of a texel's `surface` entry read: 0 the height, 1 the normal (scratch).
    pub src_word: u32,
    /// Word of a texel's `surface` entry written.
    pub dst_word: u32,
}

/// Both axes of the blur; each axis has its own uniforms and bind group, so
/// both can be recorded into one encoder.
pub struct BlurPass {
    pipeline: wgpu::ComputePipeline,
    axes: [wgpu::BindGroup; 2],
    resolution: u32,
}

impl BlurPass {
    /// Builds the pipeline and binds both axes to `res`.
    #[must_use]
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, res: &DeformResources) -> Self {
        let (pipeline, bgl) =
            layout::compute_pipeline(device, "blur", shaders::BLUR, &[layout::uniform(0, wgpu::ShaderStages::COMPUTE), layout::storage(1, false)]);
        let make = |axis: u32| {
            let params = layout::uniform_buffer::<BlurParams>(device, "blur params");
            let p = BlurParams { resolution: res.resolution, axis, src_word: axis, dst_word: 1 - axis };
            queue.write_buffer(&params, 0, bytemuck::bytes_of(&p));
            layout::bind_group(device, "blur", &bgl, &[params.as_entire_binding(), res.surface.as_entire_binding()])
        };
        let axes = [make(0), make(1)];
        Self { pipeline, axes, resolution: res.resolution }
    }

    /// Records both axes.
    pub fn record(&self, encoder: &mut wgpu::CommandEncoder, timer: &mut GpuTimer) {
        let g = layout::groups(self.resolution, 16);
        for (axis, label) in [(0, "blur_x"), (1, "blur_z")] {
            layout::dispatch(encoder, timer, label, &self.pipeline, &self.axes[axis], (g, g));
        }
    }
}
