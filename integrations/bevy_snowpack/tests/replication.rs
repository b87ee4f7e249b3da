//! `SnowReplicationPlugin` on a server app of `MinimalPlugins` (no
//! renderer, no window, no GPU), its replicon server state set by hand
//! instead of by a transport, clients' messages written as replicon would
//! and the relay's answers caught on their way out: the world is the
//! server's (a client of another is refused, the first one too), relay
//! settings changed at run time reach the relay, the depth under an owned
//! entity comes from the relay, and a relay with a store keeps its trails
//! across a restart.

use bevy::prelude::*;
use bevy::state::app::StatesPlugin;
use bevy_replicon::prelude::*;
use bevy_snowpack::prelude::*;
use bevy_snowpack::snowpack::low_level::persist::TileKey;
use bevy_snowpack::snowpack::low_level::replicate::{Message, SharedTile, decode, encode};
use bevy_snowpack::snowpack::low_level::{WorldIdentityExt, WorldSettings};
use bevy_snowpack::snowpack::{ShareErrorKind, SnowPeer, WorldIdentity};

/// What the relay sent, caught before replicon's transport would take it.
#[derive(Resource, Default)]
struct Sent(Vec<(ClientId, Vec<u8>)>);

fn catch(mut sent: ResMut<Sent>, mut out: MessageReader<ToClients<SnowToClient>>) {
    for m in out.read() {
        if let SendTargets::Single(client) = m.targets {
            sent.0.push((client, m.message.0.clone()));
        }
    }
}

fn server_app(settings: SnowReplicationSettings) -> App {
    let mut app = App::new();
    app.add_plugins((MinimalPlugins, StatesPlugin, RepliconPlugins, SnowReplicationPlugin::new(settings)))
        .init_resource::<Sent>()
        .add_systems(PreUpdate, catch.after(SnowReplicationSystems::Relay));
    app.finish();
    app.cleanup();
    // What a transport does once it listens.
    app.world_mut().resource_mut::<NextState<ServerState>>().set(ServerState::Running);
    app.update();
    app.update();
    app
}

fn world(depth_m: f32) -> WorldIdentity {
    WorldIdentity::from_settings(WorldSettings {
        texel_m: 0.0625,
        tile_side: 32,
        terrain: "flat at 0 m".into(),
        depth_m,
        refill_m_per_s: 0.0,
        snowfall_m_per_s: 0.0,
        max_fallen_m: 0.0,
        has_snowfall: false,
        stamp_range_m: [-1.0, 3.0],
    })
}

fn serving(depth_m: f32) -> SnowReplicationSettings {
    SnowReplicationSettings { world: Some(world(depth_m)), ..SnowReplicationSettings::default() }
}

/// A client entity the relay knows (what the plugin does when replicon authorizes one).
fn client(app: &mut App) -> Entity {
    let client = app.world_mut().spawn_empty().id();
    app.world_mut().resource_mut::<SnowServer>().relay_mut().connect(client.to_bits());
    client
}

/// `bytes` from `client` this frame, as replicon's receive writes them; returns what the relay answered it.
fn exchange(app: &mut App, client: Entity, bytes: Vec<Vec<u8>>) -> Vec<Vec<u8>> {
    for b in bytes {
        app.world_mut().write_message(FromClient { client_id: ClientId::Client(client), message: SnowToServer(b) });
    }
    app.update();
    let sent = std::mem::take(&mut app.world_mut().resource_mut::<Sent>().0);
    sent.into_iter().filter(|(to, _)| *to == ClientId::Client(client)).map(|(_, b)| b).collect()
}

#[test]
fn relay_settings_take_effect_when_changed() {
    let mut app = server_app(serving(0.5));
    let radius = |app: &App| app.world().resource::<SnowServer>().relay().config().accept_radius_m;
    assert_eq!(radius(&app), RelayConfig::default().accept_radius_m);
    app.world_mut().resource_mut::<SnowReplicationSettings>().relay.accept_radius_m = 2.5;
    app.update();
    assert_eq!(radius(&app), 2.5, "the changed relay settings did not reach the relay");
}

#[test]
fn a_server_without_a_world_serves_nobody() {
    let mut app = server_app(SnowReplicationSettings::default());
    app.update();
    assert!(app.world().get_resource::<SnowServer>().is_none(), "a dedicated server started a relay with no world of its own");
}

#[test]
fn the_world_is_the_servers_and_a_client_of_another_is_refused_even_first() {
    let mut app = server_app(serving(0.5));
    // The first client to speak brings 0.35 m of snow: it does not get to choose.
    let stranger = client(&mut app);
    let mut peer = SnowPeer::new(world(0.35), "stranger", PeerConfig::default());
    let hello = peer.poll_transmit().expect("a new peer says hello");
    let answers = exchange(&mut app, stranger, vec![hello]);
    assert_eq!(answers.len(), 1, "one answer to the hello");
    let err = peer.receive(&answers[0]).expect_err("the stranger was welcomed");
    assert_eq!(err.kind(), ShareErrorKind::Refused);
    assert!(err.to_string().contains("snow depth (m): 0.35 here, 0.5 there"), "{err}");
    let server = app.world().resource::<SnowServer>();
    assert_eq!(server.world(), Some(world(0.5)), "the first hello changed the server's world");
    assert_eq!(server.relay().stats().rejected.refused, 1);

    // A client of the server's world is welcomed.
    let player = client(&mut app);
    let mut peer = SnowPeer::new(world(0.5), "player", PeerConfig::default());
    let hello = peer.poll_transmit().expect("hello");
    let answers = exchange(&mut app, player, vec![hello]);
    assert!(matches!(answers.first().map(|b| decode(b)), Some(Ok(Message::Welcome { .. }))), "no welcome");
}

#[test]
fn the_depth_under_an_owned_entity_comes_from_the_relay() {
    let mut app = server_app(serving(0.35));
    let owner = client(&mut app);
    let player = app.world_mut().spawn((SnowOwnedBy(ClientId::Client(owner)), Transform::from_xyz(1.0, 0.0, -2.0))).id();
    app.update();
    let under = |app: &App| app.world().get::<SnowDepthUnder>(player).copied().expect("SnowOwnedBy requires SnowDepthUnder");
    // The server's own world answers before any client has spoken.
    assert_eq!(under(&app).depth_m, Some(0.35), "untouched snow under the player");
}

/// A peer of `world(0.5)` welcomed, then one tile 0.3 m deep at the origin sent (its deformer there).
fn press_at_origin(app: &mut App, owner: Entity) {
    let mut peer = SnowPeer::new(world(0.5), "player", PeerConfig::default());
    let hello = peer.poll_transmit().expect("hello");
    let welcome = exchange(app, owner, vec![hello]);
    assert!(matches!(welcome.first().map(|b| decode(b)), Some(Ok(Message::Welcome { .. }))), "no welcome");
    let now = app.world().resource::<SnowServer>().world_s();
    let mut tile = SharedTile::untouched(TileKey::new(0, 0), 32, world(0.5).clock_at(now), false, false);
    // 0.3 m below the rest height, in 0.1 mm quanta, over the whole tile (2 m from the origin).
    tile.deficit.iter_mut().for_each(|d| *d = 3000);
    let answers = exchange(app, owner, vec![encode(&Message::Tiles { seq: 0, tiles: vec![tile] })]);
    assert!(answers.iter().any(|b| matches!(decode(b), Ok(Message::Ack { seq: 0 }))), "the tile was not acknowledged");
    let server = app.world().resource::<SnowServer>();
    let stats = server.relay().stats();
    assert_eq!((stats.tiles_merged, stats.rejected.total()), (1, 0), "{stats:?}");
}

#[test]
fn a_relay_with_a_store_keeps_its_trails_across_a_restart() {
    let dir = std::env::temp_dir().join(format!("bevy_snowpack_relay_store_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let settings = SnowReplicationSettings { store: Some(SnowRelayStore::new(&dir)), ..serving(0.5) };
    {
        let mut app = server_app(settings.clone());
        let owner = client(&mut app);
        app.world_mut().spawn((SnowOwnedBy(ClientId::Client(owner)), Transform::from_xyz(1.0, 0.0, 1.0)));
        app.update();
        press_at_origin(&mut app, owner);
        let depth = app.world().resource::<SnowServer>().depth_at(1.0, 1.0).expect("a world");
        assert!((depth - 0.2).abs() < 1e-3, "the relay holds {depth} m there");
        // Acknowledged means written: the app goes without stopping its server (no flush on the
        // way out, as a killed server), and takes the store's lock with it.
        drop(app);
    }
    let app = server_app(settings);
    let server = app.world().resource::<SnowServer>();
    let depth = server.depth_at(1.0, 1.0).expect("a world");
    assert!((depth - 0.2).abs() < 1e-3, "after the restart the relay reads {depth} m in the trail, not 0.2 m");
    assert_eq!(server.depth_at(5.0, 5.0), Some(0.5), "open snow beyond the tile");
    // Another world over the same store is refused at start, naming the difference.
    let other = SnowReplicationSettings { store: Some(SnowRelayStore::new(&dir)), ..serving(0.4) };
    drop(app);
    let err = SnowServer::open(world(0.4), &other).err().expect("another world over the store was served");
    assert!(err.to_string().contains("snow depth (m): 0.5 here, 0.4 there"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
