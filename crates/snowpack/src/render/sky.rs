//! The sky background pass (`shaders/sky.wgsl`): the environment along each view ray.

use super::pipeline::{DEPTH_FORMAT, HDR_FORMAT, PipelineSpec, render_pipeline, storage_ro};
use crate::gpu::layout;
use crate::shaders;

/// Draws the environment (or a solid test colour) behind everything.
pub struct SkyPass {
    pipeline: wgpu::RenderPipeline,
    bind_group: wgpu::BindGroup,
}

impl SkyPass {
    /// Builds the pass reading `frame` and the full-resolution environment `env`.
    #[must_use]
    pub fn new(device: &wgpu::Device, frame: &wgpu::Buffer, env: &wgpu::Buffer) -> Self {
        let bgl = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("sky"),
            entries: &[layout::uniform(0, wgpu::ShaderStages::FRAGMENT), storage_ro(1, wgpu::ShaderStages::FRAGMENT)],
        });
        let pipeline = render_pipeline(
            device,
            &PipelineSpec {
                label: "sky",
                source: shaders::SKY,
                vertex: "vs_main",
                fragment: Some(("fs_main", HDR_FORMAT)),
                buffers: &[],
                layouts: &[&bgl],
                // Shares the scene pass; never tests or writes depth.
                depth: Some((DEPTH_FORMAT, wgpu::CompareFunction::Always, false)),
                bias: wgpu::DepthBiasState::default(),
                cull: false,
                constants: &[],
            },
        );
        let bind_group = layout::bind_group(device, "sky", &bgl, &[frame.as_entire_binding(), env.as_entire_binding()]);
        Self { pipeline, bind_group }
    }

    /// Draws the sky into the bound colour target (no depth).
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}
