//! The streamer's bounded memory cache: the tiles by key, their order of
//! use, and the budget that drops the least recently used.

use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;

use super::config::WANTED_FLOOR_BYTES;
use crate::persist::{TileData, TileKey};

/// Whether a cached tile is on disk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Dirt {
    /// Its version is the stored one.
    Clean,
    /// Its write (request `seq`) is queued.
    Queued(u64),
    /// Its last write failed; the next flush tries again.
    Failed,
}

/// One cached tile with its size, last use and whether it is on disk.
pub(super) struct Cached {
    pub(super) tile: Arc<TileData>,
    bytes: usize,
    used: u64,
    pub(super) dirt: Dirt,
    /// Loaded because it was asked for, and not yet handed out by `lookup`.
    wanted: bool,
}

impl Cached {
    /// A fresh entry for `tile` (not yet used).
    pub(super) fn new(tile: TileData, dirt: Dirt, wanted: bool) -> Self {
        let tile = Arc::new(tile);
        let bytes = tile.memory_bytes();
        Self { tile, bytes, used: 0, dirt, wanted }
    }
}

/// The cached tiles within a memory budget, least recently used dropped
/// first; tiles `wanted` (asked for and not yet handed out) only after all
/// the others, and only beyond their own allowance.
pub(super) struct StreamerCache {
    tiles: HashMap<TileKey, Cached>,
    /// The cache by last use, oldest first: tiles not `wanted`...
    by_use: BTreeSet<(u64, TileKey)>,
    /// ...and tiles `wanted` (dropped only after all of `by_use`).
    wanted: BTreeSet<(u64, TileKey)>,
    /// Bytes of the `wanted` tiles.
    wanted_bytes: usize,
    tick: u64,
    memory_bytes: usize,
    /// `StreamerConfig::memory_budget_bytes`.
    budget: usize,
    /// The cache is the only copy (no store behind it): every tile dropped is lost.
    memory_only: bool,
}

impl StreamerCache {
    /// An empty cache of at most `budget` bytes.
    pub(super) fn new(budget: usize, memory_only: bool) -> Self {
        Self { tiles: HashMap::new(), by_use: BTreeSet::new(), wanted: BTreeSet::new(), wanted_bytes: 0, tick: 0, memory_bytes: 0, budget, memory_only }
    }

    /// Whether `key` is cached.
    pub(super) fn contains(&self, key: TileKey) -> bool {
        self.tiles.contains_key(&key)
    }

    /// The cached version of `key`.
    pub(super) fn tile(&self, key: TileKey) -> Option<Arc<TileData>> {
        self.tiles.get(&key).map(|c| Arc::clone(&c.tile))
    }

    /// The entry of `key`, to change whether it is on disk.
    pub(super) fn get_mut(&mut self, key: TileKey) -> Option<&mut Cached> {
        self.tiles.get_mut(&key)
    }

    /// Tiles cached.
    pub(super) fn len(&self) -> usize {
        self.tiles.len()
    }

    /// Their bytes.
    pub(super) fn memory_bytes(&self) -> usize {
        self.memory_bytes
    }

    /// The tiles whose last write failed, to write again.
    pub(super) fn failed(&self) -> Vec<TileKey> {
        self.tiles.iter().filter(|(_, c)| c.dirt == Dirt::Failed).map(|(k, _)| *k).collect()
    }

    /// How many tiles are not on disk (queued or failed).
    pub(super) fn unclean(&self) -> usize {
        self.tiles.values().filter(|c| c.dirt != Dirt::Clean).count()
    }

    /// Caches a tile as the most recently used, then trims to the budget:
    /// the least recently used tiles first, then (only while they alone are
    /// over their allowance) the longest-waiting `wanted` ones. The tile just
    /// added stays. Returns how many tiles were lost ([`Self::trim`]).
    pub(super) fn insert(&mut self, key: TileKey, mut cached: Cached) -> u64 {
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
        self.tiles.insert(key, cached);
        self.trim(key)
    }

    /// Drops tiles until the cache is within the budget (see [`Self::insert`]),
    /// never `keep`. Returns how many were lost: for a memory-only cache
    /// every one dropped (it comes back as fresh snow), otherwise those whose
    /// last write had failed.
    pub(super) fn trim(&mut self, keep: TileKey) -> u64 {
        let wanted_allowance = self.budget.max(WANTED_FLOOR_BYTES);
        let mut lost = 0;
        while self.memory_bytes > self.budget {
            // At most two steps each: only `keep` is skipped.
            let oldest = |order: &BTreeSet<(u64, TileKey)>| order.iter().find(|(_, k)| *k != keep).map(|&(_, k)| k);
            let victim = oldest(&self.by_use).or_else(|| (self.wanted_bytes > wanted_allowance).then(|| oldest(&self.wanted)).flatten());
            let Some(victim) = victim else { break };
            let dropped = self.remove(victim);
            if self.memory_only {
                // The cache was its only copy: it comes back as fresh snow.
                lost += 1;
                continue;
            }
            if let Some(dropped) = dropped
                && dropped.dirt == Dirt::Failed
            {
                tracing::warn!("tile store: tile {victim:?} was dropped from memory before it could be written");
                lost += 1;
            }
        }
        lost
    }

    /// Takes `key` out of the cache.
    pub(super) fn remove(&mut self, key: TileKey) -> Option<Cached> {
        let cached = self.tiles.remove(&key)?;
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
    pub(super) fn touch(&mut self, key: TileKey) {
        if let Some(cached) = self.tiles.get_mut(&key) {
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
