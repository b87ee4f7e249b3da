//! Opening a store after whatever happened to it: its folders, lock and
//! meta file checked or made, the tiles indexed from the disk, and the
//! files of an unfinished save finished or undone.

use std::collections::{BTreeSet, HashMap};
use std::io;
use std::path::Path;

use super::files::{atomic_write, create_dirs, io_error, new_entry_synced, remove_temp_files, sync_dir};
use super::layout::{LOCK_FILE, META_FILE, TILES_DIR, generation_path, parse_tile_name, region_name, tile_path};
use super::records::{check_meta, meta_bytes};
use crate::persist::disk::{Disk, DiskLock};
use crate::persist::{MAX_SIDE, StoreError, TileKey};

/// The tiles found on opening: the saved version of each key (its time and
/// length), and the files of saves in progress (generation, key, length, time).
pub(super) type FoundTiles = (HashMap<TileKey, (std::time::SystemTime, u64)>, Vec<(u64, TileKey, u64, std::time::SystemTime)>);

/// Checks the tile side, makes the store's folders, takes its lock, checks
/// (or writes) its meta file and removes temporary files a crash left.
pub(super) fn prepare_dir(disk: &dyn Disk, dir: &Path, side: u32) -> Result<Option<DiskLock>, StoreError> {
    let meta_path = dir.join(META_FILE);
    if side == 0 || side > MAX_SIDE {
        return Err(StoreError::Mismatch { path: meta_path, why: format!("tile side {side} is outside 1..={MAX_SIDE}") });
    }
    create_dirs(disk, dir)?;
    let lock = match disk.lock(&dir.join(LOCK_FILE)) {
        Ok(lock) => lock,
        Err(source) => {
            return Err(StoreError::Io { path: dir.join(LOCK_FILE), op: "lock (another TileStore has the store open)", source });
        }
    };
    match disk.read(&meta_path) {
        Ok(bytes) => check_meta(&meta_path, &bytes, side)?,
        Err(e) if e.kind() == io::ErrorKind::NotFound => atomic_write(disk, &meta_path, &meta_bytes(side))?,
        Err(e) => {
            return Err(StoreError::Io { path: meta_path, op: "read", source: e });
        }
    }
    let tiles = dir.join(TILES_DIR);
    match disk.create_dir(&tiles) {
        Err(e) if e.kind() != io::ErrorKind::AlreadyExists => {
            return Err(StoreError::Io { path: tiles, op: "create the tiles directory", source: e });
        }
        Ok(()) => new_entry_synced(disk, &tiles, dir)?,
        Err(_) => {}
    }
    if let Ok(entries) = disk.list(dir) {
        remove_temp_files(disk, dir, &entries);
    }
    Ok(lock)
}

/// Every tile file under `tiles`: saved versions by key, and the files of
/// saves in progress; temporary files are removed, files not where this
/// store puts them are left alone.
pub(super) fn index_tiles(disk: &dyn Disk, tiles: &Path) -> Result<FoundTiles, StoreError> {
    let mut found = HashMap::new();
    let mut generations = Vec::new();
    let regions = disk.list(tiles).map_err(io_error(tiles, "list"))?;
    for region in regions {
        if !region.is_dir {
            continue;
        }
        let path = tiles.join(&region.name);
        let Ok(files) = disk.list(&path) else {
            tracing::warn!("tile store: cannot list {}; its tiles are not indexed", path.display());
            continue;
        };
        remove_temp_files(disk, &path, &files);
        for file in files {
            let Some((key, generation)) = file.name.to_str().and_then(parse_tile_name) else {
                continue;
            };
            if region_name(key) != region.name.to_string_lossy() {
                continue; // Not where this store puts that tile: not ours.
            }
            if let Some((len, modified)) = file.file {
                match generation {
                    None => {
                        found.insert(key, (modified, len));
                    }
                    Some(g) => generations.push((g, key, len, modified)),
                }
            }
        }
    }
    Ok((found, generations))
}

/// Tiles written for a save: a committed one's replace their saved versions
/// (a crash cut that short), a later one's are deleted (written after the
/// last complete save). Oldest generation first; durable before anything
/// new is written, so a deleted file of an unfinished save does not come
/// back once that generation is committed.
pub(super) fn finish_generations(
    disk: &dyn Disk,
    dir: &Path,
    committed: Option<u64>,
    mut generations: Vec<(u64, TileKey, u64, std::time::SystemTime)>,
    found: &mut HashMap<TileKey, (std::time::SystemTime, u64)>,
) -> Result<(), StoreError> {
    generations.sort_unstable();
    let mut touched_regions = BTreeSet::new();
    for (g, key, len, modified) in generations {
        let from = generation_path(dir, key, g);
        if committed.is_some_and(|c| g <= c) {
            let to = tile_path(dir, key);
            disk.rename(&from, &to).map_err(io_error(&to, "replace the saved tile (finishing a save)"))?;
            found.insert(key, (modified, len));
        } else {
            match disk.remove_file(&from) {
                Err(e) if e.kind() != io::ErrorKind::NotFound => {
                    return Err(StoreError::Io { path: from, op: "delete (not part of a complete save)", source: e });
                }
                _ => {}
            }
        }
        touched_regions.insert(from.parent().map(Path::to_owned).unwrap_or_default());
    }
    for region in &touched_regions {
        sync_dir(disk, region)?;
    }
    Ok(())
}
