//! `SnowReplicationPlugin` on a server app of `MinimalPlugins` (no
//! renderer, no window, no GPU), its replicon server state set by hand
//! instead of by a transport: relay settings changed at run time reach the
//! relay, and the depth under an owned entity comes from the relay once a
//! client has told it the world.

use bevy::prelude::*;
use bevy::state::app::StatesPlugin;
use bevy_replicon::prelude::*;
use bevy_snowpack::prelude::*;
use bevy_snowpack::snowpack::{SnowPeer, WorldIdentity};

fn server_app() -> App {
    let mut app = App::new();
    app.add_plugins((MinimalPlugins, StatesPlugin, RepliconPlugins, SnowReplicationPlugin::default()));
    app.finish();
    app.cleanup();
    // What a transport does once it listens.
    app.world_mut().resource_mut::<NextState<ServerState>>().set(ServerState::Running);
    app.update();
    app
}

fn world(depth_m: f32) -> WorldIdentity {
    WorldIdentity {
        texel_m: 0.0625,
        tile_side: 32,
        terrain: "flat 0".into(),
        depth_m,
        refill_m_per_s: 0.0,
        snowfall_m_per_s: 0.0,
        max_fallen_m: 0.0,
        has_snowfall: false,
        stamp_range_m: [-1.0, 3.0],
    }
}

#[test]
fn relay_settings_take_effect_when_changed() {
    let mut app = server_app();
    let radius = |app: &App| app.world().resource::<SnowServer>().relay().config().accept_radius_m;
    assert_eq!(radius(&app), RelayConfig::default().accept_radius_m);
    app.world_mut().resource_mut::<SnowReplicationSettings>().relay.accept_radius_m = 2.5;
    app.update();
    assert_eq!(radius(&app), 2.5, "the changed relay settings did not reach the relay");
}

#[test]
fn the_depth_under_an_owned_entity_comes_from_the_relay() {
    let mut app = server_app();
    let client = app.world_mut().spawn_empty().id();
    let player = app.world_mut().spawn((SnowOwnedBy(client), Transform::from_xyz(1.0, 0.0, -2.0))).id();
    app.update();
    let under = |app: &App| app.world().get::<SnowDepthUnder>(player).copied().expect("SnowOwnedBy requires SnowDepthUnder");
    assert_eq!(under(&app).depth_m, None, "no client has told the relay its world yet");

    // A peer's hello teaches the relay the world (0.35 m of snow).
    let mut peer = SnowPeer::new(world(0.35), "test", PeerConfig::default());
    let hello = peer.poll_transmit().expect("a new peer says hello");
    let mut server = app.world_mut().resource_mut::<SnowServer>();
    let now = server.world_s();
    let relay = server.relay_mut();
    relay.connect(client.to_bits());
    relay.receive(client.to_bits(), &hello, now);
    assert!(relay.world().is_some(), "the relay refused the hello: {:?}", relay.stats().rejected);
    app.update();
    assert_eq!(under(&app).depth_m, Some(0.35), "untouched snow under the player");
}
