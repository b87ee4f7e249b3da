//! Tiles off the frame's path: a worker thread owns the [`TileStore`] and
//! does all compression and file I/O; the frame talks to it through two
//! channels and a bounded memory cache, and never blocks (except in the
//! calls documented as blocking).
//!
//! Ordering: one channel carries every request to the single worker, which
//! answers them in order, except that loads go ahead of queued writes (a
//! slow disk, where every write syncs, must not hold back the tiles the
//! window waits for). A load queued after a put still sees that put's
//! version even if the cache has dropped it meanwhile: the worker answers it
//! from the queued write.
//!
//! Write-behind: [`TileStreamer::put`] puts the tile in the cache at once
//! and queues its write. A tile whose write failed stays in the cache as
//! dirty and is written again by the next [`TileStreamer::flush`] (and when
//! the streamer is dropped). The cache does not pin dirty tiles: if the
//! memory budget pushes one out while its last write had failed, it is gone
//! and counted in [`StoreStats::lost`] (keeping it would let a failing disk
//! grow memory without bound). A tile pushed out while its write is still
//! queued is not lost: the worker holds it until written.

mod cache;
mod config;
mod error_log;
mod ext;
mod lookup;
mod stand_ins;
mod stats;
#[cfg(test)]
mod tests;
mod worker;

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{RecvTimeoutError, TryRecvError};
use std::time::{Duration, Instant};

use cache::{Cached, Dirt, StreamerCache};
use error_log::ErrorLog;
use snowpack_share::persist::TileStoreExt;
use stand_ins::StandIns;
use worker::{DiskNumbers, Outcome, Reply, Request, Worker};

use super::store::tile_path;
use super::{StoreError, TileData, TileKey, TileStore};
use crate::deform::stamp::STAMP_EMPTY;

pub use config::StreamerConfig;
pub use ext::TileStreamerExt;
pub use lookup::TileLookup;
pub use stats::StoreStats;

/// Most keys remembered as absent from the store (16 bytes each, plus the set's overhead).
const MAX_ABSENT: usize = 1 << 16;

/// Streams tiles between the deformation window and a [`TileStore`] on a
/// worker thread, with a bounded memory cache; or, made with
/// `TileStreamer::in_memory` (`low_level`), keeps them in that cache alone. See the
/// module docs for the ordering, write-behind and memory-only policies.
pub struct TileStreamer {
    side: u32,
    /// The store's directory; empty for a memory-only streamer.
    dir: PathBuf,
    /// No store behind the cache (see [`TileStreamer::in_memory`]).
    memory_only: bool,
    config: StreamerConfig,
    /// The channels to the worker thread, and the thread.
    worker: Worker,
    /// The worker has stopped (reported once in `errors`).
    gone: bool,
    /// The tiles in memory, within the budget.
    cache: StreamerCache,
    /// Keys the store has answered "not there" for (and not put since);
    /// cleared when it reaches [`MAX_ABSENT`].
    absent: HashSet<TileKey>,
    /// Keys with a load in flight: the load's `seq`.
    loading: HashMap<TileKey, u64>,
    /// Keys with a write queued and not yet answered: the latest write's `seq`.
    unwritten: HashMap<TileKey, u64>,
    /// Errors for the game, and the one a flush in progress returns.
    errors: ErrorLog,
    /// Tiles the window stood in for with fresh snow, and what it made there.
    stand_ins: StandIns,
    /// Keys whose last read failed (I/O, not a damaged file): answered as
    /// fresh snow, stood in for, read again when next needed.
    unreadable: HashSet<TileKey>,
    stats: StoreStats,
}

impl TileStreamer {
    /// Starts the worker thread ("snowpack-tiles"), which owns `store`.
    ///
    /// If the thread cannot be started, the streamer answers every lookup
    /// with fresh snow and every blocking call with [`crate::StoreErrorKind::WorkerGone`].
    #[must_use]
    pub fn new(store: TileStore, config: StreamerConfig) -> Self {
        let stats = StoreStats { disk_tiles: store.disk_tiles(), disk_bytes: store.disk_bytes(), evicted: store.evicted(), ..StoreStats::default() };
        let (side, dir) = (store.side(), store.dir().to_owned());
        Self::with_worker(side, dir, config, Worker::spawn(store), stats)
    }

    /// A streamer with an empty cache around its channels to a worker
    /// (no request channel: memory only, no worker).
    fn with_worker(side: u32, dir: PathBuf, config: StreamerConfig, worker: Worker, stats: StoreStats) -> Self {
        let memory_only = !worker.has_channel();
        Self {
            side,
            dir,
            memory_only,
            config,
            worker,
            gone: false,
            cache: StreamerCache::new(config.memory_budget_bytes, memory_only),
            absent: HashSet::new(),
            loading: HashMap::new(),
            unwritten: HashMap::new(),
            errors: ErrorLog::default(),
            stand_ins: StandIns::default(),
            unreadable: HashSet::new(),
            stats,
        }
    }

    /// Whether a window move waits for the disk instead of holding
    /// ([`StreamerConfig::moves_wait_for_disk`]).
    pub(crate) fn moves_wait_for_disk(&self) -> bool {
        self.config.moves_wait_for_disk
    }

    /// Fresh snow stands in for `key`, whose stored version the window could
    /// not get in time (a late or hung disk) or could not read: from now on
    /// what the window makes there is not written over the stored version
    /// but kept, and the two are merged when the window next restores the
    /// tile ([`Self::take_for_restore`]) or at a save. The load goes on.
    /// Returns what the window made there before, if it was handed back and
    /// is not merged yet: to restore in place of fresh snow. Nothing to do
    /// for a memory-only streamer or a tile known to be absent.
    pub(crate) fn stand_in(&mut self, key: TileKey) -> Option<TileData> {
        if self.memory_only || self.absent.contains(&key) {
            return None;
        }
        let made = self.stand_ins.stand_in(key);
        self.request(key);
        made
    }

    /// What the window restores for `key`: as [`Self::lookup`], and for a
    /// tile it stood in for ([`Self::stand_in`]), what it made there meanwhile
    /// to merge with the stored version once that is here (the tile is then
    /// an ordinary one again). While the stored version cannot be read, what
    /// the window made comes back alone (`Ready`, still stood in for); while
    /// it is loading, `Pending`.
    pub(crate) fn take_for_restore(&mut self, key: TileKey) -> (TileLookup, Option<TileData>) {
        self.poll();
        if !self.stand_ins.contains(key) {
            return (self.lookup(key), None);
        }
        if self.cache.contains(key) {
            let made = self.stand_ins.remove(key);
            return (self.lookup(key), made);
        }
        if self.gone || self.unreadable.remove(&key) {
            // Read again the next time the tile is needed.
            return (TileLookup::Ready(self.stand_ins.take_made(key)), None);
        }
        self.request(key);
        (TileLookup::Pending, None)
    }

    /// Whether fresh snow (or what the window made there) stands in for `key`.
    pub(crate) fn stands_in(&self, key: TileKey) -> bool {
        self.stand_ins.contains(key)
    }

    /// Whether fresh snow stands in for any tile.
    pub(crate) fn stands_in_any(&self) -> bool {
        !self.stand_ins.is_empty()
    }

    /// Whether the stored version of stand-in `key` is in memory, ready
    /// to be merged into what the window has there now ([`Self::take_for_restore`]),
    /// as of the last poll (the frame's plan polls first).
    pub(crate) fn stand_in_arrived(&self, key: TileKey) -> bool {
        self.stand_ins.contains(key) && self.cache.contains(key)
    }

    /// Asks again for the stored version of stand-in `key` (a memory cache
    /// over its budget may have dropped it before its merge), unless its
    /// last read failed: that one is tried again when the tile is next
    /// restored and by every blocking wait, not every frame.
    pub(crate) fn ask_again_for_stand_in(&mut self, key: TileKey) {
        if !self.unreadable.contains(&key) {
            self.request(key);
        }
    }

    /// The tiles stood in for whose `made` version is held, waiting for a
    /// merge (a save merges them: `TileStreaming::checkpoint`).
    pub(crate) fn stand_ins_made(&self) -> Vec<TileKey> {
        self.stand_ins.held()
    }

    /// Why stand-in `key`'s stored version cannot be merged now: its last
    /// read failed (after [`Self::wait_for`], which tries it again). A save
    /// stops there rather than write over it.
    pub(crate) fn stand_in_error(&self, key: TileKey) -> Option<StoreError> {
        let read_error = self.stand_ins.read_error(key)?;
        if !self.unreadable.contains(&key) && !self.gone {
            return None;
        }
        let why = read_error.map_or_else(|| "the tile store's worker has stopped".to_owned(), str::to_owned);
        Some(StoreError::Io {
            path: tile_path(&self.dir, key),
            op: "read (what the window made in this tile's place is kept in memory and not saved over it)",
            source: std::io::Error::other(why),
        })
    }

    /// A stand-in resolved: the store has no version of it (never written,
    /// or set aside as damaged), so what the window made is the tile.
    fn resolve_absent(&mut self, key: TileKey) {
        if let Some(made) = self.stand_ins.remove(key) {
            self.insert(key, Cached::new(made, Dirt::Failed, false));
            self.queue_write(key);
        }
    }

    /// Blocks until every queued write is done, writing again the cached
    /// tiles whose earlier write failed. Returns the first write error of
    /// this flush; any others are in `TileStreamer::take_errors`. Gives up
    /// after [`StreamerConfig::wait_limit`] with [`crate::StoreErrorKind::TimedOut`]
    /// (the writes stay queued).
    pub fn flush(&mut self) -> Result<(), crate::error::front::StoreError> {
        if self.memory_only {
            // Nothing is ever waiting to be written.
            return Ok(());
        }
        self.poll();
        for key in self.cache.failed() {
            self.queue_write(key);
        }
        let seq = self.send(|seq| Request::Flush { seq })?;
        self.errors.begin_flush();
        let waited = self.wait(seq, || "the queued tile writes to finish (flush)".to_owned());
        let first = self.errors.end_flush();
        if let Err(gone) = waited {
            // The worker stopped or hangs mid-flush: that is the answer; keep the write error for later.
            self.errors.keep(first);
            return Err(gone.into());
        }
        first.map_or(Ok(()), |e| Err(e.into()))
    }

    /// Sends a request numbered with the next `seq`.
    fn send(&mut self, request: impl FnOnce(u64) -> Request) -> Result<u64, StoreError> {
        if self.gone {
            return Err(StoreError::WorkerGone);
        }
        match self.worker.send(request) {
            Some(seq) => Ok(seq),
            None => {
                self.worker_gone();
                Err(StoreError::WorkerGone)
            }
        }
    }

    /// Queues a write of the cached tile `key`.
    fn queue_write(&mut self, key: TileKey) {
        let Some(tile) = self.cache.tile(key) else {
            return;
        };
        let dirt = match self.send(|seq| Request::Write { seq, tile }) {
            Ok(seq) => {
                self.unwritten.insert(key, seq);
                Dirt::Queued(seq)
            }
            Err(_) => Dirt::Failed,
        };
        if let Some(cached) = self.cache.get_mut(key) {
            cached.dirt = dirt;
        }
    }

    /// Blocks for the reply to request `seq`, handling the ones before it,
    /// for at most [`StreamerConfig::wait_limit`]; then [`crate::StoreErrorKind::TimedOut`]
    /// naming `what` was waited for. A reply that arrives later is handled
    /// like any other (the answers of blocking calls are then ignored).
    fn wait(&mut self, seq: u64, what: impl FnOnce() -> String) -> Result<Outcome, StoreError> {
        let start = Instant::now();
        loop {
            let left = self.config.wait_limit.saturating_sub(start.elapsed());
            match self.worker.recv_timeout(left) {
                Ok(reply) if reply.seq == seq => {
                    self.take_disk(reply.disk);
                    return Ok(reply.outcome);
                }
                Ok(reply) => self.handle(reply),
                Err(RecvTimeoutError::Timeout) => {
                    let waited = start.elapsed();
                    let what = what();
                    tracing::error!("tile store: gave up after {waited:?} waiting for {what}");
                    return Err(StoreError::TimedOut { what, waited });
                }
                Err(RecvTimeoutError::Disconnected) => {
                    self.worker_gone();
                    return Err(StoreError::WorkerGone);
                }
            }
        }
    }

    /// The store's size as of a reply.
    fn take_disk(&mut self, disk: DiskNumbers) {
        self.stats.disk_tiles = disk.tiles;
        self.stats.disk_bytes = disk.bytes;
        self.stats.evicted = disk.evicted;
    }

    /// Takes one reply that no blocking call waits for.
    fn handle(&mut self, reply: Reply) {
        self.take_disk(reply.disk);
        let seq = reply.seq;
        match reply.outcome {
            Outcome::Loaded { key, result, queued } => self.loaded(seq, key, result, queued),
            Outcome::Written { key, result } => self.written(seq, key, result),
            // Answers to blocking calls arrive only while they wait.
            Outcome::Flushed | Outcome::StateWritten(_) | Outcome::StateRead(_) => {}
        }
    }

    /// A load's reply (`seq`): the tile into the cache, or fresh snow, or a
    /// stand-in kept for a tile the disk could not read.
    fn loaded(&mut self, seq: u64, key: TileKey, result: Result<Option<TileData>, StoreError>, queued: Option<u64>) {
        self.stats.loads += 1;
        if self.loading.get(&key) == Some(&seq) {
            self.loading.remove(&key);
        }
        // The cache holds the newest version whenever it holds one;
        // a write queued after this load also makes it stale (its
        // tile was put, then dropped from memory: load it again).
        let stale = self.cache.contains(key) || self.unwritten.get(&key).is_some_and(|&w| w > seq);
        let tile = match result {
            Ok(tile) => tile,
            Err(e) if matches!(e, StoreError::Corrupt { .. } | StoreError::Version { .. } | StoreError::Mismatch { .. }) => {
                self.stats.corrupt += 1;
                self.report(e, false);
                // Fresh snow: the store has set the bad file aside.
                None
            }
            Err(e) => {
                // Not read, but maybe still there: answered as fresh snow
                // that stands in for it (never written over it).
                if !stale {
                    self.stand_ins.set_read_error(key, &e);
                    self.unreadable.insert(key);
                }
                self.report(e, false);
                return;
            }
        };
        if stale {
            return;
        }
        self.unreadable.remove(&key);
        match tile {
            Some(tile) => {
                // Answered from a write still queued: dirty until its reply.
                let dirt = match queued {
                    Some(w) if self.unwritten.get(&key) == Some(&w) => Dirt::Queued(w),
                    _ => Dirt::Clean,
                };
                // A stand-in whose made version is held (the window has
                // left the tile) waits for its merge without holding memory
                // beyond the budget; one the window is on is merged live
                // at its next frame, so it is wanted like an asked-for tile.
                let wanted = !self.stand_ins.is_held(key);
                self.insert(key, Cached::new(tile, dirt, wanted));
            }
            None => {
                if self.absent.len() >= MAX_ABSENT {
                    // Forgetting only costs a load each if asked again.
                    self.absent.clear();
                }
                self.absent.insert(key);
                self.resolve_absent(key);
            }
        }
    }

    /// A write's reply (`seq`): the cached version clean, or failed (kept dirty), or lost.
    fn written(&mut self, seq: u64, key: TileKey, result: Result<u64, StoreError>) {
        if self.unwritten.get(&key) == Some(&seq) {
            self.unwritten.remove(&key);
        }
        let cached = self.cache.get_mut(key);
        match result {
            Ok(bytes) => {
                self.stats.writes += 1;
                self.stats.bytes_written += bytes;
                if let Some(cached) = cached
                    && cached.dirt == Dirt::Queued(seq)
                {
                    cached.dirt = Dirt::Clean;
                }
            }
            Err(e) => {
                match cached {
                    Some(cached) if cached.dirt == Dirt::Queued(seq) => cached.dirt = Dirt::Failed,
                    // A newer version is in memory or queued: this one no longer matters.
                    Some(_) => {}
                    None if self.unwritten.contains_key(&key) => {}
                    None => {
                        tracing::warn!("tile store: tile {key:?} was dropped from memory and its write failed");
                        self.stats.lost += 1;
                    }
                }
                self.report(e, true);
            }
        }
    }

    /// Counts `error` and keeps it for the game (or, from a write while a
    /// flush waits, for the flush).
    fn report(&mut self, error: StoreError, from_write: bool) {
        tracing::debug!("tile store: {error}");
        self.stats.errors += 1;
        self.errors.report(error, from_write);
    }

    fn worker_gone(&mut self) {
        if !self.gone {
            self.gone = true;
            self.loading.clear();
            tracing::error!("tile store: the worker thread has stopped");
            self.report(StoreError::WorkerGone, false);
        }
    }

    /// Caches a tile as the most recently used ([`StreamerCache::insert`]:
    /// then trims to the budget, the tile just added staying); it is no
    /// longer known absent.
    fn insert(&mut self, key: TileKey, cached: Cached) {
        self.stats.lost += self.cache.insert(key, cached);
        self.absent.remove(&key);
    }
}

/// Whether `tile` is fresh snow: every height at its rest (XOR 0), no
/// footprint, no snowfall plane and no packed snow, so restoring it gives the same bits as
/// a fresh tile (the refill of the time away leaves snow at rest unchanged).
fn is_untouched(tile: &TileData) -> bool {
    tile.fallen.is_empty() && tile.snow_xor_rest.iter().all(|&x| x == 0) && tile.stamps.iter().all(|&s| s == STAMP_EMPTY) && tile.packed.iter().all(|&q| q == 0)
}

impl Drop for TileStreamer {
    /// Writes what is still dirty, lets the worker finish its queue and joins
    /// it, waiting at most [`StreamerConfig::wait_limit`]: a worker stuck on
    /// a hung disk is then left behind (detached, still holding the store
    /// and its queued writes, which it does if the disk comes back while the
    /// program runs) with an error logged, so dropping never blocks for
    /// ever. Errors can no longer reach the game here; they are logged.
    fn drop(&mut self) {
        for key in self.cache.failed() {
            self.queue_write(key);
        }
        // Closing the channel ends the worker's loop once the queue is done.
        self.worker.close();
        let mut detached = false;
        if let Some(thread) = self.worker.take_thread() {
            // The worker's end drops its reply sender: the reply channel
            // disconnects once its queue is done (or it panicked).
            let start = Instant::now();
            let finished = loop {
                match self.worker.recv_timeout(self.config.wait_limit.saturating_sub(start.elapsed())) {
                    Ok(reply) => self.handle(reply),
                    Err(RecvTimeoutError::Disconnected) => break true,
                    Err(RecvTimeoutError::Timeout) => break false,
                }
            };
            if !finished {
                tracing::error!(
                    "tile store: gave up after {:?} waiting for the worker's last writes to {}: the disk is not answering; \
                     the worker is left to finish on its own and its unwritten tiles may be lost",
                    start.elapsed(),
                    self.dir.display()
                );
                // Dropping the handle detaches the thread.
                drop(thread);
                detached = true;
            } else if thread.join().is_err() {
                tracing::error!("tile store: the worker thread panicked; unwritten tiles are lost");
            }
        }
        // The worker ended because we closed its channel: take its last
        // replies without reporting the closed channel as a failure.
        while let Ok(reply) = self.worker.try_recv() {
            self.handle(reply);
        }
        for error in self.errors.take() {
            tracing::warn!("tile store: {error}");
        }
        let held = self.stand_ins.held_count();
        if held > 0 {
            tracing::warn!(
                "tile store: {held} tiles the window made while their stored versions were late or unreadable were never merged and are lost; the stored versions are as they were"
            );
        }
        let unwritten = self.cache.unclean();
        if unwritten > 0 && !detached {
            tracing::warn!("tile store: {unwritten} tiles could not be written and are lost");
        }
    }
}

impl TileStreamerExt for TileStreamer {
    fn in_memory(side: u32, config: StreamerConfig) -> Self {
        // No worker: nothing is ever asked or answered.
        Self::with_worker(side, PathBuf::new(), config, Worker::none(), StoreStats::default())
    }

    fn is_memory_only(&self) -> bool {
        self.memory_only
    }

    fn side(&self) -> u32 {
        self.side
    }

    fn dir(&self) -> &Path {
        &self.dir
    }

    fn is_ready(&self, key: TileKey) -> bool {
        self.memory_only || self.cache.contains(key) || self.absent.contains(&key) || self.unreadable.contains(&key) || self.gone
    }

    fn request(&mut self, key: TileKey) {
        if self.memory_only || self.cache.contains(key) || self.absent.contains(&key) || self.loading.contains_key(&key) {
            return;
        }
        if let Ok(seq) = self.send(|seq| Request::Load { seq, key }) {
            self.loading.insert(key, seq);
        }
    }

    fn lookup(&mut self, key: TileKey) -> TileLookup {
        self.poll();
        if self.memory_only
            && let Some(cached) = self.cache.remove(key)
        {
            // Handed out to the window, which puts it back when it leaves:
            // the budget holds only tiles away from the GPU.
            self.stats.hits += 1;
            return TileLookup::Ready(Some(Arc::unwrap_or_clone(cached.tile)));
        }
        if let Some(tile) = self.cache.tile(key) {
            self.cache.touch(key);
            // Handed out, it may now make room for others.
            self.stats.lost += self.cache.trim(key);
            self.stats.hits += 1;
            return TileLookup::Ready(Some((*tile).clone()));
        }
        if self.absent.contains(&key) {
            self.stats.hits += 1;
            return TileLookup::Ready(None);
        }
        if self.unreadable.remove(&key) {
            // Its read failed (reported): fresh snow stands in for it, and
            // the stored version is merged in once it can be read.
            self.stand_ins.mark(key);
            return TileLookup::Ready(None);
        }
        if self.memory_only {
            // Never kept, dropped by the budget, or untouched: fresh snow.
            self.stats.misses += 1;
            return TileLookup::Ready(None);
        }
        if self.gone {
            // Nothing will ever arrive: fresh snow rather than waiting forever.
            return TileLookup::Ready(None);
        }
        if !self.loading.contains_key(&key) {
            self.stats.misses += 1;
            self.request(key);
        }
        TileLookup::Pending
    }

    fn put(&mut self, tile: TileData) {
        let key = tile.key;
        let valid = if tile.side == self.side {
            tile.validate()
        } else {
            Err(StoreError::Mismatch { path: PathBuf::new(), why: format!("the tile is {}², the store holds {}² tiles", tile.side, self.side) })
        };
        if let Err(e) = valid {
            self.report(e.at(&tile_path(&self.dir, key)), false);
            return;
        }
        self.absent.remove(&key);
        if self.memory_only {
            // Nothing to write: the cache is the only copy.
            if is_untouched(&tile) {
                self.cache.remove(key);
            } else {
                self.insert(key, Cached::new(tile, Dirt::Clean, false));
            }
            return;
        }
        // A tile stood in for is not written: that would replace the stored
        // version, which is merged in when the window next restores the tile
        // (or at a save).
        let Some(tile) = self.stand_ins.hold(key, tile) else {
            self.stats.lost += self.stand_ins.trim(key, self.config.memory_budget_bytes);
            return;
        };
        self.insert(key, Cached::new(tile, Dirt::Failed, false));
        self.queue_write(key);
    }

    fn poll(&mut self) {
        if self.memory_only {
            return;
        }
        loop {
            match self.worker.try_recv() {
                Ok(reply) => self.handle(reply),
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    self.worker_gone();
                    break;
                }
            }
        }
    }

    fn wait_for(&mut self, keys: &[TileKey]) -> Result<(), StoreError> {
        self.wait_for_within(keys, self.config.wait_limit)
    }

    fn wait_for_within(&mut self, keys: &[TileKey], limit: Duration) -> Result<(), StoreError> {
        if self.memory_only {
            return Ok(());
        }
        self.poll();
        // A blocking wait is when a failed read is tried again (once).
        for key in keys {
            self.unreadable.remove(key);
        }
        let start = Instant::now();
        let mut waiting: Vec<TileKey> = keys.to_vec();
        loop {
            waiting.retain(|key| !self.cache.contains(*key) && !self.absent.contains(key) && !self.unreadable.contains(key));
            if waiting.is_empty() {
                return Ok(());
            }
            for &key in &waiting {
                self.request(key);
            }
            if self.gone {
                return Err(StoreError::WorkerGone);
            }
            let left = limit.saturating_sub(start.elapsed());
            match self.worker.recv_timeout(left) {
                Ok(reply) => self.handle(reply),
                Err(RecvTimeoutError::Timeout) => {
                    return Err(StoreError::TimedOut { what: format!("{} tile(s) to load", waiting.len()), waited: start.elapsed() });
                }
                Err(RecvTimeoutError::Disconnected) => {
                    self.worker_gone();
                    return Err(StoreError::WorkerGone);
                }
            }
        }
    }

    fn take_errors(&mut self) -> Vec<StoreError> {
        self.errors.take()
    }

    fn stats(&self) -> StoreStats {
        StoreStats { memory_tiles: self.cache.len(), memory_bytes: self.cache.memory_bytes(), ..self.stats }
    }

    fn write_state(&mut self, name: &str, bytes: Vec<u8>) -> Result<(), StoreError> {
        if self.memory_only {
            return Err(StoreError::NoDisk);
        }
        let owned = name.to_owned();
        let seq = self.send(|seq| Request::WriteState { seq, name: owned, bytes })?;
        match self.wait(seq, || format!("the state `{name}` to be written"))? {
            Outcome::StateWritten(result) => result,
            _ => Err(StoreError::WorkerGone),
        }
    }

    fn begin_saves(&mut self) {
        if !self.memory_only {
            // A stopped worker is reported by the next call that waits.
            let _ = self.send(|seq| Request::BeginSaves { seq });
        }
    }

    fn commit_save(&mut self, name: &str, bytes: Vec<u8>) -> Result<(), StoreError> {
        if self.memory_only {
            return Err(StoreError::NoDisk);
        }
        let owned = name.to_owned();
        let seq = self.send(|seq| Request::Commit { seq, name: owned, bytes })?;
        match self.wait(seq, || format!("the save with `{name}` to be committed"))? {
            Outcome::StateWritten(result) => result,
            _ => Err(StoreError::WorkerGone),
        }
    }

    fn read_state(&mut self, name: &str) -> Result<Option<Vec<u8>>, StoreError> {
        if self.memory_only {
            return Ok(None);
        }
        let owned = name.to_owned();
        let seq = self.send(|seq| Request::ReadState { seq, name: owned })?;
        match self.wait(seq, || format!("the state `{name}` to be read"))? {
            Outcome::StateRead(result) => result,
            _ => Err(StoreError::WorkerGone),
        }
    }
}
