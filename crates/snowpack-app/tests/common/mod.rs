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
    /// Its first line: where it listens, its store, its world, how presses travel.
    pub first_line: String,
    /// Its output after the first line, as it comes.
    output: std::sync::Arc<std::sync::Mutex<Vec<String>>>,
}

#[allow(dead_code, reason = "each test binary uses its own part of common")]
impl Server {
    /// Starts one on a free loopback port over `store`; it stops by itself after `limit`.
    pub fn start(store: &Path, limit: Duration) -> Self {
        Self::start_with(store, limit, &[])
    }

    /// As [`Server::start`], with more options (`--scene FILE`, `--disk-budget N`).
    pub fn start_with(store: &Path, limit: Duration, options: &[&std::ffi::OsStr]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_snowpack"))
            .env("SNOWPACK_LOG", "error")
            .args(["server", "--listen", "127.0.0.1:0", "--store"])
            .arg(store)
            .args(["--exit-after-s", &limit.as_secs().to_string()])
            .args(options)
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
        let output = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let sink = std::sync::Arc::clone(&output);
        std::thread::spawn(move || {
            for line in lines.map_while(Result::ok) {
                sink.lock().expect("the output lock").push(line);
            }
        });
        Self { child, addr, first_line: first, output }
    }

    /// Waits (at most `limit`, then kills it) for it to stop by itself; its output after the first line.
    pub fn wait(mut self, limit: Duration) -> Vec<String> {
        let deadline = std::time::Instant::now() + limit;
        while self.child.try_wait().ok().flatten().is_none() {
            if std::time::Instant::now() > deadline {
                let _ = self.child.kill();
                break;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.wait();
        // The reader thread ends with the pipe; give it a moment to take the last line.
        std::thread::sleep(Duration::from_millis(200));
        self.output.lock().expect("the output lock").clone()
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

/// Longest any one process of the network tests may run.
#[allow(dead_code, reason = "each test binary uses its own part of common")]
pub const PROCESS_LIMIT: Duration = Duration::from_secs(120);

/// The `snowpack` binary cargo built for these tests, logging errors only.
#[allow(dead_code, reason = "each test binary uses its own part of common")]
pub fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_snowpack"));
    c.env("SNOWPACK_LOG", "error");
    c
}

/// Runs `cmd` to completion within [`PROCESS_LIMIT`] (killed past it).
#[allow(dead_code, reason = "each test binary uses its own part of common")]
pub fn run_bounded(mut cmd: Command) -> std::process::Output {
    let child = cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("start snowpack");
    let id = child.id();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    match rx.recv_timeout(PROCESS_LIMIT) {
        Ok(out) => out.expect("snowpack's output"),
        Err(_) => {
            let _ = Command::new("kill").args(["-9", &id.to_string()]).status();
            panic!("snowpack ran longer than {PROCESS_LIMIT:?}");
        }
    }
}
