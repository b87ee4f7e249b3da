//! Actors drawn: spheres and boxes as instanced meshes (`shaders/actor_draw.wgsl`),
//! lit like the snow and casting into the shadow map.

use glam::{Mat3, Mat4, Quat, Vec3};

use super::pipeline::{DrawSpec, lit_and_shadow};
use crate::Deformer;
use crate::shaders;
use crate::deform::shape::DeformerExt;

/// One mesh vertex.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct MeshVertex {
    /// Position.
    pub position: [f32; 3],
    /// Unit normal.
    pub normal: [f32; 3],
}

/// One actor instance.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ActorInstance {
    /// Model matrix columns.
    pub model: [[f32; 4]; 4],
    /// Inverse-transpose of the model's upper 3x3, as three padded columns.
    pub normal: [[f32; 4]; 3],
    /// Albedo rgb, roughness.
    pub colour: [f32; 4],
}

impl ActorInstance {
    fn new(model: Mat4, colour: [f32; 4]) -> Self {
        let n = Mat3::from_mat4(model).inverse().transpose();
        Self {
            model: model.to_cols_array_2d(),
            normal: [n.x_axis.extend(0.0).to_array(), n.y_axis.extend(0.0).to_array(), n.z_axis.extend(0.0).to_array()],
            colour,
        }
    }
}

/// Sphere albedo and roughness: a matte red ball stands out on snow.
const SPHERE_COLOUR: [f32; 4] = [0.5, 0.09, 0.06, 0.45];
/// Box albedo and roughness: weathered wood.
const BOX_COLOUR: [f32; 4] = [0.36, 0.24, 0.14, 0.7];

/// A unit UV sphere.
#[must_use]
pub fn sphere_mesh(segments: u32, rings: u32) -> (Vec<MeshVertex>, Vec<u32>) {
    let mut v = Vec::new();
    for r in 0..=rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..=segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            let p = Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
            v.push(MeshVertex { position: p.to_array(), normal: p.to_array() });
        }
    }
    let mut idx = Vec::new();
    let row = segments + 1;
    for r in 0..rings {
        for s in 0..segments {
            let a = r * row + s;
            let (b, c, d) = (a + 1, a + row, a + row + 1);
            idx.extend_from_slice(&[a, b, c, b, d, c]);
        }
    }
    (v, idx)
}

/// A cube from -1 to 1 with flat faces.
#[must_use]
pub fn box_mesh() -> (Vec<MeshVertex>, Vec<u32>) {
    let mut v = Vec::new();
    let mut idx = Vec::new();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n = Vec3::ZERO;
            n[axis] = sign;
            let u = Vec3::from_array(std::array::from_fn(|k| if k == (axis + 1) % 3 { 1.0 } else { 0.0 }));
            let w = n.cross(u);
            let base = v.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                v.push(MeshVertex { position: (n + u * a + w * b).to_array(), normal: n.to_array() });
            }
            idx.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }
    (v, idx)
}

struct Mesh {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    count: u32,
}

fn mesh(device: &wgpu::Device, label: &str, (v, i): (Vec<MeshVertex>, Vec<u32>)) -> Mesh {
    use wgpu::util::DeviceExt as _;
    let make = |usage, contents: &[u8]| device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage });
    Mesh {
        vertices: make(wgpu::BufferUsages::VERTEX, bytemuck::cast_slice(&v)),
        indices: make(wgpu::BufferUsages::INDEX, bytemuck::cast_slice(&i)),
        count: i.len() as u32,
    }
}

/// Pipelines, meshes and per-frame instances of the actors.
pub struct ActorPass {
    lit: wgpu::RenderPipeline,
    shadow: wgpu::RenderPipeline,
    sphere: Mesh,
    cube: Mesh,
    instances: wgpu::Buffer,
    spheres: u32,
    boxes: u32,
}

const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 2] = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3];
const INSTANCE_ATTRIBUTES: [wgpu::VertexAttribute; 8] = wgpu::vertex_attr_array![
    2 => Float32x4, 3 => Float32x4, 4 => Float32x4, 5 => Float32x4,
    6 => Float32x4, 7 => Float32x4, 8 => Float32x4, 9 => Float32x4
];

impl ActorPass {
    /// Builds the pipelines and meshes.
    #[must_use]
    pub fn new(device: &wgpu::Device, lit_layout: &wgpu::BindGroupLayout, shadow_layout: &wgpu::BindGroupLayout, sphere: [u32; 2]) -> Self {
        let buffers = [
            Some(wgpu::VertexBufferLayout {
                array_stride: size_of::<MeshVertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &VERTEX_ATTRIBUTES,
            }),
            Some(wgpu::VertexBufferLayout {
                array_stride: size_of::<ActorInstance>() as u64,
                step_mode: wgpu::VertexStepMode::Instance,
                attributes: &INSTANCE_ATTRIBUTES,
            }),
        ];
        let (lit, shadow) = lit_and_shadow(
            device,
            &DrawSpec {
                label: "actors",
                source: shaders::ACTOR_DRAW,
                buffers: &buffers,
                lit_layouts: &[lit_layout],
                shadow_layouts: &[shadow_layout],
                cull: (true, true),
                constants: &[],
            },
        );
        Self {
            lit,
            shadow,
            sphere: mesh(device, "sphere mesh", sphere_mesh(sphere[0].max(3), sphere[1].max(2))),
            cube: mesh(device, "box mesh", box_mesh()),
            instances: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("actor instances"),
                size: 64 * size_of::<ActorInstance>() as u64,
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            spheres: 0,
            boxes: 0,
        }
    }

    /// Uploads this frame's actors: spheres first, then boxes; contact points are not drawn.
    pub fn prepare(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, actors: &[Deformer]) {
        let mut list: Vec<ActorInstance> = actors
            .iter()
            .filter_map(|a| match *a {
                Deformer::Sphere { center, radius } => {
                    Some(ActorInstance::new(Mat4::from_scale_rotation_translation(Vec3::splat(radius), Quat::IDENTITY, center), SPHERE_COLOUR))
                }
                _ => None,
            })
            .collect();
        self.spheres = list.len() as u32;
        list.extend(actors.iter().filter_map(|a| match *a {
            Deformer::Box { center, half_extents, rotation } => Some(ActorInstance::new(Deformer::box_matrix(center, half_extents, rotation), BOX_COLOUR)),
            _ => None,
        }));
        self.boxes = list.len() as u32 - self.spheres;
        let bytes = std::mem::size_of_val(list.as_slice()) as u64;
        if bytes > self.instances.size() {
            self.instances = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("actor instances"),
                size: bytes.next_power_of_two(),
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
        }
        queue.write_buffer(&self.instances, 0, bytemuck::cast_slice(&list));
    }

    fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        pass.set_vertex_buffer(1, self.instances.slice(..));
        for (mesh, range) in [(&self.sphere, 0..self.spheres), (&self.cube, self.spheres..self.spheres + self.boxes)] {
            if range.is_empty() {
                continue;
            }
            pass.set_vertex_buffer(0, mesh.vertices.slice(..));
            pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..mesh.count, 0, range);
        }
    }

    /// Draws the actors lit.
    pub fn draw_lit(&self, pass: &mut wgpu::RenderPass<'_>, frame: &wgpu::BindGroup) {
        pass.set_pipeline(&self.lit);
        pass.set_bind_group(0, frame, &[]);
        self.draw(pass);
    }

    /// Draws the actors into the shadow map.
    pub fn draw_shadow(&self, pass: &mut wgpu::RenderPass<'_>, frame: &wgpu::BindGroup) {
        pass.set_pipeline(&self.shadow);
        pass.set_bind_group(0, frame, &[]);
        self.draw(pass);
    }

    /// Actors drawn this frame.
    #[must_use]
    pub fn count(&self) -> u32 {
        self.spheres + self.boxes
    }

    /// Triangles drawn this frame.
    #[must_use]
    pub fn triangles(&self) -> u64 {
        u64::from(self.spheres) * u64::from(self.sphere.count / 3) + u64::from(self.boxes) * u64::from(self.cube.count / 3)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meshes_face_outward() {
        for (v, idx) in [sphere_mesh(8, 6), box_mesh()] {
            for t in idx.chunks(3) {
                let p = |k: usize| Vec3::from(v[t[k] as usize].position);
                let n = (p(1) - p(0)).cross(p(2) - p(0));
                if n.length() < 1e-6 {
                    continue; // pole slivers
                }
                let centre = (p(0) + p(1) + p(2)) / 3.0;
                assert!(n.dot(centre) > 0.0, "triangle {t:?} faces inward");
            }
        }
    }
}
