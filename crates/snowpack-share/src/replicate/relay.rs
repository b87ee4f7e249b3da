//! [`SnowRelay`]: what a server runs. It learns the world from the first
//! peer (or its store), merges the tiles peers send into its own copy,
//! relays merged tiles to the peers whose windows overlap them, answers
//! digests so lost messages are repaired, and keeps the tiles in a
//! [`TileStore`] when it has one. CPU only; no sockets (the caller moves
//! bytes: [`SnowRelay::receive`] in, [`SnowRelay::poll_transmit`] out).
//!
//! A relay trusts no peer: a peer's tile is merged only near where that
//! peer's deformers were in the last 30 s, only if it is no deeper than the
//! snow there and holds no more snowfall than has fallen, only if its
//! clock is not ahead of the world's by more than 5 s, and only within the
//! peer's byte and tile rates. Everything refused is counted
//! ([`RelayStats::rejected`]) and changes nothing.

use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet, HashMap, HashSet, VecDeque};

use crate::SNOW_QUANTUM_M;
use crate::persist::{SnowClock, StoreError, TileData, TileKey, TileStore};

use super::ShareError;
use super::message::{
    MAX_KEYS, MAX_MESSAGE_BYTES, MAX_MESSAGE_TEXELS, MAX_TILE_SIDE, MAX_TILES, MIN_TILE_SIDE, Message, MessageError, TILES_OVERHEAD_BYTES, decode,
    decode_world, encode, encode_tile, encode_world, tiles_message,
};
use super::tile::{CatchUp, NO_STAMP, ShareClock, SharedTile};
use super::world::WorldIdentity;

/// A peer as the caller knows it (a connection number).
pub type PeerId = u64;

/// The most tiles a peer's interest (window plus margin) may cover: bounds
/// what one `Presence` or `Digest` makes the relay walk and remember.
pub const MAX_INTEREST_TILES: usize = 16_384;

/// The state name the relay's world is saved under in its store.
pub const WORLD_STATE: &str = "world";

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
    /// Recent deformer positions, oldest first: (when, positions).
    history: VecDeque<(f64, Vec<[f64; 2]>)>,
    /// Until when `report_deformers` overrides the peer's own `Presence`.
    authoritative_until: f64,
    in_bytes: Bucket,
    in_tiles: Bucket,
    out_bytes: Bucket,
    /// Tiles to send at the next send (coalesced).
    pending: BTreeSet<TileKey>,
    last_send_s: f64,
    queue: VecDeque<Vec<u8>>,
    seq_out: u64,
}

/// Snapshots of deformer positions kept per peer (at least 0.25 s apart).
const MAX_SNAPSHOTS: usize = 128;
/// The least time between two kept snapshots (later ones replace the newest).
const SNAPSHOT_SPACING_S: f64 = 0.25;

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
                if world.tile_side != store.side() {
                    return Err(
                        ShareError::StoreWorld(format!("the saved world has {}² tiles, the store holds {}² tiles", world.tile_side, store.side())).into()
                    );
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
                history: VecDeque::new(),
                authoritative_until: f64::NEG_INFINITY,
                in_bytes: Bucket::full(f64::from(c.burst_bytes), now),
                in_tiles: Bucket::full(f64::from(c.burst_tiles), now),
                out_bytes: Bucket::full(f64::from(c.send_burst_bytes), now),
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
        if let Message::Query { id, points } = message {
            self.stats.queries += 1;
            let depths = points.iter().map(|p| self.depth_at(p[0], p[1]).unwrap_or(f32::NAN)).collect();
            self.enqueue(peer, encode(&Message::Depths { id, depths }));
            return;
        }
        if p.standing != Standing::Welcomed {
            self.stats.rejected.not_welcomed += 1;
            return;
        }
        match message {
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
        let bytes = self.peers.get_mut(&id)?.queue.pop_front()?;
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
        if let Some(p) = self.peers.get_mut(&peer) {
            if p.authoritative_until < now {
                // The peer's own claims stop counting once a server speaks for it.
                p.history.clear();
            }
            p.authoritative_until = now + memory;
            remember(p, world_xz, now, memory);
        }
    }

    /// Snow depth (m) at world (`x_m`, `z_m`) from the merged tiles, caught
    /// up to the latest time the relay was given; untouched snow is the
    /// rest depth plus the snowfall so far. `None` before the relay has a
    /// world (or for a position that is not a number).
    #[must_use]
    pub fn depth_at(&self, x_m: f64, z_m: f64) -> Option<f32> {
        let world = self.world.as_ref()?;
        let texel = f64::from(world.texel_m);
        let (fx, fz) = ((x_m / texel).floor(), (z_m / texel).floor());
        if !fx.is_finite() || !fz.is_finite() {
            return None;
        }
        let (col, row) = (fx as i64, fz as i64);
        let side = world.tile_side;
        let key = TileKey::containing(col, row, side);
        let clock = world.clock_at(self.now_s);
        let Some(mut tile) = self.tile(key) else {
            return Some(world.depth_m + clock.fallen_m);
        };
        if clock.covers(&tile.clock) {
            tile.catch_up(&clock, CatchUp { max_fallen_m: world.max_fallen_m });
        }
        let first = key.first_texel(side);
        Some(tile.depth_at((col - first[0]) as usize, (row - first[1]) as usize, world.depth_m))
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
        RelayStats { peers: self.peers.len(), tiles_in_memory: self.tiles.len(), ..self.stats }
    }

    /// Writes every changed tile to the store (nothing without one). The
    /// first error is returned after trying them all; failed tiles stay
    /// changed and are tried again.
    pub fn flush(&mut self) -> Result<(), crate::ShareError> {
        let Some(store) = self.store.get_mut().as_mut() else {
            return Ok(());
        };
        let mut first = None;
        for held in self.tiles.values_mut().filter(|h| h.dirty) {
            match store.write(&tile_to_data(&held.tile)) {
                Ok(()) => {
                    held.dirty = false;
                    self.stats.tiles_persisted += 1;
                }
                Err(e) => {
                    self.stats.store_errors += 1;
                    first.get_or_insert(e);
                }
            }
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
        if let Some(p) = self.peers.get_mut(&peer) {
            if p.queue.len() >= cap {
                p.queue.pop_front();
                self.stats.rejected.outgoing_dropped += 1;
            }
            p.queue.push_back(bytes);
        }
    }

    fn hello(&mut self, peer: PeerId, theirs: &WorldIdentity, now: f64) {
        if self.world.is_none() {
            let store_side = self.store.get_mut().as_ref().map(TileStore::side);
            let mut problems = world_problems(theirs);
            if let Some(side) = store_side.filter(|&s| s != theirs.tile_side) {
                problems.push(format!("tile side: {} here, {side} there (the relay's store)", theirs.tile_side));
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
        let Some(side) = self.world.as_ref().map(|w| w.tile_side) else {
            return;
        };
        let Some(rect) = KeyRect::of_window(window, resolution, side, 1) else {
            self.stats.rejected.bad_window += 1;
            return;
        };
        let memory = self.config.deformer_memory_s;
        let Some(p) = self.peers.get_mut(&peer) else {
            return;
        };
        if p.authoritative_until < now {
            remember(p, deformers, now, memory);
        }
        let old = p.interest.replace(rect);
        if old == Some(rect) {
            return;
        }
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

    fn tiles_from(&mut self, peer: PeerId, tiles: &[SharedTile], now: f64) {
        let Some(world) = self.world.clone() else {
            return;
        };
        let c = CatchUp { max_fallen_m: world.max_fallen_m };
        let so_far = world.clock_at(now);
        let limit = world.clock_at(now + self.config.max_clock_lead_s);
        let (rate, burst) = (f64::from(self.config.tiles_per_s), f64::from(self.config.burst_tiles));
        let (reach, oldest) = self.write_reach(&world, now);
        for t in tiles {
            self.stats.tiles_received += 1;
            let Some(p) = self.peers.get_mut(&peer) else {
                return;
            };
            if t.side != world.tile_side || !t.is_consistent() || (!world.has_snowfall && !t.fallen.is_empty()) {
                self.stats.rejected.bad_tile += 1;
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
                f32::from(d) * SNOW_QUANTUM_M > world.depth_m + lying + SNOW_QUANTUM_M
            });
            if too_deep {
                self.stats.rejected.too_deep += 1;
                continue;
            }
            if !may_write(p, t.key, &world, reach, oldest) {
                self.stats.rejected.far_from_deformers += 1;
                continue;
            }
            self.merge_in(peer, t, c);
        }
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
                changed
            }
            None => {
                self.tiles.insert(key, Held { tile: t.clone(), dirty: true, used, encoded: None });
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
        let half_diagonal = f64::from(world.tile_side) * f64::from(world.texel_m) * std::f64::consts::FRAC_1_SQRT_2;
        (f64::from(self.config.accept_radius_m) + half_diagonal, now - self.config.deformer_memory_s)
    }

    fn digest_from(&mut self, peer: PeerId, clock: &ShareClock, window: [i64; 2], resolution: u32, entries: &[(TileKey, u64)]) {
        let Some(world) = self.world.clone() else {
            return;
        };
        let (reach, oldest) = self.write_reach(&world, self.now_s);
        let Some(p) = self.peers.get(&peer) else {
            return;
        };
        // Only a tile the peer may have written is worth asking for: any
        // other copy it holds came from the relay, and would be refused.
        let wanted = |key: TileKey| may_write(p, key, &world, reach, oldest);
        let may_want: HashSet<TileKey> = entries.iter().map(|&(k, _)| k).filter(|&k| wanted(k)).collect();
        let Some(region) = KeyRect::of_window(window, resolution, world.tile_side, 0) else {
            self.stats.rejected.bad_window += 1;
            return;
        };
        let c = CatchUp { max_fallen_m: world.max_fallen_m };
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
            let bytes = held.encoded.get_or_insert_with(|| encode_tile(&held.tile));
            return Some((bytes.clone(), held.tile.texels()));
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
                    self.tiles.insert(key, Held { tile, dirty: false, used: self.use_counter, encoded: None });
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
        let cap = self.config.memory_tiles;
        if self.tiles.len() <= cap {
            return;
        }
        let mut by_use: Vec<(u64, TileKey)> = self.tiles.iter().map(|(k, h)| (h.used, *k)).collect();
        by_use.sort_unstable();
        let excess = self.tiles.len() - cap;
        let store = self.store.get_mut();
        for (_, key) in by_use.into_iter().take(excess) {
            let Some(held) = self.tiles.get(&key) else {
                continue;
            };
            match store.as_mut() {
                Some(store) => {
                    if held.dirty {
                        if store.write(&tile_to_data(&held.tile)).is_err() {
                            self.stats.store_errors += 1;
                            continue;
                        }
                        self.stats.tiles_persisted += 1;
                    }
                    self.stats.tiles_evicted += 1;
                }
                None => self.stats.tiles_forgotten += 1,
            }
            self.tiles.remove(&key);
        }
    }
}

/// Whether `p` may write tile `key`: its centre is within `reach` (m) of
/// one of the peer's deformer positions recorded since `oldest`.
fn may_write(p: &PeerState, key: TileKey, world: &WorldIdentity, reach: f64, oldest: f64) -> bool {
    let first = key.first_texel(world.tile_side);
    let half = f64::from(world.tile_side) / 2.0;
    let texel = f64::from(world.texel_m);
    let centre = [(first[0] as f64 + half) * texel, (first[1] as f64 + half) * texel];
    p.history.iter().filter(|(at, _)| *at >= oldest).flat_map(|(_, ds)| ds).any(|d| (d[0] - centre[0]).hypot(d[1] - centre[1]) <= reach)
}

/// Records deformer positions for `p` (non-finite ones dropped), keeping
/// snapshots at least [`SNAPSHOT_SPACING_S`] apart for `memory` seconds.
fn remember(p: &mut PeerState, positions: &[[f64; 2]], now: f64, memory: f64) {
    let positions: Vec<[f64; 2]> = positions.iter().filter(|d| d[0].is_finite() && d[1].is_finite()).take(super::message::MAX_DEFORMERS).copied().collect();
    // The newest snapshot follows the deformers until it is a spacing
    // apart from the one before it; then a new one starts.
    let n = p.history.len();
    let replace = n >= 2 && now - p.history[n - 2].0 < SNAPSHOT_SPACING_S;
    match p.history.back_mut() {
        Some(last) if replace => *last = (now, positions),
        _ => p.history.push_back((now, positions)),
    }
    while p.history.front().is_some_and(|(at, _)| *at < now - memory) || p.history.len() > MAX_SNAPSHOTS {
        p.history.pop_front();
    }
}

/// What makes a world unusable by a relay (a tile side off the wire's
/// range, a texel size or depth that is not a positive number).
fn world_problems(w: &WorldIdentity) -> Vec<String> {
    let mut out = Vec::new();
    if !(MIN_TILE_SIDE..=MAX_TILE_SIDE).contains(&w.tile_side) {
        out.push(format!("tile side: {} here, {MIN_TILE_SIDE}..={MAX_TILE_SIDE} there", w.tile_side));
    }
    if !(w.texel_m.is_finite() && w.texel_m > 0.0) {
        out.push(format!("texel size (m): {} here, a positive number there", w.texel_m));
    }
    if !(w.depth_m.is_finite() && w.depth_m >= 0.0) {
        out.push(format!("snow depth (m): {} here, a number at least 0 there", w.depth_m));
    }
    if !(w.max_fallen_m.is_finite() && w.max_fallen_m >= 0.0) {
        out.push(format!("most snowfall kept (m): {} here, a number at least 0 there", w.max_fallen_m));
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
    };
    if tile.is_consistent() { Ok(tile) } else { Err(corrupt("planes of the wrong size".to_owned())) }
}

#[cfg(test)]
mod tests {
    use super::*;

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
