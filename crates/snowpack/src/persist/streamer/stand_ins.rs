//! The tiles the window stood in for with fresh snow, and what it made
//! there meanwhile, held for the merge with the stored version.

use std::collections::HashMap;

use super::config::WANTED_FLOOR_BYTES;
use crate::persist::{StoreError, TileData, TileKey};

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

/// Every [`StandIn`], with the bytes their `made` tiles hold.
#[derive(Default)]
pub(super) struct StandIns {
    stand_ins: HashMap<TileKey, StandIn>,
    /// Bytes of the stand-ins' `made` tiles.
    made_bytes: usize,
    /// Counts hand-backs, to order them (`StandIn::since`).
    tick: u64,
}

impl StandIns {
    /// Whether `key` is stood in for.
    pub(super) fn contains(&self, key: TileKey) -> bool {
        self.stand_ins.contains_key(&key)
    }

    /// Whether no tile is stood in for.
    pub(super) fn is_empty(&self) -> bool {
        self.stand_ins.is_empty()
    }

    /// Whether `key` is stood in for and what the window made there is
    /// held here (the window has left the tile).
    pub(super) fn is_held(&self, key: TileKey) -> bool {
        self.stand_ins.get(&key).is_some_and(|s| s.made.is_some())
    }

    /// Stands in for `key` (if not already) and takes what the window made
    /// there, if it is held.
    pub(super) fn stand_in(&mut self, key: TileKey) -> Option<TileData> {
        let made = self.stand_ins.entry(key).or_default().made.take();
        self.forget_bytes(made.as_ref());
        made
    }

    /// Stands in for `key`, keeping what is held.
    pub(super) fn mark(&mut self, key: TileKey) {
        self.stand_ins.entry(key).or_default();
    }

    /// Takes the held `made` tile of stand-in `key`, leaving it stood in for.
    pub(super) fn take_made(&mut self, key: TileKey) -> Option<TileData> {
        let made = self.stand_ins.get_mut(&key).and_then(|s| s.made.take());
        self.forget_bytes(made.as_ref());
        made
    }

    /// Ends the stand-in for `key`: what the window made there, if held.
    pub(super) fn remove(&mut self, key: TileKey) -> Option<TileData> {
        let made = self.stand_ins.remove(&key).and_then(|s| s.made);
        self.forget_bytes(made.as_ref());
        made
    }

    /// The tiles stood in for whose `made` version is held, by row then column.
    pub(super) fn held(&self) -> Vec<TileKey> {
        let mut keys: Vec<TileKey> = self.stand_ins.iter().filter(|(_, s)| s.made.is_some()).map(|(k, _)| *k).collect();
        keys.sort_unstable_by_key(|k| (k.row, k.col));
        keys
    }

    /// How many `made` tiles are held.
    pub(super) fn held_count(&self) -> usize {
        self.stand_ins.values().filter(|s| s.made.is_some()).count()
    }

    /// Why stand-in `key`'s stored version could not be read the last time:
    /// `None` if it is not stood in for, `Some(None)` if no read has failed.
    pub(super) fn read_error(&self, key: TileKey) -> Option<Option<&str>> {
        self.stand_ins.get(&key).map(|s| s.read_error.as_deref())
    }

    /// Notes why stand-in `key`'s stored version could not be read (nothing if not stood in for).
    pub(super) fn set_read_error(&mut self, key: TileKey, why: &StoreError) {
        if let Some(stand_in) = self.stand_ins.get_mut(&key) {
            stand_in.read_error = Some(why.to_string());
        }
    }

    /// Holds what the window made at `key` for its merge, if `key` is stood
    /// in for (replacing what was held); otherwise hands `tile` back.
    pub(super) fn hold(&mut self, key: TileKey, tile: TileData) -> Option<TileData> {
        let Some(stand_in) = self.stand_ins.get_mut(&key) else { return Some(tile) };
        self.tick += 1;
        stand_in.since = self.tick;
        self.made_bytes += tile.memory_bytes();
        if let Some(old) = stand_in.made.replace(tile) {
            self.made_bytes -= old.memory_bytes();
        }
        None
    }

    /// Drops the oldest held `made` tiles (never `keep`'s) while they exceed
    /// `budget` (or the floor of tiles waited for, if larger): a disk failing
    /// for long must not grow memory without bound. Each is lost (returned:
    /// how many); its stored version stays as it was.
    pub(super) fn trim(&mut self, keep: TileKey, budget: usize) -> u64 {
        let allowance = budget.max(WANTED_FLOOR_BYTES);
        let mut lost = 0;
        while self.made_bytes > allowance {
            let oldest = self.stand_ins.iter().filter(|(k, s)| **k != keep && s.made.is_some()).min_by_key(|(_, s)| s.since).map(|(k, _)| *k);
            let Some(victim) = oldest else { break };
            if let Some(made) = self.stand_ins.remove(&victim).and_then(|s| s.made) {
                self.made_bytes -= made.memory_bytes();
            }
            tracing::warn!("tile store: what the window made at tile {victim:?} while its stored version could not be read was dropped from memory");
            lost += 1;
        }
        lost
    }

    /// Takes `made`'s bytes off the count (it has left the stand-ins).
    fn forget_bytes(&mut self, made: Option<&TileData>) {
        if let Some(made) = made {
            self.made_bytes -= made.memory_bytes();
        }
    }
}
