//! [`SnowPeer`]: what a game client runs beside its snow. It keeps a
//! replica of the tiles it has seen (its own changes merged with the
//! relay's), sends its changes as numbered deltas until the relay
//! acknowledges them, folds the relay's tiles (and the tiles other peers'
//! presses, passed on by the relay, press) into the snow, and every
//! second sends digests of its replica so anything lost either way is
//! repaired without a full resend. No sockets: the caller moves bytes
//! ([`SnowPeer::receive`] in, [`SnowPeer::poll_transmit`] out).

use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};

use crate::persist::TileKey;

use super::message::{
    MAX_DEFORMERS, MAX_KEYS, MAX_MESSAGE_BYTES, MAX_MESSAGE_TEXELS, MAX_TILES, Message, MessageError, PRESSES_OVERHEAD_BYTES, TILES_OVERHEAD_BYTES, decode,
    encode, encode_tile, presses_message, tiles_message,
};
use super::presses::MAX_PRESS_FRAMES;
use super::tile::{CatchUp, ShareClock, SharedTile};
use super::world::WorldIdentity;
use super::{ShareError, SharedSnow};
use crate::replicate::press::{FrameCasts, PressFrame};

/// How a peer paces itself and what it keeps.
#[derive(Clone, Debug, PartialEq)]
pub struct PeerConfig {
    /// Seconds between two `Presence` messages.
    pub(crate) presence_interval_s: f64,
    /// Seconds between two `Digest` messages until the relay first answers
    /// one with `InSync` (after joining or reconnecting): a late joiner
    /// learns quickly that it holds everything.
    pub digest_interval_s: f64,
    /// Until then, a `Digest` also goes out once the relay's tiles have
    /// stopped arriving for this long (seconds; longer than the relay's
    /// send interval, so a paced backlog is not taken for its end) while
    /// none of the peer's own changes waits: a late joiner is in sync a
    /// moment after its backlog, not at the next `digest_interval_s`.
    pub(crate) settled_digest_s: f64,
    /// Seconds between two `Digest` messages after that: digests only
    /// repair what a connection lost, and on a reliable channel (renet2's,
    /// a game's own) that is rare, while a digest of a window full of
    /// trails is tens of bytes a tile. Set it to `digest_interval_s` over
    /// an unreliable channel.
    pub synced_digest_interval_s: f64,
    /// The least time between two sends of deltas: a tile changed every
    /// frame in between goes out once, as it is then.
    pub(crate) delta_interval_s: f64,
    /// Press frames wait until the oldest is this old on the snow's clock
    /// (seconds), so a message carries several: each is coded from the
    /// ones before it in the message, and the first costs the most.
    pub(crate) press_interval_s: f64,
    /// A delta not acknowledged after this many seconds is sent again
    /// (as the replica's current tiles, which include it).
    pub(crate) resend_after_s: f64,
    /// The most deltas in flight; further changes wait (and coalesce).
    pub(crate) max_unacknowledged: usize,
    /// Messages queued to send; beyond it the oldest is dropped and counted.
    pub(crate) queue_messages: usize,
    /// Tiles kept in the replica; beyond it those farthest from the window go.
    pub(crate) replica_tiles: usize,
    /// Received tiles waiting for the next `update`; beyond it the oldest go.
    pub(crate) incoming_tiles: usize,
}

impl Default for PeerConfig {
    fn default() -> Self {
        Self {
            presence_interval_s: 0.25,
            digest_interval_s: 1.0,
            settled_digest_s: 0.3,
            synced_digest_interval_s: 5.0,
            delta_interval_s: 0.1,
            press_interval_s: 0.25,
            resend_after_s: 1.0,
            max_unacknowledged: 64,
            queue_messages: 1024,
            replica_tiles: 4096,
            incoming_tiles: 4096,
        }
    }
}

/// A peer's counters since it was made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PeerStats {
    /// Bytes received.
    pub bytes_in: u64,
    /// Bytes handed out by [`SnowPeer::poll_transmit`].
    pub bytes_out: u64,
    /// Messages received.
    pub messages_in: u64,
    /// Messages handed out.
    pub messages_out: u64,
    /// Tiles sent (resends included).
    pub tiles_sent: u64,
    /// Tiles received.
    pub tiles_received: u64,
    /// Received tiles that changed the replica.
    pub tiles_merged: u64,
    /// Deltas sent again after no acknowledgement.
    pub resends: u64,
    /// Messages that did not decode or were not expected.
    pub malformed: u64,
    /// Received tiles of another side, or dropped from a full incoming list.
    pub tiles_dropped: u64,
    /// Messages dropped from a full outgoing queue.
    pub outgoing_dropped: u64,
    /// Tiles too large to send even alone in a message.
    pub tile_too_large: u64,
    /// Bytes of the `Tiles` messages handed out (the rest of `bytes_out`
    /// is `Hello`, `Presence` and `Digest`).
    pub tile_bytes_out: u64,
    /// Tiles sent again as what they add to the copy the relay
    /// acknowledged and the presses sent ([`SharedTile::beyond`]), not whole.
    pub tiles_as_deltas: u64,
    /// Changed tiles the press frames sent explained whole: not sent.
    pub tiles_as_presses: u64,
    /// Press frames sent (resends included).
    pub press_frames_sent: u64,
    /// Press frames dropped from a full queue (what they pressed went as tiles).
    pub press_frames_dropped: u64,
    /// Press frames of other peers the relay passed on, pressed here in
    /// place of the tiles they pressed.
    pub press_frames_received: u64,
    /// Tiles those frames pressed near the window (counted in `tiles_received` too).
    pub tiles_from_presses: u64,
}

/// A numbered message in flight: when it went, the tiles whose copies it
/// carried (or explained), its press frames and what they press.
#[derive(Debug)]
struct InFlight {
    at_s: f64,
    keys: Vec<TileKey>,
    frames: Vec<PressFrame>,
    /// The tiles its frames press: the relay holds them once it
    /// acknowledges (whatever newer copies of the same tiles are in flight).
    pressed: Vec<SharedTile>,
}

/// What one tile of `to_send` sends.
enum Outgoing {
    /// Nothing: the relay holds all of it.
    Nothing,
    /// Nothing beyond the press frames sent; the relay's copy once they are acknowledged.
    Explained(SharedTile),
    /// This tile (whole or a delta), and the relay's copy once acknowledged.
    Tile(SharedTile, SharedTile),
}

/// Seconds of sent press frames a peer keeps to explain its tiles with: the
/// GPU's changed tiles arrive within a few frames of the presses, and a
/// quiet tile at most a second after it first changed.
const PRESS_LOG_S: f64 = 3.0;
/// The most sent press frames kept (a frame is a few hundred bytes).
const MAX_PRESS_LOG: usize = 1024;
/// The most ray casts one `Presses` message the relay passes on may cost
/// this peer: the relay's default burst for one peer's presses
/// (`RelayConfig::burst_press_casts`), so what a relay took it passes on.
const MAX_PASSED_ON_CASTS: u64 = 16 << 20;
/// The most press frames waiting to be sent.
const MAX_PENDING_FRAMES: usize = 4 * MAX_PRESS_FRAMES;

/// A game client's side of shared snow: see the module documentation.
#[derive(Debug)]
pub struct SnowPeer {
    world: WorldIdentity,
    name: String,
    config: PeerConfig,
    welcomed: bool,
    refused: bool,
    /// When the last `Hello` went out (`None` until the first update: the
    /// first is queued by `new`). Resent until answered, as it may be lost.
    last_hello_s: Option<f64>,
    number: Option<u32>,
    relay_clock: Option<ShareClock>,
    joined: bool,
    replica: HashMap<TileKey, SharedTile>,
    incoming: VecDeque<SharedTile>,
    outbox: VecDeque<Vec<u8>>,
    /// Deltas in flight by sequence number.
    unacked: BTreeMap<u64, InFlight>,
    /// The terrain this peer can press over, where presses travel in its
    /// world (`press::press_ground`: flat, value noise, or a heightmap the
    /// identity holds); the frames the relay passes on are pressed over it.
    ground: Option<crate::replicate::press::PressGround>,
    /// The ground when this peer's own frames travel too: `ground` until a
    /// `Welcome` says the relay does not hold it, then none (its presses
    /// go as tiles).
    presses: Option<crate::replicate::press::PressGround>,
    /// Press frames from the snow not sent yet, oldest first.
    frames_pending: VecDeque<PressFrame>,
    /// Tiles this peer's own press frames made, for the snow at the next
    /// update: what the relay makes of them (merged message by message)
    /// may hold more packed snow than the window's one timeline, and the
    /// window must hold what the relay holds of its own presses, which the
    /// relay does not send back.
    own_pressed: Vec<SharedTile>,
    /// Press frames sent in the last [`PRESS_LOG_S`] (with their ray casts):
    /// a tile goes only beyond what they make of it.
    frames_log: VecDeque<(PressFrame, FrameCasts)>,
    next_seq: u64,
    /// Replica tiles to send at the next update (changed, wanted or resent).
    to_send: BTreeSet<TileKey>,
    /// What the relay is known to hold of each tile: the merge of the
    /// copies it acknowledged. A tile sent again carries only what it adds
    /// to this ([`SharedTile::beyond`]).
    acked: HashMap<TileKey, SharedTile>,
    /// The newest copy of each tile in flight and the delta that carried it.
    sent: HashMap<TileKey, (u64, SharedTile)>,
    /// Tiles the relay asked for (`Want`): sent whole, its copy may be gone.
    wanted: BTreeSet<TileKey>,
    deformers: Vec<[f64; 2]>,
    /// The deformers the last `Presence` reported: the relay judges the
    /// peer's tiles by these.
    reported: Vec<[f64; 2]>,
    /// Where the deformers went before the welcome, a point every
    /// [`REPORTED_SLACK_M`]: what this peer pressed meanwhile waits to be
    /// sent, and the relay lets a peer write only near positions it was
    /// told of, so the first `Presence` reports the way there too.
    trail: Vec<[f64; 2]>,
    last_presence_s: f64,
    last_digest_s: f64,
    last_delta_s: f64,
    /// The snow's clock (s) at the last update.
    last_snow_s: f64,
    last_window: Option<([i64; 2], u32)>,
    /// Changes to the replica or the window so far (a counter): an `InSync`
    /// answers a digest only if nothing changed since it was made.
    activity: u64,
    /// The clock and activity of the last digest sent.
    last_digest: Option<(ShareClock, u64)>,
    /// The relay said the last digest matched, and nothing changed since.
    in_sync: bool,
    /// The relay has answered a digest with `InSync` since the peer joined.
    synced_once: bool,
    /// [`SnowPeer::request_digest`] was called.
    digest_requested: bool,
    /// When the relay's tiles last arrived (merged at an update) since the
    /// last digest, if they did: before the first `InSync`, a digest goes
    /// out once they stop (`settled_digest_s`).
    tiles_since_digest_s: Option<f64>,
    stats: PeerStats,
}

impl SnowPeer {
    /// A peer of `world`, named `name` in the relay's logs (cut at 64
    /// bytes). Its `Hello` is queued, and sent again every
    /// `resend_after_s` until the relay answers.
    #[must_use]
    pub fn new(world: WorldIdentity, name: &str, config: PeerConfig) -> Self {
        let ground = crate::replicate::press::press_ground(&world);
        let hello = encode(&Message::Hello { world: world.clone(), name: name.to_owned(), presses: ground.is_some() });
        Self {
            world,
            name: name.to_owned(),
            config,
            welcomed: false,
            refused: false,
            last_hello_s: None,
            number: None,
            relay_clock: None,
            joined: false,
            replica: HashMap::new(),
            incoming: VecDeque::new(),
            outbox: VecDeque::from([hello]),
            unacked: BTreeMap::new(),
            presses: ground.clone(),
            ground,
            frames_pending: VecDeque::new(),
            frames_log: VecDeque::new(),
            own_pressed: Vec::new(),
            next_seq: 0,
            to_send: BTreeSet::new(),
            acked: HashMap::new(),
            sent: HashMap::new(),
            wanted: BTreeSet::new(),
            deformers: Vec::new(),
            reported: Vec::new(),
            trail: Vec::new(),
            last_presence_s: f64::NEG_INFINITY,
            last_digest_s: f64::NEG_INFINITY,
            last_delta_s: f64::NEG_INFINITY,
            last_snow_s: f64::NEG_INFINITY,
            last_window: None,
            activity: 0,
            last_digest: None,
            in_sync: false,
            synced_once: false,
            digest_requested: false,
            tiles_since_digest_s: None,
            stats: PeerStats::default(),
        }
    }

    /// Handles one message from the relay. A `Refused` is
    /// [`crate::ShareErrorKind::Refused`] naming what differs ("here" is this peer's
    /// world, "there" the relay's); bytes that do not decode, or a message
    /// a relay never sends, are [`crate::ShareErrorKind::Malformed`] (and counted).
    /// Tiles, and those the presses the relay passes on press near the
    /// window, are kept for the next [`SnowPeer::update`].
    pub fn receive(&mut self, bytes: &[u8]) -> Result<(), crate::ShareError> {
        self.stats.bytes_in += bytes.len() as u64;
        self.stats.messages_in += 1;
        let message = decode(bytes).inspect_err(|_| self.stats.malformed += 1)?;
        match message {
            Message::Welcome { peer, clock, presses } => {
                self.welcomed = true;
                self.number = Some(peer);
                self.relay_clock = Some(clock);
                if !presses && self.presses.take().is_some() {
                    // The relay cannot press them: what they pressed goes
                    // as tiles (the window's changed tiles hold it).
                    self.frames_pending.clear();
                }
            }
            Message::Refused { differences } => {
                self.welcomed = false;
                self.refused = true;
                return Err(ShareError::Refused { differences }.into());
            }
            Message::Tiles { tiles, .. } => self.take_in(tiles),
            Message::Presses { frames, tiles, .. } => {
                // Another peer's presses, which the relay pressed and passed on.
                let pressed = self.press_passed_on(&frames);
                self.take_in(pressed.into_iter().chain(tiles));
            }
            Message::Ack { seq } => {
                let c = CatchUp { max_fallen_m: self.world.settings.max_fallen_m };
                let Some(flight) = self.unacked.remove(&seq) else { return Ok(()) };
                for t in flight.pressed {
                    merge_into(&mut self.acked, t, c);
                }
                for key in flight.keys {
                    // Only the newest copy in flight is kept: an older one's
                    // acknowledgement adds nothing the newer will not.
                    if self.sent.get(&key).is_some_and(|(s, _)| *s == seq)
                        && let Some((_, tile)) = self.sent.remove(&key)
                    {
                        merge_into(&mut self.acked, tile, c);
                    }
                }
            }
            Message::Want { keys } => {
                // Only what the replica holds can be sent; the rest is not ours
                // to give. Whole: the relay lacks what it asks for.
                let keys: Vec<TileKey> = keys.into_iter().filter(|k| self.replica.contains_key(k)).collect();
                self.wanted.extend(keys.iter().copied());
                self.to_send.extend(keys);
            }
            Message::Clock { clock } => self.relay_clock = Some(clock),
            Message::InSync { clock } => {
                self.in_sync = self.incoming.is_empty() && self.last_digest.is_some_and(|(c, a)| c == clock && a == self.activity);
                self.synced_once |= self.in_sync;
            }
            other => {
                self.stats.malformed += 1;
                return Err(ShareError::Malformed(MessageError::Unexpected(other.kind_name())).into());
            }
        }
        Ok(())
    }

    /// Keeps the relay's `tiles` for the next update (of another side
    /// dropped; the oldest dropped beyond `incoming_tiles`).
    fn take_in(&mut self, tiles: impl IntoIterator<Item = SharedTile>) {
        for t in tiles {
            self.stats.tiles_received += 1;
            if t.side != self.world.settings.tile_side {
                self.stats.tiles_dropped += 1;
                continue;
            }
            if self.incoming.len() >= self.config.incoming_tiles.max(1) {
                self.incoming.pop_front();
                self.stats.tiles_dropped += 1;
            }
            self.incoming.push_back(t);
        }
    }

    /// The tiles near the window (within a tile of it, as the relay's
    /// interest) that `frames`, passed on by the relay, press from
    /// untouched snow: what the relay merged of them. None in a world
    /// whose presses do not travel, or beyond the instances or the ray
    /// casts a message may make (a relay with the default press budget
    /// sends neither; counted as malformed, and the digests bring the
    /// tiles instead).
    fn press_passed_on(&mut self, frames: &[PressFrame]) -> Vec<SharedTile> {
        let (texel_m, side) = (self.world.settings.texel_m, self.world.settings.tile_side);
        let costed = crate::replicate::press::costed_casts(frames, texel_m, side).filter(|&(_, work)| work <= MAX_PASSED_ON_CASTS);
        let (Some(ground), Some((casts, _))) = (self.ground.as_ref(), costed) else {
            self.stats.malformed += 1;
            return Vec::new();
        };
        self.stats.press_frames_received += frames.len() as u64;
        let window = self.last_window;
        let near = |k: TileKey| window.is_none_or(|(first, resolution)| near_window(k, side, first, resolution));
        let pressed = crate::replicate::press::press_tiles_where(frames, &casts, (&self.world.settings, ground, side), near);
        self.stats.tiles_from_presses += pressed.len() as u64;
        pressed
    }

    /// The connection to the relay was made again (to the same relay or to
    /// one restarted from its store): the peer says `Hello` again, and
    /// deltas in flight are sent again once it is welcomed. The replica is
    /// kept, so the digests that follow give the relay whatever it lacks.
    pub fn reconnect(&mut self) {
        self.welcomed = false;
        self.in_sync = false;
        self.synced_once = false;
        self.refused = false;
        self.last_hello_s = None;
        self.last_presence_s = f64::NEG_INFINITY;
        self.reported.clear();
        self.last_digest_s = f64::NEG_INFINITY;
        for flight in std::mem::take(&mut self.unacked).into_values() {
            self.resend(flight);
        }
        // The relay may be another (restarted from its store): nothing is
        // known to be there, so the next copies go whole.
        self.acked.clear();
        self.sent.clear();
        // The relay's `Welcome` says again whether it presses.
        self.presses.clone_from(&self.ground);
        self.push(self.hello());
    }

    /// This peer's `Hello`, encoded.
    fn hello(&self) -> Vec<u8> {
        encode(&Message::Hello { world: self.world.clone(), name: self.name.clone(), presses: self.ground.is_some() })
    }

    /// Changes how the peer paces itself and what it keeps, from the next
    /// [`SnowPeer::update`] on (a game's settings changed while it runs).
    /// Queues and the replica over their new bounds shrink as they are next
    /// used.
    pub fn set_config(&mut self, config: PeerConfig) {
        self.config = config;
    }

    /// Where this peer's deformers are now (world x, z in m; at most 256
    /// are sent): where the relay lets it write.
    pub fn set_deformers(&mut self, world_xz: &[[f64; 2]]) {
        self.deformers = world_xz.iter().take(MAX_DEFORMERS).copied().collect();
        if !self.welcomed {
            for &p in &self.deformers {
                let new = self.trail.iter().all(|q| (p[0] - q[0]).hypot(p[1] - q[1]) > REPORTED_SLACK_M);
                if new && self.trail.len() + self.deformers.len() < MAX_DEFORMERS {
                    self.trail.push(p);
                }
            }
        }
    }

    /// One step, at `now_s` seconds of the caller's clock (only intervals
    /// matter): joins the relay's clock once welcomed, takes the snow's
    /// changed tiles into the replica and queues them, re-merges replica
    /// tiles over texels the window newly exposed, merges received tiles
    /// into the replica and the snow, resends deltas not acknowledged in
    /// time, and sends `Presence`, deltas (at most every
    /// `delta_interval_s`, coalesced per tile) and `Digest` when due.
    /// Before the relay answers it only resends its `Hello`.
    pub fn update(&mut self, snow: &mut dyn SharedSnow, now_s: f64) {
        let c = CatchUp { max_fallen_m: self.world.settings.max_fallen_m };
        let side = self.world.settings.tile_side;
        if self.welcomed
            && !self.joined
            && let Some(clock) = self.relay_clock
        {
            snow.join_clock(clock);
            self.joined = true;
        }
        let frames = snow.take_press_frames();
        if self.presses.is_some() {
            self.frames_pending.extend(frames);
            while self.frames_pending.len() > MAX_PENDING_FRAMES {
                // Their presses still reach the relay, in the tiles.
                self.frames_pending.pop_front();
                self.stats.press_frames_dropped += 1;
            }
        }
        for t in snow.take_changed_tiles() {
            if t.side != side || !t.is_consistent() {
                continue;
            }
            self.to_send.insert(t.key);
            merge_into(&mut self.replica, t, c);
            self.changed();
        }
        let window = snow.window();
        if window != self.last_window {
            self.changed();
            if let Some((first, resolution)) = window {
                let exposed: Vec<SharedTile> = window_keys(first, resolution, side)
                    .filter(|k| !self.last_window.is_some_and(|(f, r)| tile_inside(*k, side, f, r)))
                    .filter_map(|k| self.replica.get(&k).cloned())
                    .collect();
                if !exposed.is_empty() {
                    snow.merge_tiles(&exposed);
                }
            }
            self.last_window = window;
        }
        if !self.own_pressed.is_empty() {
            snow.merge_tiles(&std::mem::take(&mut self.own_pressed));
        }
        if !self.incoming.is_empty() {
            self.tiles_since_digest_s = Some(now_s);
            let incoming: Vec<SharedTile> = self.incoming.drain(..).collect();
            for t in &incoming {
                if merge_into(&mut self.replica, t.clone(), c) {
                    self.stats.tiles_merged += 1;
                    self.changed();
                }
                // The relay holds what it sent (its copies only grow), so a
                // tile this peer changes too goes beyond that, not with it.
                merge_into(&mut self.acked, t.clone(), c);
            }
            snow.merge_tiles(&incoming);
        }
        self.trim_replica();
        if !self.welcomed {
            match self.last_hello_s {
                None => self.last_hello_s = Some(now_s),
                Some(at) if !self.refused && now_s - at >= self.config.resend_after_s => {
                    self.last_hello_s = Some(now_s);
                    self.push(self.hello());
                }
                Some(_) => {}
            }
            return;
        }
        self.send_due(now_s, window, snow.share_clock());
    }

    /// What a welcomed peer sends when due at `now_s`: `Presence` (also
    /// before deltas when its deformers appeared or moved since the last),
    /// the resends of deltas not acknowledged in time, the deltas, and
    /// `Digest` (of the window, at `snow_clock`).
    fn send_due(&mut self, now_s: f64, window: Option<([i64; 2], u32)>, snow_clock: ShareClock) {
        let c = CatchUp { max_fallen_m: self.world.settings.max_fallen_m };
        let late: Vec<u64> = self.unacked.iter().filter(|(_, f)| now_s - f.at_s >= self.config.resend_after_s).map(|(&s, _)| s).collect();
        for seq in late {
            if let Some(flight) = self.unacked.remove(&seq) {
                self.stats.resends += 1;
                self.resend(flight);
            }
        }
        // Press frames wait until the oldest is an interval old on the
        // snow's clock (a message then carries several, which code much
        // smaller together), or the snow's time stopped (a run about to end).
        let stopped = snow_clock.time_s <= self.last_snow_s;
        self.last_snow_s = snow_clock.time_s;
        let frames_ripe = self.frames_pending.front().is_some_and(|f| stopped || snow_clock.time_s - f.clock.time_s >= self.config.press_interval_s);
        let deltas_due = (!self.to_send.is_empty() || frames_ripe) && now_s - self.last_delta_s >= self.config.delta_interval_s;
        // Deltas go after a `Presence` that says where they were pressed: a
        // relay refuses (and still acknowledges) a tile far from every
        // deformer it knows, so deformers that appeared (a first report sent
        // on the welcome, before the game set any) or jumped since the last
        // report are told first, not at the next interval.
        let stale = deltas_due && deformers_moved(&self.reported, &self.deformers);
        if (stale || now_s - self.last_presence_s >= self.config.presence_interval_s)
            && let Some((first, resolution)) = window
        {
            self.last_presence_s = now_s;
            self.reported.clone_from(&self.deformers);
            // The deformers first (the relay follows each by its place in
            // the list), then, once, the way they came before the welcome.
            let mut deformers = self.deformers.clone();
            deformers.extend(self.trail.drain(..).take(MAX_DEFORMERS.saturating_sub(self.deformers.len())));
            self.push(encode(&Message::Presence { window: first, resolution, deformers }));
        }
        if deltas_due {
            self.last_delta_s = now_s;
            self.send_tiles(now_s);
        }
        let digest_every = if self.synced_once && !self.digest_requested { self.config.synced_digest_interval_s } else { self.config.digest_interval_s };
        // Before the first `InSync`: also once the relay's tiles (a late
        // join's backlog, say) have stopped coming, while none of this
        // peer's own changes waits (a peer pressing as it goes could not be
        // answered `InSync` anyway: its digest would be extra work for the relay).
        let settled = !self.synced_once && self.unacknowledged() == 0 && self.tiles_since_digest_s.is_some_and(|t| now_s - t >= self.config.settled_digest_s);
        if (now_s - self.last_digest_s >= digest_every || settled)
            && let Some((first, resolution)) = window
        {
            self.last_digest_s = now_s;
            self.digest_requested = false;
            self.tiles_since_digest_s = None;
            self.send_digest(snow_clock, first, resolution, c);
        }
    }

    /// Whether this peer holds everything the relay has over its window and
    /// the relay has everything it changed: the relay answered its last
    /// digest with `InSync`, nothing changed since, and no change waits for
    /// an acknowledgement. A program about to stop (a headless run) pumps
    /// until this holds.
    #[must_use]
    pub fn is_synced(&self) -> bool {
        self.in_sync && self.unacknowledged() == 0 && self.incoming.is_empty()
    }

    /// Asks for a digest as soon as `digest_interval_s` has passed since the
    /// last one, whatever `synced_digest_interval_s` says (a program about
    /// to stop wants `InSync` soon).
    pub fn request_digest(&mut self) {
        self.digest_requested = true;
    }

    /// Something changed the replica or the window: the last digest no
    /// longer describes it.
    fn changed(&mut self) {
        self.activity += 1;
        self.in_sync = false;
    }

    /// The next message to send to the relay.
    pub fn poll_transmit(&mut self) -> Option<Vec<u8>> {
        let bytes = self.outbox.pop_front()?;
        self.stats.messages_out += 1;
        self.stats.bytes_out += bytes.len() as u64;
        Some(bytes)
    }

    /// Whether the relay has welcomed this peer into its world.
    #[must_use]
    pub fn is_welcomed(&self) -> bool {
        self.welcomed
    }

    /// Changes not yet acknowledged by the relay: deltas in flight plus
    /// tiles and press frames waiting to be sent. A headless run waits for
    /// 0 before exiting.
    #[must_use]
    pub fn unacknowledged(&self) -> usize {
        self.unacked.len() + self.to_send.len() + self.frames_pending.len()
    }

    /// A message not acknowledged in time (or in flight across a
    /// reconnection): its tiles go again, as the replica has them then, and
    /// its frames before any waiting (the tiles are sent beyond them).
    fn resend(&mut self, flight: InFlight) {
        self.to_send.extend(flight.keys.into_iter().filter(|k| self.replica.contains_key(k)));
        for f in flight.frames.into_iter().rev() {
            self.frames_pending.push_front(f);
        }
    }

    /// Counters since the peer was made (printed with `{:?}`; their fields
    /// are public with `low_level`).
    #[must_use]
    pub fn stats(&self) -> PeerStats {
        self.stats
    }

    fn push(&mut self, bytes: Vec<u8>) {
        if self.outbox.len() >= self.config.queue_messages.max(1) {
            self.outbox.pop_front();
            self.stats.outgoing_dropped += 1;
        }
        self.outbox.push_back(bytes);
    }

    /// Sends the tiles in `to_send` and the press frames waiting as
    /// numbered deltas, as many as the in-flight limit allows: `Presses`
    /// when frames go (each tile then only beyond what the presses the
    /// relay is sent make of it), else `Tiles`.
    fn send_tiles(&mut self, now_s: f64) {
        while (!self.to_send.is_empty() || !self.frames_pending.is_empty()) && self.unacked.len() < self.config.max_unacknowledged.max(1) {
            let (frames, pressed) = self.take_frames();
            let coded = (!frames.is_empty()).then(|| super::presses::encode_frames(&frames));
            let overhead = coded.as_ref().map_or(TILES_OVERHEAD_BYTES, |c| PRESSES_OVERHEAD_BYTES + c.len());
            let mut keys = Vec::new();
            let mut parts: Vec<Vec<u8>> = Vec::new();
            let mut pending = Vec::new();
            let (mut bytes, mut texels) = (overhead, 0usize);
            while let Some(&key) = self.to_send.first() {
                let (tile, copy) = match self.what_to_send(key) {
                    Outgoing::Nothing => {
                        self.to_send.remove(&key);
                        continue;
                    }
                    Outgoing::Explained(copy) => {
                        // The presses carry all of it: acknowledged with this message.
                        self.stats.tiles_as_presses += 1;
                        self.to_send.remove(&key);
                        keys.push(key);
                        pending.push(copy);
                        continue;
                    }
                    Outgoing::Tile(tile, copy) => (tile, copy),
                };
                let encoded = encode_tile(&tile);
                if overhead + encoded.len() > MAX_MESSAGE_BYTES || tile.texels() > MAX_MESSAGE_TEXELS {
                    self.stats.tile_too_large += 1;
                    self.to_send.remove(&key);
                    continue;
                }
                if parts.len() == MAX_TILES || bytes + encoded.len() > MAX_MESSAGE_BYTES || texels + tile.texels() > MAX_MESSAGE_TEXELS {
                    break;
                }
                bytes += encoded.len();
                texels += tile.texels();
                self.to_send.remove(&key);
                self.wanted.remove(&key);
                keys.push(key);
                parts.push(encoded);
                pending.push(copy);
            }
            if parts.is_empty() && frames.is_empty() {
                if keys.is_empty() {
                    break;
                }
                // Only tiles the presses in flight explain: nothing to send now.
                let c = CatchUp { max_fallen_m: self.world.settings.max_fallen_m };
                for copy in pending {
                    merge_into(&mut self.acked, copy, c);
                }
                continue;
            }
            let seq = self.next_seq;
            self.next_seq = self.next_seq.wrapping_add(1);
            let refs: Vec<&[u8]> = parts.iter().map(Vec::as_slice).collect();
            self.stats.tiles_sent += parts.len() as u64;
            self.stats.press_frames_sent += frames.len() as u64;
            let message = match &coded {
                Some(c) => presses_message(seq, (frames.len(), c), &refs),
                None => tiles_message(seq, &refs),
            };
            self.stats.tile_bytes_out += message.len() as u64;
            self.push(message);
            self.unacked.insert(seq, InFlight { at_s: now_s, keys, frames, pressed });
            for tile in pending {
                self.sent.insert(tile.key, (seq, tile));
            }
        }
    }

    /// The press frames for the next message (at most
    /// [`MAX_PRESS_FRAMES`]), into the log the tiles are explained from and
    /// pressed into the replica, with the tiles they press (what the relay
    /// holds once it acknowledges them).
    fn take_frames(&mut self) -> (Vec<PressFrame>, Vec<SharedTile>) {
        let n = self.frames_pending.len().min(MAX_PRESS_FRAMES);
        let frames: Vec<PressFrame> = self.frames_pending.drain(..n).collect();
        let texel_m = self.world.settings.texel_m;
        let casts: Vec<FrameCasts> = frames.iter().map(|f| f.casts(texel_m)).collect();
        // The replica holds what the relay is sent, so a digest made while
        // the window's own tiles of these presses are still on their way
        // agrees with the relay's copies (which the frames reach first).
        let mut pressed = Vec::new();
        if let Some(ground) = self.presses.as_ref().filter(|_| !frames.is_empty()) {
            let c = CatchUp { max_fallen_m: self.world.settings.max_fallen_m };
            pressed = crate::replicate::press::press_tiles(&frames, &casts, &self.world.settings, ground, self.world.settings.tile_side);
            for t in &pressed {
                if merge_into(&mut self.replica, t.clone(), c) {
                    self.changed();
                }
            }
            self.own_pressed.extend(pressed.iter().cloned());
        }
        self.frames_log.extend(frames.iter().cloned().zip(casts));
        let newest = self.frames_log.back().map_or(f64::NEG_INFINITY, |(f, _)| f.clock.time_s);
        while self.frames_log.front().is_some_and(|(f, _)| f.clock.time_s < newest - PRESS_LOG_S) || self.frames_log.len() > MAX_PRESS_LOG {
            self.frames_log.pop_front();
        }
        (frames, pressed)
    }

    /// What tile `key` of the replica sends: whole when the relay asked
    /// for it or holds nothing known of it and no press explains it; else
    /// what it adds to the acknowledged copy and the presses sent
    /// ([`SharedTile::beyond`]), or nothing. With each, the copy the relay
    /// holds once it acknowledges.
    fn what_to_send(&mut self, key: TileKey) -> Outgoing {
        let Some(tile) = self.replica.get(&key) else { return Outgoing::Nothing };
        let c = CatchUp { max_fallen_m: self.world.settings.max_fallen_m };
        if self.wanted.contains(&key) {
            return Outgoing::Tile(tile.clone(), tile.clone());
        }
        let mut explained = self.explained(key, tile.clock.time_s);
        // What the presses in flight make of the tile message by message
        // (the replica holds that too): the relay holds it once they arrive.
        for t in self.unacked.values().flat_map(|f| &f.pressed).filter(|t| t.key == key) {
            match &mut explained {
                Some(e) => {
                    e.merge(t, c);
                }
                None => explained = Some(t.clone()),
            }
        }
        let base = match (self.acked.get(&key), &explained) {
            (None, None) => return Outgoing::Tile(tile.clone(), tile.clone()),
            (Some(a), None) => a.clone(),
            (None, Some(e)) => e.clone(),
            (Some(a), Some(e)) => {
                let mut b = a.clone();
                b.merge(e, c);
                b
            }
        };
        match tile.beyond(&base, c) {
            Some(delta) => {
                self.stats.tiles_as_deltas += 1;
                let mut copy = delta.clone();
                copy.merge(&base, c);
                Outgoing::Tile(delta, copy)
            }
            None if explained.is_some() => Outgoing::Explained(base),
            None => Outgoing::Nothing,
        }
    }

    /// What the press frames logged up to `time_s` make of tile `key` from
    /// untouched snow (`None` when none reaches it): every machine that
    /// receives them makes the same.
    fn explained(&self, key: TileKey, time_s: f64) -> Option<SharedTile> {
        let ground = self.presses.as_ref()?;
        let side = self.world.settings.tile_side;
        let mut tile: Option<SharedTile> = None;
        for (frame, casts) in self.frames_log.iter().filter(|(f, _)| f.clock.time_s <= time_s) {
            if let Some(t) = crate::replicate::press::press_tile(frame, casts, key, side, (&self.world.settings, ground), tile.take()) {
                tile = Some(t);
            }
        }
        tile
    }

    /// Digests of the replica's tiles over the window (the nearest
    /// [`MAX_KEYS`]), all brought to one clock: the snow's, or a later
    /// tile's.
    fn send_digest(&mut self, snow_clock: ShareClock, first: [i64; 2], resolution: u32, c: CatchUp) {
        let side = self.world.settings.tile_side;
        let centre = [first[0] as f64 + f64::from(resolution) / 2.0, first[1] as f64 + f64::from(resolution) / 2.0];
        let mut keys: Vec<TileKey> = self.replica.keys().copied().filter(|k| overlaps_window(*k, side, first, resolution)).collect();
        keys.sort_by(|a, b| distance2(*a, side, centre).total_cmp(&distance2(*b, side, centre)).then(a.cmp(b)));
        keys.truncate(MAX_KEYS);
        let mut clock = snow_clock;
        for k in &keys {
            if let Some(t) = self.replica.get(k) {
                clock = clock.later(&t.clock);
            }
        }
        let mut entries = Vec::with_capacity(keys.len());
        for k in keys {
            if let Some(t) = self.replica.get_mut(&k) {
                // Catching up loses nothing every copy would not lose too.
                t.catch_up(&clock, c);
                entries.push((k, t.digest()));
            }
        }
        self.last_digest = Some((clock, self.activity));
        self.push(encode(&Message::Digest { clock, window: first, resolution, entries }));
    }

    /// Keeps the replica within its cap, dropping the tiles farthest from
    /// the window (tiles waiting to be sent last).
    fn trim_replica(&mut self) {
        let cap = self.config.replica_tiles.max(1);
        if self.replica.len() <= cap {
            return;
        }
        let side = self.world.settings.tile_side;
        let centre = self.last_window.map_or([0.0, 0.0], |(f, r)| [f[0] as f64 + f64::from(r) / 2.0, f[1] as f64 + f64::from(r) / 2.0]);
        let mut keys: Vec<TileKey> = self.replica.keys().copied().collect();
        keys.sort_by(|a, b| {
            let waiting = |k: &TileKey| self.to_send.contains(k);
            waiting(a).cmp(&waiting(b)).then(distance2(*b, side, centre).total_cmp(&distance2(*a, side, centre))).then(a.cmp(b))
        });
        let excess = self.replica.len() - cap;
        for k in keys.into_iter().take(excess) {
            self.replica.remove(&k);
            self.to_send.remove(&k);
            self.acked.remove(&k);
            self.sent.remove(&k);
            self.wanted.remove(&k);
        }
    }
}

/// What the tools and the tests read of a [`SnowPeer`] beyond a game's API
/// (a named extension trait, so the peer has one shape with or without
/// `low_level`; `snowpack::low_level::SnowPeerExt` re-exports it).
pub trait SnowPeerExt: Sized {
    /// How the peer paces itself now.
    #[must_use]
    fn config(&self) -> &PeerConfig;

    /// The relay's number for this peer, once welcomed.
    #[must_use]
    fn peer_number(&self) -> Option<u32>;

    /// The replica's copy of a tile (what this peer knows of it).
    #[must_use]
    fn replica_tile(&self, key: TileKey) -> Option<&SharedTile>;
}

impl SnowPeerExt for SnowPeer {
    fn config(&self) -> &PeerConfig {
        &self.config
    }

    fn peer_number(&self) -> Option<u32> {
        self.number
    }

    fn replica_tile(&self, key: TileKey) -> Option<&SharedTile> {
        self.replica.get(&key)
    }
}

/// How far (m) a deformer may be from where the last `Presence` put it
/// before deltas wait for a new one. The relay lets a peer write within
/// 6 m (and a tile's half diagonal) of its reported deformers; 2 m of that
/// for the lag leaves 4 m for what the deformer presses around itself, and
/// a car at 5 m/s (1.25 m between the 0.25 s reports) sends no more
/// `Presence` than before: what the peer sends is unchanged but for
/// deformers that appear or jump.
const REPORTED_SLACK_M: f64 = 2.0;

/// Whether `now` differs from `reported` by a deformer that appeared, went
/// or moved more than [`REPORTED_SLACK_M`].
fn deformers_moved(reported: &[[f64; 2]], now: &[[f64; 2]]) -> bool {
    reported.len() != now.len() || reported.iter().zip(now).any(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]) > REPORTED_SLACK_M)
}

/// Merges `t` into the replica (inserting it when new); whether the replica changed.
fn merge_into(replica: &mut HashMap<TileKey, SharedTile>, t: SharedTile, c: CatchUp) -> bool {
    match replica.get_mut(&t.key) {
        Some(mine) => mine.merge(&t, c),
        None => {
            replica.insert(t.key, t);
            true
        }
    }
}

/// The keys of the tiles overlapping a window.
fn window_keys(first: [i64; 2], resolution: u32, side: u32) -> impl Iterator<Item = TileKey> {
    let last = [first[0].saturating_add(i64::from(resolution.max(1)) - 1), first[1].saturating_add(i64::from(resolution.max(1)) - 1)];
    let a = TileKey::containing(first[0], first[1], side);
    let b = TileKey::containing(last[0], last[1], side);
    (a.row..=b.row).flat_map(move |row| (a.col..=b.col).map(move |col| TileKey::new(col, row)))
}

/// Whether tile `k` lies wholly inside the window.
fn tile_inside(k: TileKey, side: u32, first: [i64; 2], resolution: u32) -> bool {
    let t = k.first_texel(side);
    let s = i64::from(side);
    let r = i64::from(resolution);
    t[0] >= first[0] && t[1] >= first[1] && t[0].saturating_add(s) <= first[0].saturating_add(r) && t[1].saturating_add(s) <= first[1].saturating_add(r)
}

/// Whether tile `k` overlaps the window.
fn overlaps_window(k: TileKey, side: u32, first: [i64; 2], resolution: u32) -> bool {
    let t = k.first_texel(side);
    let s = i64::from(side);
    let r = i64::from(resolution);
    t[0] < first[0].saturating_add(r) && t[0].saturating_add(s) > first[0] && t[1] < first[1].saturating_add(r) && t[1].saturating_add(s) > first[1]
}

/// Whether tile `k` is within a tile of the window (the relay's interest).
fn near_window(k: TileKey, side: u32, first: [i64; 2], resolution: u32) -> bool {
    let s = i64::from(side);
    overlaps_window(k, side, [first[0].saturating_sub(s), first[1].saturating_sub(s)], resolution.saturating_add(2 * side))
}

/// Squared distance (texels²) from a tile's centre to `centre`.
fn distance2(k: TileKey, side: u32, centre: [f64; 2]) -> f64 {
    let t = k.first_texel(side);
    let h = f64::from(side) / 2.0;
    let (dx, dz) = (t[0] as f64 + h - centre[0], t[1] as f64 + h - centre[1]);
    dx * dx + dz * dz
}
