//! The snow characters carry, part of the characters plug-in
//! ([`super::characters`], which holds the [`Coats`]): the coat pass of each
//! posed character after the frame's steps ([`crate::skin::coat`]) and its
//! settings per skinned mesh. The game's calls (`set_coat`, `coat_buffer`)
//! are [`super::SnowDeformation`]'s.

use crate::accumulate::OcclusionParams;
use crate::deform::resources::DeformResources;
use crate::error::SnowError;
use crate::frame::FrameContext;
use crate::height_depth::{SkyTest, sky_depth_texture};
use crate::skin::coat::{CoatGround, CoatSettings, SnowCoatParams, SnowCoatPass};
use crate::skin::skinning::SkinnedInstance;

use super::core_window::CoreWindow;
use super::ground_after::GroundAfter;
use super::skinned::SkinnedId;
use crate::skin::coat::CoatSettingsExt;

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
    /// No characters yet; the pass for the window of `res`.
    pub(super) fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        Self {
            pass: SnowCoatPass::new(device, &res.bindings, &res.terrain_constants()),
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

    /// Records the coat pass of every character posed this frame (`posed`:
    /// indices into `skinned`, the characters' instances), against the ground the frame's steps left
    /// (`sky`: the objects' occlusion map).
    pub(super) fn record(
        &mut self,
        cx: &mut FrameContext<'_>,
        core: &CoreWindow,
        sky: Option<&wgpu::TextureView>,
        ground: GroundAfter,
        dt_s: f32,
        (posed, skinned): (&[usize], &[SkinnedInstance]),
    ) {
        let sky_view = sky.filter(|_| ground.sky.is_some());
        let bound = CoatGround { window: &core.res().bindings, sky: sky_view.unwrap_or(&self.no_sky) };
        let base = frame_params(core, &ground, sky_view.is_some(), dt_s);
        self.pass.reserve(cx.device(), posed.len());
        for (slot, &k) in posed.iter().enumerate() {
            let Some(instance) = skinned.get(k) else { continue };
            let params = SnowCoatParams { has_previous: u32::from(self.posed_before[k]), ..base.with_settings(&self.settings[k]) };
            self.pass.record(cx, slot, instance, bound, &params);
            self.posed_before[k] = true;
        }
    }

    /// Sets how skinned mesh `id`'s character gathers and loses snow.
    pub(super) fn set(&mut self, id: SkinnedId, settings: CoatSettings) -> Result<(), SnowError> {
        settings.validate()?;
        let slot = self.settings.get_mut(id.0).ok_or(SnowError::InvalidParameter { field: "skinned mesh", why: format!("no skinned mesh {}", id.0) })?;
        *slot = settings;
        Ok(())
    }
}

/// The coat's uniforms for the frame's ground, before a character's settings.
fn frame_params(core: &CoreWindow, ground: &GroundAfter, sky_bound: bool, dt_s: f32) -> SnowCoatParams {
    let p = core.params();
    let sky: Option<OcclusionParams> = ground.sky.filter(|_| sky_bound);
    SnowCoatParams {
        origin: [ground.window.origin[0] as i32, ground.window.origin[1] as i32],
        resolution: p.resolution,
        corner_m: [ground.window.corner.x as f32, ground.window.corner.y as f32],
        texel_m: p.texel_m(),
        depth_m: p.depth_m,
        dt_s,
        fall_m: ground.fall_m,
        use_fallen: u32::from(p.keeps_lying_snow()),
        use_sky: u32::from(sky.is_some()),
        // A vertex that moved farther than a teleport in one frame jumped.
        teleport_m: if p.teleport_m > 0.0 { p.teleport_m } else { f32::INFINITY },
        sky: sky.map_or(SkyTest::NONE, |s| s.sky_test()),
        ..SnowCoatParams::default()
    }
}
