//! Open-world persistence: the snow of tiles the player has left, kept in
//! memory (the default) or on disk and brought back when the player returns.
//!
//! The deformation window hands out whole tiles (`side`×`side` texels on the
//! global texel grid) as they leave the player's neighbourhood and asks for
//! them again when they come back into view. This module is the CPU side of
//! that: the tile type ([`TileData`]), its compressed file format
//! ([`codec`]), a crash-safe store with a disk budget ([`TileStore`]) and a
//! worker thread with a bounded memory cache that keeps compression and file
//! I/O off the frame's path ([`TileStreamer`], which without a store keeps
//! tiles in that cache alone: [`TileStreamer::in_memory`]). `docs/persistence.md`
//! explains the choices.
//!
//! The tile type, the codec, the disk and the store are the shared-snow
//! crate's (`snowpack_share::persist`: a server without a GPU keeps its
//! tiles with them), re-exported here at their old paths; the streamer is
//! this crate's.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

#[doc(hidden)]
pub use snowpack_share::persist::disk;
pub use snowpack_share::persist::store;
pub mod streamer;

pub use crate::error::StoreError;
pub use snowpack_share::persist::WhenFull;
pub use snowpack_share::persist::{SnowClock, StoreConfig, TileData, TileKey, TileStore, decode, encode};
pub use streamer::{StoreStats, StreamerConfig, TileLookup, TileStreamer};

/// Temporary directories for the streamer's unit tests (the shared-snow
/// crate's `testing::TestDir`).
#[cfg(test)]
pub(crate) use snowpack_share::testing as test_dir;
