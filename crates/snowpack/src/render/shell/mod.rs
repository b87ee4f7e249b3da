//! Volumetric surface detail by shell mapping (Leshonkov & Frolov 2021,
//! `docs/shell.md`): a shell of tetrahedra built on the GPU every frame over
//! the displayed snow near the camera, a 3D detail texture (grass and twigs,
//! or an ice crust) traced inside each tetrahedron at the mip level of the
//! pixel's footprint, and order-independent transparency by depth peeling
//! with hardware depth tests. The shell thins where the snow is pressed, so
//! grass lies flat in a trail.
//!
//! One frame, in order: [`vertices::ShellVertexPass`] → [`tetrahedra::ShellTetraPass`]
//! → K × (layer, layer depth, [`count::PeelCountPass`], shade, extend) → composite.

pub mod count;
pub mod peel;
pub mod tetrahedra;
pub mod vertices;
pub mod volume;

use glam::Vec3;

use crate::error::SnowError;
use crate::frame::FrameContext;
use crate::gpu::{GpuContext, layout};
use crate::snow::SnowDeformation;

use self::count::MAX_PASSES;
use self::peel::{PeelDraw, PeelPipelines, PeelTargets, ShellDrawParams};
use self::tetrahedra::{CORNERS_PER_TETRA, ShellTetraPass, TetraParams};
use self::vertices::{ShellVertexParams, ShellVertexPass, SnowSurface};
pub use self::volume::{DetailKind, DetailVolume};
use crate::snow::inspect::SnowInspect;
use crate::gpu::context::GpuContextExt;

/// How the shell looks and what it costs: `[shell]` in scenes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShellSettings {
    /// Draw the shell.
    pub enabled: bool,
    /// What grows in it.
    pub texture: DetailKind,
    /// Detail texture voxels per side (power of two, 8..=512; half as many in height).
    pub texture_size: u32,
    /// Shell thickness over undisturbed snow (m).
    pub thickness_m: f32,
    /// World size of one repeat of the detail texture (m).
    pub tile_m: f32,
    /// Half side of the square patch around the camera that gets a shell (m).
    pub radius_m: f32,
    /// Spacing of the shell's base vertices (m; rounded to whole snow texels).
    pub spacing_m: f32,
    /// Pressing below rest (m) that flattens the shell to `min_fraction`.
    pub flatten_m: f32,
    /// The thinnest the shell gets in a trail, as a fraction of its thickness.
    pub min_fraction: f32,
    /// Mip levels from the pixel's footprint (off: always level 0, the basic method).
    pub lod: bool,
    /// Depth-peeling passes (their K), 1..=16.
    pub passes: u32,
    /// Opacity at which a pixel's peeling ends (their 0.95).
    pub opacity: f32,
    /// Most trace steps inside one tetrahedron.
    pub max_steps: u32,
    /// Debug view: tint the pixels peeling pass k shaded (0 off; their Figure 3).
    pub debug_pass: u32,
    /// Seed of the detail texture.
    pub seed: u64,
}

impl Default for ShellSettings {
    fn default() -> Self {
        Self {
            enabled: false,
            texture: DetailKind::Grass,
            texture_size: 64,
            thickness_m: 0.12,
            tile_m: 0.36,
            radius_m: 6.0,
            spacing_m: 0.125,
            flatten_m: 0.08,
            min_fraction: 0.15,
            lod: true,
            passes: 4,
            opacity: 0.95,
            max_steps: 96,
            debug_pass: 0,
            seed: 7,
        }
    }
}

impl ShellSettings {
    /// Checks ranges; the error names the field.
    pub fn validate(&self) -> Result<(), SnowError> {
        let bad = |field: &'static str, why: String| Err(SnowError::InvalidParameter { field, why });
        if !self.texture_size.is_power_of_two() || !(8..=512).contains(&self.texture_size) {
            return bad("texture_size", format!("{} is not a power of two in 8..=512", self.texture_size));
        }
        for (field, v) in [
            ("thickness_m", self.thickness_m),
            ("tile_m", self.tile_m),
            ("radius_m", self.radius_m),
            ("spacing_m", self.spacing_m),
            ("flatten_m", self.flatten_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, format!("{v} must be positive"));
            }
        }
        if !(self.min_fraction > 0.0 && self.min_fraction <= 1.0) {
            return bad("min_fraction", format!("{} must be in (0, 1]", self.min_fraction));
        }
        if !(1..=MAX_PASSES).contains(&self.passes) {
            return bad("passes", format!("{} must be in 1..={MAX_PASSES}", self.passes));
        }
        if !(self.opacity > 0.0 && self.opacity <= 1.0) {
            return bad("opacity", format!("{} must be in (0, 1]", self.opacity));
        }
        if !(1..=1024).contains(&self.max_steps) {
            return bad("max_steps", format!("{} must be in 1..=1024", self.max_steps));
        }
        if self.debug_pass > self.passes {
            return bad("debug_pass", format!("{} is beyond the {} passes", self.debug_pass, self.passes));
        }
        Ok(())
    }

    /// Whether a change from `other` needs the shell rebuilt (texture or patch).
    #[must_use]
    pub fn rebuild_needed(&self, other: &Self) -> bool {
        (self.texture, self.texture_size, self.seed, self.radius_m.to_bits(), self.spacing_m.to_bits())
            != (other.texture, other.texture_size, other.seed, other.radius_m.to_bits(), other.spacing_m.to_bits())
    }
}

/// The shell's grid patch: vertices per side and window texels between them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShellPatch {
    /// Vertices per side.
    pub side: u32,
    /// Window texels between neighbouring vertices.
    pub stride: u32,
}

impl ShellPatch {
    /// The patch for `settings` over a window of `resolution` texels of `texel_m`.
    #[must_use]
    pub fn new(settings: &ShellSettings, resolution: u32, texel_m: f32) -> Self {
        let stride = ((settings.spacing_m / texel_m).round() as u32).max(1);
        let quads = ((2.0 * settings.radius_m / (stride as f32 * texel_m)).ceil() as u32).max(1);
        // The patch stays inside the window.
        let side = (quads + 1).min((resolution - 1) / stride + 1).max(2);
        Self { side, stride }
    }

    /// Base vertices.
    #[must_use]
    pub fn vertices(&self) -> u32 {
        self.side * self.side
    }

    /// Triangles: two per quad, row-major vertex indices (the index rule
    /// then splits every shared prism side the same way from both sides).
    #[must_use]
    pub fn faces(&self) -> Vec<u32> {
        let n = self.side;
        let mut faces = Vec::with_capacity(((n - 1) * (n - 1) * 6) as usize);
        for i in 0..n - 1 {
            for j in 0..n - 1 {
                let (a, b, c, d) = (i * n + j, i * n + j + 1, (i + 1) * n + j, (i + 1) * n + j + 1);
                faces.extend_from_slice(&[a, c, b, b, c, d]);
            }
        }
        faces
    }

    /// Window-local texel (column, row) of vertex 0 for a camera at world
    /// (x, z): snapped to the stride on the global texel grid, so the shell
    /// does not swim as the camera moves, and kept inside the window.
    #[must_use]
    pub fn origin(&self, camera: (f32, f32), corner: (f64, f64), texel_m: f64, resolution: u32) -> [i32; 2] {
        let stride = i64::from(self.stride);
        let span = i64::from((self.side - 1) * self.stride);
        let corner_texel = ((corner.0 / texel_m).round() as i64, (corner.1 / texel_m).round() as i64);
        let axis = |cam: f32, corner: i64| {
            let global = (f64::from(cam) / texel_m).floor() as i64 - span / 2;
            let snapped = global.div_euclid(stride) * stride;
            let local = snapped - corner;
            local.clamp(0, (i64::from(resolution) - 1 - span).max(0)) as i32
        };
        [axis(camera.0, corner_texel.0), axis(camera.1, corner_texel.1)]
    }
}

/// Pixels each peeling pass of the last frame shaded (see [`ShellRenderer::pass_pixels`]).
pub type PassPixels = Vec<u32>;

/// The shell over the snow: its construction, detail texture and peeling.
pub struct ShellRenderer {
    settings: ShellSettings,
    patch: ShellPatch,
    faces: u32,
    vertex_pass: ShellVertexPass,
    tetra_pass: ShellTetraPass,
    draw_params: wgpu::Buffer,
    shell_group: wgpu::BindGroup,
    pipelines: PeelPipelines,
    targets: Option<PeelTargets>,
    levels: u32,
    dims: [u32; 3],
    /// Bytes of the buffers and the volume.
    bytes: u64,
    drawn: bool,
}

fn volume_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    volume: &DetailVolume,
    format: wgpu::TextureFormat,
    texel: impl Fn(&volume::VolumeLevel) -> Vec<u8>,
    bytes_per_voxel: u32,
) -> wgpu::Texture {
    let [x, y, z] = volume.size();
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("shell detail volume"),
        size: wgpu::Extent3d { width: x, height: y, depth_or_array_layers: z },
        mip_level_count: volume.levels.len() as u32,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D3,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (level, data) in volume.levels.iter().enumerate() {
        let [lx, ly, lz] = data.size;
        queue.write_texture(
            wgpu::TexelCopyTextureInfo { texture: &texture, mip_level: level as u32, origin: wgpu::Origin3d::ZERO, aspect: wgpu::TextureAspect::All },
            &texel(data),
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(lx * bytes_per_voxel), rows_per_image: Some(ly) },
            wgpu::Extent3d { width: lx, height: ly, depth_or_array_layers: lz },
        );
    }
    texture
}

/// The detail volume on the GPU: its premultiplied colour and its distance
/// field (views), and their sampler (repeating across, clamped in height).
fn detail_textures(device: &wgpu::Device, queue: &wgpu::Queue, volume: &DetailVolume) -> (wgpu::TextureView, wgpu::TextureView, wgpu::Sampler) {
    // Premultiplied, so trilinear filtering next to empty voxels keeps the colour.
    let premultiplied = |l: &volume::VolumeLevel| {
        l.rgba.iter().flat_map(|&[r, g, b, a]| [r, g, b].map(|c| ((u32::from(c) * u32::from(a) + 127) / 255) as u8).into_iter().chain([a])).collect()
    };
    let colour = volume_texture(device, queue, volume, wgpu::TextureFormat::Rgba8Unorm, premultiplied, 4);
    // Distances in level-0 voxels, whole voxels (0..=255): what sphere tracing needs.
    let distance =
        volume_texture(device, queue, volume, wgpu::TextureFormat::R8Unorm, |l| l.sdf.iter().map(|d| d.round().clamp(0.0, 255.0) as u8).collect(), 1);
    let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("shell detail"),
        address_mode_u: wgpu::AddressMode::Repeat,
        address_mode_v: wgpu::AddressMode::Repeat,
        address_mode_w: wgpu::AddressMode::ClampToEdge,
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        mipmap_filter: wgpu::MipmapFilterMode::Linear,
        ..Default::default()
    });
    (colour.create_view(&wgpu::TextureViewDescriptor::default()), distance.create_view(&wgpu::TextureViewDescriptor::default()), sampler)
}

impl ShellRenderer {
    /// Builds the shell over `snow` with `settings`, reading the renderer's
    /// unpacked `surface` ([`crate::render::surface`]); `lit_layout` is the renderer's group 0.
    pub fn new(
        ctx: &GpuContext,
        snow: &SnowDeformation,
        surface: &wgpu::Buffer,
        settings: ShellSettings,
        lit_layout: &wgpu::BindGroupLayout,
    ) -> Result<Self, SnowError> {
        settings.validate()?;
        let (device, queue) = (&ctx.device, &ctx.queue);
        let volume = DetailVolume::generate(settings.texture, settings.texture_size, settings.seed)?;
        let (colour_view, distance_view, sampler) = detail_textures(device, queue, &volume);
        let p = snow.params();
        let patch = ShellPatch::new(&settings, p.resolution, p.texel_m());
        let faces = patch.faces();
        let face_count = (faces.len() / 3) as u32;
        let storage = |label: &str, size: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size.max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let face_buffer = storage("shell faces", faces.len() as u64 * 4);
        queue.write_buffer(&face_buffer, 0, bytemuck::cast_slice(&faces));
        let base = storage("shell base (unused in snow mode)", 32);
        let vertices = storage("shell vertices", u64::from(patch.vertices()) * size_of::<vertices::ShellVertex>() as u64);
        let tetras = storage("shell tetrahedra", u64::from(face_count) * 3 * size_of::<tetrahedra::Tetra>() as u64);
        let corners = storage("shell corners", u64::from(face_count) * 3 * u64::from(CORNERS_PER_TETRA) * 4);
        let res = snow.resources();
        let vertex_pass =
            ShellVertexPass::new(device, &base, &SnowSurface { surface, heightmap: &res.heightmap, terrain_params: &res.terrain_params, terrain_constants: res.terrain_constants() }, &vertices);
        let tetra_pass = ShellTetraPass::new(device, &face_buffer, &vertices, &tetras, &corners);
        let pipelines = PeelPipelines::new(device, lit_layout);
        let draw_params = layout::uniform_buffer::<ShellDrawParams>(device, "shell draw params");
        let shell_group = layout::bind_group(
            device,
            "shell",
            &pipelines.shell_layout,
            &[
                draw_params.as_entire_binding(),
                corners.as_entire_binding(),
                vertices.as_entire_binding(),
                tetras.as_entire_binding(),
                wgpu::BindingResource::TextureView(&colour_view),
                wgpu::BindingResource::TextureView(&distance_view),
                wgpu::BindingResource::Sampler(&sampler),
            ],
        );
        let bytes = face_buffer.size() + base.size() + vertices.size() + tetras.size() + corners.size() + volume.gpu_bytes();
        ctx.check("building the shell")?;
        Ok(Self {
            settings,
            patch,
            faces: face_count,
            vertex_pass,
            tetra_pass,
            draw_params,
            shell_group,
            pipelines,
            targets: None,
            levels: volume.levels.len() as u32,
            dims: volume.size(),
            bytes,
            drawn: false,
        })
    }

    /// The settings it was built or last updated with.
    #[must_use]
    pub fn settings(&self) -> &ShellSettings {
        &self.settings
    }

    /// Takes new settings that need no rebuild (see [`ShellSettings::rebuild_needed`]).
    pub fn set_settings(&mut self, settings: ShellSettings) {
        self.settings = settings;
    }

    /// The patch of base vertices.
    #[must_use]
    pub fn patch(&self) -> ShellPatch {
        self.patch
    }

    /// Tetrahedra drawn per pass.
    #[must_use]
    pub fn tetrahedra(&self) -> u32 {
        self.faces * 3
    }

    /// GPU memory (bytes): buffers, the detail volume and the peeling targets.
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        self.bytes + self.targets.as_ref().map_or(0, PeelTargets::memory_bytes)
    }

    /// Records the shell's construction over `snow` and its peeled drawing
    /// into `hdr` (`size` pixels; `scene_depth` holds the scene drawn so far).
    pub fn encode(
        &mut self,
        cx: &mut FrameContext<'_>,
        lit_group: &wgpu::BindGroup,
        snow: &SnowDeformation,
        camera: Vec3,
        (scene_depth, hdr, size): (&wgpu::TextureView, &wgpu::TextureView, (u32, u32)),
    ) {
        self.drawn = false;
        let Some(corner) = snow.origin_m() else { return };
        let (device, queue) = (cx.device(), cx.queue());
        let p = snow.params();
        let s = &self.settings;
        let origin = self.patch.origin((camera.x, camera.z), (corner.x, corner.y), f64::from(p.texel_m()), p.resolution);
        let vertex_params = ShellVertexParams {
            mode: ShellVertexParams::SNOW,
            count: self.patch.vertices(),
            side: self.patch.side,
            stride: self.patch.stride,
            origin,
            resolution: p.resolution,
            _pad0: 0,
            corner: [corner.x as f32, corner.y as f32],
            texel_m: p.texel_m(),
            depth_m: p.depth_m,
            thickness_m: s.thickness_m,
            flatten_m: s.flatten_m,
            min_fraction: s.min_fraction,
            tile_m: s.tile_m,
        };
        self.vertex_pass.record(cx, &vertex_params);
        self.tetra_pass.record(cx, &TetraParams { faces: self.faces, count: self.patch.vertices(), _pad: [0; 2] });
        let [x, y, z] = self.dims;
        let draw = ShellDrawParams {
            dims: [x as f32, y as f32, z as f32, self.levels as f32],
            count: self.patch.vertices(),
            use_lod: u32::from(s.lod),
            max_steps: s.max_steps,
            _pad: 0,
            lod_bias: 0.0,
            min_alpha: 0.02,
            fade_m: [0.75 * s.radius_m, 0.95 * s.radius_m],
        };
        queue.write_buffer(&self.draw_params, 0, bytemuck::bytes_of(&draw));
        if self.targets.as_ref().is_none_or(|t| t.size != size) {
            self.targets = Some(PeelTargets::new(device, &self.pipelines, size, scene_depth));
        }
        let Some(targets) = &self.targets else { return };
        let draw = PeelDraw {
            lit_group,
            shell_group: &self.shell_group,
            vertices: self.faces * 3 * CORNERS_PER_TETRA,
            passes: s.passes,
            threshold: s.opacity,
            debug_pass: s.debug_pass,
        };
        self.pipelines.record(cx, targets, &draw, hdr);
        self.drawn = true;
    }

    /// Forgets the peeling targets (the renderer's scene depth was replaced).
    pub fn drop_targets(&mut self) {
        self.targets = None;
    }

    /// Pixels each peeling pass shaded in the last frame drawn (blocking readback; for tests and tools).
    pub fn pass_pixels(&self, ctx: &GpuContext) -> Result<PassPixels, SnowError> {
        let Some(targets) = self.targets.as_ref().filter(|_| self.drawn) else { return Ok(Vec::new()) };
        let raw = crate::gpu::read_buffer(ctx, &targets.counts)?;
        let counts: Vec<u32> = bytemuck::pod_collect_to_vec(&raw);
        Ok(counts[..self.settings.passes as usize].to_vec())
    }
}
