//! The `multiplayer` example end to end, separate processes on 127.0.0.1
//! under one Xvfb, the binary run as built (no `CARGO_MANIFEST_DIR`: it
//! finds its assets itself):
//!
//! - a dedicated server (no renderer: its memory maps must hold no GPU
//!   library), a client whose fox the server walks from x = -4 m to 4 m
//!   along z = 0 on its requests, and a second client started once the fox
//!   has walked a few metres: the late client sees the trail walked before
//!   it joined, open snow off the path, and the walking player's fox where
//!   the server's replicated transform puts it;
//! - the same with the server killed (SIGKILL) after the walker left and
//!   started again on its store: the late client still reads the trail;
//! - a listen server (`host`) walking its own fox, and a late client that
//!   sees its trail and its fox.
//!
//! The server is the package's own binary, or where `MULTIPLAYER_SERVER_EXE`
//! names one, that binary: `.ci/run` builds the server alone (`cargo build
//! -p multiplayer --no-default-features --features server`, no renderer
//! compiled in) and runs these tests with it.
//!
//! Without Xvfb these tests skip, unless `SNOWPACK_REQUIRE_GPU` is set
//! (CI). Every wait is bounded; the processes are killed when a test fails.
//! The tests run one at a time (each runs two renderers on lavapipe).

#[path = "../../../tests/common/xvfb.rs"]
mod xvfb;

use std::collections::HashMap;
use std::io::{BufRead as _, BufReader, Write as _};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::Mutex;
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::time::{Duration, Instant};

use xvfb::Xvfb;

/// The example's snow depth (m).
const OPEN_M: f32 = 0.5;
/// The longest any step of the test waits.
const STEP_LIMIT: Duration = Duration::from_secs(240);
/// Libraries a process that touched a GPU (or Mesa's software one) maps.
const GPU_LIBRARIES: [&str; 6] = ["libvulkan", "libEGL", "libGL", "libnvidia", "lvp", "libgallium"];
/// The listen server's own player id in the example.
const HOST_ID: u64 = 0;

/// One test at a time: each runs the example's renderers on the software rasteriser.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// One of the example's processes: its output lines arrive on a channel; killed on drop.
struct Process {
    name: &'static str,
    child: Child,
    lines: Receiver<String>,
    seen: Vec<String>,
}

impl Process {
    fn spawn(name: &'static str, command: &mut Command) -> Self {
        let mut child = command
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("{name}: {e} (cargo test builds the example)"));
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
                Err(RecvTimeoutError::Timeout) => panic!("{}: no {what} within {STEP_LIMIT:?}; output:\n{}", self.name, self.output()),
                Err(RecvTimeoutError::Disconnected) => panic!("{}: ended before {what}; output:\n{}", self.name, self.output()),
            }
        }
    }

    /// A line on its standard input (`--leave-on-input`: it may go now).
    fn tell(&mut self) {
        let stdin = self.child.stdin.as_mut().expect("piped stdin");
        stdin.write_all(b"leave\n").and_then(|()| stdin.flush()).unwrap_or_else(|e| panic!("{}: writing its input: {e}", self.name));
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
            assert!(Instant::now() < deadline, "{}: still running after {STEP_LIMIT:?}; output:\n{}", self.name, self.output());
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Waits for a successful exit.
    fn succeed(&mut self) {
        let status = self.finish();
        assert!(status.success(), "{} exited with {status}:\n{}", self.name, self.output());
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

/// A test's X server, folder and the example's binaries.
struct Rig {
    x: Xvfb,
    dir: PathBuf,
    /// The players' (and a listen server's) binary: this package's.
    exe: PathBuf,
    /// The dedicated server's: `MULTIPLAYER_SERVER_EXE`, or this package's.
    server_exe: PathBuf,
}

impl Rig {
    fn new(name: &str) -> Option<Self> {
        let x = Xvfb::start()?;
        let dir = std::env::temp_dir().join(format!("bevy_snowpack_{name}_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("a temporary folder");
        let exe = PathBuf::from(env!("CARGO_BIN_EXE_multiplayer"));
        let server_exe = std::env::var_os("MULTIPLAYER_SERVER_EXE").map_or_else(|| exe.clone(), PathBuf::from);
        println!("server: {}", server_exe.display());
        Some(Self { x, dir, exe, server_exe })
    }

    /// The example with `args`, on this test's display, run from the temporary folder as the
    /// built binary (so it must find its assets without cargo's help).
    fn command(&self, args: &[&str]) -> Command {
        self.command_of(&self.exe, args)
    }

    /// `exe` with `args`, as [`Self::command`] runs the example.
    fn command_of(&self, exe: &Path, args: &[&str]) -> Command {
        let mut c = Command::new(exe);
        c.args(args).current_dir(&self.dir).env("DISPLAY", &self.x.display).env_remove("WAYLAND_DISPLAY").env_remove("CARGO_MANIFEST_DIR");
        c
    }

    fn store(&self) -> String {
        self.dir.join("world").to_str().expect("a UTF-8 temporary path").to_owned()
    }

    fn server(&self, port: u16, extra: &[&str]) -> Process {
        let port = port.to_string();
        let mut args = vec!["server", "--port", &port];
        let store = self.store();
        args.extend(["--store", &store]);
        args.extend(extra);
        let mut server = Process::spawn("server", &mut self.command_of(&self.server_exe, &args));
        server.wait_for("listening", |l| l.starts_with("server: listening"));
        server
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Where `MULTIPLAYER_SERVER_EXE` names the server (CI), that binary is the
/// server alone, built without the client: asked to play, it refuses.
fn assert_server_alone(rig: &Rig) {
    if std::env::var_os("MULTIPLAYER_SERVER_EXE").is_none() {
        return;
    }
    let out = Command::new(&rig.server_exe).args(["client", "--connect", "127.0.0.1:9"]).output().expect("running the server's binary");
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.code() == Some(2) && said.contains("the server alone"), "{} plays: {:?}\n{said}", rig.server_exe.display(), out.status);
    println!("the server is {}, built without the client", rig.server_exe.display());
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

/// Pixels in the box (inclusive, clipped to the picture) that are the fox's
/// fur: red well over blue. Snow, trail shadows and the sky are all at least
/// as blue as red.
fn fur_pixels(image: &image::RgbaImage, x: [f32; 2], y: [f32; 2]) -> usize {
    let clip = |v: f32, max: u32| (v.max(0.0) as u32).min(max - 1);
    let (x0, x1, y0, y1) = (clip(x[0], image.width()), clip(x[1], image.width()), clip(y[0], image.height()), clip(y[1], image.height()));
    (y0..=y1)
        .flat_map(|py| (x0..=x1).map(move |px| (px, py)))
        .filter(|&(px, py)| {
            let [r, _, b, _] = image.get_pixel(px, py).0;
            i32::from(r) > i32::from(b) + 30
        })
        .count()
}

/// The number after `key` in a line of words.
fn number_after(line: &str, key: &str) -> f64 {
    let words: Vec<&str> = line.split_whitespace().collect();
    let k = words.iter().position(|w| *w == key).unwrap_or_else(|| panic!("no {key} in {line:?}"));
    words[k + 1].parse().unwrap_or_else(|e| panic!("{key} in {line:?}: {e}"))
}

type Point = (f64, f64);

fn key(p: Point) -> (i32, i32) {
    ((p.0 * 100.0).round() as i32, (p.1 * 100.0).round() as i32)
}

/// A fox on the late client's screen: its player, where it stands, and its feet and back on the picture.
#[derive(Debug)]
struct FoxSeen {
    id: u64,
    at: Point,
    feet: (f32, f32),
    back: (f32, f32),
}

/// What a late client printed: `probe X Z depth_m D`, `pixel X Z at SX SY`, `fox ...` lines.
struct LateReport {
    depth: HashMap<(i32, i32), f32>,
    pixel: HashMap<(i32, i32), (f32, f32)>,
    foxes: Vec<FoxSeen>,
    output: String,
}

impl LateReport {
    fn of(late: &Process) -> Self {
        let mut r = Self { depth: HashMap::new(), pixel: HashMap::new(), foxes: Vec::new(), output: late.output() };
        let f = |s: &str| s.parse::<f64>().unwrap_or_else(|e| panic!("{s}: {e}"));
        for line in &late.seen {
            let w: Vec<&str> = line.split_whitespace().collect();
            match w[..] {
                ["probe", px, pz, "depth_m", d] => {
                    r.depth.insert(key((f(px), f(pz))), f(d) as f32);
                }
                ["pixel", px, pz, "at", sx, sy] => {
                    r.pixel.insert(key((f(px), f(pz))), (f(sx) as f32, f(sy) as f32));
                }
                ["fox", id, "at", x, z, "feet", fx, fy, "back", bx, by, "own", _] => r.foxes.push(FoxSeen {
                    id: id.parse().unwrap_or_else(|e| panic!("{line}: {e}")),
                    at: (f(x), f(z)),
                    feet: (f(fx) as f32, f(fy) as f32),
                    back: (f(bx) as f32, f(by) as f32),
                }),
                _ => {}
            }
        }
        r
    }

    fn depth(&self, p: Point) -> f32 {
        *self.depth.get(&key(p)).unwrap_or_else(|| panic!("no probe at {p:?}:\n{}", self.output))
    }

    fn pixel(&self, p: Point, image: &image::RgbaImage) -> (u32, u32) {
        let (sx, sy) = *self.pixel.get(&key(p)).unwrap_or_else(|| panic!("{p:?} is off the late client's screen:\n{}", self.output));
        assert!(sx >= 2.0 && sy >= 8.0 && sx < image.width() as f32 - 2.0 && sy < image.height() as f32 - 8.0, "{p:?} at {sx} {sy} is off the picture");
        (sx as u32, sy as u32)
    }
}

/// The probes' arguments.
fn probe_args(points: &[Point]) -> Vec<String> {
    points.iter().flat_map(|(x, z)| ["--probe".to_owned(), format!("{x},{z}")]).collect()
}

/// The late client's trail: its probes on the path read at least 5 cm less than open snow, off it
/// open snow; on its screenshot, around where it says each point's rest surface is (a few pixels
/// up and down: the view passes into a trench, onto its walls), the picture differs from open
/// snow on the path, and not off it.
fn assert_trail(report: &LateReport, image: &image::RgbaImage, on_path: &[Point], off_path: &[Point; 2]) {
    for &p in off_path {
        let d = report.depth(p);
        assert!((d - OPEN_M).abs() < 0.01, "off the path at {p:?} the late client reads {d} m, not open snow ({OPEN_M} m)");
    }
    println!("late client's probes: {:?}", on_path.iter().chain(off_path).map(|&p| (p, report.depth(p))).collect::<Vec<_>>());
    for &p in on_path {
        let d = report.depth(p);
        assert!(d <= OPEN_M - 0.05, "on the fox's path at {p:?} the late client reads {d} m: no trail (open snow is {OPEN_M} m)");
    }
    let (ox, oy) = report.pixel(off_path[0], image);
    let open = patch_luma(image, ox, oy);
    let contrast = |p: Point| {
        let (sx, sy) = report.pixel(p, image);
        (sy - 6..=sy + 6).map(|y| (patch_luma(image, sx, y) - open).abs()).fold(0.0, f32::max)
    };
    let trail: Vec<f32> = on_path.iter().map(|&p| contrast(p)).collect();
    let off = contrast(off_path[1]);
    println!("open snow luma {open:.1}; most different luma near the path {trail:?}, off it {off:.1}");
    assert!(open > 120.0, "open snow reads luma {open:.1}: not snow");
    assert!(off < 5.0, "open snow at {:?} differs from open snow at {:?} by {off:.1} luma", off_path[1], off_path[0]);
    for (p, t) in on_path.iter().zip(&trail) {
        assert!(*t > 10.0, "the trail at {p:?} looks like open snow (at most {t:.1} luma apart)");
    }
}

/// The walking player's fox is on the late client's screenshot: fur where it says the fox is,
/// and none on open snow the same size.
fn assert_fox(report: &LateReport, image: &image::RgbaImage, walker: impl Fn(&FoxSeen) -> bool, open: (u32, u32)) {
    let fox = report.foxes.iter().find(|f| walker(f)).unwrap_or_else(|| panic!("the late client draws no walking fox:\n{}", report.output));
    // The fox walks along x: its body spans a few tens of pixels either side of its feet.
    let half = 30.0;
    let (xs, ys) = ([fox.feet.0.min(fox.back.0) - half, fox.feet.0.max(fox.back.0) + half], [fox.back.1 - 10.0, fox.feet.1 + 4.0]);
    let fur = fur_pixels(image, xs, ys);
    let (ox, oy) = (open.0 as f32, open.1 as f32);
    let none = fur_pixels(image, [ox - half, ox + half], [oy - (ys[1] - ys[0]) / 2.0, oy + (ys[1] - ys[0]) / 2.0]);
    println!("the walking fox {} at {:?}: {fur} fur pixels in x {xs:?} y {ys:?}; {none} around open snow at {open:?}", fox.id, fox.at);
    assert!(fur >= 15, "no fox on the late client's picture where it says player {} is ({fur} fur pixels in x {xs:?} y {ys:?})", fox.id);
    assert_eq!(none, 0, "fur on open snow around {open:?}");
}

fn screenshot(path: &Path) -> image::RgbaImage {
    image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgba8()
}

/// Bytes on the wire for one walking fox.
fn assert_wire(walker: &Process) {
    let wire = walker.seen.iter().find(|l| l.starts_with("wire:")).unwrap_or_else(|| panic!("no wire line:\n{}", walker.output()));
    let per_s = number_after(wire, "snow_bytes_sent_per_s");
    println!("walker: {wire}");
    assert!(per_s > 0.0, "the walking fox sent nothing: {wire}");
    // docs/multiplayer.md measured 1.2 KB/s for a walking fox in `snowpack run`; four times
    // more would be a resend storm or tiles sent every frame.
    assert!(per_s < 16_000.0, "one walking fox sends {per_s} bytes/s: {wire}");
}

/// The server's own answer under a player (from the relay's merged tiles): it ploughed.
fn assert_server_saw_the_trench(server: &Process) {
    let under: Vec<f64> = server.seen.iter().filter(|l| l.starts_with("server: player")).map(|l| number_after(l, "depth_m")).collect();
    let least = under.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(least <= f64::from(OPEN_M) - 0.05, "the server never saw the fox in its trail: depths under it {under:?}");
}

#[test]
fn a_late_client_sees_the_trail_and_the_fox_of_a_player_walked_before_it_joined() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let Some(rig) = Rig::new("multiplayer_late") else { return };
    assert_server_alone(&rig);
    let shot = rig.dir.join("late.png");
    let port = free_port();
    let addr = format!("127.0.0.1:{port}");
    let mut server = rig.server(port, &["--exit-when-empty"]);
    let mut walker = Process::spawn("walking client", &mut rig.command(&["client", "--connect", &addr, "--walk", "--leave-on-input"]));
    walker.wait_for("the welcome", |l| l.starts_with("client: welcomed"));
    // A few metres walked (the server's word for where the fox is): the late client joins then.
    server.wait_for("the fox past x = -1.5 m", |l| l.starts_with("server: player") && number_after(l, "at") >= -1.5);
    let mapped = gpu_libraries_mapped(server.child.id());
    assert!(mapped.is_empty(), "the server maps GPU libraries: {mapped:?}");

    // On the path walked before the late client started, and well off it.
    let on_path = [(-3.0, 0.0), (-2.5, 0.0), (-2.0, 0.0)];
    let off_path = [(-2.5, 2.5), (0.0, -3.0)];
    let probes = probe_args(&[&on_path[..], &off_path[..]].concat());
    let mut args = vec!["client", "--connect", &addr, "--exit-after-frames", "10", "--screenshot", shot.to_str().expect("UTF-8")];
    args.extend(probes.iter().map(String::as_str));
    let mut late = Process::spawn("late client", &mut rig.command(&args));
    late.succeed();
    walker.tell();
    walker.succeed();
    let mapped = gpu_libraries_mapped(server.child.id());
    assert!(mapped.is_empty(), "the server maps GPU libraries after serving both: {mapped:?}");
    server.succeed();

    let report = LateReport::of(&late);
    let image = screenshot(&shot);
    println!("screenshot {}", shot.display());
    assert_trail(&report, &image, &on_path, &off_path);
    // The walker's fox, where the server put it: on the path, past where the late client joined.
    let open = report.pixel(off_path[0], &image);
    assert_fox(&report, &image, |f| f.at.0 >= -1.5 && f.at.1.abs() < 0.1, open);
    assert_server_saw_the_trench(&server);
    assert_wire(&walker);
    if let Some(keep) = std::env::var_os("BEVY_SNOWPACK_KEEP_SHOT") {
        std::fs::copy(&shot, &keep).expect("copying the screenshot");
    }
}

#[test]
fn a_late_client_reads_the_trail_after_the_server_restarted() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let Some(rig) = Rig::new("multiplayer_restart") else { return };
    assert_server_alone(&rig);
    let shot = rig.dir.join("late.png");
    let port = free_port();
    let addr = format!("127.0.0.1:{port}");
    // Without --exit-when-empty the server stays up once the walker has gone.
    let mut first = rig.server(port, &[]);
    let mut walker = Process::spawn("walking client", &mut rig.command(&["client", "--connect", &addr, "--walk"]));
    walker.succeed();
    first.wait_for("the walker leaving", |l| l.contains("left"));
    std::thread::sleep(Duration::from_secs(3));
    assert!(first.child.try_wait().expect("the server's state").is_none(), "the server stopped once empty:\n{}", first.output());
    // Killed without a goodbye: what it acknowledged must be on disk.
    first.child.kill().expect("killing the server");
    first.finish();

    let port = free_port();
    let addr = format!("127.0.0.1:{port}");
    let mut again = rig.server(port, &["--exit-when-empty"]);
    // The whole walk is in the store; the late client spawns alone at x = -4 m, so probe beyond its fox.
    let on_path = [(-2.0, 0.0), (0.0, 0.0), (2.0, 0.0)];
    let off_path = [(-2.5, 2.5), (0.0, -3.0)];
    let probes = probe_args(&[&on_path[..], &off_path[..]].concat());
    let mut args = vec!["client", "--connect", &addr, "--exit-after-frames", "10", "--screenshot", shot.to_str().expect("UTF-8")];
    args.extend(probes.iter().map(String::as_str));
    let mut late = Process::spawn("late client", &mut rig.command(&args));
    late.succeed();
    let mapped = gpu_libraries_mapped(again.child.id());
    assert!(mapped.is_empty(), "the restarted server maps GPU libraries: {mapped:?}");
    again.succeed();

    let report = LateReport::of(&late);
    let image = screenshot(&shot);
    println!("screenshot {}", shot.display());
    assert_trail(&report, &image, &on_path, &off_path);
    assert_wire(&walker);
}

#[test]
fn a_late_client_of_a_listen_server_sees_its_trail_and_its_fox() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let Some(rig) = Rig::new("multiplayer_host") else { return };
    let shot = rig.dir.join("late.png");
    let port = free_port();
    let addr = format!("127.0.0.1:{port}");
    let store = rig.store();
    let port_arg = port.to_string();
    let mut host = Process::spawn("listen server", &mut rig.command(&["host", "--port", &port_arg, "--store", &store, "--walk", "--leave-on-input"]));
    host.wait_for("its own welcome", |l| l.starts_with("client: welcomed"));
    host.wait_for("its fox past x = -1.5 m", |l| l.starts_with("server: player 0 ") && number_after(l, "at") >= -1.5);

    let on_path = [(-3.0, 0.0), (-2.5, 0.0), (-2.0, 0.0)];
    let off_path = [(-2.5, 2.5), (0.0, -3.0)];
    let probes = probe_args(&[&on_path[..], &off_path[..]].concat());
    let mut args = vec!["client", "--connect", &addr, "--exit-after-frames", "10", "--screenshot", shot.to_str().expect("UTF-8")];
    args.extend(probes.iter().map(String::as_str));
    let mut late = Process::spawn("late client", &mut rig.command(&args));
    late.succeed();
    host.tell();
    host.succeed();

    let report = LateReport::of(&late);
    let image = screenshot(&shot);
    println!("screenshot {}", shot.display());
    assert_trail(&report, &image, &on_path, &off_path);
    let open = report.pixel(off_path[0], &image);
    assert_fox(&report, &image, |f| f.id == HOST_ID, open);
    assert_server_saw_the_trench(&host);
}
