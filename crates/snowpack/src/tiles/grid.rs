//! [`TileGrid`]: how a window is cut into tiles on the global texel grid,
//! and the size of the slot pool and key table that hold the resident ones.

use crate::error::SnowError;
use crate::persist::TileKey;

/// Tiles around the window that are requested from the store ahead of need.
pub const PREFETCH_MARGIN_TILES: i64 = 2;

/// Spare slots beyond what a one-step move needs ([`TileGrid::slot_count`]).
pub const SPARE_SLOTS: u32 = 32;

/// How a window of `resolution` texels is cut into tiles, and the slot pool
/// and key table that hold the resident ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileGrid {
    side: u32,
    resolution: u32,
}

impl TileGrid {
    /// Tiles of `side` texels (a power of two, 16..=256, dividing the resolution).
    pub fn new(resolution: u32, side: u32) -> Result<Self, SnowError> {
        if !side.is_power_of_two() || !(16..=256).contains(&side) || !resolution.is_multiple_of(side) {
            return Err(SnowError::InvalidParameter {
                field: "tile_texels",
                why: format!("{side} must be a power of two in 16..=256 that divides the resolution {resolution}"),
            });
        }
        Ok(Self { side, resolution })
    }

    /// Texels per window side.
    #[must_use]
    pub fn resolution(&self) -> u32 {
        self.resolution
    }

    /// Tile side (texels).
    #[must_use]
    pub fn side(&self) -> u32 {
        self.side
    }

    /// Side of the toroidal key table: every resident tile lies within
    /// `PREFETCH_MARGIN_TILES` tiles of the window, a span of at most
    /// `resolution/side + 1 + 2·margin` tiles, one less than this, so no two
    /// resident tiles share an entry.
    #[must_use]
    pub fn keys_per_side(&self) -> u32 {
        self.resolution / self.side + 2 + 2 * PREFETCH_MARGIN_TILES as u32
    }

    /// Slots in the pool: the most tiles an unaligned window partly covers
    /// (its edge tiles, `4(n+1) − 4` with `n = resolution/side`), the tiles a
    /// one-tile diagonal step leaves behind and that keep texels stashed in
    /// that move (`2(n+1) − 1`), and `SPARE_SLOTS` for tiles near the window
    /// (prefetched, or recently left: a window jittering across a tile
    /// boundary keeps them). 225 at 1024/32.
    #[must_use]
    pub fn slot_count(&self) -> usize {
        let n = self.resolution / self.side;
        (4 * (n + 1) - 4 + 2 * (n + 1) - 1 + SPARE_SLOTS) as usize
    }

    /// Texels per tile.
    #[must_use]
    pub fn area(&self) -> usize {
        (self.side * self.side) as usize
    }

    /// The tile holding global texel `g` (`[column, row]`).
    #[must_use]
    pub fn key_of(&self, g: [i64; 2]) -> TileKey {
        let s = i64::from(self.side);
        TileKey { col: g[0].div_euclid(s), row: g[1].div_euclid(s) }
    }

    /// The key table entry of tile `key`.
    #[must_use]
    pub fn table_entry(&self, key: TileKey) -> usize {
        let n = i64::from(self.keys_per_side());
        (key.row.rem_euclid(n) * n + key.col.rem_euclid(n)) as usize
    }

    /// Whether tile `key` lies wholly inside the window at `origin` (its
    /// texels are all in the window's buffers: it needs no slot).
    #[must_use]
    pub fn inside(&self, key: TileKey, origin: [i64; 2]) -> bool {
        let (s, r) = (i64::from(self.side), i64::from(self.resolution));
        key.col * s >= origin[0] && (key.col + 1) * s <= origin[0] + r && key.row * s >= origin[1] && (key.row + 1) * s <= origin[1] + r
    }

    /// Whether tile `key` has a texel in the window at `origin`.
    #[must_use]
    pub fn touched(&self, key: TileKey, origin: [i64; 2]) -> bool {
        let (s, r) = (i64::from(self.side), i64::from(self.resolution));
        (key.col + 1) * s > origin[0] && key.col * s < origin[0] + r && (key.row + 1) * s > origin[1] && key.row * s < origin[1] + r
    }

    /// Whether tile `key` is within `margin` tiles of the window at `origin`.
    #[must_use]
    pub fn near(&self, key: TileKey, origin: [i64; 2], margin: i64) -> bool {
        let last = i64::from(self.resolution) - 1;
        let (lo, hi) = (self.key_of(origin), self.key_of([origin[0] + last, origin[1] + last]));
        key.col >= lo.col - margin && key.col <= hi.col + margin && key.row >= lo.row - margin && key.row <= hi.row + margin
    }

    /// Tiles within `margin` tiles of the window at `origin` (margin 0: those it touches).
    #[must_use]
    pub fn around(&self, origin: [i64; 2], margin: i64) -> Vec<TileKey> {
        let last = i64::from(self.resolution) - 1;
        let lo = self.key_of(origin);
        let hi = self.key_of([origin[0] + last, origin[1] + last]);
        let mut keys = Vec::new();
        for row in lo.row - margin..=hi.row + margin {
            for col in lo.col - margin..=hi.col + margin {
                keys.push(TileKey { col, row });
            }
        }
        keys
    }

    /// [`Self::around`], the tiles nearest the window's centre first (by
    /// the distance of their centres, row-major among equals): the order
    /// the streamer is asked in, so after a jump or at a start the disk
    /// reads the snow under the player first, and what a slow disk leaves
    /// to stand-ins is the window's rim.
    #[must_use]
    pub fn nearest_first(&self, origin: [i64; 2], margin: i64) -> Vec<TileKey> {
        let (s, r) = (i64::from(self.side), i64::from(self.resolution));
        // Twice the coordinates, so the centres are integers.
        let centre = [2 * origin[0] + r, 2 * origin[1] + r];
        let distance = |k: &TileKey| {
            let (dx, dz) = ((2 * k.col + 1) * s - centre[0], (2 * k.row + 1) * s - centre[1]);
            dx * dx + dz * dz
        };
        let mut keys = self.around(origin, margin);
        keys.sort_by_key(distance);
        keys
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tiles come nearest the window's centre first: the centre's tile,
    /// then rings outward, every tile of `around` once.
    #[test]
    fn nearest_first_starts_under_the_centre() {
        let grid = TileGrid::new(64, 16).expect("grid");
        for origin in [[0, 0], [-37, 5], [1000, -999]] {
            let keys = grid.nearest_first(origin, 2);
            let mut all = grid.around(origin, 2);
            assert_eq!(keys.len(), all.len());
            let centre = grid.key_of([origin[0] + 32, origin[1] + 32]);
            let first = keys[0];
            assert!((first.col - centre.col).abs() <= 1 && (first.row - centre.row).abs() <= 1, "{first:?} is not by the centre {centre:?}");
            let ring = |k: &TileKey| {
                let (c, r) = ((2 * k.col + 1) * 16 - (2 * origin[0] + 64), (2 * k.row + 1) * 16 - (2 * origin[1] + 64));
                c * c + r * r
            };
            assert!(keys.windows(2).all(|w| ring(&w[0]) <= ring(&w[1])), "not nearest first: {keys:?}");
            let mut sorted = keys.clone();
            sorted.sort_by_key(|k| (k.row, k.col));
            all.sort_by_key(|k| (k.row, k.col));
            assert_eq!(sorted, all);
        }
    }
}
