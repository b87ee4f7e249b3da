//! Shared snow under load: one `snowpack server` (a separate process, as in
//! production) and many simulated peers on loopback, each a CPU snow window
//! ([`snowpack_testkit::testing::CpuSnow`]) walking and pressing a trail, linked
//! over renet2 exactly as `snowpack run --connect` is. Measures the server's
//! CPU time per second of world time, its peak memory, the bytes it sends
//! and receives, and its CPU time per merged tile. Needs no GPU.

use std::fmt::Write as _;
use std::io::{BufRead as _, BufReader};
use std::net::SocketAddr;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use snowpack::WorldIdentity;
use snowpack::low_level::{WorldIdentityExt, WorldSettings};
use snowpack_testkit::testing::CpuSnow;

use crate::net::SnowLink;

/// One load measurement.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShareRow {
    /// Simulated peers.
    pub peers: usize,
    /// Seconds of world time they walked (wall time on loopback).
    pub world_s: f64,
    /// The server's CPU time (user + system) over the whole run (s).
    pub server_cpu_s: f64,
    /// The server's peak resident memory (KiB).
    pub server_peak_kib: u64,
    /// Tiles the server merged that changed its copy.
    pub tiles_merged: u64,
    /// Tiles the server received.
    pub tiles_received: u64,
    /// Snowpack message bytes the server received.
    pub bytes_in: u64,
    /// Snowpack message bytes the server sent.
    pub bytes_out: u64,
    /// Snowpack message bytes one peer sent per second of walking (mean).
    pub peer_up_bytes_per_s: f64,
    /// A late joiner (a 64 m, 1024² window over the walkers' start) after
    /// the walk: bytes it received until in sync.
    pub late_join_bytes: u64,
    /// Tiles it received.
    pub late_join_tiles: u64,
    /// Seconds from its connection to in sync (welcome included).
    pub late_join_s: f64,
}

impl ShareRow {
    /// The server's CPU seconds per second of world time.
    pub fn cpu_per_world_s(&self) -> f64 {
        self.server_cpu_s / self.world_s.max(1e-9)
    }

    /// The server's CPU milliseconds per tile received (merged or not).
    pub fn cpu_ms_per_tile(&self) -> f64 {
        1e3 * self.server_cpu_s / (self.tiles_received.max(1) as f64)
    }
}

/// The world every simulated peer shares: 6.25 cm texels, 32² tiles, flat
/// ground, 0.5 m of snow refilling at 1 cm a minute.
fn world() -> WorldIdentity {
    WorldIdentity::from_settings(WorldSettings {
        texel_m: 0.0625,
        tile_side: crate::net::DEFAULT_TILE_SIDE,
        terrain: snowpack::low_level::replicate::terrain_identity(&snowpack::TerrainSource::Flat { height_m: 0.0 }),
        depth_m: 0.5,
        refill_m_per_s: 0.01 / 60.0,
        snowfall_m_per_s: 0.0,
        max_fallen_m: 0.0,
        has_snowfall: false,
        stamp_range_m: [-0.5, 1.5],
    })
}

/// A server started for a measurement: the process, its address, and the
/// rest of its output once it has stopped.
type Started = (std::process::Child, SocketAddr, std::sync::mpsc::Receiver<Vec<String>>);

/// Starts `snowpack server` (this executable) on loopback with a fresh
/// store; stops by itself after `limit_s`.
fn start_server(store: &std::path::Path, limit_s: f64) -> anyhow::Result<Started> {
    let exe = std::env::current_exe().context("this executable")?;
    let mut child = Command::new(exe)
        .args(["server", "--listen", "127.0.0.1:0", "--store"])
        .arg(store)
        .args(["--exit-after-s", &format!("{limit_s}")])
        .stdout(Stdio::piped())
        .spawn()
        .context("starting snowpack server")?;
    let stdout = child.stdout.take().context("the server's output")?;
    let mut lines = BufReader::new(stdout).lines();
    let first = lines.next().context("the server said nothing")??;
    let addr = first.split_whitespace().skip_while(|w| *w != "on").nth(1).and_then(|a| a.parse().ok()).context("no address in the server's first line")?;
    // The rest of its output comes back through the join handle.
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let all: Vec<String> = lines.map_while(Result::ok).collect();
        let _ = tx.send(all);
    });
    Ok((child, addr, rx))
}

/// A `key=value` field of the server's closing line.
fn field(line: &str, key: &str) -> Option<f64> {
    line.split_whitespace().find_map(|w| w.strip_prefix(key).and_then(|r| r.strip_prefix('='))).and_then(|v| v.parse().ok())
}

/// `peers` peers walk for `seconds` (at 1.4 m/s, each its own way out of a
/// ring 40 m across, pressing a 25 cm disc 20 cm deep, 30 updates a second).
pub fn measure_load(peers: usize, seconds: f64) -> anyhow::Result<ShareRow> {
    let store = std::env::temp_dir().join(format!("snowpack-bench-share-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&store);
    let (mut server, addr, output) = start_server(&store, seconds + 20.0)?;
    let world = world();
    let mut walkers = Vec::with_capacity(peers);
    for k in 0..peers {
        let angle = std::f64::consts::TAU * k as f64 / peers as f64;
        let start = [20.0 * angle.cos(), 20.0 * angle.sin()];
        let dir = [angle.cos(), angle.sin()];
        let link = SnowLink::connect(addr, None, world.clone(), &format!("walker-{k}"))?;
        walkers.push((link, CpuSnow::new(world.clone(), 128, [0, 0], 0.0), start, dir));
    }
    for (link, snow, ..) in &mut walkers {
        link.wait_welcomed(snow, Duration::from_secs(30))?;
    }
    let tick = 1.0 / 30.0;
    let begin = Instant::now();
    let mut t = 0.0;
    while t < seconds {
        for (link, snow, start, dir) in &mut walkers {
            let p = [start[0] + dir[0] * 1.4 * t, start[1] + dir[1] * 1.4 * t];
            snow.center_on(p[0], p[1]);
            snow.press_disc(p, 0.25, 2000);
            snow.step(tick);
            link.peer.set_deformers(&[p]);
            link.pump(snow)?;
        }
        t += tick;
        let ahead = Duration::from_secs_f64(t) - begin.elapsed().min(Duration::from_secs_f64(t));
        std::thread::sleep(ahead);
    }
    let walked = begin.elapsed().as_secs_f64();
    let up: u64 = walkers.iter().map(|(l, ..)| l.peer.stats().bytes_out).sum();
    drop(walkers);
    // A late joiner over the start of the 64 trails: a window full of them.
    let joined = Instant::now();
    let mut late = SnowLink::connect(addr, None, world.clone(), "late")?;
    let mut snow = CpuSnow::new(world.clone(), 1024, [-512, -512], 0.0);
    late.wait_welcomed(&mut snow, Duration::from_secs(30))?;
    while !late.peer.is_synced() {
        late.peer.request_digest();
        late.pump(&mut snow)?;
        anyhow::ensure!(joined.elapsed() < Duration::from_secs(60), "the late joiner was not in sync within a minute");
        std::thread::sleep(Duration::from_millis(2));
    }
    let late_join_s = joined.elapsed().as_secs_f64();
    let late_stats = late.peer.stats();
    drop(late);
    // The server stops by itself and prints its totals.
    let closing = stopped_server(&mut server, &output, seconds + 60.0)?;
    let _ = std::fs::remove_dir_all(&store);
    let get = |k: &str| field(&closing, k).with_context(|| format!("{k} in {closing:?}"));
    Ok(ShareRow {
        peers,
        world_s: walked,
        server_cpu_s: get("cpu_s")?,
        server_peak_kib: get("peak_kib")? as u64,
        tiles_merged: get("tiles_merged")? as u64,
        tiles_received: get("tiles_received")? as u64,
        bytes_in: get("bytes_in")? as u64,
        bytes_out: get("bytes_out")? as u64,
        peer_up_bytes_per_s: up as f64 / walked / peers.max(1) as f64,
        late_join_bytes: late_stats.bytes_in,
        late_join_tiles: late_stats.tiles_received,
        late_join_s,
    })
}

/// A car past a watcher, linked to one server: what each sent and received.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CarRow {
    /// Whether the car's presses travelled as frames (else as the tiles they pressed).
    pub presses: bool,
    /// Seconds of world time the car drove (the windows' own clock, paced
    /// to wall time when the machine keeps up).
    pub world_s: f64,
    /// Snowpack message bytes the car sent until in sync (`Presence`,
    /// digests and all).
    pub car_up_bytes: u64,
    /// Of them, the bytes of `Tiles` and `Presses` messages.
    pub car_snow_bytes: u64,
    /// Press frames the car sent.
    pub car_frames: u64,
    /// Tiles the car sent.
    pub car_tiles: u64,
    /// Snowpack message bytes the watcher received until in sync.
    pub watcher_down_bytes: u64,
    /// Press frames the watcher was passed and pressed.
    pub watcher_frames: u64,
    /// Tiles the watcher received (those its frames pressed included).
    pub watcher_tiles: u64,
    /// The server's CPU time over the whole run (s).
    pub server_cpu_s: f64,
}

/// The world of the car: 3.125 cm texels (a tread shows), 32² tiles, flat
/// ground, 0.5 m of snow.
fn car_world() -> WorldIdentity {
    let mut settings = world().settings().clone();
    settings.texel_m = 0.031_25;
    WorldIdentity::from_settings(settings)
}

/// A car (four treaded wheels at 3 m/s for 6 s, pressing as
/// [`snowpack_testkit::testing::car_wheels`]) drives past a watcher, both
/// CPU windows of 16 m linked to one `snowpack server`; its presses travel
/// as frames when `presses`, else as the tiles they pressed.
pub fn measure_car(presses: bool) -> anyhow::Result<CarRow> {
    use snowpack_testkit::testing::{car_wheels, drive};
    let store = std::env::temp_dir().join(format!("snowpack-bench-car-{}-{presses}", std::process::id()));
    let _ = std::fs::remove_dir_all(&store);
    let seconds = 8.0;
    let (mut server, addr, output) = start_server(&store, seconds + 30.0)?;
    let world = car_world();
    let mut links = Vec::new();
    for name in ["car", "watcher"] {
        let mut snow = CpuSnow::new(world.clone(), 512, [0, 0], 0.0);
        snow.center_on(0.0, 0.0);
        snow.set_reports_presses(presses);
        let mut link = SnowLink::connect(addr, None, world.clone(), name)?;
        link.wait_welcomed(&mut snow, Duration::from_secs(30))?;
        links.push((link, snow));
    }
    let tick = 1.0 / 30.0;
    let begin = Instant::now();
    let (mut t, mut last) = (0.0, drive(0.0));
    while t < seconds {
        t += tick;
        let now = drive(t);
        let (car, snow) = &mut links[0];
        let origin = snow.origin();
        snow.press_shapes(car_wheels(world.settings().texel_m, origin, now, Some(last)), (-0.5, 1.5), 3.0);
        car.peer.set_deformers(&[now.0]);
        last = now;
        for (link, snow) in &mut links {
            snow.step(tick);
            link.pump(snow)?;
        }
        let ahead = Duration::from_secs_f64(t) - begin.elapsed().min(Duration::from_secs_f64(t));
        std::thread::sleep(ahead);
    }
    let world_s = t;
    // Both in sync: the car's changes acknowledged, the watcher holding them.
    let settling = Instant::now();
    while !links.iter().all(|(l, _)| l.peer.is_synced()) {
        for (link, snow) in &mut links {
            link.peer.request_digest();
            link.pump(snow)?;
        }
        anyhow::ensure!(settling.elapsed() < Duration::from_secs(30), "the car and the watcher were not in sync within 30 s");
        std::thread::sleep(Duration::from_millis(2));
    }
    let (car, watcher) = (links[0].0.peer.stats(), links[1].0.peer.stats());
    drop(links);
    let closing = stopped_server(&mut server, &output, seconds + 60.0)?;
    let _ = std::fs::remove_dir_all(&store);
    Ok(CarRow {
        presses,
        world_s,
        car_up_bytes: car.bytes_out,
        car_snow_bytes: car.tile_bytes_out,
        car_frames: car.press_frames_sent,
        car_tiles: car.tiles_sent,
        watcher_down_bytes: watcher.bytes_in,
        watcher_frames: watcher.press_frames_received,
        watcher_tiles: watcher.tiles_received,
        server_cpu_s: field(&closing, "cpu_s").with_context(|| format!("cpu_s in {closing:?}"))?,
    })
}

/// Waits (at most `limit_s`) for a server started by [`start_server`] to
/// stop by itself; its closing line.
fn stopped_server(server: &mut std::process::Child, output: &std::sync::mpsc::Receiver<Vec<String>>, limit_s: f64) -> anyhow::Result<String> {
    let deadline = Instant::now() + Duration::from_secs_f64(limit_s);
    loop {
        if server.try_wait()?.is_some() {
            break;
        }
        if Instant::now() > deadline {
            let _ = server.kill();
            anyhow::bail!("the server did not stop");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let lines = output.recv_timeout(Duration::from_secs(5))?;
    lines.iter().rev().find(|l| l.contains("stopped")).cloned().context("the server's closing line")
}

/// The car's section of the report.
pub fn car_markdown(rows: &[CarRow]) -> String {
    let mut md = String::from(
        "\n## Shared snow: a car past a watcher\n\n_Measured on this machine's CPU (no GPU is involved); bytes do not depend on the machine._\n\n\
         A car of four treaded wheels (3 m/s for 6 s, 3.125 cm texels) and a watcher, CPU snow windows of 16 m linked to one `snowpack server` \
         on loopback, until both are in sync. Bytes are snowpack's messages; per second of the drive.\n\n\
         | the car's presses travel as | world s | car up: bytes, B/s | of it tiles and presses: bytes (frames, tiles) | watcher down: bytes, B/s | watcher pressed frames, tiles received | server CPU s |\n\
         |---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {:.1} | {}, {:.0} | {} ({}, {}) | {}, {:.0} | {}, {} | {:.2} |",
            if r.presses { "frames" } else { "tiles" },
            r.world_s,
            r.car_up_bytes,
            r.car_up_bytes as f64 / r.world_s,
            r.car_snow_bytes,
            r.car_frames,
            r.car_tiles,
            r.watcher_down_bytes,
            r.watcher_down_bytes as f64 / r.world_s,
            r.watcher_frames,
            r.watcher_tiles,
            r.server_cpu_s
        );
    }
    md
}

/// The report's section.
pub fn markdown(rows: &[ShareRow]) -> String {
    let mut md = String::from(
        "\n## Shared snow: one relay under load\n\n_Measured on this machine's CPU (no GPU is involved)._\n\n`snowpack server` in its own process, and simulated peers on loopback (CPU snow windows of 128², walking at \
         1.4 m/s and pressing a 25 cm disc, linked over renet2 like `snowpack run --connect`). CPU time and memory are the server process's \
         own; bytes are snowpack's messages (renet2 and netcode add their headers).\n\n\
         | peers | world s | server CPU s per world s | server peak memory | tiles received | merged | CPU ms per tile | server bytes in/s | server bytes out/s | bytes/s up per peer | late join: bytes, tiles, s |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {:.1} | {:.3} | {:.1} MiB | {} | {} | {:.3} | {:.0} | {:.0} | {:.0} | {:.0} KB, {}, {:.2} s |",
            r.peers,
            r.world_s,
            r.cpu_per_world_s(),
            r.server_peak_kib as f64 / 1024.0,
            r.tiles_received,
            r.tiles_merged,
            r.cpu_ms_per_tile(),
            r.bytes_in as f64 / r.world_s,
            r.bytes_out as f64 / r.world_s,
            r.peer_up_bytes_per_s,
            r.late_join_bytes as f64 / 1e3,
            r.late_join_tiles,
            r.late_join_s
        );
    }
    md
}
