//! [`Renderer`]: one frame of snowpack's own renderer, its passes in order.

use glam::{Vec2, Vec3};

pub use super::camera::Camera;
pub use super::environment::EnvironmentMap;
pub use super::params::{DebugView, LightParams, Material, MaterialPreset, RenderParams};

use super::actors::ActorPass;
use super::ao::{AoParams, AoPass};
use super::environment::EnvironmentPass;
use super::frame::FrameUniforms;
use super::lod::LodSettings;
use super::pipeline::{DEPTH_FORMAT, HDR_FORMAT, entry, storage_ro, texture};
use super::shadow::ShadowMap;
use super::shell::ShellRenderer;
use super::skinned::SkinnedDrawPass;
use super::sky::SkyPass;
use super::terrain::TerrainPass;
use super::tonemap::TonemapPass;
use crate::Deformer;
use crate::error::SnowError;
use crate::frame::FrameContext;
use crate::gpu::context::GpuContextExt;
use crate::gpu::{GpuContext, GpuTimer, PassTimings, layout};
use crate::snow::SnowDeformation;
use crate::snow::inspect::SnowInspect;

/// Output format of [`Renderer::render_image`].
pub const IMAGE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// Exposure multiplier at 0 EV: sunlit flat fresh snow under a 35° sun comes out
/// at about 80% display white, leaving the tone curve room to show relief.
const BASE_EXPOSURE: f32 = 0.42;

/// What the last frame drew.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RenderStats {
    /// Terrain patches drawn in the view.
    pub patches: u32,
    /// Terrain triangles drawn in the view.
    pub terrain_triangles: u64,
    /// Terrain patches drawn into the shadow map.
    pub shadow_patches: u32,
    /// Actors drawn.
    pub actors: u32,
    /// Actor triangles drawn in the view.
    pub actor_triangles: u64,
    /// Finest and coarsest level of detail drawn in the view.
    pub levels: (u32, u32),
}

struct Targets {
    size: (u32, u32),
    hdr: wgpu::TextureView,
    depth: wgpu::TextureView,
    tonemap_group: wgpu::BindGroup,
}

/// The terrain pass's group 1: surface, heightmap, terrain params, AO, decal layer.
fn snow_bind_group(
    device: &wgpu::Device,
    terrain: &TerrainPass,
    snow: &SnowDeformation,
    unpack: &super::surface::SurfaceUnpackPass,
    ao: &AoPass,
) -> wgpu::BindGroup {
    let res = snow.resources();
    let decal_view = snow.decal_layer().create_view(&wgpu::TextureViewDescriptor::default());
    layout::bind_group(
        device,
        "terrain snow",
        &terrain.snow_layout,
        &[
            unpack.surface.as_entire_binding(),
            res.heightmap.as_entire_binding(),
            res.terrain_params.as_entire_binding(),
            ao.ao.as_entire_binding(),
            wgpu::BindingResource::TextureView(&decal_view),
            unpack.packing.as_entire_binding(),
        ],
    )
}

/// Draws a [`SnowDeformation`] and its actors.
pub struct Renderer {
    params: RenderParams,
    frame: wgpu::Buffer,
    lit_group: wgpu::BindGroup,
    shadow_group: wgpu::BindGroup,
    snow_group: wgpu::BindGroup,
    /// The decal layer `snow_group` binds: the deformation replaces its 1x1
    /// placeholder when the decals technique starts, and the group is rebuilt.
    decal_layer: wgpu::Texture,
    env: EnvironmentPass,
    env_sun: (Vec3, Vec3),
    shadow: ShadowMap,
    unpack: super::surface::SurfaceUnpackPass,
    ao: AoPass,
    terrain: TerrainPass,
    actors: ActorPass,
    skinned: SkinnedDrawPass,
    objects: super::objects::ObjectDrawPass,
    sky: SkyPass,
    tonemap: TonemapPass,
    targets: Option<Targets>,
    image: Option<(wgpu::Texture, (u32, u32))>,
    timer: GpuTimer,
    stats: RenderStats,
    height_bounds: (f32, f32),
    lit_layout: wgpu::BindGroupLayout,
    shell: Option<ShellRenderer>,
}

/// The layout of the lit passes' frame group: uniforms, the shadow map and
/// its comparison sampler, the prefiltered environment, the detail texture
/// and its sampler.
fn lit_frame_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let fragment = wgpu::ShaderStages::FRAGMENT;
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("lit frame"),
        entries: &[
            layout::uniform(0, wgpu::ShaderStages::VERTEX | fragment),
            entry(
                1,
                fragment,
                wgpu::BindingType::Texture { sample_type: wgpu::TextureSampleType::Depth, view_dimension: wgpu::TextureViewDimension::D2, multisampled: false },
            ),
            entry(2, fragment, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison)),
            storage_ro(3, fragment),
            texture(4, fragment, true),
            entry(5, fragment, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering)),
        ],
    })
}

/// The lit passes' frame group over `frame`, `shadow` and the `prefiltered`
/// environment, with the detail texture made here.
fn lit_frame_group(
    (device, queue): (&wgpu::Device, &wgpu::Queue),
    lit_layout: &wgpu::BindGroupLayout,
    frame: &wgpu::Buffer,
    shadow: &ShadowMap,
    prefiltered: &wgpu::Buffer,
) -> wgpu::BindGroup {
    let detail = super::detail::detail_texture(device, queue);
    let detail_view = detail.create_view(&wgpu::TextureViewDescriptor::default());
    let detail_sampler = device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("detail"),
        address_mode_u: wgpu::AddressMode::Repeat,
        address_mode_v: wgpu::AddressMode::Repeat,
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        mipmap_filter: wgpu::MipmapFilterMode::Linear,
        ..Default::default()
    });
    layout::bind_group(
        device,
        "lit frame",
        lit_layout,
        &[
            frame.as_entire_binding(),
            wgpu::BindingResource::TextureView(&shadow.view),
            wgpu::BindingResource::Sampler(&shadow.sampler),
            prefiltered.as_entire_binding(),
            wgpu::BindingResource::TextureView(&detail_view),
            wgpu::BindingResource::Sampler(&detail_sampler),
        ],
    )
}

impl Renderer {
    /// Builds every pass for `snow`, lit by `env`, drawing into `output_format`
    /// ([`IMAGE_FORMAT`] for [`Self::render_image`]); prefilters the environment.
    pub fn new(
        ctx: &GpuContext,
        snow: &SnowDeformation,
        env: &EnvironmentMap,
        params: RenderParams,
        output_format: wgpu::TextureFormat,
    ) -> Result<Self, SnowError> {
        ctx.guarded(|| Self::build(ctx, snow, env, params, output_format))
    }

    fn build(
        ctx: &GpuContext,
        snow: &SnowDeformation,
        env: &EnvironmentMap,
        params: RenderParams,
        output_format: wgpu::TextureFormat,
    ) -> Result<Self, SnowError> {
        let (device, queue) = (&ctx.device, &ctx.queue);
        let flags = ctx.downlevel;
        if !flags.contains(wgpu::DownlevelFlags::VERTEX_STORAGE) {
            return Err(SnowError::Unsupported("storage buffers in vertex shaders (the terrain reads the snow surface)".into()));
        }
        if params.patch_quads < 4 || !params.patch_quads.is_multiple_of(4) {
            return Err(SnowError::InvalidParameter { field: "patch_quads", why: format!("{} is not a positive multiple of 4", params.patch_quads) });
        }
        let lit_layout = lit_frame_layout(device);
        let shadow_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shadow frame"),
            entries: &[layout::uniform(0, wgpu::ShaderStages::VERTEX)],
        });
        let frame = layout::uniform_buffer::<FrameUniforms>(device, "frame");
        let env_pass = EnvironmentPass::new(device, queue, env);
        let shadow = ShadowMap::new(device, params.shadow_map_size);
        let lit_group = lit_frame_group((device, queue), &lit_layout, &frame, &shadow, &env_pass.prefiltered);
        let shadow_group = layout::bind_group(device, "shadow frame", &shadow_layout, &[frame.as_entire_binding()]);
        let res = snow.resources();
        let unpack = super::surface::SurfaceUnpackPass::new(device, res);
        let ao = AoPass::new(device, &unpack.surface, res.resolution);
        let terrain = TerrainPass::new(device, &lit_layout, &shadow_layout, params.patch_quads, res.terrain_kind);
        let snow_group = snow_bind_group(device, &terrain, snow, &unpack, &ao);
        let actors = ActorPass::new(device, &lit_layout, &shadow_layout, params.sphere_mesh);
        let skinned = SkinnedDrawPass::new(device, &lit_layout, &shadow_layout);
        let objects = super::objects::ObjectDrawPass::new(device, &lit_layout, &shadow_layout);
        let sky = SkyPass::new(device, &frame, &env_pass.full);
        let tonemap = TonemapPass::new(device, output_format);
        let mut timer = GpuTimer::new(device, queue);

        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("environment prefilter") });
        timer.begin_frame();
        env_pass.record(&mut FrameContext::new(ctx, &mut encoder, &mut timer));
        timer.end_frame(&mut encoder);
        queue.submit([encoder.finish()]);
        ctx.check("environment prefilter")?;

        let (lo, hi) = snow.terrain().height_bounds();
        let p = snow.params();
        Ok(Self {
            params,
            frame,
            lit_group,
            shadow_group,
            snow_group,
            decal_layer: snow.decal_layer().clone(),
            env_sun: env.brightest(),
            env: env_pass,
            shadow,
            unpack,
            ao,
            terrain,
            actors,
            skinned,
            objects,
            sky,
            tonemap,
            targets: None,
            image: None,
            timer,
            stats: RenderStats::default(),
            // Rims rise above rest; leave room for them and for rounding.
            height_bounds: (lo - 0.5, hi + (p.depth_m + p.snowfall.as_ref().map_or(0.0, |s| s.max_m)) * (1.0 + p.elevation.max(0.0)) + 1.0),
            lit_layout,
            shell: None,
        })
    }

    /// The parameters in use.
    #[must_use]
    pub fn params(&self) -> &RenderParams {
        &self.params
    }

    /// Changes material, light, debug view or distances (the shadow map size,
    /// patch grid and sphere mesh stay as built).
    pub fn set_params(&mut self, params: RenderParams) {
        self.params =
            RenderParams { shadow_map_size: self.params.shadow_map_size, patch_quads: self.params.patch_quads, sphere_mesh: self.params.sphere_mesh, ..params };
    }

    /// Unit vector toward the sun as lit.
    #[must_use]
    pub fn sun_direction(&self) -> Vec3 {
        self.params.light.sun_direction.map_or(self.env_sun.0, Vec3::normalize)
    }

    /// What the last frame drew.
    #[must_use]
    pub fn stats(&self) -> RenderStats {
        self.stats
    }

    /// Median GPU time per render pass since the last [`Self::clear_timings`].
    #[must_use]
    pub fn timings(&self) -> PassTimings {
        self.timer.medians()
    }

    /// Forgets timing samples (after warm-up).
    pub fn clear_timings(&mut self) {
        self.timer.clear();
    }

    /// Bytes of GPU memory the renderer holds (targets included).
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        let targets = self.targets.as_ref().map_or(0, |t| u64::from(t.size.0) * u64::from(t.size.1) * (8 + 4));
        self.env.memory_bytes()
            + self.shadow.memory_bytes()
            + self.unpack.memory_bytes()
            + self.ao.ao.size()
            + targets
            + self.shell().map_or(0, ShellRenderer::memory_bytes)
    }

    fn ensure_targets(&mut self, device: &wgpu::Device, size: (u32, u32)) {
        if self.targets.as_ref().is_some_and(|t| t.size == size) {
            return;
        }
        let hdr = super::pipeline::screen_target(device, "hdr scene", size, HDR_FORMAT);
        let depth = super::pipeline::screen_target(device, "scene depth", size, DEPTH_FORMAT);
        let tonemap_group = self.tonemap.bind_group(device, &self.frame, &hdr);
        // The shell's targets sample the old scene depth.
        if let Some(shell) = &mut self.shell {
            shell.drop_targets();
        }
        self.targets = Some(Targets { size, hdr, depth, tonemap_group });
    }

    fn uniforms(&self, snow: &SnowDeformation, camera: &Camera, size: (u32, u32), eye_height: f32) -> (FrameUniforms, LodSettings) {
        let p = &self.params;
        let aspect = size.0 as f32 / size.1.max(1) as f32;
        let view_proj = camera.view_proj(aspect);
        let sun = self.sun_direction();
        let (light_view_proj, shadow_texel) = super::shadow::fit_shadow(camera, aspect, sun, p.shadow_distance_m, self.shadow.size);
        let sp = snow.params();
        let window = snow.origin_m().map(|o| (Vec2::new(o.x as f32, o.y as f32), sp.extent_m));
        let bonus = sp.extent_m * 0.5;
        let lod = LodSettings {
            finest_m: p.finest_patch_m,
            quads: p.patch_quads,
            range_factor: 8.0,
            morph_start: 0.8,
            morph_end: 0.98,
            view_distance_m: p.view_distance_m,
            bonus_m: bonus,
            bonus_margin_m: bonus,
            window,
            vertical_m: eye_height,
        };
        let m = p.material;
        let (corner, placed) = window.map_or((Vec2::ZERO, 0), |(c, _)| (c, 1));
        let u = FrameUniforms {
            view_proj: view_proj.to_cols_array_2d(),
            inv_view_proj: view_proj.inverse().to_cols_array_2d(),
            light_view_proj: light_view_proj.to_cols_array_2d(),
            camera: camera.position.extend(eye_height).to_array(),
            sun: sun.extend(p.light.sun_intensity).to_array(),
            sun_color: self.env_sun.1.extend(p.light.sky_intensity).to_array(),
            window: [corner.x, corner.y, sp.extent_m, sp.texel_m()],
            window_info: [sp.resolution, placed, p.debug_view.index(), u32::from(sp.technique == crate::Technique::Decals)],
            lod: [lod.bonus_m, lod.bonus_margin_m, 0.0, p.view_distance_m],
            // The rest depth of open ground: the window's undisturbed snow
            // and the ground outside it, which get the same snowfall, so no
            // edge shows where the window ends.
            snow: [sp.depth_m + snow.fallen_m(), p.shadow_distance_m, shadow_texel, BASE_EXPOSURE * p.light.exposure_ev.exp2()],
            fresh: m.fresh_albedo.extend(m.fresh_roughness).to_array(),
            packed: m.packed_albedo.extend(m.packed_roughness).to_array(),
            ground: m.ground_albedo.extend(m.ground_roughness).to_array(),
            scatter: m.scatter.extend(m.wrap).to_array(),
            detail: [m.sparkle, m.detail_strength, m.detail_frequency, m.macro_variation],
            background: p.background.map_or([0.0; 4], |c| c.extend(1.0).to_array()),
            env_info: [self.env.size.0, self.env.size.1, 0, 0],
            compaction: [m.compaction_full, m.packed_detail, m.packed_sparkle, m.ground_show_through],
        };
        (u, lod)
    }

    /// Records one frame into `encoder`, drawing into `target` (of the output
    /// format, `size` pixels). Nothing is called after the submit: the
    /// frame's timestamps are mapped when the encoder is submitted and taken
    /// by the next `encode` (a non-blocking poll).
    #[expect(
        clippy::too_many_arguments,
        reason = "each is a separate thing the caller holds (device, encoder, snow, actors, camera, target); a bundle would be built only to be unpacked"
    )]
    pub fn encode(
        &mut self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        snow: &SnowDeformation,
        actors: &[Deformer],
        camera: &Camera,
        target: &wgpu::TextureView,
        size: (u32, u32),
    ) {
        self.prepare_frame(ctx, snow, actors, camera, size);
        self.timer.begin_frame();
        if let Some(origin) = snow.origin_texel() {
            // Window coordinates fit i32 on the GPU (see the deformation's frame).
            let sp = snow.params();
            self.unpack.record(&mut FrameContext::new(ctx, encoder, &mut self.timer), [origin[0] as i32, origin[1] as i32], sp);
            let params = AoParams { resolution: sp.resolution, steps: AoPass::STEPS, texel_m: sp.texel_m(), strength: self.params.ao_strength };
            self.ao.record(&mut FrameContext::new(ctx, encoder, &mut self.timer), params);
        }
        self.record_shadow(encoder, snow);
        if self.params.shell.enabled {
            self.sync_shell(ctx, snow);
        }
        let Some(targets) = &self.targets else { return };
        {
            let mut pass = scene_pass(encoder, &mut self.timer, targets, "sky", true);
            self.sky.draw(&mut pass);
        }
        {
            let mut pass = scene_pass(encoder, &mut self.timer, targets, "terrain", false);
            self.terrain.draw_lit(&mut pass, &self.lit_group, &self.snow_group);
        }
        if self.actors.count() > 0 || snow.posed_meshes().next().is_some() {
            let mut pass = scene_pass(encoder, &mut self.timer, targets, "actors", false);
            self.actors.draw_lit(&mut pass, &self.lit_group);
            self.skinned.draw_lit(&mut pass, &self.lit_group, snow.posed_meshes());
        }
        if let Some(acc) = snow.accumulation() {
            let mut pass = scene_pass(encoder, &mut self.timer, targets, "objects", false);
            self.objects.draw_lit(&mut pass, &self.lit_group, acc);
        }
        if self.params.shell.enabled
            && let Some(shell) = &mut self.shell
        {
            shell.encode(&mut FrameContext::new(ctx, encoder, &mut self.timer), &self.lit_group, snow, camera.position, (&targets.depth, &targets.hdr, size));
        }
        self.record_tonemap(encoder, target);
        self.timer.end_frame(encoder);
    }

    /// Takes the timestamps that came back, sizes the targets, writes the
    /// frame's uniforms, and culls and uploads what the frame draws.
    fn prepare_frame(&mut self, ctx: &GpuContext, snow: &SnowDeformation, actors: &[Deformer], camera: &Camera, size: (u32, u32)) {
        let (device, queue) = (&ctx.device, &ctx.queue);
        // Timestamps that have come back since the last frame.
        let _ = device.poll(wgpu::PollType::Poll);
        self.timer.collect();
        self.ensure_targets(device, size);
        let ground = snow.terrain().height_at(camera.position.x, camera.position.z) + snow.params().depth_m + snow.fallen_m();
        let eye_height = (camera.position.y - ground).max(0.0);
        let (uniforms, lod) = self.uniforms(snow, camera, size, eye_height);
        queue.write_buffer(&self.frame, 0, bytemuck::bytes_of(&uniforms));
        if snow.decal_layer() != &self.decal_layer {
            self.snow_group = snow_bind_group(device, &self.terrain, snow, &self.unpack, &self.ao);
            self.decal_layer = snow.decal_layer().clone();
        }

        let eye = Vec2::new(camera.position.x, camera.position.z);
        let all = lod.select(eye);
        let view_proj = glam::Mat4::from_cols_array_2d(&uniforms.view_proj);
        let light = glam::Mat4::from_cols_array_2d(&uniforms.light_view_proj);
        let visible = super::lod::cull(&all, &super::lod::side_planes(view_proj), self.height_bounds);
        let casters = super::lod::cull(&all, &super::lod::side_planes(light), self.height_bounds);
        self.terrain.prepare(device, queue, &visible, &casters);
        self.actors.prepare(device, queue, actors);
        self.objects.prepare(device, queue, snow.accumulation());
        self.stats = RenderStats {
            patches: visible.len() as u32,
            terrain_triangles: visible.iter().map(|p| u64::from(p.triangles())).sum(),
            shadow_patches: casters.len() as u32,
            actors: self.actors.count(),
            actor_triangles: self.actors.triangles() + self.objects.triangles(),
            levels: (
                visible.iter().map(super::lod::PatchInstance::level).min().unwrap_or(0),
                visible.iter().map(super::lod::PatchInstance::level).max().unwrap_or(0),
            ),
        };
    }

    /// The shadow map: terrain, actors, characters and objects from the sun.
    fn record_shadow(&mut self, encoder: &mut wgpu::CommandEncoder, snow: &SnowDeformation) {
        let slot = self.timer.reserve("shadow");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("shadow"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.shadow.view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: self.timer.render_writes(slot),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        self.terrain.draw_shadow(&mut pass, &self.shadow_group, &self.snow_group);
        self.actors.draw_shadow(&mut pass, &self.shadow_group);
        self.skinned.draw_shadow(&mut pass, &self.shadow_group, snow.posed_meshes());
        if let Some(acc) = snow.accumulation() {
            self.objects.draw_shadow(&mut pass, &self.shadow_group, acc);
        }
    }

    /// The tonemap of the HDR target into `target`.
    fn record_tonemap(&mut self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::TextureView) {
        let Some(targets) = &self.targets else { return };
        let slot = self.timer.reserve("tonemap");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("tonemap"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::BLACK), store: wgpu::StoreOp::Store },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: self.timer.render_writes(slot),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        self.tonemap.draw(&mut pass, &targets.tonemap_group);
    }

    /// Builds the shell, or rebuilds it when its texture or patch changed;
    /// hands it settings that need no rebuild. A failure is logged and the
    /// shell left off (the settings are validated when a scene is read).
    fn sync_shell(&mut self, ctx: &GpuContext, snow: &SnowDeformation) {
        let wanted = self.params.shell;
        match &mut self.shell {
            Some(shell) if !shell.settings().rebuild_needed(&wanted) => shell.set_settings(wanted),
            _ => {
                self.shell = match ShellRenderer::new(ctx, snow, &self.unpack.surface, wanted, &self.lit_layout) {
                    Ok(shell) => Some(shell),
                    Err(e) => {
                        tracing::warn!("shell detail off: {e}");
                        self.params.shell.enabled = false;
                        None
                    }
                };
            }
        }
    }

    /// The shell, once drawn (for its statistics).
    #[must_use]
    pub fn shell(&self) -> Option<&ShellRenderer> {
        self.shell.as_ref().filter(|_| self.params.shell.enabled)
    }

    /// Renders one frame headless and returns it as sRGB RGBA8 rows (blocking;
    /// the renderer must have been built for [`IMAGE_FORMAT`]).
    pub fn render_image(
        &mut self,
        ctx: &GpuContext,
        snow: &SnowDeformation,
        actors: &[Deformer],
        camera: &Camera,
        size: (u32, u32),
    ) -> Result<Vec<u8>, SnowError> {
        ctx.guarded(|| self.render_image_unguarded(ctx, snow, actors, camera, size))
    }

    fn render_image_unguarded(
        &mut self,
        ctx: &GpuContext,
        snow: &SnowDeformation,
        actors: &[Deformer],
        camera: &Camera,
        size: (u32, u32),
    ) -> Result<Vec<u8>, SnowError> {
        let device = &ctx.device;
        if self.image.as_ref().is_none_or(|(_, s)| *s != size) {
            let texture = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("frame image"),
                size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: IMAGE_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            });
            self.image = Some((texture, size));
        }
        let Some((texture, _)) = &self.image else { unreachable!("image target made above") };
        let texture = texture.clone();
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("render frame") });
        self.encode(ctx, &mut encoder, snow, actors, camera, &view, size);
        let readback = crate::gpu::readback::TextureReadback::record(device, &mut encoder, &texture);
        ctx.queue.submit([encoder.finish()]);
        ctx.check("render frame")?;
        readback.read(ctx)
    }

    /// Waits for outstanding timestamp readbacks and collects them.
    pub fn finish(&mut self, ctx: &GpuContext) -> Result<(), crate::SnowError> {
        ctx.guarded(|| self.finish_unguarded(ctx))
    }

    fn finish_unguarded(&mut self, ctx: &GpuContext) -> Result<(), crate::SnowError> {
        ctx.wait_idle("finishing render timings")?;
        self.timer.collect();
        Ok(())
    }
}

/// Begins a pass over the HDR scene target and depth, cleared or loaded.
fn scene_pass<'e>(encoder: &'e mut wgpu::CommandEncoder, timer: &mut GpuTimer, targets: &Targets, label: &'static str, clear: bool) -> wgpu::RenderPass<'e> {
    let slot = timer.reserve(label);
    let (colour_load, depth_load) =
        if clear { (wgpu::LoadOp::Clear(wgpu::Color::BLACK), wgpu::LoadOp::Clear(0.0)) } else { (wgpu::LoadOp::Load, wgpu::LoadOp::Load) };
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: &targets.hdr,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations { load: colour_load, store: wgpu::StoreOp::Store },
        })],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: &targets.depth,
            depth_ops: Some(wgpu::Operations { load: depth_load, store: wgpu::StoreOp::Store }),
            stencil_ops: None,
        }),
        timestamp_writes: timer.render_writes(slot),
        occlusion_query_set: None,
        multiview_mask: None,
    })
}
