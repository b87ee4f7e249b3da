//! Open-world persistence without a GPU: the snow of tiles kept on disk.
//!
//! snowpack's deformation window hands out whole tiles (`side`×`side`
//! texels on the global texel grid) as they leave the player's
//! neighbourhood and asks for them again when they come back into view; a
//! relay keeps its world's tiles the same way. This module is the part of
//! that without a GPU or a thread: the tile type ([`TileData`]), its
//! compressed file format ([`codec`]) and a crash-safe store with a disk
//! budget ([`TileStore`]). snowpack's `TileStreamer` (a worker thread with a
//! bounded memory cache) runs over it. `docs/persistence.md` explains the
//! choices.

pub mod codec;
#[doc(hidden)]
pub mod disk;
pub mod store;

use std::path::PathBuf;

pub use crate::error::StoreError;
pub use codec::{FORMAT_VERSION, decode, encode};
pub use store::{DEFAULT_DISK_BUDGET_BYTES, StoreConfig, TileStore, TileStoreExt, WhenFull};

/// The largest tile side the format accepts (the whole default window).
pub const MAX_SIDE: u32 = 1024;

/// Global tile coordinates: tile (col, row) holds global texels
/// `col*side .. (col+1)*side` (x) and `row*side .. (row+1)*side` (z).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TileKey {
    /// Tile column (global texel column divided by `side`, rounded down).
    pub col: i64,
    /// Tile row (global texel row divided by `side`, rounded down; row = +z).
    pub row: i64,
}

impl TileKey {
    /// The tile at column `col`, row `row`.
    #[must_use]
    pub const fn new(col: i64, row: i64) -> Self {
        Self { col, row }
    }

    /// The tile holding global texel (`texel_col`, `texel_row`). Rounds
    /// towards negative infinity, so texel -1 is in tile -1, not 0.
    #[must_use]
    pub fn containing(texel_col: i64, texel_row: i64, side: u32) -> Self {
        let side = i64::from(side.max(1));
        Self { col: texel_col.div_euclid(side), row: texel_row.div_euclid(side) }
    }

    /// Global texel `[column, row]` of the tile's first texel.
    #[must_use]
    pub fn first_texel(self, side: u32) -> [i64; 2] {
        let side = i64::from(side);
        [self.col.saturating_mul(side), self.row.saturating_mul(side)]
    }
}

/// The simulation clock a tile's contents are current at (cumulative
/// counters since the world began), so a returning tile can be caught up
/// with the refill and snowfall it missed while it was away.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SnowClock {
    /// Simulated seconds.
    pub time_s: f64,
    /// Refill so far (m): the sum of `refill_m_per_s * dt`.
    pub refill_m: f64,
    /// Snowfall so far on open ground (m).
    pub fallen_m: f64,
    /// Stamp quanta issued so far (the stamp encoding's clock).
    pub stamp_quanta: u64,
}

/// One tile's persistent state, row-major (row = +z), `side*side` texels per plane.
#[derive(Clone, Debug, PartialEq)]
pub struct TileData {
    /// Where the tile is.
    pub key: TileKey,
    /// Texels per side.
    pub side: u32,
    /// The clock the contents are current at.
    pub clock: SnowClock,
    /// The snow surface height's f32 bits XOR its rest height's (terrain +
    /// depth + this texel's snowfall, f32 adds in that order): 0 where the
    /// snow is untouched, so untouched tiles compress to almost nothing,
    /// and the height comes back bit for bit where the GPU recomputes the
    /// rest (the tile restore pass).
    pub snow_xor_rest: Vec<u32>,
    /// Packed footprints (`shared/stamp.wgsl`).
    pub stamps: Vec<u32>,
    /// Snowfall so far per texel (m); empty when the world has no snowfall.
    pub fallen: Vec<f32>,
    /// Packed snow per texel ([`SNOW_QUANTUM_M`](crate::SNOW_QUANTUM_M)
    /// steps of fresh snow that presses squeezed into the column,
    /// `docs/mechanics.md`); empty reads as none (fresh snow), as tiles
    /// written before the plane existed do.
    pub packed: Vec<u16>,
}

impl TileData {
    /// Texels per plane (`side²`).
    #[must_use]
    pub fn texels(&self) -> usize {
        let side = self.side as usize;
        side * side
    }

    /// Bytes of the planes (4 per texel per plane present); the streamer's
    /// memory budget counts this. The struct itself (about 100 bytes) is left
    /// out, so budgets are simple multiples of a tile.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of_val(self.snow_xor_rest.as_slice())
            + std::mem::size_of_val(self.stamps.as_slice())
            + std::mem::size_of_val(self.fallen.as_slice())
            + std::mem::size_of_val(self.packed.as_slice())
    }

    /// Checks that `side` is in `1..=`[`MAX_SIDE`] and the planes hold
    /// `side²` texels each (`fallen` and `packed` may be empty). The error is a
    /// [`StoreError::Mismatch`] without a path.
    pub fn validate(&self) -> Result<(), StoreError> {
        let why = if self.side == 0 || self.side > MAX_SIDE {
            format!("tile side {} is outside 1..={MAX_SIDE}", self.side)
        } else if self.snow_xor_rest.len() != self.texels() {
            format!("snow holds {} texels, a {}² tile needs {}", self.snow_xor_rest.len(), self.side, self.texels())
        } else if self.stamps.len() != self.texels() {
            format!("stamps holds {} texels, a {}² tile needs {}", self.stamps.len(), self.side, self.texels())
        } else if !self.fallen.is_empty() && self.fallen.len() != self.texels() {
            format!("fallen holds {} texels, a {}² tile needs {} (or none)", self.fallen.len(), self.side, self.texels())
        } else if !self.packed.is_empty() && self.packed.len() != self.texels() {
            format!("packed holds {} texels, a {}² tile needs {} (or none)", self.packed.len(), self.side, self.texels())
        } else {
            return Ok(());
        };
        Err(StoreError::Mismatch { path: PathBuf::new(), why })
    }
}

/// Temporary directories for the store's unit tests (`testing::TestDir`,
/// which snowpack's tests use as well).
#[cfg(test)]
pub(crate) use crate::testing as test_dir;
