//! A disk that hangs or fails on demand: while held, every operation blocks
//! until it is released, as a network share or a dying drive that stops
//! answering; while failing, every operation fails with an I/O error. For
//! the tests that every blocking call of the tile store gives up, and that
//! no trail is lost to a late or failing disk.

use std::path::Path;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};
use std::{fmt, io};

use snowpack::low_level::persist::disk::{DirEntry, Disk, DiskFile, DiskLock, OsDisk};

#[derive(Debug, Default)]
struct Hold {
    /// Operations block while this is set.
    held: bool,
    /// Operations blocked now.
    blocked: usize,
    /// Operations fail while this is set.
    failing: bool,
}

#[derive(Debug, Default)]
struct Shared {
    hold: Mutex<Hold>,
    changed: Condvar,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Hold> {
        self.hold.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Blocks while the disk is held; an error while it fails.
    fn pass(&self) -> io::Result<()> {
        let mut hold = self.lock();
        if hold.failing {
            return Err(io::Error::other("the disk fails (as the test asked)"));
        }
        if !hold.held {
            return Ok(());
        }
        hold.blocked += 1;
        self.changed.notify_all();
        while hold.held {
            hold = self.changed.wait(hold).unwrap_or_else(PoisonError::into_inner);
        }
        hold.blocked -= 1;
        self.changed.notify_all();
        Ok(())
    }
}

/// A [`Disk`] over another (the operating system's by default) whose
/// operations block while it is held ([`HeldDisk::hold`]) until it is
/// released ([`HeldDisk::release`]), and fail while it fails
/// ([`HeldDisk::fail`]); writes to an open file too.
/// Clones share one hold.
#[derive(Clone)]
pub struct HeldDisk {
    inner: Arc<dyn Disk>,
    shared: Arc<Shared>,
}

impl fmt::Debug for HeldDisk {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("HeldDisk").field("inner", &self.inner).field("hold", &*self.shared.lock()).finish()
    }
}

impl Default for HeldDisk {
    fn default() -> Self {
        Self::new(Arc::new(OsDisk))
    }
}

impl HeldDisk {
    /// A disk passing operations to `inner`, not held.
    #[must_use]
    pub fn new(inner: Arc<dyn Disk>) -> Self {
        Self { inner, shared: Arc::new(Shared::default()) }
    }

    /// From now on every operation blocks until [`Self::release`].
    pub fn hold(&self) {
        self.shared.lock().held = true;
        self.shared.changed.notify_all();
    }

    /// Lets the blocked operations, and those to come, go on.
    pub fn release(&self) {
        self.shared.lock().held = false;
        self.shared.changed.notify_all();
    }

    /// From now on (`true`) every operation fails with an I/O error, until
    /// called with `false`.
    pub fn fail(&self, failing: bool) {
        self.shared.lock().failing = failing;
    }

    /// Operations blocked now.
    #[must_use]
    pub fn blocked(&self) -> usize {
        self.shared.lock().blocked
    }

    /// Waits until at least one operation is blocked, for at most `limit`;
    /// whether one is.
    pub fn wait_until_blocked(&self, limit: Duration) -> bool {
        let start = Instant::now();
        let mut hold = self.shared.lock();
        while hold.blocked == 0 {
            let left = limit.saturating_sub(start.elapsed());
            if left.is_zero() {
                return false;
            }
            hold = self.shared.changed.wait_timeout(hold, left).unwrap_or_else(PoisonError::into_inner).0;
        }
        true
    }
}

/// A file being written on a [`HeldDisk`].
struct HeldFile {
    inner: Box<dyn DiskFile>,
    shared: Arc<Shared>,
}

impl DiskFile for HeldFile {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.shared.pass()?;
        self.inner.write_all(bytes)
    }

    fn sync(&mut self) -> io::Result<()> {
        self.shared.pass()?;
        self.inner.sync()
    }
}

impl Disk for HeldDisk {
    fn create_dir(&self, path: &Path) -> io::Result<()> {
        self.shared.pass()?;
        self.inner.create_dir(path)
    }

    fn read(&self, path: &Path) -> io::Result<Vec<u8>> {
        self.shared.pass()?;
        self.inner.read(path)
    }

    fn create(&self, path: &Path) -> io::Result<Box<dyn DiskFile>> {
        self.shared.pass()?;
        let inner = self.inner.create(path)?;
        Ok(Box::new(HeldFile { inner, shared: Arc::clone(&self.shared) }))
    }

    fn rename(&self, from: &Path, to: &Path) -> io::Result<()> {
        self.shared.pass()?;
        self.inner.rename(from, to)
    }

    fn remove_file(&self, path: &Path) -> io::Result<()> {
        self.shared.pass()?;
        self.inner.remove_file(path)
    }

    fn remove_dir(&self, path: &Path) -> io::Result<()> {
        self.shared.pass()?;
        self.inner.remove_dir(path)
    }

    fn sync_dir(&self, path: &Path) -> io::Result<()> {
        self.shared.pass()?;
        self.inner.sync_dir(path)
    }

    fn list(&self, dir: &Path) -> io::Result<Vec<DirEntry>> {
        self.shared.pass()?;
        self.inner.list(dir)
    }

    fn lock(&self, path: &Path) -> io::Result<Option<DiskLock>> {
        self.shared.pass()?;
        self.inner.lock(path)
    }
}
