//! A file system in memory that can lose power: what was not synced is lost
//! (or, as a real disk may, partly kept), for crash tests of the tile store.
//!
//! The model is strict POSIX: `fsync` on a file makes its contents durable,
//! not its name; a new, renamed or removed directory entry is durable only
//! once its directory has been synced. Nothing else is promised, so at a
//! power cut each unsynced change may survive or not ([`Unsynced`]); a
//! rename within one directory is one change (both names or neither), as
//! journaling file systems make it.

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::io;
use std::path::{Component, Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, SystemTime};

use super::Rng;
use snowpack::low_level::persist::disk::{DirEntry, Disk, DiskFile, DiskLock};

/// Index of a node (file or directory) in the image.
type Ino = usize;

/// Directory changes made together: (name, new target or removed).
type Change = Vec<(OsString, Option<Ino>)>;

#[derive(Clone, Debug)]
enum Node {
    File {
        /// What a read sees now.
        data: Vec<u8>,
        /// The contents at the last sync (empty for a file never synced).
        synced: Vec<u8>,
        /// Modification time on the disk's own clock.
        modified: u64,
    },
    Dir {
        /// What a lookup sees now.
        entries: BTreeMap<OsString, Ino>,
        /// The entries at the last sync.
        durable: BTreeMap<OsString, Ino>,
        /// Changes since the last sync, oldest first.
        pending: Vec<Change>,
    },
}

impl Node {
    fn dir() -> Self {
        Self::Dir { entries: BTreeMap::new(), durable: BTreeMap::new(), pending: Vec::new() }
    }
}

#[derive(Clone, Debug)]
struct Image {
    /// Node 0 is the root directory (always there).
    nodes: Vec<Node>,
    /// Operations done so far.
    ops: u64,
    /// The power goes off once `ops` reaches this.
    cut_at: Option<u64>,
    clock: u64,
}

/// Which of the changes not yet synced survive [`PowerLossDisk::crash`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unsynced {
    /// None: only synced contents and synced directory entries remain.
    Lost,
    /// All of them, as if the system wrote everything back just before the cut.
    Kept,
    /// Each directory change independently survives or not, and each file's
    /// unsynced contents are lost, kept, or kept in part (a torn write), by
    /// a generator seeded with this.
    Random(u64),
}

/// A disk in memory for [`snowpack_share::persist::TileStoreExt::open_on`] that can be
/// told to lose power after a number of operations; from then on every
/// operation fails, and [`PowerLossDisk::crash`] gives the disk as it is
/// when the power comes back. Clones share one disk.
#[derive(Clone, Debug)]
pub struct PowerLossDisk(Arc<Mutex<Image>>);

impl Default for PowerLossDisk {
    fn default() -> Self {
        Self::new()
    }
}

fn power_off() -> io::Error {
    io::Error::other("the power is off (PowerLossDisk)")
}

fn not_found(path: &Path) -> io::Error {
    io::Error::new(io::ErrorKind::NotFound, format!("{} not found (PowerLossDisk)", path.display()))
}

/// An error of `kind` about `path`, saying which layer refused it.
fn fault(kind: io::ErrorKind, path: &Path) -> io::Error {
    io::Error::new(kind, format!("{} (PowerLossDisk)", path.display()))
}

/// The names along `path` (the root for an empty or absolute one).
fn names(path: &Path) -> io::Result<Vec<OsString>> {
    let mut out = Vec::new();
    for component in path.components() {
        match component {
            Component::Normal(name) => out.push(name.to_owned()),
            Component::ParentDir => return Err(io::Error::new(io::ErrorKind::InvalidInput, "`..` is not supported (PowerLossDisk)")),
            Component::RootDir | Component::CurDir | Component::Prefix(_) => {}
        }
    }
    Ok(out)
}

impl Image {
    /// Counts an operation, or fails it once the power is off.
    fn op(&mut self) -> io::Result<()> {
        if self.cut_at.is_some_and(|cut| self.ops >= cut) {
            return Err(power_off());
        }
        self.ops += 1;
        self.clock += 1;
        Ok(())
    }

    fn entries(&self, ino: Ino) -> Option<&BTreeMap<OsString, Ino>> {
        match &self.nodes[ino] {
            Node::Dir { entries, .. } => Some(entries),
            Node::File { .. } => None,
        }
    }

    fn lookup(&self, path: &Path) -> io::Result<Ino> {
        let mut ino = 0;
        for name in names(path)? {
            let entries = self.entries(ino).ok_or_else(|| fault(io::ErrorKind::NotADirectory, path))?;
            ino = *entries.get(&name).ok_or_else(|| not_found(path))?;
        }
        Ok(ino)
    }

    /// The directory holding `path`'s last name, and that name.
    fn parent(&self, path: &Path) -> io::Result<(Ino, OsString)> {
        let mut names = names(path)?;
        let name = names.pop().ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "the root has no parent (PowerLossDisk)"))?;
        let dir: PathBuf = names.iter().collect();
        let ino = self.lookup(&Path::new("/").join(dir)).map_err(|_| not_found(path))?;
        match self.nodes[ino] {
            Node::Dir { .. } => Ok((ino, name)),
            Node::File { .. } => Err(fault(io::ErrorKind::NotADirectory, path)),
        }
    }

    fn is_dir(&self, ino: Ino) -> bool {
        matches!(self.nodes[ino], Node::Dir { .. })
    }

    /// Applies `change` to directory `dir` now; durable once `dir` is synced.
    fn change(&mut self, dir: Ino, change: Change) {
        if let Node::Dir { entries, pending, .. } = &mut self.nodes[dir] {
            apply(entries, &change);
            pending.push(change);
        }
    }

    fn add(&mut self, node: Node) -> Ino {
        self.nodes.push(node);
        self.nodes.len() - 1
    }
}

fn apply(entries: &mut BTreeMap<OsString, Ino>, change: &Change) {
    for (name, target) in change {
        match target {
            Some(ino) => entries.insert(name.clone(), *ino),
            None => entries.remove(name),
        };
    }
}

impl PowerLossDisk {
    /// An empty disk (only the root directory) with the power on.
    #[must_use]
    pub fn new() -> Self {
        Self(Arc::new(Mutex::new(Image { nodes: vec![Node::dir()], ops: 0, cut_at: None, clock: 0 })))
    }

    fn image(&self) -> MutexGuard<'_, Image> {
        // A panic while holding the lock leaves the image consistent (every
        // operation checks before it changes anything).
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Operations done so far (every call of [`Disk`] and [`DiskFile`]).
    #[must_use]
    pub fn ops(&self) -> u64 {
        self.image().ops
    }

    /// Lets `ops` more operations succeed, then cuts the power: every
    /// operation after them fails with an I/O error.
    pub fn cut_power_after(&self, ops: u64) {
        let mut image = self.image();
        image.cut_at = Some(image.ops + ops);
    }

    /// Whether the power is off.
    #[must_use]
    pub fn power_is_off(&self) -> bool {
        let image = self.image();
        image.cut_at.is_some_and(|cut| image.ops >= cut)
    }

    /// An independent copy of the disk as it is now (power on, nothing lost).
    #[must_use]
    pub fn fork(&self) -> Self {
        let mut image = self.image().clone();
        image.cut_at = None;
        Self(Arc::new(Mutex::new(image)))
    }

    /// The disk after a power cut now: an independent disk, power on,
    /// holding what was synced plus the unsynced changes `unsynced` keeps.
    #[must_use]
    pub fn crash(&self, unsynced: Unsynced) -> Self {
        let mut image = self.image().clone();
        let mut rng = Rng::new(match unsynced {
            Unsynced::Random(seed) => seed,
            _ => 0,
        });
        let mut keep = |choices: u64| match unsynced {
            Unsynced::Lost => 0,
            Unsynced::Kept => 1,
            Unsynced::Random(_) => rng.next_u64() % choices,
        };
        for node in &mut image.nodes {
            match node {
                Node::File { data, synced, .. } => {
                    if data != synced {
                        match keep(3) {
                            0 => data.clone_from(synced),
                            1 => {}
                            _ => {
                                let torn = rng_len(data.len(), &mut keep);
                                data.truncate(torn);
                            }
                        }
                    }
                    synced.clone_from(data);
                }
                Node::Dir { entries, durable, pending } => {
                    for change in pending.drain(..) {
                        if keep(2) == 1 {
                            apply(durable, &change);
                        }
                    }
                    entries.clone_from(durable);
                }
            }
        }
        image.ops = 0;
        image.cut_at = None;
        Self(Arc::new(Mutex::new(image)))
    }

    /// Every file on the disk now (not directories), sorted.
    #[must_use]
    pub fn files(&self) -> Vec<PathBuf> {
        let image = self.image();
        let mut out = Vec::new();
        let mut stack = vec![(0, PathBuf::from("/"))];
        while let Some((ino, path)) = stack.pop() {
            match &image.nodes[ino] {
                Node::Dir { entries, .. } => stack.extend(entries.iter().map(|(name, &child)| (child, path.join(name)))),
                Node::File { .. } => out.push(path),
            }
        }
        out.sort();
        out
    }
}

/// A length in `0..len` for a torn write, from `pick`.
fn rng_len(len: usize, pick: &mut impl FnMut(u64) -> u64) -> usize {
    if len == 0 { 0 } else { pick(len as u64) as usize }
}

/// A file of a [`PowerLossDisk`] open for writing.
struct PowerLossFile {
    disk: PowerLossDisk,
    ino: Ino,
}

impl DiskFile for PowerLossFile {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        let mut image = self.disk.image();
        image.op()?;
        let now = image.clock;
        if let Node::File { data, modified, .. } = &mut image.nodes[self.ino] {
            data.extend_from_slice(bytes);
            *modified = now;
        }
        Ok(())
    }

    fn sync(&mut self) -> io::Result<()> {
        let mut image = self.disk.image();
        image.op()?;
        if let Node::File { data, synced, .. } = &mut image.nodes[self.ino] {
            synced.clone_from(data);
        }
        Ok(())
    }
}

impl Disk for PowerLossDisk {
    fn create_dir(&self, path: &Path) -> io::Result<()> {
        let mut image = self.image();
        image.op()?;
        let (dir, name) = image.parent(path)?;
        if image.entries(dir).is_some_and(|e| e.contains_key(&name)) {
            return Err(io::Error::new(io::ErrorKind::AlreadyExists, format!("{} exists (PowerLossDisk)", path.display())));
        }
        let ino = image.add(Node::dir());
        image.change(dir, vec![(name, Some(ino))]);
        Ok(())
    }

    fn read(&self, path: &Path) -> io::Result<Vec<u8>> {
        let mut image = self.image();
        image.op()?;
        let ino = image.lookup(path)?;
        match &image.nodes[ino] {
            Node::File { data, .. } => Ok(data.clone()),
            Node::Dir { .. } => Err(fault(io::ErrorKind::IsADirectory, path)),
        }
    }

    fn create(&self, path: &Path) -> io::Result<Box<dyn DiskFile>> {
        let mut image = self.image();
        image.op()?;
        let (dir, name) = image.parent(path)?;
        let now = image.clock;
        let ino = match image.entries(dir).and_then(|e| e.get(&name)).copied() {
            Some(ino) if image.is_dir(ino) => {
                return Err(fault(io::ErrorKind::IsADirectory, path));
            }
            Some(ino) => {
                if let Node::File { data, modified, .. } = &mut image.nodes[ino] {
                    data.clear();
                    *modified = now;
                }
                ino
            }
            None => {
                let ino = image.add(Node::File { data: Vec::new(), synced: Vec::new(), modified: now });
                image.change(dir, vec![(name, Some(ino))]);
                ino
            }
        };
        Ok(Box::new(PowerLossFile { disk: self.clone(), ino }))
    }

    fn rename(&self, from: &Path, to: &Path) -> io::Result<()> {
        let mut image = self.image();
        image.op()?;
        let ino = image.lookup(from)?;
        let (from_dir, from_name) = image.parent(from)?;
        let (to_dir, to_name) = image.parent(to)?;
        if let Some(&there) = image.entries(to_dir).and_then(|e| e.get(&to_name))
            && image.is_dir(there)
        {
            return Err(fault(io::ErrorKind::IsADirectory, to));
        }
        if from_dir == to_dir {
            image.change(to_dir, vec![(from_name, None), (to_name, Some(ino))]);
        } else {
            // Two directories, each synced on its own: either half may be lost.
            image.change(to_dir, vec![(to_name, Some(ino))]);
            image.change(from_dir, vec![(from_name, None)]);
        }
        Ok(())
    }

    fn remove_file(&self, path: &Path) -> io::Result<()> {
        let mut image = self.image();
        image.op()?;
        let ino = image.lookup(path)?;
        if image.is_dir(ino) {
            return Err(fault(io::ErrorKind::IsADirectory, path));
        }
        let (dir, name) = image.parent(path)?;
        image.change(dir, vec![(name, None)]);
        Ok(())
    }

    fn remove_dir(&self, path: &Path) -> io::Result<()> {
        let mut image = self.image();
        image.op()?;
        let ino = image.lookup(path)?;
        match image.entries(ino) {
            None => return Err(fault(io::ErrorKind::NotADirectory, path)),
            Some(entries) if !entries.is_empty() => {
                return Err(fault(io::ErrorKind::DirectoryNotEmpty, path));
            }
            Some(_) => {}
        }
        let (dir, name) = image.parent(path)?;
        image.change(dir, vec![(name, None)]);
        Ok(())
    }

    fn sync_dir(&self, path: &Path) -> io::Result<()> {
        let mut image = self.image();
        image.op()?;
        let ino = image.lookup(path)?;
        match &mut image.nodes[ino] {
            Node::Dir { entries, durable, pending } => {
                durable.clone_from(entries);
                pending.clear();
                Ok(())
            }
            Node::File { .. } => Err(fault(io::ErrorKind::NotADirectory, path)),
        }
    }

    fn list(&self, dir: &Path) -> io::Result<Vec<DirEntry>> {
        let mut image = self.image();
        image.op()?;
        let ino = image.lookup(dir)?;
        let entries = image.entries(ino).ok_or_else(|| fault(io::ErrorKind::NotADirectory, dir))?;
        Ok(entries
            .iter()
            .map(|(name, &child)| DirEntry {
                name: name.clone(),
                is_dir: image.is_dir(child),
                file: match &image.nodes[child] {
                    Node::File { data, modified, .. } => Some((data.len() as u64, SystemTime::UNIX_EPOCH + Duration::from_nanos(*modified))),
                    Node::Dir { .. } => None,
                },
            })
            .collect())
    }

    fn lock(&self, path: &Path) -> io::Result<Option<DiskLock>> {
        // The lock file is created as the OS's would be; there is one
        // process, so the lock itself is a token.
        drop(self.create(path)?);
        Ok(Some(Box::new(())))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(disk: &PowerLossDisk, path: &str, bytes: &[u8], sync: bool) {
        let mut file = disk.create(Path::new(path)).expect("create");
        file.write_all(bytes).expect("write");
        if sync {
            file.sync().expect("sync");
        }
    }

    fn read(disk: &PowerLossDisk, path: &str) -> Option<Vec<u8>> {
        disk.read(Path::new(path)).ok()
    }

    #[test]
    fn only_synced_contents_and_entries_survive() {
        let disk = PowerLossDisk::new();
        disk.create_dir(Path::new("/d")).expect("mkdir");
        disk.sync_dir(Path::new("/")).expect("sync root");
        write(&disk, "/d/synced", b"one", true);
        write(&disk, "/d/unsynced", b"two", false);
        // Not synced into /d yet: both names are lost.
        assert_eq!(read(&disk.crash(Unsynced::Lost), "/d/synced"), None);
        disk.sync_dir(Path::new("/d")).expect("sync d");
        let after = disk.crash(Unsynced::Lost);
        assert_eq!(read(&after, "/d/synced"), Some(b"one".to_vec()));
        assert_eq!(read(&after, "/d/unsynced"), Some(Vec::new()), "the name survives, its unsynced contents do not");
        assert_eq!(read(&disk.crash(Unsynced::Kept), "/d/unsynced"), Some(b"two".to_vec()));

        // A rename not yet synced: old or new, never both or neither.
        write(&disk, "/d/t", b"new", true);
        disk.rename(Path::new("/d/t"), Path::new("/d/synced")).expect("rename");
        assert_eq!(read(&disk.crash(Unsynced::Lost), "/d/synced"), Some(b"one".to_vec()));
        assert_eq!(read(&disk.crash(Unsynced::Kept), "/d/synced"), Some(b"new".to_vec()));
        assert_eq!(read(&disk.crash(Unsynced::Kept), "/d/t"), None);
        for seed in 0..32 {
            let after = disk.crash(Unsynced::Random(seed));
            let (file, temp) = (read(&after, "/d/synced"), read(&after, "/d/t"));
            // The temporary name's creation is a change of its own: it may survive alone.
            let ok = matches!((file.as_deref(), temp.as_deref()), (Some(b"one"), None | Some(b"new")) | (Some(b"new"), None));
            assert!(ok, "seed {seed}: {file:?} {temp:?}");
        }
    }

    #[test]
    fn the_power_goes_off_after_the_given_operations() {
        let disk = PowerLossDisk::new();
        disk.cut_power_after(2);
        disk.create_dir(Path::new("/a")).expect("first");
        disk.sync_dir(Path::new("/")).expect("second");
        assert!(disk.power_is_off());
        assert!(disk.create_dir(Path::new("/b")).is_err());
        assert!(disk.read(Path::new("/a")).is_err(), "reads fail too");
        assert_eq!(disk.ops(), 2);
        let after = disk.crash(Unsynced::Kept);
        assert!(!after.power_is_off());
        assert!(after.list(Path::new("/a")).is_ok_and(|e| e.is_empty()));
        assert_eq!(after.create_dir(Path::new("/a")).map_err(|e| e.kind()), Err(io::ErrorKind::AlreadyExists));
    }
}
