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

use std::collections::{BTreeSet, HashMap};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use super::codec::{FORMAT_VERSION, decode, encode, readable};
use super::disk::{DirEntry, Disk, DiskLock, OsDisk};
use super::{MAX_SIDE, StoreError, TileData, TileKey};

/// Identifies `store.meta`.
const META_MAGIC: &[u8; 8] = b"SNOWSTOR";
/// Identifies a `.state` file.
const STATE_MAGIC: &[u8; 8] = b"SNOWSTAT";
/// Identifies `save.commit`.
const SAVE_MAGIC: &[u8; 8] = b"SNOWSAVE";
/// The record of the last complete save.
const SAVE_FILE: &str = "save.commit";
/// The store's description file.
const META_FILE: &str = "store.meta";
/// The file locked while a store is open.
const LOCK_FILE: &str = "store.lock";
/// The folder of region folders.
const TILES_DIR: &str = "tiles";
/// Suffix of temporary files (deleted on open).
const TEMP_SUFFIX: &str = ".tmp";
/// Suffix given to a tile file that failed to decode.
const CORRUPT_SUFFIX: &str = ".corrupt";
/// Tiles per region folder side is `1 << REGION_SHIFT`.
const REGION_SHIFT: u32 = 5;
/// Longest name `write_state` accepts.
const MAX_STATE_NAME: usize = 64;

/// The disk budget of [`StoreConfig::default`]: 1 GiB of tile files (some
/// 200,000 tiles of 32² texels as a relay keeps them, a few thousand of a
/// game's 64² height tiles).
pub const DEFAULT_DISK_BUDGET_BYTES: u64 = 1 << 30;

/// What a store does when a write would take it past its disk budget.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WhenFull {
    /// Deletes the least recently touched tiles (they come back as fresh
    /// snow): a game's store, a cache of the world around its player.
    #[default]
    EvictOldest,
    /// Keeps every tile and refuses to write a new one
    /// (an I/O error, of kind `std::io::ErrorKind::StorageFull`); tiles
    /// already kept may still be rewritten. A server's store, whose
    /// tiles are other players' trails.
    RefuseNew,
}

/// How the store may use the disk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StoreConfig {
    /// Most bytes of tile files to keep (0 = unlimited; default
    /// 1 GiB, `DEFAULT_DISK_BUDGET_BYTES`). Beyond it, `when_full` says what
    /// goes. `store.meta` and state blobs are not counted, and the tile just
    /// written is never deleted, so a budget smaller than one tile keeps
    /// exactly one.
    pub disk_budget_bytes: u64,
    /// What a write past the budget does.
    pub when_full: WhenFull,
}

impl Default for StoreConfig {
    fn default() -> Self {
        Self { disk_budget_bytes: DEFAULT_DISK_BUDGET_BYTES, when_full: WhenFull::EvictOldest }
    }
}

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
    index: HashMap<TileKey, Entry>,
    /// The index ordered by recency, oldest first, for eviction.
    by_age: BTreeSet<(u64, TileKey)>,
    clock: u64,
    total_bytes: u64,
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

    /// Indexes a tile as just touched.
    fn insert(&mut self, key: TileKey, bytes: u64, generation: Option<u64>) {
        self.clock += 1;
        self.index.insert(key, Entry { bytes, touched: self.clock, generation });
        self.by_age.insert((self.clock, key));
        self.total_bytes += bytes;
    }

    fn touch(&mut self, key: TileKey) {
        if let Some(entry) = self.forget(key) {
            self.insert(key, entry.bytes, entry.generation);
        }
    }

    /// Drops a tile from the index, returning its entry.
    fn forget(&mut self, key: TileKey) -> Option<Entry> {
        let entry = self.index.remove(&key)?;
        self.by_age.remove(&(entry.touched, key));
        self.total_bytes -= entry.bytes;
        Some(entry)
    }

    /// The file holding a tile's newest version: the one written for the
    /// next save, if any, else the plain one.
    fn live_path(&self, key: TileKey) -> PathBuf {
        match self.index.get(&key).and_then(|e| e.generation) {
            Some(g) => generation_path(&self.dir, key, g),
            None => tile_path(&self.dir, key),
        }
    }

    fn quarantine(&mut self, key: TileKey, path: &Path) {
        self.forget(key);
        let mut aside = path.as_os_str().to_owned();
        aside.push(CORRUPT_SUFFIX);
        if let Err(e) = self.disk.rename(path, Path::new(&aside)) {
            tracing::warn!("tile store: cannot move the corrupt tile {} aside: {e}", path.display());
        }
    }

    /// With [`WhenFull::RefuseNew`], refuses a tile not yet kept whose
    /// `len` bytes would take the store past its budget.
    fn refuse_if_full(&self, key: TileKey, len: u64, path: &Path) -> Result<(), StoreError> {
        let budget = self.config.disk_budget_bytes;
        if self.config.when_full != WhenFull::RefuseNew || budget == 0 || self.index.contains_key(&key) || self.total_bytes + len <= budget {
            return Ok(());
        }
        let why = format!("the store's disk budget of {budget} bytes is spent ({} bytes kept); new tiles are refused, kept ones stay", self.total_bytes);
        Err(StoreError::Io { path: path.to_owned(), op: "write a new tile to", source: io::Error::new(io::ErrorKind::StorageFull, why) })
    }

    /// Deletes the least recently touched tiles (never `keep`) until the
    /// total is within the budget (never, when the store refuses new tiles instead).
    fn enforce_budget(&mut self, keep: Option<TileKey>) -> Result<(), StoreError> {
        let budget = if self.config.when_full == WhenFull::RefuseNew { 0 } else { self.config.disk_budget_bytes };
        while budget > 0 && self.total_bytes > budget {
            // At most two steps: only `keep` is skipped.
            let Some(&(_, key)) = self.by_age.iter().find(|(_, k)| Some(*k) != keep) else {
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
            self.forget(key);
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
            index: HashMap::with_capacity(found.len()),
            by_age: BTreeSet::new(),
            clock: 0,
            total_bytes: 0,
            evicted: 0,
            committed: committed.unwrap_or(0),
            saving: committed.is_some(),
            _lock: lock,
        };
        for (_, key, bytes) in found {
            store.insert(key, bytes, None);
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
        if !self.index.contains_key(&key) {
            return Ok(None);
        }
        let path = self.live_path(key);
        let bytes = match self.disk.read(&path) {
            Ok(bytes) => bytes,
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                // Deleted behind the store's back: as if never written.
                self.forget(key);
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
                self.touch(key);
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
        self.refuse_if_full(tile.key, bytes.len() as u64, &path)?;
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
        self.forget(tile.key);
        self.insert(tile.key, bytes.len() as u64, generation);
        self.enforce_budget(Some(tile.key))
    }

    fn write_state(&self, name: &str, bytes: &[u8]) -> Result<(), StoreError> {
        let path = self.state_path(name)?;
        let mut framed = Vec::with_capacity(24 + bytes.len());
        framed.extend_from_slice(STATE_MAGIC);
        framed.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        framed.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        let mut crc = crc32fast::Hasher::new();
        crc.update(&framed);
        crc.update(bytes);
        framed.extend_from_slice(&crc.finalize().to_le_bytes());
        framed.extend_from_slice(bytes);
        atomic_write(&*self.disk, &path, &framed)
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
        let corrupt = |why: &str| StoreError::Corrupt { path: path.clone(), why: why.to_owned() };
        if framed.len() < 24 || &framed[..8] != STATE_MAGIC {
            return Err(corrupt("not a snowpack state file (no SNOWSTAT magic or too short)"));
        }
        let version = u32::from_le_bytes([framed[8], framed[9], framed[10], framed[11]]);
        if !readable(version) {
            return Err(StoreError::Version { path, found: version, expected: FORMAT_VERSION });
        }
        let mut len = [0; 8];
        len.copy_from_slice(&framed[12..20]);
        let stored = u32::from_le_bytes([framed[20], framed[21], framed[22], framed[23]]);
        let payload = &framed[24..];
        if u64::from_le_bytes(len) != payload.len() as u64 {
            return Err(corrupt("length mismatch (truncated?)"));
        }
        let mut crc = crc32fast::Hasher::new();
        crc.update(&framed[..20]);
        crc.update(payload);
        if crc.finalize() != stored {
            return Err(corrupt("bad CRC32"));
        }
        Ok(Some(payload.to_vec()))
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
        let written: Vec<(TileKey, u64)> = self.index.iter().filter_map(|(k, e)| e.generation.map(|g| (*k, g))).collect();
        for (key, g) in written {
            let to = tile_path(&self.dir, key);
            match self.disk.rename(&generation_path(&self.dir, key, g), &to) {
                Ok(()) => {
                    if let Some(entry) = self.index.get_mut(&key) {
                        entry.generation = None;
                    }
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
        self.total_bytes
    }

    fn evicted(&self) -> u64 {
        self.evicted
    }

    fn contains(&self, key: TileKey) -> bool {
        self.index.contains_key(&key)
    }

    fn has_room(&self) -> bool {
        let budget = self.config.disk_budget_bytes;
        self.config.when_full == WhenFull::EvictOldest || budget == 0 || self.total_bytes < budget
    }

    fn keys(&self) -> impl Iterator<Item = TileKey> + '_ {
        self.index.keys().copied()
    }

    fn tile_bytes(&self, key: TileKey) -> Option<u64> {
        self.index.get(&key).map(|e| e.bytes)
    }

    fn tile_path(&self, key: TileKey) -> PathBuf {
        tile_path(&self.dir, key)
    }
}

/// Where tile `key` of the store in `dir` lives. Arithmetic shifts keep
/// negative coordinates in their own regions (-1 >> 5 is -1).
#[doc(hidden)]
pub fn tile_path(dir: &Path, key: TileKey) -> PathBuf {
    dir.join(TILES_DIR).join(region_name(key)).join(format!("{}_{}.tile", key.col, key.row))
}

fn region_name(key: TileKey) -> String {
    format!("r{}_{}", key.col >> REGION_SHIFT, key.row >> REGION_SHIFT)
}

/// The tiles found on opening: the saved version of each key (its time and
/// length), and the files of saves in progress (generation, key, length, time).
type FoundTiles = (HashMap<TileKey, (std::time::SystemTime, u64)>, Vec<(u64, TileKey, u64, std::time::SystemTime)>);

/// Checks the tile side, makes the store's folders, takes its lock, checks
/// (or writes) its meta file and removes temporary files a crash left.
fn prepare_dir(disk: &dyn Disk, dir: &Path, side: u32) -> Result<Option<DiskLock>, StoreError> {
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
fn index_tiles(disk: &dyn Disk, tiles: &Path) -> Result<FoundTiles, StoreError> {
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
fn finish_generations(
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

/// Where tile `key`'s version written for save generation `g` lives until committed.
fn generation_path(dir: &Path, key: TileKey, g: u64) -> PathBuf {
    dir.join(TILES_DIR).join(region_name(key)).join(format!("{}_{}.g{g}.tile", key.col, key.row))
}

/// `{col}_{row}.tile` (generation `None`) or `{col}_{row}.g{N}.tile` back to its key.
fn parse_tile_name(name: &str) -> Option<(TileKey, Option<u64>)> {
    let stem = name.strip_suffix(".tile")?;
    let (stem, generation) = match stem.rsplit_once(".g") {
        Some((stem, g)) => (stem, Some(g.parse().ok()?)),
        None => (stem, None),
    };
    let (col, row) = stem.split_once('_')?;
    Some((TileKey { col: col.parse().ok()?, row: row.parse().ok()? }, generation))
}

/// `save.commit`: magic, format version, generation, state count, then each
/// state's name length, name, byte length and bytes; CRC32 of all that last.
fn encode_save(generation: u64, states: &[(&str, &[u8])]) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(SAVE_MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&generation.to_le_bytes());
    out.extend_from_slice(&(states.len() as u32).to_le_bytes());
    for (name, bytes) in states {
        out.extend_from_slice(&(name.len() as u32).to_le_bytes());
        out.extend_from_slice(name.as_bytes());
        out.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        out.extend_from_slice(bytes);
    }
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Named state blobs, as `save.commit` holds them.
type NamedStates = Vec<(String, Vec<u8>)>;

/// The generation and states of a `save.commit`, once its magic, CRC, version and lengths check out.
fn decode_save(path: &Path, bytes: &[u8]) -> Result<(u64, NamedStates), StoreError> {
    let corrupt = |why: &str| StoreError::Corrupt { path: path.to_owned(), why: why.to_owned() };
    if bytes.len() < 28 || &bytes[..8] != SAVE_MAGIC {
        return Err(corrupt("not a snowpack save record (no SNOWSAVE magic or too short)"));
    }
    let (body, crc) = bytes.split_at(bytes.len() - 4);
    if crc32fast::hash(body).to_le_bytes() != crc {
        return Err(corrupt("bad CRC32"));
    }
    let mut at = 8;
    let mut take = |n: usize| -> Result<&[u8], StoreError> {
        let field = body.get(at..at + n).ok_or_else(|| corrupt("length mismatch"))?;
        at += n;
        Ok(field)
    };
    let u32_at = |b: &[u8]| u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    let u64_at = |b: &[u8]| u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]);
    let version = u32_at(take(4)?);
    if !readable(version) {
        return Err(StoreError::Version { path: path.to_owned(), found: version, expected: FORMAT_VERSION });
    }
    let generation = u64_at(take(8)?);
    let count = u32_at(take(4)?);
    let mut states = Vec::new();
    for _ in 0..count {
        let name_len = u32_at(take(4)?) as usize;
        let name = String::from_utf8(take(name_len)?.to_vec()).map_err(|_| corrupt("a state name is not UTF-8"))?;
        let len = usize::try_from(u64_at(take(8)?)).map_err(|_| corrupt("length mismatch"))?;
        states.push((name, take(len)?.to_vec()));
    }
    if at != body.len() {
        return Err(corrupt("length mismatch (bytes after the last state)"));
    }
    Ok((generation, states))
}

fn meta_bytes(side: u32) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(20);
    bytes.extend_from_slice(META_MAGIC);
    bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    bytes.extend_from_slice(&side.to_le_bytes());
    let crc = crc32fast::hash(&bytes);
    bytes.extend_from_slice(&crc.to_le_bytes());
    bytes
}

fn check_meta(path: &Path, bytes: &[u8], side: u32) -> Result<(), StoreError> {
    let found_side = meta_side(path, bytes)?;
    if found_side != side {
        return Err(StoreError::Mismatch { path: path.to_owned(), why: format!("the store holds {found_side}² tiles, {side}² were asked for") });
    }
    Ok(())
}

/// The tile side a `store.meta` records, once its magic, CRC and version check out.
fn meta_side(path: &Path, bytes: &[u8]) -> Result<u32, StoreError> {
    let field = |at: usize| u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    if bytes.len() != 20 || &bytes[..8] != META_MAGIC {
        return Err(StoreError::Corrupt { path: path.to_owned(), why: "not a snowpack store description".to_owned() });
    }
    if crc32fast::hash(&bytes[..16]) != field(16) {
        return Err(StoreError::Corrupt { path: path.to_owned(), why: "bad CRC32".to_owned() });
    }
    let version = field(8);
    if !readable(version) {
        return Err(StoreError::Version { path: path.to_owned(), found: version, expected: FORMAT_VERSION });
    }
    Ok(field(12))
}

/// Creates `dir` and any missing parents (as `create_dir_all`), syncing
/// each new folder's parent so that the folders survive a power cut along
/// with what is later synced in them.
fn create_dirs(disk: &dyn Disk, dir: &Path) -> Result<(), StoreError> {
    let failed = io_error(dir, "create the store directory");
    match disk.create_dir(dir) {
        Ok(()) => {}
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => return Ok(()),
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            match dir.parent() {
                Some(parent) if !parent.as_os_str().is_empty() => create_dirs(disk, parent)?,
                _ => return Err(failed(e)),
            }
            match disk.create_dir(dir) {
                Ok(()) => {}
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => return Ok(()),
                Err(e) => return Err(failed(e)),
            }
        }
        Err(e) => return Err(failed(e)),
    }
    let parent = dir.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    new_entry_synced(disk, dir, parent)
}

/// Syncs `parent` after the folder `new` was created in it. On failure the
/// folder is removed again (best effort) so that the next attempt creates
/// and syncs it rather than finding it there and trusting it.
fn new_entry_synced(disk: &dyn Disk, new: &Path, parent: &Path) -> Result<(), StoreError> {
    sync_dir(disk, parent).inspect_err(|_| {
        let _ = disk.remove_dir(new);
    })
}

/// Deletes the temporary files a crash left among `entries` of `dir` (best effort).
fn remove_temp_files(disk: &dyn Disk, dir: &Path, entries: &[DirEntry]) {
    for entry in entries {
        if entry.name.to_string_lossy().ends_with(TEMP_SUFFIX) {
            let path = dir.join(&entry.name);
            match disk.remove_file(&path) {
                Ok(()) => tracing::debug!("tile store: removed the leftover {}", path.display()),
                Err(e) => tracing::warn!("tile store: cannot remove the leftover {}: {e}", path.display()),
            }
        }
    }
}

/// Maps an I/O error on `path` to [`StoreError::Io`].
fn io_error(path: &Path, op: &'static str) -> impl FnOnce(io::Error) -> StoreError {
    let path = path.to_owned();
    move |source| StoreError::Io { path, op, source }
}

/// Replaces `path` with `bytes` so that a crash leaves the old or the new
/// file, never a mix: a unique temporary file in the same directory (rename
/// is atomic only within a file system), synced, renamed over, and the
/// directory synced so the rename itself is durable before this returns.
fn atomic_write(disk: &dyn Disk, path: &Path, bytes: &[u8]) -> Result<(), StoreError> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mut temp = path.as_os_str().to_owned();
    temp.push(format!(".{}-{}{TEMP_SUFFIX}", std::process::id(), COUNTER.fetch_add(1, Ordering::Relaxed)));
    let temp = PathBuf::from(temp);
    let written = (|| {
        let mut file = disk.create(&temp).map_err(io_error(&temp, "create"))?;
        file.write_all(bytes).map_err(io_error(&temp, "write"))?;
        file.sync().map_err(io_error(&temp, "sync"))?;
        drop(file);
        disk.rename(&temp, path).map_err(io_error(path, "rename into place"))
    })();
    if written.is_err() {
        // Best effort; open() deletes leftovers anyway.
        let _ = disk.remove_file(&temp);
    }
    written?;
    match path.parent() {
        Some(dir) => sync_dir(disk, dir),
        None => Ok(()),
    }
}

/// Makes the entries of `dir` durable (a rename or a new folder in it). A
/// failure is an error: the new entry is in place but could be lost to a
/// power cut, so the write must not count as done. Platforms that cannot
/// sync directories at all answer `Ok` ([`Disk::sync_dir`]).
fn sync_dir(disk: &dyn Disk, dir: &Path) -> Result<(), StoreError> {
    disk.sync_dir(dir).map_err(io_error(dir, "sync the directory"))
}

#[cfg(test)]
mod tests {
    use std::fs;

    use super::*;
    use crate::persist::SnowClock;
    use crate::persist::test_dir::TestDir;

    const SIDE: u32 = 16;

    /// A tile whose every texel holds `v` (stamps `v`, fallen `v`).
    fn tile(col: i64, row: i64, v: f32) -> TileData {
        let n = (SIDE * SIDE) as usize;
        TileData {
            key: TileKey::new(col, row),
            side: SIDE,
            clock: SnowClock { time_s: f64::from(v), ..SnowClock::default() },
            // A little variation so sizes are realistic rather than minimal.
            snow_xor_rest: (0..n).map(|k| (v + (k % 7) as f32 * 0.001).to_bits()).collect(),
            stamps: vec![v as u32; n],
            fallen: vec![v; n],
            packed: vec![v as u16; n],
        }
    }

    fn open(dir: &Path, budget: u64) -> TileStore {
        TileStore::open(dir, SIDE, StoreConfig { disk_budget_bytes: budget, ..StoreConfig::default() }).expect("open the store")
    }

    #[test]
    fn write_read_overwrite() {
        let dir = TestDir::new("store-rw");
        let mut store = open(dir.path(), 0);
        assert_eq!(store.read(TileKey::new(0, 0)).expect("read"), None);
        let a = tile(0, 0, 1.0);
        store.write(&a).expect("write");
        assert_eq!(store.read(a.key).expect("read"), Some(a.clone()));
        let b = tile(0, 0, 2.0);
        store.write(&b).expect("overwrite");
        assert_eq!(store.read(a.key).expect("read"), Some(b));
        assert_eq!(store.disk_tiles(), 1);
        let on_disk = fs::metadata(store.tile_path(a.key)).expect("the tile file").len();
        assert_eq!(store.disk_bytes(), on_disk);
        assert_eq!(store.tile_bytes(a.key), Some(on_disk));
        // A tile of another side is refused, naming the file.
        let mut wrong = tile(1, 0, 1.0);
        wrong.side = 8;
        match store.write(&wrong) {
            Err(StoreError::Mismatch { path, .. }) => assert_eq!(path, store.tile_path(wrong.key)),
            other => panic!("expected Mismatch, got {other:?}"),
        }
        let mut short = tile(1, 0, 1.0);
        short.stamps.pop();
        assert!(matches!(store.write(&short), Err(StoreError::Mismatch { .. })));
        assert_eq!(store.disk_tiles(), 1);
    }

    /// While saving, tiles are written beside their saved versions: until the
    /// commit, reopening finds the last save (the later files deleted); after
    /// it, the new one (the files in place).
    #[test]
    fn tiles_written_after_a_save_belong_to_the_next_one() {
        let dir = TestDir::new("store-saves");
        let (a, b) = (TileKey::new(0, 0), TileKey::new(-40, 3));
        {
            let mut store = open(dir.path(), 0);
            store.begin_saves();
            store.write(&tile(0, 0, 1.0)).expect("write");
            store.commit(&[("window", b"one")]).expect("commit the first save");
            store.write(&tile(0, 0, 2.0)).expect("write for the next save");
            store.write(&tile(-40, 3, 2.0)).expect("write for the next save");
            // The newest version is what reads back meanwhile.
            assert_eq!(store.read(a).expect("read"), Some(tile(0, 0, 2.0)));
            assert_eq!(store.read_state("window").expect("state"), Some(b"one".to_vec()));
        }
        // Not committed: the store holds the first save, whole.
        {
            let mut store = open(dir.path(), 0);
            assert_eq!(store.read(a).expect("read"), Some(tile(0, 0, 1.0)));
            assert_eq!(store.read(b).expect("read"), None);
            assert_eq!(store.disk_tiles(), 1);
            assert_eq!(store.read_state("window").expect("state"), Some(b"one".to_vec()));
            // Opened holding a save, it saves on: this write belongs to the next one.
            store.write(&tile(-40, 3, 3.0)).expect("write");
            store.commit(&[("window", b"two")]).expect("commit the second save");
            assert!(!store.live_path(b).to_string_lossy().contains(".g"), "committed files are in place");
        }
        let mut store = open(dir.path(), 0);
        assert_eq!(store.read(a).expect("read"), Some(tile(0, 0, 1.0)));
        assert_eq!(store.read(b).expect("read"), Some(tile(-40, 3, 3.0)));
        assert_eq!(store.read_state("window").expect("state"), Some(b"two".to_vec()));
        let leftovers: Vec<_> = walk(dir.path()).into_iter().filter(|p| p.to_string_lossy().contains(".g")).collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
        // A damaged save record is an error naming it.
        fs::write(dir.path().join(SAVE_FILE), b"SNOWSAVE and then nonsense").expect("damage");
        drop(store);
        assert!(
            matches!(TileStore::open(dir.path(), SIDE, StoreConfig::default()).map_err(StoreError::from), Err(StoreError::Corrupt { path, .. }) if path.ends_with(SAVE_FILE))
        );
    }

    /// Every file under `dir`.
    fn walk(dir: &Path) -> Vec<PathBuf> {
        let mut out = Vec::new();
        for entry in fs::read_dir(dir).into_iter().flatten().flatten() {
            let path = entry.path();
            if path.is_dir() {
                out.extend(walk(&path));
            } else {
                out.push(path);
            }
        }
        out
    }

    #[test]
    fn negative_keys_have_their_own_regions() {
        let dir = TestDir::new("store-negative");
        let mut store = open(dir.path(), 0);
        let keys = [(-1, -1), (-32, 0), (-33, 5), (31, -32), (32, 31), (0, 0), (i64::MIN, i64::MAX)];
        for (k, &(col, row)) in keys.iter().enumerate() {
            store.write(&tile(col, row, k as f32)).expect("write");
        }
        assert_eq!(store.tile_path(TileKey::new(-1, -1)), dir.path().join("tiles/r-1_-1/-1_-1.tile"));
        assert_eq!(store.tile_path(TileKey::new(-33, 5)), dir.path().join("tiles/r-2_0/-33_5.tile"));
        assert_eq!(store.tile_path(TileKey::new(32, 31)), dir.path().join("tiles/r1_0/32_31.tile"));
        for (k, &(col, row)) in keys.iter().enumerate() {
            let back = store.read(TileKey::new(col, row)).expect("read").expect("written");
            assert_eq!(back, tile(col, row, k as f32));
        }
        drop(store);
        let mut store = open(dir.path(), 0);
        assert_eq!(store.disk_tiles(), keys.len());
        assert!(store.read(TileKey::new(-33, 5)).expect("read").is_some());
    }

    /// A server's store: filled to its budget, it refuses new tiles and
    /// keeps every old one (across a reopen too); a kept tile still updates.
    #[test]
    fn a_store_that_refuses_new_tiles_keeps_the_old_ones() {
        let dir = TestDir::new("store-refuse");
        let size = encode(&tile(0, 0, 1.0)).len() as u64;
        let config = StoreConfig { disk_budget_bytes: 3 * size + size / 2, when_full: WhenFull::RefuseNew };
        let mut store = TileStore::open(dir.path(), SIDE, config).expect("open");
        for col in 0..3 {
            store.write(&tile(col, 0, 1.0)).expect("write");
        }
        assert!(store.has_room(), "half a tile of the budget is left");
        let refused = store.write(&tile(3, 0, 1.0)).expect_err("past the budget");
        assert!(matches!(&refused, StoreError::Io { source, .. } if source.kind() == io::ErrorKind::StorageFull), "{refused}");
        assert!(refused.to_string().contains("disk budget"), "{refused}");
        assert!(!store.contains(TileKey::new(3, 0)) && !store.tile_path(TileKey::new(3, 0)).exists());
        store.write(&tile(1, 0, 2.0)).expect("a kept tile is rewritten");
        assert_eq!(store.evicted(), 0);
        drop(store);
        let mut store = TileStore::open(dir.path(), SIDE, StoreConfig { disk_budget_bytes: size, when_full: WhenFull::RefuseNew }).expect("reopen");
        assert_eq!(store.disk_tiles(), 3, "a smaller budget on reopening deletes nothing");
        for col in 0..3 {
            let back = store.read(TileKey::new(col, 0)).expect("read").expect("kept");
            assert_eq!(back, tile(col, 0, if col == 1 { 2.0 } else { 1.0 }));
        }
        assert!(!store.has_room());
    }

    #[test]
    fn the_budget_evicts_the_least_recently_touched() {
        let dir = TestDir::new("store-budget");
        let size = encode(&tile(0, 0, 1.0)).len() as u64;
        // Room for three tiles (all tiles here encode to the same size).
        let mut store = open(dir.path(), 3 * size + size / 2);
        for col in 0..3 {
            store.write(&tile(col, 0, 1.0)).expect("write");
        }
        assert_eq!((store.disk_tiles(), store.evicted()), (3, 0));
        // Reading tile 0 touches it, so tile 1 is now the oldest.
        assert!(store.read(TileKey::new(0, 0)).expect("read").is_some());
        store.write(&tile(3, 0, 1.0)).expect("write");
        assert_eq!(store.evicted(), 1);
        assert!(!store.contains(TileKey::new(1, 0)), "tile 1 was the least recently touched");
        assert!(!store.tile_path(TileKey::new(1, 0)).exists());
        assert_eq!(store.read(TileKey::new(1, 0)).expect("read"), None);
        for col in [0, 2, 3] {
            assert!(store.contains(TileKey::new(col, 0)), "tile {col}");
        }
        // Overwriting tile 2 touches it: tile 0 goes next.
        store.write(&tile(2, 0, 2.0)).expect("write");
        store.write(&tile(4, 0, 1.0)).expect("write");
        assert!(!store.contains(TileKey::new(0, 0)));
        assert!(store.disk_bytes() <= 3 * size + size / 2);
        assert_eq!(store.disk_tiles(), 3);

        // A budget smaller than one tile keeps the one just written.
        drop(store);
        let mut tiny = open(dir.path(), 1);
        assert_eq!(tiny.disk_tiles(), 0, "open evicts down to the new budget");
        tiny.write(&tile(9, 9, 1.0)).expect("write");
        tiny.write(&tile(8, 9, 1.0)).expect("write");
        assert_eq!(tiny.disk_tiles(), 1);
        assert!(tiny.contains(TileKey::new(8, 9)));
    }

    #[test]
    fn reopening_keeps_the_index_and_removes_temp_files() {
        let dir = TestDir::new("store-reopen");
        let mut store = open(dir.path(), 0);
        for col in 0..5 {
            store.write(&tile(col, -col, col as f32)).expect("write");
        }
        store.write_state("window", b"origin").expect("state");
        let (tiles, bytes) = (store.disk_tiles(), store.disk_bytes());
        drop(store);
        // What a crash between create and rename leaves behind.
        let region = dir.path().join("tiles/r0_-1");
        let leftover = region.join("-3_3.tile.1234-0.tmp");
        fs::write(&leftover, b"half a tile").expect("leftover");
        let state_leftover = dir.path().join("window.state.1234-1.tmp");
        fs::write(&state_leftover, b"half").expect("leftover");
        let unrelated = region.join("notes.txt");
        fs::write(&unrelated, b"mine").expect("unrelated file");

        let mut store = open(dir.path(), 0);
        assert_eq!((store.disk_tiles(), store.disk_bytes()), (tiles, bytes));
        assert!(!leftover.exists() && !state_leftover.exists(), "temp files are removed on open");
        assert!(unrelated.exists(), "files the store did not write are left alone");
        for col in 0..5 {
            assert_eq!(store.read(TileKey::new(col, -col)).expect("read"), Some(tile(col, -col, col as f32)));
        }
        assert_eq!(store.read_state("window").expect("state"), Some(b"origin".to_vec()));
    }

    #[test]
    fn a_corrupt_tile_is_quarantined() {
        let dir = TestDir::new("store-corrupt");
        let mut store = open(dir.path(), 0);
        let key = TileKey::new(-2, 3);
        store.write(&tile(key.col, key.row, 1.0)).expect("write");
        let path = store.tile_path(key);
        let mut bytes = fs::read(&path).expect("tile file");
        let at = bytes.len() / 2;
        bytes[at] ^= 0x40;
        fs::write(&path, &bytes).expect("flip a byte");
        match store.read(key) {
            Err(StoreError::Corrupt { path: p, why }) => {
                assert_eq!(p, path);
                assert!(why.contains("CRC"), "{why}");
            }
            other => panic!("expected Corrupt, got {other:?}"),
        }
        assert!(!path.exists());
        assert!(dir.path().join("tiles/r-1_0/-2_3.tile.corrupt").exists());
        assert_eq!(store.read(key).expect("second read"), None);
        assert_eq!(store.disk_tiles(), 0);
        // Fresh snow can be written there again.
        store.write(&tile(key.col, key.row, 5.0)).expect("write");
        assert_eq!(store.read(key).expect("read"), Some(tile(key.col, key.row, 5.0)));
        // A tile file under another key's name is a mismatch, also set aside.
        let other = TileKey::new(-2, 4);
        fs::copy(&path, store.tile_path(other)).expect("copy");
        drop(store);
        let mut store = open(dir.path(), 0);
        assert!(matches!(store.read(other), Err(StoreError::Mismatch { .. })));
        assert_eq!(store.read(other).expect("second read"), None);
    }

    #[test]
    fn store_meta_must_match() {
        let dir = TestDir::new("store-meta");
        assert_eq!(TileStore::side_in(dir.path()).expect("no store yet"), None);
        drop(open(dir.path(), 0));
        assert_eq!(TileStore::side_in(dir.path()).expect("a store"), Some(SIDE));
        let meta = dir.path().join(META_FILE);
        match TileStore::open(dir.path(), 32, StoreConfig::default()).map_err(StoreError::from) {
            Err(e @ StoreError::Mismatch { .. }) => {
                assert_eq!(e.path(), Some(meta.as_path()));
                assert!(e.to_string().contains("store.meta"), "{e}");
            }
            other => panic!("expected Mismatch, got {other:?}"),
        }
        let mut bytes = fs::read(&meta).expect("meta");
        bytes[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
        let crc = crc32fast::hash(&bytes[..16]);
        bytes[16..20].copy_from_slice(&crc.to_le_bytes());
        fs::write(&meta, &bytes).expect("write meta");
        match TileStore::open(dir.path(), SIDE, StoreConfig::default()).map_err(StoreError::from) {
            Err(StoreError::Version { path, found, expected }) => {
                assert_eq!((path, found, expected), (meta.clone(), FORMAT_VERSION + 1, FORMAT_VERSION));
            }
            other => panic!("expected Version, got {other:?}"),
        }
        fs::write(&meta, b"garbage").expect("write meta");
        assert!(matches!(TileStore::side_in(dir.path()), Err(StoreError::Corrupt { .. })));
        assert!(matches!(TileStore::open(dir.path(), SIDE, StoreConfig::default()).map_err(StoreError::from), Err(StoreError::Corrupt { .. })));
        assert!(matches!(TileStore::open(dir.path(), 0, StoreConfig::default()).map_err(StoreError::from), Err(StoreError::Mismatch { .. })));
    }

    #[test]
    fn one_store_per_directory() {
        let dir = TestDir::new("store-lock");
        let store = open(dir.path(), 0);
        match TileStore::open(dir.path(), SIDE, StoreConfig::default()).map_err(StoreError::from) {
            // Where the file system has locks, the second open is refused.
            Err(StoreError::Io { source, .. }) => {
                assert_eq!(source.kind(), io::ErrorKind::WouldBlock)
            }
            Ok(_) => assert!(store._lock.is_none(), "locked, yet a second store opened"),
            Err(e) => panic!("unexpected {e}"),
        }
        drop(store);
        drop(open(dir.path(), 0));
    }

    #[test]
    fn state_round_trip_and_damage() {
        let dir = TestDir::new("store-state");
        let store = open(dir.path(), 0);
        assert_eq!(store.read_state("window").expect("read"), None);
        store.write_state("window", &[1, 2, 3]).expect("write");
        store.write_state("empty", &[]).expect("write");
        assert_eq!(store.read_state("window").expect("read"), Some(vec![1, 2, 3]));
        assert_eq!(store.read_state("empty").expect("read"), Some(Vec::new()));
        store.write_state("window", &[4; 1000]).expect("overwrite");
        assert_eq!(store.read_state("window").expect("read"), Some(vec![4; 1000]));
        for bad in ["", "../x", "a/b", "a.b", "x".repeat(65).as_str()] {
            assert!(matches!(store.write_state(bad, b"x"), Err(StoreError::Mismatch { .. })), "{bad:?}");
        }
        let path = dir.path().join("window.state");
        let mut bytes = fs::read(&path).expect("state file");
        bytes[500] ^= 1;
        fs::write(&path, &bytes).expect("damage");
        match store.read_state("window") {
            Err(StoreError::Corrupt { path: p, .. }) => assert_eq!(p, path),
            other => panic!("expected Corrupt, got {other:?}"),
        }
    }

    #[test]
    fn a_vanished_directory_is_an_error() {
        let dir = TestDir::new("store-vanished");
        let mut store = open(dir.path(), 0);
        store.write(&tile(0, 0, 1.0)).expect("write");
        fs::remove_dir_all(dir.path()).expect("remove the store");
        assert!(matches!(store.write(&tile(1, 0, 1.0)), Err(StoreError::Io { .. })));
        assert!(matches!(store.write(&tile(0, 0, 2.0)), Err(StoreError::Io { .. })));
        // Gone from disk: as if never written.
        assert_eq!(store.read(TileKey::new(0, 0)).expect("read"), None);
        assert!(matches!(store.write_state("s", b"x"), Err(StoreError::Io { .. })));
        assert!(!dir.path().exists(), "the store is not recreated behind the caller's back");
    }
}
