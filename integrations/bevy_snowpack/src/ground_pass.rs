//! snowpack's own ground ([`snowpack::SnowGround`]: one displaced grid over
//! the window, its own snow shading) drawn into a Bevy camera's main pass,
//! after the opaque phase, with the camera's colour and depth targets. The
//! alternative to [`crate::SnowGroundMaterial`] that needs no mesh: put
//! [`SnowGroundPass`] on a `Camera3d`.

use bevy::core_pipeline::core_3d::{CORE_3D_DEPTH_FORMAT, main_opaque_pass_3d, main_transparent_pass_3d};
use bevy::core_pipeline::schedule::Core3d;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use bevy::render::render_resource::StoreOp;
use bevy::render::renderer::{RenderContext, RenderDevice, ViewQuery};
use bevy::render::view::{ExtractedView, Msaa, ViewDepthStencilTexture, ViewTarget};
use bevy::render::{RenderApp, sync_world::MainEntity};
use snowpack::{GroundCamera, SnowGround, SnowGroundDescriptor};

use crate::render_state::SnowRenderState;

/// Draw snowpack's own snow ground in this camera's main pass.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, ExtractComponent)]
#[reflect(Component, Clone, Debug, Default)]
#[extract_app(RenderApp)]
pub struct SnowGroundPass;

/// One ground per camera (each has its own camera uniform), with the target
/// format, sample count and snow world (`SnowRenderState::generation`) it was made for.
#[derive(Resource, Default)]
struct Grounds(HashMap<MainEntity, (wgpu::TextureFormat, u32, u64, SnowGround)>);

pub(crate) fn build(app: &mut App) {
    app.add_plugins(ExtractComponentPlugin::<SnowGroundPass>::default()).register_type::<SnowGroundPass>();
    if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
        render_app.init_resource::<Grounds>().add_systems(Core3d, draw_snow_ground.after(main_opaque_pass_3d).before(main_transparent_pass_3d));
    }
}

/// What the pass reads of a camera's view.
type GroundView = (&'static MainEntity, &'static ExtractedView, &'static ViewTarget, &'static ViewDepthStencilTexture, Option<&'static Msaa>);

fn draw_snow_ground(
    view: ViewQuery<GroundView, With<SnowGroundPass>>,
    state: Option<Res<SnowRenderState>>,
    device: Res<RenderDevice>,
    mut grounds: ResMut<Grounds>,
    mut ctx: RenderContext,
) {
    let Some(state) = state else { return };
    let (main, extracted, target, depth, msaa) = view.into_inner();
    let snow = state.deformation();
    let format = target.main_texture_format();
    let samples = msaa.map_or(1, Msaa::samples);
    let made_for = (format, samples, state.generation);
    let entry = grounds.0.entry(*main).or_insert_with(|| (format, samples, made_for.2, new_ground(&device, &snow, format, samples)));
    // A new snow world has new buffers: its ground is made again.
    if (entry.0, entry.1, entry.2) != made_for {
        *entry = (format, samples, made_for.2, new_ground(&device, &snow, format, samples));
    }
    let ground = &mut entry.3;
    let world_from_view = extracted.world_from_view.to_matrix();
    let clip_from_world = extracted.clip_from_world.unwrap_or_else(|| extracted.clip_from_view * world_from_view.inverse());
    let camera = GroundCamera::new(clip_from_world, extracted.world_from_view.translation());
    let color = [Some(target.get_color_attachment())];
    let mut pass = ctx.command_encoder().begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("snow ground"),
        color_attachments: &color,
        depth_stencil_attachment: Some(depth.get_attachment(StoreOp::Store)),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    ground.draw(&mut pass, &state.context().queue, &snow, &camera);
}

fn new_ground(device: &RenderDevice, snow: &snowpack::SnowDeformation, format: wgpu::TextureFormat, samples: u32) -> SnowGround {
    // Bevy's 3D depth is reverse-Z.
    let mut desc = SnowGroundDescriptor::new(format).with_depth(CORE_3D_DEPTH_FORMAT, wgpu::CompareFunction::GreaterEqual);
    desc.sample_count = samples;
    SnowGround::new(device.wgpu_device(), snow, &desc)
}
