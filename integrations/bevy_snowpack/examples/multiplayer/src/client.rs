//! The game's client side (feature `client`): every player's fox drawn
//! where the server's replicated transform puts it, its own fox's snow
//! shared, the walk asked of the server, and the scripted end a test reads.

#[path = "../../common/assets.rs"]
mod assets;
#[path = "../../common/gltf.rs"]
mod gltf;

use std::io::BufRead as _;
use std::net::{Ipv4Addr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use bevy::animation::graph::{AnimationGraph, AnimationGraphHandle, AnimationNodeIndex};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::gltf::GltfAssetLabel;
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured, save_to_disk};
use bevy::world_serialization::{WorldAsset, WorldAssetRoot, WorldInstanceReady};
use bevy_replicon::prelude::*;
use bevy_replicon_renet2::netcode::{ClientAuthentication, NativeSocket, NetcodeClientTransport};
use bevy_replicon_renet2::renet2::{ConnectionConfig, RenetClient};
use bevy_replicon_renet2::{RenetChannelsExt, RepliconRenetPlugins};
use bevy_snowpack::prelude::*;

use crate::cli::{ClientCli, ServerCli, bad, fail};
use crate::protocol::{DEPTH_M, EXTENT_M, GameProtocol, HOST_ID, MAX_SPEED_M_PER_S, MoveRequest, PROTOCOL_ID, Player, RESOLUTION, WALK_FROM_M, unix_now};
use crate::server::{ServerGame, listen, spawn_host_player};

/// Where a scripted walk ends (x, m).
const WALK_TO_M: f32 = 4.0;
/// The fox's model is in centimetres.
const FOX_SCALE: f32 = 0.01;
/// A scripted walk asks for this much a frame (m), so the trail is whole however slow the frames.
const WALK_STEP_M: f32 = 0.1;
/// How long a client waits for the server's welcome and its player, and then to be in sync at its end.
const JOIN_LIMIT: Duration = Duration::from_secs(120);
const SETTLE_LIMIT: Duration = Duration::from_secs(120);
/// Frames in a row a client must be settled before it reads the snow.
const SETTLED_FRAMES: u32 = 5;
/// How high (m) over a player's feet its fox's back is, for where the screen shows it.
const FOX_BACK_M: f32 = 0.5;

/// The snow every machine of this game runs: [`crate::protocol::world`]'s,
/// [`EXTENT_M`] around the origin in [`DEPTH_M`] of snow.
fn snow_settings() -> SnowpackSettings {
    SnowpackSettings {
        params: SnowParams { extent_m: EXTENT_M, resolution: RESOLUTION, depth_m: DEPTH_M, refill_m_per_s: 0.0, ..SnowParams::default() },
        terrain: TerrainSource::Flat { height_m: 0.0 },
        center: Vec2::ZERO,
        fixed_dt_s: None,
        store: None,
    }
}

/// This app's own player id (netcode's client id, or [`HOST_ID`]).
#[derive(Resource, Clone, Copy)]
struct Me(u64);

/// Set once a line (or the end) came on standard input (`--leave-on-input`).
#[derive(Resource, Clone, Default)]
struct Leave(Arc<AtomicBool>);

pub fn run_client(cli: ClientCli, host: Option<ServerCli>) {
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

#[cfg(test)]
mod tests {
    use bevy_snowpack::SnowReplicationSettings;
    use bevy_snowpack::snowpack::{SharedWindow as _, SnowDeformation};

    /// The server's world, found from constants without a GPU, is the one the clients' snow has.
    #[test]
    fn the_clients_snow_is_the_servers_world() {
        let snow = super::snow_settings();
        let tile_side = SnowReplicationSettings::default().tile_side;
        assert_eq!(SnowDeformation::world_identity_for(&snow.params, &snow.terrain, tile_side), crate::protocol::world());
    }
}
