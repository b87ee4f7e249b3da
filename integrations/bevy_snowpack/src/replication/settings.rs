//! What the shared snow is made of: [`SnowReplicationSettings`] (the
//! resource, the same on the server and the clients) and the server relay's
//! store, [`SnowRelayStore`].

use std::path::PathBuf;

use bevy::prelude::*;
use snowpack_share::{PeerConfig, RelayConfig, StoreConfig, WorldIdentity};

/// What the shared snow is made of (a resource, the same on the server and
/// the clients). Applied when changed: `peer` (clients) and `relay` (the
/// server). Fixed when a client first joins: `tile_side`, `gather_interval_s`
/// and `peer_name` (a change warns and is ignored until the app restarts).
/// Read when the server starts its relay (`ServerState` becomes `Running`):
/// `world` and `store` (a change while it runs warns and waits for the next
/// start).
#[derive(Resource, Clone, Debug, PartialEq)]
pub struct SnowReplicationSettings {
    /// Side of a shared tile (texels, 8..=256). Every client of a world must
    /// use the same side (the relay refuses another, naming it).
    pub tile_side: u32,
    /// A changed tile is gathered at most this often (s of the snow's time).
    pub gather_interval_s: f64,
    /// How a client's peer paces itself (presence, digests, deltas, resends).
    pub peer: PeerConfig,
    /// How the server's relay paces and polices its clients (the radius
    /// around their entities they may write in, byte and tile rates).
    pub relay: RelayConfig,
    /// The client's name in the relay's logs.
    pub peer_name: String,
    /// On the server: the world it serves, from its own configuration
    /// (`SnowDeformation::world_identity_for` of the snow its clients run, with
    /// `tile_side`). A client of another world is refused naming what
    /// differs, the first one too; a client never chooses the world. `None`:
    /// a listen server serves its own snow's world; a dedicated server
    /// serves nobody until it is set (it warns).
    pub world: Option<WorldIdentity>,
    /// On the server: where the relay keeps its tiles (and the world and its
    /// clock), so a restarted server, or a player joining an empty one,
    /// still sees every trail. `None`: in memory, for the server's life.
    pub store: Option<SnowRelayStore>,
}

impl Default for SnowReplicationSettings {
    fn default() -> Self {
        Self {
            tile_side: 32,
            gather_interval_s: 0.25,
            peer: PeerConfig::default(),
            relay: RelayConfig::default(),
            peer_name: "bevy_snowpack".into(),
            world: None,
            store: None,
        }
    }
}

/// The server relay's tile store (`snowpack::TileStore`, the format
/// `snowpack server --store` keeps: either can serve the other's folder).
#[derive(Clone, Debug, PartialEq)]
pub struct SnowRelayStore {
    /// The store's folder (created when missing; one server at a time, and
    /// not a folder the snow's own [`crate::SnowStoreSettings`] uses: the
    /// relay's tiles hold deficits, not heights).
    pub dir: PathBuf,
    /// Its disk budget.
    pub config: StoreConfig,
}

impl SnowRelayStore {
    /// A store in `dir` with the library's default budget.
    #[must_use]
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self { dir: dir.into(), config: StoreConfig::default() }
    }
}
