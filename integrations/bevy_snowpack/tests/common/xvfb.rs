//! A private X server for the examples' tests (one per test, on the display
//! it picks). Shared by bevy_snowpack's tests and the multiplayer package's.

use std::io::{BufRead as _, BufReader};
use std::process::{Child, Command, Stdio};

/// A private X server for one test, stopped on drop.
#[allow(dead_code, reason = "each test file uses its own subset of these helpers")]
pub struct Xvfb {
    child: Child,
    /// The display (`:N`) for `DISPLAY`.
    pub display: String,
}

#[allow(dead_code, reason = "each test file uses its own subset of these helpers")]
impl Xvfb {
    /// Starts one; `None` (skip) when Xvfb is missing and no GPU is required.
    pub fn start() -> Option<Self> {
        let spawned = Command::new("Xvfb")
            .args(["-displayfd", "1", "-screen", "0", "1024x768x24", "-nolisten", "tcp"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn();
        let mut child = match spawned {
            Ok(c) => c,
            Err(e) => {
                assert!(
                    std::env::var_os("SNOWPACK_REQUIRE_GPU").is_none_or(|v| v == "0"),
                    "SNOWPACK_REQUIRE_GPU is set but Xvfb cannot start ({e}); install it: apt-get install xvfb"
                );
                eprintln!("skipping: no Xvfb ({e})");
                return None;
            }
        };
        // Xvfb writes the display number it chose once it accepts connections.
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("piped stdout")).read_line(&mut line).expect("reading Xvfb's display number");
        let number = line.trim();
        assert!(!number.is_empty() && number.chars().all(|c| c.is_ascii_digit()), "Xvfb printed {line:?}");
        Some(Self { child, display: format!(":{number}") })
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
