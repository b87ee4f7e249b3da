//! The tiles in the relay's memory: each with whether the store has it,
//! when it was last used and its cached wire bytes; loaded from the store,
//! written to it, and dropped beyond the memory caps.

use crate::persist::TileStoreExt;
use std::collections::HashMap;

use super::stats::RelayStats;
use super::stored::{is_full, tile_from_data, tile_to_data};
use crate::persist::{StoreError, TileKey, TileStore};
use crate::replicate::message::encode_tile;
use crate::replicate::tile::{CatchUp, SharedTile};

/// A tile in the relay's memory.
#[derive(Debug)]
struct Held {
    tile: SharedTile,
    /// Changed since it was last written to the store.
    dirty: bool,
    /// When it was last merged into or loaded, on the relay's own counter (for eviction).
    used: u64,
    /// The tile as [`encode_tile`] writes it, kept between merges: every
    /// peer interested in a change is sent the same bytes.
    encoded: Option<Vec<u8>>,
    /// Bytes counted for it in `SnowRelay::stats`'s `tile_bytes_in_memory`.
    bytes: usize,
    /// The one peer whose tiles (and presses) made all of it, when one did:
    /// that peer lacks nothing of it, so a merge is not sent back to it.
    /// `None` once a second peer changed it, or when it came from the store.
    author: Option<u64>,
}

/// Every [`Held`] tile by key, and the counter their uses are ordered by.
#[derive(Debug, Default)]
pub(super) struct HeldTiles {
    tiles: HashMap<TileKey, Held>,
    use_counter: u64,
}

impl HeldTiles {
    /// Whether `key` is in memory.
    pub(super) fn contains(&self, key: TileKey) -> bool {
        self.tiles.contains_key(&key)
    }

    /// The tile `key`, if in memory.
    pub(super) fn tile(&self, key: TileKey) -> Option<&SharedTile> {
        self.tiles.get(&key).map(|h| &h.tile)
    }

    /// The keys in memory.
    pub(super) fn keys(&self) -> impl Iterator<Item = TileKey> + '_ {
        self.tiles.keys().copied()
    }

    /// Tiles in memory.
    pub(super) fn len(&self) -> usize {
        self.tiles.len()
    }

    /// Bytes they cost ([`held_bytes`]).
    pub(super) fn bytes(&self) -> usize {
        self.tiles.values().map(|h| h.bytes).sum()
    }

    /// Merges `t` from peer `from` into the copy in memory (or keeps it as
    /// the first), marking it just used; whether the copy changed.
    pub(super) fn merge(&mut self, t: &SharedTile, c: CatchUp, from: u64) -> bool {
        self.use_counter += 1;
        let used = self.use_counter;
        match self.tiles.get_mut(&t.key) {
            Some(held) => {
                held.used = used;
                held.encoded = None;
                let changed = held.tile.merge(t, c);
                held.dirty |= changed;
                held.bytes = held_bytes(&held.tile, None);
                if changed && held.author != Some(from) {
                    held.author = None;
                }
                changed
            }
            None => {
                self.tiles.insert(t.key, Held { tile: t.clone(), dirty: true, used, encoded: None, bytes: held_bytes(t, None), author: Some(from) });
                true
            }
        }
    }

    /// The one peer whose tiles made all of tile `key`, if one did.
    pub(super) fn sole_author(&self, key: TileKey) -> Option<u64> {
        self.tiles.get(&key).and_then(|h| h.author)
    }

    /// A tile's wire bytes and texels from the cache, filling it; `None`
    /// for a tile not in memory.
    pub(super) fn encoded(&mut self, key: TileKey) -> Option<(Vec<u8>, usize)> {
        let held = self.tiles.get_mut(&key)?;
        let bytes = held.encoded.get_or_insert_with(|| encode_tile(&held.tile)).clone();
        held.bytes = held_bytes(&held.tile, Some(&bytes));
        Some((bytes, held.tile.texels()))
    }

    /// Brings a tile from `store` into memory if it is not there.
    pub(super) fn load(&mut self, key: TileKey, store: Option<&mut TileStore>, stats: &mut RelayStats) {
        if self.tiles.contains_key(&key) {
            return;
        }
        let Some(store) = store else {
            return;
        };
        match store.read(key) {
            Ok(Some(data)) => match tile_from_data(data) {
                Ok(tile) => {
                    stats.tiles_loaded += 1;
                    let bytes = held_bytes(&tile, None);
                    self.tiles.insert(key, Held { tile, dirty: false, used: self.use_counter, encoded: None, bytes, author: None });
                }
                Err(_) => stats.store_errors += 1,
            },
            Ok(None) => {}
            Err(_) => stats.store_errors += 1,
        }
    }

    /// Writes every changed tile to `store`; the first error, after trying
    /// them all (failed tiles stay changed and are tried again).
    pub(super) fn flush(&mut self, store: &mut TileStore, stats: &mut RelayStats) -> Option<StoreError> {
        let mut first = None;
        let mut refused = Vec::new();
        for (key, held) in self.tiles.iter_mut().filter(|(_, h)| h.dirty) {
            match store.write(&tile_to_data(&held.tile)) {
                Ok(()) => {
                    held.dirty = false;
                    stats.tiles_persisted += 1;
                }
                Err(e) if is_full(&e) => refused.push(*key),
                Err(e) => {
                    stats.store_errors += 1;
                    first.get_or_insert(e);
                }
            }
        }
        // New tiles past the disk budget (others of the same tick took the
        // last bytes) are dropped, as they would have been at their merge.
        for key in refused {
            self.tiles.remove(&key);
            stats.rejected.disk_full += 1;
        }
        first
    }

    /// Drops the least recently merged or loaded tiles beyond `cap` tiles
    /// or `cap_bytes` bytes, writing changed ones to `store` first (a tile
    /// whose write fails stays); without a store they are forgotten.
    pub(super) fn trim(&mut self, mut store: Option<&mut TileStore>, cap: usize, cap_bytes: usize, stats: &mut RelayStats) {
        let mut bytes = self.bytes();
        if self.tiles.len() <= cap && bytes <= cap_bytes {
            return;
        }
        let mut by_use: Vec<(u64, TileKey)> = self.tiles.iter().map(|(k, h)| (h.used, *k)).collect();
        by_use.sort_unstable();
        for (_, key) in by_use {
            if self.tiles.len() <= cap && bytes <= cap_bytes {
                break;
            }
            let Some(held) = self.tiles.get(&key) else {
                continue;
            };
            match store.as_deref_mut() {
                Some(store) => {
                    if held.dirty {
                        match store.write(&tile_to_data(&held.tile)) {
                            Ok(()) => stats.tiles_persisted += 1,
                            // A new tile past the budget is dropped, as at its merge.
                            Err(e) if is_full(&e) => stats.rejected.disk_full += 1,
                            Err(_) => {
                                stats.store_errors += 1;
                                continue;
                            }
                        }
                    }
                    stats.tiles_evicted += 1;
                }
                None => stats.tiles_forgotten += 1,
            }
            bytes -= held.bytes;
            self.tiles.remove(&key);
        }
    }
}

/// Bytes a tile held in memory costs: its planes and its cached encoding.
fn held_bytes(t: &SharedTile, encoded: Option<&Vec<u8>>) -> usize {
    96 + 2 * t.deficit.len() + 4 * t.stamps.len() + 4 * t.fallen.len() + encoded.map_or(0, Vec::len)
}
