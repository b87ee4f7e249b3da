//! The snow characters carry, part of the characters plug-in
//! ([`super::characters`]): the coat pass of each posed character after the
//! frame's steps ([`crate::skin::coat`]), its settings per skinned mesh, and
//! reading it back.

use crate::accumulate::OcclusionParams;
use crate::error::SnowError;
use crate::frame::FrameContext;
use crate::gpu::GpuContext;
use crate::height_depth::sky_depth_texture;
use crate::skin::coat::{CoatGround, CoatSettings, SnowCoatParams, SnowCoatPass};

use super::characters::{Characters, SkinnedId};
use super::core_window::CoreWindow;
use super::deformation::SnowDeformation;
use super::steps::GroundAfter;

/// The coats' state: the pass, each skinned mesh's settings and whether it
/// was posed before (has last frame's positions).
pub(super) struct Coats {
    pass: SnowCoatPass,
    settings: Vec<CoatSettings>,
    posed_before: Vec<bool>,
    /// A 1x1 occlusion map for frames without objects.
    no_sky: wgpu::TextureView,
}

impl Coats {
    /// No characters yet; the pass for a window whose terrain kind `terrain_constants` names.
    pub(super) fn new(device: &wgpu::Device, terrain_constants: &[(&'static str, f64)]) -> Self {
        Self {
            pass: SnowCoatPass::new(device, terrain_constants),
            settings: Vec::new(),
            posed_before: Vec::new(),
            no_sky: sky_depth_texture(device, 1).create_view(&wgpu::TextureViewDescriptor::default()),
        }
    }

    /// A skinned mesh was added: default settings, no pose yet.
    pub(super) fn register(&mut self) {
        self.settings.push(CoatSettings::default());
        self.posed_before.push(false);
    }
}

/// The coat's uniforms for the frame's ground, before a character's settings.
fn frame_params(core: &CoreWindow, ground: &GroundAfter, sky_bound: bool, dt_s: f32) -> SnowCoatParams {
    let p = &core.params;
    let sky: Option<OcclusionParams> = ground.sky.filter(|_| sky_bound);
    SnowCoatParams {
        origin: [ground.window.origin[0] as i32, ground.window.origin[1] as i32],
        resolution: p.resolution,
        corner_m: [ground.window.corner.x as f32, ground.window.corner.y as f32],
        texel_m: p.texel_m(),
        depth_m: p.depth_m,
        dt_s,
        fall_m: ground.fall_m,
        use_fallen: u32::from(p.snowfall.is_some()),
        use_sky: u32::from(sky.is_some()),
        // A vertex that moved farther than a teleport in one frame jumped.
        teleport_m: if p.teleport_m > 0.0 { p.teleport_m } else { f32::INFINITY },
        sky_shear: sky.map_or([0.0; 2], |s| s.shear),
        sky_offset_m: sky.map_or([0.0; 2], |s| s.offset_m),
        sky_y0_m: sky.map_or(0.0, |s| s.y0_m),
        sky_low_m: sky.map_or(0.0, |s| s.low_m),
        sky_high_m: sky.map_or(1.0, |s| s.high_m),
        ..SnowCoatParams::default()
    }
}

impl Characters {
    /// Records the coat pass of every character posed this frame, against
    /// the ground the frame's steps left (`sky`: the objects' occlusion map).
    pub(super) fn record_coats(&mut self, cx: &mut FrameContext<'_>, core: &CoreWindow, sky: Option<&wgpu::TextureView>, ground: GroundAfter, dt_s: f32) {
        let sky_view = sky.filter(|_| ground.sky.is_some());
        let bound = CoatGround {
            heightmap: &core.res.heightmap,
            snow: &core.res.snow,
            fallen: &core.res.fallen,
            terrain_params: &core.res.terrain_params,
            sky: sky_view.unwrap_or(&self.coats.no_sky),
        };
        let base = frame_params(core, &ground, sky_view.is_some(), dt_s);
        self.coats.pass.reserve(cx.device(), self.posed.len());
        for (slot, &k) in self.posed.iter().enumerate() {
            let Some(instance) = self.skinned.get(k) else { continue };
            let params = SnowCoatParams { has_previous: u32::from(self.coats.posed_before[k]), ..base.with_settings(&self.coats.settings[k]) };
            self.coats.pass.record(cx, slot, instance, bound, &params);
            self.coats.posed_before[k] = true;
        }
    }
}

impl SnowDeformation {
    /// Sets how skinned mesh `id`'s character gathers and loses snow.
    pub fn set_coat(&mut self, id: SkinnedId, settings: CoatSettings) -> Result<(), crate::SnowError> {
        settings.validate()?;
        let slot = self
            .characters
            .coats
            .settings
            .get_mut(id.0)
            .ok_or(SnowError::InvalidParameter { field: "skinned mesh", why: format!("no skinned mesh {}", id.0) })?;
        *slot = settings;
        Ok(())
    }

    /// The snow on skinned mesh `id`'s vertices: one `f32` a vertex (m), in
    /// the mesh's vertex order, usable as `STORAGE` and `VERTEX`. A character
    /// material binds it as a per-vertex attribute (`docs/rendering.md`,
    /// "Snow on characters"); [`Self::encode`] updates it for posed meshes.
    #[must_use]
    pub fn coat_buffer(&self, id: SkinnedId) -> Option<&wgpu::Buffer> {
        self.characters.skinned.get(id.0).map(|s| &s.coat)
    }

    low_level_pub! {
        /// Reads skinned mesh `id`'s coat back (m a vertex); blocks until the GPU is done.
        #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, tools and tests (`low_level`)"))]
        fn read_coat(&self, ctx: &GpuContext, id: SkinnedId) -> Result<Vec<f32>, SnowError> {
            let buffer = self.coat_buffer(id).ok_or(SnowError::InvalidParameter { field: "skinned mesh", why: format!("no skinned mesh {}", id.0) })?;
            Ok(bytemuck::pod_collect_to_vec(&crate::gpu::read_buffer(ctx, buffer)?))
        }
    }
}
