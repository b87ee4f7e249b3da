//! The `multiplayer` example end to end, three processes on 127.0.0.1: the
//! server (no renderer: its memory maps must hold no GPU library), a client
//! whose fox walks from x = -4 m to 4 m along z = 0, and a second client
//! started once the fox has walked a few metres. The late client must see
//! the trail walked before it joined (probes at least 5 cm shallower than
//! open snow, and a picture where the trail differs from open snow), open
//! snow off the path, and the walking client's bytes on the wire are
//! measured.
//!
//! Without Xvfb this test skips, unless `SNOWPACK_REQUIRE_GPU` is set (CI).
//! Every wait is bounded; the processes are killed when the test fails.

mod common;

use std::collections::HashMap;
use std::io::{BufRead as _, BufReader};
use std::net::UdpSocket;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::time::{Duration, Instant};

use common::{Xvfb, example};

/// The example's snow depth (m).
const OPEN_M: f32 = 0.5;
/// The longest any step of the test waits.
const STEP_LIMIT: Duration = Duration::from_secs(240);
/// Libraries a process that touched a GPU (or Mesa's software one) maps.
const GPU_LIBRARIES: [&str; 6] = ["libvulkan", "libEGL", "libGL", "libnvidia", "lvp", "libgallium"];

/// One of the example's processes: its output lines arrive on a channel; killed on drop.
struct Process {
    name: &'static str,
    child: Child,
    lines: Receiver<String>,
    seen: Vec<String>,
}

impl Process {
    fn spawn(name: &'static str, command: &mut Command) -> Self {
        let mut child = command.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap_or_else(|e| panic!("{name}: {e} (cargo test builds the example)"));
        let (tx, lines) = channel();
        let out = child.stdout.take().expect("piped stdout");
        let err = child.stderr.take().expect("piped stderr");
        let tx2 = tx.clone();
        std::thread::spawn(move || BufReader::new(out).lines().map_while(Result::ok).for_each(|l| drop(tx.send(l))));
        std::thread::spawn(move || BufReader::new(err).lines().map_while(Result::ok).for_each(|l| drop(tx2.send(format!("stderr: {l}")))));
        Self { name, child, lines, seen: Vec::new() }
    }

    /// Reads lines until one satisfies `want` (returned); panics after `STEP_LIMIT` or if the process ends first.
    fn wait_for(&mut self, what: &str, want: impl Fn(&str) -> bool) -> String {
        let deadline = Instant::now() + STEP_LIMIT;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    self.seen.push(line.clone());
                    if want(&line) {
                        return line;
                    }
                }
                Err(RecvTimeoutError::Timeout) => panic!("{}: no {what} within {STEP_LIMIT:?}; output:\n{}", self.name, self.seen.join("\n")),
                Err(RecvTimeoutError::Disconnected) => panic!("{}: ended before {what}; output:\n{}", self.name, self.seen.join("\n")),
            }
        }
    }

    /// Waits for the process to stop by itself (bounded), with all its output read.
    fn finish(&mut self) -> ExitStatus {
        let deadline = Instant::now() + STEP_LIMIT;
        loop {
            if let Some(status) = self.child.try_wait().expect("waiting for a child") {
                // The readers end once the pipes close.
                while let Ok(line) = self.lines.recv_timeout(Duration::from_secs(5)) {
                    self.seen.push(line);
                }
                return status;
            }
            while let Ok(line) = self.lines.try_recv() {
                self.seen.push(line);
            }
            assert!(Instant::now() < deadline, "{}: still running after {STEP_LIMIT:?}; output:\n{}", self.name, self.seen.join("\n"));
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    fn output(&self) -> String {
        self.seen.join("\n")
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// GPU libraries among the files `pid` has mapped.
fn gpu_libraries_mapped(pid: u32) -> Vec<String> {
    let maps = std::fs::read_to_string(format!("/proc/{pid}/maps")).expect("the server's memory maps");
    let mut found: Vec<String> =
        maps.lines().filter_map(|l| l.split_whitespace().nth(5)).filter(|path| GPU_LIBRARIES.iter().any(|lib| path.contains(lib))).map(str::to_owned).collect();
    found.dedup();
    found
}

/// A UDP port free on loopback now.
fn free_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0").and_then(|s| s.local_addr()).expect("a free UDP port").port()
}

/// Mean luma (0..255) of the 5x5 pixels around (x, y).
fn patch_luma(image: &image::RgbaImage, x: u32, y: u32) -> f32 {
    let (mut sum, mut n) = (0.0, 0.0);
    for py in y.saturating_sub(2)..=(y + 2).min(image.height() - 1) {
        for px in x.saturating_sub(2)..=(x + 2).min(image.width() - 1) {
            let [r, g, b, _] = image.get_pixel(px, py).0;
            sum += 0.2126 * f32::from(r) + 0.7152 * f32::from(g) + 0.0722 * f32::from(b);
            n += 1.0;
        }
    }
    sum / n
}

/// The number after `key` in a line of words.
fn number_after(line: &str, key: &str) -> f64 {
    let words: Vec<&str> = line.split_whitespace().collect();
    let k = words.iter().position(|w| *w == key).unwrap_or_else(|| panic!("no {key} in {line:?}"));
    words[k + 1].parse().unwrap_or_else(|e| panic!("{key} in {line:?}: {e}"))
}

#[test]
fn a_late_client_sees_the_trail_of_a_fox_walked_before_it_joined() {
    let Some(x) = Xvfb::start() else { return };
    let dir = std::env::temp_dir().join(format!("bevy_snowpack_multiplayer_{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    let shot = dir.join("late.png");
    let exe = example("multiplayer");
    let port = free_port();
    let addr = format!("127.0.0.1:{port}");
    let client = |args: &[&str]| {
        let mut c = Command::new(&exe);
        c.arg("client")
            .args(["--connect", &addr])
            .args(args)
            .env("DISPLAY", &x.display)
            // Bevy resolves the assets folder from the manifest's directory.
            .env("CARGO_MANIFEST_DIR", env!("CARGO_MANIFEST_DIR"))
            .env_remove("WAYLAND_DISPLAY");
        c
    };

    let mut server = Process::spawn("server", Command::new(&exe).args(["server", "--port", &port.to_string(), "--exit-after-s", "600"]));
    server.wait_for("listening", |l| l.starts_with("server: listening"));
    let mut walker = Process::spawn("walking client", &mut client(&["--walk"]));
    walker.wait_for("the welcome", |l| l.starts_with("client: welcomed"));
    // A few metres walked (the server's word for where the fox is): the late client joins then.
    server.wait_for("the fox past x = -1.5 m", |l| l.starts_with("server: player") && number_after(l, "at") >= -1.5);
    let mapped = gpu_libraries_mapped(server.child.id());
    assert!(mapped.is_empty(), "the server maps GPU libraries: {mapped:?}");

    // On the path walked before the late client started, and well off it.
    let on_path = [(-3.0, 0.0), (-2.5, 0.0), (-2.0, 0.0)];
    let off_path = [(-2.5, 2.5), (0.0, -3.0)];
    let mut probes = Vec::new();
    for (px, pz) in on_path.iter().chain(&off_path) {
        probes.push("--probe".to_owned());
        probes.push(format!("{px},{pz}"));
    }
    let mut late_args: Vec<&str> = vec!["--exit-after-frames", "10", "--screenshot", shot.to_str().expect("a UTF-8 temporary path")];
    late_args.extend(probes.iter().map(String::as_str));
    let mut late = Process::spawn("late client", &mut client(&late_args));
    let late_status = late.finish();
    assert!(late_status.success(), "the late client exited with {late_status}:\n{}", late.output());
    let walker_status = walker.finish();
    assert!(walker_status.success(), "the walking client exited with {walker_status}:\n{}", walker.output());
    let mapped = gpu_libraries_mapped(server.child.id());
    assert!(mapped.is_empty(), "the server maps GPU libraries after serving both: {mapped:?}");
    let server_status = server.finish();
    assert!(server_status.success(), "the server exited with {server_status}:\n{}", server.output());

    // The late client's probes: `probe X Z depth_m D`, and where each is on its screenshot.
    let mut depth: HashMap<(i32, i32), f32> = HashMap::new();
    let mut pixel: HashMap<(i32, i32), (f32, f32)> = HashMap::new();
    let key = |x: f64, z: f64| ((x * 100.0).round() as i32, (z * 100.0).round() as i32);
    for line in late.seen.iter() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w[..] {
            ["probe", px, pz, "depth_m", d] => {
                depth.insert(key(px.parse().expect("x"), pz.parse().expect("z")), d.parse().unwrap_or_else(|e| panic!("{line}: {e}")));
            }
            ["pixel", px, pz, "at", sx, sy] => {
                pixel.insert(key(px.parse().expect("x"), pz.parse().expect("z")), (sx.parse().expect("pixel x"), sy.parse().expect("pixel y")));
            }
            _ => {}
        }
    }
    let read = |p: &(f64, f64)| *depth.get(&key(p.0, p.1)).unwrap_or_else(|| panic!("no probe at {p:?}:\n{}", late.output()));
    for p in &off_path {
        let d = read(p);
        assert!((d - OPEN_M).abs() < 0.01, "off the path at {p:?} the late client reads {d} m, not open snow ({OPEN_M} m)");
    }
    println!("late client's probes: {:?}", on_path.iter().chain(&off_path).map(|p| (p, read(p))).collect::<Vec<_>>());
    for p in &on_path {
        let d = read(p);
        assert!(
            d <= OPEN_M - 0.05,
            "on the fox's path at {p:?} the late client reads {d} m: no trail (open snow is {OPEN_M} m); the server said:\n{}",
            server.seen.iter().rev().take(12).rev().cloned().collect::<Vec<_>>().join("\n")
        );
    }

    // The screenshot: around where the late client says each point's rest surface is on screen
    // (a few pixels up and down: the view passes into a trench, onto its walls), the picture
    // differs from open snow on the path, and not off it.
    let image = image::open(&shot).unwrap_or_else(|e| panic!("{}: {e}", shot.display())).to_rgba8();
    let at = |p: &(f64, f64)| {
        let (sx, sy) = *pixel.get(&key(p.0, p.1)).unwrap_or_else(|| panic!("{p:?} is off the late client's screen:\n{}", late.output()));
        assert!(sx >= 2.0 && sy >= 8.0 && sx < image.width() as f32 - 2.0 && sy < image.height() as f32 - 8.0, "{p:?} at {sx} {sy} is off the picture");
        (sx as u32, sy as u32)
    };
    let (ox, oy) = at(&off_path[0]);
    let open = patch_luma(&image, ox, oy);
    let contrast = |p: &(f64, f64)| {
        let (sx, sy) = at(p);
        (sy - 6..=sy + 6).map(|y| (patch_luma(&image, sx, y) - open).abs()).fold(0.0, f32::max)
    };
    let trail: Vec<f32> = on_path.iter().map(contrast).collect();
    let off = contrast(&off_path[1]);
    println!("screenshot {}: open snow luma {open:.1}; most different luma near the path {trail:?}, off it {off:.1}", shot.display());
    assert!(open > 120.0, "open snow reads luma {open:.1}: not snow");
    assert!(off < 5.0, "open snow at {:?} differs from open snow at {:?} by {off:.1} luma", off_path[1], off_path[0]);
    for (p, t) in on_path.iter().zip(&trail) {
        assert!(*t > 10.0, "the trail at {p:?} looks like open snow (at most {t:.1} luma apart)");
    }

    // The server's own answer under the fox (from the relay's merged tiles): it ploughed.
    let under: Vec<f64> = server.seen.iter().filter(|l| l.starts_with("server: player")).map(|l| number_after(l, "depth_m")).collect();
    let least = under.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(least <= f64::from(OPEN_M) - 0.05, "the server never saw the fox in its trail: depths under it {under:?}");

    // Bytes on the wire for one walking fox.
    let wire = walker.seen.iter().find(|l| l.starts_with("wire:")).unwrap_or_else(|| panic!("no wire line:\n{}", walker.output())).clone();
    let per_s = number_after(&wire, "snow_bytes_sent_per_s");
    println!("walking client: {wire}");
    assert!(per_s > 0.0, "the walking fox sent nothing: {wire}");
    // docs/multiplayer.md measured 1.2 KB/s for a walking fox in `snowpack run`; four times
    // more would be a resend storm or tiles sent every frame.
    assert!(per_s < 16_000.0, "one walking fox sends {per_s} bytes/s: {wire}");
    let _ = std::fs::remove_dir_all(&dir);
}
