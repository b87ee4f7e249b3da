//! Shared by the binary's integration tests.

use std::path::PathBuf;

/// A fresh temporary folder for one test, removed on drop.
pub struct Temp(pub PathBuf);

impl Temp {
    /// `snowpack-test-NAME-PID` under the system's temporary folder, emptied.
    pub fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("snowpack-test-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("temp dir");
        Self(dir)
    }
}

impl Drop for Temp {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
