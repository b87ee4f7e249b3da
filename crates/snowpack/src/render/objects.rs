//! Accumulation objects drawn with their snow (`shaders/object_draw.wgsl`),
//! lit like the snow and casting into the shadow map.

use super::pipeline::{DrawSpec, lit_and_shadow, storage_ro};
use crate::accumulate::{ObjectVertex, SnowAccumulation};
use crate::gpu::layout;
use crate::shaders;

const ATTRIBUTES: [wgpu::VertexAttribute; 8] = wgpu::vertex_attr_array![
    0 => Float32x3, 1 => Float32x3, 2 => Float32x3, 3 => Float32x3,
    4 => Float32x2, 5 => Float32, 6 => Uint32, 7 => Float32x4
];

/// Pipelines for drawing accumulation objects.
pub struct ObjectDrawPass {
    lit: wgpu::RenderPipeline,
    shadow: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    info: wgpu::Buffer,
    /// The bind group and the object buffer it was made for (a new
    /// accumulation brings new buffers; the same one is bound frame after frame).
    group: Option<(wgpu::Buffer, wgpu::BindGroup)>,
    count: u32,
}

impl ObjectDrawPass {
    /// Builds both pipelines.
    #[must_use]
    pub fn new(device: &wgpu::Device, lit_layout: &wgpu::BindGroupLayout, shadow_layout: &wgpu::BindGroupLayout) -> Self {
        let stages = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("objects"),
            entries: &[storage_ro(0, stages), storage_ro(1, stages), layout::uniform(2, stages)],
        });
        let buffers = [Some(wgpu::VertexBufferLayout {
            array_stride: size_of::<ObjectVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &ATTRIBUTES,
        })];
        let (lit, shadow) = lit_and_shadow(
            device,
            &DrawSpec {
                label: "objects",
                source: shaders::OBJECT_DRAW,
                buffers: &buffers,
                lit_layouts: &[lit_layout, &layout],
                shadow_layouts: &[shadow_layout, &layout],
                cull: (true, true),
                constants: &[],
            },
        );
        let info = layout::uniform_buffer::<[u32; 4]>(device, "atlas info");
        Self { lit, shadow, layout, info, group: None, count: 0 }
    }

    /// Binds this frame's objects (none when `acc` is `None`).
    pub fn prepare(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, acc: Option<&SnowAccumulation>) {
        let Some(acc) = acc else {
            self.count = 0;
            self.group = None;
            return;
        };
        if self.group.as_ref().is_none_or(|(buffer, _)| *buffer != acc.object_buffer) {
            queue.write_buffer(&self.info, 0, bytemuck::bytes_of(&[acc.layout().resolution, 0, 0, 0]));
            let group = layout::bind_group(
                device,
                "objects",
                &self.layout,
                &[acc.object_buffer.as_entire_binding(), acc.surface.as_entire_binding(), self.info.as_entire_binding()],
            );
            self.group = Some((acc.object_buffer.clone(), group));
        }
        self.count = acc.index_count();
    }

    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, pipeline: &wgpu::RenderPipeline, frame: &wgpu::BindGroup, acc: &SnowAccumulation) {
        let Some((_, group)) = &self.group else { return };
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, frame, &[]);
        pass.set_bind_group(1, group, &[]);
        pass.set_vertex_buffer(0, acc.vertices.slice(..));
        pass.set_index_buffer(acc.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..self.count, 0, 0..1);
    }

    /// Draws the objects lit.
    pub fn draw_lit(&self, pass: &mut wgpu::RenderPass<'_>, frame: &wgpu::BindGroup, acc: &SnowAccumulation) {
        self.draw(pass, &self.lit, frame, acc);
    }

    /// Draws the objects into the shadow map.
    pub fn draw_shadow(&self, pass: &mut wgpu::RenderPass<'_>, frame: &wgpu::BindGroup, acc: &SnowAccumulation) {
        self.draw(pass, &self.shadow, frame, acc);
    }

    /// Triangles drawn this frame.
    #[must_use]
    pub fn triangles(&self) -> u64 {
        u64::from(self.count / 3)
    }
}
