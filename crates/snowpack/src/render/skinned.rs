//! Skinned characters (`shaders/skinned_draw.wgsl`): the meshes the
//! deformation posed this frame ([`crate::snow::inspect::SnowInspect::posed_meshes`]),
//! drawn lit and into the shadow map, with the snow they carry.

use super::pipeline::{DrawSpec, lit_and_shadow};
use crate::shaders;
use crate::skin::skinning::SkinnedInstance;

/// Pipelines for drawing posed skinned meshes.
pub struct SkinnedDrawPass {
    lit: wgpu::RenderPipeline,
    shadow: wgpu::RenderPipeline,
}

const POSITION: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![0 => Float32x3];
/// The snow coat (m a vertex), blended over the fur.
const COAT: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![1 => Float32];

impl SkinnedDrawPass {
    /// Builds both pipelines.
    #[must_use]
    pub fn new(device: &wgpu::Device, lit_layout: &wgpu::BindGroupLayout, shadow_layout: &wgpu::BindGroupLayout) -> Self {
        let buffers = [
            Some(wgpu::VertexBufferLayout { array_stride: 12, step_mode: wgpu::VertexStepMode::Vertex, attributes: &POSITION }),
            Some(wgpu::VertexBufferLayout { array_stride: 4, step_mode: wgpu::VertexStepMode::Vertex, attributes: &COAT }),
        ];
        // Exporters wind triangles either way; cull nothing (the shader faces normals to the eye).
        let (lit, shadow) = lit_and_shadow(
            device,
            &DrawSpec {
                label: "skinned",
                source: shaders::SKINNED_DRAW,
                buffers: &buffers,
                lit_layouts: &[lit_layout],
                shadow_layouts: &[shadow_layout],
                cull: (false, false),
                constants: &[],
            },
        );
        Self { lit, shadow }
    }

    fn draw<'m>(pass: &mut wgpu::RenderPass<'_>, pipeline: &wgpu::RenderPipeline, group: &wgpu::BindGroup, meshes: impl Iterator<Item = &'m SkinnedInstance>) {
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, group, &[]);
        for m in meshes {
            pass.set_vertex_buffer(0, m.skinned.slice(..));
            pass.set_vertex_buffer(1, m.coat.slice(..));
            pass.set_index_buffer(m.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..m.index_count, 0, 0..1);
        }
    }

    /// Draws `meshes` lit.
    pub fn draw_lit<'m>(&self, pass: &mut wgpu::RenderPass<'_>, lit_group: &wgpu::BindGroup, meshes: impl Iterator<Item = &'m SkinnedInstance>) {
        Self::draw(pass, &self.lit, lit_group, meshes);
    }

    /// Draws `meshes` into the shadow map.
    pub fn draw_shadow<'m>(&self, pass: &mut wgpu::RenderPass<'_>, shadow_group: &wgpu::BindGroup, meshes: impl Iterator<Item = &'m SkinnedInstance>) {
        Self::draw(pass, &self.shadow, shadow_group, meshes);
    }
}
