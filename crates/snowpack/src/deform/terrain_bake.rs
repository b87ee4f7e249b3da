//! Terrain bake: draws a terrain mesh from above into the grid its
//! [`TerrainMesh`] describes (`terrain_bake.wgsl`, depth only), then resolves
//! depth into metres (`terrain_resolve.wgsl`), producing the heightmap samples
//! the window pass reads. Runs once when a window is created over mesh terrain.
//! CPU twin: `cpu::terrain_bake::draw`, which is [`crate::terrain::draw_from_above`].

use bytemuck::{Pod, Zeroable};

use crate::gpu::layout;
use crate::terrain::HeightmapTerrainExt;
use crate::terrain::TerrainMeshExt;
use crate::{TerrainMesh, shaders};

/// Uniforms of `terrain_bake.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TerrainBakeParams {
    /// World (x, z) of the grid's low corner (m).
    pub origin_m: [f32; 2],
    /// World size (x, z) of the grid (m).
    pub size_m: [f32; 2],
    /// World height at depth 0 (m).
    pub low_m: f32,
    /// World height at depth 1 (m).
    pub high_m: f32,
    /// Padding to 16 bytes.
    pub _pad: [f32; 2],
}

/// Uniforms of `terrain_resolve.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ResolveParams {
    /// Grid columns.
    pub width: u32,
    /// Grid rows.
    pub height: u32,
    /// World height at depth 0 (m).
    pub low_m: f32,
    /// World height at depth 1 (m).
    pub high_m: f32,
    /// Height of texels no triangle covers (m).
    pub floor_m: f32,
    /// Padding to 32 bytes.
    pub _pad: [u32; 3],
}

const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The pipelines that draw terrain meshes from above and resolve them to metres.
pub struct TerrainBakePass {
    pipeline: wgpu::RenderPipeline,
    bgl: wgpu::BindGroupLayout,
    resolve: wgpu::ComputePipeline,
    resolve_bgl: wgpu::BindGroupLayout,
}

impl TerrainBakePass {
    /// Builds the pipeline.
    #[must_use]
    pub fn new(device: &wgpu::Device) -> Self {
        let bgl = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("terrain bake"),
            entries: &[layout::uniform(0, wgpu::ShaderStages::VERTEX)],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("terrain bake"),
            bind_group_layouts: &[Some(&bgl)],
            immediate_size: 0,
        });
        let module = device
            .create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("terrain bake"), source: wgpu::ShaderSource::Wgsl(shaders::TERRAIN_BAKE.into()) });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("terrain bake"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: 12,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x3],
                })],
            },
            // Winding depends on the modeller; the depth test picks the top surface.
            primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Greater),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            }),
            multisample: wgpu::MultisampleState::default(),
            fragment: None,
            multiview_mask: None,
            cache: None,
        });
        let (resolve, resolve_bgl) = layout::compute_pipeline(
            device,
            "terrain resolve",
            shaders::TERRAIN_RESOLVE,
            &[layout::uniform(0, wgpu::ShaderStages::COMPUTE), layout::depth_texture(1), layout::storage(2, false)],
        );
        Self { pipeline, bgl, resolve, resolve_bgl }
    }

    /// Draws `mesh` into a new storage buffer of `grid.width() * grid.height()`
    /// heights (row-major, row 0 at the smallest z), recorded into `encoder`.
    /// Not one of a frame's passes (they take a `FrameContext`): it runs once,
    /// when the window is made, untimed, into an encoder of its own.
    #[must_use]
    pub fn bake(&self, device: &wgpu::Device, encoder: &mut wgpu::CommandEncoder, mesh: &TerrainMesh) -> wgpu::Buffer {
        use wgpu::util::DeviceExt as _;
        let grid = &mesh.grid;
        let (low, high) = mesh.height_range();
        let params = TerrainBakeParams {
            origin_m: [grid.center_m()[0] - grid.size_m()[0] * 0.5, grid.center_m()[1] - grid.size_m()[1] * 0.5],
            size_m: grid.size_m(),
            // A margin keeps the lowest and highest vertices strictly inside (0, 1).
            low_m: low - 1.0,
            high_m: high + 1.0,
            _pad: [0.0; 2],
        };
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("terrain bake params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bind_group = layout::bind_group(device, "terrain bake", &self.bgl, &[uniform.as_entire_binding()]);
        let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("terrain mesh"),
            contents: bytemuck::cast_slice(&mesh.triangles),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let depth = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("terrain bake depth"),
            size: wgpu::Extent3d { width: grid.width(), height: grid.height(), depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let depth_view = depth.create_view(&wgpu::TextureViewDescriptor::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("terrain bake"),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(0.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.set_vertex_buffer(0, vertices.slice(..));
            pass.draw(0..mesh.triangles.len() as u32 * 3, 0..1);
        }
        let out = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("heightmap (drawn terrain mesh)"),
            size: u64::from(grid.width()) * u64::from(grid.height()) * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let resolve_params =
            ResolveParams { width: grid.width(), height: grid.height(), low_m: params.low_m, high_m: params.high_m, floor_m: low, _pad: [0; 3] };
        let resolve_uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("terrain resolve params"),
            contents: bytemuck::bytes_of(&resolve_params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let resolve_group = layout::bind_group(
            device,
            "terrain resolve",
            &self.resolve_bgl,
            &[resolve_uniform.as_entire_binding(), wgpu::BindingResource::TextureView(&depth_view), out.as_entire_binding()],
        );
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("terrain resolve"), timestamp_writes: None });
        pass.set_pipeline(&self.resolve);
        pass.set_bind_group(0, &resolve_group, &[]);
        pass.dispatch_workgroups(layout::groups(grid.width(), 16), layout::groups(grid.height(), 16), 1);
        drop(pass);
        out
    }
}
