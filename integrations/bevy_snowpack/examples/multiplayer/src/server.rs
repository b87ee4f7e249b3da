//! The game's server side, a dedicated server and a listen server alike:
//! players spawned, moved from their requests, reported to the relay. No
//! renderer: it builds with bevy_snowpack's `server` feature alone.

use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use bevy::app::ScheduleRunnerPlugin;
use bevy::prelude::*;
use bevy::state::app::StatesPlugin;
use bevy_replicon::prelude::*;
use bevy_replicon::shared::backend::connected_client::NetworkId;
use bevy_replicon_renet2::netcode::{NativeSocket, NetcodeServerTransport, ServerAuthentication, ServerSetupConfig};
use bevy_replicon_renet2::renet2::{ConnectionConfig, RenetServer};
use bevy_replicon_renet2::{RenetChannelsExt, RepliconRenetPlugins};
use bevy_snowpack::prelude::*;

use crate::cli::{ServerCli, bad, fail};
#[cfg(feature = "client")]
use crate::protocol::HOST_ID;
use crate::protocol::{FOX_SOLE_M, GameProtocol, MAX_SPEED_M_PER_S, MoveRequest, PROTOCOL_ID, Player, WALK_FROM_M, unix_now, world};

/// Each player spawns this far (m, along -z) behind the one before.
const SPAWN_SPACING_M: f32 = 2.5;
/// The longest move one request asks for (m); a new request replaces what is left of the last.
const MAX_REQUEST_M: f32 = 1.0;
/// A player moved within this long (s) is walking (its fox's walk clip plays).
const MOVING_FOR_S: f32 = 0.5;

/// The game's server side (a dedicated server and a listen server alike):
/// players spawned, moved from their requests, reported.
pub struct ServerGame;

impl Plugin for ServerGame {
    fn build(&self, app: &mut App) {
        app.insert_resource(ServerRun { started: Instant::now(), had_clients: false, empty_since: None, last_report: Instant::now() })
            .add_observer(spawn_player)
            .add_observer(despawn_player)
            .add_systems(Update, (take_requests, move_players, report_server).chain().run_if(in_state(ServerState::Running)));
    }
}

#[derive(Resource)]
struct ServerRun {
    started: Instant,
    had_clients: bool,
    empty_since: Option<Instant>,
    last_report: Instant,
}

/// On the server: what is left of the player's last move request.
#[derive(Component, Default)]
struct Stride {
    direction: Vec2,
    left_m: f32,
    /// When the last request to move came (s of the server's time).
    requested_s: Option<f32>,
}

/// On the server: the player's spawn place (the lowest free one).
#[derive(Component)]
pub struct Slot(u32);

pub fn run_server(cli: ServerCli) {
    let settings = SnowReplicationSettings { world: Some(world()), store: Some(SnowRelayStore::new(&cli.store)), ..default() };
    // Opened here, so a bad store is said and exits 2 before anything listens.
    let snow = SnowServer::open(world(), &settings).unwrap_or_else(|e| bad(&format!("--store {}: {e}", cli.store.display())));
    let exit = App::new()
        .add_plugins((
            MinimalPlugins.set(ScheduleRunnerPlugin::run_loop(Duration::from_secs_f64(1.0 / 60.0))),
            StatesPlugin,
            RepliconPlugins,
            RepliconRenetPlugins,
        ))
        .add_plugins((GameProtocol(settings), ServerGame))
        .insert_resource(snow)
        .insert_resource(cli)
        .add_systems(Startup, listen.map(|r: Result<(), String>| r.unwrap_or_else(|e| fail(&e))))
        .add_systems(Update, stop_server.after(report_server))
        .run();
    std::process::exit(if exit == AppExit::Success { 0 } else { 1 });
}

pub fn listen(mut commands: Commands, channels: Res<RepliconChannels>, cli: Res<ServerCli>) -> Result<(), String> {
    let addr = SocketAddr::from((Ipv4Addr::LOCALHOST, cli.port));
    let socket = UdpSocket::bind(addr).map_err(|e| format!("listening on {addr}: {e}"))?;
    let local = socket.local_addr().map_err(|e| e.to_string())?;
    let setup = ServerSetupConfig {
        current_time: unix_now(),
        max_clients: 16,
        protocol_id: PROTOCOL_ID,
        socket_addresses: vec![vec![local]],
        // Loopback only, so no key: anyone on this machine may join.
        authentication: ServerAuthentication::Unsecure,
        max_token_lifetime: 0,
    };
    let transport = NetcodeServerTransport::new(setup, NativeSocket::new(socket).map_err(|e| format!("{e:?}"))?).map_err(|e| e.to_string())?;
    commands.insert_resource(RenetServer::new(ConnectionConfig::from_channels(channels.server_configs(), channels.client_configs())));
    commands.insert_resource(transport);
    println!("server: listening on {local}, tiles in {}", cli.store.display());
    Ok(())
}

/// Where a player of spawn place `slot` starts, facing +x.
fn spawn_transform(slot: u32) -> Transform {
    Transform::from_xyz(WALK_FROM_M, FOX_SOLE_M, -SPAWN_SPACING_M * slot as f32).with_rotation(Quat::from_rotation_y(std::f32::consts::FRAC_PI_2))
}

/// A replicated player owned by `owner`, at the lowest free spawn place.
fn player_bundle(id: u64, owner: ClientId, slots: &Query<&Slot>) -> impl Bundle {
    let taken: Vec<u32> = slots.iter().map(|s| s.0).collect();
    let slot = (0..).find(|s| !taken.contains(s)).unwrap_or(0);
    (Player { id, moving: false }, Replicated, SnowOwnedBy(owner), Stride::default(), Slot(slot), spawn_transform(slot))
}

/// Each authorized client gets a replicated player that it owns: where it may change the snow.
fn spawn_player(add: On<Add<AuthorizedClient>>, mut commands: Commands, mut run: ResMut<ServerRun>, ids: Query<&NetworkId>, slots: Query<&Slot>) {
    run.had_clients = true;
    let id = ids.get(add.entity).map_or(add.entity.to_bits(), NetworkId::get);
    commands.spawn(player_bundle(id, ClientId::Client(add.entity), &slots));
    println!("server: client {id} joined");
}

/// A listen server's own player (a listen server plays: feature `client`).
#[cfg(feature = "client")]
pub fn spawn_host_player(mut commands: Commands, slots: Query<&Slot>) {
    commands.spawn(player_bundle(HOST_ID, ClientId::Server, &slots));
}

fn despawn_player(remove: On<Remove<ConnectedClient>>, mut commands: Commands, players: Query<(Entity, &SnowOwnedBy, &Player)>) {
    for (entity, owner, player) in &players {
        if owner.0 == ClientId::Client(remove.entity) {
            commands.entity(entity).despawn();
            println!("server: client {} left", player.id);
        }
    }
}

/// The clients' requests: a direction and how far, at most [`MAX_REQUEST_M`];
/// anything not a number is ignored.
fn take_requests(time: Res<Time>, mut requests: MessageReader<FromClient<MoveRequest>>, mut players: Query<(&SnowOwnedBy, &mut Stride)>) {
    for m in requests.read() {
        let MoveRequest { direction, distance_m } = m.message;
        let direction = Vec2::from_array(direction);
        if !direction.is_finite() || !distance_m.is_finite() {
            continue;
        }
        for (owner, mut stride) in &mut players {
            if owner.0 == m.client_id {
                stride.direction = direction.normalize_or_zero();
                stride.left_m = if stride.direction == Vec2::ZERO { 0.0 } else { distance_m.clamp(0.0, MAX_REQUEST_M) };
                if stride.left_m > 0.0 {
                    stride.requested_s = Some(time.elapsed_secs());
                }
            }
        }
    }
}

/// The server moves every player (never faster than [`MAX_SPEED_M_PER_S`]):
/// the transform replicated to the clients and reported to the relay.
fn move_players(time: Res<Time>, mut players: Query<(&mut Transform, &mut Stride, &mut Player)>) {
    let now = time.elapsed_secs();
    for (mut transform, mut stride, mut player) in &mut players {
        let step = stride.left_m.min(MAX_SPEED_M_PER_S * time.delta_secs());
        if step > 0.0 {
            let d = stride.direction;
            transform.translation += Vec3::new(d.x, 0.0, d.y) * step;
            // The fox faces +z.
            transform.rotation = Quat::from_rotation_y(d.x.atan2(d.y));
            stride.left_m -= step;
        }
        let moving = stride.requested_s.is_some_and(|at| now - at < MOVING_FOR_S);
        if player.moving != moving {
            player.moving = moving;
        }
    }
}

/// Every second: the snow depth under each player, from the relay.
fn report_server(mut run: ResMut<ServerRun>, snow: Option<Res<SnowServer>>, players: Query<(&Player, &Transform, &SnowDepthUnder)>) {
    if run.last_report.elapsed() < Duration::from_secs(1) {
        return;
    }
    run.last_report = Instant::now();
    for (player, t, under) in &players {
        if let Some(d) = under.depth_m {
            println!("server: player {} at {:.2} {:.2} depth_m {d:.4}", player.id, t.translation.x, t.translation.z);
        }
    }
    let Some(snow) = snow else { return };
    let s = snow.relay().stats();
    if s.rejected.total() > 0 {
        println!("server: refused so far: {:?}", s.rejected);
    }
    println!(
        "server: {} peers, tiles received {} merged {} sent {} persisted {}, bytes in {} out {}, refused {}",
        s.peers,
        s.tiles_received,
        s.tiles_merged,
        s.tiles_sent,
        s.tiles_persisted,
        s.bytes_in,
        s.bytes_out,
        s.rejected.total()
    );
}

/// With `--exit-when-empty`, stops 2 s after the last client left; with
/// `--exit-after-s`, at that time. Otherwise it serves until killed.
fn stop_server(
    mut run: ResMut<ServerRun>,
    cli: Res<ServerCli>,
    clients: Query<(), With<ConnectedClient>>,
    snow: Option<ResMut<SnowServer>>,
    mut exit: MessageWriter<AppExit>,
) {
    let Some(mut snow) = snow else { return };
    let empty = clients.is_empty();
    run.empty_since = match (empty, run.empty_since) {
        (true, None) => Some(Instant::now()),
        (true, since) => since,
        (false, _) => None,
    };
    let done = cli.exit_when_empty && run.had_clients && run.empty_since.is_some_and(|t| t.elapsed() >= Duration::from_secs(2));
    let late = cli.exit_after_s.is_some_and(|s| run.started.elapsed().as_secs_f64() >= s);
    if done || late {
        let flushed = snow.relay_mut().flush();
        let s = snow.relay().stats();
        println!(
            "server: stopped after {:.1} s ({}): tiles received {} merged {} persisted {}, bytes in {} out {}, refused {}",
            run.started.elapsed().as_secs_f64(),
            if done { "no clients left" } else { "time limit" },
            s.tiles_received,
            s.tiles_merged,
            s.tiles_persisted,
            s.bytes_in,
            s.bytes_out,
            s.rejected.total()
        );
        if let Err(e) = flushed {
            eprintln!("multiplayer: the store failed at the end: {e}");
            exit.write(AppExit::error());
        } else {
            exit.write(AppExit::Success);
        }
    }
}
