//! The file-system operations the tile store uses, behind a trait so tests
//! can put a fault-injecting disk under it (`testing::PowerLossDisk` cuts
//! the power after any operation). [`OsDisk`], the default, is `std::fs`.
//!
//! Not a stable API: it exists for fault-injection tests.

use std::ffi::OsString;
use std::fmt::Debug;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::Path;
use std::time::{Duration, Instant, SystemTime};

/// How long [`OsDisk::lock`] waits for a busy lock.
const LOCK_PATIENCE: Duration = Duration::from_millis(500);

/// Held while a store has its directory open; dropping it releases the lock.
pub type DiskLock = Box<dyn Debug + Send + Sync>;

/// A file being written: created (or truncated) by [`Disk::create`].
pub trait DiskFile {
    /// Appends all of `bytes`.
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// Makes the contents durable (`fsync`); not the file's directory entry.
    fn sync(&mut self) -> io::Result<()>;
}

/// One entry of [`Disk::list`].
#[derive(Clone, Debug)]
pub struct DirEntry {
    /// The entry's name.
    pub name: OsString,
    /// Whether it is a directory (following symbolic links).
    pub is_dir: bool,
    /// Size and modification time, when it is a regular file (not a link).
    pub file: Option<(u64, SystemTime)>,
}

/// The file-system operations of [`crate::persist::TileStore`]. Paths are
/// the store's own (its directory joined with file names).
pub trait Disk: Debug + Send + Sync {
    /// Creates a directory; `AlreadyExists` if there is one, `NotFound` if
    /// its parent is missing.
    fn create_dir(&self, path: &Path) -> io::Result<()>;
    /// Reads a whole file.
    fn read(&self, path: &Path) -> io::Result<Vec<u8>>;
    /// Creates a file for writing, truncating any there.
    fn create(&self, path: &Path) -> io::Result<Box<dyn DiskFile>>;
    /// Renames a file, replacing any at `to`.
    fn rename(&self, from: &Path, to: &Path) -> io::Result<()>;
    /// Deletes a file.
    fn remove_file(&self, path: &Path) -> io::Result<()>;
    /// Deletes an empty directory.
    fn remove_dir(&self, path: &Path) -> io::Result<()>;
    /// Makes the entries of a directory durable (`fsync` on the directory).
    /// `Ok` where the platform cannot sync directories at all.
    fn sync_dir(&self, path: &Path) -> io::Result<()>;
    /// The entries of a directory. An entry that cannot be examined is left
    /// out (and logged).
    fn list(&self, dir: &Path) -> io::Result<Vec<DirEntry>>;
    /// Takes the advisory lock on `path` (creating the file): `Ok(None)`
    /// where locks are unavailable, a `WouldBlock` error while another
    /// holder keeps it.
    fn lock(&self, path: &Path) -> io::Result<Option<DiskLock>>;
}

/// The operating system's file system, through `std::fs`.
#[derive(Clone, Copy, Debug, Default)]
pub struct OsDisk;

impl DiskFile for File {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        Write::write_all(self, bytes)
    }

    fn sync(&mut self) -> io::Result<()> {
        self.sync_all()
    }
}

impl Disk for OsDisk {
    fn create_dir(&self, path: &Path) -> io::Result<()> {
        fs::create_dir(path)
    }

    fn read(&self, path: &Path) -> io::Result<Vec<u8>> {
        fs::read(path)
    }

    fn create(&self, path: &Path) -> io::Result<Box<dyn DiskFile>> {
        Ok(Box::new(OpenOptions::new().write(true).create(true).truncate(true).open(path)?))
    }

    fn rename(&self, from: &Path, to: &Path) -> io::Result<()> {
        fs::rename(from, to)
    }

    fn remove_file(&self, path: &Path) -> io::Result<()> {
        fs::remove_file(path)
    }

    fn remove_dir(&self, path: &Path) -> io::Result<()> {
        fs::remove_dir(path)
    }

    fn sync_dir(&self, path: &Path) -> io::Result<()> {
        #[cfg(unix)]
        match File::open(path).and_then(|d| d.sync_all()) {
            // EINVAL: this file system cannot sync directories (some network
            // and FUSE ones); nothing more can be done, as on other platforms.
            Err(e) if matches!(e.kind(), io::ErrorKind::InvalidInput | io::ErrorKind::Unsupported) => {
                tracing::debug!("tile store: cannot sync the directory {}: {e}", path.display());
                Ok(())
            }
            other => other,
        }
        #[cfg(not(unix))]
        {
            let _ = path;
            Ok(())
        }
    }

    fn list(&self, dir: &Path) -> io::Result<Vec<DirEntry>> {
        let mut out = Vec::new();
        for entry in fs::read_dir(dir)?.flatten() {
            let path = entry.path();
            let file = match entry.metadata() {
                Ok(meta) if meta.is_file() => Some((meta.len(), meta.modified().unwrap_or(SystemTime::UNIX_EPOCH))),
                Ok(_) => None,
                Err(e) => {
                    tracing::warn!("tile store: cannot stat {}: {e}", path.display());
                    continue;
                }
            };
            out.push(DirEntry { name: entry.file_name(), is_dir: path.is_dir(), file });
        }
        Ok(out)
    }

    fn lock(&self, path: &Path) -> io::Result<Option<DiskLock>> {
        let file = match OpenOptions::new().create(true).truncate(false).write(true).open(path) {
            Ok(file) => file,
            Err(e) => {
                tracing::debug!("tile store: no lock file {}: {e}", path.display());
                return Ok(None);
            }
        };
        // A lock can outlive its holder for a moment: a process spawned while it
        // was held keeps the locked file open until it execs. So a busy lock is
        // retried briefly before it counts as another store.
        let deadline = Instant::now() + LOCK_PATIENCE;
        loop {
            match file.try_lock() {
                Ok(()) => return Ok(Some(Box::new(file))),
                Err(fs::TryLockError::WouldBlock) if Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(5));
                }
                Err(fs::TryLockError::WouldBlock) => return Err(io::ErrorKind::WouldBlock.into()),
                Err(fs::TryLockError::Error(e)) => {
                    tracing::debug!("tile store: cannot lock {}: {e}", path.display());
                    return Ok(None);
                }
            }
        }
    }
}
