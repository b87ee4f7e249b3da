//! Where a store's files live: the file and folder names, the region
//! folders, and a tile file's name for its key and save generation.

use std::path::{Path, PathBuf};

use crate::persist::TileKey;

/// The record of the last complete save.
pub(super) const SAVE_FILE: &str = "save.commit";
/// The store's description file.
pub(super) const META_FILE: &str = "store.meta";
/// The file locked while a store is open.
pub(super) const LOCK_FILE: &str = "store.lock";
/// The folder of region folders.
pub(super) const TILES_DIR: &str = "tiles";
/// Suffix of temporary files (deleted on open).
pub(super) const TEMP_SUFFIX: &str = ".tmp";
/// Suffix given to a tile file that failed to decode.
pub(super) const CORRUPT_SUFFIX: &str = ".corrupt";
/// Tiles per region folder side is `1 << REGION_SHIFT`.
const REGION_SHIFT: u32 = 5;
/// Longest name `write_state` accepts.
pub(super) const MAX_STATE_NAME: usize = 64;

/// Where tile `key` of the store in `dir` lives. Arithmetic shifts keep
/// negative coordinates in their own regions (-1 >> 5 is -1).
#[doc(hidden)]
pub fn tile_path(dir: &Path, key: TileKey) -> PathBuf {
    dir.join(TILES_DIR).join(region_name(key)).join(format!("{}_{}.tile", key.col, key.row))
}

/// The region folder of tile `key`.
pub(super) fn region_name(key: TileKey) -> String {
    format!("r{}_{}", key.col >> REGION_SHIFT, key.row >> REGION_SHIFT)
}

/// Where tile `key`'s version written for save generation `g` lives until committed.
pub(super) fn generation_path(dir: &Path, key: TileKey, g: u64) -> PathBuf {
    dir.join(TILES_DIR).join(region_name(key)).join(format!("{}_{}.g{g}.tile", key.col, key.row))
}

/// `{col}_{row}.tile` (generation `None`) or `{col}_{row}.g{N}.tile` back to its key.
pub(super) fn parse_tile_name(name: &str) -> Option<(TileKey, Option<u64>)> {
    let stem = name.strip_suffix(".tile")?;
    let (stem, generation) = match stem.rsplit_once(".g") {
        Some((stem, g)) => (stem, Some(g.parse().ok()?)),
        None => (stem, None),
    };
    let (col, row) = stem.split_once('_')?;
    Some((TileKey { col: col.parse().ok()?, row: row.parse().ok()? }, generation))
}
