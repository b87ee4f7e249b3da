//! The changed-tile flags of shared snow: where the stamp and update passes
//! mark the tiles a press changed (`shaders/shared/share_flags.wgsl`, whose
//! CPU twin this is), and how the CPU turns a copy of them back into tile
//! keys.
//!
//! One `u32` per slot, toroidal by tile key: tile (col, row) of `side`
//! texels has slot `(row mod keys) * keys + (col mod keys)`, with
//! `keys = ceil(resolution / side) + 1`. A window of `resolution` texels
//! overlaps at most `keys` tiles per axis, so the tiles it overlaps never
//! share a slot, and a slot is decoded against the window's origin at the
//! frame the flags were copied. (A tile flagged in one frame and decoded
//! against a later origin, after the window moved past it, would be read as
//! the tile now in its slot; the flags are copied and cleared every frame,
//! so that happens only in a frame whose copy was skipped because every
//! staging buffer was in flight, and only for tiles that left the window.)
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use crate::persist::TileKey;

/// The flags' layout for a window resolution and a sharing tile side.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShareGrid {
    /// Texels per tile side.
    pub side: u32,
    /// Slots per side.
    pub keys: u32,
}

impl ShareGrid {
    /// The layout for a window of `resolution` texels and tiles of `side` (at least 1).
    #[must_use]
    pub fn new(resolution: u32, side: u32) -> Self {
        let side = side.max(1);
        Self { side, keys: resolution.div_ceil(side) + 1 }
    }

    /// Slots (`u32`s) in the flags buffer.
    #[must_use]
    pub fn slots(&self) -> u32 {
        self.keys * self.keys
    }

    /// The slot of the tile holding global texel `g` = (column, row).
    #[must_use]
    pub fn slot(&self, g: [i64; 2]) -> usize {
        let key = TileKey::containing(g[0], g[1], self.side);
        let k = i64::from(self.keys);
        (key.row.rem_euclid(k) * k + key.col.rem_euclid(k)) as usize
    }

    /// The tiles flagged in `flags` (a copy of the buffer), for a window
    /// whose first texel was `origin` (global column, row) and `resolution`
    /// texels a side: each non-zero slot as the key of the one tile the
    /// window overlaps in it, in slot order.
    #[must_use]
    pub fn flagged(&self, origin: [i64; 2], resolution: u32, flags: &[u32]) -> Vec<TileKey> {
        let first = TileKey::containing(origin[0], origin[1], self.side);
        let last = TileKey::containing(origin[0] + i64::from(resolution) - 1, origin[1] + i64::from(resolution) - 1, self.side);
        let k = i64::from(self.keys);
        // The one value in first..first + keys congruent to `m` modulo keys.
        let lift = |first: i64, m: i64| first + (m - first).rem_euclid(k);
        let mut out = Vec::new();
        for (slot, _) in flags.iter().enumerate().filter(|(_, f)| **f != 0) {
            let (r, c) = ((slot as i64) / k, (slot as i64) % k);
            let key = TileKey::new(lift(first.col, c), lift(first.row, r));
            // Slots past the window's tiles can hold no flag from this origin.
            if key.col <= last.col && key.row <= last.row {
                out.push(key);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_tile_of_a_window_decodes_from_its_slot() {
        for (origin, res, side) in [([-37i64, 91i64], 128u32, 16u32), ([0, 0], 64, 8), ([-1, -1], 100, 24), ([1000, -517], 96, 256)] {
            let grid = ShareGrid::new(res, side);
            let mut seen = std::collections::BTreeMap::new();
            for i in 0..i64::from(res) {
                for j in 0..i64::from(res) {
                    let g = [origin[0] + j, origin[1] + i];
                    let key = TileKey::containing(g[0], g[1], side);
                    let slot = grid.slot(g);
                    assert_eq!(*seen.entry(slot).or_insert(key), key, "two tiles share slot {slot}");
                    let mut flags = vec![0; grid.slots() as usize];
                    flags[slot] = 1;
                    assert_eq!(grid.flagged(origin, res, &flags), vec![key]);
                }
            }
        }
    }
}
