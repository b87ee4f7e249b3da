//! snowpack-share: the CPU core of snowpack's shared snow, without a GPU.
//!
//! One world's trails on every player's machine: the snow of a tile is a
//! deficit below its rest height, copies brought to the same world clock
//! merge texel by texel ([`SharedTile::merge`]), and the wire format carries
//! them between a game's clients ([`SnowPeer`]) and its server
//! ([`SnowRelay`], which keeps the world's tiles in a [`TileStore`]).
//!
//! This crate depends on no GPU, windowing or image crate: a dedicated
//! server (`snowpack server`, bevy_snowpack's `server` feature) builds it
//! alone. The `snowpack` crate's GPU side (gathering changed tiles from the
//! window, merging tiles into it, streaming tiles in and out) builds on it
//! and re-exports what it exported before at the same paths
//! (`snowpack::SnowRelay`, `snowpack::low_level::replicate::tile`, ...).
//!
//! A relay owns no socket: bytes go in through `receive` and come out of
//! `poll_transmit`, over whatever transport the game uses.
//!
//! ```
//! use snowpack_share::{RelayConfig, SnowRelay};
//!
//! let mut relay = SnowRelay::new(RelayConfig::default());
//! // A datagram that is not a message is refused and counted, never a panic.
//! relay.receive(1, b"not a message", 0.0);
//! let stats = relay.stats();
//! assert_eq!((stats.messages_in, stats.rejected.total(), stats.peers), (1, 1, 0));
//! ```
//!
//! | module | what |
//! |---|---|
//! | [`replicate`] | tiles and their clock, the world identity, the wire messages, peers and relays, and the presses that travel instead of the snow they pressed ([`replicate::press`]) |
//! | [`mechanics`] | snow with mass: density from compaction, hardness, Bekker's sinkage and resistance |
//! | [`persist`] | the tile type, its compressed file format, the crash-safe store on disk |
//! | [`error`] | the errors in detail; the opaque ones at the root |
//! | `bytes` | the little-endian reader the formats share |
//!
//! Feature `low_level` (snowpack's `low_level` turns it on) shows in the
//! docs what snowpack's app, tools and tests use beyond a game's API, and
//! adds `testing`'s support for tests.

/// Little-endian fields read in order (the codec's, the wire's and
/// snowpack's saved state's one reader).
#[cfg_attr(not(feature = "low_level"), doc(hidden))]
pub mod bytes;
pub mod error;
pub mod mechanics;
pub mod persist;
pub mod replicate;
#[cfg(any(test, feature = "low_level"))]
pub mod testing;

pub use error::front::{ShareError, ShareErrorKind, StoreError, StoreErrorKind};
pub use persist::{StoreConfig, TileData, TileKey, TileStore};
pub use replicate::tile::SNOW_QUANTUM_M;
pub use replicate::{
    CatchUp, Message, PeerConfig, PeerId, PeerStats, RelayConfig, RelayRejections, RelayStats, ShareClock, SharedSnow, SharedTile, SnowPeer, SnowRelay,
    WorldIdentity, WorldSnow, WorldSnowfall, WorldTerrain,
};
