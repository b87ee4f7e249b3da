//! How a relay paces and polices its peers: [`RelayConfig`].

use super::interest::MAX_INTEREST_TILES;

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
    /// counted in [`RelayStats::tiles_forgotten`](super::RelayStats::tiles_forgotten)).
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
    /// (counted in [`RelayRejections::teleports`](super::RelayRejections::teleports)) and lets the peer write
    /// nothing there. 60 m/s fits vehicles; raise it for projectiles. Not
    /// applied to positions a game server reports ([`SnowRelay::report_deformers`](super::SnowRelay::report_deformers)).
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
    /// them are refused ([`RelayRejections::out_of_bounds`](super::RelayRejections::out_of_bounds)). Whatever this
    /// says, tiles whose texels do not fit in i32 (where no window can be)
    /// are refused.
    pub bounds_m: Option<[f64; 4]>,
    /// Ray casts a second a peer's `Presses` may make the relay do (a
    /// token bucket: each shape instance times the texels of the tiles its
    /// bounds cover). A car's four treaded wheels at 3 m/s and 1.6 cm
    /// texels cost 4.5 million a second (0.19 s of the relay's CPU for 7 s
    /// of driving); a message beyond the bucket is refused whole.
    pub press_casts_per_s: u64,
    /// The press bucket's size.
    pub burst_press_casts: u64,
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
            press_casts_per_s: 8 << 20,
            burst_press_casts: 16 << 20,
        }
    }
}
