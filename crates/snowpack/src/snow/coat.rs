//! The snow characters carry, as a plug-in of [`SnowDeformation`]: the coat
//! pass of each posed character after the ground's update
//! ([`crate::skin::coat`]), its settings per skinned mesh, and reading it back.

use crate::accumulate::{OcclusionParams, SnowAccumulation};
use crate::error::SnowError;
use crate::frame::FrameContext;
use crate::gpu::GpuContext;
use crate::height_depth::sky_depth_texture;
use crate::skin::coat::{CoatGround, CoatSettings, SnowCoatParams, SnowCoatPass};
use crate::skin::skinning::SkinnedInstance;

use super::deformation::{SkinnedId, SnowDeformation};

/// What the frame's ground passes leave for the coats: where the window is,
/// this frame's snowfall and the occlusion's projection.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct CoatFrame {
    pub origin: [i32; 2],
    pub corner_m: [f32; 2],
    pub fall_m: f32,
    pub dt_s: f32,
    pub sky: Option<OcclusionParams>,
}

/// The coats' state: the pass, each skinned mesh's settings and whether it
/// has a previous pose, and the frame's ground.
pub(super) struct Coats {
    pass: SnowCoatPass,
    settings: Vec<CoatSettings>,
    posed_before: Vec<bool>,
    no_sky: wgpu::TextureView,
    pub frame: CoatFrame,
}

impl Coats {
    pub fn new(device: &wgpu::Device, terrain_constants: &[(&str, f64)]) -> Self {
        Self {
            pass: SnowCoatPass::new(device, terrain_constants),
            settings: Vec::new(),
            posed_before: Vec::new(),
            no_sky: sky_depth_texture(device, 1).create_view(&wgpu::TextureViewDescriptor::default()),
            frame: CoatFrame::default(),
        }
    }

    /// A skinned mesh was added: default settings, no pose yet.
    pub fn register(&mut self) {
        self.settings.push(CoatSettings::default());
        self.posed_before.push(false);
    }
}

impl SnowDeformation {
    /// Sets how skinned mesh `id`'s character gathers and loses snow.
    pub fn set_coat(&mut self, id: SkinnedId, settings: CoatSettings) -> Result<(), SnowError> {
        settings.validate()?;
        let slot = self.coats.settings.get_mut(id.0).ok_or(SnowError::InvalidParameter { field: "skinned mesh", why: format!("no skinned mesh {}", id.0) })?;
        *slot = settings;
        Ok(())
    }

    /// The snow on skinned mesh `id`'s vertices: one `f32` a vertex (m), in
    /// the mesh's vertex order, `STORAGE | VERTEX`. A character material
    /// binds it as a per-vertex attribute (`docs/rendering.md`, "Snow on
    /// characters"); it is written by [`Self::encode`] for posed meshes.
    #[must_use]
    pub fn coat_buffer(&self, id: SkinnedId) -> Option<&wgpu::Buffer> {
        self.skinned.get(id.0).map(|s| &s.coat)
    }

    /// Reads skinned mesh `id`'s coat back (m a vertex); blocks until the GPU is done.
    pub fn read_coat(&self, ctx: &GpuContext, id: SkinnedId) -> Result<Vec<f32>, SnowError> {
        let buffer = self.coat_buffer(id).ok_or(SnowError::InvalidParameter { field: "skinned mesh", why: format!("no skinned mesh {}", id.0) })?;
        Ok(bytemuck::pod_collect_to_vec(&crate::gpu::read_buffer(ctx, buffer)?))
    }

    /// Records the coat pass of every character posed this frame (`skinned`
    /// is `self.skinned`, taken out while the frame borrows it).
    pub(super) fn record_coats(&mut self, ctx: &GpuContext, encoder: &mut wgpu::CommandEncoder, skinned: &[SkinnedInstance]) {
        let f = self.coats.frame;
        let p = &self.params;
        let sky_view = self.accumulation.as_ref().filter(|_| f.sky.is_some()).map(SnowAccumulation::sky_view);
        let ground = CoatGround {
            heightmap: &self.res.heightmap,
            snow: &self.res.snow,
            fallen: &self.res.fallen,
            terrain_params: &self.res.terrain_params,
            sky: sky_view.unwrap_or(&self.coats.no_sky),
        };
        let base = SnowCoatParams {
            origin: f.origin,
            resolution: p.resolution,
            corner_m: f.corner_m,
            texel_m: p.texel_m(),
            depth_m: p.depth_m,
            dt_s: f.dt_s,
            fall_m: f.fall_m,
            use_fallen: u32::from(p.snowfall.is_some()),
            use_sky: u32::from(sky_view.is_some()),
            // A vertex that moved farther than a capsule's teleport in one frame jumped.
            teleport_m: if p.teleport_m > 0.0 { p.teleport_m } else { f32::INFINITY },
            sky_shear: f.sky.map_or([0.0; 2], |s| s.shear),
            sky_offset_m: f.sky.map_or([0.0; 2], |s| s.offset_m),
            sky_y0_m: f.sky.map_or(0.0, |s| s.y0_m),
            sky_low_m: f.sky.map_or(0.0, |s| s.low_m),
            sky_high_m: f.sky.map_or(1.0, |s| s.high_m),
            ..SnowCoatParams::default()
        };
        for (slot, &k) in self.posed.iter().enumerate() {
            let Some(instance) = skinned.get(k) else { continue };
            let params = base.with_settings(&self.coats.settings[k]);
            let params = SnowCoatParams { has_previous: u32::from(self.coats.posed_before[k]), ..params };
            self.coats.pass.record(FrameContext::new(ctx, encoder, &mut self.timer), slot, instance, ground, &params);
            self.coats.posed_before[k] = true;
        }
    }
}
