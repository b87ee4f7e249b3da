//! Writing the store's files so a crash or a power cut leaves each whole:
//! atomic replacement, synced folders, and the leftovers a crash leaves.

use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use super::layout::TEMP_SUFFIX;
use crate::persist::StoreError;
use crate::persist::disk::{DirEntry, Disk};

/// Creates `dir` and any missing parents (as `create_dir_all`), syncing
/// each new folder's parent so that the folders survive a power cut along
/// with what is later synced in them.
pub(super) fn create_dirs(disk: &dyn Disk, dir: &Path) -> Result<(), StoreError> {
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
pub(super) fn new_entry_synced(disk: &dyn Disk, new: &Path, parent: &Path) -> Result<(), StoreError> {
    sync_dir(disk, parent).inspect_err(|_| {
        let _ = disk.remove_dir(new);
    })
}

/// Deletes the temporary files a crash left among `entries` of `dir` (best effort).
pub(super) fn remove_temp_files(disk: &dyn Disk, dir: &Path, entries: &[DirEntry]) {
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
pub(super) fn io_error(path: &Path, op: &'static str) -> impl FnOnce(io::Error) -> StoreError {
    let path = path.to_owned();
    move |source| StoreError::Io { path, op, source }
}

/// Replaces `path` with `bytes` so that a crash leaves the old or the new
/// file, never a mix: a unique temporary file in the same directory (rename
/// is atomic only within a file system), synced, renamed over, and the
/// directory synced so the rename itself is durable before this returns.
pub(super) fn atomic_write(disk: &dyn Disk, path: &Path, bytes: &[u8]) -> Result<(), StoreError> {
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
pub(super) fn sync_dir(disk: &dyn Disk, dir: &Path) -> Result<(), StoreError> {
    disk.sync_dir(dir).map_err(io_error(dir, "sync the directory"))
}
