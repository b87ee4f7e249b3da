//! What a peer is sent: the rectangle of tile keys its window (plus a
//! margin) covers, bounded by [`MAX_INTEREST_TILES`].

use crate::persist::TileKey;

/// The most tiles a peer's interest (window plus margin) may cover: bounds
/// what one `Presence` or `Digest` makes the relay walk and remember.
pub const MAX_INTEREST_TILES: usize = 16_384;

/// Tile keys `col0..=col1` × `row0..=row1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct KeyRect {
    col: [i64; 2],
    row: [i64; 2],
}

impl KeyRect {
    /// The tiles overlapping a window, grown by `margin` tiles; `None` when
    /// empty, impossibly placed or larger than [`MAX_INTEREST_TILES`].
    pub(super) fn of_window(first: [i64; 2], resolution: u32, side: u32, margin: i64) -> Option<Self> {
        if resolution == 0 {
            return None;
        }
        let last = [first[0].checked_add(i64::from(resolution) - 1)?, first[1].checked_add(i64::from(resolution) - 1)?];
        let a = TileKey::containing(first[0], first[1], side);
        let b = TileKey::containing(last[0], last[1], side);
        let rect = Self { col: [a.col.checked_sub(margin)?, b.col.checked_add(margin)?], row: [a.row.checked_sub(margin)?, b.row.checked_add(margin)?] };
        let cols = usize::try_from(rect.col[1] - rect.col[0] + 1).ok()?;
        let rows = usize::try_from(rect.row[1] - rect.row[0] + 1).ok()?;
        (cols.checked_mul(rows)? <= MAX_INTEREST_TILES).then_some(rect)
    }

    /// Whether `k` is in the rectangle.
    pub(super) fn contains(&self, k: TileKey) -> bool {
        (self.col[0]..=self.col[1]).contains(&k.col) && (self.row[0]..=self.row[1]).contains(&k.row)
    }

    /// Its keys, row by row.
    pub(super) fn keys(&self) -> impl Iterator<Item = TileKey> + '_ {
        (self.row[0]..=self.row[1]).flat_map(move |row| (self.col[0]..=self.col[1]).map(move |col| TileKey::new(col, row)))
    }

    /// Twice the centre, in tile units (integers, no overflow for real windows).
    pub(super) fn centre2(&self) -> [i128; 2] {
        [i128::from(self.col[0]) + i128::from(self.col[1]), i128::from(self.row[0]) + i128::from(self.row[1])]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_rects_are_bounded() {
        assert!(KeyRect::of_window([0, 0], 0, 16, 1).is_none());
        assert!(KeyRect::of_window([i64::MAX - 4, 0], 64, 16, 1).is_none());
        assert!(KeyRect::of_window([0, 0], u32::MAX, 16, 1).is_none());
        let r = KeyRect::of_window([-16, 0], 32, 16, 1).expect("small window");
        assert_eq!(r, KeyRect { col: [-2, 1], row: [-1, 2] });
        assert_eq!(r.keys().count(), 16);
    }
}
