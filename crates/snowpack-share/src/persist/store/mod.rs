//! The crash-safe tile store on disk: one file per tile, replaced atomically.
//!
//! ```text
//! DIR/store.meta                     magic, format version, tile side, CRC32
//! DIR/store.lock                     held (advisory lock) while a TileStore has DIR open
//! DIR/{name}.state                   named blobs (`write_state`), framed with a CRC32
//! DIR/save.commit                    the last complete save: its generation and states (`commit`)
//! DIR/tiles/r{col>>5}_{row>>5}/{col}_{row}.tile
//! DIR/tiles/r{col>>5}_{row>>5}/{col}_{row}.g{N}.tile   a tile written for save N, not yet committed
//! ```
//!
//! Every file is written to a unique temporary file beside it, synced,
//! renamed over the old one and the directory synced, so a crash (or a
//! kill) leaves each file either its old or its new version, never a mix.
//! A folder the store creates is synced into its parent before anything is
//! written in it, so a write that returned survives a power cut.
//! Temporary files left by a crash are deleted on open.
//!
//! Saves ([`TileStore::begin_saves`]): from then on a tile is written beside
//! its saved version, as generation `N` of the save being made, and the save
//! is made whole by one atomic write, `save.commit`, naming generation `N`
//! and holding the states saved with it; the generation's files then replace
//! their saved versions. On open, files of a committed generation finish
//! replacing theirs and files of a later one (written after the last save)
//! are deleted, so a crash at any moment leaves the last complete save:
//! every tile and state from the same save. Region folders of
//! 32×32 tiles keep directories small. All file-system calls go through a
//! [`Disk`] ([`OsDisk`] unless a test supplies one).

mod budget;
mod files;
mod index;
mod layout;
mod records;
mod recovery;
#[cfg(test)]
mod tests;

use std::collections::BTreeSet;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::codec::{decode, encode};
use super::disk::{Disk, DiskLock, OsDisk};
use super::{StoreError, TileData, TileKey};
use files::{atomic_write, new_entry_synced, sync_dir};
use index::TileIndex;
use layout::{CORRUPT_SUFFIX, MAX_STATE_NAME, META_FILE, SAVE_FILE, TILES_DIR, generation_path};
use records::{decode_save, encode_save, frame_state, meta_side, unframe_state};
use recovery::{finish_generations, index_tiles, prepare_dir};

pub use budget::{DEFAULT_DISK_BUDGET_BYTES, StoreConfig, WhenFull};
#[doc(hidden)]
pub use layout::tile_path;

/// Tiles on disk, one file each, with an index of their sizes and recency
/// and a disk budget. Blocking: the streamer runs it on its worker thread.
///
/// One `TileStore` at a time may have a directory open (an advisory lock on
/// `store.lock` enforces it where the file system supports locks).
#[derive(Debug)]
pub struct TileStore {
    disk: Arc<dyn Disk>,
    dir: PathBuf,
    side: u32,
    config: StoreConfig,
    /// The tiles on disk: sizes, recency, save generations.
    index: TileIndex,
    evicted: u64,
    /// The generation of the last complete save (0: none).
    committed: u64,
    /// Tiles are written for the next save (generation `committed + 1`).
    saving: bool,
    /// Held for the lock; released when the store is dropped (or the process dies).
    _lock: Option<DiskLock>,
}

impl TileStore {
    /// Opens the store in `dir` for tiles of `side`² texels, creating it if
    /// missing. An existing store must have the same tile side and format
    /// version. Leftover temporary files are deleted, the tiles are indexed
    /// (recency from their modification times) and, if the budget is now
    /// smaller than what is stored, the oldest are evicted.
    pub fn open(dir: &Path, side: u32, config: StoreConfig) -> Result<Self, crate::StoreError> {
        Self::open_on(Arc::new(OsDisk), dir, side, config).map_err(Into::into)
    }

    fn state_path(&self, name: &str) -> Result<PathBuf, StoreError> {
        let ok = !name.is_empty() && name.len() <= MAX_STATE_NAME && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_');
        if ok {
            Ok(self.dir.join(format!("{name}.state")))
        } else {
            Err(StoreError::Mismatch {
                path: self.dir.clone(),
                why: format!("{name:?} is not a state name (1 to {MAX_STATE_NAME} ASCII letters, digits, '-', '_')"),
            })
        }
    }

    /// The file holding a tile's newest version: the one written for the
    /// next save, if any, else the plain one.
    fn live_path(&self, key: TileKey) -> PathBuf {
        match self.index.generation(key) {
            Some(g) => generation_path(&self.dir, key, g),
            None => tile_path(&self.dir, key),
        }
    }

    fn quarantine(&mut self, key: TileKey, path: &Path) {
        self.index.forget(key);
        let mut aside = path.as_os_str().to_owned();
        aside.push(CORRUPT_SUFFIX);
        if let Err(e) = self.disk.rename(path, Path::new(&aside)) {
            tracing::warn!("tile store: cannot move the corrupt tile {} aside: {e}", path.display());
        }
    }

    /// Deletes the least recently touched tiles (never `keep`) until the
    /// total is within the budget (never, when the store refuses new tiles instead).
    fn enforce_budget(&mut self, keep: Option<TileKey>) -> Result<(), StoreError> {
        let budget = budget::eviction_budget(&self.config);
        while budget > 0 && self.index.total_bytes() > budget {
            let Some(key) = self.index.oldest_except(keep) else {
                break;
            };
            let path = self.live_path(key);
            // Not synced: a power cut can only bring an evicted tile back.
            match self.disk.remove_file(&path) {
                Err(e) if e.kind() != io::ErrorKind::NotFound => {
                    return Err(StoreError::Io { path, op: "delete (evicting to the disk budget)", source: e });
                }
                _ => {}
            }
            if path != self.tile_path(key) {
                // Its saved version goes too (best effort), or it would come back.
                let _ = self.disk.remove_file(&self.tile_path(key));
            }
            self.index.forget(key);
            self.evicted += 1;
            if let Some(region) = path.parent() {
                // Best effort: fails (harmlessly) while the region holds other tiles.
                let _ = self.disk.remove_dir(region);
            }
        }
        Ok(())
    }
}

/// The tile-level calls of a [`TileStore`] beyond a game's API: what
/// snowpack's GPU side, the relay, the tools and the tests use (a named
/// extension trait, so the store has one shape with or without
/// `low_level`; `snowpack::low_level::TileStoreExt` re-exports it).
pub trait TileStoreExt: Sized {
    /// [`TileStore::open`] on another [`Disk`] than the operating system's
    /// (a fault-injecting one in tests: `testing::PowerLossDisk`).
    fn open_on(disk: Arc<dyn Disk>, dir: &Path, side: u32, config: StoreConfig) -> Result<Self, StoreError>;

    /// The tile side of the store in `dir` (its `store.meta`), without
    /// opening or locking it; `None` where there is no store yet. A damaged
    /// or foreign `store.meta` is an error naming it.
    fn side_in(dir: &Path) -> Result<Option<u32>, StoreError>;

    /// Reads a tile. `Ok(None)`: it was never written (or was evicted).
    ///
    /// A tile that fails to decode is an error naming its file, which is
    /// renamed to `*.tile.corrupt` (best effort, for inspection) and dropped
    /// from the index, so the next read answers `Ok(None)` and the caller
    /// can write fresh snow there.
    fn read(&mut self, key: TileKey) -> Result<Option<TileData>, StoreError>;

    /// Writes a tile, atomically replacing any older version, then evicts the
    /// least recently touched tiles (never this one) until the total is
    /// within the disk budget. An error from eviction comes after the tile
    /// itself was written.
    fn write(&mut self, tile: &TileData) -> Result<(), StoreError>;

    /// Writes a small named blob (the saved window, the clock) atomically,
    /// framed with a magic, the format version and a CRC32. Names are 1 to
    /// 64 characters of ASCII letters, digits, `-` and `_`.
    fn write_state(&self, name: &str, bytes: &[u8]) -> Result<(), StoreError>;

    /// Reads a blob written by [`TileStore::commit`] with the last complete
    /// save, or else by [`TileStore::write_state`]; `Ok(None)` if there is none.
    fn read_state(&self, name: &str) -> Result<Option<Vec<u8>>, StoreError>;

    /// From now on tiles are written for the next save (beside their saved
    /// versions, which stay as they are until [`TileStore::commit`]), so a
    /// crash before the save is complete leaves the last complete one. A
    /// store that holds a save is in this mode from when it is opened.
    fn begin_saves(&mut self);

    /// Completes a save: one atomic write of `save.commit` (the new
    /// generation and `states`, named blobs as for
    /// [`TileStore::write_state`], CRC-checked) makes every tile written
    /// since the last save part of it; then those files replace their
    /// saved versions (a crash meanwhile is finished on open). Before it
    /// returns, a crash leaves the old save; once it has returned, the new
    /// one. Call once every tile of the save is written.
    fn commit(&mut self, states: &[(&str, &[u8])]) -> Result<(), StoreError>;

    /// The store's directory.
    #[must_use]
    fn dir(&self) -> &Path;

    /// Texels per tile side.
    #[must_use]
    fn side(&self) -> u32;

    /// Tiles on disk.
    #[must_use]
    fn disk_tiles(&self) -> usize;

    /// Bytes of tile files on disk (what the budget limits).
    #[must_use]
    fn disk_bytes(&self) -> u64;

    /// Tiles deleted to keep within the budget since the store was opened.
    #[must_use]
    fn evicted(&self) -> u64;

    /// Whether a tile is on disk (by the index; no I/O).
    #[must_use]
    fn contains(&self, key: TileKey) -> bool;

    /// Whether a new tile may still be written: always, unless the store
    /// refuses new tiles ([`WhenFull::RefuseNew`]) and its budget is spent.
    fn has_room(&self) -> bool;

    /// The keys of every tile on disk (by the index; no I/O), in no particular order.
    fn keys(&self) -> impl Iterator<Item = TileKey> + '_;

    /// Size of a tile's file, if it is on disk (by the index; no I/O).
    #[must_use]
    fn tile_bytes(&self, key: TileKey) -> Option<u64>;

    /// Where a tile's file is (whether or not it exists).
    #[must_use]
    fn tile_path(&self, key: TileKey) -> PathBuf;
}

impl TileStoreExt for TileStore {
    fn open_on(disk: Arc<dyn Disk>, dir: &Path, side: u32, config: StoreConfig) -> Result<Self, StoreError> {
        let lock = prepare_dir(&*disk, dir, side)?;
        let save_path = dir.join(SAVE_FILE);
        let committed = match disk.read(&save_path) {
            Ok(bytes) => Some(decode_save(&save_path, &bytes)?.0),
            Err(e) if e.kind() == io::ErrorKind::NotFound => None,
            Err(e) => return Err(StoreError::Io { path: save_path, op: "read", source: e }),
        };
        let (mut found, generations) = index_tiles(&*disk, &dir.join(TILES_DIR))?;
        finish_generations(&*disk, dir, committed, generations, &mut found)?;
        // Oldest first; the key breaks ties (file times are often coarser than writes).
        let mut found: Vec<(std::time::SystemTime, TileKey, u64)> = found.into_iter().map(|(key, (modified, len))| (modified, key, len)).collect();
        found.sort_unstable();

        let mut store = Self {
            disk,
            dir: dir.to_owned(),
            side,
            config,
            index: TileIndex::with_capacity(found.len()),
            evicted: 0,
            committed: committed.unwrap_or(0),
            saving: committed.is_some(),
            _lock: lock,
        };
        for (_, key, bytes) in found {
            store.index.insert(key, bytes, None);
        }
        if let Err(e) = store.enforce_budget(None) {
            // The store still works; the next write tries again.
            tracing::warn!("tile store: over its disk budget: {e}");
        }
        Ok(store)
    }

    fn side_in(dir: &Path) -> Result<Option<u32>, StoreError> {
        let path = dir.join(META_FILE);
        match std::fs::read(&path) {
            Ok(bytes) => meta_side(&path, &bytes).map(Some),
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(None),
            Err(source) => Err(StoreError::Io { path, op: "read", source }),
        }
    }

    fn read(&mut self, key: TileKey) -> Result<Option<TileData>, StoreError> {
        if !self.index.contains(key) {
            return Ok(None);
        }
        let path = self.live_path(key);
        let bytes = match self.disk.read(&path) {
            Ok(bytes) => bytes,
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                // Deleted behind the store's back: as if never written.
                self.index.forget(key);
                return Ok(None);
            }
            Err(e) => {
                return Err(StoreError::Io { path, op: "read", source: e });
            }
        };
        let tile = decode(&bytes).and_then(|tile| {
            if tile.key != key || tile.side != self.side {
                return Err(StoreError::Mismatch {
                    path: PathBuf::new(),
                    why: format!("holds tile {:?} of side {}, expected {key:?} of side {}", tile.key, tile.side, self.side),
                });
            }
            Ok(tile)
        });
        match tile {
            Ok(tile) => {
                self.index.touch(key);
                Ok(Some(tile))
            }
            Err(e) => {
                self.quarantine(key, &path);
                Err(e.at(&path))
            }
        }
    }

    fn write(&mut self, tile: &TileData) -> Result<(), StoreError> {
        let path = self.tile_path(tile.key);
        if tile.side != self.side {
            return Err(StoreError::Mismatch { path, why: format!("the tile is {}², the store holds {}² tiles", tile.side, self.side) });
        }
        tile.validate().map_err(|e| e.at(&path))?;
        let bytes = encode(tile);
        budget::refuse_if_full(&self.config, self.index.total_bytes(), self.index.contains(tile.key), bytes.len() as u64, &path)?;
        // While saving, beside the saved version, for the next save.
        let generation = self.saving.then_some(self.committed + 1);
        let path = generation.map_or(path, |g| generation_path(&self.dir, tile.key, g));
        if let Some(region) = path.parent() {
            // `create_dir`, not `create_dir_all`: if `tiles` itself has gone,
            // that is an error to report, not a directory to recreate.
            match self.disk.create_dir(region) {
                Err(e) if e.kind() != io::ErrorKind::AlreadyExists => {
                    return Err(StoreError::Io { path: region.to_owned(), op: "create the region directory", source: e });
                }
                // A new region folder is an entry in `tiles`: synced, so a
                // power cut cannot lose the folder under a synced tile.
                Ok(()) => {
                    if let Some(tiles) = region.parent() {
                        new_entry_synced(&*self.disk, region, tiles)?;
                    }
                }
                Err(_) => {}
            }
        }
        atomic_write(&*self.disk, &path, &bytes)?;
        self.index.forget(tile.key);
        self.index.insert(tile.key, bytes.len() as u64, generation);
        self.enforce_budget(Some(tile.key))
    }

    fn write_state(&self, name: &str, bytes: &[u8]) -> Result<(), StoreError> {
        let path = self.state_path(name)?;
        atomic_write(&*self.disk, &path, &frame_state(bytes))
    }

    fn read_state(&self, name: &str) -> Result<Option<Vec<u8>>, StoreError> {
        let path = self.state_path(name)?;
        // The last complete save's states first (read from disk each time:
        // what is there is the answer).
        let save_path = self.dir.join(SAVE_FILE);
        match self.disk.read(&save_path) {
            Ok(bytes) => {
                if let Some((_, bytes)) = decode_save(&save_path, &bytes)?.1.into_iter().find(|(n, _)| n == name) {
                    return Ok(Some(bytes));
                }
            }
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(e) => return Err(StoreError::Io { path: save_path, op: "read", source: e }),
        }
        let framed = match self.disk.read(&path) {
            Ok(framed) => framed,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
            Err(e) => {
                return Err(StoreError::Io { path, op: "read", source: e });
            }
        };
        unframe_state(path, &framed).map(Some)
    }

    fn begin_saves(&mut self) {
        self.saving = true;
    }

    fn commit(&mut self, states: &[(&str, &[u8])]) -> Result<(), StoreError> {
        for (name, _) in states {
            self.state_path(name)?;
        }
        let generation = self.committed + 1;
        atomic_write(&*self.disk, &self.dir.join(SAVE_FILE), &encode_save(generation, states))?;
        self.committed = generation;
        self.saving = true;
        // Best effort: what is not done here, open does.
        let mut regions = BTreeSet::new();
        for (key, g) in self.index.generations() {
            let to = tile_path(&self.dir, key);
            match self.disk.rename(&generation_path(&self.dir, key, g), &to) {
                Ok(()) => {
                    self.index.clear_generation(key);
                    regions.insert(to.parent().map(Path::to_owned).unwrap_or_default());
                }
                Err(e) => tracing::warn!("tile store: {} stays beside its saved version until the store is opened again: {e}", to.display()),
            }
        }
        for region in regions {
            if let Err(e) = sync_dir(&*self.disk, &region) {
                tracing::warn!("tile store: {e}");
            }
        }
        Ok(())
    }

    fn dir(&self) -> &Path {
        &self.dir
    }

    fn side(&self) -> u32 {
        self.side
    }

    fn disk_tiles(&self) -> usize {
        self.index.len()
    }

    fn disk_bytes(&self) -> u64 {
        self.index.total_bytes()
    }

    fn evicted(&self) -> u64 {
        self.evicted
    }

    fn contains(&self, key: TileKey) -> bool {
        self.index.contains(key)
    }

    fn has_room(&self) -> bool {
        budget::has_room(&self.config, self.index.total_bytes())
    }

    fn keys(&self) -> impl Iterator<Item = TileKey> + '_ {
        self.index.keys()
    }

    fn tile_bytes(&self, key: TileKey) -> Option<u64> {
        self.index.bytes(key)
    }

    fn tile_path(&self, key: TileKey) -> PathBuf {
        tile_path(&self.dir, key)
    }
}
