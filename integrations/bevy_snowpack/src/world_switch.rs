//! Snow worlds that change at run time: when [`SnowpackSettings`] changes
//! what sizes the snow (the window's extent, resolution and depth, the
//! hardness, tile memory and teleport distance, the terrain, the store),
//! the render world saves the old world to its store, ends it and builds
//! the new one from the settings (a save in the new world's store is
//! loaded), before this frame's materials are prepared; the main world
//! marks the snow materials changed in the same frame so they bind the new
//! world's buffers. Going back to a world's settings loads its save: its
//! trails come back.

use bevy::prelude::*;
use snowpack::GpuContext;

use crate::from_render::ToMainWorld;
use crate::render_state::{SnowRenderState, create_world};
use crate::settings::AppliedSettings;
use crate::{SnowCoverMaterial, SnowGroundMaterial, SnowpackSettings};

/// The settings that differ between two configurations of the snow and
/// need a new world (named as `SnowpackSettings`' fields); empty when the
/// world can go on.
#[must_use]
pub(crate) fn world_changes(old: &SnowpackSettings, new: &SnowpackSettings) -> Vec<&'static str> {
    let (p, q) = (&new.params, &old.params);
    let fields = [
        ("params.extent_m", p.extent_m != q.extent_m),
        ("params.resolution", p.resolution != q.resolution),
        ("params.depth_m", p.depth_m != q.depth_m),
        ("params.hardness_kpa", p.hardness_kpa != q.hardness_kpa),
        ("params.density_kg_m3", p.density_kg_m3 != q.density_kg_m3),
        ("params.max_density_kg_m3", p.max_density_kg_m3 != q.max_density_kg_m3),
        ("params.repose_deg", p.repose_deg != q.repose_deg),
        ("params.displace", p.displace != q.displace),
        ("params.tile_memory_bytes", p.tile_memory_bytes != q.tile_memory_bytes),
        ("params.teleport_m", p.teleport_m != q.teleport_m),
        ("params.store_ground", p.store_ground != q.store_ground),
        ("terrain", new.terrain != old.terrain),
        ("store", format!("{:?}", new.store) != format!("{:?}", old.store)),
    ];
    fields.into_iter().filter_map(|(name, changed)| changed.then_some(name)).collect()
}

pub(crate) fn build(app: &mut App) {
    // After the terrain asset's system, which changes the terrain: the materials are marked in the same frame.
    app.add_systems(PostUpdate, refresh_snow_materials.after(crate::terrain_asset::apply_terrain_asset));
}

/// Render world, after extraction and before the materials are prepared:
/// a new snow world when the settings ask for one.
pub(crate) fn switch_world(world: &mut World) {
    let (Some(new), Some(applied)) = (world.get_resource::<SnowpackSettings>(), world.get_resource::<AppliedSettings>()) else { return };
    let changes = world_changes(&applied.0, new);
    if changes.is_empty() {
        return;
    }
    let (new, old) = (new.clone(), applied.0.clone());
    let Some(state) = world.remove_resource::<SnowRenderState>() else { return };
    // A store holds one world: the old one is saved into its own, never into the new world's folder.
    let shared_dir = matches!((&old.store, &new.store), (Some(a), Some(b)) if a.dir == b.dir);
    let save = old.store.is_some() && !shared_dir;
    tracing::info!(
        "bevy_snowpack: a new snow world ({} changed){}",
        changes.join(", "),
        if save { "; the old one's snow is saved to its store" } else { "; the old one's snow is not kept (no store of its own)" }
    );
    let (ctx, registrations, generation) = state.retire(save);
    let to_main = world.resource::<ToMainWorld>();
    let created = create_world(fresh(&ctx), &new, to_main, generation + 1, registrations.clone());
    let (state, settings) = match created {
        Ok(state) => (state, new),
        Err(e) => {
            // The old world again (from its save, where it has a store): the game goes on.
            tracing::error!("bevy_snowpack: the new snow world cannot be made, the old one goes on: {e}");
            match create_world(ctx, &old, to_main, generation + 1, registrations) {
                Ok(state) => (state, old),
                Err(e) => {
                    tracing::error!("bevy_snowpack: nor can the old snow world be made again: {e}");
                    return;
                }
            }
        }
    };
    state.insert_into(world);
    world.insert_resource(AppliedSettings(settings));
}

/// Another context over the same device and queue (the library's contexts are not `Clone`).
fn fresh(ctx: &GpuContext) -> GpuContext {
    GpuContext::from_device(ctx.device.clone(), ctx.queue.clone())
}

/// Main world: when the settings ask for a new snow world, every snow
/// material is marked changed, so the render world prepares it again (after
/// the new world is made) with the new world's buffers.
fn refresh_snow_materials(
    settings: Res<SnowpackSettings>,
    mut seen: Local<Option<SnowpackSettings>>,
    mut grounds: ResMut<Assets<SnowGroundMaterial>>,
    mut covers: ResMut<Assets<SnowCoverMaterial>>,
) {
    if !settings.is_changed() {
        return;
    }
    let changed = seen.as_ref().is_some_and(|old| !world_changes(old, &settings).is_empty());
    *seen = Some(settings.clone());
    if !changed {
        return;
    }
    let ids: Vec<_> = grounds.ids().collect();
    for id in ids {
        // Dereferenced mutably: the asset counts as modified.
        if let Some(mut m) = grounds.get_mut(id) {
            let _: &mut SnowGroundMaterial = &mut m;
        }
    }
    let ids: Vec<_> = covers.ids().collect();
    for id in ids {
        if let Some(mut m) = covers.get_mut(id) {
            let _: &mut SnowCoverMaterial = &mut m;
        }
    }
}
