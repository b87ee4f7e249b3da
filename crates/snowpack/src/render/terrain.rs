//! The snow terrain draw: CDLOD patches displaced in the vertex shader
//! (`shaders/terrain_draw.wgsl`), lit in the fragment shader, and drawn again
//! depth-only into the shadow map.

use super::ground::grid_indices;
use super::lod::PatchInstance;
use super::pipeline::{DrawSpec, lit_and_shadow, storage_ro, texture};
use crate::shaders;

/// Instance buffer that grows as needed.
struct Instances {
    buffer: wgpu::Buffer,
    full: u32,
    half: u32,
}

impl Instances {
    fn new(device: &wgpu::Device, label: &str, capacity: u64) -> Self {
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: capacity * size_of::<PatchInstance>() as u64,
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self { buffer, full: 0, half: 0 }
    }

    /// Uploads full patches first, then half patches.
    fn upload(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, label: &str, patches: &[PatchInstance], quads: u32) {
        let mut sorted: Vec<PatchInstance> = patches.iter().filter(|p| p.quads() == quads).copied().collect();
        self.full = sorted.len() as u32;
        sorted.extend(patches.iter().filter(|p| p.quads() != quads));
        self.half = sorted.len() as u32 - self.full;
        let bytes = std::mem::size_of_val(sorted.as_slice()) as u64;
        if bytes > self.buffer.size() {
            *self = Self::new(device, label, (sorted.len() as u64).next_power_of_two());
            self.full = sorted.len() as u32 - self.half;
        }
        queue.write_buffer(&self.buffer, 0, bytemuck::cast_slice(&sorted));
    }
}

/// The terrain's pipelines, grids and per-frame instances.
pub struct TerrainPass {
    lit: wgpu::RenderPipeline,
    shadow: wgpu::RenderPipeline,
    full_indices: wgpu::Buffer,
    half_indices: wgpu::Buffer,
    quads: u32,
    main: Instances,
    caster: Instances,
    /// Group 1 layout: surface, heightmap, terrain params, AO, decal layer.
    pub snow_layout: wgpu::BindGroupLayout,
}

const INSTANCE_ATTRIBUTES: [wgpu::VertexAttribute; 2] = wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4];

impl TerrainPass {
    /// Builds both pipelines for patches of `quads`² quads, for a terrain of
    /// `terrain_kind` (`DeformResources::terrain_kind`).
    #[must_use]
    pub fn new(device: &wgpu::Device, lit_layout: &wgpu::BindGroupLayout, shadow_layout: &wgpu::BindGroupLayout, quads: u32, terrain_kind: u32) -> Self {
        let vf = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let snow_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("terrain snow"),
            entries: &[
                storage_ro(0, vf),
                storage_ro(1, vf),
                crate::gpu::layout::uniform(2, vf),
                storage_ro(3, wgpu::ShaderStages::FRAGMENT),
                texture(4, wgpu::ShaderStages::FRAGMENT, false),
                storage_ro(5, wgpu::ShaderStages::FRAGMENT),
            ],
        });
        let buffers = [Some(wgpu::VertexBufferLayout {
            array_stride: size_of::<PatchInstance>() as u64,
            step_mode: wgpu::VertexStepMode::Instance,
            attributes: &INSTANCE_ATTRIBUTES,
        })];
        // The terrain is a height field: its back faces never face the sun, so the shadow pass culls nothing.
        let (lit, shadow) = lit_and_shadow(
            device,
            &DrawSpec {
                label: "terrain",
                source: shaders::TERRAIN_DRAW,
                buffers: &buffers,
                lit_layouts: &[lit_layout, &snow_layout],
                shadow_layouts: &[shadow_layout, &snow_layout],
                cull: (true, false),
                constants: &[("TERRAIN_KIND", f64::from(terrain_kind))],
            },
        );
        let index_buffer = |label: &str, q: u32| {
            use wgpu::util::DeviceExt as _;
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(&grid_indices(q)),
                usage: wgpu::BufferUsages::INDEX,
            })
        };
        Self {
            lit,
            shadow,
            full_indices: index_buffer("patch grid", quads),
            half_indices: index_buffer("half patch grid", quads / 2),
            quads,
            main: Instances::new(device, "patches", 1024),
            caster: Instances::new(device, "shadow patches", 1024),
            snow_layout,
        }
    }

    /// Uploads this frame's visible and shadow-casting patches.
    pub fn prepare(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, visible: &[PatchInstance], casters: &[PatchInstance]) {
        self.main.upload(device, queue, "patches", visible, self.quads);
        self.caster.upload(device, queue, "shadow patches", casters, self.quads);
    }

    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, instances: &Instances) {
        let full = self.quads * self.quads * 6;
        let half = (self.quads / 2) * (self.quads / 2) * 6;
        pass.set_vertex_buffer(0, instances.buffer.slice(..));
        if instances.full > 0 {
            pass.set_index_buffer(self.full_indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..full, 0, 0..instances.full);
        }
        if instances.half > 0 {
            pass.set_index_buffer(self.half_indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..half, 0, instances.full..instances.full + instances.half);
        }
    }

    /// Draws the visible patches lit (group 0 and 1 bound by the caller's arguments).
    pub fn draw_lit(&self, pass: &mut wgpu::RenderPass<'_>, frame: &wgpu::BindGroup, snow: &wgpu::BindGroup) {
        pass.set_pipeline(&self.lit);
        pass.set_bind_group(0, frame, &[]);
        pass.set_bind_group(1, snow, &[]);
        self.draw(pass, &self.main);
    }

    /// Draws the casting patches into the shadow map.
    pub fn draw_shadow(&self, pass: &mut wgpu::RenderPass<'_>, frame: &wgpu::BindGroup, snow: &wgpu::BindGroup) {
        pass.set_pipeline(&self.shadow);
        pass.set_bind_group(0, frame, &[]);
        pass.set_bind_group(1, snow, &[]);
        self.draw(pass, &self.caster);
    }
}

#[cfg(test)]
mod tests {
    use super::super::ground::grid_indices;

    #[test]
    fn grid_triangles_face_up() {
        let q = 4u32;
        let idx = grid_indices(q);
        assert_eq!(idx.len(), (q * q * 6) as usize);
        let pos = |i: u32| glam::Vec3::new((i % (q + 1)) as f32, 0.0, (i / (q + 1)) as f32);
        for t in idx.chunks(3) {
            let n = (pos(t[1]) - pos(t[0])).cross(pos(t[2]) - pos(t[0]));
            assert!(n.y > 0.0, "triangle {t:?} faces down");
        }
    }
}
