//! A listen server in one headless app (Bevy's render plugins without a
//! window, updated by hand): the plugin's snow and the relay together,
//! replicon's server state set by hand. The app's own snow joins its own
//! relay through replicon's local messages, the relay serves the snow's
//! world (taken from it, or given and equal to it), and a ball owned by the
//! listen server (`ClientId::Server`) leaves its trail in the relay's tiles.

mod common;

use bevy::app::PluginsState;
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::window::ExitCondition;
use bevy_replicon::prelude::*;
use bevy_snowpack::prelude::*;

/// The test's snow: 0.4 m deep (`common::test_settings`).
const DEPTH_M: f32 = 0.4;
/// Frames the app may take to join its relay and share the trail.
const FRAME_LIMIT: u32 = 600;

fn listen_server(replication: SnowReplicationSettings) -> Option<App> {
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin { primary_window: None, exit_condition: ExitCondition::DontExit, close_when_requested: false, ..default() })
            .disable::<bevy::winit::WinitPlugin>()
            .disable::<bevy::log::LogPlugin>(),
    )
    .add_plugins((SnowpackPlugin::new(common::test_settings()), RepliconPlugins, SnowReplicationPlugin::new(replication)));
    while app.plugins_state() == PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    app.cleanup();
    if app.get_sub_app(RenderApp).is_none() {
        assert!(!common::gpu_required(), "no GPU adapter for Bevy's renderer, and SNOWPACK_REQUIRE_GPU is set");
        return None;
    }
    // What a transport does once it listens; no client connects.
    app.world_mut().resource_mut::<NextState<ServerState>>().set(ServerState::Running);
    Some(app)
}

/// Frames the ball takes from x = -1 m to x = 1 m.
const ROLL: u32 = 120;

/// Where the ball is at `frame`: rolling through the origin, its bottom 5 cm under the ground.
fn ball_at(frame: u32) -> Vec3 {
    Vec3::new(-1.0 + 2.0 * (frame.min(ROLL) as f32 / ROLL as f32), 0.25, 0.0)
}

/// Runs the listen server with a ball of its own rolling through the
/// origin (it presses from its first frame; sharing is on from the frame
/// after) until the relay holds the trail; returns the relay's depth at the
/// origin and off the trail, and the ball's `SnowDepthUnder` at its end.
fn share_a_trail(mut app: App) -> (f32, f32, Option<f32>) {
    let ball = app.world_mut().spawn((SnowDeformer::Sphere { radius: 0.3 }, SnowOwnedBy(ClientId::Server), Transform::from_translation(ball_at(0)))).id();
    for frame in 0..FRAME_LIMIT {
        app.world_mut().get_mut::<Transform>(ball).expect("the ball").translation = ball_at(frame);
        if frame > ROLL {
            // Rolled: everything pressed goes to the relay now.
            app.world_mut().resource_mut::<SnowSharing>().request_sync();
        }
        app.update();
        let sharing = app.world().resource::<SnowSharing>();
        assert!(sharing.refused().is_none(), "the listen server refused its own snow: {:?}", sharing.refused());
        let Some(server) = app.world().get_resource::<SnowServer>() else { continue };
        if let Some(own) = sharing.world() {
            assert_eq!(server.world().as_ref(), Some(own), "the relay serves another world than the app's snow");
        }
        let depth = server.depth_at(0.0, 0.0).expect("the relay has its world");
        if frame > ROLL && sharing.is_settled() && depth < DEPTH_M - 0.1 {
            println!("the trail reached the relay after {frame} frames: {depth} m under the ball");
            let off = server.depth_at(2.5, 2.5).expect("world");
            let under = app.world().get::<SnowDepthUnder>(ball).and_then(|u| u.depth_m);
            return (depth, off, under);
        }
    }
    let sharing = app.world().resource::<SnowSharing>();
    panic!(
        "no trail at the relay within {FRAME_LIMIT} frames: welcomed {}, settled {}, stats {:?}, relay {:?}",
        sharing.is_welcomed(),
        sharing.is_settled(),
        sharing.stats(),
        app.world().get_resource::<SnowServer>().map(|s| s.relay().stats())
    );
}

#[test]
fn a_listen_server_shares_its_own_snow_with_its_own_relay() {
    // No world given: the relay serves the app's own snow's.
    let Some(app) = listen_server(SnowReplicationSettings::default()) else { return };
    let (depth, off, under) = share_a_trail(app);
    // The ball's bottom is 5 cm under the ground: the snow under it is pressed to the ground.
    assert!(depth < 0.05, "the relay reads {depth} m under the ball");
    assert!((off - DEPTH_M).abs() < 1e-4, "the relay reads {off} m off the trail, not open snow");
    // The ball rests at x = 1 m, in its own trench.
    let under = under.expect("the ball's SnowDepthUnder");
    assert!(under < 0.05, "SnowDepthUnder {under} m under the ball at rest");
}

#[test]
fn a_world_computed_on_the_cpu_is_the_snows_own() {
    // The world a dedicated server would be configured with, from the same settings without a GPU:
    // the app's own snow must be welcomed into it.
    let settings = common::test_settings();
    let tile_side = SnowReplicationSettings::default().tile_side;
    let world = bevy_snowpack::snowpack::SnowDeformation::world_identity_for(&settings.params, &settings.terrain, tile_side);
    let Some(app) = listen_server(SnowReplicationSettings { world: Some(world), ..default() }) else { return };
    let (depth, _, _) = share_a_trail(app);
    assert!(depth < 0.05, "the relay reads {depth} m under the ball");
}
