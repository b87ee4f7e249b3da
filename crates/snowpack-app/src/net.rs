//! Shared snow over UDP, with renet2's netcode transport: the dedicated
//! `snowpack server` (a [`SnowRelay`] that merges on the CPU, persists to a
//! tile store and never opens a GPU), `snowpack token` (connect tokens for a
//! server started with `--key`), `snowpack query` (snow depth at points,
//! from the server's tiles) and [`SnowLink`], the client side of
//! `snowpack run --connect` and the demo's `--connect`.
//!
//! Every snowpack message travels on one reliable, unordered channel: tiles
//! merge in any order, so nothing waits behind a lost packet, and the
//! protocol's own acknowledgements and digests repair what a connection that
//! drops and comes back lost. `docs/multiplayer.md` has the protocol.

use snowpack_share::persist::TileStoreExt;
use snowpack_share::replicate::WorldIdentityExt;
use std::collections::VecDeque;
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::Context as _;
use renet2::{ChannelConfig, ConnectionConfig, RenetClient, RenetServer, SendType, ServerEvent};
use renet2_netcode::{
    ClientAuthentication, ConnectToken, NETCODE_KEY_BYTES, NativeSocket, NetcodeClientTransport, NetcodeServerTransport, ServerAuthentication,
    ServerSetupConfig,
};
#[cfg(feature = "gpu")]
use snowpack::SharedWindow as _;
#[cfg(feature = "gpu")]
use snowpack::low_level::SnowInspect;
use snowpack_app::BadInput;
use snowpack_share::persist::{StoreConfig, TileStore, WhenFull};
#[cfg(feature = "gpu")]
use snowpack_share::replicate::{PeerConfig, SharedSnow, SnowPeer};
use snowpack_share::replicate::{RelayConfig, RelayStats, ShareError, SnowRelay, WorldIdentity};

/// Netcode's protocol id: packets of other programs (or another version of
/// this protocol) are refused before they reach the relay.
const PROTOCOL_ID: u64 = 0x736e_6f77_7061_636b ^ snowpack_share::replicate::message::PROTOCOL_VERSION as u64;
/// The one channel snowpack's messages travel on.
pub(crate) const CHANNEL: u8 = 0;
/// Bytes a connection's channel may hold unacknowledged; the relay paces
/// itself well below this (a full reliable channel disconnects).
const CHANNEL_BYTES: usize = 1 << 20;
/// The server's loop period.
const TICK: Duration = Duration::from_millis(10);
/// How long a connect token made by `snowpack token` stays valid (s).
const TOKEN_LIFETIME_S: u64 = 12 * 3600;
/// Messages kept per connection while its channel is full; beyond it the
/// oldest go (an acknowledgement lost is a delta resent, a tile lost is
/// repaired by the next digest), so a client that stops reading costs
/// bounded memory.
const MAX_BACKLOG: usize = 1024;
/// Bytes the server keeps for one client while its channel is full: a
/// client that stops reading is disconnected past it, so it costs at most
/// this plus its channel ([`CHANNEL_BYTES`]).
pub const MAX_BACKLOG_BYTES: usize = 1 << 20;
/// Clients a server takes at once.
const MAX_CLIENTS: usize = 256;
/// The bytes of one client's messages the relay takes in one tick; the
/// message that crosses it is taken whole, so a tick takes at most this plus
/// one message ([`snowpack_share::replicate::MAX_MESSAGE_BYTES`]). The loop is
/// one thread: without this, one client's flood would be processed whole
/// before anyone else's next message. What a client sends beyond it waits in
/// its own channel for the next tick, and a client that keeps sending more
/// fills that channel ([`CHANNEL_BYTES`]) and is disconnected by renet. At
/// 100 ticks a second it is 6.4 MB/s a client, above renet's own pace for
/// a client (60 kB a tick) and far above what an honest peer sends.
pub const TICK_BYTES_PER_CLIENT: usize = 64 * 1024;
/// Tile side of the worlds a `snowpack server` serves when its store does not say.
pub const DEFAULT_TILE_SIDE: u32 = 32;

/// Prints a line on stdout, ignoring a closed stdout: a server whose
/// output nobody reads any more (a pipe closed, `| head`) goes on serving.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

fn connection_config() -> ConnectionConfig {
    let channel = ChannelConfig {
        channel_id: CHANNEL,
        max_memory_usage_bytes: CHANNEL_BYTES,
        send_type: SendType::ReliableUnordered { resend_time: Duration::from_millis(150) },
    };
    ConnectionConfig::from_shared_channels(vec![channel])
}

fn unix_now() -> Duration {
    SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default()
}

/// A server's private key: 32 bytes, in the file as 64 hexadecimal digits
/// (whitespace around them ignored) or as the raw bytes.
fn read_key(path: &Path) -> anyhow::Result<[u8; NETCODE_KEY_BYTES]> {
    let bytes = std::fs::read(path).map_err(|e| BadInput(format!("--key {}: {e}", path.display())))?;
    if bytes.len() == NETCODE_KEY_BYTES {
        let mut key = [0; NETCODE_KEY_BYTES];
        key.copy_from_slice(&bytes);
        return Ok(key);
    }
    let text = String::from_utf8_lossy(&bytes);
    let hex = text.trim();
    let bad = || BadInput(format!("--key {}: a key is 32 bytes, or 64 hexadecimal digits; this file is neither", path.display()));
    if hex.len() != 2 * NETCODE_KEY_BYTES || !hex.is_ascii() {
        return Err(bad().into());
    }
    let mut key = [0; NETCODE_KEY_BYTES];
    for (k, byte) in key.iter_mut().enumerate() {
        *byte = u8::from_str_radix(&hex[2 * k..2 * k + 2], 16).map_err(|_| bad())?;
    }
    Ok(key)
}

/// What `snowpack server` was asked for.
#[derive(Clone, Debug)]
pub struct ServerOptions {
    /// Address to listen on (UDP).
    pub listen: SocketAddr,
    /// The tile store's folder (created when missing).
    pub store: PathBuf,
    /// The private key file: clients then need a connect token made from it.
    pub key: Option<PathBuf>,
    /// Stop after this many seconds (tests; default: run until killed).
    pub exit_after_s: Option<f64>,
    /// The scene file whose `[snow]` and `[terrain]` make the world: the
    /// server's, checked against its store, never a peer's. Without it the
    /// world is the store's, or the first accepted peer's.
    pub scene: Option<PathBuf>,
    /// Bytes of tile files the store may hold; past it new tiles are
    /// refused and kept ones stay (0: unlimited).
    pub disk_budget_bytes: u64,
    /// Top speed (m/s) of a peer's own deformers between two reports.
    pub max_speed_m_per_s: f64,
    /// The world's bounds `[x0, z0, x1, z1]` (m): tiles beyond are refused.
    pub bounds_m: Option<[f64; 4]>,
}

/// The world of a scene file: its `[snow]` and `[terrain]`, shared in tiles
/// of [`DEFAULT_TILE_SIDE`]² (as `snowpack run --connect` shares them).
/// Found on the CPU: no GPU is opened.
#[cfg(feature = "gpu")]
pub fn scene_world(path: &Path) -> anyhow::Result<WorldIdentity> {
    scene_snow(path).map(|(world, _)| world)
}

/// A scene file's world ([`scene_world`]) and its snow's mechanics (its
/// densities and hardness, `[snow]`), which turn a server's depth and
/// packed snow into a density and a hardness.
#[cfg(feature = "gpu")]
pub fn scene_snow(path: &Path) -> anyhow::Result<(WorldIdentity, snowpack_share::mechanics::SnowMechanics)> {
    let scene = snowpack_scene::Scene::load(path)?;
    if scene.snow.resolution % DEFAULT_TILE_SIDE != 0 {
        return Err(BadInput(format!(
            "{}: [snow].resolution: {} is not a multiple of the shared tile side {DEFAULT_TILE_SIDE}",
            path.display(),
            scene.snow.resolution
        ))
        .into());
    }
    Ok((snowpack::SnowDeformation::world_identity_for(&scene.snow, &scene.terrain, DEFAULT_TILE_SIDE), scene.snow.mechanics()))
}

/// A scene's world needs the scene loader (heightmaps, meshes, the window's
/// parameters), which the server-only build leaves out with the GPU stack:
/// bad input saying how to serve a scene's world from this build.
#[cfg(not(feature = "gpu"))]
pub fn scene_world(path: &Path) -> anyhow::Result<WorldIdentity> {
    scene_snow(path).map(|(world, _)| world)
}

/// See [`scene_world`]: the server-only build has no scene loader.
#[cfg(not(feature = "gpu"))]
pub fn scene_snow(path: &Path) -> anyhow::Result<(WorldIdentity, snowpack_share::mechanics::SnowMechanics)> {
    Err(BadInput(format!(
        "--scene {}: this snowpack is the server-only build (no GPU stack, no scene loader); \
         pin the world into the store once with the full build (`snowpack server --scene FILE --store DIR`; \
         a heightmap world's heightmap is kept with it, so presses travel as frames), \
         then serve that store with this build: a store's world is never redefined by a peer",
        path.display()
    ))
    .into())
}

/// The scene key a difference between two worlds is about.
fn scene_key(difference: &str) -> &'static str {
    let name = difference.split(':').next().unwrap_or_default();
    match name {
        "texel size (m)" => "[snow].extent_m / [snow].resolution",
        "snow depth (m)" => "[snow].depth_m",
        "refill (m/s)" => "[snow].refill_m_per_s",
        "snowfall rate (m/s)" => "[snowfall].rate_m_per_s",
        "most snowfall kept (m)" => "[snowfall].max_m",
        "snowfall" => "[snowfall]",
        "terrain" => "[terrain]",
        "tile side" => "the tile side",
        _ => "[terrain] heights and [snow].depth_m (the footprint range)",
    }
}

/// A store whose saved world is not the scene's: bad input naming both,
/// and each scene key that differs.
fn store_mismatch(store: &Path, scene: &Path, differences: &str) -> anyhow::Error {
    let listed: Vec<String> =
        differences.split("; ").map(|d| format!("{}: {}", scene_key(d), d.replace(" here", " in the store").replace(" there", " in the scene"))).collect();
    BadInput(format!(
        "--store {}: it keeps another world than --scene {}: {} (start the server on a fresh --store, or with the scene that made it)",
        store.display(),
        scene.display(),
        listed.join("; ")
    ))
    .into()
}

/// Opens the server's store and relay: the world pinned from the scene
/// (checked against the store's) when there is one.
fn open_relay(opts: &ServerOptions) -> anyhow::Result<(SnowRelay, f64)> {
    let world = opts.scene.as_deref().map(scene_world).transpose()?;
    std::fs::create_dir_all(&opts.store).with_context(|| format!("creating the store folder {}", opts.store.display()))?;
    let stored = TileStore::side_in(&opts.store).context("reading the store's description")?;
    let side = match (&world, stored) {
        (Some(w), Some(s)) if s != w.settings().tile_side => {
            let scene = opts.scene.as_deref().unwrap_or(Path::new(""));
            return Err(store_mismatch(&opts.store, scene, &format!("tile side: {s} here, {} there", w.settings().tile_side)));
        }
        (Some(w), _) => w.settings().tile_side,
        (None, s) => s.unwrap_or(DEFAULT_TILE_SIDE),
    };
    let config = StoreConfig { disk_budget_bytes: opts.disk_budget_bytes, when_full: WhenFull::RefuseNew };
    let store = TileStore::open(&opts.store, side, config).with_context(|| format!("opening the tile store {}", opts.store.display()))?;
    let epoch = world_epoch(&store)?;
    let relay_config = RelayConfig { max_speed_m_per_s: opts.max_speed_m_per_s, bounds_m: opts.bounds_m, ..RelayConfig::default() };
    let mut relay = SnowRelay::with_store(store, relay_config).context("resuming the world from the store")?;
    if let (Some(world), Some(scene)) = (world, opts.scene.as_deref()) {
        match relay.pin_world(world).map_err(snowpack_share::error::ShareError::from) {
            Ok(()) => {}
            Err(ShareError::StoreWorld(differences)) => return Err(store_mismatch(&opts.store, scene, &differences)),
            Err(e) => return Err(e).context("saving the scene's world in the store"),
        }
    }
    Ok((relay, epoch))
}

/// The relay's work and refusals, as `key=value` fields.
fn stats_fields(s: &RelayStats) -> String {
    let r = &s.rejected;
    format!(
        "distance_tests={} window_keys_walked={} queries={} tile_bytes_in_memory={} refused_far={} refused_teleports={} refused_world={} \
         refused_not_welcomed={} refused_rate_bytes={} refused_rate_tiles={} refused_rate_window={} refused_rate_query={} refused_bad_window={} \
         refused_out_of_bounds={} refused_disk_full={} refused_bad_footprint={} refused_bad_tile={} refused_too_deep={} refused_malformed={} \
         refused_oversized={} refused_rate_presses={} refused_unpressable={} press_frames={} press_casts={} press_frames_passed_on={} awaiting_presence={} outgoing_dropped={}",
        s.distance_tests,
        s.window_keys_walked,
        s.queries,
        s.tile_bytes_in_memory,
        r.far_from_deformers,
        r.teleports,
        r.refused,
        r.not_welcomed,
        r.rate_bytes,
        r.rate_tiles,
        r.rate_window,
        r.rate_query,
        r.bad_window,
        r.out_of_bounds,
        r.disk_full,
        r.bad_footprint,
        r.bad_tile,
        r.too_deep,
        r.malformed,
        r.oversized,
        r.rate_presses,
        r.unpressable,
        s.press_frames,
        s.press_casts,
        s.press_frames_sent,
        s.awaiting_presence,
        r.outgoing_dropped
    )
}

/// The world's epoch (Unix seconds) kept in the store, so the world clock
/// goes on across restarts: time passes (and trails refill) while the
/// server is down, as it would for a game world.
fn world_epoch(store: &TileStore) -> anyhow::Result<f64> {
    const NAME: &str = "epoch";
    if let Some(bytes) = store.read_state(NAME)? {
        let raw: [u8; 8] = bytes.as_slice().try_into().map_err(|_| anyhow::anyhow!("{}: the world epoch is damaged", store.dir().display()))?;
        return Ok(f64::from_le_bytes(raw));
    }
    let now = unix_now().as_secs_f64();
    store.write_state(NAME, &now.to_le_bytes())?;
    Ok(now)
}

/// How the server's peers send their analytic presses in `world`, for its
/// first line: as frames where it can press them, or as tiles, and why.
fn presses_phrase(world: &WorldIdentity) -> String {
    let settings = world.settings();
    match snowpack_share::replicate::press::press_ground(world) {
        Some(_) => ", presses travel as frames".to_owned(),
        None if settings.has_snowfall => ", presses go as tiles (lying snow)".to_owned(),
        None if settings.terrain.starts_with("heightmap") => {
            ", presses go as tiles (this server lacks the heightmap the world names: start it with --scene)".to_owned()
        }
        None => ", presses go as tiles (a mesh terrain)".to_owned(),
    }
}

/// Runs `snowpack server` until killed (or `exit_after_s`). Creates no GPU
/// device and loads no graphics library: it merges integers on the CPU.
/// Everything it acknowledges is on disk first, so killing it at any moment
/// loses nothing a client was told is kept.
pub fn serve(opts: &ServerOptions) -> anyhow::Result<()> {
    if opts.key.is_none() && !opts.listen.ip().is_loopback() {
        return Err(BadInput(format!(
            "--listen {}: without --key the server accepts anyone, so it listens on loopback only (127.0.0.1 or ::1); give --key FILE to listen here",
            opts.listen
        ))
        .into());
    }
    let key = opts.key.as_deref().map(read_key).transpose()?;
    let (mut relay, epoch) = open_relay(opts)?;
    let (mut transport, local) = listen(opts.listen, key)?;
    let mut server = RenetServer::new(connection_config());
    say!(
        "snowpack server listening on {local} ({}), tiles in {}, world {}{}",
        if key.is_some() { "connect tokens required" } else { "no key: loopback only" },
        opts.store.display(),
        match (&opts.scene, relay.world().is_some()) {
            (Some(scene), _) => format!("of {}", scene.display()),
            (None, true) => "kept in the store".to_owned(),
            (None, false) => "from the first peer".to_owned(),
        },
        relay.world().map_or(String::new(), presses_phrase)
    );
    let started = Instant::now();
    let mut last = started;
    let mut backlog: std::collections::HashMap<u64, Backlog> = std::collections::HashMap::new();
    let mut last_report = started;
    let mut last_store_error: Option<Instant> = None;
    let mut work = TickWork::default();
    loop {
        let now = Instant::now();
        server.update(now - last);
        if let Err(errors) = transport.update(now - last, &mut server) {
            for e in errors {
                tracing::debug!("netcode: {e}");
            }
        }
        last = now;
        let world_s = unix_now().as_secs_f64() - epoch;
        take_events(&mut server, &mut relay, &mut backlog);
        let before = relay.stats();
        for client_id in server.clients_id() {
            let taken = take_messages(&mut server, &mut relay, client_id, world_s);
            work.max_peer_bytes_in = work.max_peer_bytes_in.max(taken as u64);
            work.capped += u64::from(taken >= TICK_BYTES_PER_CLIENT);
        }
        relay.update(world_s);
        work.tick(&before, &relay.stats());
        // Persisted before anything (acknowledgements included) goes out. A
        // store that fails is said (at most every 10 s); the world goes on
        // in memory.
        if let Err(e) = relay.flush()
            && last_store_error.is_none_or(|t| now - t >= Duration::from_secs(10))
        {
            last_store_error = Some(now);
            eprintln!("snowpack server: the tile store failed, tiles are kept in memory only until it works again: {e}");
        }
        deliver(&mut server, &mut relay, &mut backlog, &mut work);
        transport.send_packets(&mut server);
        if now - last_report >= Duration::from_secs(10) {
            last_report = now;
            say!("{}", work.report(&server, &relay.stats()));
        }
        if opts.exit_after_s.is_some_and(|limit| started.elapsed().as_secs_f64() >= limit) {
            transport.disconnect_all(&mut server);
            relay.flush()?;
            say!("{}", work.closing(started, &relay.stats()));
            return Ok(());
        }
        std::thread::sleep(TICK);
    }
}

/// The server's socket and netcode transport on `addr` (secured with `key`).
fn listen(addr: SocketAddr, key: Option<[u8; NETCODE_KEY_BYTES]>) -> anyhow::Result<(NetcodeServerTransport, SocketAddr)> {
    let socket = UdpSocket::bind(addr).with_context(|| format!("listening on {addr}"))?;
    let local = socket.local_addr()?;
    let setup = ServerSetupConfig {
        current_time: unix_now(),
        // Netcode rejects tokens that expire before start + this: 0 accepts
        // every token still valid, so tokens made before a restart (same key)
        // keep working until they expire.
        max_token_lifetime: 0,
        max_clients: MAX_CLIENTS,
        protocol_id: PROTOCOL_ID,
        socket_addresses: vec![vec![local]],
        authentication: match key {
            Some(private_key) => ServerAuthentication::Secure { private_key },
            None => ServerAuthentication::Unsecure,
        },
    };
    let transport = NetcodeServerTransport::new(setup, NativeSocket::new(socket).context("the server's socket")?)?;
    Ok((transport, local))
}

/// One client's messages into the relay, up to [`TICK_BYTES_PER_CLIENT`]
/// (a message is taken whole, so the last may pass it); returns the bytes
/// taken. The rest stays in its channel for the next tick.
fn take_messages(server: &mut RenetServer, relay: &mut SnowRelay, client_id: u64, world_s: f64) -> usize {
    let mut taken = 0;
    while taken < TICK_BYTES_PER_CLIENT
        && let Some(bytes) = server.receive_message(client_id, CHANNEL)
    {
        taken += bytes.len();
        relay.receive(client_id, &bytes, world_s);
    }
    taken
}

/// Clients that came and went, told to the relay.
fn take_events(server: &mut RenetServer, relay: &mut SnowRelay, backlog: &mut std::collections::HashMap<u64, Backlog>) {
    while let Some(event) = server.get_event() {
        match event {
            ServerEvent::ClientConnected { client_id } => {
                relay.connect(client_id);
                say!("peer {client_id} connected");
            }
            ServerEvent::ClientDisconnected { client_id, reason } => {
                relay.disconnect(client_id);
                backlog.remove(&client_id);
                say!("peer {client_id} left: {reason}");
            }
        }
    }
}

/// The relay's messages into each client's backlog and channel; a client
/// owed more than [`MAX_BACKLOG_BYTES`] (it stopped reading) is disconnected.
fn deliver(server: &mut RenetServer, relay: &mut SnowRelay, backlog: &mut std::collections::HashMap<u64, Backlog>, work: &mut TickWork) {
    while let Some((peer, bytes)) = relay.poll_transmit() {
        backlog.entry(peer).or_default().push(bytes, work);
    }
    for (peer, queue) in backlog.iter_mut() {
        if queue.bytes > MAX_BACKLOG_BYTES {
            // It stopped reading: what it is owed is more than it may cost.
            say!("peer {peer} disconnected: {} bytes waiting for it, over {MAX_BACKLOG_BYTES}", queue.bytes);
            server.disconnect(*peer);
            relay.disconnect(*peer);
            queue.clear();
            work.slow_disconnects += 1;
            continue;
        }
        queue.send(*peer, server);
    }
    backlog.retain(|peer, _| server.is_connected(*peer));
}

/// What the server owes one client while its channel is full.
#[derive(Default)]
struct Backlog {
    queue: VecDeque<Vec<u8>>,
    /// Bytes in `queue`.
    bytes: usize,
}

impl Backlog {
    fn push(&mut self, message: Vec<u8>, work: &mut TickWork) {
        if self.queue.len() >= MAX_BACKLOG
            && let Some(old) = self.queue.pop_front()
        {
            self.bytes -= old.len();
            work.dropped += 1;
        }
        self.bytes += message.len();
        self.queue.push_back(message);
    }

    fn clear(&mut self) {
        self.queue.clear();
        self.bytes = 0;
    }

    /// Moves messages into the client's channel while it has room.
    fn send(&mut self, peer: u64, server: &mut RenetServer) {
        while let Some(bytes) = self.queue.front() {
            if !server.is_connected(peer) {
                self.clear();
                return;
            }
            if !server.can_send_message(peer, CHANNEL, bytes.len()) {
                return;
            }
            let bytes = self.queue.pop_front().unwrap_or_default();
            self.bytes -= bytes.len();
            server.send_message(peer, CHANNEL, bytes);
        }
    }
}

/// The server's work per tick (one pass of its loop), at its largest: what
/// the closing line reports, so tests can bound it without timing anything.
#[derive(Default)]
struct TickWork {
    max_bytes_in: u64,
    /// The most bytes one client's messages brought in one tick (at most
    /// [`TICK_BYTES_PER_CLIENT`] plus one message).
    max_peer_bytes_in: u64,
    /// Ticks in which a client reached [`TICK_BYTES_PER_CLIENT`] (the rest of
    /// what it sent waited for the next tick).
    capped: u64,
    max_distance_tests: u64,
    max_window_keys: u64,
    /// Clients disconnected for not reading.
    slow_disconnects: u64,
    /// Messages dropped from full backlogs.
    dropped: u64,
}

impl TickWork {
    /// The line said every 10 s.
    fn report(&self, server: &RenetServer, s: &RelayStats) -> String {
        format!(
            "snowpack server: {} peers, {} tiles in memory, {} merged of {} received, {} bytes in, {} out, {} refused, {} messages dropped for slow clients; {}",
            server.connected_clients(),
            s.tiles_in_memory,
            s.tiles_merged,
            s.tiles_received,
            s.bytes_in,
            s.bytes_out,
            s.rejected.total(),
            self.dropped,
            stats_fields(s)
        )
    }

    /// The closing line: totals, peak memory, the busiest tick's work.
    fn closing(&self, started: Instant, s: &RelayStats) -> String {
        let (cpu_s, peak_kib) = own_usage();
        format!(
            "snowpack server stopped after {:.1} s: cpu_s={cpu_s:.3} peak_kib={peak_kib} tiles_received={} tiles_merged={} bytes_in={} bytes_out={} rejected={} \
             messages_in={} max_tick_bytes_in={} max_tick_peer_bytes_in={} peer_ticks_capped={} max_tick_distance_tests={} max_tick_window_keys={} slow_disconnects={} backlog_dropped={} {}",
            started.elapsed().as_secs_f64(),
            s.tiles_received,
            s.tiles_merged,
            s.bytes_in,
            s.bytes_out,
            s.rejected.total(),
            s.messages_in,
            self.max_bytes_in,
            self.max_peer_bytes_in,
            self.capped,
            self.max_distance_tests,
            self.max_window_keys,
            self.slow_disconnects,
            self.dropped,
            stats_fields(s)
        )
    }

    fn tick(&mut self, before: &RelayStats, after: &RelayStats) {
        self.max_bytes_in = self.max_bytes_in.max(after.bytes_in - before.bytes_in);
        self.max_distance_tests = self.max_distance_tests.max(after.distance_tests - before.distance_tests);
        self.max_window_keys = self.max_window_keys.max(after.window_keys_walked - before.window_keys_walked);
    }
}

/// This process's CPU time (s, from the scheduler's nanosecond count) and
/// peak resident memory (KiB); zeros where `/proc` does not say.
fn own_usage() -> (f64, u64) {
    let cpu_ns = std::fs::read_to_string("/proc/self/schedstat").ok().and_then(|s| s.split_whitespace().next().and_then(|v| v.parse::<u64>().ok()));
    let peak = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| s.lines().find_map(|l| l.strip_prefix("VmHWM:").and_then(|v| v.split_whitespace().next().and_then(|n| n.parse::<u64>().ok()))));
    (cpu_ns.unwrap_or(0) as f64 * 1e-9, peak.unwrap_or(0))
}

/// `snowpack token`: writes a connect token for the server at `server`
/// (its public address), made from the server's `--key` file.
pub fn make_token(key: &Path, server: SocketAddr, out: &Path) -> anyhow::Result<()> {
    let private_key = read_key(key)?;
    let client_id = random_id();
    let token = ConnectToken::generate(unix_now(), PROTOCOL_ID, TOKEN_LIFETIME_S, client_id, 15, 0, vec![server], None, &private_key)
        .map_err(|e| anyhow::anyhow!("making a connect token: {e}"))?;
    let mut bytes = Vec::new();
    token.write(&mut bytes)?;
    std::fs::write(out, bytes).with_context(|| format!("writing the connect token {}", out.display()))?;
    println!("wrote a connect token for {server} (client {client_id}, valid {} h) to {}", TOKEN_LIFETIME_S / 3600, out.display());
    Ok(())
}

fn random_id() -> u64 {
    // Unique enough among a server's clients: time, process and a counter, mixed.
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mut x =
        unix_now().as_nanos() as u64 ^ (u64::from(std::process::id()) << 32) ^ COUNTER.fetch_add(1, Ordering::Relaxed).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    x ^= x >> 33;
    x = x.wrapping_mul(0xff51_afd7_ed55_8ccd);
    x ^ (x >> 33)
}

/// `snowpack query`: the snow depth and the packed snow in it (m) at
/// `points` (world x, z in m) from the server's merged tiles. The server
/// answers peers of its world only: the query says hello as a peer of
/// `world` first (refused: exit 2).
pub fn query(addr: SocketAddr, token: Option<&Path>, world: &WorldIdentity, points: &[(f64, f64)]) -> anyhow::Result<Vec<Option<(f32, f32)>>> {
    use snowpack_share::replicate::{Message, decode, encode};
    let mut link = Transport::connect(addr, token)?;
    let deadline = Instant::now() + CONNECT_LIMIT;
    let (mut hello, mut welcomed, mut sent) = (false, false, false);
    let mut answers = Vec::with_capacity(points.len());
    // At most MAX_DEFORMERS points a message: the query goes in chunks.
    let chunks: Vec<Vec<[f64; 2]>> = points.chunks(snowpack_share::replicate::message::MAX_DEFORMERS).map(|c| c.iter().map(|p| [p.0, p.1]).collect()).collect();
    while answers.len() < chunks.len() {
        link.update()?;
        if link.client.is_connected() && !hello {
            link.client.send_message(CHANNEL, encode(&Message::Hello { world: world.clone(), name: "snowpack query".to_owned(), presses: false }));
            hello = true;
        }
        if welcomed && !sent {
            for (id, chunk) in chunks.iter().enumerate() {
                link.client.send_message(CHANNEL, encode(&Message::Query { id: id as u32, points: chunk.clone() }));
            }
            sent = true;
        }
        while let Some(bytes) = link.client.receive_message(CHANNEL) {
            match decode(&bytes) {
                Ok(Message::Welcome { .. }) => welcomed = true,
                Ok(Message::Refused { differences }) => return Err(LinkError::Refused { addr, why: differences.join("; ") }.into()),
                Ok(Message::Depths { id, depths, packed }) => answers.push((id, depths, packed)),
                _ => {}
            }
        }
        link.send();
        if Instant::now() > deadline {
            return Err(LinkError::Lost { addr, why: format!("no answer to the query within {CONNECT_LIMIT:?}") }.into());
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    answers.sort_by_key(|a| a.0);
    Ok(answers
        .into_iter()
        .flat_map(|(_, depths, packed)| {
            let n = depths.len();
            depths.into_iter().zip(packed.into_iter().chain(std::iter::repeat(0.0)).take(n))
        })
        .map(|(d, q)| (d.is_finite() && q.is_finite()).then_some((d, q)))
        .collect())
}

/// A renet2 client over netcode, without a peer: the connection itself.
pub(crate) struct Transport {
    addr: SocketAddr,
    pub(crate) client: RenetClient,
    transport: NetcodeClientTransport,
    last: Instant,
}

impl Transport {
    pub(crate) fn connect(addr: SocketAddr, token: Option<&Path>) -> anyhow::Result<Self> {
        // A server on loopback is reached from loopback: nothing else need hear this socket.
        let bind: SocketAddr = match (addr.is_ipv4(), addr.ip().is_loopback()) {
            (true, true) => "127.0.0.1:0",
            (true, false) => "0.0.0.0:0",
            (false, true) => "[::1]:0",
            (false, false) => "[::]:0",
        }
        .parse()?;
        let socket = UdpSocket::bind(bind).context("a UDP socket for --connect")?;
        let authentication = match token {
            Some(path) => {
                let bytes = std::fs::read(path).map_err(|e| BadInput(format!("--token {}: {e}", path.display())))?;
                let connect_token =
                    ConnectToken::read(&mut bytes.as_slice()).map_err(|e| BadInput(format!("--token {}: not a connect token ({e})", path.display())))?;
                ClientAuthentication::Secure { connect_token }
            }
            None => ClientAuthentication::Unsecure { protocol_id: PROTOCOL_ID, client_id: random_id(), socket_id: 0, server_addr: addr, user_data: None },
        };
        let transport = NetcodeClientTransport::new(unix_now(), authentication, NativeSocket::new(socket).context("the client's socket")?)
            .map_err(|e| LinkError::Lost { addr, why: e.to_string() })?;
        Ok(Self { addr, client: RenetClient::new(connection_config(), false), transport, last: Instant::now() })
    }

    /// Takes in what arrived; an error once the connection is gone.
    pub(crate) fn update(&mut self) -> Result<(), LinkError> {
        let now = Instant::now();
        self.client.update(now - self.last);
        let update = self.transport.update(now - self.last, &mut self.client);
        self.last = now;
        if let Err(e) = update {
            return Err(LinkError::Lost { addr: self.addr, why: e.to_string() });
        }
        if self.client.is_disconnected() {
            let why = self.client.disconnect_reason().map_or_else(|| "disconnected".to_owned(), |r| r.to_string());
            return Err(LinkError::Lost { addr: self.addr, why });
        }
        Ok(())
    }

    /// Sends what was queued.
    pub(crate) fn send(&mut self) {
        if let Err(e) = self.transport.send_packets(&mut self.client) {
            tracing::debug!("netcode: {e}");
        }
    }
}

impl Drop for Transport {
    fn drop(&mut self) {
        self.transport.disconnect();
    }
}

/// Why a link to a server failed.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The server serves another world: bad input (exit 2).
    #[error("the server at {addr} refused this world: {why}")]
    Refused {
        /// The server.
        addr: SocketAddr,
        /// What differs, as the server said it.
        why: String,
    },
    /// The connection could not be made or was lost, or a wait ran out.
    #[error("shared snow at {addr}: {why}")]
    Lost {
        /// The server.
        addr: SocketAddr,
        /// What happened.
        why: String,
    },
}

#[cfg(feature = "gpu")]
/// The client side of shared snow: a renet2 connection to a `snowpack
/// server` and the [`SnowPeer`] beside the game's snow. [`Self::pump`]
/// once a frame; it never blocks.
pub struct SnowLink {
    net: Transport,
    /// The replication state machine.
    pub peer: SnowPeer,
    started: Instant,
    /// When the server's welcome arrived.
    welcomed_at: Option<Instant>,
    backlog: VecDeque<Vec<u8>>,
}

#[cfg(feature = "gpu")]
impl SnowLink {
    /// Starts connecting to `addr` (with the connect token in `token` when the
    /// server has a key) as a peer of `world`.
    pub fn connect(addr: SocketAddr, token: Option<&Path>, world: WorldIdentity, name: &str) -> anyhow::Result<Self> {
        Ok(Self {
            net: Transport::connect(addr, token)?,
            peer: SnowPeer::new(world, name, PeerConfig::default()),
            started: Instant::now(),
            welcomed_at: None,
            backlog: VecDeque::new(),
        })
    }

    /// The server's address.
    pub fn addr(&self) -> SocketAddr {
        self.net.addr
    }

    /// Seconds since the link started (the peer's own clock for its timers).
    fn now_s(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// One exchange: what arrived goes to the peer, the peer takes the
    /// snow's changed tiles and merges what came in, and its messages go
    /// out. Never blocks.
    pub fn pump(&mut self, snow: &mut dyn SharedSnow) -> Result<(), LinkError> {
        self.net.update()?;
        let mut refused = None;
        while let Some(bytes) = self.net.client.receive_message(CHANNEL) {
            match self.peer.receive(&bytes).map_err(snowpack_share::error::ShareError::from) {
                Ok(()) => {}
                Err(ShareError::Refused { differences }) => refused = Some(differences.join("; ")),
                Err(e) => tracing::warn!("shared snow: {e}"),
            }
        }
        if let Some(why) = refused {
            return Err(LinkError::Refused { addr: self.net.addr, why });
        }
        let now_s = self.now_s();
        self.peer.update(snow, now_s);
        if self.welcomed_at.is_none() && self.peer.is_welcomed() {
            self.welcomed_at = Some(Instant::now());
        }
        while let Some(bytes) = self.peer.poll_transmit() {
            if self.backlog.len() >= MAX_BACKLOG {
                // Repaired as the server's are: deltas are resent, digests fill in.
                self.backlog.pop_front();
            }
            self.backlog.push_back(bytes);
        }
        if self.net.client.is_connected() {
            while let Some(bytes) = self.backlog.front() {
                if !self.net.client.can_send_message(CHANNEL, bytes.len()) {
                    break;
                }
                let bytes = self.backlog.pop_front().unwrap_or_default();
                self.net.client.send_message(CHANNEL, bytes);
            }
        }
        self.net.send();
        Ok(())
    }

    /// Pumps until the server has welcomed this peer (the world clock is
    /// then the snow's), for at most `limit`.
    pub fn wait_welcomed(&mut self, snow: &mut dyn SharedSnow, limit: Duration) -> Result<(), LinkError> {
        let deadline = Instant::now() + limit;
        while !self.peer.is_welcomed() {
            self.pump(snow)?;
            if Instant::now() > deadline {
                return Err(LinkError::Lost { addr: self.net.addr, why: format!("no answer from the server within {limit:?}") });
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        Ok(())
    }

    /// Messages waiting for room in the connection.
    pub fn backlog(&self) -> usize {
        self.backlog.len()
    }
}

/// How long a run waits for the server's welcome.
const CONNECT_LIMIT: Duration = Duration::from_secs(10);
#[cfg(feature = "gpu")]
/// How long a run waits, at its end, for the server to acknowledge its
/// changes and for its window to hold everything the server has.
const SETTLE_LIMIT: Duration = Duration::from_secs(30);
#[cfg(feature = "gpu")]
/// Changed tiles go out at most this often (world seconds).
pub const SHARE_INTERVAL_S: f64 = 0.25;

#[cfg(feature = "gpu")]
/// Joins the shared world at `addr`: sharing switched on in `snow`, a link
/// made, and the server's welcome awaited (its clock is then the snow's).
pub fn join(ctx: &snowpack::GpuContext, snow: &mut snowpack::SnowDeformation, addr: SocketAddr, token: Option<&Path>, name: &str) -> anyhow::Result<SnowLink> {
    snow.enable_sharing(ctx, DEFAULT_TILE_SIDE, SHARE_INTERVAL_S).context("sharing the snow")?;
    let mut link = SnowLink::connect(addr, token, snow.world_identity(), name)?;
    link.wait_welcomed(snow, CONNECT_LIMIT)?;
    Ok(link)
}

#[cfg(feature = "gpu")]
/// World (x, z) of every deformer and character of `world`: the places
/// where this peer may change the snow (the relay's check).
pub fn deformer_positions(world: &snowpack_scene::World) -> Vec<[f64; 2]> {
    let mut out: Vec<[f64; 2]> = world.deformers().iter().filter_map(deformer_xz).collect();
    out.extend(world.characters().iter().map(|c| {
        let p = c.model.w_axis;
        [f64::from(p.x), f64::from(p.z)]
    }));
    out
}

#[cfg(feature = "gpu")]
/// World (x, z) of a deformer; `None` for a kind added later (no place of
/// its own, so the relay lets it change nothing more).
pub fn deformer_xz(d: &snowpack::Deformer) -> Option<[f64; 2]> {
    use snowpack::Deformer;
    match d {
        Deformer::Sphere { center, .. } | Deformer::Box { center, .. } | Deformer::Wheel { center, .. } => Some([f64::from(center.x), f64::from(center.z)]),
        Deformer::Point { position, .. } => Some([f64::from(position.x), f64::from(position.z)]),
        _ => None,
    }
}

#[cfg(feature = "gpu")]
/// What a run's link did, for `meta.json`'s `share`.
#[derive(Clone, Debug)]
pub struct ShareReport {
    /// The server.
    pub addr: SocketAddr,
    /// Seconds from the link's start to the end of settling.
    pub linked_s: f64,
    /// Seconds the end of the run waited for acknowledgements and merges.
    pub settle_s: f64,
    /// Seconds from the server's welcome to holding everything it has over
    /// the window (for a run that presses little: the late join).
    pub synced_s: f64,
    /// The peer's counters.
    pub stats: snowpack_share::PeerStats,
}

#[cfg(feature = "gpu")]
impl ShareReport {
    /// As `meta.json` holds it.
    pub fn to_json(&self) -> serde_json::Value {
        let s = &self.stats;
        serde_json::json!({
            "server": self.addr.to_string(),
            "linked_s": self.linked_s,
            "settle_s": self.settle_s,
            "synced_s": self.synced_s,
            "tile_bytes_sent": s.tile_bytes_out,
            "bytes_sent": s.bytes_out,
            "bytes_received": s.bytes_in,
            "tiles_sent": s.tiles_sent,
            "tiles_received": s.tiles_received,
            "resends": s.resends,
            "tiles_as_deltas": s.tiles_as_deltas,
            "tiles_as_presses": s.tiles_as_presses,
            "press_frames_sent": s.press_frames_sent,
            "press_frames_received": s.press_frames_received,
            "tiles_from_presses": s.tiles_from_presses,
        })
    }
}

#[cfg(feature = "gpu")]
/// The end of a connected run: frames that press nothing and let no time
/// pass, until every change of this run is acknowledged by the server and
/// everything the server holds for the window is merged into it (exit 1
/// after [`SETTLE_LIMIT`]).
pub fn settle(ctx: &snowpack::GpuContext, snow: &mut snowpack::SnowDeformation, link: &mut SnowLink) -> anyhow::Result<ShareReport> {
    let start = Instant::now();
    let deadline = start + SETTLE_LIMIT;
    loop {
        snow.flush_changed_tiles();
        link.peer.request_digest();
        snow.step(ctx, &[], 0.0)?;
        snow.finish(ctx)?;
        link.pump(snow)?;
        let quiet = link.peer.unacknowledged() == 0 && link.backlog() == 0 && snow.dirty_tiles() == 0 && link.peer.is_synced() && snow.waiting_tiles() == 0;
        if quiet {
            break;
        }
        if Instant::now() > deadline {
            return Err(LinkError::Lost {
                addr: link.addr(),
                why: format!(
                    "the server did not acknowledge this run's changes within {SETTLE_LIMIT:?} ({} unacknowledged, {} unsent)",
                    link.peer.unacknowledged(),
                    link.backlog()
                ),
            }
            .into());
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    Ok(ShareReport {
        addr: link.addr(),
        linked_s: link.started.elapsed().as_secs_f64(),
        settle_s: start.elapsed().as_secs_f64(),
        synced_s: link.welcomed_at.map_or(0.0, |t| t.elapsed().as_secs_f64()),
        stats: link.peer.stats(),
    })
}
