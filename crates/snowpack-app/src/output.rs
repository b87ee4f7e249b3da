//! Writing a run's files so that nothing half-written is left behind: every
//! file goes to a temporary name first and is renamed into place only when
//! all of them were written.

use std::path::{Path, PathBuf};

use anyhow::Context as _;

/// Files staged for one output directory.
pub struct OutputSet {
    dir: PathBuf,
    staged: Vec<(PathBuf, PathBuf)>,
}

impl OutputSet {
    /// Outputs for `dir` (created if missing).
    pub fn new(dir: &Path) -> anyhow::Result<Self> {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create output directory {}", dir.display()))?;
        Ok(Self { dir: dir.to_owned(), staged: Vec::new() })
    }

    /// Writes `bytes` under a temporary name for `name`.
    pub fn stage(&mut self, name: &str, bytes: &[u8]) -> anyhow::Result<()> {
        let final_path = self.dir.join(name);
        let tmp = self.dir.join(format!(".{name}.{}.tmp", std::process::id()));
        if let Err(e) = std::fs::write(&tmp, bytes) {
            let _ = std::fs::remove_file(&tmp);
            self.abort();
            return Err(e).with_context(|| format!("cannot write {}", final_path.display()));
        }
        self.staged.push((tmp, final_path));
        Ok(())
    }

    /// Renames every staged file into place; returns their final paths.
    pub fn commit(mut self) -> anyhow::Result<Vec<PathBuf>> {
        let staged = std::mem::take(&mut self.staged);
        let mut done = Vec::new();
        for (tmp, path) in staged {
            std::fs::rename(&tmp, &path).with_context(|| format!("cannot move {} into place", path.display()))?;
            done.push(path);
        }
        Ok(done)
    }

    fn abort(&mut self) {
        for (tmp, _) in self.staged.drain(..) {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        self.abort();
    }
}
