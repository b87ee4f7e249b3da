//! The render world's side: the deformation on Bevy's device, each frame's
//! deformers extracted from the main world, the frame recorded into the
//! render graph before `camera_driver`, readbacks started after the submit.

use std::sync::{Mutex, MutexGuard};

use bevy::core_pipeline::schedule::camera_driver;
use bevy::prelude::*;
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderGraphSystems, RenderQueue};
use bevy::render::{Extract, ExtractSchedule, RenderStartup};
use snowpack::render::sampling::SnowWindowUniform;
use snowpack::{Deformer, GpuContext, SnowDeformation, SnowFrame};

use crate::query::{SnowQuery, SnowTicket};
use crate::{SnowDeformer, SnowWindowTarget, SnowpackSettings, dvec2};

/// The plugin's deformation in the render world, on Bevy's device and queue.
/// Tests and tools read it back (`deformation().read_snow(context())`).
#[derive(Resource)]
pub struct SnowRenderState {
    ctx: GpuContext,
    /// Behind a mutex because resources are `Sync` and the deformation is only `Send`
    /// (its tile streamer's channel); the systems reach it through `get_mut`, without locking.
    snow: Mutex<SnowDeformation>,
    /// The `SnowWindow` uniform of the sampling WGSL, rewritten each frame.
    pub(crate) window: wgpu::Buffer,
    /// Library tickets of the combined requests in flight, with the callers' tickets and ranges.
    in_flight: Vec<(snowpack::QueryTicket, Split)>,
}

impl SnowRenderState {
    /// The deformation (locked while the guard lives; the render systems never wait on it
    /// except while a tool in the render world holds it).
    pub fn deformation(&self) -> MutexGuard<'_, SnowDeformation> {
        self.snow.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// The deformation, to change settings at run time (refill, technique, blur).
    pub fn deformation_mut(&mut self) -> &mut SnowDeformation {
        self.snow.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// snowpack's context over Bevy's device and queue.
    #[must_use]
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }
}

/// How one combined request splits back into the callers' requests: their tickets and ranges.
type Split = Vec<(SnowTicket, std::ops::Range<usize>)>;

/// What presses the snow this frame, extracted from the main world.
#[derive(Resource, Default)]
pub(crate) struct ExtractedSnowFrame {
    dt_s: f32,
    deformers: Vec<Deformer>,
    center: Option<Vec2>,
    requests: Vec<(SnowTicket, Vec<Vec2>)>,
}

/// The settings, in the render world.
#[derive(Resource)]
struct RenderSettings(SnowpackSettings);

pub(crate) fn build(render_app: &mut SubApp, settings: SnowpackSettings, query: SnowQuery) {
    render_app
        .insert_resource(RenderSettings(settings))
        .insert_resource(query)
        .init_resource::<ExtractedSnowFrame>()
        .add_systems(RenderStartup, create_deformation)
        .add_systems(ExtractSchedule, extract_snow_frame)
        .add_systems(RenderGraph, (encode_snow.before(camera_driver), after_submit.in_set(RenderGraphSystems::Finish)));
}

fn create_deformation(mut commands: Commands, settings: Res<RenderSettings>, device: Res<RenderDevice>, queue: Res<RenderQueue>) {
    let ctx = GpuContext::from_device(device.wgpu_device().clone(), (**queue).clone());
    let s = &settings.0;
    match SnowDeformation::new(&ctx, s.params.clone(), s.terrain.clone(), dvec2(s.center)) {
        Ok(snow) => {
            let window = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("bevy_snowpack window"),
                size: std::mem::size_of::<SnowWindowUniform>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            ctx.queue.write_buffer(&window, 0, bytemuck::bytes_of(&SnowWindowUniform::new(&snow)));
            commands.insert_resource(crate::ground::SnowGpuBuffers::new(&snow, &window));
            commands.insert_resource(SnowRenderState { ctx, snow: Mutex::new(snow), window, in_flight: Vec::new() });
        }
        Err(e) => tracing::error!("bevy_snowpack: cannot create the snow: {e}"),
    }
}

fn extract_snow_frame(
    mut frame: ResMut<ExtractedSnowFrame>,
    settings: Res<RenderSettings>,
    query: Res<SnowQuery>,
    time: Extract<Res<Time>>,
    deformers: Extract<Query<(&SnowDeformer, &GlobalTransform)>>,
    target: Extract<Query<&GlobalTransform, With<SnowWindowTarget>>>,
) {
    frame.dt_s = settings.0.fixed_dt_s.unwrap_or_else(|| time.delta_secs());
    frame.deformers.clear();
    frame.deformers.extend(deformers.iter().map(|(d, t)| d.placed(t)));
    frame.center = target.iter().next().map(|t| t.translation().xz());
    frame.requests = query.take_requests();
}

fn encode_snow(mut render_context: RenderContext, state: Option<ResMut<SnowRenderState>>, mut frame: ResMut<ExtractedSnowFrame>) {
    let Some(mut state) = state else { return };
    let SnowRenderState { ctx, snow, window, in_flight } = &mut *state;
    let snow = snow.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some(center) = frame.center {
        snow.set_center(dvec2(center));
    }
    let requests = std::mem::take(&mut frame.requests);
    if !requests.is_empty() {
        // One gather for every caller this frame; the answer is split back by range.
        let mut points = Vec::new();
        let mut ranges = Vec::with_capacity(requests.len());
        for (ticket, p) in requests {
            ranges.push((ticket, points.len()..points.len() + p.len()));
            points.extend(p);
        }
        let ticket = snow.query_points(&points);
        in_flight.push((ticket, ranges));
    }
    let encoder = render_context.command_encoder();
    snow.encode(ctx, encoder, &SnowFrame::new(frame.dt_s, &frame.deformers));
    // Written before this frame's submit, so the cameras' draws see the window as encoded.
    ctx.queue.write_buffer(window, 0, bytemuck::bytes_of(&SnowWindowUniform::new(snow)));
}

fn after_submit(state: Option<ResMut<SnowRenderState>>, query: Res<SnowQuery>) {
    let Some(mut state) = state else { return };
    let SnowRenderState { ctx, snow, in_flight, .. } = &mut *state;
    let snow = snow.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner);
    snow.after_submit(ctx);
    let Some(answers) = snow.point_answers() else { return };
    if let Some(k) = in_flight.iter().position(|(t, _)| *t == answers.ticket) {
        let (_, ranges) = in_flight.remove(k);
        query.deliver(answers, &ranges);
    }
    // Requests the library skipped (all staging buffers busy) never answer.
    in_flight.retain(|(t, _)| t.0 > answers.ticket.0);
}
