//! The render world's side: the deformation on Bevy's device, each frame's
//! deformers extracted from the main world, the frame recorded into the
//! render graph before `camera_driver`, readbacks started after the submit.

use std::collections::HashMap;

use bevy::core_pipeline::schedule::camera_driver;
use bevy::prelude::*;
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderGraphSystems, RenderQueue};
use bevy::render::{Extract, ExtractSchedule, MainWorld, Render, RenderStartup, RenderSystems};
use snowpack::{Deformer, GpuContext, ObjectShape, SkinnedId, SkinnedPose, SnowDeformation, SnowFrame, SnowWindowUniform, StoredWindow as _};

use crate::control::SnowControl;
use crate::from_render::{FromRender, ToMainWorld};
use crate::mesh_deformer::{MeshDeformerFrame, MeshPose, MeshRegistration};
use crate::query::{SnowQuery, SnowTicket, split_answers};
use crate::render_state::{SnowRenderState, create_world};
use crate::settings::{AppliedSettings, apply_settings};
use crate::snowpack_settings::dvec2;
use crate::systems::SnowSystems;
use crate::{SnowCatcher, SnowDeformer, SnowWindowTarget, SnowpackSettings};

/// What presses the snow this frame, extracted from the main world.
#[derive(Resource, Default)]
pub(crate) struct ExtractedSnowFrame {
    dt_s: f32,
    deformers: Vec<Deformer>,
    /// A stable id per deformer (its entity), so each is swept from its own last pose.
    ids: Vec<u64>,
    center: Option<Vec2>,
    requests: Vec<(SnowTicket, Vec<Vec2>)>,
    meshes: MeshDeformerFrame,
    /// Every object this frame, by entity, with its pose.
    objects: Vec<(Entity, SnowCatcher, Vec3, Quat)>,
    /// A save was asked for this frame ([`SnowControl::request_save`]).
    save_requested: bool,
    /// The objects' snow was asked for this frame ([`SnowControl::request_object_stats`]).
    stats_requested: bool,
}

pub(crate) fn build(render_app: &mut SubApp, settings: SnowpackSettings, to_main: ToMainWorld) {
    render_app
        // Here for the deformation's creation; `ExtractResourcePlugin` replaces it whenever the main world changes it.
        .insert_resource(settings)
        .insert_resource(to_main)
        .init_resource::<ExtractedSnowFrame>()
        .add_systems(RenderStartup, create_deformation)
        .add_systems(
            Render,
            crate::world_switch::switch_world
                .run_if(resource_changed::<SnowpackSettings>)
                .after(RenderSystems::ExtractCommands)
                .before(RenderSystems::PrepareAssets),
        )
        .add_systems(ExtractSchedule, (extract_snow_frame, take_requests).in_set(SnowSystems::Extract))
        .add_systems(
            RenderGraph,
            (apply_settings.before(encode_snow), encode_snow.before(camera_driver), after_frame.in_set(RenderGraphSystems::Finish)).in_set(SnowSystems::Encode),
        );
}

fn create_deformation(world: &mut World) {
    let ctx = {
        let (device, queue) = (world.resource::<RenderDevice>(), world.resource::<RenderQueue>());
        GpuContext::from_device(device.wgpu_device().clone(), (**queue).clone())
    };
    let settings = world.resource::<SnowpackSettings>().clone();
    match create_world(ctx, &settings, world.resource::<ToMainWorld>(), 0, Vec::new()) {
        Ok(state) => {
            state.insert_into(world);
            world.insert_resource(AppliedSettings(settings));
        }
        Err(e) => tracing::error!("bevy_snowpack: cannot create the snow: {e}"),
    }
}

#[allow(clippy::too_many_arguments, reason = "an extract system: each argument is a main-world query or resource it copies")]
fn extract_snow_frame(
    mut frame: ResMut<ExtractedSnowFrame>,
    settings: Extract<Res<SnowpackSettings>>,
    time: Extract<Res<Time>>,
    deformers: Extract<Query<(Entity, &SnowDeformer, &GlobalTransform)>>,
    target: Extract<Query<&GlobalTransform, With<SnowWindowTarget>>>,
    meshes: Extract<Res<MeshDeformerFrame>>,
    objects: Extract<Query<(Entity, &SnowCatcher, &GlobalTransform)>>,
) {
    frame.dt_s = settings.fixed_dt_s.unwrap_or_else(|| time.delta_secs());
    // Reuses last frame's lists: nothing is allocated once they have grown.
    frame.deformers.clear();
    frame.ids.clear();
    for (e, d, t) in &deformers {
        if let Some(placed) = d.placed(t) {
            frame.deformers.push(placed);
            frame.ids.push(e.to_bits());
        }
    }
    frame.center = target.iter().next().map(|t| t.translation().xz());
    frame.meshes = (*meshes).clone();
    frame.objects = objects
        .iter()
        .map(|(e, o, t)| {
            let (_, rotation, translation) = t.to_scale_rotation_translation();
            (e, o.clone(), translation, rotation)
        })
        .collect();
    frame.objects.sort_by_key(|(e, ..)| *e);
}

/// Takes the questions and requests the main world made this frame (they are
/// asked once: the main world's lists are emptied), and hands the main world
/// what has arrived from the render world since its `PreUpdate`.
fn take_requests(mut main_world: ResMut<MainWorld>, mut frame: ResMut<ExtractedSnowFrame>) {
    crate::receive::receive_in(&mut main_world);
    if let Some(mut query) = main_world.get_resource_mut::<SnowQuery>() {
        // Appended: questions an encode never took (no deformation yet) wait for the next one.
        let asked = query.take_requests();
        frame.requests.extend(asked);
    }
    if let Some(mut control) = main_world.get_resource_mut::<SnowControl>() {
        let (save, stats) = control.take_requests();
        frame.save_requested |= save;
        frame.stats_requested |= stats;
    }
}

/// Registers the meshes new this frame (kept in `kept` for a rebuilt world); the poses of every registered one.
fn pose_meshes(
    ctx: &GpuContext,
    snow: &mut SnowDeformation,
    ids: &mut HashMap<u64, SkinnedId>,
    kept: &mut Vec<MeshRegistration>,
    frame: &MeshDeformerFrame,
) -> Vec<(SkinnedId, usize)> {
    for registration in &frame.registrations {
        let MeshRegistration { key, mesh, joint_count } = registration;
        match snow.add_skinned_mesh(ctx, mesh, *joint_count) {
            Ok(id) => {
                ids.insert(*key, id);
                kept.push(registration.clone());
            }
            Err(e) => tracing::error!("bevy_snowpack: a mesh deformer cannot be registered: {e}"),
        }
    }
    frame.poses.iter().enumerate().filter_map(|(k, MeshPose { key, .. })| ids.get(key).map(|&id| (id, k))).collect()
}

/// Lays the objects out anew when the set changed, then places each.
fn place_objects(ctx: &GpuContext, snow: &mut SnowDeformation, laid_out: &mut Vec<(Entity, ObjectShape, bool)>, objects: &[(Entity, SnowCatcher, Vec3, Quat)]) {
    let unchanged = laid_out.len() == objects.len()
        && laid_out.iter().zip(objects).all(|((e, shape, dilate), (f, o, ..))| e == f && *shape == o.shape && *dilate == o.dilate);
    if !unchanged {
        let list: Vec<snowpack::SnowObject> = objects
            .iter()
            .map(|(e, o, position, rotation)| snowpack::SnowObject {
                name: format!("{e}"),
                shape: o.shape.clone(),
                position: *position,
                rotation: *rotation,
                dilate: o.dilate,
            })
            .collect();
        if let Err(e) = snow.set_objects(ctx, &list) {
            tracing::error!("bevy_snowpack: the snow objects cannot be laid out: {e}");
        }
        *laid_out = objects.iter().map(|(e, o, ..)| (*e, o.shape.clone(), o.dilate)).collect();
    }
    for (k, (_, _, position, rotation)) in objects.iter().enumerate() {
        snow.set_object_pose(k, *position, *rotation);
    }
}

fn encode_snow(mut render_context: RenderContext, state: Option<ResMut<SnowRenderState>>, mut frame: ResMut<ExtractedSnowFrame>, to_main: Res<ToMainWorld>) {
    let Some(mut state) = state else { return };
    let SnowRenderState { ctx, snow, window, in_flight, meshes, objects, coats, registrations, cover, .. } = &mut *state;
    let snow = snow.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner);
    place_objects(ctx, snow, objects, &frame.objects);
    let posed = pose_meshes(ctx, snow, meshes, registrations, &frame.meshes);
    let posed_keys: Vec<(u64, SkinnedId)> = posed.iter().map(|&(id, k)| (frame.meshes.poses[k].key, id)).collect();
    for (&(key, id), &(_, k)) in posed_keys.iter().zip(&posed) {
        coats.apply(snow, key, id, frame.meshes.poses[k].coat);
    }
    if let Some(center) = frame.center {
        snow.set_center(dvec2(center));
    }
    let requests = std::mem::take(&mut frame.requests);
    // One gather for every caller this frame; the answer is split back by range.
    let mut points = Vec::new();
    let mut ranges = Vec::with_capacity(requests.len());
    for (ticket, p) in requests {
        ranges.push((ticket, points.len()..points.len() + p.len()));
        points.extend(p);
    }
    let encoder = render_context.command_encoder();
    let poses: Vec<SkinnedPose<'_>> =
        posed.iter().map(|&(mesh, k)| SkinnedPose { mesh, joints: &frame.meshes.poses[k].joints, model: Mat4::IDENTITY }).collect();
    let snow_frame = SnowFrame::new(frame.dt_s, &frame.deformers).with_ids(&frame.ids).with_poses(&poses);
    let snow_frame = if ranges.is_empty() { snow_frame } else { snow_frame.with_queries(&points) };
    if let Some(ticket) = snow.encode(ctx, encoder, &snow_frame) {
        in_flight.push((ticket, ranges));
    }
    coats.record(ctx, encoder, snow, &posed_keys, &to_main);
    cover.record(encoder, snow);
    // Written before this frame's submit, so the cameras' draws see the window as encoded.
    ctx.queue.write_buffer(window, 0, bytemuck::bytes_of(&SnowWindowUniform::new(snow)));
}

/// After the frame's submit: the answers the encode took back sent to the
/// main world, and requests that need the frame submitted.
fn after_frame(state: Option<ResMut<SnowRenderState>>, mut frame: ResMut<ExtractedSnowFrame>, to_main: Res<ToMainWorld>) {
    let Some(mut state) = state else { return };
    let SnowRenderState { ctx, snow, in_flight, objects, .. } = &mut *state;
    let snow = snow.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner);
    // Blocking requests, after the frame's submit so they see it.
    if std::mem::take(&mut frame.save_requested) {
        to_main.send(FromRender::Saved(snow.save(ctx).map(|()| snow.frame()).map_err(|e| e.to_string())));
    }
    if std::mem::take(&mut frame.stats_requested) {
        match snow.read_object_stats(ctx) {
            Ok(stats) => to_main.send(FromRender::ObjectStats(objects.iter().map(|(e, ..)| *e).zip(stats).collect())),
            Err(e) => tracing::error!("bevy_snowpack: reading the objects' snow: {e}"),
        }
    }
    let Some(answers) = snow.point_answers() else { return };
    if let Some(k) = in_flight.iter().position(|(t, _)| *t == answers.ticket) {
        let (_, ranges) = in_flight.remove(k);
        to_main.send(FromRender::Answers(split_answers(answers, &ranges)));
    }
    // Requests the library skipped (all staging buffers busy) never answer.
    in_flight.retain(|(t, _)| t.0 > answers.ticket.0);
}
