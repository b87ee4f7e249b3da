//! `snowpack server` under attack, every party a process of its own on
//! 127.0.0.1: a server started with `--scene`, a hostile process
//! (`snowpack attack --role hostile`: another world's first `Hello`, forged
//! far tiles, teleporting deformers, the largest digests, window flips and
//! queries at the rate limits, a client that never reads, 48 more
//! connections) and one honest CPU peer (`--role honest`) pressing a
//! trail. Needs no GPU. Asserts the honest trail arrives whole, the forged
//! ones appear nowhere, and the server's memory and work per tick stay
//! under the bounds `docs/multiplayer.md` ("What the relay refuses") states.

use std::path::{Path, PathBuf};
use std::process::Output;
use std::time::Duration;

mod common;
use common::{Server, Temp, bin, run_bounded};

/// How long the server runs before it stops by itself and prints its totals.
const SERVER_S: u64 = 40;
/// The server's peak resident memory may not pass this (KiB) under the attack.
const PEAK_KIB_BOUND: u64 = 96 * 1024;

/// 8 m of `depth_m` snow at 6.25 cm on flat ground, no refill (tiles of 32², 2 m).
fn scene(dir: &Path, name: &str, depth_m: f32) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    let text = format!(
        "[snow]\nextent_m = 8.0\nresolution = 128\ndepth_m = {depth_m}\nrefill_m_per_s = 0.0\n\n[terrain]\nkind = \"flat\"\nheight_m = 0.0\n\n[window]\ncenter = [0.0, 0.0]\n\n[sim]\nframes = 10\ndt_s = 0.025\n"
    );
    std::fs::write(&path, text).expect("write the scene");
    path
}

fn text(out: &Output) -> String {
    format!("{}\n{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr))
}

/// `snowpack query` at `points` as a peer of `scene`'s world.
fn query(addr: std::net::SocketAddr, scene: &Path, points: &[[f64; 2]]) -> Output {
    let mut c = bin();
    c.args(["query", "--connect", &addr.to_string(), "--scene"]).arg(scene);
    for p in points {
        c.arg(format!("--at={},{}", p[0], p[1]));
    }
    run_bounded(c)
}

fn depths(out: &Output) -> Vec<f32> {
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.strip_prefix("depth_m ").and_then(|r| r.split_whitespace().nth(2)).and_then(|d| d.parse().ok()))
        .collect()
}

/// A `key=value` field of a line.
fn field(line: &str, key: &str) -> u64 {
    line.split_whitespace()
        .find_map(|w| w.strip_prefix(key).and_then(|r| r.strip_prefix('=')))
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or_else(|| panic!("no {key} in {line:?}")) as u64
}

#[test]
fn the_server_refuses_every_abuse_and_keeps_the_honest_trail() {
    let dir = Temp::new("server-attack");
    let world = scene(&dir.0, "world", 0.5);
    let other = scene(&dir.0, "other", 0.8);
    let server = Server::start_with(&dir.0.join("store"), Duration::from_secs(SERVER_S), &["--scene".as_ref(), world.as_os_str()]);

    // The first peer to connect is of another world: refused, exit 2, naming the difference.
    let first = query(server.addr, &other, &[[0.0, 0.0]]);
    assert_eq!(first.status.code(), Some(2), "{}", text(&first));
    assert!(text(&first).contains("snow depth (m): 0.8 here, 0.5 there"), "{}", text(&first));

    let attack = |role: &str, seconds: &str| {
        let mut c = bin();
        c.args(["attack", "--connect", &server.addr.to_string(), "--scene"]).arg(&world).args(["--role", role, "--seconds", seconds]);
        std::thread::spawn(move || run_bounded(c))
    };
    let hostile = attack("hostile", "12");
    let honest = attack("honest", "60");
    let (hostile, honest) = (hostile.join().expect("the hostile process"), honest.join().expect("the honest process"));
    assert!(hostile.status.success(), "{}", text(&hostile));
    assert!(honest.status.success(), "{}", text(&honest));
    assert!(text(&hostile).contains("stranger refused=\"snow depth (m): 0.8 here, 0.5 there\""), "{}", text(&hostile));

    // The honest trail (z = -1 m, x from -3 m to 3 m, pressed 0.4 m into 0.5 m) is whole.
    let trail: Vec<[f64; 2]> = (0..=10).map(|k| [-2.5 + 0.5 * f64::from(k), -1.0]).collect();
    let got = query(server.addr, &world, &trail);
    assert!(got.status.success(), "{}", text(&got));
    let d = depths(&got);
    assert_eq!(d.len(), trail.len(), "{}", text(&got));
    let shallow: Vec<String> = trail.iter().zip(&d).filter(|(_, depth)| (*depth - 0.1).abs() >= 0.01).map(|(p, depth)| format!("{p:?}: {depth} m")).collect();
    if !shallow.is_empty() {
        // Everything the parties said, the server's closing counters (its refusals) included.
        let lines = server.wait(Duration::from_secs(SERVER_S + 60));
        panic!("the honest trail is not 0.1 m deep at {shallow:?}\nhonest:\n{}\nhostile:\n{}\nserver:\n{}", text(&honest), text(&hostile), lines.join("\n"));
    }
    // The forged trails (where the forger pressed tiles and teleported to) are nowhere.
    let forged: Vec<[f64; 2]> = [[200.0, 200.0], [-150.0, 120.0]]
        .iter()
        .flat_map(|c: &[f64; 2]| (-2..=2).flat_map(move |i| (-2..=2).map(move |j| [c[0] + f64::from(i), c[1] + f64::from(j)])))
        .collect();
    let got = query(server.addr, &world, &forged);
    let d = depths(&got);
    assert_eq!(d.len(), forged.len(), "{}", text(&got));
    for (p, depth) in forged.iter().zip(&d) {
        assert!((depth - 0.5).abs() < 1e-4, "a forged trail at {p:?}: {depth} m");
    }

    let pid = server.pid();
    let lines = server.wait(Duration::from_secs(SERVER_S + 60));
    let closing = lines.iter().rev().find(|l| l.contains("stopped after")).unwrap_or_else(|| panic!("no closing line (pid {pid}):\n{}", lines.join("\n")));
    eprintln!("{closing}");
    let f = |k: &str| field(closing, k);
    // Memory.
    assert!(f("peak_kib") < PEAK_KIB_BOUND, "peak memory {} KiB over {PEAK_KIB_BOUND} KiB", f("peak_kib"));
    // Work: the police's distance tests are bounded by the bytes received
    // (at most 81 look-ups per 24-byte digest entry or per tile), over the
    // whole run and in the busiest tick.
    assert!(f("distance_tests") <= 4 * f("bytes_in"), "{closing}");
    assert!(f("max_tick_distance_tests") <= 4 * f("max_tick_bytes_in"), "{closing}");
    assert!(f("max_tick_window_keys") <= 4 * 16_384, "{closing}");
    // Fair ticks: the flooder's largest digests reached the per-client
    // budget (64 KiB a tick, the message crossing it taken whole), and no
    // client brought more than that plus one largest message into a tick;
    // the rest waited for the next one while the honest peer was served.
    assert!(f("peer_ticks_capped") >= 1, "{closing}");
    assert!(f("max_tick_peer_bytes_in") <= 64 * 1024 + 256 * 1024, "{closing}");
    // Every abuse was met.
    for key in [
        "refused_world",
        "refused_not_welcomed",
        "refused_far",
        "refused_teleports",
        "refused_rate_bytes",
        "refused_rate_window",
        "refused_rate_query",
        "refused_rate_presses",
    ] {
        assert!(f(key) >= 1, "{key} = 0: {closing}");
    }
    assert!(f("refused_world") >= 2, "the query and the stranger: {closing}");
}

/// A store keeps its world: the server started on it with another scene is
/// bad input naming the store and the scene key; with the same scene it starts.
#[test]
fn a_server_on_a_store_of_another_world_is_refused() {
    let dir = Temp::new("server-store-world");
    let store = dir.0.join("store");
    let world = scene(&dir.0, "world", 0.5);
    let other = scene(&dir.0, "other", 0.8);
    let serve = |scene: &Path| {
        let mut c = bin();
        c.args(["server", "--listen", "127.0.0.1:0", "--exit-after-s", "0.2", "--store"]).arg(&store).arg("--scene").arg(scene);
        run_bounded(c)
    };
    let made = serve(&world);
    assert!(made.status.success(), "{}", text(&made));
    let refused = serve(&other);
    assert_eq!(refused.status.code(), Some(2), "{}", text(&refused));
    let why = String::from_utf8_lossy(&refused.stderr);
    assert!(why.contains(&store.display().to_string()) && why.contains("[snow].depth_m") && why.contains("0.5 in the store, 0.8 in the scene"), "{why}");
    let again = serve(&world);
    assert!(again.status.success(), "{}", text(&again));
}

/// A server's store filled to its budget refuses new tiles and keeps the
/// old ones: a trail kept before the budget shrank is still there after a
/// restart with `--disk-budget 1`, a new trail is refused (counted), and the
/// store's tile files are the same ones.
#[test]
fn a_store_at_its_budget_refuses_new_tiles_and_keeps_the_old() {
    let dir = Temp::new("server-budget");
    let store = dir.0.join("store");
    let world = scene(&dir.0, "world", 0.5);
    let honest = |addr: std::net::SocketAddr, z: &str| {
        let mut c = bin();
        c.args(["attack", "--connect", &addr.to_string(), "--scene"]).arg(&world).args(["--role", "honest", "--seconds", "60", "--trail-z", z]);
        run_bounded(c)
    };
    let tiles = || {
        let mut files: Vec<PathBuf> = Vec::new();
        let mut stack = vec![store.join("tiles")];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
                if e.path().is_dir() {
                    stack.push(e.path());
                } else {
                    files.push(e.path());
                }
            }
        }
        files.sort();
        files
    };
    let server = Server::start_with(&store, Duration::from_secs(60), &["--scene".as_ref(), world.as_os_str()]);
    let first = honest(server.addr, "-1");
    assert!(first.status.success(), "{}", text(&first));
    server.kill();
    let kept = tiles();
    assert!(!kept.is_empty(), "the first trail was stored");

    let server =
        Server::start_with(&store, Duration::from_secs(SERVER_S / 2), &["--scene".as_ref(), world.as_os_str(), "--disk-budget".as_ref(), "1".as_ref()]);
    let second = honest(server.addr, "2");
    assert!(second.status.success(), "{}", text(&second));
    let points = [[-2.0, -1.0], [0.0, -1.0], [2.0, -1.0], [-2.0, 2.0], [0.0, 2.0], [2.0, 2.0]];
    let got = query(server.addr, &world, &points);
    let d = depths(&got);
    assert_eq!(d.len(), points.len(), "{}", text(&got));
    for (p, depth) in points.iter().zip(&d) {
        let want = if p[1] < 0.0 { 0.1 } else { 0.5 };
        assert!((depth - want).abs() < 0.01, "at {p:?}: {depth} m, not {want}");
    }
    let lines = server.wait(Duration::from_secs(SERVER_S + 60));
    let closing = lines.iter().rev().find(|l| l.contains("stopped after")).expect("the closing line");
    assert!(field(closing, "refused_disk_full") >= 1, "{closing}");
    assert_eq!(tiles(), kept, "the store's tiles changed");
}
