//! [`SnowRelay`]: what a server runs. Its world is pinned by the server
//! ([`SnowRelay::pin_world`]), or else learnt from its store or the first
//! peer, and never redefined; it merges the tiles peers send into its own copy,
//! relays merged tiles to the peers whose windows overlap them (and the
//! analytic presses a peer sends, in place of the tiles they press), answers
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

mod admission;
mod bucket;
mod config;
mod digest;
mod held;
mod interest;
mod outbox;
mod peers;
mod stats;
mod stored;
#[cfg(test)]
mod tests;

use crate::persist::TileStoreExt;
use crate::replicate::WorldIdentityExt;
use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet};

use crate::persist::{TileKey, TileStore};

use super::ShareError;
use super::message::{
    MAX_KEYS, MAX_MESSAGE_BYTES, MAX_MESSAGE_TEXELS, MAX_TILES, Message, MessageError, TILES_OVERHEAD_BYTES, decode, decode_world, encode, encode_tile,
    encode_world, tiles_message,
};
use super::motion::MotionWork;
use super::tile::{CatchUp, ShareClock, SharedTile};
use super::world::WorldIdentity;
use admission::{fits_the_world, is_believable, world_problems};
use held::HeldTiles;
use interest::KeyRect;
use peers::{PeerState, Standing};

pub use config::RelayConfig;
pub use interest::MAX_INTEREST_TILES;
pub use peers::PeerId;
pub use stats::{RelayRejections, RelayStats};
pub use stored::{EPOCH_STATE, GROUND_STATE, WORLD_STATE, tile_from_data, tile_to_data};

/// The relay: see the module documentation.
#[derive(Debug)]
pub struct SnowRelay {
    config: RelayConfig,
    /// In a cell so the read-only queries can read evicted tiles back.
    store: RefCell<Option<TileStore>>,
    world: Option<WorldIdentity>,
    /// The tiles in memory.
    tiles: HeldTiles,
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

/// Seconds after presses were passed on to a peer during which its digests
/// may have crossed them: a tile they pressed that a digest shows
/// otherwise is not sent then (the presses are on their way), only if a
/// later digest still shows it otherwise (they were lost).
const PASSED_ON_S: f64 = 1.0;

impl SnowRelay {
    /// A relay that keeps its tiles in memory; the world comes from the first `Hello`.
    #[must_use]
    pub fn new(config: RelayConfig) -> Self {
        Self {
            config,
            store: RefCell::new(None),
            world: None,
            tiles: HeldTiles::default(),
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
    /// there (if any; tiles are read back when they are needed), and the
    /// heightmap saved with it ([`GROUND_STATE`]), over which it presses.
    /// The store's tile files hold deficits (see `tile_to_data`), not the
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
                Some(match store.read_state(GROUND_STATE)? {
                    Some(bytes) => {
                        let grid = stored::saved_ground(&bytes, &world)?;
                        world.holding(grid)
                    }
                    None => world,
                })
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
    /// store's and "there" `world`); otherwise the world is saved there,
    /// with the heightmap it holds ([`GROUND_STATE`]: a relay opened on
    /// the store later presses over it without the scene's file).
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
            if let Some(grid) = &world.grid {
                store.write_state(GROUND_STATE, &grid.to_bytes()).map_err(ShareError::Store)?;
            }
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
            v.insert(PeerState::new(number, c, now));
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
        if let Message::Hello { world, presses, .. } = message {
            self.hello(peer, &world, presses, now);
            return;
        }
        // Queries too: only a peer of this world may read it.
        if p.standing != Standing::Welcomed {
            self.stats.rejected.not_welcomed += 1;
            return;
        }
        // Tiles and presses are judged by where the peer's deformers are:
        // before the peer first says so (its `Presence` can come after the
        // changes it sent with it), for a few seconds after its welcome,
        // they are left unacknowledged, and the peer sends them again.
        if matches!(message, Message::Tiles { .. } | Message::Presses { .. }) && p.awaits_presence(now) {
            self.stats.awaiting_presence += 1;
            return;
        }
        match message {
            Message::Query { id, points } => self.query(peer, id, &points, now),
            Message::Presence { window, resolution, deformers } => self.presence(peer, window, resolution, &deformers, now),
            Message::Tiles { seq, tiles } => {
                self.tiles_from(peer, &tiles, now, true, &BTreeSet::new());
                self.enqueue(peer, encode(&Message::Ack { seq }));
            }
            Message::Presses { seq, frames, tiles } => {
                // What the frames pressed, judged and merged as tiles the
                // peer sent (paid for by the press bucket, not the tile
                // bucket), then the frames go on to the peers that watch
                // those tiles, in place of the tiles.
                let pressed = self.pressed_by(peer, &frames, now);
                let watchers = self.watchers_of(peer, &pressed);
                let accepted = self.tiles_from(peer, &pressed, now, false, &watchers);
                self.pass_presses_on(&frames, (&pressed, &accepted), &watchers, now);
                self.tiles_from(peer, &tiles, now, true, &BTreeSet::new());
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
        let id = after.chain(before.into_iter().flatten()).find(|(_, p)| !p.outbox.is_empty()).map(|(&id, _)| id)?;
        let p = self.peers.get_mut(&id)?;
        let bytes = p.outbox.pop()?;
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
        if let Some(tile) = self.tiles.tile(key) {
            return Some(tile.clone());
        }
        let mut store = self.store.borrow_mut();
        let data = store.as_mut()?.read(key).ok()??;
        tile_from_data(data).ok()
    }

    /// The keys of every tile the relay holds (in memory or in its store).
    #[must_use]
    pub fn tile_keys(&self) -> Vec<TileKey> {
        let mut keys: BTreeSet<TileKey> = self.tiles.keys().collect();
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
            tile_bytes_in_memory: self.tiles.bytes(),
            queued_bytes: self.peers.values().map(|p| p.outbox.bytes()).sum(),
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
        let first = self.tiles.flush(store, &mut self.stats);
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
            self.stats.rejected.outgoing_dropped += p.outbox.push(bytes, cap, cap_bytes);
        }
    }

    fn hello(&mut self, peer: PeerId, theirs: &WorldIdentity, presses: bool, now: f64) {
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
        let relay_presses = crate::replicate::press::press_ground(world).is_some();
        if let Some(p) = self.peers.get_mut(&peer) {
            if p.standing != Standing::Welcomed {
                p.welcomed_s = now;
            }
            p.standing = Standing::Welcomed;
            p.presses = presses;
            let number = p.number;
            self.enqueue(peer, encode(&Message::Welcome { peer: number, clock, presses: relay_presses }));
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
            if self.tiles.contains(key) || store.as_ref().is_some_and(|s| s.contains(key)) {
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

    /// Judges and merges `tiles` from `peer`, each paid for by its tile
    /// bucket when `counted` (tiles its presses made are paid for by the
    /// press bucket); a merge that changed a tile is sent to the peers
    /// watching it but `forwarded` (those are sent the presses that made
    /// it). The tiles accepted, by key, with whether each changed the
    /// relay's copy.
    fn tiles_from(&mut self, peer: PeerId, tiles: &[SharedTile], now: f64, counted: bool, forwarded: &BTreeSet<PeerId>) -> Vec<(TileKey, bool)> {
        let mut accepted = Vec::new();
        let Some(world) = self.world.clone() else {
            return accepted;
        };
        let c = CatchUp { max_fallen_m: world.settings.max_fallen_m };
        let so_far = world.clock_at(now);
        let limit = world.clock_at(now + self.config.max_clock_lead_s);
        let (rate, burst) = (f64::from(self.config.tiles_per_s), f64::from(self.config.burst_tiles));
        let (reach, oldest) = self.write_reach(&world, now);
        for t in tiles {
            self.stats.tiles_received += 1;
            let Some(p) = self.peers.get_mut(&peer) else {
                return accepted;
            };
            if !fits_the_world(t, &world, self.config.bounds_m, &mut self.stats.rejected) {
                continue;
            }
            if counted && !p.in_tiles.take(now, rate, burst, 1.0) {
                self.stats.rejected.rate_tiles += 1;
                continue;
            }
            if !is_believable(t, &world, &limit, &so_far, &mut self.stats.rejected) {
                continue;
            }
            let mut work = MotionWork::default();
            let allowed = p.may_write(t.key, &world, reach, oldest, &mut work);
            self.count(work);
            if !allowed {
                self.stats.rejected.far_from_deformers += 1;
                continue;
            }
            if !self.has_room_for(t.key) {
                continue;
            }
            accepted.push((t.key, self.merge_in(peer, t, c, forwarded)));
        }
        accepted
    }

    /// The welcomed peers but `sender` whose interest holds one of the
    /// `pressed` tiles: those a `Presses` message is passed on to.
    fn watchers_of(&self, sender: PeerId, pressed: &[SharedTile]) -> BTreeSet<PeerId> {
        self.peers
            .iter()
            .filter(|&(&id, p)| id != sender && p.standing == Standing::Welcomed && p.interest.is_some_and(|r| pressed.iter().any(|t| r.contains(t.key))))
            .map(|(&id, _)| id)
            .collect()
    }

    /// Sends `frames` on to `watchers` when the relay accepted every tile
    /// they `pressed` and one of them changed its copy: each watcher
    /// presses them as the relay did, paid from its byte budget. A watcher
    /// that does not hold the world's ground (its `Hello` said so), or
    /// whose budget cannot pay for them now, is sent the tiles instead,
    /// paced with its other tiles (so many senders cannot flood one
    /// watcher's queue); and when a tile was refused (far from the
    /// sender's deformers, say) the frames would press it at the watchers
    /// too, so every watcher is sent the accepted merges as tiles.
    fn pass_presses_on(
        &mut self,
        frames: &[crate::replicate::press::PressFrame],
        (pressed, accepted): (&[SharedTile], &[(TileKey, bool)]),
        watchers: &BTreeSet<PeerId>,
        now: f64,
    ) {
        if watchers.is_empty() || !accepted.iter().any(|&(_, changed)| changed) {
            return;
        }
        let changed = || accepted.iter().filter(|(_, changed)| *changed).map(|&(key, _)| key);
        let coded = (accepted.len() == pressed.len()).then(|| super::presses::encode_frames(frames));
        let (rate, burst) = (f64::from(self.config.send_bytes_per_s), f64::from(self.config.send_burst_bytes));
        for &id in watchers {
            let Some(p) = self.peers.get_mut(&id) else { continue };
            let interest = p.interest;
            let message = coded.as_ref().map(|c| super::message::presses_message(p.seq_out, (frames.len(), c), &[]));
            match message {
                Some(message) if p.presses && p.out_bytes.take(now, rate, burst, message.len() as f64) => {
                    p.seq_out = p.seq_out.wrapping_add(1);
                    p.passed_on.retain(|_, at| now - *at < PASSED_ON_S);
                    p.passed_on.extend(pressed.iter().map(|t| t.key).filter(|k| interest.is_some_and(|r| r.contains(*k))).map(|k| (k, now)));
                    self.stats.press_frames_sent += frames.len() as u64;
                    self.enqueue(id, message);
                }
                _ => p.pending.extend(changed().filter(|k| interest.is_some_and(|r| r.contains(*k)))),
            }
        }
    }

    /// The tiles `frames` (a `Presses` message from `peer`) press, each from
    /// untouched snow at its first frame's clock; none when the world's
    /// presses cannot travel or the peer's press bucket cannot pay for the
    /// message's ray casts (counted as refusals).
    fn pressed_by(&mut self, peer: PeerId, frames: &[crate::replicate::press::PressFrame], now: f64) -> Vec<SharedTile> {
        let Some(world) = self.world.clone() else {
            return Vec::new();
        };
        let Some(ground) = crate::replicate::press::press_ground(&world) else {
            self.stats.rejected.unpressable += 1;
            return Vec::new();
        };
        let (side, texel_m) = (world.settings.tile_side, world.settings.texel_m);
        // Too many instances for one message: refused whole, none made.
        let Some((casts, work)) = crate::replicate::press::costed_casts(frames, texel_m, side) else {
            self.stats.rejected.rate_presses += 1;
            return Vec::new();
        };
        let (rate, burst) = (self.config.press_casts_per_s as f64, self.config.burst_press_casts as f64);
        let Some(p) = self.peers.get_mut(&peer) else {
            return Vec::new();
        };
        if !p.press_casts.take(now, rate, burst, work as f64) {
            self.stats.rejected.rate_presses += 1;
            return Vec::new();
        }
        self.stats.press_frames += frames.len() as u64;
        self.stats.press_casts += work;
        crate::replicate::press::press_tiles(frames, &casts, &world.settings, &ground, side)
    }

    /// Whether tile `key` may be merged: one the relay keeps (in memory or
    /// in its store) always; a new one only while the store has room
    /// (refused and counted otherwise, with a warning at most every 10 s).
    fn has_room_for(&mut self, key: TileKey) -> bool {
        if self.tiles.contains(key) {
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

    /// Merges an accepted tile from `sender` and marks it for the peers
    /// that need it but `forwarded` (sent what pressed it); whether it
    /// changed the relay's copy.
    fn merge_in(&mut self, sender: PeerId, t: &SharedTile, c: CatchUp, forwarded: &BTreeSet<PeerId>) -> bool {
        let key = t.key;
        self.tiles.load(key, self.store.get_mut().as_mut(), &mut self.stats);
        let changed = self.tiles.merge(t, c, sender);
        let Some(merged) = self.tiles.tile(key) else {
            return changed;
        };
        if changed {
            self.stats.tiles_merged += 1;
        }
        // The sender needs the merge back only if it adds to what it sent
        // and the sender did not make all of it itself (a tile sent beyond
        // the copy the relay acknowledged, or pressed from its frames, lacks
        // what the sender already holds).
        let sender_lacks = self.tiles.sole_author(key) != Some(sender) && {
            let mut theirs = t.clone();
            theirs.merge(merged, c)
        };
        for (&id, p) in &mut self.peers {
            let needs = if id == sender { sender_lacks } else { changed && !forwarded.contains(&id) };
            if p.standing == Standing::Welcomed && p.interest.is_some_and(|r| r.contains(key)) && needs {
                p.pending.insert(key);
            }
        }
        changed
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
        let may_want = digest::may_want(p, entries, region, &world, (reach, oldest), &mut work);
        self.count(work);
        let c = CatchUp { max_fallen_m: world.settings.max_fallen_m };
        let digest::DigestDiff { listed, mut send, mut want } = digest::compare(entries, region, clock, c, &may_want, |key| self.tile(key));
        let store = self.store.get_mut();
        for key in region.keys() {
            if !listed.contains(&key) && (self.tiles.contains(key) || store.as_ref().is_some_and(|s| s.contains(key))) {
                send.push(key);
            }
        }
        let now = self.now_s;
        let mut in_sync = want.is_empty();
        if let Some(p) = self.peers.get_mut(&peer) {
            // A tile that presses passed on to the peer lately pressed may
            // differ only because the digest crossed them: sent if it
            // still differs at a later digest.
            let crossed = |k: &TileKey| p.passed_on.get(k).is_some_and(|at| now - at < PASSED_ON_S);
            in_sync &= send.is_empty();
            send.retain(|k| !crossed(k));
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
        if let Some(encoded) = self.tiles.encoded(key) {
            return Some(encoded);
        }
        self.tile(key).map(|t| (encode_tile(&t), t.texels()))
    }

    /// Drops the least recently merged or loaded tiles beyond `memory_tiles`, writing
    /// changed ones to the store first (a tile whose write fails stays).
    fn trim_memory(&mut self) {
        let (cap, cap_bytes) = (self.config.memory_tiles, self.config.memory_bytes);
        self.tiles.trim(self.store.get_mut().as_mut(), cap, cap_bytes, &mut self.stats);
    }
}
