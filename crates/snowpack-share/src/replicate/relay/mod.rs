//! [`SnowRelay`]: what a server runs. Its world is pinned by the server
//! ([`SnowRelay::pin_world`]), or else learnt from its store or the first
//! peer, and never redefined; it merges the tiles peers send into its own copy,
//! relays merged tiles to the peers whose windows overlap them, answers
//! digests so lost messages are repaired, and keeps the tiles in a
//! [`TileStore`] when it has one. CPU only; no sockets (the caller moves
//! bytes: [`SnowRelay::receive`] in, [`SnowRelay::poll_transmit`] out).
//!
//! A relay trusts no peer: a peer's tile is merged only near where that
//! peer's deformers were in the last 30 s (positions held to a top speed,
//! `motion.rs`), only inside the world, only while the store has room for
//! a new tile, only if it is no deeper than the
//! snow there and holds no more snowfall than has fallen, only if its
//! clock is not ahead of the world's by more than 5 s, and only within the
//! peer's byte and tile rates. Everything refused is counted
//! ([`RelayStats::rejected`]) and changes nothing.

use crate::persist::TileStoreExt;
use crate::replicate::WorldIdentityExt;
use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet, HashMap, HashSet, VecDeque};

use crate::SNOW_QUANTUM_M;
use crate::persist::{SnowClock, StoreError, TileData, TileKey, TileStore};

use super::ShareError;
use super::message::{
    MAX_KEYS, MAX_MESSAGE_BYTES, MAX_MESSAGE_TEXELS, MAX_TILE_SIDE, MAX_TILES, MIN_TILE_SIDE, Message, MessageError, TILES_OVERHEAD_BYTES, decode,
    decode_world, encode, encode_tile, encode_world, tiles_message,
};
use super::motion::{MotionHistory, MotionWork};
use super::tile::{CatchUp, NO_STAMP, ShareClock, SharedTile};
use super::world::WorldIdentity;

/// A peer as the caller knows it (a connection number).
pub type PeerId = u64;

/// The most tiles a peer's interest (window plus margin) may cover: bounds
/// what one `Presence` or `Digest` makes the relay walk and remember.
pub const MAX_INTEREST_TILES: usize = 16_384;

/// The state name the relay's world is saved under in its store.
pub const WORLD_STATE: &str = "world";

/// The state name the world's epoch (f64 Unix seconds, little-endian) is saved under ([`SnowRelay::world_epoch`]).
pub const EPOCH_STATE: &str = "epoch";

/// Marks, in a stored tile's snow plane, a tile without a footprint plane
/// (bit 16 of every texel; the deficit takes bits 0..16). The store's
/// format always has a footprint plane, so this keeps "none" apart from
/// "all empty", which digest differently.
const NO_STAMP_PLANE: u32 = 1 << 16;

/// How a relay paces and polices its peers. Rates are per peer.
#[derive(Clone, Debug, PartialEq)]
pub struct RelayConfig {
    /// How far (m) from one of a peer's recent deformers a tile it sends may
    /// be (plus the tile's half diagonal).
    pub accept_radius_m: f32,
    /// Bytes a second a peer may send (a token bucket).
    pub bytes_per_s: u32,
    /// The byte bucket's size: the most a peer may send at once.
    pub burst_bytes: u32,
    /// Tiles a second a peer may send (a token bucket).
    pub tiles_per_s: u32,
    /// The tile bucket's size.
    pub burst_tiles: u32,
    /// The least time (s) between two sends of relayed tiles to one peer:
    /// changes to a tile in between are coalesced into one send.
    pub send_interval_s: f64,
    /// Bytes a second the relay sends one peer (relayed tiles and the
    /// late join's backlog; small messages are not counted).
    pub send_bytes_per_s: u32,
    /// The outgoing byte bucket's size. When full it lets one tile through
    /// whatever its size, so a budget smaller than a tile still progresses.
    pub send_burst_bytes: u32,
    /// Tiles the relay keeps in memory; beyond it the least recently merged or loaded
    /// are written to the store and dropped (without a store, dropped and
    /// counted in [`RelayStats::tiles_forgotten`]).
    pub memory_tiles: usize,
    /// Messages queued for one peer; beyond it the oldest is dropped and
    /// counted (the digests repair what a peer missed).
    pub queue_messages: usize,
    /// Seconds between two `Clock` broadcasts.
    pub clock_interval_s: f64,
    /// Seconds between two writes of changed tiles to the store.
    pub persist_interval_s: f64,
    /// How far (s) a tile's clock may be ahead of the world's.
    pub max_clock_lead_s: f64,
    /// How long (s) a reported deformer position lets its peer write near it.
    pub deformer_memory_s: f64,
    /// How fast (m/s) a peer's own deformers may move between two of its
    /// reports; a position farther from the last accepted one is refused
    /// (counted in [`RelayRejections::teleports`]) and lets the peer write
    /// nothing there. 60 m/s fits vehicles; raise it for projectiles. Not
    /// applied to positions a game server reports ([`SnowRelay::report_deformers`]).
    pub max_speed_m_per_s: f64,
    /// Tiles a second a peer's window changes may make the relay walk (a
    /// token bucket; the first window of up to [`MAX_INTEREST_TILES`] always fits).
    pub window_keys_per_s: u32,
    /// The window bucket's size.
    pub burst_window_keys: u32,
    /// Points a second a peer may ask the depth of (`Query`, a token bucket).
    pub query_points_per_s: u32,
    /// The query bucket's size.
    pub burst_query_points: u32,
    /// Bytes of tiles the relay keeps in memory (their planes and cached
    /// encodings); beyond it, as beyond `memory_tiles`, the least recently
    /// used go to the store.
    pub memory_bytes: usize,
    /// Bytes queued for one peer; beyond it the oldest messages are dropped
    /// (with `queue_messages`, whichever comes first).
    pub queue_bytes: usize,
    /// The world's bounds in metres, `[x0, z0, x1, z1]`: tiles not within
    /// them are refused ([`RelayRejections::out_of_bounds`]). Whatever this
    /// says, tiles whose texels do not fit in i32 (where no window can be)
    /// are refused.
    pub bounds_m: Option<[f64; 4]>,
}

impl Default for RelayConfig {
    fn default() -> Self {
        Self {
            accept_radius_m: 6.0,
            bytes_per_s: 256 * 1024,
            burst_bytes: 1024 * 1024,
            tiles_per_s: 256,
            burst_tiles: 512,
            send_interval_s: 0.2,
            send_bytes_per_s: 256 * 1024,
            send_burst_bytes: 256 * 1024,
            memory_tiles: 16_384,
            queue_messages: 256,
            clock_interval_s: 1.0,
            persist_interval_s: 5.0,
            max_clock_lead_s: 5.0,
            deformer_memory_s: 30.0,
            max_speed_m_per_s: 60.0,
            window_keys_per_s: 4 * MAX_INTEREST_TILES as u32,
            burst_window_keys: 2 * MAX_INTEREST_TILES as u32,
            query_points_per_s: 1024,
            burst_query_points: 4096,
            memory_bytes: 256 << 20,
            queue_bytes: 4 << 20,
            bounds_m: None,
        }
    }
}

/// Everything a relay refused or dropped, by cause. Each refusal changed nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RelayRejections {
    /// Messages that did not decode.
    pub malformed: u64,
    /// Messages over [`MAX_MESSAGE_BYTES`].
    pub oversized: u64,
    /// Messages from a peer that is not connected.
    pub unknown_peer: u64,
    /// Messages other than `Hello` from a peer not (yet) welcomed.
    pub not_welcomed: u64,
    /// `Hello`s of another world (answered with `Refused`).
    pub refused: u64,
    /// Messages only the relay sends (`Welcome`, `Ack`, ...) sent to it.
    pub unexpected_kind: u64,
    /// `Presence` or `Digest` windows too large or impossible.
    pub bad_window: u64,
    /// Messages over the peer's byte rate.
    pub rate_bytes: u64,
    /// Tiles over the peer's tile rate.
    pub rate_tiles: u64,
    /// Tiles of another side or with planes the world has not.
    pub bad_tile: u64,
    /// Tiles not near any of the sender's recent deformers.
    pub far_from_deformers: u64,
    /// Tiles with a deficit deeper than the snow.
    pub too_deep: u64,
    /// Tiles with more snowfall than has fallen (or not a number).
    pub too_much_snowfall: u64,
    /// Tiles with a clock ahead of the world's by more than the lead allowed.
    pub clock_ahead: u64,
    /// Outgoing messages dropped from a full queue.
    pub outgoing_dropped: u64,
    /// Tiles too large to send in one message even alone.
    pub tile_too_large: u64,
    /// Deformer positions farther from the peer's last ones than its top speed allows.
    pub teleports: u64,
    /// Tiles outside the world's bounds.
    pub out_of_bounds: u64,
    /// New tiles refused because the store's disk budget is spent (tiles
    /// already kept still merge).
    pub disk_full: u64,
    /// Window changes over the peer's window rate.
    pub rate_window: u64,
    /// `Query`s over the peer's query rate.
    pub rate_query: u64,
    /// Tiles whose footprint plane holds a footprint no deformer makes
    /// (its foot above its top).
    pub bad_footprint: u64,
}

impl RelayRejections {
    /// All refusals and drops together.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.malformed
            + self.oversized
            + self.unknown_peer
            + self.not_welcomed
            + self.refused
            + self.unexpected_kind
            + self.bad_window
            + self.rate_bytes
            + self.rate_tiles
            + self.bad_tile
            + self.far_from_deformers
            + self.too_deep
            + self.too_much_snowfall
            + self.clock_ahead
            + self.outgoing_dropped
            + self.tile_too_large
            + self.teleports
            + self.out_of_bounds
            + self.disk_full
            + self.rate_window
            + self.rate_query
            + self.bad_footprint
    }
}

/// A relay's counters since it was made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RelayStats {
    /// Peers connected now.
    pub peers: usize,
    /// Tiles in memory now.
    pub tiles_in_memory: usize,
    /// Messages received.
    pub messages_in: u64,
    /// Messages handed out by [`SnowRelay::poll_transmit`].
    pub messages_out: u64,
    /// Bytes received.
    pub bytes_in: u64,
    /// Bytes handed out.
    pub bytes_out: u64,
    /// Tiles received from peers (accepted or not).
    pub tiles_received: u64,
    /// Received tiles that changed the relay's copy.
    pub tiles_merged: u64,
    /// Tiles sent to peers.
    pub tiles_sent: u64,
    /// Depth queries answered.
    pub queries: u64,
    /// Tiles written to the store.
    pub tiles_persisted: u64,
    /// Tiles read back from the store.
    pub tiles_loaded: u64,
    /// Tiles dropped from memory (after writing them to the store).
    pub tiles_evicted: u64,
    /// Tiles dropped from memory with no store to keep them: lost.
    pub tiles_forgotten: u64,
    /// Store reads or writes that failed (the relay goes on; `flush` reports the error).
    pub store_errors: u64,
    /// What was refused, by cause.
    pub rejected: RelayRejections,
    /// Distance tests (or grid look-ups) made judging where peers may write
    /// and how far their deformers moved: the police's work, bounded per
    /// message by the message's size.
    pub distance_tests: u64,
    /// Tile keys walked for window changes.
    pub window_keys_walked: u64,
    /// Bytes of tiles in memory now.
    pub tile_bytes_in_memory: usize,
    /// Bytes queued for peers now (not yet handed out).
    pub queued_bytes: usize,
}

/// A token bucket.
#[derive(Clone, Copy, Debug)]
struct Bucket {
    tokens: f64,
    at: f64,
}

impl Bucket {
    fn full(burst: f64, now: f64) -> Self {
        Self { tokens: burst, at: now }
    }

    /// Refills at `rate` up to `burst` for the time since the last call; the tokens now.
    fn refill(&mut self, now: f64, rate: f64, burst: f64) -> f64 {
        let dt = (now - self.at).max(0.0);
        self.tokens = (self.tokens + dt * rate).min(burst);
        self.at = self.at.max(now);
        self.tokens
    }

    /// Takes `amount` tokens if there are that many after refilling at `rate` up to `burst`.
    fn take(&mut self, now: f64, rate: f64, burst: f64, amount: f64) -> bool {
        if self.refill(now, rate, burst) >= amount {
            self.tokens -= amount;
            true
        } else {
            false
        }
    }
}

/// Tile keys `col0..=col1` × `row0..=row1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct KeyRect {
    col: [i64; 2],
    row: [i64; 2],
}

impl KeyRect {
    /// The tiles overlapping a window, grown by `margin` tiles; `None` when
    /// empty, impossibly placed or larger than [`MAX_INTEREST_TILES`].
    fn of_window(first: [i64; 2], resolution: u32, side: u32, margin: i64) -> Option<Self> {
        if resolution == 0 {
            return None;
        }
        let last = [first[0].checked_add(i64::from(resolution) - 1)?, first[1].checked_add(i64::from(resolution) - 1)?];
        let a = TileKey::containing(first[0], first[1], side);
        let b = TileKey::containing(last[0], last[1], side);
        let rect = Self { col: [a.col.checked_sub(margin)?, b.col.checked_add(margin)?], row: [a.row.checked_sub(margin)?, b.row.checked_add(margin)?] };
        let cols = usize::try_from(rect.col[1] - rect.col[0] + 1).ok()?;
        let rows = usize::try_from(rect.row[1] - rect.row[0] + 1).ok()?;
        (cols.checked_mul(rows)? <= MAX_INTEREST_TILES).then_some(rect)
    }

    fn contains(&self, k: TileKey) -> bool {
        (self.col[0]..=self.col[1]).contains(&k.col) && (self.row[0]..=self.row[1]).contains(&k.row)
    }

    fn keys(&self) -> impl Iterator<Item = TileKey> + '_ {
        (self.row[0]..=self.row[1]).flat_map(move |row| (self.col[0]..=self.col[1]).map(move |col| TileKey::new(col, row)))
    }

    /// Twice the centre, in tile units (integers, no overflow for real windows).
    fn centre2(&self) -> [i128; 2] {
        [i128::from(self.col[0]) + i128::from(self.col[1]), i128::from(self.row[0]) + i128::from(self.row[1])]
    }
}

/// Where a peer is in the handshake.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Standing {
    New,
    Welcomed,
    Refused,
}

/// What the relay keeps per peer; every collection in it is capped.
#[derive(Debug)]
struct PeerState {
    number: u32,
    standing: Standing,
    /// Tiles the peer is sent (its window plus one tile of margin).
    interest: Option<KeyRect>,
    /// Where its deformers were, in a grid hash.
    history: MotionHistory,
    /// Until when `report_deformers` overrides the peer's own `Presence`.
    authoritative_until: f64,
    in_bytes: Bucket,
    in_tiles: Bucket,
    out_bytes: Bucket,
    window_keys: Bucket,
    query_points: Bucket,
    /// Bytes in `queue`.
    queued: usize,
    /// Tiles to send at the next send (coalesced).
    pending: BTreeSet<TileKey>,
    last_send_s: f64,
    queue: VecDeque<Vec<u8>>,
    seq_out: u64,
}

/// A tile in the relay's memory.
#[derive(Debug)]
struct Held {
    tile: SharedTile,
    /// Changed since it was last written to the store.
    dirty: bool,
    /// When it was last merged into or loaded, on the relay's own counter (for eviction).
    used: u64,
    /// The tile as [`encode_tile`] writes it, kept between merges: every
    /// peer interested in a change is sent the same bytes.
    encoded: Option<Vec<u8>>,
    /// Bytes counted for it in [`SnowRelay::stats`]'s `tile_bytes_in_memory`.
    bytes: usize,
}

/// The relay: see the module documentation.
#[derive(Debug)]
pub struct SnowRelay {
    config: RelayConfig,
    /// In a cell so the read-only queries can read evicted tiles back.
    store: RefCell<Option<TileStore>>,
    world: Option<WorldIdentity>,
    tiles: HashMap<TileKey, Held>,
    use_counter: u64,
    peers: BTreeMap<PeerId, PeerState>,
    next_number: u32,
    now_s: f64,
    last_clock_s: f64,
    last_persist_s: f64,
    /// The peer `poll_transmit` served last (round robin).
    last_served: Option<PeerId>,
    stats: RelayStats,
    /// When the relay last logged that its store's disk budget is spent.
    last_full_warning_s: f64,
}

impl SnowRelay {
    /// A relay that keeps its tiles in memory; the world comes from the first `Hello`.
    #[must_use]
    pub fn new(config: RelayConfig) -> Self {
        Self {
            config,
            store: RefCell::new(None),
            world: None,
            tiles: HashMap::new(),
            use_counter: 0,
            peers: BTreeMap::new(),
            next_number: 1,
            now_s: 0.0,
            last_clock_s: f64::NEG_INFINITY,
            last_persist_s: 0.0,
            last_served: None,
            stats: RelayStats::default(),
            last_full_warning_s: f64::NEG_INFINITY,
        }
    }

    /// A relay that keeps its tiles in `store`, resuming the world saved
    /// there (if any; tiles are read back when they are needed). The
    /// store's tile files hold deficits (see `tile_to_data`), not the
    /// heights snowpack's `TileStreamer` keeps: give a relay
    /// a directory of its own.
    pub fn with_store(store: TileStore, config: RelayConfig) -> Result<Self, crate::ShareError> {
        let world = match store.read_state(WORLD_STATE)? {
            Some(bytes) => {
                let world = decode_world(&bytes).map_err(|e| ShareError::StoreWorld(format!("the saved world does not decode: {e}")))?;
                if world.settings.tile_side != store.side() {
                    return Err(ShareError::StoreWorld(format!(
                        "the saved world has {}² tiles, the store holds {}² tiles",
                        world.settings.tile_side,
                        store.side()
                    ))
                    .into());
                }
                Some(world)
            }
            None => None,
        };
        let mut relay = Self::new(config);
        relay.world = world;
        relay.store = RefCell::new(Some(store));
        Ok(relay)
    }

    /// Makes `world` the relay's before any peer says hello: a peer of
    /// another world is refused, the first one included, and no peer ever
    /// redefines it. A relay whose store holds another world refuses it
    /// ([`ShareError::StoreWorld`], naming each difference, "here" being the
    /// store's and "there" `world`); otherwise the world is saved there.
    pub fn pin_world(&mut self, world: WorldIdentity) -> Result<(), crate::ShareError> {
        let mut problems = world_problems(&world);
        if let Some(side) = self.store.get_mut().as_ref().map(TileStore::side).filter(|&s| s != world.settings.tile_side) {
            problems.push(format!("tile side: {side} here (the store's tiles), {} there", world.settings.tile_side));
        }
        if let Some(saved) = &self.world {
            problems.extend(saved.differences(&world));
        }
        if !problems.is_empty() {
            return Err(ShareError::StoreWorld(problems.join("; ")).into());
        }
        if let Some(store) = self.store.get_mut().as_ref() {
            store.write_state(WORLD_STATE, &encode_world(&world)).map_err(ShareError::Store)?;
        }
        self.world = Some(world);
        Ok(())
    }

    /// When the world began (s since the Unix epoch), so its clock goes on
    /// across restarts: read from the relay's store (the `epoch` state,
    /// where `snowpack server` keeps it too), or `now_unix_s` written there
    /// the first time. Without a store, `now_unix_s`. World time is then
    /// the Unix time less this.
    pub fn world_epoch(&mut self, now_unix_s: f64) -> Result<f64, crate::ShareError> {
        let Some(store) = self.store.get_mut().as_ref() else {
            return Ok(now_unix_s);
        };
        if let Some(bytes) = store.read_state(EPOCH_STATE).map_err(ShareError::Store)? {
            let raw: [u8; 8] = bytes.as_slice().try_into().map_err(|_| ShareError::StoreWorld(format!("the world epoch is {} bytes, not 8", bytes.len())))?;
            return Ok(f64::from_le_bytes(raw));
        }
        store.write_state(EPOCH_STATE, &now_unix_s.to_le_bytes()).map_err(ShareError::Store)?;
        Ok(now_unix_s)
    }

    /// Changes how the relay paces and polices its peers, from the next
    /// message on (a game server's settings changed while it runs); the
    /// peers' buckets keep what they hold, refilled at the new rates.
    pub fn set_config(&mut self, config: RelayConfig) {
        self.config = config;
    }

    /// How the relay paces and polices its peers now.
    #[must_use]
    pub fn config(&self) -> &RelayConfig {
        &self.config
    }

    /// A peer connected (its messages are accepted from now on).
    pub fn connect(&mut self, peer: PeerId) {
        let now = self.now_s;
        let c = &self.config;
        let number = self.next_number;
        let entry = self.peers.entry(peer);
        if let std::collections::btree_map::Entry::Vacant(v) = entry {
            v.insert(PeerState {
                number,
                standing: Standing::New,
                interest: None,
                history: MotionHistory::default(),
                authoritative_until: f64::NEG_INFINITY,
                in_bytes: Bucket::full(f64::from(c.burst_bytes), now),
                in_tiles: Bucket::full(f64::from(c.burst_tiles), now),
                out_bytes: Bucket::full(f64::from(c.send_burst_bytes), now),
                window_keys: Bucket::full(f64::from(c.burst_window_keys.max(MAX_INTEREST_TILES as u32)), now),
                query_points: Bucket::full(f64::from(c.burst_query_points), now),
                queued: 0,
                pending: BTreeSet::new(),
                last_send_s: f64::NEG_INFINITY,
                queue: VecDeque::new(),
                seq_out: 0,
            });
            self.next_number = self.next_number.wrapping_add(1);
        }
    }

    /// A peer left; what was queued for it is dropped.
    pub fn disconnect(&mut self, peer: PeerId) {
        self.peers.remove(&peer);
    }

    /// Handles one message from `peer` at world time `now_s` (s). Never
    /// panics; anything malformed, oversized or refused is counted in
    /// [`SnowRelay::stats`] and changes nothing.
    pub fn receive(&mut self, peer: PeerId, bytes: &[u8], now_s: f64) {
        let now = self.advance(now_s);
        self.stats.messages_in += 1;
        self.stats.bytes_in += bytes.len() as u64;
        let (rate, burst) = (f64::from(self.config.bytes_per_s), f64::from(self.config.burst_bytes));
        let Some(p) = self.peers.get_mut(&peer) else {
            self.stats.rejected.unknown_peer += 1;
            return;
        };
        // Refused before the budget is charged: a peer's one oversized
        // message should not also starve its next ones.
        if bytes.len() > MAX_MESSAGE_BYTES {
            self.stats.rejected.oversized += 1;
            return;
        }
        if !p.in_bytes.take(now, rate, burst, bytes.len() as f64) {
            self.stats.rejected.rate_bytes += 1;
            return;
        }
        let message = match decode(bytes) {
            Ok(m) => m,
            Err(MessageError::Oversized { .. }) => {
                self.stats.rejected.oversized += 1;
                return;
            }
            Err(_) => {
                self.stats.rejected.malformed += 1;
                return;
            }
        };
        if let Message::Hello { world, .. } = message {
            self.hello(peer, &world, now);
            return;
        }
        // Queries too: only a peer of this world may read it.
        if p.standing != Standing::Welcomed {
            self.stats.rejected.not_welcomed += 1;
            return;
        }
        match message {
            Message::Query { id, points } => self.query(peer, id, &points, now),
            Message::Presence { window, resolution, deformers } => self.presence(peer, window, resolution, &deformers, now),
            Message::Tiles { seq, tiles } => {
                self.tiles_from(peer, &tiles, now);
                self.enqueue(peer, encode(&Message::Ack { seq }));
            }
            Message::Digest { clock, window, resolution, entries } => self.digest_from(peer, &clock, window, resolution, &entries),
            _ => self.stats.rejected.unexpected_kind += 1,
        }
    }

    /// Sends what is due at world time `now_s`: relayed tiles (each peer at
    /// most every `send_interval_s`, within its byte rate), clock
    /// broadcasts, changed tiles to the store every `persist_interval_s`,
    /// and tiles beyond `memory_tiles` out of memory.
    pub fn update(&mut self, now_s: f64) {
        let now = self.advance(now_s);
        let Some(world) = self.world.clone() else {
            return;
        };
        if now - self.last_clock_s >= self.config.clock_interval_s {
            self.last_clock_s = now;
            let bytes = encode(&Message::Clock { clock: world.clock_at(now) });
            let ids: Vec<PeerId> = self.peers.iter().filter(|(_, p)| p.standing == Standing::Welcomed).map(|(&id, _)| id).collect();
            for id in ids {
                self.enqueue(id, bytes.clone());
            }
        }
        let ids: Vec<PeerId> = self.peers.keys().copied().collect();
        for id in ids {
            self.send_pending(id, now);
        }
        if self.store.get_mut().is_some() && now - self.last_persist_s >= self.config.persist_interval_s {
            self.last_persist_s = now;
            // Counted in the stats; the next persist or `flush` tries again.
            let _ = self.flush();
        }
        self.trim_memory();
    }

    /// The next message to send, and to whom (peers served in turn).
    pub fn poll_transmit(&mut self) -> Option<(PeerId, Vec<u8>)> {
        let start = self.last_served;
        let after = start.map_or(self.peers.range(..), |s| self.peers.range((std::ops::Bound::Excluded(s), std::ops::Bound::Unbounded)));
        let before = start.map(|s| self.peers.range(..=s));
        let id = after.chain(before.into_iter().flatten()).find(|(_, p)| !p.queue.is_empty()).map(|(&id, _)| id)?;
        let p = self.peers.get_mut(&id)?;
        let bytes = p.queue.pop_front()?;
        p.queued -= bytes.len();
        self.last_served = Some(id);
        self.stats.messages_out += 1;
        self.stats.bytes_out += bytes.len() as u64;
        Some((id, bytes))
    }

    /// Where `peer`'s deformers are (world x, z in m), from a game server
    /// that knows: for the next `deformer_memory_s` this replaces what the
    /// peer's own `Presence` says when judging where it may write.
    pub fn report_deformers(&mut self, peer: PeerId, world_xz: &[[f64; 2]]) {
        let now = self.now_s;
        let memory = self.config.deformer_memory_s;
        let reach = self.world.as_ref().map_or(0.0, |w| self.write_reach(w, now).0);
        if let Some(p) = self.peers.get_mut(&peer) {
            if p.authoritative_until < now {
                // The peer's own claims stop counting once a server speaks for it.
                p.history.clear();
            }
            p.authoritative_until = now + memory;
            p.history.authoritative(world_xz, now, reach, memory);
        }
    }

    /// Snow depth (m) at world (`x_m`, `z_m`) from the merged tiles, caught
    /// up to the latest time the relay was given; untouched snow is the
    /// rest depth plus the snowfall so far. `None` before the relay has a
    /// world (or for a position that is not a number).
    #[must_use]
    pub fn depth_at(&self, x_m: f64, z_m: f64) -> Option<f32> {
        self.column_at(x_m, z_m).map(|(depth, _)| depth)
    }

    /// The snow depth (m) and the packed snow in it (m of fresh snow
    /// squeezed into the column, `docs/mechanics.md`) at world (`x_m`,
    /// `z_m`), as [`SnowRelay::depth_at`] finds the depth: with the world's
    /// densities they give the column's mass, density and hardness
    /// (`snowpack_share::mechanics`).
    #[must_use]
    pub fn column_at(&self, x_m: f64, z_m: f64) -> Option<(f32, f32)> {
        let world = self.world.as_ref()?;
        let texel = f64::from(world.settings.texel_m);
        let (fx, fz) = ((x_m / texel).floor(), (z_m / texel).floor());
        if !fx.is_finite() || !fz.is_finite() {
            return None;
        }
        let (col, row) = (fx as i64, fz as i64);
        let side = world.settings.tile_side;
        let key = TileKey::containing(col, row, side);
        let clock = world.clock_at(self.now_s);
        let Some(mut tile) = self.tile(key) else {
            return Some((world.settings.depth_m + clock.fallen_m, 0.0));
        };
        if clock.covers(&tile.clock) {
            tile.catch_up(&clock, CatchUp { max_fallen_m: world.settings.max_fallen_m });
        }
        let first = key.first_texel(side);
        let (x, z) = ((col - first[0]) as usize, (row - first[1]) as usize);
        Some((tile.depth_at(x, z, world.settings.depth_m), tile.packed_at(x, z)))
    }

    /// The world, once learnt.
    #[must_use]
    pub fn world(&self) -> Option<&WorldIdentity> {
        self.world.as_ref()
    }

    /// The world clock at `now_s` (the world identity's clock at that time).
    #[must_use]
    pub fn clock(&self, now_s: f64) -> Option<ShareClock> {
        self.world.as_ref().map(|w| w.clock_at(now_s))
    }

    /// The relay's copy of a tile, as merged (at its own clock), from memory
    /// or the store.
    #[must_use]
    pub fn tile(&self, key: TileKey) -> Option<SharedTile> {
        if let Some(h) = self.tiles.get(&key) {
            return Some(h.tile.clone());
        }
        let mut store = self.store.borrow_mut();
        let data = store.as_mut()?.read(key).ok()??;
        tile_from_data(data).ok()
    }

    /// The keys of every tile the relay holds (in memory or in its store).
    #[must_use]
    pub fn tile_keys(&self) -> Vec<TileKey> {
        let mut keys: BTreeSet<TileKey> = self.tiles.keys().copied().collect();
        if let Some(store) = self.store.borrow().as_ref() {
            keys.extend(store.keys());
        }
        keys.into_iter().collect()
    }

    /// Counters since the relay was made.
    #[must_use]
    pub fn stats(&self) -> RelayStats {
        RelayStats {
            peers: self.peers.len(),
            tiles_in_memory: self.tiles.len(),
            tile_bytes_in_memory: self.tiles.values().map(|h| h.bytes).sum(),
            queued_bytes: self.peers.values().map(|p| p.queued).sum(),
            ..self.stats
        }
    }

    /// Writes every changed tile to the store (nothing without one). The
    /// first error is returned after trying them all; failed tiles stay
    /// changed and are tried again.
    pub fn flush(&mut self) -> Result<(), crate::ShareError> {
        let Some(store) = self.store.get_mut().as_mut() else {
            return Ok(());
        };
        let mut first = None;
        let mut refused = Vec::new();
        for (key, held) in self.tiles.iter_mut().filter(|(_, h)| h.dirty) {
            match store.write(&tile_to_data(&held.tile)) {
                Ok(()) => {
                    held.dirty = false;
                    self.stats.tiles_persisted += 1;
                }
                Err(e) if is_full(&e) => refused.push(*key),
                Err(e) => {
                    self.stats.store_errors += 1;
                    first.get_or_insert(e);
                }
            }
        }
        // New tiles past the disk budget (others of the same tick took the
        // last bytes) are dropped, as they would have been at their merge.
        for key in refused {
            self.tiles.remove(&key);
            self.stats.rejected.disk_full += 1;
        }
        first.map_or(Ok(()), |e| Err(ShareError::Store(e).into()))
    }

    /// Takes a new time, ignoring one that is not a number.
    fn advance(&mut self, now_s: f64) -> f64 {
        if now_s.is_finite() {
            self.now_s = now_s;
        }
        self.now_s
    }

    /// Queues `bytes` for `peer`, dropping its oldest message when full.
    fn enqueue(&mut self, peer: PeerId, bytes: Vec<u8>) {
        let cap = self.config.queue_messages.max(1);
        let cap_bytes = self.config.queue_bytes;
        if let Some(p) = self.peers.get_mut(&peer) {
            while !p.queue.is_empty() && (p.queue.len() >= cap || p.queued + bytes.len() > cap_bytes) {
                if let Some(old) = p.queue.pop_front() {
                    p.queued -= old.len();
                }
                self.stats.rejected.outgoing_dropped += 1;
            }
            p.queued += bytes.len();
            p.queue.push_back(bytes);
        }
    }

    fn hello(&mut self, peer: PeerId, theirs: &WorldIdentity, now: f64) {
        if self.world.is_none() {
            let store_side = self.store.get_mut().as_ref().map(TileStore::side);
            let mut problems = world_problems(theirs);
            if let Some(side) = store_side.filter(|&s| s != theirs.settings.tile_side) {
                problems.push(format!("tile side: {} here, {side} there (the relay's store)", theirs.settings.tile_side));
            }
            if problems.is_empty() {
                if let Some(store) = self.store.get_mut().as_ref()
                    && store.write_state(WORLD_STATE, &encode_world(theirs)).is_err()
                {
                    self.stats.store_errors += 1;
                }
                self.world = Some(theirs.clone());
            } else {
                self.refuse(peer, problems);
                return;
            }
        }
        let Some(world) = self.world.as_ref() else {
            return;
        };
        let differences = theirs.differences(world);
        if !differences.is_empty() {
            self.refuse(peer, differences);
            return;
        }
        let clock = world.clock_at(now);
        if let Some(p) = self.peers.get_mut(&peer) {
            p.standing = Standing::Welcomed;
            let number = p.number;
            self.enqueue(peer, encode(&Message::Welcome { peer: number, clock }));
        }
    }

    fn refuse(&mut self, peer: PeerId, differences: Vec<String>) {
        self.stats.rejected.refused += 1;
        if let Some(p) = self.peers.get_mut(&peer) {
            p.standing = Standing::Refused;
        }
        self.enqueue(peer, encode(&Message::Refused { differences }));
    }

    fn presence(&mut self, peer: PeerId, window: [i64; 2], resolution: u32, deformers: &[[f64; 2]], now: f64) {
        let Some(world) = self.world.clone() else {
            return;
        };
        let Some(rect) = KeyRect::of_window(window, resolution, world.settings.tile_side, 1) else {
            self.stats.rejected.bad_window += 1;
            return;
        };
        let (reach, _) = self.write_reach(&world, now);
        let c = &self.config;
        let (memory, speed) = (c.deformer_memory_s, c.max_speed_m_per_s);
        let (rate, burst) = (f64::from(c.window_keys_per_s), f64::from(c.burst_window_keys.max(MAX_INTEREST_TILES as u32)));
        let Some(p) = self.peers.get_mut(&peer) else {
            return;
        };
        if p.authoritative_until < now {
            let work = p.history.report(deformers, now, speed, reach, memory);
            self.count(work);
        }
        let Some(p) = self.peers.get_mut(&peer) else {
            return;
        };
        if p.interest == Some(rect) {
            return;
        }
        // A change walks the new window's keys: paced, so flipping between
        // two far windows costs the flipper, not everyone.
        let walk = rect.keys().count() as f64;
        if !p.window_keys.take(now, rate, burst, walk) {
            self.stats.rejected.rate_window += 1;
            return;
        }
        self.stats.window_keys_walked += walk as u64;
        let old = p.interest.replace(rect);
        // Newly covered tiles the relay has are sent (all of them on the
        // first Presence: the late join), paced by the byte budget.
        let store = self.store.get_mut();
        for key in rect.keys() {
            if old.is_some_and(|o| o.contains(key)) {
                continue;
            }
            if self.tiles.contains_key(&key) || store.as_ref().is_some_and(|s| s.contains(key)) {
                p.pending.insert(key);
            }
        }
        p.pending.retain(|k| rect.contains(*k));
    }

    /// Adds the police's work to the counters.
    fn count(&mut self, work: MotionWork) {
        self.stats.distance_tests += work.distance_tests;
        self.stats.rejected.teleports += work.teleports;
    }

    /// Answers a `Query` within the peer's query rate.
    fn query(&mut self, peer: PeerId, id: u32, points: &[[f64; 2]], now: f64) {
        let (rate, burst) = (f64::from(self.config.query_points_per_s), f64::from(self.config.burst_query_points));
        let Some(p) = self.peers.get_mut(&peer) else {
            return;
        };
        if !p.query_points.take(now, rate, burst, points.len().max(1) as f64) {
            self.stats.rejected.rate_query += 1;
            return;
        }
        self.stats.queries += 1;
        let (depths, packed) = points.iter().map(|p| self.column_at(p[0], p[1]).unwrap_or((f32::NAN, f32::NAN))).unzip();
        self.enqueue(peer, encode(&Message::Depths { id, depths, packed }));
    }

    fn tiles_from(&mut self, peer: PeerId, tiles: &[SharedTile], now: f64) {
        let Some(world) = self.world.clone() else {
            return;
        };
        let c = CatchUp { max_fallen_m: world.settings.max_fallen_m };
        let so_far = world.clock_at(now);
        let limit = world.clock_at(now + self.config.max_clock_lead_s);
        let (rate, burst) = (f64::from(self.config.tiles_per_s), f64::from(self.config.burst_tiles));
        let (reach, oldest) = self.write_reach(&world, now);
        for t in tiles {
            self.stats.tiles_received += 1;
            let Some(p) = self.peers.get_mut(&peer) else {
                return;
            };
            if t.side != world.settings.tile_side || !t.is_consistent() || (!world.settings.has_snowfall && !t.fallen.is_empty()) {
                self.stats.rejected.bad_tile += 1;
                continue;
            }
            if !in_bounds(t.key, &world, self.config.bounds_m) {
                self.stats.rejected.out_of_bounds += 1;
                continue;
            }
            // A packed footprint is (top << 16) | foot, its foot never above its top.
            if t.stamps.iter().any(|&s| s != NO_STAMP && (s & 0xffff) > (s >> 16)) {
                self.stats.rejected.bad_footprint += 1;
                continue;
            }
            if !p.in_tiles.take(now, rate, burst, 1.0) {
                self.stats.rejected.rate_tiles += 1;
                continue;
            }
            if !t.clock.time_s.is_finite() || t.clock.time_s > limit.time_s || !limit.covers(&t.clock) {
                self.stats.rejected.clock_ahead += 1;
                continue;
            }
            let most_fallen = limit.fallen_m.max(so_far.fallen_m);
            if t.fallen.iter().any(|f| !f.is_finite() || *f < 0.0 || *f > most_fallen) {
                self.stats.rejected.too_much_snowfall += 1;
                continue;
            }
            let too_deep = t.deficit.iter().enumerate().any(|(k, &d)| {
                let lying = t.fallen.get(k).copied().unwrap_or(0.0);
                f32::from(d) * SNOW_QUANTUM_M > world.settings.depth_m + lying + SNOW_QUANTUM_M
            });
            if too_deep {
                self.stats.rejected.too_deep += 1;
                continue;
            }
            let mut work = MotionWork::default();
            let allowed = may_write(p, t.key, &world, reach, oldest, &mut work);
            self.count(work);
            if !allowed {
                self.stats.rejected.far_from_deformers += 1;
                continue;
            }
            if !self.has_room_for(t.key) {
                continue;
            }
            self.merge_in(peer, t, c);
        }
    }

    /// Whether tile `key` may be merged: one the relay keeps (in memory or
    /// in its store) always; a new one only while the store has room
    /// (refused and counted otherwise, with a warning at most every 10 s).
    fn has_room_for(&mut self, key: TileKey) -> bool {
        if self.tiles.contains_key(&key) {
            return true;
        }
        let Some(store) = self.store.get_mut().as_ref() else {
            return true;
        };
        if store.contains(key) || store.has_room() {
            return true;
        }
        self.stats.rejected.disk_full += 1;
        if self.now_s - self.last_full_warning_s >= 10.0 {
            self.last_full_warning_s = self.now_s;
            tracing::warn!(
                "snow relay: the store {} is at its disk budget: new tiles are refused ({} so far), kept trails stay and still merge",
                store.dir().display(),
                self.stats.rejected.disk_full
            );
        }
        false
    }

    /// Merges an accepted tile from `sender` and marks it for the peers that need it.
    fn merge_in(&mut self, sender: PeerId, t: &SharedTile, c: CatchUp) {
        let key = t.key;
        self.load(key);
        self.use_counter += 1;
        let used = self.use_counter;
        let changed = match self.tiles.get_mut(&key) {
            Some(held) => {
                held.used = used;
                held.encoded = None;
                let changed = held.tile.merge(t, c);
                held.dirty |= changed;
                held.bytes = held_bytes(&held.tile, None);
                changed
            }
            None => {
                self.tiles.insert(key, Held { tile: t.clone(), dirty: true, used, encoded: None, bytes: held_bytes(t, None) });
                true
            }
        };
        let Some(merged) = self.tiles.get(&key).map(|h| &h.tile) else {
            return;
        };
        if changed {
            self.stats.tiles_merged += 1;
        }
        // The sender needs the merge back only if it adds to what it sent.
        let sender_lacks = {
            let mut theirs = t.clone();
            theirs.merge(merged, c)
        };
        for (&id, p) in &mut self.peers {
            if p.standing == Standing::Welcomed && p.interest.is_some_and(|r| r.contains(key)) && (if id == sender { sender_lacks } else { changed }) {
                p.pending.insert(key);
            }
        }
    }

    /// How far from a recent deformer a peer may write (m, the accept
    /// radius plus a tile's half diagonal), and the oldest position that counts.
    fn write_reach(&self, world: &WorldIdentity, now: f64) -> (f64, f64) {
        let half_diagonal = f64::from(world.settings.tile_side) * f64::from(world.settings.texel_m) * std::f64::consts::FRAC_1_SQRT_2;
        (f64::from(self.config.accept_radius_m) + half_diagonal, now - self.config.deformer_memory_s)
    }

    fn digest_from(&mut self, peer: PeerId, clock: &ShareClock, window: [i64; 2], resolution: u32, entries: &[(TileKey, u64)]) {
        let Some(world) = self.world.clone() else {
            return;
        };
        let (reach, oldest) = self.write_reach(&world, self.now_s);
        // The region first: entries outside it cost one comparison each.
        let Some(region) = KeyRect::of_window(window, resolution, world.settings.tile_side, 0) else {
            self.stats.rejected.bad_window += 1;
            return;
        };
        let Some(p) = self.peers.get_mut(&peer) else {
            return;
        };
        // Only a tile the peer may have written is worth asking for: any
        // other copy it holds came from the relay, and would be refused.
        let mut work = MotionWork::default();
        let mut seen = HashSet::with_capacity(entries.len());
        let may_want: HashSet<TileKey> = entries
            .iter()
            .map(|&(k, _)| k)
            .filter(|&k| region.contains(k) && seen.insert(k))
            .filter(|&k| may_write(p, k, &world, reach, oldest, &mut work))
            .collect();
        self.count(work);
        let c = CatchUp { max_fallen_m: world.settings.max_fallen_m };
        let mut listed = HashSet::with_capacity(entries.len());
        let mut send = Vec::new();
        let mut want = Vec::new();
        for &(key, digest) in entries {
            if !region.contains(key) || !listed.insert(key) {
                continue;
            }
            match self.tile(key) {
                None if may_want.contains(&key) => want.push(key),
                None => {}
                Some(mut mine) => {
                    if clock.covers(&mine.clock) {
                        mine.catch_up(clock, c);
                        if mine.digest() == digest {
                            continue;
                        }
                    }
                    // Different, or the relay's copy is ahead of the
                    // digest's clock: which is newer cannot be told, so
                    // each side sends the other its copy.
                    send.push(key);
                    if may_want.contains(&key) {
                        want.push(key);
                    }
                }
            }
        }
        let store = self.store.get_mut();
        for key in region.keys() {
            if !listed.contains(&key) && (self.tiles.contains_key(&key) || store.as_ref().is_some_and(|s| s.contains(key))) {
                send.push(key);
            }
        }
        let mut in_sync = send.is_empty() && want.is_empty();
        if let Some(p) = self.peers.get_mut(&peer) {
            p.pending.extend(send.into_iter().filter(|k| p.interest.is_some_and(|r| r.contains(*k))));
            in_sync &= p.pending.is_empty();
        }
        want.truncate(MAX_KEYS);
        if !want.is_empty() {
            self.enqueue(peer, encode(&Message::Want { keys: want }));
        }
        if in_sync {
            self.enqueue(peer, encode(&Message::InSync { clock: *clock }));
        }
    }

    /// Sends `peer` its pending tiles, nearest its window first, as many
    /// as its byte budget holds now (the rest wait for the next send).
    fn send_pending(&mut self, peer: PeerId, now: f64) {
        let (rate, burst) = (f64::from(self.config.send_bytes_per_s), f64::from(self.config.send_burst_bytes));
        let (keys, mut tokens) = {
            let Some(p) = self.peers.get_mut(&peer) else {
                return;
            };
            if p.standing != Standing::Welcomed || p.pending.is_empty() || now - p.last_send_s < self.config.send_interval_s {
                return;
            }
            let Some(rect) = p.interest else {
                return;
            };
            p.last_send_s = now;
            p.pending.retain(|k| rect.contains(*k));
            let c2 = rect.centre2();
            let mut keys: Vec<TileKey> = p.pending.iter().copied().collect();
            keys.sort_by_key(|k| {
                let (dx, dy) = (2 * i128::from(k.col) - c2[0], 2 * i128::from(k.row) - c2[1]);
                (dx * dx + dy * dy, *k)
            });
            (keys, p.out_bytes.refill(now, rate, burst))
        };
        // A full bucket always lets one tile through, however large (the
        // bucket then owes it), so a budget below one tile still progresses.
        let mut may_overdraw = tokens >= burst;
        let mut batch: Vec<(TileKey, Vec<u8>)> = Vec::new();
        let (mut bytes, mut texels) = (TILES_OVERHEAD_BYTES, 0usize);
        for key in keys {
            let Some((encoded, tile_texels)) = self.encoded(key) else {
                if let Some(p) = self.peers.get_mut(&peer) {
                    p.pending.remove(&key);
                }
                continue;
            };
            if TILES_OVERHEAD_BYTES + encoded.len() > MAX_MESSAGE_BYTES || tile_texels > MAX_MESSAGE_TEXELS {
                self.stats.rejected.tile_too_large += 1;
                if let Some(p) = self.peers.get_mut(&peer) {
                    p.pending.remove(&key);
                }
                continue;
            }
            if !batch.is_empty() && (batch.len() == MAX_TILES || bytes + encoded.len() > MAX_MESSAGE_BYTES || texels + tile_texels > MAX_MESSAGE_TEXELS) {
                tokens -= self.send_batch(peer, &mut batch) as f64;
                (bytes, texels) = (TILES_OVERHEAD_BYTES, 0);
            }
            if (bytes + encoded.len()) as f64 > tokens && !(may_overdraw && batch.is_empty()) {
                break;
            }
            may_overdraw = false;
            bytes += encoded.len();
            texels += tile_texels;
            batch.push((key, encoded));
        }
        if !batch.is_empty() {
            tokens -= self.send_batch(peer, &mut batch) as f64;
        }
        if let Some(p) = self.peers.get_mut(&peer) {
            p.out_bytes.tokens = tokens;
        }
    }

    /// Queues one `Tiles` message of `batch` (its tiles leave `pending`);
    /// returns the message's size.
    fn send_batch(&mut self, peer: PeerId, batch: &mut Vec<(TileKey, Vec<u8>)>) -> usize {
        let Some(p) = self.peers.get_mut(&peer) else {
            batch.clear();
            return 0;
        };
        let parts: Vec<&[u8]> = batch.iter().map(|(_, e)| e.as_slice()).collect();
        let message = tiles_message(p.seq_out, &parts);
        p.seq_out = p.seq_out.wrapping_add(1);
        for (key, _) in batch.iter() {
            p.pending.remove(key);
        }
        self.stats.tiles_sent += batch.len() as u64;
        batch.clear();
        let len = message.len();
        self.enqueue(peer, message);
        len
    }

    /// A tile's wire bytes and texels: from the cache for a tile in memory
    /// (filling it), encoded afresh for one read from the store.
    fn encoded(&mut self, key: TileKey) -> Option<(Vec<u8>, usize)> {
        if let Some(held) = self.tiles.get_mut(&key) {
            let bytes = held.encoded.get_or_insert_with(|| encode_tile(&held.tile)).clone();
            held.bytes = held_bytes(&held.tile, Some(&bytes));
            return Some((bytes, held.tile.texels()));
        }
        self.tile(key).map(|t| (encode_tile(&t), t.texels()))
    }

    /// Brings a tile from the store into memory if it is not there.
    fn load(&mut self, key: TileKey) {
        if self.tiles.contains_key(&key) {
            return;
        }
        let Some(store) = self.store.get_mut().as_mut() else {
            return;
        };
        match store.read(key) {
            Ok(Some(data)) => match tile_from_data(data) {
                Ok(tile) => {
                    self.stats.tiles_loaded += 1;
                    let bytes = held_bytes(&tile, None);
                    self.tiles.insert(key, Held { tile, dirty: false, used: self.use_counter, encoded: None, bytes });
                }
                Err(_) => self.stats.store_errors += 1,
            },
            Ok(None) => {}
            Err(_) => self.stats.store_errors += 1,
        }
    }

    /// Drops the least recently merged or loaded tiles beyond `memory_tiles`, writing
    /// changed ones to the store first (a tile whose write fails stays).
    fn trim_memory(&mut self) {
        let (cap, cap_bytes) = (self.config.memory_tiles, self.config.memory_bytes);
        let mut bytes: usize = self.tiles.values().map(|h| h.bytes).sum();
        if self.tiles.len() <= cap && bytes <= cap_bytes {
            return;
        }
        let mut by_use: Vec<(u64, TileKey)> = self.tiles.iter().map(|(k, h)| (h.used, *k)).collect();
        by_use.sort_unstable();
        let store = self.store.get_mut();
        for (_, key) in by_use {
            if self.tiles.len() <= cap && bytes <= cap_bytes {
                break;
            }
            let Some(held) = self.tiles.get(&key) else {
                continue;
            };
            match store.as_mut() {
                Some(store) => {
                    if held.dirty {
                        match store.write(&tile_to_data(&held.tile)) {
                            Ok(()) => self.stats.tiles_persisted += 1,
                            // A new tile past the budget is dropped, as at its merge.
                            Err(e) if is_full(&e) => self.stats.rejected.disk_full += 1,
                            Err(_) => {
                                self.stats.store_errors += 1;
                                continue;
                            }
                        }
                    }
                    self.stats.tiles_evicted += 1;
                }
                None => self.stats.tiles_forgotten += 1,
            }
            bytes -= held.bytes;
            self.tiles.remove(&key);
        }
    }
}

/// Whether `p` may write tile `key`: its centre is within `reach` (m) of
/// one of the peer's deformer positions recorded since `oldest`.
/// (A fixed number of grid look-ups, counted in `work`.)
fn may_write(p: &mut PeerState, key: TileKey, world: &WorldIdentity, reach: f64, oldest: f64, work: &mut MotionWork) -> bool {
    let first = key.first_texel(world.settings.tile_side);
    let half = f64::from(world.settings.tile_side) / 2.0;
    let texel = f64::from(world.settings.texel_m);
    let centre = [(first[0] as f64 + half) * texel, (first[1] as f64 + half) * texel];
    p.history.near(centre, reach, oldest, work)
}

/// Whether tile `key` lies where a window can be (its texels fit in i32,
/// as every window's do) and, with `bounds_m`, overlaps those bounds.
fn in_bounds(key: TileKey, world: &WorldIdentity, bounds_m: Option<[f64; 4]>) -> bool {
    let side = i64::from(world.settings.tile_side);
    let first = key.first_texel(world.settings.tile_side);
    let fits = |v: i64| v >= i64::from(i32::MIN) && v.saturating_add(side) <= i64::from(i32::MAX);
    if !(fits(first[0]) && fits(first[1])) {
        return false;
    }
    let Some([x0, z0, x1, z1]) = bounds_m else {
        return true;
    };
    let texel = f64::from(world.settings.texel_m);
    let (a, b) = ([first[0] as f64 * texel, first[1] as f64 * texel], [(first[0] + side) as f64 * texel, (first[1] + side) as f64 * texel]);
    a[0] < x1 && b[0] > x0 && a[1] < z1 && b[1] > z0
}

/// Whether a store refused a write because its disk budget is spent.
fn is_full(e: &StoreError) -> bool {
    matches!(e, StoreError::Io { source, .. } if source.kind() == std::io::ErrorKind::StorageFull)
}

/// Bytes a tile held in memory costs: its planes and its cached encoding.
fn held_bytes(t: &SharedTile, encoded: Option<&Vec<u8>>) -> usize {
    96 + 2 * t.deficit.len() + 4 * t.stamps.len() + 4 * t.fallen.len() + encoded.map_or(0, Vec::len)
}

/// What makes a world unusable by a relay (a tile side off the wire's
/// range, a texel size or depth that is not a positive number).
fn world_problems(w: &WorldIdentity) -> Vec<String> {
    let mut out = Vec::new();
    if !(MIN_TILE_SIDE..=MAX_TILE_SIDE).contains(&w.settings.tile_side) {
        out.push(format!("tile side: {} here, {MIN_TILE_SIDE}..={MAX_TILE_SIDE} there", w.settings.tile_side));
    }
    if !(w.settings.texel_m.is_finite() && w.settings.texel_m > 0.0) {
        out.push(format!("texel size (m): {} here, a positive number there", w.settings.texel_m));
    }
    if !(w.settings.depth_m.is_finite() && w.settings.depth_m >= 0.0) {
        out.push(format!("snow depth (m): {} here, a number at least 0 there", w.settings.depth_m));
    }
    if !(w.settings.max_fallen_m.is_finite() && w.settings.max_fallen_m >= 0.0) {
        out.push(format!("most snowfall kept (m): {} here, a number at least 0 there", w.settings.max_fallen_m));
    }
    out
}

/// A relay's tile as the tile store keeps it. The store's planes are
/// reused for deficits, not heights: `snow_xor_rest` holds the deficit
/// (bits 0..16), with bit 16 set in every texel when the tile has no
/// footprint plane (the store's format always has one; it is then all
/// [`NO_STAMP`]); the clock's `refill_m` holds the refill quanta (an
/// integer, exact below 2⁵³) and `fallen_m` the f32 widened. Reading back
/// ([`tile_from_data`]) gives the same tile bit for bit.
#[must_use]
pub fn tile_to_data(t: &SharedTile) -> TileData {
    let flag = if t.stamps.is_empty() { NO_STAMP_PLANE } else { 0 };
    TileData {
        key: t.key,
        side: t.side,
        clock: SnowClock {
            time_s: t.clock.time_s,
            refill_m: t.clock.refill_quanta as f64,
            fallen_m: f64::from(t.clock.fallen_m),
            stamp_quanta: t.clock.stamp_quanta,
        },
        snow_xor_rest: t.deficit.iter().map(|&d| u32::from(d) | flag).collect(),
        stamps: if t.stamps.is_empty() { vec![NO_STAMP; t.texels()] } else { t.stamps.clone() },
        fallen: t.fallen.clone(),
        packed: t.packed.clone(),
    }
}

/// Inverse of [`tile_to_data`]. Data that no relay wrote is
/// [`StoreError::Corrupt`] (naming no file) saying what does not fit.
pub fn tile_from_data(d: TileData) -> Result<SharedTile, StoreError> {
    let corrupt = |why: String| StoreError::Corrupt { path: std::path::PathBuf::new(), why };
    let q = d.clock.refill_m;
    if !((0.0..9_007_199_254_740_992.0).contains(&q) && q.fract() == 0.0) {
        return Err(corrupt(format!("refill {q} is not a whole number of quanta")));
    }
    let fallen_m = d.clock.fallen_m as f32;
    if f64::from(fallen_m).to_bits() != d.clock.fallen_m.to_bits() {
        return Err(corrupt(format!("snowfall so far {} is not an f32", d.clock.fallen_m)));
    }
    let flag = d.snow_xor_rest.first().map_or(0, |v| v & !0xffff);
    if flag != 0 && flag != NO_STAMP_PLANE {
        return Err(corrupt(format!("snow plane flags {flag:#x}")));
    }
    let mut deficit = Vec::with_capacity(d.snow_xor_rest.len());
    for &v in &d.snow_xor_rest {
        if v & !0xffff != flag {
            return Err(corrupt("snow plane flags differ between texels".to_owned()));
        }
        deficit.push((v & 0xffff) as u16);
    }
    let stamps = if flag == NO_STAMP_PLANE { Vec::new() } else { d.stamps };
    let tile = SharedTile {
        key: d.key,
        side: d.side,
        clock: ShareClock { time_s: d.clock.time_s, refill_quanta: q as u64, stamp_quanta: d.clock.stamp_quanta, fallen_m },
        deficit,
        stamps,
        fallen: d.fallen,
        packed: d.packed,
    };
    if tile.is_consistent() { Ok(tile) } else { Err(corrupt("planes of the wrong size".to_owned())) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::replicate::world::WorldSettings;

    #[test]
    fn stored_tiles_come_back_bit_for_bit() {
        let key = TileKey::new(-2, 5);
        let clock = ShareClock { time_s: 3.5, refill_quanta: 123_456, stamp_quanta: 77, fallen_m: 0.015_625 };
        for (stamps, fallen) in [(false, false), (true, false), (false, true), (true, true)] {
            let mut t = SharedTile::untouched(key, 8, clock, stamps, fallen);
            t.deficit[3] = 65_535;
            t.deficit[9] = 17;
            if stamps {
                t.stamps[4] = 0x0102_0304;
            }
            if fallen {
                t.fallen[5] = 0.25;
                t.packed = vec![0; t.texels()];
                t.packed[9] = 40_000;
            }
            let back = tile_from_data(tile_to_data(&t)).expect("round trip");
            assert_eq!(back, t);
            assert_eq!(back.digest(), t.digest());
        }
    }

    /// A server moves its relay to a thread of its own.
    #[test]
    fn a_relay_and_a_peer_can_move_between_threads() {
        fn send<T: Send>() {}
        send::<SnowRelay>();
        send::<super::super::SnowPeer>();
    }

    #[test]
    fn data_no_relay_wrote_is_corrupt() {
        let t = SharedTile::untouched(TileKey::new(0, 0), 8, ShareClock::default(), false, false);
        let why = |d: TileData| match tile_from_data(d) {
            Err(StoreError::Corrupt { why, .. }) => why,
            other => panic!("expected Corrupt, got {other:?}"),
        };
        let mut half = tile_to_data(&t);
        half.clock.refill_m = 0.5;
        assert!(why(half).contains("whole number"));
        let mut mixed = tile_to_data(&t);
        mixed.snow_xor_rest[3] = 7;
        assert!(why(mixed).contains("differ"));
        let mut flags = tile_to_data(&t);
        flags.snow_xor_rest[0] |= 1 << 20;
        assert!(why(flags).contains("flags"));
    }

    fn pinned_world() -> WorldIdentity {
        WorldIdentity::from_settings(WorldSettings {
            texel_m: 0.0625,
            tile_side: 32,
            terrain: "flat at 0 m".to_owned(),
            depth_m: 0.5,
            refill_m_per_s: 0.0,
            snowfall_m_per_s: 0.0,
            max_fallen_m: 0.0,
            has_snowfall: false,
            stamp_range_m: [-1.0, 3.0],
        })
    }

    /// A pinned world: the first peer of another is refused, and the world stays.
    #[test]
    fn a_pinned_world_is_never_a_peers() {
        let w = pinned_world();
        let mut relay = SnowRelay::new(RelayConfig::default());
        relay.pin_world(w.clone()).expect("pinned");
        relay.connect(1);
        let other = WorldIdentity::from_settings(WorldSettings { depth_m: 0.8, ..w.settings.clone() });
        relay.receive(1, &encode(&Message::Hello { world: other, name: "first".to_owned() }), 0.0);
        let (_, answer) = relay.poll_transmit().expect("an answer");
        match decode(&answer) {
            Ok(Message::Refused { differences }) => assert_eq!(differences, ["snow depth (m): 0.8 here, 0.5 there"]),
            other => panic!("not refused: {other:?}"),
        }
        assert_eq!(relay.world(), Some(&w));
        assert_eq!(relay.stats().rejected.refused, 1);
    }

    /// A store keeps its world: pinning another is an error naming each difference.
    #[test]
    fn pinning_another_world_than_the_stores_fails() {
        let dir = std::env::temp_dir().join(format!("snowpack-relay-pin-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let w = pinned_world();
        {
            let store = TileStore::open(&dir, 32, crate::persist::StoreConfig::default()).expect("store");
            let mut relay = SnowRelay::with_store(store, RelayConfig::default()).expect("relay");
            relay.pin_world(w.clone()).expect("a fresh store takes the world");
        }
        let store = TileStore::open(&dir, 32, crate::persist::StoreConfig::default()).expect("store");
        let mut relay = SnowRelay::with_store(store, RelayConfig::default()).expect("relay");
        assert_eq!(relay.world(), Some(&w));
        match relay.pin_world(WorldIdentity::from_settings(WorldSettings { depth_m: 0.8, ..w.settings.clone() })).map_err(crate::error::ShareError::from) {
            Err(ShareError::StoreWorld(why)) => assert_eq!(why, "snow depth (m): 0.5 here, 0.8 there"),
            other => panic!("not refused: {other:?}"),
        }
        relay.pin_world(w).expect("the same world");
        drop(relay);
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The world's epoch is written once and read back after a restart.
    #[test]
    fn the_world_epoch_is_kept_in_the_store() {
        let dir = std::env::temp_dir().join(format!("snowpack-relay-epoch-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let open =
            || SnowRelay::with_store(TileStore::open(&dir, 32, crate::persist::StoreConfig::default()).expect("store"), RelayConfig::default()).expect("relay");
        assert_eq!(SnowRelay::new(RelayConfig::default()).world_epoch(7.0).expect("no store"), 7.0);
        assert_eq!(open().world_epoch(100.0).expect("epoch"), 100.0);
        assert_eq!(open().world_epoch(250.0).expect("epoch"), 100.0, "the epoch was not kept");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn key_rects_are_bounded() {
        assert!(KeyRect::of_window([0, 0], 0, 16, 1).is_none());
        assert!(KeyRect::of_window([i64::MAX - 4, 0], 64, 16, 1).is_none());
        assert!(KeyRect::of_window([0, 0], u32::MAX, 16, 1).is_none());
        let r = KeyRect::of_window([-16, 0], 32, 16, 1).expect("small window");
        assert_eq!(r, KeyRect { col: [-2, 1], row: [-1, 2] });
        assert_eq!(r.keys().count(), 16);
    }
}
