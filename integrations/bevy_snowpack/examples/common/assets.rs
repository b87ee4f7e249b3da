//! Where the examples' assets are, however the example was started: by
//! `cargo run` (Bevy would look beside this crate's manifest), or as the
//! built binary from anywhere (Bevy would look beside the executable).

use std::path::{Path, PathBuf};

/// The example's package as it was at compile time: the repository's
/// `assets` folder is beside one of its ancestors (bevy_snowpack's, or the
/// multiplayer example's own package two levels below it).
const COMPILED_IN: &str = env!("CARGO_MANIFEST_DIR");

/// The assets folder (absolute): `overridden` when given, else the
/// repository's as compiled in (the first `assets` folder above the
/// package), else the first `assets` folder beside the executable or above it; each must hold `marker` (a file the example
/// loads). The error names every place tried.
pub fn assets_dir(overridden: Option<&Path>, marker: &str) -> Result<PathBuf, String> {
    let holds = |dir: &Path| dir.join(marker).is_file();
    if let Some(dir) = overridden {
        return if holds(dir) { absolute(dir) } else { Err(format!("--assets {}: no {marker} there", dir.display())) };
    }
    let mut tried: Vec<PathBuf> = Path::new(COMPILED_IN).ancestors().map(|dir| dir.join("assets")).collect();
    if let Ok(exe) = std::env::current_exe() {
        tried.extend(exe.ancestors().skip(1).map(|dir| dir.join("assets")));
    }
    match tried.iter().find(|dir| holds(dir)) {
        Some(dir) => absolute(dir),
        None => Err(format!(
            "no assets folder with {marker}; looked in {}; give --assets DIR",
            tried.iter().map(|d| d.display().to_string()).collect::<Vec<_>>().join(", ")
        )),
    }
}

fn absolute(dir: &Path) -> Result<PathBuf, String> {
    std::fs::canonicalize(dir).map_err(|e| format!("{}: {e}", dir.display()))
}
