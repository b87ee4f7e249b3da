//! Shared by the binary's integration tests.

use std::io::{BufRead as _, BufReader};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

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

/// A running `snowpack server`, killed on drop.
#[allow(dead_code, reason = "each test binary uses its own part of common")]
pub struct Server {
    child: Child,
    /// Where it listens.
    pub addr: SocketAddr,
}

#[allow(dead_code, reason = "each test binary uses its own part of common")]
impl Server {
    /// Starts one on a free loopback port over `store`; it stops by itself after `limit`.
    pub fn start(store: &Path, limit: Duration) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_snowpack"))
            .env("SNOWPACK_LOG", "error")
            .args(["server", "--listen", "127.0.0.1:0", "--store"])
            .arg(store)
            .args(["--exit-after-s", &limit.as_secs().to_string()])
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start snowpack server");
        let stdout = child.stdout.take().expect("the server's stdout");
        let mut lines = BufReader::new(stdout).lines();
        let first = lines.next().expect("the server says where it listens").expect("a line");
        let addr: SocketAddr = first
            .split_whitespace()
            .skip_while(|w| *w != "on")
            .nth(1)
            .and_then(|a| a.parse().ok())
            .unwrap_or_else(|| panic!("no address in the server's first line: {first:?}"));
        // Keep draining its output so it never blocks on a full pipe.
        std::thread::spawn(move || for _ in lines.map_while(Result::ok) {});
        Self { child, addr }
    }

    /// Its process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Kills it at once (SIGKILL), as a crash would.
    pub fn kill(mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
