//! The renderer's targets and its lit-and-shadow pipeline pairs; the
//! generic builders live in [`crate::gpu::render`] and are re-exported here.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

pub use crate::gpu::render::{PipelineSpec, entry, render_pipeline, screen_target, storage_ro, texture};

/// Colour format of the HDR scene target.
pub const HDR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
/// Depth format of the scene (reverse-Z: cleared to 0, nearer is greater).
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The two pipelines of a drawn thing, from one shader: lit (`vs_main`,
/// `fs_main` into the HDR target, reverse-Z) and into the sun's shadow map
/// (`vs_shadow`, depth only, biased against acne).
#[cfg(feature = "renderer")]
pub struct DrawSpec<'a> {
    /// Label of the lit pipeline (the shadow one adds " shadow").
    pub label: &'a str,
    /// WGSL source with `vs_main`, `fs_main` and `vs_shadow`.
    pub source: &'a str,
    /// Vertex buffers.
    pub buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
    /// Bind group layouts of the lit pipeline.
    pub lit_layouts: &'a [&'a wgpu::BindGroupLayout],
    /// Bind group layouts of the shadow pipeline.
    pub shadow_layouts: &'a [&'a wgpu::BindGroupLayout],
    /// Back-face culling of the lit and of the shadow pipeline.
    pub cull: (bool, bool),
    /// Values of the shader's `override` constants, in both pipelines.
    pub constants: &'a [(&'a str, f64)],
}

#[cfg(feature = "renderer")]
/// Builds the lit and the shadow pipeline of `spec`.
#[must_use]
pub fn lit_and_shadow(device: &wgpu::Device, spec: &DrawSpec<'_>) -> (wgpu::RenderPipeline, wgpu::RenderPipeline) {
    let lit = render_pipeline(
        device,
        &PipelineSpec {
            label: spec.label,
            source: spec.source,
            vertex: "vs_main",
            fragment: Some(("fs_main", HDR_FORMAT)),
            buffers: spec.buffers,
            layouts: spec.lit_layouts,
            depth: Some((DEPTH_FORMAT, wgpu::CompareFunction::Greater, true)),
            bias: wgpu::DepthBiasState::default(),
            cull: spec.cull.0,
            constants: spec.constants,
        },
    );
    let shadow_label = format!("{} shadow", spec.label);
    let shadow = render_pipeline(
        device,
        &PipelineSpec {
            label: &shadow_label,
            source: spec.source,
            vertex: "vs_shadow",
            fragment: None,
            buffers: spec.buffers,
            layouts: spec.shadow_layouts,
            depth: Some((super::shadow::SHADOW_FORMAT, wgpu::CompareFunction::Less, true)),
            bias: wgpu::DepthBiasState { constant: 2, slope_scale: 2.0, clamp: 0.0 },
            cull: spec.cull.1,
            constants: spec.constants,
        },
    );
    (lit, shadow)
}
