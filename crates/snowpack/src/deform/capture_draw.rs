//! The capture's rasterised part (`capture_mesh.wgsl`, and with
//! [`super::capture::ShapeCapture::Raster`] `capture_sphere.wgsl` and
//! `capture_wheel.wgsl`): an orthographic camera below the terrain looks up
//! over the window into the capture depth target, whose depth is linear in
//! world height, so the depth test keeps the lowest surface per texel.
//! Meshes (skinned characters, caller meshes) are always drawn here, swept
//! in sub-steps, their vertices again as points. Drawn, spheres are
//! impostor quads writing their capsule's exact lower surface, tyres
//! impostor quads writing the tyre's, tread included, and boxes instanced
//! unit cubes.

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::height_depth::CAPTURE_FORMAT;
use crate::shaders;

use super::capture_instances::{CaptureInstances, CaptureParams, SweptMesh};
use super::resources::DeformResources;

/// Unit cube, corners at ±1: 8 vertices, 12 triangles.
const CUBE_VERTICES: [[f32; 3]; 8] =
    [[-1.0, -1.0, -1.0], [1.0, -1.0, -1.0], [1.0, 1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]];
const CUBE_INDICES: [u16; 36] = [0, 1, 2, 0, 2, 3, 4, 6, 5, 4, 7, 6, 0, 4, 5, 0, 5, 1, 3, 2, 6, 3, 6, 7, 0, 3, 7, 0, 7, 4, 1, 5, 6, 1, 6, 2];

fn growable(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(256),
        usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Draws into the capture depth target: the meshes, and with
/// [`super::capture::ShapeCapture::Raster`] the analytic shapes too.
pub struct CaptureDrawPass {
    sphere_pipeline: wgpu::RenderPipeline,
    wheel_pipeline: wgpu::RenderPipeline,
    mesh_pipeline: wgpu::RenderPipeline,
    /// World-space meshes, each vertex between its last and this frame's position.
    swept_pipeline: wgpu::RenderPipeline,
    /// The meshes' vertices again as points: a paw or a leg thinner than a
    /// texel can fall between texel centres and leave no print at all; a
    /// point always marks the texel it lies in, so every vertex prints.
    swept_point_pipeline: wgpu::RenderPipeline,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    capsule_instances: wgpu::Buffer,
    box_instances: wgpu::Buffer,
    wheel_instances: wgpu::Buffer,
    /// Per mesh sub-step: (corner x, corner z, t, 0); entry 0 is t = 1.
    step_instances: wgpu::Buffer,
    /// First entry in `step_instances` and sub-steps of each prepared mesh.
    mesh_steps: Vec<(u32, u32)>,
    cube_vertices: wgpu::Buffer,
    cube_indices: wgpu::Buffer,
    /// Capsules, boxes and wheel poses prepared.
    counts: (u32, u32, u32),
    /// This frame's `step_instances`, kept for its memory.
    step_data: Vec<[f32; 4]>,
    /// What `params` and `step_instances` last had written, so an unchanged
    /// frame writes neither.
    written: (Option<CaptureParams>, Vec<[f32; 4]>),
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

/// The unit cube's vertex and index buffers (boxes are drawn as instances of it).
fn cube_buffers(device: &wgpu::Device) -> (wgpu::Buffer, wgpu::Buffer) {
    use wgpu::util::DeviceExt as _;
    let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("cube vertices"),
        contents: bytemuck::cast_slice(&CUBE_VERTICES),
        usage: wgpu::BufferUsages::VERTEX,
    });
    let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("cube indices"),
        contents: bytemuck::cast_slice(&CUBE_INDICES),
        usage: wgpu::BufferUsages::INDEX,
    });
    (vertices, indices)
}

/// A depth-only capture pipeline: `vertex` (entry point and buffers) of
/// `module`, with its `fs_main` (no colour target) when `fragment`.
fn capture_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::PipelineLayout,
    label: &str,
    module: &wgpu::ShaderModule,
    (entry, buffers): (&str, &[Option<wgpu::VertexBufferLayout<'_>>]),
    primitive: wgpu::PrimitiveState,
    fragment: bool,
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        vertex: wgpu::VertexState { module, entry_point: Some(entry), compilation_options: wgpu::PipelineCompilationOptions::default(), buffers },
        primitive,
        depth_stencil: Some(depth_state()),
        multisample: wgpu::MultisampleState::default(),
        fragment: fragment.then(|| wgpu::FragmentState {
            module,
            entry_point: Some("fs_main"),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            targets: &[],
        }),
        multiview_mask: None,
        cache: None,
    })
}

impl CaptureDrawPass {
    /// Builds the pipelines (the shapes' too: the capture may switch to drawing them).
    #[must_use]
    pub fn new(device: &wgpu::Device) -> Self {
        let bgl = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("capture"),
            entries: &[layout::uniform(0, wgpu::ShaderStages::VERTEX_FRAGMENT)],
        });
        let pipeline_layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor { label: Some("capture"), bind_group_layouts: &[Some(&bgl)], immediate_size: 0 });
        // Seen from below, front and back faces swap; cull nothing and let the depth test choose.
        let primitive = wgpu::PrimitiveState { cull_mode: None, ..Default::default() };
        let module = |label: &str, source: &str| {
            device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(source.into()) })
        };
        let pipeline = |label: &str, module: &wgpu::ShaderModule, vertex: (&str, &[Option<wgpu::VertexBufferLayout<'_>>]), primitive, fragment| {
            capture_pipeline(device, &pipeline_layout, label, module, vertex, primitive, fragment)
        };
        let sphere_module = module("capture spheres", shaders::CAPTURE_SPHERE);
        let sphere_instances = [Some(wgpu::VertexBufferLayout {
            array_stride: 32,
            step_mode: wgpu::VertexStepMode::Instance,
            attributes: &wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4],
        })];
        let sphere_pipeline = pipeline("capture spheres", &sphere_module, ("vs_main", &sphere_instances), primitive, true);
        let wheel_module = module("capture wheels", shaders::CAPTURE_WHEEL);
        let wheel_instances = [Some(wgpu::VertexBufferLayout {
            array_stride: 64,
            step_mode: wgpu::VertexStepMode::Instance,
            attributes: &wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4, 2 => Float32x4, 3 => Float32x4],
        })];
        let wheel_pipeline = pipeline("capture wheels", &wheel_module, ("vs_main", &wheel_instances), primitive, true);
        let mesh_module = module("capture meshes", shaders::CAPTURE_MESH);
        let positions =
            wgpu::VertexBufferLayout { array_stride: 12, step_mode: wgpu::VertexStepMode::Vertex, attributes: &wgpu::vertex_attr_array![0 => Float32x3] };
        let box_buffers = [
            Some(positions.clone()),
            Some(wgpu::VertexBufferLayout {
                array_stride: 64,
                step_mode: wgpu::VertexStepMode::Instance,
                attributes: &wgpu::vertex_attr_array![1 => Float32x4, 2 => Float32x4, 3 => Float32x4, 4 => Float32x4],
            }),
        ];
        let mesh_pipeline = pipeline("capture boxes", &mesh_module, ("vs_main", &box_buffers), primitive, false);
        let swept_buffers = [
            Some(positions),
            Some(wgpu::VertexBufferLayout {
                array_stride: 16,
                step_mode: wgpu::VertexStepMode::Instance,
                attributes: &wgpu::vertex_attr_array![1 => Float32x4],
            }),
            Some(wgpu::VertexBufferLayout { array_stride: 12, step_mode: wgpu::VertexStepMode::Vertex, attributes: &wgpu::vertex_attr_array![5 => Float32x3] }),
        ];
        let swept_pipeline = pipeline("capture meshes", &mesh_module, ("vs_swept", &swept_buffers), primitive, false);
        let points = wgpu::PrimitiveState { topology: wgpu::PrimitiveTopology::PointList, ..primitive };
        let swept_point_pipeline = pipeline("capture mesh points", &mesh_module, ("vs_swept", &swept_buffers), points, false);
        let params = layout::uniform_buffer::<CaptureParams>(device, "capture params");
        let bind_group = layout::bind_group(device, "capture", &bgl, &[params.as_entire_binding()]);
        let (cube_vertices, cube_indices) = cube_buffers(device);
        Self {
            sphere_pipeline,
            wheel_pipeline,
            mesh_pipeline,
            swept_pipeline,
            swept_point_pipeline,
            params,
            bind_group,
            capsule_instances: growable(device, "capsule instances", 32 * 64),
            box_instances: growable(device, "box instances", 64 * 64),
            wheel_instances: growable(device, "wheel instances", 64 * 64),
            step_instances: growable(device, "mesh step instances", 16 * 64),
            mesh_steps: Vec::new(),
            cube_vertices,
            cube_indices,
            counts: (0, 0, 0),
            step_data: Vec::new(),
            written: (None, Vec::new()),
        }
    }

    /// Records this frame's draw: uploads `params` and, when `shapes`, the
    /// analytic shapes of `inst` (growing their buffers when needed), clears
    /// the capture depth target and draws them and `meshes`, mesh k swept
    /// over the sub-steps [`CaptureInstances::mesh_steps`]`[k]` where it
    /// has previous positions.
    pub fn record(
        &mut self,
        cx: &mut FrameContext<'_>,
        res: &DeformResources,
        (params, inst): (&CaptureParams, &CaptureInstances),
        meshes: &[SweptMesh<'_>],
        shapes: bool,
    ) {
        self.upload(cx.device(), cx.queue(), params, inst, shapes);
        self.draw(cx, res, meshes);
    }

    /// Uploads this frame's instances, growing the instance buffers when needed.
    fn upload(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, params: &CaptureParams, inst: &CaptureInstances, shapes: bool) {
        if self.written.0 != Some(*params) {
            queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
            self.written.0 = Some(*params);
        }
        // Without the shapes, their lists are empty: nothing uploaded or drawn.
        let (capsules, boxes, wheels) = if shapes { (&inst.capsules[..], &inst.boxes[..], &inst.wheels[..]) } else { (&[][..], &[][..], &[][..]) };
        let capsule_bytes: &[u8] = bytemuck::cast_slice(capsules);
        let box_bytes: &[u8] = bytemuck::cast_slice(boxes);
        let wheel_bytes: &[u8] = bytemuck::cast_slice(wheels);
        // Entry 0 is every unswept mesh's only draw; then each swept mesh's steps.
        let [cx, cz] = inst.corner_m;
        let mut steps = std::mem::take(&mut self.step_data);
        steps.clear();
        steps.push([cx, cz, 1.0, 0.0]);
        self.mesh_steps.clear();
        for &n in &inst.mesh_steps {
            if n == 0 {
                self.mesh_steps.push((0, 0));
                continue;
            }
            self.mesh_steps.push((steps.len() as u32, n));
            steps.extend((0..=n).map(|k| [cx, cz, k as f32 / n as f32, 0.0]));
        }
        // The steps are the same every frame without meshes: written once.
        let steps_changed = self.written.1 != steps;
        let step_bytes: &[u8] = if steps_changed { bytemuck::cast_slice(&steps) } else { &[] };
        for (buffer, bytes, label) in [
            (&mut self.capsule_instances, capsule_bytes, "capsule instances"),
            (&mut self.box_instances, box_bytes, "box instances"),
            (&mut self.wheel_instances, wheel_bytes, "wheel instances"),
            (&mut self.step_instances, step_bytes, "mesh step instances"),
        ] {
            // An empty list draws nothing: its buffer is not read.
            if bytes.is_empty() {
                continue;
            }
            if bytes.len() as u64 > buffer.size() {
                *buffer = growable(device, label, (bytes.len() as u64).next_power_of_two());
            }
            queue.write_buffer(buffer, 0, bytes);
        }
        if steps_changed {
            self.written.1.clear();
            self.written.1.extend_from_slice(&steps);
        }
        self.counts = (capsules.len() as u32, boxes.len() as u32, wheels.len() as u32);
        self.step_data = steps;
    }

    /// Clears the capture target and draws the uploaded instances and `meshes`.
    fn draw<'a>(&self, cx: &mut FrameContext<'_>, res: &DeformResources, meshes: &[SweptMesh<'a>]) {
        let (encoder, timer) = (&mut *cx.encoder, &mut *cx.timer);
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
            pass.set_vertex_buffer(0, self.capsule_instances.slice(..));
            pass.draw(0..6, 0..self.counts.0);
        }
        if self.counts.1 > 0 {
            pass.set_pipeline(&self.mesh_pipeline);
            pass.set_vertex_buffer(0, self.cube_vertices.slice(..));
            pass.set_vertex_buffer(1, self.box_instances.slice(..));
            pass.set_index_buffer(self.cube_indices.slice(..), wgpu::IndexFormat::Uint16);
            pass.draw_indexed(0..CUBE_INDICES.len() as u32, 0, 0..self.counts.1);
        }
        if self.counts.2 > 0 {
            pass.set_pipeline(&self.wheel_pipeline);
            pass.set_vertex_buffer(0, self.wheel_instances.slice(..));
            pass.draw(0..6, 0..self.counts.2);
        }
        if meshes.is_empty() {
            return;
        }
        // (previous positions, instances) of mesh k: itself and t = 1 when not swept.
        let steps = &self.mesh_steps;
        let draw_of = |k: usize, m: &SweptMesh<'a>| -> (&'a wgpu::Buffer, std::ops::Range<u32>) {
            match (m.previous, steps.get(k).copied()) {
                (Some(prev), Some((first, n))) if n > 0 => (prev, first..first + n + 1),
                _ => (m.mesh.vertices, 0..1),
            }
        };
        pass.set_vertex_buffer(1, self.step_instances.slice(..));
        pass.set_pipeline(&self.swept_pipeline);
        for (k, m) in meshes.iter().enumerate() {
            let (prev, instances) = draw_of(k, m);
            pass.set_vertex_buffer(0, m.mesh.vertices.slice(..));
            pass.set_vertex_buffer(2, prev.slice(..));
            pass.set_index_buffer(m.mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..m.mesh.index_count, 0, instances);
        }
        pass.set_pipeline(&self.swept_point_pipeline);
        for (k, m) in meshes.iter().enumerate() {
            let (prev, instances) = draw_of(k, m);
            pass.set_vertex_buffer(0, m.mesh.vertices.slice(..));
            pass.set_vertex_buffer(2, prev.slice(..));
            pass.draw(0..m.mesh.vertex_count, instances);
        }
    }
}
