//! Shared snow over a game's own bevy_replicon connection (renet2's netcode
//! over UDP): the server owns the world, moves every player from its inputs
//! and keeps the trails on disk; every client draws every player's fox and
//! sees every trail, a client that joins late, or after the server
//! restarted, too.
//!
//! ```text
//! cargo run --release --example multiplayer -- server --port P [--store DIR]
//!     [--exit-when-empty] [--exit-after-s S]
//! cargo run --release --example multiplayer -- client --connect 127.0.0.1:P [CLIENT OPTIONS]
//! cargo run --release --example multiplayer -- host --port P [--store DIR] [CLIENT OPTIONS]
//! CLIENT OPTIONS: [--walk] [--leave-on-input] [--exit-after-frames N]
//!     [--screenshot FILE] [--probe X,Z]... [--assets DIR]
//! ```
//!
//! - `server`: a dedicated server (no renderer, no GPU). The world (0.5 m of
//!   snow on flat ground, 4.7 cm texels, 32² tiles) is its own
//!   configuration (`SnowDeformation::world_identity_for`, no GPU): a client
//!   of another world is refused. The relay keeps
//!   its tiles in `--store` (default `multiplayer-world/`), so a restarted
//!   server, or a client joining an empty one, still sees every trail. It
//!   spawns a replicated player per client (at x = -4 m, the next one 2.5 m
//!   further back, ...), moves it from the client's move requests at most
//!   1.5 m/s, reports the players' positions to the relay as where each
//!   client may press snow, and prints the depth under each player every
//!   second. It runs until killed, or 2 s after its last client left with
//!   `--exit-when-empty`, or after `--exit-after-s`.
//! - `client`: draws every player's fox where the server's replicated
//!   transform puts it; its own fox presses its snow. Arrow keys or WASD
//!   walk it. With `--walk` it asks the server to walk it from x = -4 m to
//!   x = 4 m along z = 0 through the snow, 0.1 m a frame at most (so a slow
//!   renderer still leaves a whole trail), and prints what it sent
//!   (`wire: ...`). Once its walk is over, it has run N frames and (with
//!   `--leave-on-input`) a line or the end came on its standard input, it
//!   waits until the server acknowledged its changes and it holds
//!   everything the server has over its window, prints `probe X Z depth_m D`
//!   per `--probe` and where each fox is on screen, takes the screenshot and
//!   exits.
//! - `host`: a listen server: both at once in one app (its own snow is a
//!   client of its own relay, its player is replicon's `ClientId::Server`).
//!
//! The fox is found in the repository's `assets` folder wherever the
//! example runs from (`--assets` overrides it).

#[path = "common/assets.rs"]
mod assets;
#[path = "common/gltf.rs"]
mod gltf;

use std::io::BufRead as _;
use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use bevy::animation::graph::{AnimationGraph, AnimationGraphHandle, AnimationNodeIndex};
use bevy::app::ScheduleRunnerPlugin;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::gltf::GltfAssetLabel;
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured, save_to_disk};
use bevy::state::app::StatesPlugin;
use bevy::world_serialization::{WorldAsset, WorldAssetRoot, WorldInstanceReady};
use bevy_replicon::prelude::*;
use bevy_replicon::shared::backend::connected_client::NetworkId;
use bevy_replicon_renet2::netcode::{
    ClientAuthentication, NativeSocket, NetcodeClientTransport, NetcodeServerTransport, ServerAuthentication, ServerSetupConfig,
};
use bevy_replicon_renet2::renet2::{ConnectionConfig, RenetClient, RenetServer};
use bevy_replicon_renet2::{RenetChannelsExt, RepliconRenetPlugins};
use bevy_snowpack::prelude::*;
use bevy_snowpack::snowpack::{SnowDeformation, WorldIdentity};
use serde::{Deserialize, Serialize};

/// Netcode's protocol id: this example's, so nothing else connects by mistake.
const PROTOCOL_ID: u64 = 0x736e_6f77_6d70_0002;
/// Snow depth (m) on flat ground.
const DEPTH_M: f32 = 0.5;
/// The fox's model is in centimetres.
const FOX_SCALE: f32 = 0.01;
/// The fox wades: its soles this high (m) over the ground, its legs and belly ploughing the snow.
const FOX_SOLE_M: f32 = 0.02;
const WALK_FROM_M: f32 = -4.0;
const WALK_TO_M: f32 = 4.0;
/// Each player spawns this far (m, along -z) behind the one before.
const SPAWN_SPACING_M: f32 = 2.5;
/// The fastest the server moves a player (m/s).
const MAX_SPEED_M_PER_S: f32 = 1.5;
/// The longest move one request asks for (m); a new request replaces what is left of the last.
const MAX_REQUEST_M: f32 = 1.0;
/// A scripted walk asks for this much a frame (m), so the trail is whole however slow the frames.
const WALK_STEP_M: f32 = 0.1;
/// A player moved within this long (s) is walking (its fox's walk clip plays).
const MOVING_FOR_S: f32 = 0.5;
/// The listen server's own player id (clients' ids are netcode's, never 0 here).
const HOST_ID: u64 = 0;
/// How long a client waits for the server's welcome and its player, and then to be in sync at its end.
const JOIN_LIMIT: Duration = Duration::from_secs(120);
const SETTLE_LIMIT: Duration = Duration::from_secs(120);
/// Frames in a row a client must be settled before it reads the snow.
const SETTLED_FRAMES: u32 = 5;
/// How high (m) over a player's feet its fox's back is, for where the screen shows it.
const FOX_BACK_M: f32 = 0.5;

fn main() {
    match Cli::parse() {
        Cli::Server(server) => run_server(server),
        Cli::Client(client) => run_client(client, None),
        Cli::Host(server, client) => run_client(client, Some(server)),
    }
}

// ---------------------------------------------------------------- command line

enum Cli {
    Server(ServerCli),
    Client(ClientCli),
    Host(ServerCli, ClientCli),
}

#[derive(Resource, Clone, Debug)]
struct ServerCli {
    port: u16,
    store: PathBuf,
    exit_when_empty: bool,
    exit_after_s: Option<f64>,
}

#[derive(Resource, Clone, Debug)]
struct ClientCli {
    /// The server's address; `None` for a listen server.
    connect: Option<SocketAddr>,
    walk: bool,
    leave_on_input: bool,
    exit_after_frames: u32,
    screenshot: Option<PathBuf>,
    probes: Vec<Vec2>,
    assets: Option<PathBuf>,
}

impl Cli {
    /// Parses the process's arguments; exits with status 2 on a bad one.
    fn parse() -> Self {
        let args: Vec<String> = std::env::args().skip(1).collect();
        let Some((mode, rest)) = args.split_first() else { bad("no mode") };
        let (serves, plays) = match mode.as_str() {
            "server" => (true, false),
            "client" => (false, true),
            "host" => (true, true),
            other => bad(&format!("unknown mode {other}")),
        };
        let mut port = None;
        let mut server = ServerCli { port: 0, store: PathBuf::from("multiplayer-world"), exit_when_empty: false, exit_after_s: None };
        let mut client =
            ClientCli { connect: None, walk: false, leave_on_input: false, exit_after_frames: 0, screenshot: None, probes: Vec::new(), assets: None };
        let mut it = rest.iter();
        while let Some(arg) = it.next() {
            let mut value = |name: &str| it.next().cloned().unwrap_or_else(|| bad(&format!("{name} needs a value")));
            match (serves, plays, arg.as_str()) {
                (true, _, "--port") => port = Some(value("--port").parse().unwrap_or_else(|e| bad(&format!("--port: {e}")))),
                (true, _, "--store") => server.store = value("--store").into(),
                (true, false, "--exit-when-empty") => server.exit_when_empty = true,
                (true, false, "--exit-after-s") => {
                    let v = value("--exit-after-s");
                    server.exit_after_s =
                        Some(v.parse().ok().filter(|s: &f64| s.is_finite() && *s >= 0.0).unwrap_or_else(|| bad(&format!("--exit-after-s {v}: give seconds"))));
                }
                (false, true, "--connect") => client.connect = Some(value("--connect").parse().unwrap_or_else(|e| bad(&format!("--connect: {e}")))),
                (_, true, "--walk") => client.walk = true,
                (_, true, "--leave-on-input") => client.leave_on_input = true,
                (_, true, "--exit-after-frames") => {
                    client.exit_after_frames = value("--exit-after-frames").parse().unwrap_or_else(|e| bad(&format!("--exit-after-frames: {e}")));
                }
                (_, true, "--screenshot") => client.screenshot = Some(value("--screenshot").into()),
                (_, true, "--assets") => client.assets = Some(value("--assets").into()),
                (_, true, "--probe") => {
                    let v = value("--probe");
                    let xz: Vec<f32> = v.split(',').map(|s| s.trim().parse().unwrap_or_else(|e| bad(&format!("--probe {v}: {e}")))).collect();
                    let [x, z] = xz[..] else { bad(&format!("--probe {v}: give X,Z")) };
                    client.probes.push(Vec2::new(x, z));
                }
                _ => bad(&format!("unknown or misplaced argument {arg}")),
            }
        }
        if serves {
            server.port = port.unwrap_or_else(|| bad(&format!("{mode} needs --port")));
        }
        match mode.as_str() {
            "server" => Self::Server(server),
            "host" => Self::Host(server, client),
            _ => {
                if client.connect.is_none() {
                    bad("client needs --connect");
                }
                Self::Client(client)
            }
        }
    }
}

fn bad(why: &str) -> ! {
    eprintln!(
        "{why}\nusage: multiplayer server --port P [--store DIR] [--exit-when-empty] [--exit-after-s S]\n       multiplayer client --connect ADDR [CLIENT OPTIONS]\n       multiplayer host --port P [--store DIR] [CLIENT OPTIONS]\nCLIENT OPTIONS: [--walk] [--leave-on-input] [--exit-after-frames N] [--screenshot FILE] [--probe X,Z]... [--assets DIR]"
    );
    std::process::exit(2)
}

fn fail(why: &str) -> ! {
    eprintln!("multiplayer: {why}");
    std::process::exit(1)
}

// ---------------------------------------------------------------- the game's protocol

/// A player, replicated to every client: whose it is (netcode's client id,
/// [`HOST_ID`] for a listen server's own) and whether it is walking. Where
/// it is comes with its replicated `Transform`.
#[derive(Component, Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
struct Player {
    id: u64,
    moving: bool,
}

/// A `Transform` on the wire (position and heading; players are not scaled).
#[derive(Serialize, Deserialize, Clone, Copy, Debug)]
struct NetTransform {
    translation: [f32; 3],
    rotation: [f32; 4],
}

impl From<Transform> for NetTransform {
    fn from(t: Transform) -> Self {
        Self { translation: t.translation.to_array(), rotation: t.rotation.to_array() }
    }
}

impl From<NetTransform> for Transform {
    fn from(t: NetTransform) -> Self {
        Self::from_translation(Vec3::from_array(t.translation)).with_rotation(Quat::from_array(t.rotation).normalize())
    }
}

/// A client's input (client → server): walk up to `distance_m` that way
/// (x, z). The server decides where that takes the player (at most
/// [`MAX_SPEED_M_PER_S`]); a client never says where its player is.
#[derive(Message, Serialize, Deserialize, Clone, Copy, Debug)]
struct MoveRequest {
    direction: [f32; 2],
    distance_m: f32,
}

/// What server and clients register, in the same order (replicon checks it).
struct GameProtocol(SnowReplicationSettings);

impl Plugin for GameProtocol {
    fn build(&self, app: &mut App) {
        app.add_plugins(SnowReplicationPlugin::new(self.0.clone()))
            .replicate::<Player>()
            .replicate_as::<Transform, NetTransform>()
            .add_client_message::<MoveRequest>(Channel::Ordered);
    }
}

/// Seconds since the Unix epoch (netcode's clock).
fn unix_now() -> Duration {
    SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default()
}

/// The snow every machine of this game runs: 12 m of 4.7 cm texels around the
/// origin (the whole walk, and a margin of open snow) in 0.5 m of snow.
fn snow_settings() -> SnowpackSettings {
    SnowpackSettings {
        params: SnowParams { extent_m: 12.0, resolution: 256, depth_m: DEPTH_M, refill_m_per_s: 0.0, ..SnowParams::default() },
        terrain: TerrainSource::Flat { height_m: 0.0 },
        center: Vec2::ZERO,
        fixed_dt_s: None,
        store: None,
    }
}

/// The world the server serves: the snow above, shared in the default tiles.
fn world() -> WorldIdentity {
    let snow = snow_settings();
    SnowDeformation::world_identity_for(&snow.params, &snow.terrain, SnowReplicationSettings::default().tile_side)
}

// ---------------------------------------------------------------- server

/// The game's server side (a dedicated server and a listen server alike):
/// players spawned, moved from their requests, reported.
struct ServerGame;

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
struct Slot(u32);

fn run_server(cli: ServerCli) {
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

fn listen(mut commands: Commands, channels: Res<RepliconChannels>, cli: Res<ServerCli>) -> Result<(), String> {
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

/// A listen server's own player.
fn spawn_host_player(mut commands: Commands, slots: Query<&Slot>) {
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

// ---------------------------------------------------------------- client

/// This app's own player id (netcode's client id, or [`HOST_ID`]).
#[derive(Resource, Clone, Copy)]
struct Me(u64);

/// Set once a line (or the end) came on standard input (`--leave-on-input`).
#[derive(Resource, Clone, Default)]
struct Leave(Arc<AtomicBool>);

fn run_client(cli: ClientCli, host: Option<ServerCli>) {
    let assets = assets::assets_dir(cli.assets.as_deref(), "Fox.glb").unwrap_or_else(|e| bad(&e));
    let leave = Leave::default();
    if cli.leave_on_input {
        let flag = leave.0.clone();
        std::thread::spawn(move || {
            let _ = std::io::stdin().lock().lines().next();
            flag.store(true, Ordering::Relaxed);
        });
    }
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin {
                primary_window: Some(Window { title: "bevy_snowpack multiplayer".into(), resolution: (320, 240).into(), ..default() }),
                ..default()
            })
            .set(AssetPlugin { file_path: assets.to_string_lossy().into_owned(), ..default() }),
    )
    .add_plugins((SnowpackPlugin::new(snow_settings()), RepliconPlugins, RepliconRenetPlugins))
    .insert_resource(ClearColor(Color::srgb(0.62, 0.74, 0.88)))
    .insert_resource(Script::new())
    .insert_resource(leave)
    .insert_resource(cli)
    .add_plugins(gltf::GltfTypesPlugin)
    .add_systems(Startup, setup_scene)
    .add_systems(Update, (dress_players, animate_foxes, walk, script).chain())
    .add_observer(start_fox);
    match host {
        Some(server) => {
            // The listen server's world is its own snow's; its tiles are kept on disk.
            let settings = SnowReplicationSettings { store: Some(SnowRelayStore::new(&server.store)), ..default() };
            app.add_plugins((GameProtocol(settings), ServerGame))
                .insert_resource(server)
                .insert_resource(Me(HOST_ID))
                .add_systems(Startup, (listen.map(|r: Result<(), String>| r.unwrap_or_else(|e| fail(&e))), spawn_host_player));
        }
        None => {
            app.add_plugins(GameProtocol(SnowReplicationSettings::default()))
                .add_systems(Startup, connect.map(|r: Result<(), String>| r.unwrap_or_else(|e| fail(&e))));
        }
    }
    let exit = app.run();
    std::process::exit(if exit == AppExit::Success { 0 } else { 1 });
}

fn connect(mut commands: Commands, channels: Res<RepliconChannels>, cli: Res<ClientCli>) -> Result<(), String> {
    let server_addr = cli.connect.ok_or("no server address")?;
    let socket = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).map_err(|e| format!("a UDP socket: {e}"))?;
    let now = unix_now();
    // Unique enough among the clients of one machine, and never the host's 0.
    let client_id = (now.as_nanos() as u64 ^ u64::from(std::process::id())).max(1);
    let authentication = ClientAuthentication::Unsecure { client_id, protocol_id: PROTOCOL_ID, socket_id: 0, server_addr, user_data: None };
    let transport = NetcodeClientTransport::new(now, authentication, NativeSocket::new(socket).map_err(|e| format!("{e:?}"))?).map_err(|e| e.to_string())?;
    commands.insert_resource(RenetClient::new(ConnectionConfig::from_channels(channels.server_configs(), channels.client_configs()), false));
    commands.insert_resource(transport);
    commands.insert_resource(Me(client_id));
    Ok(())
}

/// A player's fox (a child of its player entity); its walk clip plays while the player moves.
#[derive(Component)]
struct Fox {
    walk: AnimationNodeIndex,
    animators: Vec<Entity>,
}

#[derive(Resource)]
struct FoxAssets {
    scene: Handle<WorldAsset>,
    graph: Handle<AnimationGraph>,
    walk: AnimationNodeIndex,
}

fn setup_scene(mut commands: Commands, assets: Res<AssetServer>, mut graphs: ResMut<Assets<AnimationGraph>>) {
    // Fox.glb's clip 1 is the walk.
    let (graph, walk) = AnimationGraph::from_clip(assets.load(GltfAssetLabel::Animation(1).from_asset("Fox.glb")));
    commands.insert_resource(FoxAssets { scene: assets.load(GltfAssetLabel::Scene(0).from_asset("Fox.glb")), graph: graphs.add(graph), walk });
    commands.spawn((DirectionalLight { illuminance: 10_000.0, ..default() }, Transform::from_xyz(-3.0, 6.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y)));
    // Over the path from the side, the whole walk in view.
    commands.spawn((
        Camera3d::default(),
        SnowGroundPass,
        Tonemapping::AcesFitted,
        Transform::from_xyz(0.0, 6.5, 6.0).looking_at(Vec3::new(0.0, 0.0, 0.3), Vec3::Y),
    ));
}

/// Every player (replicated, or a listen server's own) gets a fox where its
/// transform is; only this app's own fox presses the snow here (the others'
/// trails come from the server).
fn dress_players(mut commands: Commands, players: Query<(Entity, &Player), Added<Player>>, me: Option<Res<Me>>, fox: Res<FoxAssets>) {
    for (entity, player) in &players {
        commands.entity(entity).insert(Visibility::default());
        let mut child = commands.spawn((
            Fox { walk: fox.walk, animators: Vec::new() },
            WorldAssetRoot(fox.scene.clone()),
            Transform::from_scale(Vec3::splat(FOX_SCALE)),
            ChildOf(entity),
        ));
        if me.as_ref().is_some_and(|me| me.0 == player.id) {
            // Every mesh of the fox's scene presses the snow, skinned in pose.
            child.insert(SnowDeformer::Mesh);
        }
    }
}

fn start_fox(
    ready: On<WorldInstanceReady>,
    mut commands: Commands,
    mut foxes: Query<&mut Fox>,
    children: Query<&Children>,
    mut animators: Query<&mut AnimationPlayer>,
    fox_assets: Res<FoxAssets>,
) {
    let Ok(mut fox) = foxes.get_mut(ready.entity) else { return };
    for entity in children.iter_descendants(ready.entity) {
        if let Ok(mut animator) = animators.get_mut(entity) {
            animator.play(fox.walk).repeat();
            commands.entity(entity).insert(AnimationGraphHandle(fox_assets.graph.clone()));
            fox.animators.push(entity);
        }
    }
}

/// A fox walks while its player moves and stands still otherwise (so its paws stop changing the snow).
fn animate_foxes(players: Query<(&Player, &Children)>, foxes: Query<&Fox>, mut animators: Query<&mut AnimationPlayer>) {
    for (player, children) in &players {
        for fox in foxes.iter_many(children).flatten() {
            for &entity in &fox.animators {
                let Ok(mut animator) = animators.get_mut(entity) else { continue };
                if player.moving && animator.all_paused() {
                    animator.resume_all();
                } else if !player.moving && !animator.all_paused() {
                    animator.pause_all();
                }
            }
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Joining,
    Walking,
    Holding,
    Settling,
    Probing,
    Shooting,
}

/// The client's run, phase by phase.
#[derive(Resource)]
struct Script {
    phase: Phase,
    frames: u32,
    phase_started: Instant,
    /// Wall time, snow bytes sent and received when the walk began.
    walk_start: Option<(Instant, u64, u64)>,
    /// Wall seconds, snow bytes sent and received over the walk.
    walked: Option<(f64, u64, u64)>,
    /// renet2's send and receive rates (bytes/s, whole connection) sampled each walking frame.
    renet_rates: Vec<(f64, f64)>,
    settled_frames: u32,
    ticket: Option<SnowTicket>,
    shot: Option<u32>,
}

impl Script {
    fn new() -> Self {
        Self {
            phase: Phase::Joining,
            frames: 0,
            phase_started: Instant::now(),
            walk_start: None,
            walked: None,
            renet_rates: Vec::new(),
            settled_frames: 0,
            ticket: None,
            shot: None,
        }
    }

    fn enter(&mut self, phase: Phase) {
        self.phase = phase;
        self.phase_started = Instant::now();
    }
}

/// This app's own player's position, once the server has made it.
fn own_position(me: Option<&Me>, players: &Query<(&Player, &Transform)>) -> Option<Vec3> {
    let me = me?;
    players.iter().find(|(p, _)| p.id == me.0).map(|(_, t)| t.translation)
}

/// The player's input: the scripted walk, or the arrow keys / WASD. The
/// server moves the player; this only asks.
fn walk(
    time: Res<Time>,
    script: Res<Script>,
    keys: Res<ButtonInput<KeyCode>>,
    me: Option<Res<Me>>,
    players: Query<(&Player, &Transform)>,
    mut requests: MessageWriter<MoveRequest>,
) {
    let Some(at) = own_position(me.as_deref(), &players) else { return };
    if script.phase == Phase::Walking {
        if at.x < WALK_TO_M {
            requests.write(MoveRequest { direction: [1.0, 0.0], distance_m: WALK_STEP_M.min(WALK_TO_M - at.x) });
        }
        return;
    }
    let pressed = |a: KeyCode, b: KeyCode| keys.pressed(a) || keys.pressed(b);
    let mut direction = Vec2::ZERO;
    for (on, d) in [
        (pressed(KeyCode::ArrowLeft, KeyCode::KeyA), Vec2::NEG_X),
        (pressed(KeyCode::ArrowRight, KeyCode::KeyD), Vec2::X),
        (pressed(KeyCode::ArrowUp, KeyCode::KeyW), Vec2::NEG_Y),
        (pressed(KeyCode::ArrowDown, KeyCode::KeyS), Vec2::Y),
    ] {
        if on {
            direction += d;
        }
    }
    if direction != Vec2::ZERO {
        requests.write(MoveRequest { direction: direction.to_array(), distance_m: MAX_SPEED_M_PER_S * time.delta_secs() });
    }
}

/// Joining: waits for the server's welcome and this client's player, then walks or holds.
fn join(cli: &ClientCli, script: &mut Script, sharing: &SnowSharing, own: Option<Vec3>) {
    if sharing.is_welcomed() && own.is_some() {
        println!("client: welcomed after {} frames", script.frames);
        if cli.walk {
            script.walk_start = Some((Instant::now(), sharing.bytes_sent(), sharing.bytes_received()));
            script.enter(Phase::Walking);
        } else {
            script.enter(Phase::Holding);
        }
    } else if script.phase_started.elapsed() > JOIN_LIMIT {
        fail(&format!("no welcome and player from {:?} within {JOIN_LIMIT:?}", cli.connect));
    }
}

/// Settling: waits until the server acknowledged this client's changes and it
/// holds everything the server has over its window, then asks the probes.
fn settle(cli: &ClientCli, script: &mut Script, sharing: &mut SnowSharing, query: &mut SnowQuery) {
    sharing.request_sync();
    script.settled_frames = if sharing.is_settled() { script.settled_frames + 1 } else { 0 };
    if script.settled_frames >= SETTLED_FRAMES {
        let s = sharing.stats();
        println!(
            "client: in sync after {:.1} s of settling: tiles sent {} received {} merged {}",
            script.phase_started.elapsed().as_secs_f64(),
            s.tiles_sent,
            s.tiles_received,
            s.tiles_merged
        );
        script.ticket = (!cli.probes.is_empty()).then(|| query.ask(&cli.probes));
        script.enter(Phase::Probing);
    } else if script.phase_started.elapsed() > SETTLE_LIMIT {
        fail(&format!(
            "not in sync with the server within {SETTLE_LIMIT:?}: {} unacknowledged, {} tiles waiting, {} not gathered, synced {}",
            sharing.unacknowledged(),
            sharing.waiting_tiles(),
            sharing.dirty_tiles(),
            sharing.is_synced()
        ));
    }
}

/// Where each player's fox is on the screenshot: its feet and its back.
fn print_foxes(players: &Query<(&Player, &Transform)>, me: Option<&Me>, on_screen: &dyn Fn(Vec3) -> Option<Vec2>) {
    for (player, t) in players {
        let (Some(feet), Some(back)) = (on_screen(t.translation), on_screen(t.translation + Vec3::Y * FOX_BACK_M)) else { continue };
        let own = me.is_some_and(|me| me.0 == player.id);
        println!(
            "fox {} at {:.2} {:.2} feet {:.0} {:.0} back {:.0} {:.0} own {own}",
            player.id, t.translation.x, t.translation.z, feet.x, feet.y, back.x, back.y
        );
    }
}

/// What the walk sent and received (`wire: ...`), for the tests and docs/bevy.md.
fn print_wire(script: &Script) {
    if let Some((wall_s, sent, received)) = script.walked {
        let n = script.renet_rates.len().max(1) as f64;
        let (renet_sent, renet_received) = script.renet_rates.iter().fold((0.0, 0.0), |(a, b), (s, r)| (a + s / n, b + r / n));
        let walked_m = f64::from(WALK_TO_M - WALK_FROM_M);
        println!(
            "wire: walk_s {wall_s:.2} walk_m {walked_m:.1} snow_bytes_sent {sent} snow_bytes_received {received} snow_bytes_sent_per_s {:.0} snow_bytes_sent_per_m {:.0} renet_bytes_sent_per_s {renet_sent:.0} renet_bytes_received_per_s {renet_received:.0}",
            sent as f64 / wall_s.max(1e-3),
            sent as f64 / walked_m
        );
    }
}

/// Takes the screenshot (then exits a few frames later), or exits now without one.
fn shoot_or_exit(commands: &mut Commands, cli: &ClientCli, script: &mut Script, exit: &mut MessageWriter<AppExit>) {
    match &cli.screenshot {
        Some(path) => {
            commands
                .spawn(Screenshot::primary_window())
                .observe(save_to_disk(path.clone()))
                .observe(|_: On<ScreenshotCaptured>, mut script: ResMut<Script>| script.shot = Some(script.frames));
            script.enter(Phase::Shooting);
        }
        None => {
            exit.write(AppExit::Success);
        }
    }
}

#[allow(clippy::too_many_arguments, reason = "the script reads each of the client's parts")]
fn script(
    mut commands: Commands,
    cli: Res<ClientCli>,
    mut script: ResMut<Script>,
    mut sharing: ResMut<SnowSharing>,
    mut query: ResMut<SnowQuery>,
    leave: Res<Leave>,
    me: Option<Res<Me>>,
    renet: Option<Res<RenetClient>>,
    players: Query<(&Player, &Transform)>,
    view: Single<(&Camera, &GlobalTransform)>,
    window: Single<&Window>,
    mut exit: MessageWriter<AppExit>,
) {
    script.frames += 1;
    if let Some(why) = sharing.refused() {
        fail(&format!("the server refused this client's snow: {why}"));
    }
    let own = own_position(me.as_deref(), &players);
    match script.phase {
        Phase::Joining => join(&cli, &mut script, &sharing, own),
        Phase::Walking => {
            if let Some(renet) = renet.as_deref() {
                let info = renet.network_info();
                script.renet_rates.push((info.bytes_sent_per_second, info.bytes_received_per_second));
            }
            if own.is_some_and(|at| at.x >= WALK_TO_M - 1e-3)
                && let Some((at, sent, received)) = script.walk_start
            {
                script.walked = Some((at.elapsed().as_secs_f64(), sharing.bytes_sent() - sent, sharing.bytes_received() - received));
                script.enter(Phase::Holding);
            }
        }
        Phase::Holding => {
            if script.frames >= cli.exit_after_frames && (!cli.leave_on_input || leave.0.load(Ordering::Relaxed)) {
                script.enter(Phase::Settling);
            }
        }
        Phase::Settling => settle(&cli, &mut script, &mut sharing, &mut query),
        Phase::Probing => {
            let answers = match script.ticket {
                Some(ticket) => match query.take(ticket) {
                    Some(a) => Some(a),
                    None if script.phase_started.elapsed() > SETTLE_LIMIT => fail("the probes were never answered"),
                    None => return,
                },
                None => None,
            };
            let (camera, at) = *view;
            let on_screen = |p: Vec3| camera.world_to_viewport(at, p).ok().map(|v| v * window.scale_factor());
            for (p, sample) in cli.probes.iter().zip(answers.iter().flat_map(|a| a.samples.iter())) {
                let Some(s) = sample else {
                    println!("probe {} {} depth_m outside", p.x, p.y);
                    continue;
                };
                println!("probe {} {} depth_m {:.4}", p.x, p.y, s.depth_m());
                // Where the screenshot shows the snow's rest surface there (physical pixels), for the
                // tests: on a trail the view passes into the trench, onto its walls.
                if let Some(v) = on_screen(Vec3::new(p.x, s.rest_m, p.y)) {
                    println!("pixel {} {} at {:.0} {:.0}", p.x, p.y, v.x, v.y);
                }
            }
            print_foxes(&players, me.as_deref(), &on_screen);
            print_wire(&script);
            shoot_or_exit(&mut commands, &cli, &mut script, &mut exit);
        }
        Phase::Shooting => {
            // Exit a couple of frames after the capture so the file is written.
            if script.shot.is_some_and(|at| script.frames > at + 2) {
                exit.write(AppExit::Success);
            } else if script.phase_started.elapsed() > SETTLE_LIMIT {
                fail("the screenshot was never taken");
            }
        }
    }
}
