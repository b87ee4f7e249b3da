//! What snowpack's own app, tools and tests ask of a `TileStreamer` beyond
//! the front door: [`TileStreamerExt`], declared here and implemented beside
//! the streamer.

use std::path::Path;
use std::time::Duration;

use super::config::StreamerConfig;
use super::lookup::TileLookup;
use super::stats::StoreStats;
use crate::persist::{StoreError, TileData, TileKey};

/// What snowpack's own app, tools and tests do with a [`TileStreamer`](super::TileStreamer) beyond the front door: tile-level requests and lookups, waits, saved state and counters.
/// A named item of `low_level` (an extension trait): [`TileStreamer`](super::TileStreamer) has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait TileStreamerExt: Sized {
    /// Keeps tiles of `side` texels in memory only: no store, no worker
    /// thread, no files. `TileStreamer::lookup` answers at once: the tile
    /// put last (handed out once: it leaves the cache, as the window holds it
    /// from then on and puts it back when it leaves), or `Ready(None)` (fresh
    /// snow) for one never put, dropped by the budget or untouched. `config` bounds the memory: beyond it the
    /// least recently used tiles are dropped and come back as fresh snow
    /// (each counted in `StoreStats::lost`). Untouched tiles (every height
    /// at rest, no footprint, no snowfall plane) are not kept, as fresh snow
    /// is the same. `TileStreamer::write_state` (and so saving) fails:
    /// saving needs a disk store.
    #[must_use]
    fn in_memory(side: u32, config: StreamerConfig) -> Self;

    /// Whether tiles are kept in memory only ([`TileStreamer::in_memory`](super::TileStreamer::in_memory)).
    #[must_use]
    fn is_memory_only(&self) -> bool;

    /// Texels per tile side.
    #[must_use]
    fn side(&self) -> u32;

    /// The store's directory (empty for a memory-only streamer).
    #[must_use]
    fn dir(&self) -> &Path;

    /// Whether [`TileStreamer::lookup`](super::TileStreamer::lookup) would answer `Ready` now (the tile is
    /// in memory or known to be absent, or the worker has stopped). Does not
    /// drain replies or start a load: call [`TileStreamer::poll`](super::TileStreamer::poll) and
    /// [`TileStreamer::request`](super::TileStreamer::request) for that.
    #[must_use]
    fn is_ready(&self, key: TileKey) -> bool;

    /// Starts loading a tile the window will soon need (non-blocking). Does
    /// nothing if it is cached, known to be absent, or already loading.
    fn request(&mut self, key: TileKey);

    /// A tile's stored state if it is at hand (non-blocking): a copy from
    /// memory, `Ready(None)` if the store has none, otherwise `Pending` (and
    /// the load is started). Drains the worker's replies first, as
    /// [`TileStreamer::poll`](super::TileStreamer::poll) does.
    fn lookup(&mut self, key: TileKey) -> TileLookup;

    /// Hands a tile to the store (non-blocking): it becomes the cached,
    /// newest version at once and is written behind by the worker. A tile of
    /// the wrong side or with planes of the wrong length is refused with an
    /// error in [`TileStreamer::take_errors`](super::TileStreamer::take_errors).
    fn put(&mut self, tile: TileData);

    /// Takes the worker's replies into the cache, the statistics and the
    /// errors (non-blocking). Call once a frame.
    fn poll(&mut self);

    /// Blocks until every key is ready (in memory or known absent): for the
    /// first placement of the window and for loading a save. A tile whose
    /// read failed before is read again. Read errors do not stop it (those
    /// tiles are answered as fresh snow standing in for them, and the
    /// errors are in [`TileStreamer::take_errors`](super::TileStreamer::take_errors)); only a stopped worker does. If the
    /// keys together exceed the memory budget, the first may have been
    /// dropped again by the time it returns. Gives up after
    /// [`StreamerConfig::wait_limit`] with [`crate::StoreErrorKind::TimedOut`].
    fn wait_for(&mut self, keys: &[TileKey]) -> Result<(), StoreError>;

    /// [`Self::wait_for`] giving up after `limit` with
    /// [`crate::StoreErrorKind::TimedOut`]; the tiles keep loading and a later
    /// [`Self::lookup`] or wait finds them.
    fn wait_for_within(&mut self, keys: &[TileKey], limit: Duration) -> Result<(), StoreError>;

    /// The errors since the last call, for the game to show or log. A
    /// corrupt tile is reported here and answered as `Ready(None)`.
    fn take_errors(&mut self) -> Vec<StoreError>;

    /// The counters now (disk numbers as of the worker's last reply).
    #[must_use]
    fn stats(&self) -> StoreStats;

    /// Stores a small named blob (blocking, ordered after the writes queued
    /// before it); see [`TileStore::write_state`](crate::persist::store::TileStoreExt::write_state). A memory-only streamer
    /// has nowhere to put it: [`StoreError::NoDisk`]. Gives up after
    /// [`StreamerConfig::wait_limit`] with [`crate::StoreErrorKind::TimedOut`] (the
    /// write stays queued and may still be done).
    fn write_state(&mut self, name: &str, bytes: Vec<u8>) -> Result<(), StoreError>;

    /// From now on the store writes tiles for the next save, beside the
    /// saved ones ([`TileStore::begin_saves`](crate::persist::store::TileStoreExt::begin_saves)): a crash before
    /// [`Self::commit_save`] returns leaves the last complete save, every
    /// tile and state of it. Ordered after the writes queued before it;
    /// nothing for a memory-only streamer.
    fn begin_saves(&mut self);

    /// Completes a save with the named state `bytes` ([`TileStore::commit`](crate::persist::store::TileStoreExt::commit)):
    /// blocking, ordered after the writes queued before it, so call it once
    /// [`TileStreamer::flush`](super::TileStreamer::flush) has written the save's tiles. A memory-only streamer
    /// has nowhere to put it: [`StoreError::NoDisk`]. Gives up after
    /// [`StreamerConfig::wait_limit`] with [`StoreError::TimedOut`] (the
    /// commit stays queued and may still be done: the save is then complete).
    fn commit_save(&mut self, name: &str, bytes: Vec<u8>) -> Result<(), StoreError>;

    /// Reads a named blob (blocking, ordered after the writes queued before
    /// it); `Ok(None)` if there is none (always, for a memory-only streamer).
    /// Gives up after [`StreamerConfig::wait_limit`] with [`crate::StoreErrorKind::TimedOut`].
    fn read_state(&mut self, name: &str) -> Result<Option<Vec<u8>>, StoreError>;
}
