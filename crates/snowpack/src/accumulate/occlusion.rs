//! Occlusion pass: the objects drawn from the sky along the snowfall
//! direction into a depth target (what the sky sees; the ground's update reads
//! it) and a footprint target (the atlas texels each pixel covers; the scatter
//! reads it). See `shaders/occlusion.wgsl`.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use bytemuck::{Pod, Zeroable};
use glam::{Vec2, Vec3};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::gpu::render::{PipelineSpec, render_pipeline, storage_ro};
use crate::height_depth::{CAPTURE_FORMAT, sky_depth_texture};
use crate::shaders;

use super::atlas::ObjectVertex;

/// Format of the footprint target: `[x0, y0, x1, y1]` atlas texels, `u16::MAX`
/// where no object is (integers: float targets are not renderable on GL).
pub const FOOTPRINT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Uint;

/// Uniforms of `occlusion.wgsl`: the sheared orthographic projection.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct OcclusionParams {
    /// Side of the window and of the occlusion map (m).
    pub extent_m: f32,
    /// Height of the projection plane (m).
    pub y0_m: f32,
    /// Height at depth 1 (m).
    pub low_m: f32,
    /// Height at depth 0 (m).
    pub high_m: f32,
    /// `d.xz / -d.y` for the fall direction `d`.
    pub shear: [f32; 2],
    /// Jitter of the map against the window (m).
    pub offset_m: [f32; 2],
}

impl OcclusionParams {
    /// The projection for fall direction `d` (pointing down).
    #[must_use]
    pub fn new(extent_m: f32, y0_m: f32, (low_m, high_m): (f32, f32), d: Vec3, offset_m: Vec2) -> Self {
        let shear = Vec2::new(d.x, d.z) / (-d.y).max(crate::snowfall::MIN_DOWNWARD * 0.5);
        Self { extent_m, y0_m, low_m, high_m, shear: shear.to_array(), offset_m: offset_m.to_array() }
    }

    /// The sky test of this projection, as the passes that read the
    /// occlusion depth carry it in their uniforms.
    #[must_use]
    pub fn sky_test(&self) -> crate::height_depth::SkyTest {
        crate::height_depth::SkyTest { shear: self.shear, offset_m: self.offset_m, y0_m: self.y0_m, low_m: self.low_m, high_m: self.high_m, _pad: 0 }
    }

    /// Window-local (x, z) where the flake through window-local point `p` meets the plane, and its depth.
    #[must_use]
    pub fn project(&self, p: Vec3) -> (Vec2, f32) {
        let q = Vec2::new(p.x, p.z) + Vec2::from(self.shear) * (p.y - self.y0_m) + Vec2::from(self.offset_m);
        (q, (self.high_m - p.y) / (self.high_m - self.low_m))
    }
}

const ATTRIBUTES: [wgpu::VertexAttribute; 4] = [
    wgpu::VertexAttribute { format: wgpu::VertexFormat::Float32x3, offset: 0, shader_location: 0 },
    wgpu::VertexAttribute { format: wgpu::VertexFormat::Float32x2, offset: 48, shader_location: 1 },
    wgpu::VertexAttribute { format: wgpu::VertexFormat::Uint32, offset: 60, shader_location: 2 },
    wgpu::VertexAttribute { format: wgpu::VertexFormat::Float32x4, offset: 64, shader_location: 3 },
];

/// The occlusion render and its two targets.
pub struct OcclusionPass {
    pipeline: wgpu::RenderPipeline,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    /// Depth: what the sky sees, linear in height (window-local, the
    /// window's resolution); the view keeps its texture alive.
    pub depth_view: wgpu::TextureView,
    /// Footprint rectangles per pixel.
    pub footprint_view: wgpu::TextureView,
}

impl OcclusionPass {
    /// Builds the pipeline and `resolution`² targets; `objects` is the `ObjectGpu` array.
    #[must_use]
    pub fn new(device: &wgpu::Device, resolution: u32, objects: &wgpu::Buffer) -> Self {
        let vertex = wgpu::ShaderStages::VERTEX;
        let bgl = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("occlusion"),
            entries: &[layout::uniform(0, vertex), storage_ro(1, vertex)],
        });
        let buffers = [Some(wgpu::VertexBufferLayout {
            array_stride: size_of::<ObjectVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &ATTRIBUTES,
        })];
        let pipeline = render_pipeline(
            device,
            &PipelineSpec {
                label: "occlusion",
                source: shaders::OCCLUSION,
                vertex: "vs_main",
                fragment: Some(("fs_main", FOOTPRINT_FORMAT)),
                buffers: &buffers,
                layouts: &[&bgl],
                depth: Some((CAPTURE_FORMAT, wgpu::CompareFunction::Less, true)),
                bias: wgpu::DepthBiasState::default(),
                cull: false,
                constants: &[],
            },
        );
        let params = layout::uniform_buffer::<OcclusionParams>(device, "occlusion params");
        let bind_group = layout::bind_group(device, "occlusion", &bgl, &[params.as_entire_binding(), objects.as_entire_binding()]);
        let depth = sky_depth_texture(device, resolution);
        let footprint = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("occlusion footprint"),
            size: wgpu::Extent3d { width: resolution, height: resolution, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: FOOTPRINT_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        Self {
            pipeline,
            params,
            bind_group,
            depth_view: depth.create_view(&wgpu::TextureViewDescriptor::default()),
            footprint_view: footprint.create_view(&wgpu::TextureViewDescriptor::default()),
        }
    }

    /// Draws `index_count` indices of the objects' mesh from the sky.
    pub fn record(&self, cx: &mut FrameContext<'_>, params: &OcclusionParams, (vertices, indices, index_count): (&wgpu::Buffer, &wgpu::Buffer, u32)) {
        let (queue, encoder, timer) = (cx.queue(), &mut *cx.encoder, &mut *cx.timer);
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let slot = timer.reserve("occlusion");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("occlusion"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.footprint_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color { r: 65535.0, g: 65535.0, b: 65535.0, a: 65535.0 }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.depth_view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: timer.render_writes(slot),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_vertex_buffer(0, vertices.slice(..));
        pass.set_index_buffer(indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..index_count, 0, 0..1);
    }
}
