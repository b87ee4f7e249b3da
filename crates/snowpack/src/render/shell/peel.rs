//! The shell's rendering with depth-peeled transparency (Leshonkov & Frolov
//! 2021, section 3.1, Figure 2): `shaders/shell_draw.wgsl` rasterises and
//! traces the tetrahedra, `shaders/shell_resolve.wgsl` holds the full-screen
//! steps. Each pass: (1) the next layer's depth, (2) that depth into the
//! depth buffer, culled behind the scene, (3) the layer shaded with depth
//! test `equal`, blended front to back, (4) the depth buffer extended where
//! the opacity so far passes the threshold, so later passes skip the pixel.
//!
//! One departure, for portability: step 1 keeps the nearest layer with the
//! hardware depth test (`greater`, reverse-Z) and rejects the layers already
//! peeled with a texture load of the cull depth and a discard, where the
//! paper culls with a read-only depth buffer and finds the nearest with a
//! `min` blend into a float colour target. WebGPU has no portable `min`
//! blending of 32-bit floats (it needs `FLOAT32_BLENDABLE`, absent on GL).
//! The discard comes before the trace, so a finished pixel costs one load.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::render::pipeline::{HDR_FORMAT, screen_target};
use crate::shaders;

use super::count::{MAX_PASSES, PeelCountPass};

/// Depth format of the peeling's buffers (reverse-Z, as the scene).
pub const PEEL_DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Parameters of the shell's draw (`ShellDrawParams` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ShellDrawParams {
    /// Level-0 voxels along u, v, w; w: mip levels.
    pub dims: [f32; 4],
    /// Base vertices (their offset copies follow in the corner indices).
    pub count: u32,
    /// 1: mip level from the pixel's footprint; 0: always level 0.
    pub use_lod: u32,
    /// Most trace steps per tetrahedron.
    pub max_steps: u32,
    /// Padding.
    pub _pad: u32,
    /// Added to the footprint's level.
    pub lod_bias: f32,
    /// Coverage below this is empty space.
    pub min_alpha: f32,
    /// The shell fades out between these distances from the camera (m, along x or z).
    pub fade_m: [f32; 2],
}

/// Parameters of the full-screen steps (`PeelParams` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PeelParams {
    /// Accumulated opacity that ends a pixel's peeling (their 0.95).
    pub threshold: f32,
    /// 0: off; k: the debug view tints the pixels pass k shaded.
    pub debug_pass: u32,
    /// Target width (pixels).
    pub width: u32,
    /// Padding.
    pub _pad: u32,
}

/// Labels of the passes' GPU timings, one per peeling pass.
pub const PASS_LABELS: [&str; MAX_PASSES as usize] = [
    "shell pass 1",
    "shell pass 2",
    "shell pass 3",
    "shell pass 4",
    "shell pass 5",
    "shell pass 6",
    "shell pass 7",
    "shell pass 8",
    "shell pass 9",
    "shell pass 10",
    "shell pass 11",
    "shell pass 12",
    "shell pass 13",
    "shell pass 14",
    "shell pass 15",
    "shell pass 16",
];

fn depth_binding(binding: u32) -> wgpu::BindGroupLayoutEntry {
    layout_entry(
        binding,
        // Unfilterable float, not depth: GLSL has no `textureLoad` of depth textures.
        wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
    )
}

fn layout_entry(binding: u32, ty: wgpu::BindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry { binding, visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT, ty, count: None }
}

fn storage_ro(binding: u32) -> wgpu::BindGroupLayoutEntry {
    layout_entry(
        binding,
        wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only: true }, has_dynamic_offset: false, min_binding_size: None },
    )
}

fn uniform(binding: u32) -> wgpu::BindGroupLayoutEntry {
    layout_entry(binding, wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: None })
}

fn volume_binding(binding: u32) -> wgpu::BindGroupLayoutEntry {
    layout_entry(
        binding,
        wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: true },
            view_dimension: wgpu::TextureViewDimension::D3,
            multisampled: false,
        },
    )
}

/// How one of the peeling's pipelines draws.
struct Spec<'a> {
    label: &'a str,
    module: &'a wgpu::ShaderModule,
    vertex: &'a str,
    fragment: &'a str,
    layouts: &'a [&'a wgpu::BindGroupLayout],
    colour: Option<(wgpu::TextureFormat, Option<wgpu::BlendState>)>,
    depth: Option<(wgpu::CompareFunction, bool)>,
    cull: bool,
}

fn pipeline(device: &wgpu::Device, spec: &Spec<'_>) -> wgpu::RenderPipeline {
    let layouts: Vec<Option<&wgpu::BindGroupLayout>> = spec.layouts.iter().map(|l| Some(*l)).collect();
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor { label: Some(spec.label), bind_group_layouts: &layouts, immediate_size: 0 });
    let targets = [spec.colour.map(|(format, blend)| wgpu::ColorTargetState { format, blend, write_mask: wgpu::ColorWrites::ALL })];
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(spec.label),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module: spec.module,
            entry_point: Some(spec.vertex),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState { cull_mode: spec.cull.then_some(wgpu::Face::Back), ..wgpu::PrimitiveState::default() },
        depth_stencil: spec.depth.map(|(compare, write)| wgpu::DepthStencilState {
            format: PEEL_DEPTH_FORMAT,
            depth_write_enabled: Some(write),
            depth_compare: Some(compare),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: spec.module,
            entry_point: Some(spec.fragment),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            targets: if spec.colour.is_some() { &targets } else { &[] },
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// Front to back "under" blending of premultiplied colour.
const UNDER: wgpu::BlendComponent =
    wgpu::BlendComponent { src_factor: wgpu::BlendFactor::OneMinusDstAlpha, dst_factor: wgpu::BlendFactor::One, operation: wgpu::BlendOperation::Add };
/// Premultiplied "over" for the composite onto the scene.
const OVER: wgpu::BlendComponent =
    wgpu::BlendComponent { src_factor: wgpu::BlendFactor::One, dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha, operation: wgpu::BlendOperation::Add };

/// The peeling's pipelines and layouts (independent of the target size).
pub struct PeelPipelines {
    /// Group 1 of the tetrahedra draws: params, corners, vertices, tetrahedra, volume, distance, sampler.
    pub shell_layout: wgpu::BindGroupLayout,
    depth_layout: wgpu::BindGroupLayout,
    resolve_layout: wgpu::BindGroupLayout,
    layer: wgpu::RenderPipeline,
    shade: wgpu::RenderPipeline,
    layer_depth: wgpu::RenderPipeline,
    extend: wgpu::RenderPipeline,
    composite: wgpu::RenderPipeline,
}

/// The shell's bind group layouts: its own (parameters, vertices,
/// tetrahedra, volumes), the two peeling depths, and the resolve's.
fn peel_layouts(device: &wgpu::Device) -> (wgpu::BindGroupLayout, wgpu::BindGroupLayout, wgpu::BindGroupLayout) {
    let shell_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("shell"),
        entries: &[
            uniform(0),
            storage_ro(1),
            storage_ro(2),
            storage_ro(3),
            volume_binding(4),
            volume_binding(5),
            layout_entry(6, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering)),
        ],
    });
    let depth_layout =
        device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("shell depths"), entries: &[depth_binding(0), depth_binding(1)] });
    let resolve_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("shell resolve"),
        entries: &[
            uniform(0),
            depth_binding(1),
            depth_binding(2),
            layout_entry(
                3,
                wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
            ),
            storage_ro(4),
        ],
    });
    (shell_layout, depth_layout, resolve_layout)
}

impl PeelPipelines {
    /// Builds the pipelines; `lit_layout` is the renderer's group 0 (frame, shadow map, sky light).
    #[must_use]
    pub fn new(device: &wgpu::Device, lit_layout: &wgpu::BindGroupLayout) -> Self {
        let (shell_layout, depth_layout, resolve_layout) = peel_layouts(device);
        let draw = device
            .create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("shell draw"), source: wgpu::ShaderSource::Wgsl(shaders::SHELL_DRAW.into()) });
        let resolve = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("shell resolve"),
            source: wgpu::ShaderSource::Wgsl(shaders::SHELL_RESOLVE.into()),
        });
        let tetra_layouts = [lit_layout, &shell_layout, &depth_layout];
        let full = [&resolve_layout];
        let under = wgpu::BlendState { color: UNDER, alpha: UNDER };
        let over = wgpu::BlendState { color: OVER, alpha: OVER };
        let layer = pipeline(
            device,
            &Spec {
                label: "shell layer",
                module: &draw,
                vertex: "vs_tetra",
                fragment: "fs_layer",
                layouts: &tetra_layouts,
                colour: None,
                depth: Some((wgpu::CompareFunction::Greater, true)),
                cull: true,
            },
        );
        let shade = pipeline(
            device,
            &Spec {
                label: "shell shade",
                module: &draw,
                vertex: "vs_tetra",
                fragment: "fs_shade",
                layouts: &tetra_layouts,
                colour: Some((HDR_FORMAT, Some(under))),
                depth: Some((wgpu::CompareFunction::Equal, false)),
                cull: true,
            },
        );
        let layer_depth = pipeline(
            device,
            &Spec {
                label: "shell layer depth",
                module: &resolve,
                vertex: "vs_full",
                fragment: "fs_layer_depth",
                layouts: &full,
                colour: None,
                depth: Some((wgpu::CompareFunction::Always, true)),
                cull: false,
            },
        );
        let extend = pipeline(
            device,
            &Spec {
                label: "shell extend",
                module: &resolve,
                vertex: "vs_full",
                fragment: "fs_extend",
                layouts: &full,
                colour: None,
                depth: Some((wgpu::CompareFunction::Always, true)),
                cull: false,
            },
        );
        let composite = pipeline(
            device,
            &Spec {
                label: "shell composite",
                module: &resolve,
                vertex: "vs_full",
                fragment: "fs_composite",
                layouts: &full,
                colour: Some((HDR_FORMAT, Some(over))),
                depth: None,
                cull: false,
            },
        );
        Self { shell_layout, depth_layout, resolve_layout, layer, shade, layer_depth, extend, composite }
    }

    /// Records the peeling passes and the composite into `hdr`.
    pub fn record(&self, cx: &mut FrameContext<'_>, targets: &PeelTargets, draw: &PeelDraw<'_>, hdr: &wgpu::TextureView) {
        let gpu = cx.gpu;
        let (queue, encoder, timer) = (&gpu.queue, &mut *cx.encoder, &mut *cx.timer);
        let size = targets.size;
        queue.write_buffer(
            &targets.resolve_params,
            0,
            bytemuck::bytes_of(&PeelParams { threshold: draw.threshold, debug_pass: draw.debug_pass, width: size.0, _pad: 0 }),
        );
        encoder.clear_buffer(&targets.counts, 0, None);
        // Nothing peeled yet: the cull depth at the near plane lets every layer through.
        drop(depth_pass(encoder, "shell cull clear", &targets.cull_depth, Some(1.0), None));
        drop(colour_pass(encoder, "shell colour clear", &targets.accumulated, true, None, None));
        // The counts are not timed: one slot each would crowd out the passes' own.
        let mut untimed = crate::gpu::GpuTimer::disabled();
        for k in 0..draw.passes.min(MAX_PASSES) {
            // One timestamp pair spans the pass's four steps (and its count).
            let slot = timer.reserve(PASS_LABELS[k as usize]);
            let stamps = timer.render_writes(slot);
            let (begin, end) = stamps.map_or((None, None), |w| {
                (
                    Some(wgpu::RenderPassTimestampWrites {
                        query_set: w.query_set,
                        beginning_of_pass_write_index: w.beginning_of_pass_write_index,
                        end_of_pass_write_index: None,
                    }),
                    Some(wgpu::RenderPassTimestampWrites {
                        query_set: w.query_set,
                        beginning_of_pass_write_index: None,
                        end_of_pass_write_index: w.end_of_pass_write_index,
                    }),
                )
            });
            {
                // Step 1: the next layer's depth.
                let mut pass = depth_pass(encoder, "shell layer", &targets.layer_depth, Some(0.0), begin);
                pass.set_pipeline(&self.layer);
                pass.set_bind_group(0, draw.lit_group, &[]);
                pass.set_bind_group(1, draw.shell_group, &[]);
                pass.set_bind_group(2, &targets.tetra_depths, &[]);
                pass.draw(0..draw.vertices, 0..1);
            }
            {
                // Step 2: into the depth buffer, culled behind the scene.
                let mut pass = depth_pass(encoder, "shell layer depth", &targets.peel_depth, None, None);
                pass.set_pipeline(&self.layer_depth);
                pass.set_bind_group(0, &targets.resolve_layer, &[]);
                pass.draw(0..3, 0..1);
            }
            targets.count.record(&mut FrameContext::new(gpu, encoder, &mut untimed), k, size);
            {
                // Step 3: shade the layer, depth test `equal`, under what is there.
                let mut pass = colour_pass(encoder, "shell shade", &targets.accumulated, false, Some(&targets.peel_depth), None);
                pass.set_pipeline(&self.shade);
                pass.set_bind_group(0, draw.lit_group, &[]);
                pass.set_bind_group(1, draw.shell_group, &[]);
                pass.set_bind_group(2, &targets.tetra_depths, &[]);
                pass.draw(0..draw.vertices, 0..1);
            }
            {
                // Step 4: extend the depth buffer where the pixel is opaque enough.
                let mut pass = depth_pass(encoder, "shell extend", &targets.cull_depth, None, end);
                pass.set_pipeline(&self.extend);
                pass.set_bind_group(0, &targets.resolve_peel, &[]);
                pass.draw(0..3, 0..1);
            }
        }
        let slot = timer.reserve("shell composite");
        let mut pass = colour_pass(encoder, "shell composite", hdr, false, None, timer.render_writes(slot));
        pass.set_pipeline(&self.composite);
        pass.set_bind_group(0, &targets.resolve_layer, &[]);
        pass.draw(0..3, 0..1);
    }
}

/// The peeling's per-size textures and bind groups.
pub struct PeelTargets {
    /// Target size (pixels).
    pub size: (u32, u32),
    layer_depth: wgpu::TextureView,
    peel_depth: wgpu::TextureView,
    cull_depth: wgpu::TextureView,
    accumulated: wgpu::TextureView,
    /// Pixels each pass shades (one u32 per pass).
    pub counts: wgpu::Buffer,
    count: PeelCountPass,
    resolve_params: wgpu::Buffer,
    tetra_depths: wgpu::BindGroup,
    resolve_layer: wgpu::BindGroup,
    resolve_peel: wgpu::BindGroup,
}

impl PeelTargets {
    /// Targets of `size` over the scene's depth `scene_depth` (reverse-Z, sampled).
    #[must_use]
    pub fn new(device: &wgpu::Device, pipelines: &PeelPipelines, size: (u32, u32), scene_depth: &wgpu::TextureView) -> Self {
        let layer_depth = screen_target(device, "shell layer depth", size, PEEL_DEPTH_FORMAT);
        let peel_depth = screen_target(device, "shell peel depth", size, PEEL_DEPTH_FORMAT);
        let cull_depth = screen_target(device, "shell cull depth", size, PEEL_DEPTH_FORMAT);
        let accumulated = screen_target(device, "shell colour", size, HDR_FORMAT);
        let counts = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shell pass pixels"),
            size: u64::from(MAX_PASSES) * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let shaded = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shell shaded mask"),
            size: u64::from(size.0) * u64::from(size.1) * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let count = PeelCountPass::new(device, &peel_depth, &counts, &shaded);
        let resolve_params = layout::uniform_buffer::<PeelParams>(device, "shell resolve params");
        let tetra_depths = layout::bind_group(
            device,
            "shell depths",
            &pipelines.depth_layout,
            &[wgpu::BindingResource::TextureView(&cull_depth), wgpu::BindingResource::TextureView(scene_depth)],
        );
        let resolve = |label: &str, a: &wgpu::TextureView| {
            layout::bind_group(
                device,
                label,
                &pipelines.resolve_layout,
                &[
                    resolve_params.as_entire_binding(),
                    wgpu::BindingResource::TextureView(a),
                    wgpu::BindingResource::TextureView(scene_depth),
                    wgpu::BindingResource::TextureView(&accumulated),
                    shaded.as_entire_binding(),
                ],
            )
        };
        let resolve_layer = resolve("shell resolve layer", &layer_depth);
        let resolve_peel = resolve("shell resolve peel", &peel_depth);
        Self { size, layer_depth, peel_depth, cull_depth, accumulated, counts, count, resolve_params, tetra_depths, resolve_layer, resolve_peel }
    }

    /// GPU memory of the targets (bytes).
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        // Three depth buffers (4 B), the colour (8 B) and the mask (4 B) per pixel.
        u64::from(self.size.0) * u64::from(self.size.1) * (3 * 4 + 8 + 4) + self.counts.size()
    }
}

/// What one frame of peeling draws.
pub struct PeelDraw<'a> {
    /// The renderer's group 0.
    pub lit_group: &'a wgpu::BindGroup,
    /// The shell's group 1.
    pub shell_group: &'a wgpu::BindGroup,
    /// Vertices to draw (12 per tetrahedron).
    pub vertices: u32,
    /// Peeling passes.
    pub passes: u32,
    /// Opacity threshold.
    pub threshold: f32,
    /// Debug view pass (0 off).
    pub debug_pass: u32,
}

fn depth_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    view: &wgpu::TextureView,
    clear: Option<f32>,
    timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view,
            depth_ops: Some(wgpu::Operations { load: clear.map_or(wgpu::LoadOp::Load, wgpu::LoadOp::Clear), store: wgpu::StoreOp::Store }),
            stencil_ops: None,
        }),
        timestamp_writes: timestamps,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

/// A pass drawing into colour `view` (cleared to transparent or loaded), over
/// the read-only depth `depth` if any.
fn colour_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    view: &wgpu::TextureView,
    clear: bool,
    depth: Option<&wgpu::TextureView>,
    timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations { load: if clear { wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT) } else { wgpu::LoadOp::Load }, store: wgpu::StoreOp::Store },
        })],
        depth_stencil_attachment: depth.map(|view| wgpu::RenderPassDepthStencilAttachment { view, depth_ops: None, stencil_ops: None }),
        timestamp_writes: timestamps,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

