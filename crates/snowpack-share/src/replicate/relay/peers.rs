//! What the relay keeps per peer: [`PeerId`], where it is in the handshake,
//! its interest, the police's memory of its deformers, its rate buckets and
//! what is queued for it.

use std::collections::{BTreeSet, HashMap};

use super::bucket::Bucket;
use super::config::RelayConfig;
use super::interest::{KeyRect, MAX_INTEREST_TILES};
use super::outbox::Outbox;
use crate::persist::TileKey;
use crate::replicate::motion::{MotionHistory, MotionWork};
use crate::replicate::world::WorldIdentity;

/// A peer as the caller knows it (a connection number).
pub type PeerId = u64;

/// Where a peer is in the handshake.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Standing {
    New,
    Welcomed,
    Refused,
}

/// How long (s) after its welcome a peer's tiles and presses wait,
/// unacknowledged, for its first `Presence` (which the network may deliver
/// after them): a few of the peer's resends (one a second).
pub(super) const AWAIT_PRESENCE_S: f64 = 5.0;

/// What the relay keeps per peer; every collection in it is capped.
#[derive(Debug)]
pub(super) struct PeerState {
    pub(super) number: u32,
    pub(super) standing: Standing,
    /// Tiles the peer is sent (its window plus one tile of margin).
    pub(super) interest: Option<KeyRect>,
    /// Where its deformers were, in a grid hash.
    pub(super) history: MotionHistory,
    /// Until when `report_deformers` overrides the peer's own `Presence`.
    pub(super) authoritative_until: f64,
    /// When (relay time) the peer was last welcomed.
    pub(super) welcomed_s: f64,
    /// Its `Hello` said it presses the frames passed on to it (it holds
    /// the world's ground); otherwise it is sent their tiles.
    pub(super) presses: bool,
    pub(super) in_bytes: Bucket,
    pub(super) in_tiles: Bucket,
    pub(super) out_bytes: Bucket,
    pub(super) window_keys: Bucket,
    pub(super) query_points: Bucket,
    /// Ray casts its `Presses` may cost.
    pub(super) press_casts: Bucket,
    /// Tiles to send at the next send (coalesced).
    pub(super) pending: BTreeSet<TileKey>,
    /// Tiles of its interest that presses passed on to it pressed, and when
    /// (relay time): a digest that lacks them may have crossed them.
    pub(super) passed_on: HashMap<TileKey, f64>,
    pub(super) last_send_s: f64,
    /// The messages queued for it.
    pub(super) outbox: Outbox,
    pub(super) seq_out: u64,
}

impl PeerState {
    /// A peer just connected at `now`, numbered `number`: not yet welcomed,
    /// its buckets full.
    pub(super) fn new(number: u32, c: &RelayConfig, now: f64) -> Self {
        Self {
            number,
            standing: Standing::New,
            interest: None,
            history: MotionHistory::default(),
            authoritative_until: f64::NEG_INFINITY,
            welcomed_s: f64::NEG_INFINITY,
            presses: false,
            in_bytes: Bucket::full(f64::from(c.burst_bytes), now),
            in_tiles: Bucket::full(f64::from(c.burst_tiles), now),
            out_bytes: Bucket::full(f64::from(c.send_burst_bytes), now),
            window_keys: Bucket::full(f64::from(c.burst_window_keys.max(MAX_INTEREST_TILES as u32)), now),
            query_points: Bucket::full(f64::from(c.burst_query_points), now),
            press_casts: Bucket::full(c.burst_press_casts as f64, now),
            pending: BTreeSet::new(),
            passed_on: HashMap::new(),
            last_send_s: f64::NEG_INFINITY,
            outbox: Outbox::default(),
            seq_out: 0,
        }
    }

    /// Whether the peer's tiles wait at `now` for it to say where its
    /// deformers are: it has not (no `Presence`, nor a game server's
    /// report, within the deformer memory) and was welcomed less than
    /// [`AWAIT_PRESENCE_S`] ago. Later, a peer that never says is judged
    /// (and refused) as before rather than made to resend forever.
    pub(super) fn awaits_presence(&self, now: f64) -> bool {
        self.history.is_empty() && now - self.welcomed_s < AWAIT_PRESENCE_S
    }

    /// Whether the peer may write tile `key`: its centre is within `reach`
    /// (m) of one of the peer's deformer positions recorded since `oldest`.
    /// (A fixed number of grid look-ups, counted in `work`.)
    pub(super) fn may_write(&mut self, key: TileKey, world: &WorldIdentity, reach: f64, oldest: f64, work: &mut MotionWork) -> bool {
        let first = key.first_texel(world.settings.tile_side);
        let half = f64::from(world.settings.tile_side) / 2.0;
        let texel = f64::from(world.settings.texel_m);
        let centre = [(first[0] as f64 + half) * texel, (first[1] as f64 + half) * texel];
        self.history.near(centre, reach, oldest, work)
    }
}
