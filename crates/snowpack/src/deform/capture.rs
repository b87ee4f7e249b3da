//! Capture pass: actors' lowest surfaces, seen from below the terrain.
//!
//! Depth is linear in world height between `low_m` (depth 0) and `high_m`
//! (depth 1), quantised to 16-bit codes, and the lowest surface per texel
//! wins. The analytic shapes (spheres, tyres with their tread, boxes) are
//! ray cast exactly by compute ([`super::capture_shapes`]); meshes
//! (skinned characters, caller meshes) are drawn as triangles into the
//! capture depth target. The update takes the lower of the two. Every
//! deformer is swept over its motion since the last frame (see
//! [`super::sweep`]): spheres as capsules, boxes, tyres and meshes in
//! sub-steps. Actors outside the window leave no mark.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use bytemuck::{Pod, Zeroable};
use glam::{DVec2, Mat4, Vec3};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::height_depth::CAPTURE_FORMAT;
use crate::{Deformer, shaders};

use super::capture_shapes::{ShapeCapturePass, Shapes};
use super::resources::DeformResources;
use super::update::UpdateParams;
use crate::deform::shape::DeformerExt;

/// What a capture covers: the window, its texels and the height range of
/// its depth (`capture_mesh.wgsl`'s uniforms; [`super::capture_shapes::ShapeParams`] carries the same).
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

/// Instances prepared for one frame, in window-local coordinates.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CaptureInstances {
    /// Per sphere, swept from `a` (last frame) to `b` (this frame):
    /// `[ax, ay, az, radius, bx, by, bz, 0]`, x and z relative to the
    /// window's corner; `a == b` for a sphere that is not swept.
    pub capsules: Vec<[f32; 8]>,
    /// Column-major model matrix per box (and per sub-step of a swept box),
    /// mapping the unit cube to window-local space.
    pub boxes: Vec<[f32; 16]>,
    /// Per wheel pose (and per sub-step of a swept wheel), window-local:
    /// see [`super::wheel::instance`].
    pub wheels: Vec<[f32; 16]>,
    /// World (x, z) of the window's corner (window-local 0, 0), relative to
    /// the floating origin, for meshes given in world space.
    pub corner_m: [f32; 2],
    /// Sub-steps of each world-space mesh drawn with
    /// [`CapturePass::record`], in order (0: its current pose only).
    pub mesh_steps: Vec<u32>,
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

/// A world-space mesh with the positions its vertices had last frame: drawn
/// at `steps` sub-steps between them (see `crate::deform::sweep`), plus
/// this frame's pose.
#[derive(Clone, Copy, Debug)]
pub struct SweptMesh<'a> {
    /// This frame's mesh.
    pub mesh: CaptureMesh<'a>,
    /// Last frame's positions of the same vertices (same layout); `None`
    /// draws only this frame's pose.
    pub previous: Option<&'a wgpu::Buffer>,
}

impl CaptureInstances {
    /// Window-local instances of the deformers that can touch the window:
    /// footprint overlapping it and lowest point below `high_m`. Nothing is
    /// swept.
    #[must_use]
    pub fn new(deformers: &[Deformer], window_corner_m: DVec2, params: &CaptureParams) -> Self {
        Self::swept(deformers, &[], window_corner_m, params)
    }

    /// Like [`Self::new`], sweeping deformer k from `previous[k]` where it is
    /// `Some` (see `crate::deform::sweep::DeformerHistory::sweeps`): spheres
    /// as capsules, boxes in sub-steps.
    #[must_use]
    pub fn swept(deformers: &[Deformer], previous: &[Option<Deformer>], window_corner_m: DVec2, params: &CaptureParams) -> Self {
        let mut out = Self::default();
        out.fill_swept(deformers, previous, window_corner_m, params);
        out
    }

    /// [`Self::swept`] into `self`, reusing its lists' memory (a frame
    /// after the first allocates nothing unless it has more instances);
    /// `mesh_steps` is left as it was.
    pub fn fill_swept(&mut self, deformers: &[Deformer], previous: &[Option<Deformer>], window_corner_m: DVec2, params: &CaptureParams) {
        self.corner_m = [window_corner_m.x as f32, window_corner_m.y as f32];
        self.capsules.clear();
        self.boxes.clear();
        self.wheels.clear();
        let out = self;
        let extent = f64::from(params.extent_m);
        let local = |c: Vec3| Vec3::new((f64::from(c.x) - window_corner_m.x) as f32, c.y, (f64::from(c.z) - window_corner_m.y) as f32);
        // Whether the square of half-side `reach` around the segment a..b misses the window.
        let outside = |a: Vec3, b: Vec3, reach: f32| {
            let reach = f64::from(reach);
            let (x0, x1) = (f64::from(a.x.min(b.x)) - reach, f64::from(a.x.max(b.x)) + reach);
            let (z0, z1) = (f64::from(a.z.min(b.z)) - reach, f64::from(a.z.max(b.z)) + reach);
            x1 < 0.0 || x0 > extent || z1 < 0.0 || z0 > extent
        };
        for (k, d) in deformers.iter().enumerate() {
            let prev = previous.get(k).copied().flatten();
            if d.lowest_point().min(prev.map_or(f32::INFINITY, |p| p.lowest_point())) >= params.high_m {
                continue;
            }
            match (*d, prev) {
                (Deformer::Sphere { center, radius }, prev) => {
                    let b = local(center);
                    let a = match prev {
                        Some(Deformer::Sphere { center, .. }) => local(center),
                        _ => b,
                    };
                    if !outside(a, b, radius) && radius > 0.0 {
                        out.capsules.push([a.x, a.y, a.z, radius, b.x, b.y, b.z, 0.0]);
                    }
                }
                (Deformer::Box { center, half_extents, rotation }, prev) => {
                    let now = (local(center), half_extents, rotation);
                    // From `then` in `steps` sub-steps (see `box_poses`), or `now` alone.
                    let (then, steps) = match prev {
                        Some(Deformer::Box { center, half_extents, rotation }) => {
                            let then = (local(center), half_extents, rotation);
                            (then, super::sweep::steps_for(super::sweep::box_travel(then, now), params.texel_m))
                        }
                        _ => (now, 0),
                    };
                    let first = if steps == 0 { now } else { super::sweep::box_pose(then, now, 0, steps) };
                    let reach = half_extents.length();
                    if !outside(first.0, now.0, reach) {
                        let matrix = |(c, h, q): (Vec3, Vec3, glam::Quat)| Mat4::from_scale_rotation_translation(h, q, c).to_cols_array();
                        if steps == 0 {
                            out.boxes.push(matrix(now));
                        } else {
                            out.boxes.extend((0..=steps).map(|k| matrix(super::sweep::box_pose(then, now, k, steps))));
                        }
                    }
                }
                (Deformer::Wheel { center, axle, radius, half_width, tread, roll_m }, prev) => {
                    use super::wheel;
                    let now = (local(center), axle, roll_m);
                    // From `then` in `steps` sub-steps (see `wheel_poses`), or `now` alone.
                    let (then, steps) = match prev.as_ref().and_then(Deformer::wheel_pose) {
                        Some((c, a, roll)) => {
                            let then = (local(c), a, roll);
                            (then, super::sweep::steps_for(wheel::wheel_travel(then, now, radius, half_width), params.texel_m))
                        }
                        None => (now, 0),
                    };
                    let first = if steps == 0 { now } else { wheel::wheel_pose(then, now, 0, steps) };
                    let reach = radius.hypot(half_width);
                    if !outside(first.0, now.0, reach) && radius > 0.0 && half_width > 0.0 {
                        let instance = |(c, a, roll): wheel::WheelPose| wheel::instance(c, a, radius, half_width, &tread, f64::from(roll));
                        if steps == 0 {
                            out.wheels.push(instance(now));
                        } else {
                            out.wheels.extend((0..=steps).map(|k| instance(wheel::wheel_pose(then, now, k, steps))));
                        }
                    }
                }
                // Points have no surface to draw; only the stamp pass uses them.
                (Deformer::Point { .. }, _) => {}
            }
        }
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

/// The capture: the analytic shapes ray cast by compute
/// ([`ShapeCapturePass`]) and the meshes drawn into the capture depth target.
pub struct CapturePass {
    /// Spheres (swept: capsules), tyres and boxes, by compute.
    shapes: ShapeCapturePass,
    /// World-space meshes, each vertex between its last and this frame's position.
    swept_pipeline: wgpu::RenderPipeline,
    /// The meshes' vertices again as points: a paw or a leg thinner than a
    /// texel can fall between texel centres and leave no print at all; a
    /// point always marks the texel it lies in, so every vertex prints.
    swept_point_pipeline: wgpu::RenderPipeline,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    /// Per mesh sub-step: (corner x, corner z, t, 0); entry 0 is t = 1.
    step_instances: wgpu::Buffer,
    /// First entry in `step_instances` and sub-steps of each prepared mesh.
    mesh_steps: Vec<(u32, u32)>,
    /// This frame's `step_instances`, kept for its memory.
    step_data: Vec<[f32; 4]>,
    /// What `params` and `step_instances` last had written, so an unchanged
    /// frame writes neither.
    written: (Option<CaptureParams>, Vec<[f32; 4]>),
    /// What the last record captured, as the update's flags
    /// ([`Self::update_flags`]).
    captured: u32,
}

/// A depth-only capture pipeline for the meshes: `vs_swept` of `module`
/// drawing `primitive`s, no fragment stage.
fn mesh_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::PipelineLayout,
    label: &str,
    module: &wgpu::ShaderModule,
    primitive: wgpu::PrimitiveState,
) -> wgpu::RenderPipeline {
    let positions = |location| wgpu::VertexBufferLayout {
        array_stride: 12,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: match location {
            0 => &wgpu::vertex_attr_array![0 => Float32x3],
            _ => &wgpu::vertex_attr_array![5 => Float32x3],
        },
    };
    let buffers = [
        Some(positions(0)),
        Some(wgpu::VertexBufferLayout { array_stride: 16, step_mode: wgpu::VertexStepMode::Instance, attributes: &wgpu::vertex_attr_array![1 => Float32x4] }),
        Some(positions(5)),
    ];
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_swept"),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            buffers: &buffers,
        },
        primitive,
        depth_stencil: Some(wgpu::DepthStencilState {
            format: CAPTURE_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: None,
        multiview_mask: None,
        cache: None,
    })
}

impl CapturePass {
    /// Builds the shapes' compute pass and the meshes' pipelines.
    #[must_use]
    pub fn new(device: &wgpu::Device) -> Self {
        let bgl = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("capture meshes"),
            entries: &[layout::uniform(0, wgpu::ShaderStages::VERTEX_FRAGMENT)],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("capture meshes"),
            bind_group_layouts: &[Some(&bgl)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("capture meshes"),
            source: wgpu::ShaderSource::Wgsl(shaders::CAPTURE_MESH.into()),
        });
        // Seen from below, front and back faces swap; cull nothing and let the depth test choose.
        let primitive = wgpu::PrimitiveState { cull_mode: None, ..Default::default() };
        let points = wgpu::PrimitiveState { topology: wgpu::PrimitiveTopology::PointList, ..primitive };
        let params = layout::uniform_buffer::<CaptureParams>(device, "capture params");
        let bind_group = layout::bind_group(device, "capture meshes", &bgl, &[params.as_entire_binding()]);
        Self {
            shapes: ShapeCapturePass::new(device),
            swept_pipeline: mesh_pipeline(device, &pipeline_layout, "capture meshes", &module, primitive),
            swept_point_pipeline: mesh_pipeline(device, &pipeline_layout, "capture mesh points", &module, points),
            params,
            bind_group,
            step_instances: growable(device, "mesh step instances", 16 * 64),
            mesh_steps: Vec::new(),
            step_data: Vec::new(),
            written: (None, Vec::new()),
            captured: 0,
        }
    }

    /// Records this frame's capture: the analytic shapes of `inst` ray cast
    /// by compute, and `meshes` (world-space) drawn into the capture depth
    /// target, mesh k swept over the sub-steps
    /// [`CaptureInstances::mesh_steps`]`[k]` where it has previous
    /// positions. Either part is skipped when it has nothing to capture;
    /// [`Self::update_flags`] then tells the update what to read. The one
    /// form of the presses' passes: the stamp pass and the decal pass record
    /// the same way (what, where, one call).
    pub fn record(&mut self, cx: &mut FrameContext<'_>, res: &DeformResources, (params, inst): (&CaptureParams, &CaptureInstances), meshes: &[SweptMesh<'_>]) {
        let shapes = Shapes { capsules: &inst.capsules, wheels: &inst.wheels, boxes: &inst.boxes };
        let shapes = self.shapes.record(cx, res, [params.low_m, params.high_m], shapes);
        self.captured = if shapes { UpdateParams::CAPTURE_SHAPES } else { 0 };
        if !meshes.is_empty() {
            if res.capture.width() != res.resolution {
                tracing::error!("meshes captured before DeformResources::allocate_mesh_capture: skipped");
                return;
            }
            self.upload(cx.device(), cx.queue(), params, inst);
            self.draw(cx, res, meshes);
            self.captured |= UpdateParams::CAPTURE_MESHES;
        }
    }

    /// What the last [`Self::record`] captured, as
    /// [`UpdateParams::CAPTURE_SHAPES`] and [`UpdateParams::CAPTURE_MESHES`]:
    /// the update reads those (with [`UpdateParams::USE_CAPTURE`]) and
    /// nothing else.
    #[must_use]
    pub fn update_flags(&self) -> u32 {
        self.captured
    }

    /// Uploads this frame's mesh sub-steps.
    fn upload(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, params: &CaptureParams, inst: &CaptureInstances) {
        if self.written.0 != Some(*params) {
            queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
            self.written.0 = Some(*params);
        }
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
        // The steps are the same every frame while meshes do not sweep: written once.
        if self.written.1 != steps {
            let bytes: &[u8] = bytemuck::cast_slice(&steps);
            if bytes.len() as u64 > self.step_instances.size() {
                self.step_instances = growable(device, "mesh step instances", (bytes.len() as u64).next_power_of_two());
            }
            queue.write_buffer(&self.step_instances, 0, bytes);
            self.written.1.clear();
            self.written.1.extend_from_slice(&steps);
        }
        self.step_data = steps;
    }

    /// Clears the capture depth target and draws `meshes` into it.
    fn draw<'a>(&self, cx: &mut FrameContext<'_>, res: &DeformResources, meshes: &[SweptMesh<'a>]) {
        let (encoder, timer) = (&mut *cx.encoder, &mut *cx.timer);
        let slot = timer.reserve("capture meshes");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("capture meshes"),
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
