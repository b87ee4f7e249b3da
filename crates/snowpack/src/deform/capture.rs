//! Capture pass: actors' lowest surfaces, drawn from below into a depth target.
//!
//! An orthographic camera below the terrain looks up over the window; depth is
//! linear in world height between `low_m` (depth 0) and `high_m` (depth 1), so
//! the depth test keeps the lowest surface per texel. Spheres are impostor
//! quads writing their exact lower surface; boxes (and meshes in general) are
//! instanced triangles. Actors outside the window leave no mark.

use bytemuck::{Pod, Zeroable};
use glam::{DVec2, Mat4, Vec3};

use crate::gpu::{GpuTimer, layout};
use crate::height_depth::CAPTURE_FORMAT;
use crate::{Deformer, shaders};

use super::resources::DeformResources;

/// Uniforms of `capture_sphere.wgsl` and `capture_mesh.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct CaptureParams {
    /// Side of the window (m).
    pub extent_m: f32,
    /// Texel size (m).
    pub texel_m: f32,
    /// World height at depth 0 (m).
    pub low_m: f32,
    /// World height at depth 1 (m).
    pub high_m: f32,
}

impl CaptureParams {
    /// World height of a captured depth value; `None` for the cleared value 1.
    #[must_use]
    pub fn height_of_depth(&self, depth: f32) -> Option<f32> {
        (depth < 1.0).then_some(self.low_m + depth * (self.high_m - self.low_m))
    }
}

/// Unit cube, corners at ±1: 8 vertices, 12 triangles.
const CUBE_VERTICES: [[f32; 3]; 8] =
    [[-1.0, -1.0, -1.0], [1.0, -1.0, -1.0], [1.0, 1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]];
const CUBE_INDICES: [u16; 36] = [0, 1, 2, 0, 2, 3, 4, 6, 5, 4, 7, 6, 0, 4, 5, 0, 5, 1, 3, 2, 6, 3, 6, 7, 0, 3, 7, 0, 7, 4, 1, 5, 6, 1, 6, 2];

/// Instances prepared for one frame, in window-local coordinates.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CaptureInstances {
    /// (x, y, z, radius) per sphere; x and z relative to the window's corner.
    pub spheres: Vec<[f32; 4]>,
    /// Column-major model matrix per box, mapping the unit cube to window-local space.
    pub boxes: Vec<[f32; 16]>,
    /// World to window-local space (a translation by minus the corner), for meshes given in world space.
    pub window_offset: [f32; 16],
}

/// A triangle mesh already in world space this frame (a skinned character in
/// pose, from [`crate::skin::skinning::SkinningPass`]), drawn into the capture.
#[derive(Clone, Copy, Debug)]
pub struct CaptureMesh<'a> {
    /// World positions, packed xyz f32 (12 bytes a vertex), with `VERTEX` usage.
    pub vertices: &'a wgpu::Buffer,
    /// Triangle list, u32 indices, with `INDEX` usage.
    pub indices: &'a wgpu::Buffer,
    /// Number of indices to draw.
    pub index_count: u32,
    /// Number of vertices, each also drawn as a point (see [`CapturePass`]).
    pub vertex_count: u32,
}

impl CaptureInstances {
    /// Window-local instances of the deformers that can touch the window:
    /// footprint overlapping it and lowest point below `high_m`.
    #[must_use]
    pub fn new(deformers: &[Deformer], window_corner_m: DVec2, params: &CaptureParams) -> Self {
        let offset = Vec3::new(-window_corner_m.x as f32, 0.0, -window_corner_m.y as f32);
        let mut out = Self { window_offset: Mat4::from_translation(offset).to_cols_array(), ..Self::default() };
        let extent = f64::from(params.extent_m);
        let local = |c: Vec3| Vec3::new((f64::from(c.x) - window_corner_m.x) as f32, c.y, (f64::from(c.z) - window_corner_m.y) as f32);
        for d in deformers {
            if d.lowest_point() >= params.high_m {
                continue;
            }
            match *d {
                Deformer::Sphere { center, radius } => {
                    let c = local(center);
                    let r = f64::from(radius);
                    let outside = f64::from(c.x) + r < 0.0 || f64::from(c.x) - r > extent || f64::from(c.z) + r < 0.0 || f64::from(c.z) - r > extent;
                    if !outside && radius > 0.0 {
                        out.spheres.push([c.x, c.y, c.z, radius]);
                    }
                }
                Deformer::Box { center, half_extents, rotation } => {
                    let c = local(center);
                    let reach = f64::from(half_extents.length());
                    let outside =
                        f64::from(c.x) + reach < 0.0 || f64::from(c.x) - reach > extent || f64::from(c.z) + reach < 0.0 || f64::from(c.z) - reach > extent;
                    if !outside {
                        out.boxes.push(Mat4::from_scale_rotation_translation(half_extents, rotation, c).to_cols_array());
                    }
                }
                // Points have no surface to draw; only the stamp pass uses them.
                Deformer::Point { .. } => {}
            }
        }
        out
    }
}

fn growable(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(256),
        usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Draws deformers into the capture depth target.
pub struct CapturePass {
    sphere_pipeline: wgpu::RenderPipeline,
    mesh_pipeline: wgpu::RenderPipeline,
    /// The meshes' vertices again as points: a paw or a leg thinner than a
    /// texel can fall between texel centres and leave no print at all; a
    /// point always marks the texel it lies in, so every vertex prints.
    mesh_point_pipeline: wgpu::RenderPipeline,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    sphere_instances: wgpu::Buffer,
    box_instances: wgpu::Buffer,
    cube_vertices: wgpu::Buffer,
    cube_indices: wgpu::Buffer,
    counts: (u32, u32),
}

fn depth_state() -> wgpu::DepthStencilState {
    wgpu::DepthStencilState {
        format: CAPTURE_FORMAT,
        depth_write_enabled: Some(true),
        depth_compare: Some(wgpu::CompareFunction::Less),
        stencil: wgpu::StencilState::default(),
        bias: wgpu::DepthBiasState::default(),
    }
}

impl CapturePass {
    /// Builds both pipelines.
    #[must_use]
    pub fn new(device: &wgpu::Device) -> Self {
        use wgpu::util::DeviceExt as _;
        let bgl = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("capture"),
            entries: &[layout::uniform(0, wgpu::ShaderStages::VERTEX_FRAGMENT)],
        });
        let pipeline_layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor { label: Some("capture"), bind_group_layouts: &[Some(&bgl)], immediate_size: 0 });
        // Seen from below, front and back faces swap; cull nothing and let the depth test choose.
        let primitive = wgpu::PrimitiveState { cull_mode: None, ..Default::default() };
        let sphere_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("capture spheres"),
            source: wgpu::ShaderSource::Wgsl(shaders::CAPTURE_SPHERE.into()),
        });
        let sphere_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("capture spheres"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &sphere_module,
                entry_point: Some("vs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: 16,
                    step_mode: wgpu::VertexStepMode::Instance,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x4],
                })],
            },
            primitive,
            depth_stencil: Some(depth_state()),
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &sphere_module,
                entry_point: Some("fs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                targets: &[],
            }),
            multiview_mask: None,
            cache: None,
        });
        let mesh_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("capture meshes"),
            source: wgpu::ShaderSource::Wgsl(shaders::CAPTURE_MESH.into()),
        });
        let mesh_pipeline_with = |label: &str, primitive: wgpu::PrimitiveState| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &mesh_module,
                    entry_point: Some("vs_main"),
                    compilation_options: wgpu::PipelineCompilationOptions::default(),
                    buffers: &[
                        Some(wgpu::VertexBufferLayout {
                            array_stride: 12,
                            step_mode: wgpu::VertexStepMode::Vertex,
                            attributes: &wgpu::vertex_attr_array![0 => Float32x3],
                        }),
                        Some(wgpu::VertexBufferLayout {
                            array_stride: 64,
                            step_mode: wgpu::VertexStepMode::Instance,
                            attributes: &wgpu::vertex_attr_array![1 => Float32x4, 2 => Float32x4, 3 => Float32x4, 4 => Float32x4],
                        }),
                    ],
                },
                primitive,
                depth_stencil: Some(depth_state()),
                multisample: wgpu::MultisampleState::default(),
                fragment: None,
                multiview_mask: None,
                cache: None,
            })
        };
        let mesh_pipeline = mesh_pipeline_with("capture meshes", primitive);
        let mesh_point_pipeline = mesh_pipeline_with("capture mesh points", wgpu::PrimitiveState { topology: wgpu::PrimitiveTopology::PointList, ..primitive });
        let params = layout::uniform_buffer::<CaptureParams>(device, "capture params");
        let bind_group = layout::bind_group(device, "capture", &bgl, &[params.as_entire_binding()]);
        let cube_vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("cube vertices"),
            contents: bytemuck::cast_slice(&CUBE_VERTICES),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let cube_indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("cube indices"),
            contents: bytemuck::cast_slice(&CUBE_INDICES),
            usage: wgpu::BufferUsages::INDEX,
        });
        Self {
            sphere_pipeline,
            mesh_pipeline,
            mesh_point_pipeline,
            params,
            bind_group,
            sphere_instances: growable(device, "sphere instances", 16 * 64),
            box_instances: growable(device, "box instances", 64 * 64),
            cube_vertices,
            cube_indices,
            counts: (0, 0),
        }
    }

    /// Uploads this frame's instances, growing the instance buffers when needed.
    pub fn prepare(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, params: &CaptureParams, inst: &CaptureInstances) {
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let sphere_bytes: &[u8] = bytemuck::cast_slice(&inst.spheres);
        // The boxes' model matrices, then the window offset that world-space meshes use.
        let mut matrices = inst.boxes.clone();
        matrices.push(inst.window_offset);
        let box_bytes: &[u8] = bytemuck::cast_slice(&matrices);
        if sphere_bytes.len() as u64 > self.sphere_instances.size() {
            self.sphere_instances = growable(device, "sphere instances", (sphere_bytes.len() as u64).next_power_of_two());
        }
        if box_bytes.len() as u64 > self.box_instances.size() {
            self.box_instances = growable(device, "box instances", (box_bytes.len() as u64).next_power_of_two());
        }
        queue.write_buffer(&self.sphere_instances, 0, sphere_bytes);
        queue.write_buffer(&self.box_instances, 0, box_bytes);
        self.counts = (inst.spheres.len() as u32, inst.boxes.len() as u32);
    }

    /// Clears the capture target and draws the prepared instances.
    pub fn record(&self, encoder: &mut wgpu::CommandEncoder, timer: &mut GpuTimer, res: &DeformResources) {
        self.record_with_meshes(encoder, timer, res, &[]);
    }

    /// Like [`Self::record`], also drawing world-space `meshes`.
    pub fn record_with_meshes(&self, encoder: &mut wgpu::CommandEncoder, timer: &mut GpuTimer, res: &DeformResources, meshes: &[CaptureMesh<'_>]) {
        let slot = timer.reserve("capture");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("capture"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &res.capture_view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: timer.render_writes(slot),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_bind_group(0, &self.bind_group, &[]);
        if self.counts.0 > 0 {
            pass.set_pipeline(&self.sphere_pipeline);
            pass.set_vertex_buffer(0, self.sphere_instances.slice(..));
            pass.draw(0..6, 0..self.counts.0);
        }
        if self.counts.1 > 0 {
            pass.set_pipeline(&self.mesh_pipeline);
            pass.set_vertex_buffer(0, self.cube_vertices.slice(..));
            pass.set_vertex_buffer(1, self.box_instances.slice(..));
            pass.set_index_buffer(self.cube_indices.slice(..), wgpu::IndexFormat::Uint16);
            pass.draw_indexed(0..CUBE_INDICES.len() as u32, 0, 0..self.counts.1);
        }
        if !meshes.is_empty() {
            pass.set_pipeline(&self.mesh_pipeline);
            pass.set_vertex_buffer(1, self.box_instances.slice(..));
            let offset = self.counts.1;
            for mesh in meshes {
                pass.set_vertex_buffer(0, mesh.vertices.slice(..));
                pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..mesh.index_count, 0, offset..offset + 1);
            }
            pass.set_pipeline(&self.mesh_point_pipeline);
            for mesh in meshes {
                pass.set_vertex_buffer(0, mesh.vertices.slice(..));
                pass.draw(0..mesh.vertex_count, offset..offset + 1);
            }
        }
    }
}
