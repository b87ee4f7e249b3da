//! The snow surface drawn into a render pass the caller owns
//! (`shaders/ground.wgsl`), for games with their own wgpu renderer; and the
//! WGSL module their own ground shaders import to sample the snow
//! ([`SNOW_SAMPLING_WGSL`], from [`super::sampling`]).
//!
//! [`super::Renderer`] owns a whole frame (targets, sky, shadows, tone map);
//! [`SnowGround`] owns only a pipeline and its bind groups and draws into the
//! caller's pass, with the caller's formats, depth test and camera.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};

use crate::gpu::layout;
use crate::shaders;
use crate::snow::SnowDeformation;

pub use super::sampling::{SNOW_SAMPLING_GROUP, SNOW_SAMPLING_WGSL, SnowSampling, SnowWindowUniform, snow_sampling_wgsl};
use crate::snow::inspect::SnowInspect;

/// Default quads per side of the ground grid.
pub const DEFAULT_GRID_QUADS: u32 = 256;

/// The caller's camera for one frame: `GroundCamera` in `ground.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GroundCamera {
    /// World-to-clip matrix (column-major), in the frame the snow's positions are in
    /// (world, or relative to the deformation's floating origin when one is set).
    pub(crate) view_proj: [[f32; 4]; 4],
    /// Eye position (xyz); w unused.
    pub(crate) position: [f32; 4],
}

impl GroundCamera {
    /// From a view-projection matrix (any convention: reverse-Z or not) and the eye.
    #[must_use]
    pub fn new(view_proj: Mat4, position: Vec3) -> Self {
        Self { view_proj: view_proj.to_cols_array_2d(), position: position.extend(1.0).to_array() }
    }
}

/// How the ground is lit and what the snow looks like. Colours are linear;
/// the output is linear radiance in the caller's units (no tone mapping), so
/// for an 8-bit target keep `sun_color + sky_color` at or below about 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundLighting {
    /// Direction toward the sun (normalised when used).
    pub sun_direction: Vec3,
    /// What a white Lambertian surface facing the sun reflects from the sun alone.
    pub sun_color: Vec3,
    /// What a white surface facing up reflects from the sky alone (hemispherical ambient).
    pub sky_color: Vec3,
    /// What a white surface facing down reflects (light bounced off the ground).
    pub bounce_color: Vec3,
    /// Albedo of untouched snow.
    pub fresh_albedo: Vec3,
    /// Albedo of snow pressed to the ground (denser, larger grains: darker, bluer).
    pub packed_albedo: Vec3,
    /// Albedo of the ground where the snow is gone.
    pub bare_albedo: Vec3,
    /// Wrapped diffuse (light scattered through the grains past the terminator), 0..1.
    pub wrap: f32,
    /// Tint of that scattered light.
    pub scatter: Vec3,
}

impl Default for GroundLighting {
    /// A clear day with the sun 35° up, for an 8-bit sRGB target: fresh snow
    /// facing up comes out at about 0.85 of white.
    fn default() -> Self {
        let elevation = 35f32.to_radians();
        Self {
            sun_direction: Vec3::new(0.55 * elevation.cos(), elevation.sin(), 0.84 * elevation.cos()),
            sun_color: Vec3::new(1.0, 0.96, 0.9) * 0.62,
            sky_color: Vec3::new(0.36, 0.42, 0.52),
            bounce_color: Vec3::new(0.2, 0.2, 0.22),
            fresh_albedo: Vec3::new(0.92, 0.94, 0.98),
            packed_albedo: Vec3::new(0.6, 0.66, 0.76),
            bare_albedo: Vec3::new(0.22, 0.19, 0.16),
            wrap: 0.45,
            scatter: Vec3::new(0.45, 0.7, 1.0),
        }
    }
}

/// The caller's depth attachment and how the ground tests against it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GroundDepth {
    /// Format of the caller's depth attachment.
    pub format: wgpu::TextureFormat,
    /// `Less` for a conventional depth buffer cleared to 1, `Greater` for reverse-Z cleared to 0.
    pub compare: wgpu::CompareFunction,
    /// Whether the ground writes depth (true unless the caller has a depth pre-pass).
    pub write: bool,
}

/// What [`SnowGround`] draws into.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SnowGroundDescriptor {
    /// Format of the caller's colour attachment.
    pub(crate) color_format: wgpu::TextureFormat,
    /// The caller's depth attachment, or `None` for a pass without one.
    pub(crate) depth: Option<GroundDepth>,
    /// Samples per pixel of the caller's attachments (1 unless multisampled).
    pub sample_count: u32,
    /// Quads per side of the grid over the window (see [`SnowGround`]).
    pub(crate) grid_quads: u32,
    /// Cull triangles facing away (the grid is counter-clockwise seen from
    /// above under a view-projection that keeps handedness); false draws both sides.
    pub(crate) cull_back_faces: bool,
    /// Light and material.
    pub(crate) lighting: GroundLighting,
}

impl SnowGroundDescriptor {
    /// Colour target `color_format`, no depth, one sample, `DEFAULT_GRID_QUADS`, back faces culled, default lighting.
    #[must_use]
    pub fn new(color_format: wgpu::TextureFormat) -> Self {
        Self { color_format, depth: None, sample_count: 1, grid_quads: DEFAULT_GRID_QUADS, cull_back_faces: true, lighting: GroundLighting::default() }
    }

    /// The same with a depth attachment of `format`, tested with `compare` and written.
    #[must_use]
    pub fn with_depth(mut self, format: wgpu::TextureFormat, compare: wgpu::CompareFunction) -> Self {
        self.depth = Some(GroundDepth { format, compare, write: true });
        self
    }
}

/// The tools' tuning of a [`SnowGroundDescriptor`] beside what a game sets
/// (a named extension trait of `low_level`: the descriptor has one shape
/// with or without the feature).
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait SnowGroundDescriptorExt: Sized {
    /// The same with `quads` quads per side of the grid over the window.
    #[must_use]
    fn with_grid_quads(self, quads: u32) -> Self;
}

impl SnowGroundDescriptorExt for SnowGroundDescriptor {
    fn with_grid_quads(mut self, quads: u32) -> Self {
        self.grid_quads = quads;
        self
    }
}

/// `GroundParams` in `ground.wgsl`: lighting, material and where the grid lies.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GroundParams {
    /// Unit vector toward the sun; w: wrap.
    pub sun_direction: [f32; 4],
    /// Sun (rgb).
    pub sun_color: [f32; 4],
    /// Sky ambient (rgb).
    pub sky_color: [f32; 4],
    /// Bounce ambient (rgb).
    pub bounce_color: [f32; 4],
    /// Untouched snow albedo (rgb).
    pub fresh_albedo: [f32; 4],
    /// Pressed snow albedo (rgb).
    pub packed_albedo: [f32; 4],
    /// Bare ground albedo (rgb).
    pub bare_albedo: [f32; 4],
    /// Scatter tint (rgb).
    pub scatter: [f32; 4],
    /// First grid line x, z (m), quad size (m), quads per side.
    pub grid: [f32; 4],
    /// Window corner x, z and far corner x, z (m).
    pub bounds: [f32; 4],
}

impl GroundParams {
    /// `lighting` with the grid of `quads` quads over the window `corner` (m) .. `+ extent_m`.
    #[must_use]
    pub fn new(lighting: &GroundLighting, quads: u32, corner: glam::DVec2, extent_m: f64) -> Self {
        let v = |c: Vec3, w: f32| [c.x, c.y, c.z, w];
        // Grid lines on multiples of the quad size in world space: a window
        // move shifts which lines are drawn, never where they are. One more
        // quad than `quads` covers the window from the line at or before its corner.
        let quad = extent_m / f64::from(quads);
        let first = (corner / quad).floor() * quad;
        let far = corner + extent_m;
        Self {
            sun_direction: v(lighting.sun_direction.normalize_or(Vec3::Y), lighting.wrap.clamp(0.0, 1.0)),
            sun_color: v(lighting.sun_color, 0.0),
            sky_color: v(lighting.sky_color, 0.0),
            bounce_color: v(lighting.bounce_color, 0.0),
            fresh_albedo: v(lighting.fresh_albedo, 0.0),
            packed_albedo: v(lighting.packed_albedo, 0.0),
            bare_albedo: v(lighting.bare_albedo, 0.0),
            scatter: v(lighting.scatter, 0.0),
            grid: [first.x as f32, first.y as f32, quad as f32, (quads + 1) as f32],
            bounds: [corner.x as f32, corner.y as f32, far.x as f32, far.y as f32],
        }
    }
}

/// The snow terrain drawn into a render pass the caller began.
///
/// Geometry: a grid of `grid_quads + 1` quads per side over the deformation
/// window, its lines fixed in world space on multiples of
/// `extent / grid_quads` (so the window's moves do not make it swim) and
/// clamped to the window's edges, displaced by `snow_height` in the vertex
/// shader. The default 256 quads over a 64 m, 1024² window is one vertex per
/// 4x4 texels (25 cm), 66,000 quads, one indexed draw: cheap on any GPU, and
/// a trail's cross-section (tens of centimetres) still shows in silhouette.
/// There is no level of detail: the window is small; beyond it the game draws
/// its own ground ([`SNOW_SAMPLING_WGSL`] gives the rest surface there). The
/// fragment shader samples normal, compaction and depth per pixel at the full
/// texel resolution. Shading: sun (Lambert plus a wrapped, tinted scatter
/// term) and a hemispherical ambient; no shadows, no specular.
///
/// ```no_run
/// # fn frame(device: &wgpu::Device, queue: &wgpu::Queue, snow: &snowpack::SnowDeformation,
/// #          encoder: &mut wgpu::CommandEncoder, color: &wgpu::TextureView, depth: &wgpu::TextureView,
/// #          view_proj: glam::Mat4, eye: glam::Vec3) {
/// use snowpack::{GroundCamera, SnowGround, SnowGroundDescriptor};
///
/// // Once: the game's formats; reverse-Z depth compares with Greater.
/// let desc = SnowGroundDescriptor::new(wgpu::TextureFormat::Bgra8UnormSrgb)
///     .with_depth(wgpu::TextureFormat::Depth32Float, wgpu::CompareFunction::Greater);
/// let mut ground = SnowGround::new(device, snow, &desc);
///
/// // Each frame, after the deformation's frame is encoded:
/// let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
///     label: Some("game"),
///     color_attachments: &[Some(wgpu::RenderPassColorAttachment {
///         view: color,
///         depth_slice: None,
///         resolve_target: None,
///         ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::BLACK), store: wgpu::StoreOp::Store },
///     })],
///     depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
///         view: depth,
///         depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(0.0), store: wgpu::StoreOp::Store }),
///         stencil_ops: None,
///     }),
///     timestamp_writes: None,
///     occlusion_query_set: None,
///     multiview_mask: None,
/// });
/// // ... the game's own draws ...
/// ground.draw(&mut pass, queue, snow, &GroundCamera::new(view_proj, eye));
/// # }
/// ```
pub struct SnowGround {
    pipeline: wgpu::RenderPipeline,
    frame_group: wgpu::BindGroup,
    camera: wgpu::Buffer,
    params: wgpu::Buffer,
    sampling: SnowSampling,
    indices: wgpu::Buffer,
    index_count: u32,
    lighting: GroundLighting,
    grid_quads: u32,
}

impl SnowGround {
    /// Builds the pipeline for `desc`'s attachments and binds `snow`'s surface.
    #[must_use]
    pub fn new(device: &wgpu::Device, snow: &SnowDeformation, desc: &SnowGroundDescriptor) -> Self {
        let vf = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let frame_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("snow ground"),
            entries: &[layout::uniform(0, vf), layout::uniform(1, vf)],
        });
        let sampling = SnowSampling::new(device, snow, vf);
        let camera = layout::uniform_buffer::<GroundCamera>(device, "snow ground camera");
        let params = layout::uniform_buffer::<GroundParams>(device, "snow ground params");
        let frame_group = layout::bind_group(device, "snow ground", &frame_layout, &[camera.as_entire_binding(), params.as_entire_binding()]);
        let module =
            device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("snow ground"), source: wgpu::ShaderSource::Wgsl(shaders::GROUND.into()) });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("snow ground"),
            bind_group_layouts: &[Some(&frame_layout), Some(sampling.layout())],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("snow ground"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                cull_mode: desc.cull_back_faces.then_some(wgpu::Face::Back),
                ..Default::default()
            },
            depth_stencil: desc.depth.map(|d| wgpu::DepthStencilState {
                format: d.format,
                depth_write_enabled: Some(d.write),
                depth_compare: Some(d.compare),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            }),
            multisample: wgpu::MultisampleState { count: desc.sample_count.max(1), ..Default::default() },
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                targets: &[Some(wgpu::ColorTargetState { format: desc.color_format, blend: None, write_mask: wgpu::ColorWrites::ALL })],
            }),
            multiview_mask: None,
            cache: None,
        });
        // The vertex shader clamps one extra quad per side to the window's edges.
        let grid_quads = desc.grid_quads.max(1);
        let indices = grid_indices(grid_quads + 1);
        let index_count = indices.len() as u32;
        let indices = {
            use wgpu::util::DeviceExt as _;
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("snow ground grid"),
                contents: bytemuck::cast_slice(&indices),
                usage: wgpu::BufferUsages::INDEX,
            })
        };
        Self { pipeline, frame_group, camera, params, sampling, indices, index_count, lighting: desc.lighting, grid_quads }
    }

    /// Changes the lighting and material from the next [`Self::draw`] on.
    pub fn set_lighting(&mut self, lighting: GroundLighting) {
        self.lighting = lighting;
    }

    /// Draws `snow` as its last encoded frame left it into `pass`, seen by
    /// `camera` (one indexed draw); draws nothing before the window is
    /// placed (the deformation's first frame). Call after
    /// [`SnowDeformation::encode`], in a pass of the same submit.
    ///
    /// It writes the frame's uniforms (camera, lighting, where the window
    /// is) with `queue`, which the submit applies before any of its work:
    /// one camera per ground and submit (a second view in the same submit
    /// wants a second [`SnowGround`]). Sets its own pipeline and bind groups
    /// 0 and 1; the caller's later draws set theirs.
    pub fn draw(&mut self, pass: &mut wgpu::RenderPass<'_>, queue: &wgpu::Queue, snow: &SnowDeformation, camera: &GroundCamera) {
        self.sampling.update(queue, snow);
        let Some(origin) = snow.origin_m() else { return };
        let corner = origin - snow.floating_origin();
        let params = GroundParams::new(&self.lighting, self.grid_quads, corner, f64::from(snow.params().extent_m));
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        queue.write_buffer(&self.camera, 0, bytemuck::bytes_of(camera));
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.frame_group, &[]);
        pass.set_bind_group(1, self.sampling.bind_group(), &[]);
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..self.index_count, 0, 0..1);
    }
}

/// Index list of a `quads`² grid of `(quads + 1)²` vertices numbered row by row.
#[must_use]
pub fn grid_indices(quads: u32) -> Vec<u32> {
    let row = quads + 1;
    let mut out = Vec::with_capacity((quads * quads * 6) as usize);
    for z in 0..quads {
        for x in 0..quads {
            let a = z * row + x;
            let (b, c, d) = (a + 1, a + row, a + row + 1);
            // Counter-clockwise seen from above (+y), one diagonal throughout:
            // a fully morphed patch then is exactly the next level's grid.
            out.extend_from_slice(&[a, c, d, a, d, b]);
        }
    }
    out
}

/// What snowpack's own renderer, tools and tests read of a [`SnowGround`] beyond the front door.
/// A named item of `low_level` (an extension trait): [`SnowGround`] has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait SnowGroundExt: Sized {
    /// The lighting and material in use.
    #[must_use]
    fn lighting(&self) -> &GroundLighting;

    /// The snow bindings this pass uses (group 1, visible to vertex and
    /// fragment shaders), which the caller's own draws may bind too.
    #[must_use]
    fn sampling(&self) -> &SnowSampling;

    /// Triangles one [`SnowGround::draw`] draws.
    #[must_use]
    fn triangles(&self) -> u32;
}

impl SnowGroundExt for SnowGround {
    fn lighting(&self) -> &GroundLighting {
        &self.lighting
    }

    fn sampling(&self) -> &SnowSampling {
        &self.sampling
    }

    fn triangles(&self) -> u32 {
        self.index_count / 3
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec2;

    use super::{GroundLighting, GroundParams};

    #[test]
    fn grid_lines_stay_put_in_world_space_and_cover_the_window() {
        let lighting = GroundLighting::default();
        let texel = 64.0 / 1024.0;
        // The window at two places a few texels apart (and off the quad size).
        let corners = [DVec2::new(-32.0, -32.0), DVec2::new(-32.0 + 3.0 * texel, -32.0 - 5.0 * texel), DVec2::new(1000.1875, -7.0625)];
        for corner in corners {
            let p = GroundParams::new(&lighting, 256, corner, 64.0);
            let quad = p.grid[2];
            assert_eq!(quad, 0.25);
            assert_eq!(p.grid[3], 257.0, "one quad more than asked, to cover the window from a line before it");
            for k in 0..2 {
                let first = f64::from(p.grid[k]);
                // On a multiple of the quad size, at or before the corner, and the last line at or past the far side.
                assert_eq!((first / 0.25).fract(), 0.0, "grid line {first} off the world grid");
                assert!(first <= corner[k] && corner[k] - first < 0.25);
                assert!(first + 257.0 * 0.25 >= corner[k] + 64.0);
                assert_eq!(f64::from(p.bounds[k]), corner[k]);
                assert_eq!(f64::from(p.bounds[k + 2]), corner[k] + 64.0);
            }
        }
    }
}
