//! Builders for render pipelines and bind-group layout entries, shared by
//! every draw pass (the renderer's, the ground's, the accumulation's).
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

/// A screen-sized texture drawn into and then read by later passes, and its view.
#[must_use]
pub fn screen_target(device: &wgpu::Device, label: &str, size: (u32, u32), format: wgpu::TextureFormat) -> wgpu::TextureView {
    device
        .create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        })
        .create_view(&wgpu::TextureViewDescriptor::default())
}

/// A binding of `ty` visible to `visibility`.
#[must_use]
pub fn entry(binding: u32, visibility: wgpu::ShaderStages, ty: wgpu::BindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry { binding, visibility, ty, count: None }
}

/// A read-only storage buffer binding.
#[must_use]
pub fn storage_ro(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    entry(
        binding,
        visibility,
        wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only: true }, has_dynamic_offset: false, min_binding_size: None },
    )
}

/// A 2D float texture binding.
#[must_use]
pub fn texture(binding: u32, visibility: wgpu::ShaderStages, filterable: bool) -> wgpu::BindGroupLayoutEntry {
    entry(
        binding,
        visibility,
        wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
    )
}

/// What a render pipeline draws into and how.
pub struct PipelineSpec<'a> {
    /// Label.
    pub label: &'a str,
    /// WGSL source.
    pub source: &'a str,
    /// Vertex entry point.
    pub vertex: &'a str,
    /// Fragment entry point and colour format; `None` for depth-only.
    pub fragment: Option<(&'a str, wgpu::TextureFormat)>,
    /// Vertex buffers.
    pub buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
    /// Bind group layouts, in group order.
    pub layouts: &'a [&'a wgpu::BindGroupLayout],
    /// Depth format, compare and write; `None` for no depth.
    pub depth: Option<(wgpu::TextureFormat, wgpu::CompareFunction, bool)>,
    /// Depth bias (shadow casters).
    pub bias: wgpu::DepthBiasState,
    /// Cull back faces (counter-clockwise front).
    pub cull: bool,
    /// Values of the shader's `override` constants, by name.
    pub constants: &'a [(&'a str, f64)],
}

/// Builds a render pipeline from `spec`.
#[must_use]
pub fn render_pipeline(device: &wgpu::Device, spec: &PipelineSpec<'_>) -> wgpu::RenderPipeline {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(spec.label), source: wgpu::ShaderSource::Wgsl(spec.source.into()) });
    let layouts: Vec<Option<&wgpu::BindGroupLayout>> = spec.layouts.iter().map(|l| Some(*l)).collect();
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor { label: Some(spec.label), bind_group_layouts: &layouts, immediate_size: 0 });
    let targets = spec.fragment.map(|(_, format)| [Some(wgpu::ColorTargetState { format, blend: None, write_mask: wgpu::ColorWrites::ALL })]);
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(spec.label),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some(spec.vertex),
            compilation_options: wgpu::PipelineCompilationOptions { constants: spec.constants, ..Default::default() },
            buffers: spec.buffers,
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            front_face: wgpu::FrontFace::Ccw,
            cull_mode: spec.cull.then_some(wgpu::Face::Back),
            ..Default::default()
        },
        depth_stencil: spec.depth.map(|(format, compare, write)| wgpu::DepthStencilState {
            format,
            depth_write_enabled: Some(write),
            depth_compare: Some(compare),
            stencil: wgpu::StencilState::default(),
            bias: spec.bias,
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: spec.fragment.zip(targets.as_ref()).map(|((entry, _), targets)| wgpu::FragmentState {
            module: &module,
            entry_point: Some(entry),
            compilation_options: wgpu::PipelineCompilationOptions { constants: spec.constants, ..Default::default() },
            targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}
