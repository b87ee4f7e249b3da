//! Settings that take effect when changed: [`SnowpackSettings`] is extracted
//! into the render world whenever the main world changes it (Bevy's
//! `ExtractResourcePlugin`), and the render world applies what changed to
//! the deformation before the next frame is encoded; what sizes the world
//! makes a new one (`crate::world_switch`).

use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::extract_resource::{ExtractResource, ExtractResourcePlugin};

use crate::SnowpackSettings;
use crate::render_state::SnowRenderState;
use crate::snowpack_settings::dvec2;

impl ExtractResource<RenderApp> for SnowpackSettings {
    type Source = Self;

    fn extract_resource(source: &Self::Source) -> Self {
        source.clone()
    }
}

/// The settings the render world's deformation runs with now.
#[derive(Resource)]
pub(crate) struct AppliedSettings(pub SnowpackSettings);

pub(crate) fn build(app: &mut App) {
    app.add_plugins(ExtractResourcePlugin::<SnowpackSettings>::default());
}

/// Applies the settings the main world changed (render world, before the frame is encoded).
pub(crate) fn apply_settings(settings: Res<SnowpackSettings>, applied: Option<ResMut<AppliedSettings>>, state: Option<ResMut<SnowRenderState>>) {
    let (Some(mut applied), Some(mut state)) = (applied, state) else { return };
    if !settings.is_changed() {
        return;
    }
    let (new, old) = (&*settings, &applied.0);
    let snow = state.deformation_mut();
    let (p, q) = (&new.params, &old.params);
    if p.technique != q.technique {
        snow.set_technique(p.technique);
    }
    if p.refill_m_per_s != q.refill_m_per_s {
        snow.set_refill(p.refill_m_per_s);
    }
    if p.blur != q.blur {
        snow.set_blur(p.blur);
    }
    if p.elevation != q.elevation {
        snow.set_elevation(p.elevation);
    }
    if p.range_texels != q.range_texels || p.rim != q.rim {
        snow.set_points(p.range_texels, p.rim);
    }
    if p.snowfall != q.snowfall
        && let Err(e) = snow.set_snowfall(p.snowfall.clone())
    {
        tracing::error!("bevy_snowpack: the new snowfall cannot be applied: {e}");
    }
    // The window target, when there is one, moves the window every frame anyway.
    if new.center != old.center {
        snow.set_center(dvec2(new.center));
    }
    // What sizes the world is applied by a new world (`crate::world_switch`, earlier in the frame); where
    // that failed the old world goes on, and its values stay here so a later change tries again.
    let mut now = new.clone();
    let (created, params) = (&applied.0, &mut now.params);
    (params.extent_m, params.resolution, params.depth_m) = (created.params.extent_m, created.params.resolution, created.params.depth_m);
    (params.hardness_kpa, params.tile_memory_bytes, params.teleport_m) =
        (created.params.hardness_kpa, created.params.tile_memory_bytes, created.params.teleport_m);
    (params.density_kg_m3, params.max_density_kg_m3, params.repose_deg, params.displace) =
        (created.params.density_kg_m3, created.params.max_density_kg_m3, created.params.repose_deg, created.params.displace);
    params.store_ground = created.params.store_ground;
    now.terrain = created.terrain.clone();
    now.store = created.store.clone();
    if snow.params().snowfall.is_none() && now.params.snowfall.is_some() {
        // A window created without snowfall cannot start it (the error above).
        now.params.snowfall = None;
    }
    applied.0 = now;
}
