//! A relay's counters: [`RelayStats`], with what it refused by cause
//! ([`RelayRejections`]).

/// Everything a relay refused or dropped, by cause. Each refusal changed nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RelayRejections {
    /// Messages that did not decode.
    pub malformed: u64,
    /// Messages over [`MAX_MESSAGE_BYTES`](crate::replicate::MAX_MESSAGE_BYTES).
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
    /// `Presses` messages beyond the peer's press rate
    /// ([`super::RelayConfig::press_casts_per_s`]) or making more than
    /// 16,384 ray-cast instances, refused whole.
    pub rate_presses: u64,
    /// `Presses` in a world whose presses cannot travel (terrain its identity
    /// names by a digest only, a heightmap or a mesh; or with
    /// lying snow: [`crate::replicate::press::presses_travel`]), refused whole.
    pub unpressable: u64,
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
            + self.rate_presses
            + self.unpressable
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
    /// Messages handed out by [`SnowRelay::poll_transmit`](super::SnowRelay::poll_transmit).
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
    /// Frames of analytic presses received and pressed.
    pub press_frames: u64,
    /// Ray casts pressing them cost (bounded by the peers' press rate).
    pub press_casts: u64,
    /// Frames passed on to the peers watching what they pressed (a frame
    /// to two watchers counts twice), in place of the tiles they pressed.
    pub press_frames_sent: u64,
    /// `Tiles` and `Presses` messages left unacknowledged, and so sent
    /// again, because their peer, welcomed less than 5 s before, had not
    /// yet said where its deformers are (its first `Presence` still on its
    /// way): not judged, not refused.
    pub awaiting_presence: u64,
    /// Bytes of tiles in memory now.
    pub tile_bytes_in_memory: usize,
    /// Bytes queued for peers now (not yet handed out).
    pub queued_bytes: usize,
}
