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

use snowpack_share::persist::TileStoreExt;
use std::collections::{BTreeSet, HashMap, HashSet, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender, TryRecvError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::store::tile_path;
use super::{StoreError, TileData, TileKey, TileStore};
use crate::deform::stamp::STAMP_EMPTY;

/// Most errors kept for [`TileStreamer::take_errors`]; more are logged and
/// counted but not kept, so a game that never takes them does not grow.
const MAX_ERRORS: usize = 1024;
/// Tiles loaded for a request and not yet handed out by `lookup` may use up
/// to this much (or the budget, if larger) before they are dropped, so a
/// small budget cannot drop a tile the window is waiting for before it
/// takes it (which would make it wait forever).
const WANTED_FLOOR_BYTES: usize = 64 << 20;
/// The default [`StreamerConfig::wait_limit`]: the longest any blocking call
/// waits for the worker (tiles to load, a flush, a state read or write, the
/// last writes when the streamer is dropped). A disk that stops answering
/// must not freeze the window, a save or the program's exit for good.
pub const WAIT_LIMIT: Duration = Duration::from_secs(30);

/// Most keys remembered as absent from the store (16 bytes each, plus the set's overhead).
const MAX_ABSENT: usize = 1 << 16;

/// How much memory the streamer's cache may use, and how long it waits for
/// the disk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamerConfig {
    /// Most bytes of tiles (by `TileData::memory_bytes`) to keep in memory;
    /// beyond it the least recently used are dropped. Exceptions: the tile
    /// most recently added is always kept (a budget smaller than one tile
    /// keeps one); tiles loaded because they were asked for
    /// (`TileStreamer::request`, `TileStreamer::lookup`,
    /// `TileStreamer::wait_for`) and not yet handed out by `lookup` are
    /// dropped last, and only beyond the budget or 64 MiB, whichever is
    /// larger, so the window cannot wait forever for tiles that a small
    /// budget keeps dropping. Tiles queued for writing are held by the
    /// worker until written and are not counted.
    pub memory_budget_bytes: usize,
    /// The longest a blocking call waits for the worker thread (and so for
    /// the disk): `TileStreamer::wait_for`, [`TileStreamer::flush`],
    /// `TileStreamer::write_state` and `TileStreamer::read_state` give up
    /// after it with [`crate::StoreErrorKind::TimedOut`], and dropping the streamer
    /// stops waiting for the last writes after it (logging an error and
    /// leaving the worker to finish, or hang, on its own).
    pub wait_limit: Duration,
}

impl Default for StreamerConfig {
    /// 128 MiB: about 2,700 tiles of 64² texels with all three planes; a
    /// `WAIT_LIMIT` (30 s) wait limit.
    fn default() -> Self {
        Self { memory_budget_bytes: 128 << 20, wait_limit: WAIT_LIMIT }
    }
}

/// The answer to [`TileStreamer::lookup`].
#[derive(Clone, Debug, PartialEq)]
pub enum TileLookup {
    /// The tile's stored state; `None`: not in the store (never written,
    /// evicted, or unreadable: see [`TileStreamer::take_errors`]), use fresh snow.
    Ready(Option<TileData>),
    /// Being loaded; ask again on a later frame.
    Pending,
}

/// Counters of the cache and the store.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StoreStats {
    /// Tiles in the memory cache.
    pub memory_tiles: usize,
    /// Their [`TileData::memory_bytes`].
    pub memory_bytes: usize,
    /// Tiles on disk (as of the worker's last reply).
    pub disk_tiles: usize,
    /// Bytes of tile files on disk (as of the worker's last reply).
    pub disk_bytes: u64,
    /// Lookups answered from memory (a cached tile, or known to be absent).
    pub hits: u64,
    /// Lookups that had to start a load from disk. (Asking again while the
    /// load is in flight counts neither.)
    pub misses: u64,
    /// Loads the worker has answered.
    pub loads: u64,
    /// Tiles written to disk.
    pub writes: u64,
    /// Bytes of those writes (compressed, headers included).
    pub bytes_written: u64,
    /// Tiles that failed to decode (answered as absent, set aside on disk).
    pub corrupt: u64,
    /// Errors of any kind (each returned by [`TileStreamer::flush`] or in
    /// [`TileStreamer::take_errors`]).
    pub errors: u64,
    /// Dirty tiles dropped from memory after their write had failed: their
    /// latest version is lost. For a memory-only streamer
    /// ([`TileStreamer::in_memory`]): every tile the budget dropped (it comes
    /// back as fresh snow).
    pub lost: u64,
    /// Tiles deleted from disk to keep within its budget.
    pub evicted: u64,
}

impl StoreStats {
    /// `hits / (hits + misses)`, 0 before any lookup.
    #[must_use]
    pub fn hit_rate(&self) -> f64 {
        let total = self.hits + self.misses;
        if total == 0 { 0.0 } else { self.hits as f64 / total as f64 }
    }
}

/// What the frame asks of the worker. `seq` orders requests and replies.
enum Request {
    Load {
        seq: u64,
        key: TileKey,
    },
    Write {
        seq: u64,
        tile: Arc<TileData>,
    },
    Flush {
        seq: u64,
    },
    WriteState {
        seq: u64,
        name: String,
        bytes: Vec<u8>,
    },
    ReadState {
        seq: u64,
        name: String,
    },
    BeginSaves {
        seq: u64,
    },
    Commit {
        seq: u64,
        name: String,
        bytes: Vec<u8>,
    },
    /// Lets the tests kill the worker the way a bug would.
    #[cfg(test)]
    Panic,
    /// Lets the tests hold the worker until `gate` is sent to or dropped;
    /// `entered` is told when the worker is held.
    #[cfg(test)]
    Pause {
        seq: u64,
        gate: Receiver<()>,
        entered: Option<Sender<()>>,
    },
}

/// The store's size after a request.
#[derive(Clone, Copy, Debug, Default)]
struct DiskNumbers {
    tiles: usize,
    bytes: u64,
    evicted: u64,
}

struct Reply {
    seq: u64,
    disk: DiskNumbers,
    outcome: Outcome,
}

enum Outcome {
    Loaded {
        key: TileKey,
        result: Result<Option<TileData>, StoreError>,
        /// The write (its `seq`) still queued that answered this load.
        queued: Option<u64>,
    },
    /// The file's size on success.
    Written {
        key: TileKey,
        result: Result<u64, StoreError>,
    },
    Flushed,
    StateWritten(Result<(), StoreError>),
    StateRead(Result<Option<Vec<u8>>, StoreError>),
}

/// Whether a cached tile is on disk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Dirt {
    /// Its version is the stored one.
    Clean,
    /// Its write (request `seq`) is queued.
    Queued(u64),
    /// Its last write failed; the next flush tries again.
    Failed,
}

struct Cached {
    tile: Arc<TileData>,
    bytes: usize,
    used: u64,
    dirt: Dirt,
    /// Loaded because it was asked for, and not yet handed out by `lookup`.
    wanted: bool,
}

impl Cached {
    /// A fresh entry for `tile` (not yet used).
    fn new(tile: TileData, dirt: Dirt, wanted: bool) -> Self {
        let tile = Arc::new(tile);
        let bytes = tile.memory_bytes();
        Self { tile, bytes, used: 0, dirt, wanted }
    }
}

/// A tile the window made fresh in place of the stored one, which the disk
/// did not give in time (late, hung) or could not read (failing): the stored
/// version is merged into what the window made there (shared snow's merge,
/// on the GPU: `tile_restore.wgsl`), never replaced by it or written over.
#[derive(Default)]
struct StandIn {
    /// What the window made in the tile's place, handed back by `put` and
    /// not merged yet; not written (that would replace the stored version).
    made: Option<TileData>,
    /// When it was handed back (`tick`), so the oldest go first beyond the budget.
    since: u64,
    /// Why the stored version could not be read, the last time it was tried.
    read_error: Option<String>,
}

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
    requests: Option<Sender<Request>>,
    replies: Receiver<Reply>,
    worker: Option<JoinHandle<()>>,
    /// The worker has stopped (reported once in `errors`).
    gone: bool,
    seq: u64,
    cache: HashMap<TileKey, Cached>,
    /// The cache by last use, oldest first: tiles not `wanted`...
    by_use: BTreeSet<(u64, TileKey)>,
    /// ...and tiles `wanted` (dropped only after all of `by_use`).
    wanted: BTreeSet<(u64, TileKey)>,
    /// Bytes of the `wanted` tiles.
    wanted_bytes: usize,
    tick: u64,
    memory_bytes: usize,
    /// Keys the store has answered "not there" for (and not put since);
    /// cleared when it reaches [`MAX_ABSENT`].
    absent: HashSet<TileKey>,
    /// Keys with a load in flight: the load's `seq`.
    loading: HashMap<TileKey, u64>,
    /// Keys with a write queued and not yet answered: the latest write's `seq`.
    unwritten: HashMap<TileKey, u64>,
    /// Errors for the game (at most [`MAX_ERRORS`]).
    errors: Vec<StoreError>,
    /// While `flush` waits: where the first write error goes, for it to return.
    flush_error: Option<Option<StoreError>>,
    /// Tiles the window stood in for with fresh snow ([`StandIn`]).
    stand_ins: HashMap<TileKey, StandIn>,
    /// Bytes of the stand-ins' `made` tiles.
    made_bytes: usize,
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
        let (request_tx, request_rx) = mpsc::channel();
        let (reply_tx, reply_rx) = mpsc::channel();
        let stats = StoreStats { disk_tiles: store.disk_tiles(), disk_bytes: store.disk_bytes(), evicted: store.evicted(), ..StoreStats::default() };
        let (side, dir) = (store.side(), store.dir().to_owned());
        let worker = std::thread::Builder::new().name("snowpack-tiles".to_owned()).spawn(move || work(store, &request_rx, &reply_tx));
        let worker = match worker {
            Ok(handle) => Some(handle),
            Err(e) => {
                // The closure, and with it the reply sender, is dropped: the
                // first poll finds the channel closed and reports WorkerGone.
                tracing::error!("tile store: cannot start the worker thread: {e}");
                None
            }
        };
        Self::with_channels(side, dir, config, (Some(request_tx), reply_rx, worker), stats)
    }

    /// A streamer with an empty cache around its channels to a worker
    /// (`None` requests: memory only, no worker).
    fn with_channels(
        side: u32,
        dir: PathBuf,
        config: StreamerConfig,
        (requests, replies, worker): (Option<Sender<Request>>, Receiver<Reply>, Option<JoinHandle<()>>),
        stats: StoreStats,
    ) -> Self {
        Self {
            side,
            dir,
            memory_only: requests.is_none(),
            config,
            requests,
            replies,
            worker,
            gone: false,
            seq: 0,
            cache: HashMap::new(),
            by_use: BTreeSet::new(),
            wanted: BTreeSet::new(),
            wanted_bytes: 0,
            tick: 0,
            memory_bytes: 0,
            absent: HashSet::new(),
            loading: HashMap::new(),
            unwritten: HashMap::new(),
            errors: Vec::new(),
            flush_error: None,
            stand_ins: HashMap::new(),
            made_bytes: 0,
            unreadable: HashSet::new(),
            stats,
        }
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
        let made = self.stand_ins.entry(key).or_default().made.take();
        if let Some(made) = &made {
            self.made_bytes -= made.memory_bytes();
        }
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
        if !self.stand_ins.contains_key(&key) {
            return (self.lookup(key), None);
        }
        if self.cache.contains_key(&key) {
            let made = self.stand_ins.remove(&key).and_then(|s| s.made);
            if let Some(made) = &made {
                self.made_bytes -= made.memory_bytes();
            }
            return (self.lookup(key), made);
        }
        if self.gone || self.unreadable.remove(&key) {
            // Read again the next time the tile is needed.
            return (TileLookup::Ready(self.stand_in_made(key)), None);
        }
        self.request(key);
        (TileLookup::Pending, None)
    }

    /// Whether fresh snow (or what the window made there) stands in for `key`.
    pub(crate) fn stands_in(&self, key: TileKey) -> bool {
        self.stand_ins.contains_key(&key)
    }

    /// Takes the held `made` tile of stand-in `key`, leaving it stood in for.
    fn stand_in_made(&mut self, key: TileKey) -> Option<TileData> {
        let made = self.stand_ins.get_mut(&key).and_then(|s| s.made.take());
        if let Some(made) = &made {
            self.made_bytes -= made.memory_bytes();
        }
        made
    }

    /// The tiles stood in for whose `made` version is held, waiting for a
    /// merge (a save merges them: `TileStreaming::checkpoint`).
    pub(crate) fn stand_ins_made(&self) -> Vec<TileKey> {
        let mut keys: Vec<TileKey> = self.stand_ins.iter().filter(|(_, s)| s.made.is_some()).map(|(k, _)| *k).collect();
        keys.sort_unstable_by_key(|k| (k.row, k.col));
        keys
    }

    /// Why stand-in `key`'s stored version cannot be merged now: its last
    /// read failed (after [`Self::wait_for`], which tries it again). A save
    /// stops there rather than write over it.
    pub(crate) fn stand_in_error(&self, key: TileKey) -> Option<StoreError> {
        let stand_in = self.stand_ins.get(&key)?;
        if !self.unreadable.contains(&key) && !self.gone {
            return None;
        }
        let why = stand_in.read_error.clone().unwrap_or_else(|| "the tile store's worker has stopped".to_owned());
        Some(StoreError::Io {
            path: tile_path(&self.dir, key),
            op: "read (what the window made in this tile's place is kept in memory and not saved over it)",
            source: std::io::Error::other(why),
        })
    }

    /// A stand-in resolved: the store has no version of it (never written,
    /// or set aside as damaged), so what the window made is the tile.
    fn resolve_absent(&mut self, key: TileKey) {
        let Some(stand_in) = self.stand_ins.remove(&key) else { return };
        if let Some(made) = stand_in.made {
            self.made_bytes -= made.memory_bytes();
            self.insert(key, Cached::new(made, Dirt::Failed, false));
            self.queue_write(key);
        }
    }

    /// Drops the oldest held `made` tiles (never `keep`'s) while they exceed
    /// the memory budget (or the floor of tiles waited for, if larger): a
    /// disk failing for long must not grow memory without bound. Each is
    /// lost (counted); its stored version stays as it was.
    fn trim_stand_ins(&mut self, keep: TileKey) {
        let allowance = self.config.memory_budget_bytes.max(WANTED_FLOOR_BYTES);
        while self.made_bytes > allowance {
            let oldest = self.stand_ins.iter().filter(|(k, s)| **k != keep && s.made.is_some()).min_by_key(|(_, s)| s.since).map(|(k, _)| *k);
            let Some(victim) = oldest else { break };
            if let Some(made) = self.stand_ins.remove(&victim).and_then(|s| s.made) {
                self.made_bytes -= made.memory_bytes();
            }
            tracing::warn!("tile store: what the window made at tile {victim:?} while its stored version could not be read was dropped from memory");
            self.stats.lost += 1;
        }
    }

    /// Blocks until every queued write is done, writing again the cached
    /// tiles whose earlier write failed. Returns the first write error of
    /// this flush; any others are in `TileStreamer::take_errors`. Gives up
    /// after [`StreamerConfig::wait_limit`] with [`crate::StoreErrorKind::TimedOut`]
    /// (the writes stay queued).
    pub fn flush(&mut self) -> Result<(), crate::StoreError> {
        if self.memory_only {
            // Nothing is ever waiting to be written.
            return Ok(());
        }
        self.poll();
        let failed: Vec<TileKey> = self.cache.iter().filter(|(_, c)| c.dirt == Dirt::Failed).map(|(k, _)| *k).collect();
        for key in failed {
            self.queue_write(key);
        }
        let seq = self.send(|seq| Request::Flush { seq })?;
        self.flush_error = Some(None);
        let waited = self.wait(seq, || "the queued tile writes to finish (flush)".to_owned());
        let first = self.flush_error.take().flatten();
        if let Err(gone) = waited {
            // The worker stopped or hangs mid-flush: that is the answer; keep the write error for later.
            self.errors.extend(first);
            return Err(gone.into());
        }
        first.map_or(Ok(()), |e| Err(e.into()))
    }

    /// Sends a request numbered with the next `seq`.
    fn send(&mut self, request: impl FnOnce(u64) -> Request) -> Result<u64, StoreError> {
        if self.gone {
            return Err(StoreError::WorkerGone);
        }
        self.seq += 1;
        let sent = self.requests.as_ref().is_some_and(|tx| tx.send(request(self.seq)).is_ok());
        if sent {
            Ok(self.seq)
        } else {
            self.worker_gone();
            Err(StoreError::WorkerGone)
        }
    }

    /// Queues a write of the cached tile `key`.
    fn queue_write(&mut self, key: TileKey) {
        let Some(tile) = self.cache.get(&key).map(|c| Arc::clone(&c.tile)) else {
            return;
        };
        let dirt = match self.send(|seq| Request::Write { seq, tile }) {
            Ok(seq) => {
                self.unwritten.insert(key, seq);
                Dirt::Queued(seq)
            }
            Err(_) => Dirt::Failed,
        };
        if let Some(cached) = self.cache.get_mut(&key) {
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
            match self.replies.recv_timeout(left) {
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

    fn take_disk(&mut self, disk: DiskNumbers) {
        self.stats.disk_tiles = disk.tiles;
        self.stats.disk_bytes = disk.bytes;
        self.stats.evicted = disk.evicted;
    }

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
        let stale = self.cache.contains_key(&key) || self.unwritten.get(&key).is_some_and(|&w| w > seq);
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
                    if let Some(stand_in) = self.stand_ins.get_mut(&key) {
                        stand_in.read_error = Some(e.to_string());
                    }
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
                // A stand-in's stored version waits for its merge without
                // holding memory beyond the budget.
                let wanted = !self.stand_ins.contains_key(&key);
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
        let cached = self.cache.get_mut(&key);
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

    fn report(&mut self, error: StoreError, from_write: bool) {
        tracing::debug!("tile store: {error}");
        self.stats.errors += 1;
        if from_write && let Some(slot @ None) = &mut self.flush_error {
            *slot = Some(error);
        } else if self.errors.len() < MAX_ERRORS {
            self.errors.push(error);
        } else {
            tracing::warn!("tile store: {error} (not kept: {MAX_ERRORS} errors are waiting for take_errors)");
        }
    }

    fn worker_gone(&mut self) {
        if !self.gone {
            self.gone = true;
            self.loading.clear();
            tracing::error!("tile store: the worker thread has stopped");
            self.report(StoreError::WorkerGone, false);
        }
    }

    /// Caches a tile as the most recently used, then trims to the budget:
    /// the least recently used tiles first, then (only while they alone are
    /// over their allowance) the longest-waiting `wanted` ones. The tile just
    /// added stays.
    fn insert(&mut self, key: TileKey, mut cached: Cached) {
        self.remove(key);
        self.tick += 1;
        cached.used = self.tick;
        self.memory_bytes += cached.bytes;
        if cached.wanted {
            self.wanted_bytes += cached.bytes;
            self.wanted.insert((self.tick, key));
        } else {
            self.by_use.insert((self.tick, key));
        }
        self.cache.insert(key, cached);
        self.absent.remove(&key);
        self.trim(key);
    }

    /// Drops tiles until the cache is within the budget (see [`Self::insert`]), never `keep`.
    fn trim(&mut self, keep: TileKey) {
        let wanted_allowance = self.config.memory_budget_bytes.max(WANTED_FLOOR_BYTES);
        while self.memory_bytes > self.config.memory_budget_bytes {
            // At most two steps each: only `keep` is skipped.
            let oldest = |order: &BTreeSet<(u64, TileKey)>| order.iter().find(|(_, k)| *k != keep).map(|&(_, k)| k);
            let victim = oldest(&self.by_use).or_else(|| (self.wanted_bytes > wanted_allowance).then(|| oldest(&self.wanted)).flatten());
            let Some(victim) = victim else { break };
            let dropped = self.remove(victim);
            if self.memory_only {
                // The cache was its only copy: it comes back as fresh snow.
                self.stats.lost += 1;
                continue;
            }
            if let Some(dropped) = dropped
                && dropped.dirt == Dirt::Failed
            {
                tracing::warn!("tile store: tile {victim:?} was dropped from memory before it could be written");
                self.stats.lost += 1;
            }
        }
    }

    fn remove(&mut self, key: TileKey) -> Option<Cached> {
        let cached = self.cache.remove(&key)?;
        if cached.wanted {
            self.wanted.remove(&(cached.used, key));
            self.wanted_bytes -= cached.bytes;
        } else {
            self.by_use.remove(&(cached.used, key));
        }
        self.memory_bytes -= cached.bytes;
        Some(cached)
    }

    /// Marks a cached tile as just used and no longer `wanted` (it has been handed out).
    fn touch(&mut self, key: TileKey) {
        if let Some(cached) = self.cache.get_mut(&key) {
            if cached.wanted {
                cached.wanted = false;
                self.wanted.remove(&(cached.used, key));
                self.wanted_bytes -= cached.bytes;
            } else {
                self.by_use.remove(&(cached.used, key));
            }
            self.tick += 1;
            cached.used = self.tick;
            self.by_use.insert((self.tick, key));
        }
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
        let failed: Vec<TileKey> = self.cache.iter().filter(|(_, c)| c.dirt == Dirt::Failed).map(|(k, _)| *k).collect();
        for key in failed {
            self.queue_write(key);
        }
        // Closing the channel ends the worker's loop once the queue is done.
        drop(self.requests.take());
        let mut detached = false;
        if let Some(worker) = self.worker.take() {
            // The worker's end drops its reply sender: the reply channel
            // disconnects once its queue is done (or it panicked).
            let start = Instant::now();
            let finished = loop {
                match self.replies.recv_timeout(self.config.wait_limit.saturating_sub(start.elapsed())) {
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
                drop(worker);
                detached = true;
            } else if worker.join().is_err() {
                tracing::error!("tile store: the worker thread panicked; unwritten tiles are lost");
            }
        }
        // The worker ended because we closed its channel: take its last
        // replies without reporting the closed channel as a failure.
        while let Ok(reply) = self.replies.try_recv() {
            self.handle(reply);
        }
        for error in self.errors.drain(..) {
            tracing::warn!("tile store: {error}");
        }
        let held = self.stand_ins.values().filter(|s| s.made.is_some()).count();
        if held > 0 {
            tracing::warn!(
                "tile store: {held} tiles the window made while their stored versions were late or unreadable were never merged and are lost; the stored versions are as they were"
            );
        }
        let unwritten = self.cache.values().filter(|c| c.dirt != Dirt::Clean).count();
        if unwritten > 0 && !detached {
            tracing::warn!("tile store: {unwritten} tiles could not be written and are lost");
        }
    }
}

/// The worker: answers requests until the streamer hangs up, in order
/// except that loads go first (see the module docs). Never panics on I/O
/// errors: they go back in the replies.
fn work(mut store: TileStore, requests: &Receiver<Request>, replies: &Sender<Reply>) {
    let mut queue: VecDeque<Request> = VecDeque::new();
    loop {
        // Block only when nothing is queued; then take all that has arrived.
        if queue.is_empty() {
            match requests.recv() {
                Ok(request) => queue.push_back(request),
                Err(_) => return,
            }
        }
        queue.extend(requests.try_iter());
        let load = queue.iter().enumerate().find_map(|(at, r)| match r {
            Request::Load { seq, key } => Some((at, *seq, *key)),
            _ => None,
        });
        let (seq, outcome) = match load {
            Some((at, seq, key)) => {
                queue.remove(at);
                // The newest write of the same tile queued before the load is its answer.
                let queued = queue.iter().take(at).rev().find_map(|r| match r {
                    Request::Write { seq, tile } if tile.key == key => Some((*seq, Arc::clone(tile))),
                    _ => None,
                });
                let outcome = match queued {
                    Some((w, tile)) => Outcome::Loaded { key, result: Ok(Some((*tile).clone())), queued: Some(w) },
                    None => Outcome::Loaded { key, result: store.read(key), queued: None },
                };
                (seq, outcome)
            }
            None => match queue.pop_front() {
                Some(request) => answer(&mut store, request),
                None => continue,
            },
        };
        let disk = DiskNumbers { tiles: store.disk_tiles(), bytes: store.disk_bytes(), evicted: store.evicted() };
        // The streamer may be dropping: keep going, the queued writes still matter.
        let _ = replies.send(Reply { seq, disk, outcome });
    }
}

/// Does one request other than a load jumping the queue.
fn answer(store: &mut TileStore, request: Request) -> (u64, Outcome) {
    match request {
        Request::Load { seq, key } => (seq, Outcome::Loaded { key, result: store.read(key), queued: None }),
        Request::Write { seq, tile } => {
            let result = store.write(&tile).map(|()| store.tile_bytes(tile.key).unwrap_or(0));
            (seq, Outcome::Written { key: tile.key, result })
        }
        Request::Flush { seq } => (seq, Outcome::Flushed),
        Request::WriteState { seq, name, bytes } => (seq, Outcome::StateWritten(store.write_state(&name, &bytes))),
        Request::ReadState { seq, name } => (seq, Outcome::StateRead(store.read_state(&name))),
        Request::BeginSaves { seq } => {
            store.begin_saves();
            (seq, Outcome::Flushed)
        }
        Request::Commit { seq, name, bytes } => (seq, Outcome::StateWritten(store.commit(&[(&name, &bytes)]))),
        #[cfg(test)]
        Request::Panic => panic!("the tile worker panics (as a test asked)"),
        #[cfg(test)]
        Request::Pause { seq, gate, entered } => {
            if let Some(entered) = entered {
                let _ = entered.send(());
            }
            let _ = gate.recv();
            (seq, Outcome::Flushed)
        }
    }
}

/// What snowpack's own app, tools and tests do with a [`TileStreamer`] beyond the front door: tile-level requests and lookups, waits, saved state and counters.
/// A named item of `low_level` (an extension trait): [`TileStreamer`] has one
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

    /// Whether tiles are kept in memory only ([`TileStreamer::in_memory`]).
    #[must_use]
    fn is_memory_only(&self) -> bool;

    /// Texels per tile side.
    #[must_use]
    fn side(&self) -> u32;

    /// The store's directory (empty for a memory-only streamer).
    #[must_use]
    fn dir(&self) -> &Path;

    /// Whether [`TileStreamer::lookup`] would answer `Ready` now (the tile is
    /// in memory or known to be absent, or the worker has stopped). Does not
    /// drain replies or start a load: call [`TileStreamer::poll`] and
    /// [`TileStreamer::request`] for that.
    #[must_use]
    fn is_ready(&self, key: TileKey) -> bool;

    /// Starts loading a tile the window will soon need (non-blocking). Does
    /// nothing if it is cached, known to be absent, or already loading.
    fn request(&mut self, key: TileKey);

    /// A tile's stored state if it is at hand (non-blocking): a copy from
    /// memory, `Ready(None)` if the store has none, otherwise `Pending` (and
    /// the load is started). Drains the worker's replies first, as
    /// [`TileStreamer::poll`] does.
    fn lookup(&mut self, key: TileKey) -> TileLookup;

    /// Hands a tile to the store (non-blocking): it becomes the cached,
    /// newest version at once and is written behind by the worker. A tile of
    /// the wrong side or with planes of the wrong length is refused with an
    /// error in [`TileStreamer::take_errors`].
    fn put(&mut self, tile: TileData);

    /// Takes the worker's replies into the cache, the statistics and the
    /// errors (non-blocking). Call once a frame.
    fn poll(&mut self);

    /// Blocks until every key is ready (in memory or known absent): for the
    /// first placement of the window and for loading a save. A tile whose
    /// read failed before is read again. Read errors do not stop it (those
    /// tiles are answered as fresh snow standing in for them, and the
    /// errors are in [`TileStreamer::take_errors`]); only a stopped worker does. If the
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
    /// before it); see [`TileStore::write_state`]. A memory-only streamer
    /// has nowhere to put it: [`StoreError::NoDisk`]. Gives up after
    /// [`StreamerConfig::wait_limit`] with [`crate::StoreErrorKind::TimedOut`] (the
    /// write stays queued and may still be done).
    fn write_state(&mut self, name: &str, bytes: Vec<u8>) -> Result<(), StoreError>;

    /// From now on the store writes tiles for the next save, beside the
    /// saved ones ([`TileStore::begin_saves`]): a crash before
    /// [`Self::commit_save`] returns leaves the last complete save, every
    /// tile and state of it. Ordered after the writes queued before it;
    /// nothing for a memory-only streamer.
    fn begin_saves(&mut self);

    /// Completes a save with the named state `bytes` ([`TileStore::commit`]):
    /// blocking, ordered after the writes queued before it, so call it once
    /// [`TileStreamer::flush`] has written the save's tiles. A memory-only streamer
    /// has nowhere to put it: [`StoreError::NoDisk`]. Gives up after
    /// [`StreamerConfig::wait_limit`] with [`StoreError::TimedOut`] (the
    /// commit stays queued and may still be done: the save is then complete).
    fn commit_save(&mut self, name: &str, bytes: Vec<u8>) -> Result<(), StoreError>;

    /// Reads a named blob (blocking, ordered after the writes queued before
    /// it); `Ok(None)` if there is none (always, for a memory-only streamer).
    /// Gives up after [`StreamerConfig::wait_limit`] with [`crate::StoreErrorKind::TimedOut`].
    fn read_state(&mut self, name: &str) -> Result<Option<Vec<u8>>, StoreError>;
}

impl TileStreamerExt for TileStreamer {
    fn in_memory(side: u32, config: StreamerConfig) -> Self {
        // A channel whose sender is gone: nothing is ever asked or answered.
        let (_, replies) = mpsc::channel();
        Self::with_channels(side, PathBuf::new(), config, (None, replies, None), StoreStats::default())
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
        self.memory_only || self.cache.contains_key(&key) || self.absent.contains(&key) || self.unreadable.contains(&key) || self.gone
    }

    fn request(&mut self, key: TileKey) {
        if self.memory_only || self.cache.contains_key(&key) || self.absent.contains(&key) || self.loading.contains_key(&key) {
            return;
        }
        if let Ok(seq) = self.send(|seq| Request::Load { seq, key }) {
            self.loading.insert(key, seq);
        }
    }

    fn lookup(&mut self, key: TileKey) -> TileLookup {
        self.poll();
        if self.memory_only
            && let Some(cached) = self.remove(key)
        {
            // Handed out to the window, which puts it back when it leaves:
            // the budget holds only tiles away from the GPU.
            self.stats.hits += 1;
            return TileLookup::Ready(Some(Arc::unwrap_or_clone(cached.tile)));
        }
        if let Some(tile) = self.cache.get(&key).map(|c| Arc::clone(&c.tile)) {
            self.touch(key);
            // Handed out, it may now make room for others.
            self.trim(key);
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
            self.stand_ins.entry(key).or_default();
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
                self.remove(key);
            } else {
                self.insert(key, Cached::new(tile, Dirt::Clean, false));
            }
            return;
        }
        if let Some(stand_in) = self.stand_ins.get_mut(&key) {
            // Not written: that would replace the stored version, which is
            // merged in when the window next restores the tile (or at a save).
            self.tick += 1;
            stand_in.since = self.tick;
            self.made_bytes += tile.memory_bytes();
            if let Some(old) = stand_in.made.replace(tile) {
                self.made_bytes -= old.memory_bytes();
            }
            self.trim_stand_ins(key);
            return;
        }
        self.insert(key, Cached::new(tile, Dirt::Failed, false));
        self.queue_write(key);
    }

    fn poll(&mut self) {
        if self.memory_only {
            return;
        }
        loop {
            match self.replies.try_recv() {
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
            waiting.retain(|key| !self.cache.contains_key(key) && !self.absent.contains(key) && !self.unreadable.contains(key));
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
            match self.replies.recv_timeout(left) {
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
        std::mem::take(&mut self.errors)
    }

    fn stats(&self) -> StoreStats {
        StoreStats { memory_tiles: self.cache.len(), memory_bytes: self.memory_bytes, ..self.stats }
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

#[cfg(test)]
mod tests {
    use std::time::{Duration, Instant};

    use super::*;
    use crate::persist::test_dir::TestDir;
    use crate::persist::{SnowClock, StoreConfig, decode};

    const SIDE: u32 = 8;

    fn tile(col: i64, row: i64, v: f32) -> TileData {
        let n = (SIDE * SIDE) as usize;
        TileData {
            key: TileKey::new(col, row),
            side: SIDE,
            clock: SnowClock { time_s: f64::from(v), ..SnowClock::default() },
            snow_xor_rest: vec![v.to_bits(); n],
            stamps: vec![v as u32; n],
            fallen: Vec::new(),
            packed: Vec::new(),
        }
    }

    fn streamer(dir: &TestDir, tiles_in_memory: usize) -> TileStreamer {
        let store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
        let budget = tiles_in_memory * tile(0, 0, 0.0).memory_bytes();
        TileStreamer::new(store, StreamerConfig { memory_budget_bytes: budget, ..StreamerConfig::default() })
    }

    /// Polls until the lookup is ready (bounded, so a bug fails instead of hanging).
    fn ready(s: &mut TileStreamer, key: TileKey) -> Option<TileData> {
        let start = Instant::now();
        loop {
            if let TileLookup::Ready(tile) = s.lookup(key) {
                return tile;
            }
            assert!(start.elapsed() < Duration::from_secs(10), "{key:?} never became ready");
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    #[test]
    fn pending_then_ready_and_hits() {
        let dir = TestDir::new("streamer-pending");
        {
            let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
            store.write(&tile(1, -1, 3.0)).expect("write");
        }
        let mut s = streamer(&dir, 16);
        assert_eq!(s.side(), SIDE);
        assert_eq!(s.stats().disk_tiles, 1);
        let key = TileKey::new(1, -1);
        assert!(!s.is_ready(key));
        assert_eq!(s.lookup(key), TileLookup::Pending, "the first lookup cannot be in memory");
        assert_eq!(ready(&mut s, key), Some(tile(1, -1, 3.0)));
        assert!(s.is_ready(key));
        assert_eq!(s.lookup(key), TileLookup::Ready(Some(tile(1, -1, 3.0))));
        let stats = s.stats();
        assert_eq!((stats.misses, stats.hits, stats.loads), (1, 2, 1));
        assert_eq!(stats.memory_tiles, 1);

        // Never written: Pending, then known absent without another load.
        let never = TileKey::new(50, 50);
        s.request(never);
        assert_eq!(ready(&mut s, never), None);
        assert_eq!(s.lookup(never), TileLookup::Ready(None));
        let stats = s.stats();
        assert_eq!((stats.loads, stats.misses), (2, 1), "request() is a prefetch, not a miss");
        assert!((stats.hit_rate() - stats.hits as f64 / (stats.hits + 1) as f64).abs() < 1e-12);
        assert!(s.take_errors().is_empty());
    }

    #[test]
    fn memory_budget_is_respected() {
        let dir = TestDir::new("streamer-budget");
        let mut s = streamer(&dir, 3);
        let budget = 3 * tile(0, 0, 0.0).memory_bytes();
        for col in 0..10 {
            s.put(tile(col, 0, col as f32));
            assert!(s.stats().memory_bytes <= budget);
            assert!(s.stats().memory_tiles <= 3);
        }
        s.flush().expect("flush");
        for col in 0..10 {
            assert_eq!(ready(&mut s, TileKey::new(col, 0)), Some(tile(col, 0, col as f32)));
            assert!(s.stats().memory_bytes <= budget);
        }
        let stats = s.stats();
        assert_eq!((stats.writes, stats.disk_tiles, stats.lost), (10, 10, 0));
    }

    #[test]
    fn tiles_asked_for_wait_for_their_lookup() {
        let dir = TestDir::new("streamer-wanted");
        let keys: Vec<TileKey> = (0..6).map(|k| TileKey::new(k, -k)).collect();
        {
            let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
            for key in &keys {
                store.write(&tile(key.col, key.row, key.col as f32)).expect("write");
            }
        }
        // Room for one tile, but the window needs six at once.
        let mut s = streamer(&dir, 1);
        s.wait_for(&keys).expect("wait");
        assert!(keys.iter().all(|&k| s.is_ready(k)), "every tile asked for is still there");
        for key in &keys {
            assert_eq!(s.lookup(*key), TileLookup::Ready(Some(tile(key.col, key.row, key.col as f32))));
        }
        // Handed out, they no longer hold memory beyond the budget.
        let stats = s.stats();
        assert_eq!((stats.memory_tiles, stats.loads, stats.misses), (1, 6, 0));
        // Once taken, a tile is an ordinary cache entry and may be dropped.
        s.put(tile(9, 9, 1.0));
        assert_eq!(s.stats().memory_tiles, 1);
        assert_eq!(s.lookup(keys[0]), TileLookup::Pending);
    }

    #[test]
    fn put_then_evict_then_lookup_returns_the_newest() {
        let dir = TestDir::new("streamer-newest");
        {
            let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
            store.write(&tile(0, 0, 1.0)).expect("write");
        }
        let mut s = streamer(&dir, 1);
        let a = TileKey::new(0, 0);
        // A load of the old version is queued before the put...
        s.request(a);
        s.put(tile(0, 0, 2.0));
        // ...and the new version leaves memory before anything was written.
        s.put(tile(1, 0, 9.0));
        assert_eq!(s.stats().memory_tiles, 1);
        s.wait_for(&[a]).expect("wait");
        assert_eq!(s.lookup(a), TileLookup::Ready(Some(tile(0, 0, 2.0))));
        assert_eq!(ready(&mut s, TileKey::new(1, 0)), Some(tile(1, 0, 9.0)));
        assert_eq!(s.stats().lost, 0);
    }

    #[test]
    fn loads_go_ahead_of_queued_writes_and_see_the_newest_version() {
        let dir = TestDir::new("streamer-loads-first");
        let mut s = streamer(&dir, 1);
        let a = TileKey::new(0, 0);
        // Hold the worker, as a disk that syncs slowly would, while writes queue up.
        let (release, gate) = mpsc::channel();
        s.send(|seq| Request::Pause { seq, gate, entered: None }).expect("send");
        s.put(tile(0, 0, 1.0));
        s.put(tile(0, 0, 2.0));
        for col in 1..20 {
            s.put(tile(col, 0, 9.0));
        }
        // The newest version of `a` has left memory; only its queued write holds it.
        assert_eq!(s.lookup(a), TileLookup::Pending);
        drop(release);
        s.wait_for(&[a]).expect("wait");
        // The load was answered before any of the 21 writes...
        assert_eq!(s.stats().writes, 0);
        // ...from the newest queued write, which is still dirty until written.
        assert_eq!(s.lookup(a), TileLookup::Ready(Some(tile(0, 0, 2.0))));
        s.flush().expect("flush");
        assert_eq!(s.stats().writes, 21);
        assert_eq!(s.stats().lost, 0);
        drop(s);
        let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
        assert_eq!(store.read(a).expect("read"), Some(tile(0, 0, 2.0)));
    }

    /// A blocking wait on a disk that stops answering gives up after its limit
    /// with `TimedOut` instead of freezing the caller; the load goes on, and
    /// once the disk answers the tile is there.
    #[test]
    fn a_wait_on_a_hung_disk_gives_up_and_the_tile_arrives_later() {
        let dir = TestDir::new("streamer-hung");
        {
            let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
            store.write(&tile(3, 4, 5.0)).expect("write");
        }
        let mut s = streamer(&dir, 4);
        let a = TileKey::new(3, 4);
        // The worker is held, as a disk that hangs would hold it (loads jump the queue,
        // so the wait starts once the worker is inside the pause).
        let (release, gate) = mpsc::channel();
        let (entered, held) = mpsc::channel();
        s.send(|seq| Request::Pause { seq, gate, entered: Some(entered) }).expect("send");
        held.recv().expect("the worker is held");
        let limit = Duration::from_millis(200);
        match s.wait_for_within(&[a], limit) {
            Err(StoreError::TimedOut { what, waited }) => {
                assert!(what.contains("1 tile"), "{what}");
                assert!(waited >= limit, "gave up after {waited:?}, before its limit");
            }
            other => panic!("a wait on a held worker gave {other:?}, not TimedOut"),
        }
        assert!(!s.is_ready(a));
        drop(release);
        s.wait_for(&[a]).expect("the disk answers again");
        assert_eq!(s.lookup(a), TileLookup::Ready(Some(tile(3, 4, 5.0))));
        assert!(WAIT_LIMIT <= Duration::from_secs(60), "the default bound is a bound");
    }

    /// Fresh snow the window stood in for a late tile with is never written
    /// over the stored tile: it is held until the stored version is here and
    /// both go to the restore to merge; where the store has none, it is the tile.
    #[test]
    fn a_stand_in_is_held_for_its_merge_not_written_over_the_stored_tile() {
        let dir = TestDir::new("streamer-stand-in");
        let (stored, never) = (TileKey::new(1, 1), TileKey::new(2, 1));
        {
            let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
            store.write(&tile(1, 1, 1.0)).expect("write");
        }
        let mut s = streamer(&dir, 8);
        // The disk is late: the window stands in for both tiles, then hands back what it made there.
        let (release, gate) = mpsc::channel();
        let (entered, held) = mpsc::channel();
        s.send(|seq| Request::Pause { seq, gate, entered: Some(entered) }).expect("send");
        held.recv().expect("the worker is held");
        assert_eq!(s.stand_in(stored), None, "nothing made there yet");
        assert_eq!(s.stand_in(never), None);
        s.put(tile(1, 1, 7.0));
        s.put(tile(2, 1, 8.0));
        assert_eq!(s.stand_ins_made(), vec![stored, never]);
        assert_eq!(s.take_for_restore(stored), (TileLookup::Pending, None), "the stored version is still loading");
        drop(release);
        s.wait_for(&[stored, never]).expect("the disk answers");
        s.flush().expect("flush");
        // The store has no version of `never`: what the window made is the tile, written.
        assert_eq!(s.stats().writes, 1);
        assert_eq!(s.stand_ins_made(), vec![stored]);
        // Both versions of `stored` go to the restore, which merges them; then it is an ordinary tile.
        assert_eq!(s.take_for_restore(stored), (TileLookup::Ready(Some(tile(1, 1, 1.0))), Some(tile(1, 1, 7.0))));
        assert!(s.stand_ins_made().is_empty());
        assert_eq!(s.take_for_restore(stored), (TileLookup::Ready(Some(tile(1, 1, 1.0))), None));
        assert!(s.take_errors().is_empty());
        drop(s);
        let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("reopen");
        assert_eq!(store.read(stored).expect("read"), Some(tile(1, 1, 1.0)), "never written over");
        assert_eq!(store.read(never).expect("read"), Some(tile(2, 1, 8.0)));
    }

    #[test]
    fn flush_writes_everything_and_state_is_ordered() {
        let dir = TestDir::new("streamer-flush");
        let mut s = streamer(&dir, 64);
        for col in -5..5 {
            s.put(tile(col, 7, col as f32 + 10.0));
        }
        // State requests are ordered after the tile writes before them.
        s.write_state("clock", vec![1, 2, 3]).expect("write state");
        assert_eq!(s.stats().writes, 10);
        s.flush().expect("flush");
        assert_eq!(s.read_state("clock").expect("read state"), Some(vec![1, 2, 3]));
        assert_eq!(s.read_state("nothing").expect("read state"), None);
        assert!(s.write_state("../escape", Vec::new()).is_err());
        let stats = s.stats();
        assert_eq!((stats.writes, stats.disk_tiles, stats.errors), (10, 10, 0));
        assert_eq!(stats.bytes_written, stats.disk_bytes);
        for col in -5..5 {
            let bytes = std::fs::read(tile_path(dir.path(), TileKey::new(col, 7))).expect("the tile's file");
            assert_eq!(decode(&bytes).expect("decode"), tile(col, 7, col as f32 + 10.0));
        }
        // Dropping writes what is queued.
        s.put(tile(100, 100, 1.0));
        drop(s);
        let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("reopen");
        assert_eq!(store.read(TileKey::new(100, 100)).expect("read"), Some(tile(100, 100, 1.0)));
    }

    #[test]
    fn failed_writes_stay_dirty_and_are_retried() {
        let dir = TestDir::new("streamer-retry");
        let mut s = streamer(&dir, 2);
        let tiles = dir.path().join("tiles");
        // A file where the directory was: every tile write fails, as root too.
        std::fs::remove_dir_all(&tiles).expect("remove tiles");
        std::fs::write(&tiles, b"in the way").expect("block tiles");
        s.put(tile(0, 0, 1.0));
        // Let the worker answer that write (it fails) before a flush looks at
        // the cache: whether flush's own poll saw the failure, and so retried
        // the write once more, depended on timing (1 in 60 runs).
        let seq = s.send(|seq| Request::Flush { seq }).expect("send");
        s.wait(seq, || "the test's flush".to_owned()).expect("answered");
        assert_eq!(s.stats().errors, 1);
        assert_eq!(s.take_errors().len(), 1, "the failed write is reported");
        // A flush retries the failed write, which fails again: that error is
        // flush's answer, and is not repeated in take_errors.
        assert!(matches!(s.flush().map_err(StoreError::from), Err(StoreError::Io { .. })));
        assert_eq!(s.stats().errors, 2);
        assert!(s.take_errors().is_empty(), "the error flush returned is not repeated");
        // Still answered from memory, and written once the disk is back.
        assert_eq!(s.lookup(TileKey::new(0, 0)), TileLookup::Ready(Some(tile(0, 0, 1.0))));
        std::fs::remove_file(&tiles).expect("unblock");
        std::fs::create_dir(&tiles).expect("tiles again");
        s.flush().expect("the retry succeeds");
        assert_eq!((s.stats().writes, s.stats().disk_tiles), (1, 1));

        // Dropping a failed tile from memory loses it, and says so.
        std::fs::remove_dir_all(&tiles).expect("remove tiles");
        std::fs::write(&tiles, b"in the way").expect("block tiles");
        s.put(tile(1, 0, 1.0));
        s.put(tile(2, 0, 1.0));
        assert!(s.flush().is_err());
        // One error was returned; the other write's (and any earlier attempt's) are here.
        let errors = s.take_errors();
        assert!(!errors.is_empty() && errors.iter().all(|e| matches!(e, StoreError::Io { .. })), "{errors:?}");
        s.put(tile(3, 0, 1.0));
        s.put(tile(4, 0, 1.0));
        let stats = s.stats();
        assert_eq!(stats.lost, 2, "tiles 1 and 2 were dropped unwritten");
        assert_eq!(stats.memory_tiles, 2);
        // Pushed out while their writes are queued: not lost until those fail.
        s.put(tile(5, 0, 1.0));
        s.put(tile(6, 0, 1.0));
        assert!(s.flush().is_err());
        assert_eq!(s.stats().lost, 4, "tiles 3 and 4 failed after leaving memory");
        assert!(s.lookup(TileKey::new(6, 0)) == TileLookup::Ready(Some(tile(6, 0, 1.0))));
    }

    #[test]
    fn a_dead_worker_is_reported_not_panicked() {
        let dir = TestDir::new("streamer-dead");
        let mut s = streamer(&dir, 4);
        s.put(tile(0, 0, 1.0));
        s.send(|_| Request::Panic).expect("send");
        assert!(matches!(s.flush().map_err(StoreError::from), Err(StoreError::WorkerGone)));
        assert!(matches!(s.wait_for(&[TileKey::new(5, 5)]), Err(StoreError::WorkerGone)));
        assert!(matches!(s.read_state("x"), Err(StoreError::WorkerGone)));
        assert_eq!(s.lookup(TileKey::new(5, 5)), TileLookup::Ready(None));
        assert_eq!(s.lookup(TileKey::new(0, 0)), TileLookup::Ready(Some(tile(0, 0, 1.0))));
        s.put(tile(1, 0, 1.0));
        let errors = s.take_errors();
        assert_eq!(errors.len(), 1, "{errors:?}");
        assert!(matches!(errors[0], StoreError::WorkerGone));
        drop(s); // Must not panic.
    }

    fn memory(tiles_in_memory: usize) -> TileStreamer {
        let budget = tiles_in_memory * tile(0, 0, 0.0).memory_bytes();
        TileStreamer::in_memory(SIDE, StreamerConfig { memory_budget_bytes: budget, ..StreamerConfig::default() })
    }

    #[test]
    fn in_memory_keeps_tiles_within_the_budget_and_forgets_the_oldest() {
        let mut s = memory(3);
        assert!(s.is_memory_only() && s.dir().as_os_str().is_empty());
        let key = |col| TileKey::new(col, 2);
        // Never put: fresh snow at once, no load, no worker.
        assert!(s.is_ready(key(0)));
        assert_eq!(s.lookup(key(0)), TileLookup::Ready(None));
        s.wait_for(&[key(0), key(1)]).expect("nothing to wait for");
        for col in 0..5 {
            s.put(tile(col, 2, col as f32 + 1.0));
            assert!(s.stats().memory_tiles <= 3);
        }
        let stats = s.stats();
        assert_eq!((stats.memory_tiles, stats.memory_bytes), (3, 3 * tile(0, 0, 0.0).memory_bytes()));
        assert_eq!(stats.lost, 2, "tiles 0 and 1 were forgotten for the budget");
        assert_eq!((stats.writes, stats.disk_tiles, stats.errors), (0, 0, 0));
        // The two oldest are fresh snow; the newest three come back as put.
        assert_eq!(s.lookup(key(0)), TileLookup::Ready(None));
        assert_eq!(s.lookup(key(1)), TileLookup::Ready(None));
        for col in 2..5 {
            assert_eq!(s.lookup(key(col)), TileLookup::Ready(Some(tile(col, 2, col as f32 + 1.0))));
        }
        // Handed out once: the window holds them now.
        assert_eq!(s.stats().memory_tiles, 0);
        assert_eq!(s.lookup(key(4)), TileLookup::Ready(None));
        s.flush().expect("nothing to flush");
        assert!(s.take_errors().is_empty());
    }

    #[test]
    fn in_memory_keeps_the_newest_version_and_not_untouched_tiles() {
        let mut s = memory(8);
        let key = TileKey::new(-3, 7);
        s.put(tile(-3, 7, 1.0));
        s.put(tile(-3, 7, 2.0));
        assert_eq!(s.stats().memory_tiles, 1);
        // Snow at rest everywhere, no footprint, no snowfall: the same as fresh snow.
        let untouched = TileData { snow_xor_rest: vec![0; 64], stamps: vec![STAMP_EMPTY; 64], ..tile(-3, 7, 0.0) };
        s.put(untouched.clone());
        assert_eq!(s.stats().memory_tiles, 0, "an untouched tile replaces what was kept and is not kept");
        assert_eq!(s.lookup(key), TileLookup::Ready(None));
        // With a snowfall plane it is kept (snowfall may differ from the fresh snow's).
        s.put(TileData { fallen: vec![0.0; 64], ..untouched });
        assert_eq!(s.stats().memory_tiles, 1);
        s.put(tile(-3, 7, 5.0));
        assert_eq!(s.lookup(key), TileLookup::Ready(Some(tile(-3, 7, 5.0))));
        assert_eq!(s.stats().lost, 0);
    }

    #[test]
    fn in_memory_has_no_state_to_save() {
        let mut s = memory(2);
        assert_eq!(s.read_state("window.state").expect("read"), None);
        let err = s.write_state("window.state", vec![1]).expect_err("no disk");
        assert!(matches!(err, StoreError::NoDisk) && err.path().is_none());
        assert!(err.to_string().contains("disk store"), "{err}");
        let mut short = tile(0, 0, 1.0);
        short.stamps.pop();
        s.put(short);
        assert_eq!(s.take_errors().len(), 1, "a wrong tile is refused in memory too");
        drop(s); // No worker to join, nothing to write.
    }

    #[test]
    fn a_wrong_tile_is_refused() {
        let dir = TestDir::new("streamer-wrong");
        let mut s = streamer(&dir, 4);
        let mut short = tile(0, 0, 1.0);
        short.snow_xor_rest.pop();
        s.put(short);
        let mut big = tile(1, 0, 1.0);
        big.side = 16;
        s.put(big);
        let errors = s.take_errors();
        assert_eq!(errors.len(), 2);
        assert!(errors.iter().all(|e| matches!(e, StoreError::Mismatch { .. }) && e.path().is_some()));
        assert_eq!(s.stats().memory_tiles, 0);
    }
}
