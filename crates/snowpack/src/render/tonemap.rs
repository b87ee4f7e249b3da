//! Exposure and filmic tone mapping (`shaders/tonemap.wgsl`) from the HDR target to the output.

use super::pipeline::{PipelineSpec, render_pipeline, texture};
use crate::gpu::layout;
use crate::shaders;

/// Maps the HDR scene to the output format (an sRGB format encodes on store).
pub struct TonemapPass {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
}

impl TonemapPass {
    /// Builds the pass for an output of `format`.
    #[must_use]
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Self {
        let bgl = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("tonemap"),
            entries: &[layout::uniform(0, wgpu::ShaderStages::FRAGMENT), texture(1, wgpu::ShaderStages::FRAGMENT, false)],
        });
        let pipeline = render_pipeline(
            device,
            &PipelineSpec {
                label: "tonemap",
                source: shaders::TONEMAP,
                vertex: "vs_main",
                fragment: Some(("fs_main", format)),
                buffers: &[],
                layouts: &[&bgl],
                depth: None,
                bias: wgpu::DepthBiasState::default(),
                cull: false,
                constants: &[],
            },
        );
        Self { pipeline, layout: bgl }
    }

    /// The bind group reading `frame` and the HDR view.
    #[must_use]
    pub fn bind_group(&self, device: &wgpu::Device, frame: &wgpu::Buffer, hdr: &wgpu::TextureView) -> wgpu::BindGroup {
        layout::bind_group(device, "tonemap", &self.layout, &[frame.as_entire_binding(), wgpu::BindingResource::TextureView(hdr)])
    }

    /// Draws the full-screen triangle.
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>, bind_group: &wgpu::BindGroup) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}
