//! What a store knows of its tiles without touching the disk: each tile's
//! file size, recency and save generation, ordered by age for eviction.

use std::collections::{BTreeSet, HashMap};

use crate::persist::TileKey;

/// What the index knows of a tile on disk.
#[derive(Clone, Copy, Debug)]
struct Entry {
    /// Size of its file.
    bytes: u64,
    /// When it was last read or written, on the store's own clock.
    touched: u64,
    /// The save generation its file was written for and that has not
    /// replaced the saved version yet (`{col}_{row}.g{N}.tile`); `None`: the
    /// plain file.
    generation: Option<u64>,
}

/// The tiles on disk by key, by age (oldest first) and their total bytes.
#[derive(Debug, Default)]
pub(super) struct TileIndex {
    index: HashMap<TileKey, Entry>,
    /// The index ordered by recency, oldest first, for eviction.
    by_age: BTreeSet<(u64, TileKey)>,
    clock: u64,
    total_bytes: u64,
}

impl TileIndex {
    /// An empty index with room for `capacity` tiles.
    pub(super) fn with_capacity(capacity: usize) -> Self {
        Self { index: HashMap::with_capacity(capacity), ..Self::default() }
    }

    /// Indexes a tile as just touched.
    pub(super) fn insert(&mut self, key: TileKey, bytes: u64, generation: Option<u64>) {
        self.clock += 1;
        self.index.insert(key, Entry { bytes, touched: self.clock, generation });
        self.by_age.insert((self.clock, key));
        self.total_bytes += bytes;
    }

    /// Marks a tile as just touched.
    pub(super) fn touch(&mut self, key: TileKey) {
        if let Some(entry) = self.remove(key) {
            self.insert(key, entry.bytes, entry.generation);
        }
    }

    /// Drops a tile from the index.
    pub(super) fn forget(&mut self, key: TileKey) {
        self.remove(key);
    }

    /// Drops a tile from the index, returning its entry.
    fn remove(&mut self, key: TileKey) -> Option<Entry> {
        let entry = self.index.remove(&key)?;
        self.by_age.remove(&(entry.touched, key));
        self.total_bytes -= entry.bytes;
        Some(entry)
    }

    /// Whether a tile is indexed.
    pub(super) fn contains(&self, key: TileKey) -> bool {
        self.index.contains_key(&key)
    }

    /// Tiles indexed.
    pub(super) fn len(&self) -> usize {
        self.index.len()
    }

    /// Bytes of their files.
    pub(super) fn total_bytes(&self) -> u64 {
        self.total_bytes
    }

    /// Their keys, in no particular order.
    pub(super) fn keys(&self) -> impl Iterator<Item = TileKey> + '_ {
        self.index.keys().copied()
    }

    /// Size of a tile's file.
    pub(super) fn bytes(&self, key: TileKey) -> Option<u64> {
        self.index.get(&key).map(|e| e.bytes)
    }

    /// The save generation a tile's newest file was written for, if it has
    /// not replaced the saved version yet.
    pub(super) fn generation(&self, key: TileKey) -> Option<u64> {
        self.index.get(&key).and_then(|e| e.generation)
    }

    /// The tiles whose newest file belongs to a save generation, with it.
    pub(super) fn generations(&self) -> Vec<(TileKey, u64)> {
        self.index.iter().filter_map(|(k, e)| e.generation.map(|g| (*k, g))).collect()
    }

    /// Marks a tile's file as its saved version (its generation replaced it).
    pub(super) fn clear_generation(&mut self, key: TileKey) {
        if let Some(entry) = self.index.get_mut(&key) {
            entry.generation = None;
        }
    }

    /// The least recently touched tile other than `keep`.
    pub(super) fn oldest_except(&self, keep: Option<TileKey>) -> Option<TileKey> {
        // At most two steps: only `keep` is skipped.
        self.by_age.iter().find(|(_, k)| Some(*k) != keep).map(|&(_, k)| k)
    }
}
