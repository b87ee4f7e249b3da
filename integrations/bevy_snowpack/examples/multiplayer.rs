//! Shared snow over a game's own bevy_replicon connection (renet2's netcode
//! over UDP): a dedicated server without renderer or GPU runs the relay, and
//! every client sees every fox's trail, a client that joins late too.
//!
//! ```text
//! cargo run --release --example multiplayer -- server --port P [--exit-after-s S]
//! cargo run --release --example multiplayer -- client --connect 127.0.0.1:P [--walk]
//!     [--exit-after-frames N] [--screenshot FILE] [--probe X,Z]...
//! ```
//!
//! - The server spawns a replicated player per client, owned by it
//!   ([`SnowOwnedBy`]), moves it where the client says its fox is, and
//!   prints the snow depth under each player every second (the relay's
//!   answer, on the CPU). It stops 2 s after its last client leaves (or after
//!   `--exit-after-s`, 300 by default).
//! - A client with `--walk` walks its fox from x = -4 m to x = 4 m along
//!   z = 0 through 0.5 m of snow (at most 0.1 m a frame, so a slow renderer
//!   still leaves a whole trail), then prints what it sent (`wire: ...`).
//! - Every client, once its walk is over and it has run N frames, waits
//!   until the server has acknowledged its changes and it holds everything
//!   the server has over its window, prints `probe X Z depth_m D` per
//!   `--probe`, takes the screenshot and exits.
//!
//! Built with `--no-default-features --features server` the example is the
//! server alone (no renderer, wgpu or window in the plugin); its client
//! needs the default features (`multiplayer`, `gltf`).
#![cfg_attr(
    not(all(feature = "multiplayer", feature = "gltf")),
    allow(dead_code, unused_imports, reason = "built with the server's features alone, the client's half is left out")
)]

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
#[path = "common/gltf.rs"]
mod gltf;

use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::path::PathBuf;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
use bevy::animation::graph::{AnimationGraph, AnimationGraphHandle, AnimationNodeIndex};
use bevy::app::ScheduleRunnerPlugin;
#[cfg(all(feature = "multiplayer", feature = "gltf"))]
use bevy::core_pipeline::tonemapping::Tonemapping;
#[cfg(all(feature = "multiplayer", feature = "gltf"))]
use bevy::gltf::GltfAssetLabel;
use bevy::prelude::*;
#[cfg(all(feature = "multiplayer", feature = "gltf"))]
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured, save_to_disk};
use bevy::state::app::StatesPlugin;
#[cfg(all(feature = "multiplayer", feature = "gltf"))]
use bevy::world_serialization::{WorldAssetRoot, WorldInstanceReady};
use bevy_replicon::prelude::*;
use bevy_replicon_renet2::netcode::{
    ClientAuthentication, NativeSocket, NetcodeClientTransport, NetcodeServerTransport, ServerAuthentication, ServerSetupConfig,
};
use bevy_replicon_renet2::renet2::{ConnectionConfig, RenetClient, RenetServer};
use bevy_replicon_renet2::{RenetChannelsExt, RepliconRenetPlugins};
use bevy_snowpack::prelude::*;
use serde::{Deserialize, Serialize};

/// Netcode's protocol id: this example's, so nothing else connects by mistake.
const PROTOCOL_ID: u64 = 0x736e_6f77_6d70_0001;
/// Snow depth (m) on flat ground.
const DEPTH_M: f32 = 0.5;
/// The fox's model is in centimetres.
const FOX_SCALE: f32 = 0.01;
/// The fox wades: its soles this high (m) over the ground, its legs and belly ploughing the snow.
const FOX_SOLE_M: f32 = 0.02;
const WALK_FROM_M: f32 = -4.0;
const WALK_TO_M: f32 = 4.0;
const WALK_M_PER_S: f32 = 1.0;
/// The walk advances at most this much a frame (s), so the trail is whole however slow the frames.
const MAX_WALK_STEP_S: f32 = 0.1;
/// How long a client waits for the server's welcome, and then to be in sync at its end.
const JOIN_LIMIT: Duration = Duration::from_secs(120);
const SETTLE_LIMIT: Duration = Duration::from_secs(120);
/// Frames in a row a client must be settled before it reads the snow.
const SETTLED_FRAMES: u32 = 5;

fn main() {
    match Cli::parse() {
        Cli::Server { port, exit_after_s } => run_server(port, exit_after_s),
        Cli::Client(client) => run_client(client),
    }
}

// ---------------------------------------------------------------- command line

enum Cli {
    Server { port: u16, exit_after_s: f64 },
    Client(ClientCli),
}

#[derive(Resource, Clone, Debug)]
struct ClientCli {
    connect: SocketAddr,
    walk: bool,
    exit_after_frames: u32,
    screenshot: Option<PathBuf>,
    probes: Vec<Vec2>,
}

impl Cli {
    /// Parses the process's arguments; exits with status 2 on a bad one.
    fn parse() -> Self {
        let args: Vec<String> = std::env::args().skip(1).collect();
        let Some((mode, rest)) = args.split_first() else { bad("no mode") };
        let mut port = None;
        let mut exit_after_s = 300.0;
        let mut client =
            ClientCli { connect: SocketAddr::from((Ipv4Addr::LOCALHOST, 0)), walk: false, exit_after_frames: 0, screenshot: None, probes: Vec::new() };
        let mut connect = None;
        let mut it = rest.iter();
        while let Some(arg) = it.next() {
            let mut value = |name: &str| it.next().cloned().unwrap_or_else(|| bad(&format!("{name} needs a value")));
            match (mode.as_str(), arg.as_str()) {
                ("server", "--port") => port = Some(value("--port").parse().unwrap_or_else(|e| bad(&format!("--port: {e}")))),
                ("server", "--exit-after-s") => exit_after_s = value("--exit-after-s").parse().unwrap_or_else(|e| bad(&format!("--exit-after-s: {e}"))),
                ("client", "--connect") => connect = Some(value("--connect").parse().unwrap_or_else(|e| bad(&format!("--connect: {e}")))),
                ("client", "--walk") => client.walk = true,
                ("client", "--exit-after-frames") => {
                    client.exit_after_frames = value("--exit-after-frames").parse().unwrap_or_else(|e| bad(&format!("--exit-after-frames: {e}")));
                }
                ("client", "--screenshot") => client.screenshot = Some(value("--screenshot").into()),
                ("client", "--probe") => {
                    let v = value("--probe");
                    let xz: Vec<f32> = v.split(',').map(|s| s.trim().parse().unwrap_or_else(|e| bad(&format!("--probe {v}: {e}")))).collect();
                    let [x, z] = xz[..] else { bad(&format!("--probe {v}: give X,Z")) };
                    client.probes.push(Vec2::new(x, z));
                }
                _ => bad(&format!("unknown or misplaced argument {arg}")),
            }
        }
        match mode.as_str() {
            "server" => Self::Server { port: port.unwrap_or_else(|| bad("server needs --port")), exit_after_s },
            "client" => {
                client.connect = connect.unwrap_or_else(|| bad("client needs --connect"));
                Self::Client(client)
            }
            other => bad(&format!("unknown mode {other}")),
        }
    }
}

fn bad(why: &str) -> ! {
    eprintln!(
        "{why}\nusage: multiplayer server --port P [--exit-after-s S]\n       multiplayer client --connect ADDR [--walk] [--exit-after-frames N] [--screenshot FILE] [--probe X,Z]..."
    );
    std::process::exit(2)
}

// ---------------------------------------------------------------- the game's protocol

/// A player, replicated to every client: where its fox is.
#[derive(Component, Serialize, Deserialize, Clone, Copy, Debug, Default)]
struct Player {
    at: [f32; 3],
}

/// A client's fox is here now (client → server).
#[derive(Message, Serialize, Deserialize, Clone, Copy, Debug)]
struct FoxAt([f32; 3]);

/// What server and clients register, in the same order (replicon checks it).
struct GameProtocol;

impl Plugin for GameProtocol {
    fn build(&self, app: &mut App) {
        app.add_plugins(SnowReplicationPlugin::default()).replicate::<Player>().add_client_message::<FoxAt>(Channel::Unreliable);
    }
}

/// Seconds since the Unix epoch (netcode's clock).
fn unix_now() -> Duration {
    SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default()
}

// ---------------------------------------------------------------- server

#[derive(Resource)]
struct ServerRun {
    port: u16,
    exit_after_s: f64,
    started: Instant,
    had_clients: bool,
    empty_since: Option<Instant>,
    last_report: Instant,
}

fn run_server(port: u16, exit_after_s: f64) {
    let exit = App::new()
        .add_plugins((
            MinimalPlugins.set(ScheduleRunnerPlugin::run_loop(Duration::from_secs_f64(1.0 / 60.0))),
            StatesPlugin,
            RepliconPlugins,
            RepliconRenetPlugins,
        ))
        .add_plugins(GameProtocol)
        .insert_resource(ServerRun { port, exit_after_s, started: Instant::now(), had_clients: false, empty_since: None, last_report: Instant::now() })
        .add_systems(Startup, listen.map(|r: Result<(), String>| r.unwrap_or_else(|e| fail(&e))))
        .add_observer(spawn_player)
        .add_observer(despawn_player)
        .add_systems(Update, (move_players, report_server, stop_server).chain())
        .run();
    std::process::exit(if exit == AppExit::Success { 0 } else { 1 });
}

fn fail(why: &str) -> ! {
    eprintln!("multiplayer: {why}");
    std::process::exit(1)
}

fn listen(mut commands: Commands, channels: Res<RepliconChannels>, run: Res<ServerRun>) -> Result<(), String> {
    let addr = SocketAddr::from((Ipv4Addr::LOCALHOST, run.port));
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
    println!("server: listening on {local}");
    Ok(())
}

/// Each authorized client gets a replicated player that it owns: where it may change the snow.
fn spawn_player(add: On<Add<AuthorizedClient>>, mut commands: Commands, mut run: ResMut<ServerRun>) {
    run.had_clients = true;
    commands.spawn((Player::default(), Replicated, SnowOwnedBy(add.entity), Transform::default()));
    println!("server: client {} joined", add.entity);
}

fn despawn_player(remove: On<Remove<ConnectedClient>>, mut commands: Commands, players: Query<(Entity, &SnowOwnedBy)>) {
    for (player, owner) in &players {
        if owner.0 == remove.entity {
            commands.entity(player).despawn();
        }
    }
    println!("server: client {} left", remove.entity);
}

/// The client's word for where its fox is (a real game would check it).
fn move_players(mut moves: MessageReader<FromClient<FoxAt>>, mut players: Query<(&SnowOwnedBy, &mut Player, &mut Transform)>) {
    for m in moves.read() {
        for (owner, mut player, mut transform) in &mut players {
            if ClientId::Client(owner.0) == m.client_id {
                player.at = m.message.0;
                transform.translation = Vec3::from_array(m.message.0);
            }
        }
    }
}

/// Every second: the snow depth under each player, from the relay.
fn report_server(mut run: ResMut<ServerRun>, snow: Res<SnowServer>, players: Query<(&SnowOwnedBy, &Transform, &SnowDepthUnder)>) {
    if run.last_report.elapsed() < Duration::from_secs(1) {
        return;
    }
    run.last_report = Instant::now();
    for (owner, t, under) in &players {
        if let Some(d) = under.depth_m {
            println!("server: player {} at {:.2} {:.2} depth_m {d:.4}", owner.0, t.translation.x, t.translation.z);
        }
    }
    let s = snow.relay().stats();
    if s.rejected.total() > 0 {
        println!("server: refused so far: {:?}", s.rejected);
    }
    println!(
        "server: {} peers, tiles received {} merged {} sent {}, bytes in {} out {}, refused {}",
        s.peers,
        s.tiles_received,
        s.tiles_merged,
        s.tiles_sent,
        s.bytes_in,
        s.bytes_out,
        s.rejected.total()
    );
}

/// Stops 2 s after the last client left, or at the time limit.
fn stop_server(mut run: ResMut<ServerRun>, clients: Query<(), With<ConnectedClient>>, snow: Res<SnowServer>, mut exit: MessageWriter<AppExit>) {
    let empty = clients.is_empty();
    run.empty_since = match (empty, run.empty_since) {
        (true, None) => Some(Instant::now()),
        (true, since) => since,
        (false, _) => None,
    };
    let done = run.had_clients && run.empty_since.is_some_and(|t| t.elapsed() >= Duration::from_secs(2));
    let late = run.started.elapsed().as_secs_f64() >= run.exit_after_s;
    if done || late {
        let s = snow.relay().stats();
        println!(
            "server: stopped after {:.1} s ({}): tiles received {} merged {}, bytes in {} out {}, refused {}",
            run.started.elapsed().as_secs_f64(),
            if done { "no clients left" } else { "time limit" },
            s.tiles_received,
            s.tiles_merged,
            s.bytes_in,
            s.bytes_out,
            s.rejected.total()
        );
        exit.write(AppExit::Success);
    }
}

/// Built without `multiplayer` and `gltf` the example is the server alone.
#[cfg(not(all(feature = "multiplayer", feature = "gltf")))]
fn run_client(_: ClientCli) {
    bad("this build of the example is the server alone; its client needs the features `multiplayer` and `gltf` (the default ones)")
}

// ---------------------------------------------------------------- client

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
fn snow_settings() -> SnowpackSettings {
    SnowpackSettings {
        // 12 m of 4.7 cm texels around the origin: the whole walk, and a margin of open snow.
        params: SnowParams { extent_m: 12.0, resolution: 256, depth_m: DEPTH_M, refill_m_per_s: 0.0, ..SnowParams::default() },
        terrain: TerrainSource::Flat { height_m: 0.0 },
        center: Vec2::ZERO,
        fixed_dt_s: None,
        store: None,
    }
}

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
fn run_client(cli: ClientCli) {
    let exit = App::new()
        .add_plugins(
            DefaultPlugins
                .set(WindowPlugin {
                    primary_window: Some(Window { title: "bevy_snowpack multiplayer".into(), resolution: (320, 240).into(), ..default() }),
                    ..default()
                })
                // The fox lives in the repository's assets folder (relative to this crate's manifest).
                .set(AssetPlugin { file_path: "../../assets".into(), ..default() }),
        )
        .add_plugins((SnowpackPlugin::new(snow_settings()), RepliconPlugins, RepliconRenetPlugins, GameProtocol, gltf::GltfTypesPlugin))
        .insert_resource(ClearColor(Color::srgb(0.62, 0.74, 0.88)))
        .insert_resource(Script::new())
        .insert_resource(cli)
        .add_systems(Startup, (connect.map(|r: Result<(), String>| r.unwrap_or_else(|e| fail(&e))), setup_scene))
        .add_systems(Update, (walk, script).chain())
        .run();
    std::process::exit(if exit == AppExit::Success { 0 } else { 1 });
}

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
fn connect(mut commands: Commands, channels: Res<RepliconChannels>, cli: Res<ClientCli>) -> Result<(), String> {
    let socket = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).map_err(|e| format!("a UDP socket: {e}"))?;
    let now = unix_now();
    let authentication = ClientAuthentication::Unsecure {
        // Unique enough among the clients of one machine.
        client_id: now.as_nanos() as u64 ^ u64::from(std::process::id()),
        protocol_id: PROTOCOL_ID,
        socket_id: 0,
        server_addr: cli.connect,
        user_data: None,
    };
    let transport = NetcodeClientTransport::new(now, authentication, NativeSocket::new(socket).map_err(|e| format!("{e:?}"))?).map_err(|e| e.to_string())?;
    commands.insert_resource(RenetClient::new(ConnectionConfig::from_channels(channels.server_configs(), channels.client_configs()), false));
    commands.insert_resource(transport);
    Ok(())
}

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
#[derive(Component)]
struct Fox {
    walk: AnimationNodeIndex,
}

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
#[derive(Resource)]
struct FoxAnimation(Handle<AnimationGraph>);

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
fn fox_at(x: f32) -> Vec3 {
    Vec3::new(x, FOX_SOLE_M, 0.0)
}

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
fn setup_scene(mut commands: Commands, cli: Res<ClientCli>, assets: Res<AssetServer>, mut graphs: ResMut<Assets<AnimationGraph>>) {
    if cli.walk {
        // Fox.glb's clip 1 is the walk.
        let (graph, node) = AnimationGraph::from_clip(assets.load(GltfAssetLabel::Animation(1).from_asset("Fox.glb")));
        commands.insert_resource(FoxAnimation(graphs.add(graph)));
        commands
            .spawn((
                Fox { walk: node },
                WorldAssetRoot(assets.load(GltfAssetLabel::Scene(0).from_asset("Fox.glb"))),
                // Every mesh of the fox's scene presses the snow, skinned in pose: this client's only deformer.
                SnowDeformer::Mesh,
                // The model faces +z; the walk goes along +x.
                Transform::from_translation(fox_at(WALK_FROM_M))
                    .with_rotation(Quat::from_rotation_y(std::f32::consts::FRAC_PI_2))
                    .with_scale(Vec3::splat(FOX_SCALE)),
            ))
            .observe(start_fox);
    }
    commands.spawn((DirectionalLight { illuminance: 10_000.0, ..default() }, Transform::from_xyz(-3.0, 6.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y)));
    // Over the path from the side, the whole walk in view.
    commands.spawn((
        Camera3d::default(),
        SnowGroundPass,
        Tonemapping::AcesFitted,
        Transform::from_xyz(0.0, 6.5, 6.0).looking_at(Vec3::new(0.0, 0.0, 0.3), Vec3::Y),
    ));
}

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
fn start_fox(
    ready: On<WorldInstanceReady>,
    mut commands: Commands,
    foxes: Query<&Fox>,
    children: Query<&Children>,
    mut players: Query<&mut AnimationPlayer>,
    animation: Res<FoxAnimation>,
) {
    let Ok(fox) = foxes.get(ready.entity) else { return };
    for entity in children.iter_descendants(ready.entity) {
        if let Ok(mut player) = players.get_mut(entity) {
            player.play(fox.walk).repeat();
            commands.entity(entity).insert(AnimationGraphHandle(animation.0.clone()));
        }
    }
}

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Joining,
    Walking,
    Holding,
    Settling,
    Probing,
    Shooting,
}

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
/// The client's run, phase by phase.
#[derive(Resource)]
struct Script {
    phase: Phase,
    frames: u32,
    phase_started: Instant,
    /// Walk time so far (s).
    walk_t: f32,
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

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
impl Script {
    fn new() -> Self {
        Self {
            phase: Phase::Joining,
            frames: 0,
            phase_started: Instant::now(),
            walk_t: 0.0,
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

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
/// Walks the fox while the script says so, and tells the server where it is.
fn walk(
    time: Res<Time>,
    mut script: ResMut<Script>,
    mut fox: Query<&mut Transform, With<Fox>>,
    mut players: Query<&mut AnimationPlayer>,
    mut moves: MessageWriter<FoxAt>,
) {
    let Ok(mut transform) = fox.single_mut() else { return };
    if script.phase == Phase::Walking {
        script.walk_t += time.delta_secs().min(MAX_WALK_STEP_S);
        let x = (WALK_FROM_M + script.walk_t * WALK_M_PER_S).min(WALK_TO_M);
        transform.translation = fox_at(x);
        if x >= WALK_TO_M {
            // At the end it stands still, so its paws stop changing the snow and the client can settle.
            for mut player in &mut players {
                player.pause_all();
            }
        }
    }
    moves.write(FoxAt(transform.translation.to_array()));
}

#[cfg(all(feature = "multiplayer", feature = "gltf"))]
#[allow(clippy::too_many_arguments, reason = "the script reads each of the client's parts")]
fn script(
    mut commands: Commands,
    cli: Res<ClientCli>,
    mut script: ResMut<Script>,
    mut sharing: ResMut<SnowSharing>,
    mut query: ResMut<SnowQuery>,
    renet: Option<Res<RenetClient>>,
    fox: Query<&Transform, With<Fox>>,
    view: Single<(&Camera, &GlobalTransform)>,
    window: Single<&Window>,
    mut exit: MessageWriter<AppExit>,
) {
    script.frames += 1;
    if let Some(why) = sharing.refused() {
        fail(&format!("the server refused this client's snow: {why}"));
    }
    match script.phase {
        Phase::Joining => {
            if sharing.is_welcomed() {
                println!("client: welcomed after {} frames", script.frames);
                if cli.walk {
                    script.walk_start = Some((Instant::now(), sharing.bytes_sent(), sharing.bytes_received()));
                    script.enter(Phase::Walking);
                } else {
                    script.enter(Phase::Holding);
                }
            } else if script.phase_started.elapsed() > JOIN_LIMIT {
                fail(&format!("no welcome from {} within {JOIN_LIMIT:?}", cli.connect));
            }
        }
        Phase::Walking => {
            if let Some(renet) = renet.as_deref() {
                let info = renet.network_info();
                script.renet_rates.push((info.bytes_sent_per_second, info.bytes_received_per_second));
            }
            if fox.single().is_ok_and(|t| t.translation.x >= WALK_TO_M)
                && let Some((at, sent, received)) = script.walk_start
            {
                script.walked = Some((at.elapsed().as_secs_f64(), sharing.bytes_sent() - sent, sharing.bytes_received() - received));
                script.enter(Phase::Holding);
            }
        }
        Phase::Holding => {
            if script.frames >= cli.exit_after_frames {
                script.enter(Phase::Settling);
            }
        }
        Phase::Settling => {
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
            for (p, sample) in cli.probes.iter().zip(answers.iter().flat_map(|a| a.samples.iter())) {
                let Some(s) = sample else {
                    println!("probe {} {} depth_m outside", p.x, p.y);
                    continue;
                };
                println!("probe {} {} depth_m {:.4}", p.x, p.y, s.depth_m());
                // Where the screenshot shows the snow's rest surface there (physical pixels), for the
                // tests: on a trail the view passes into the trench, onto its walls.
                if let Ok(v) = camera.world_to_viewport(at, Vec3::new(p.x, s.rest_m, p.y)) {
                    let v = v * window.scale_factor();
                    println!("pixel {} {} at {:.0} {:.0}", p.x, p.y, v.x, v.y);
                }
            }
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
