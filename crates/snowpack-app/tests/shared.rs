//! Shared snow between real processes on loopback: a `snowpack server`, a
//! headless run whose sphere ploughs a trail and exits, a second run that
//! joins later over the same place and must see that trail, a restart of the
//! server on the same store and a third run that still sees it. Every
//! process is bounded in time and killed if it overstays.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::Stdio;

mod common;
use common::{PROCESS_LIMIT, Server, Temp, bin, run_bounded};

fn gpu_available() -> bool {
    snowpack_testkit::testing::gpu().is_some()
}

/// The scene all three runs share: 8 m of 0.5 m snow at 6.25 cm, window
/// fixed at the origin, no refill; `actors` is the `[[actor]]` part.
fn scene(dir: &Path, name: &str, depth_m: f32, actors: &str) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    let text = format!(
        "[snow]\nextent_m = 8.0\nresolution = 128\ndepth_m = {depth_m}\nrefill_m_per_s = 0.0\n\n[terrain]\nkind = \"flat\"\nheight_m = 0.0\n\n[window]\ncenter = [0.0, 0.0]\n\n{actors}\n[sim]\nframes = 40\ndt_s = 0.025\n"
    );
    std::fs::write(&path, text).expect("write the scene");
    path
}

/// A sphere of radius 0.3 m ploughing along z = -1 from x = -3 to x = 3:
/// its bottom 0.1 m above the ground, so 0.4 m of the 0.5 m is pressed away.
const PLOUGH: &str = "[[actor]]\nkind = \"sphere\"\nradius_m = 0.3\npath = [[-3.0, 0.4, -1.0, 0.0], [3.0, 0.4, -1.0, 1.0]]\n";
/// A sphere resting far from the trail, so the joining runs press nothing near it.
const IDLE: &str = "[[actor]]\nkind = \"sphere\"\nradius_m = 0.2\nposition = [0.0, 2.0, 3.0]\n";

fn load_npy(path: &Path) -> Vec<f32> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    bytes[10 + len..].chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
}

/// The snow in a run's window at its end (kg, `meta.json`'s mass).
fn window_kg(out: &Path) -> f64 {
    let meta: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("meta.json")).expect("meta.json")).expect("valid JSON");
    meta["mass"]["window_kg"].as_f64().expect("the window's mass")
}

/// `snowpack query`'s `KEY X Z VALUE` lines for `key`, in order.
fn answers(out: &std::process::Output, key: &str) -> Vec<f32> {
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.strip_prefix(key).and_then(|r| r.strip_prefix(' ')).and_then(|r| r.split_whitespace().nth(2)).and_then(|d| d.parse().ok()))
        .collect()
}

fn run_connected(scene: &Path, out: &Path, addr: SocketAddr) -> std::process::Output {
    let mut cmd = bin();
    cmd.args(["run", "--headless", "--scene"]).arg(scene).arg("--out").arg(out).args(["--connect", &addr.to_string()]);
    run_bounded(cmd)
}

fn assert_ok(what: &str, out: &std::process::Output) {
    assert!(out.status.success(), "{what} failed ({}):\n{}\n{}", out.status, String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
}

/// Texel (i, j) of the 128² window at the origin: world x = -4 + (j + 0.5) / 16.
fn trail_texels() -> impl Iterator<Item = (usize, usize)> {
    // z = -1 is row 48; x from -2.5 to 2.5 (clear of the ends) is columns 24..104.
    (24..104).map(|j| (48, j))
}

#[test]
fn a_late_run_sees_the_first_runs_trail_and_so_does_one_after_a_server_restart() {
    if !gpu_available() {
        return;
    }
    let dir = Temp::new("shared-snow");
    let store = dir.0.join("world");
    let server = Server::start(&store, PROCESS_LIMIT);

    // The server maps no GPU library: it never opens a device.
    let maps = std::fs::read_to_string(format!("/proc/{}/maps", server.pid())).expect("the server's memory maps");
    for lib in ["libvulkan", "libEGL", "libGL", "libgbm", "lvp", "swrast", "libLLVM", "dri"] {
        assert!(!maps.contains(lib), "the server mapped {lib}:\n{}", maps.lines().filter(|l| l.contains(lib)).collect::<Vec<_>>().join("\n"));
    }

    let first = run_connected(&scene(&dir.0, "plough", 0.5, PLOUGH), &dir.0.join("a"), server.addr);
    assert_ok("the ploughing run", &first);
    let a = load_npy(&dir.0.join("a/snow.npy"));
    for (i, j) in trail_texels() {
        assert!((a[i * 128 + j] - 0.1).abs() < 0.01, "the plough's own trail at ({i}, {j}): {}", a[i * 128 + j]);
    }

    let second = run_connected(&scene(&dir.0, "join", 0.5, IDLE), &dir.0.join("b"), server.addr);
    assert_ok("the joining run", &second);
    let b = load_npy(&dir.0.join("b/snow.npy"));
    for (i, j) in trail_texels() {
        let (ha, hb) = (a[i * 128 + j], b[i * 128 + j]);
        assert!((ha - hb).abs() <= 1e-3, "the late run's snow at ({i}, {j}) is {hb}, the plough left {ha}");
    }
    // Away from the trail, open snow in both.
    for j in 0..128 {
        assert!((b[100 * 128 + j] - 0.5).abs() < 1e-3, "open snow at row 100: {}", b[100 * 128 + j]);
    }

    // The server answers depth queries from its tiles, to peers of its world.
    let query = run_bounded({
        let mut c = bin();
        c.args(["query", "--connect", &server.addr.to_string(), "--scene"]).arg(dir.0.join("join.toml")).args(["--at", "0.0,-1.0", "--at", "0.0,2.0"]);
        c
    });
    assert_ok("the query", &query);
    let depths = answers(&query, "depth_m");
    assert_eq!(depths.len(), 2, "{}", String::from_utf8_lossy(&query.stdout));
    assert!((depths[0] - 0.1).abs() < 0.01 && (depths[1] - 0.5).abs() < 1e-3, "server depths {depths:?}");
    // Snow with mass: the trail's 0.4 m went into 0.1 m of snow, about five
    // times as dense (at most the final density, 500 kg/m³; the point is
    // off the sphere's lowest texel), which the server knows from the
    // tiles' packed snow; the open snow is fresh.
    let (packed, density, hardness) = (answers(&query, "packed_m"), answers(&query, "density_kg_m3"), answers(&query, "hardness_kpa"));
    assert!((packed[0] - 0.4).abs() < 0.01 && packed[1] == 0.0, "server packed snow {packed:?}");
    assert!((450.0..=500.001).contains(&density[0]) && (density[1] - 100.0).abs() < 1e-3, "server densities {density:?}");
    assert!(hardness[0] > 5.0 * hardness[1], "the trail is not harder than open snow: {hardness:?}");
    // The late run holds the trail's mass: its window weighs what the
    // ploughing run's did (the packed snow came with the tiles).
    let (ma, mb) = (window_kg(&dir.0.join("a")), window_kg(&dir.0.join("b")));
    eprintln!("window mass: ploughing run {ma:.2} kg, late run {mb:.2} kg");
    assert!((ma - mb).abs() <= 1e-3 * ma, "the late run's window holds {mb:.2} kg, the ploughing run's {ma:.2} kg");

    // Killed at once (no chance to save): what it acknowledged is on disk.
    server.kill();
    let server = Server::start(&store, PROCESS_LIMIT);
    let third = run_connected(&scene(&dir.0, "again", 0.5, IDLE), &dir.0.join("c"), server.addr);
    assert_ok("the run after the restart", &third);
    let c = load_npy(&dir.0.join("c/snow.npy"));
    for (i, j) in trail_texels() {
        assert!((a[i * 128 + j] - c[i * 128 + j]).abs() <= 1e-3, "after the restart at ({i}, {j}): {} vs {}", c[i * 128 + j], a[i * 128 + j]);
    }
    // And the packed snow came back from the server's store.
    let mc = window_kg(&dir.0.join("c"));
    assert!((ma - mc).abs() <= 1e-3 * ma, "after the restart the window holds {mc:.2} kg, the ploughing run's {ma:.2} kg");

    // Another world (deeper snow) is refused, naming what differs, with exit code 2.
    let other = run_connected(&scene(&dir.0, "other", 0.8, IDLE), &dir.0.join("d"), server.addr);
    assert_eq!(other.status.code(), Some(2), "{}", String::from_utf8_lossy(&other.stderr));
    assert!(String::from_utf8_lossy(&other.stderr).contains("snow depth"), "{}", String::from_utf8_lossy(&other.stderr));
    assert!(!dir.0.join("d/snow.npy").exists(), "a refused run writes nothing");
}

/// `snowpack server --scene`: the world is the scene's. The first run to
/// connect, of another world, is refused with exit 2 naming the difference;
/// a run of the scene's world (found here on the GPU, there on the CPU) is
/// welcomed and its trail kept.
#[test]
fn a_server_with_a_scene_refuses_a_first_run_of_another_world() {
    if !gpu_available() {
        return;
    }
    let dir = Temp::new("shared-scene");
    let world = scene(&dir.0, "plough", 0.5, PLOUGH);
    let server = Server::start_with(&dir.0.join("world"), PROCESS_LIMIT, &["--scene".as_ref(), world.as_os_str()]);
    let other = run_connected(&scene(&dir.0, "other", 0.8, IDLE), &dir.0.join("o"), server.addr);
    assert_eq!(other.status.code(), Some(2), "{}", String::from_utf8_lossy(&other.stderr));
    assert!(String::from_utf8_lossy(&other.stderr).contains("snow depth (m): 0.8 here, 0.5 there"), "{}", String::from_utf8_lossy(&other.stderr));
    let run = run_connected(&world, &dir.0.join("a"), server.addr);
    assert_ok("the run of the scene's world", &run);
    let a = load_npy(&dir.0.join("a/snow.npy"));
    for (i, j) in trail_texels() {
        assert!((a[i * 128 + j] - 0.1).abs() < 0.01, "the trail at ({i}, {j}): {}", a[i * 128 + j]);
    }
}

#[test]
fn a_server_without_a_key_refuses_to_listen_beyond_loopback() {
    let dir = Temp::new("shared-open");
    let out = run_bounded({
        let mut c = bin();
        c.args(["server", "--listen", "0.0.0.0:0", "--store"]).arg(dir.0.join("s"));
        c
    });
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--key"), "{}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn a_run_that_cannot_reach_its_server_fails_with_exit_1() {
    if !gpu_available() {
        return;
    }
    let dir = Temp::new("shared-nobody");
    // A port nobody listens on: bound and dropped.
    let port = std::net::UdpSocket::bind("127.0.0.1:0").and_then(|s| s.local_addr()).expect("a free port");
    let out = run_connected(&scene(&dir.0, "alone", 0.5, IDLE), &dir.0.join("o"), port);
    assert_eq!(out.status.code(), Some(1), "{}", String::from_utf8_lossy(&out.stderr));
}

/// With `--key` the server listens beyond loopback and lets in only clients
/// with a connect token made from that key: a query with a token is
/// answered, one without fails (exit 1), a malformed key file is bad input.
#[test]
fn a_server_with_a_key_answers_only_clients_with_a_token() {
    let dir = Temp::new("shared-key");
    let key = dir.0.join("server.key");
    std::fs::write(&key, "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff\n").expect("a key file");
    let mut child = bin()
        .args(["server", "--listen", "127.0.0.1:0", "--store"])
        .arg(dir.0.join("world"))
        .arg("--key")
        .arg(&key)
        .args(["--exit-after-s", "60"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("start snowpack server");
    let mut first = String::new();
    let mut stdout = std::io::BufReader::new(child.stdout.take().expect("stdout"));
    std::io::BufRead::read_line(&mut stdout, &mut first).expect("the first line");
    let addr = first.split_whitespace().skip_while(|w| *w != "on").nth(1).expect("an address").to_owned();
    assert!(first.contains("connect tokens required"), "{first}");
    // The server's output is drained: a closed pipe must not matter, but a full one would block it.
    std::thread::spawn(move || std::io::copy(&mut stdout, &mut std::io::sink()));

    let token = dir.0.join("player.token");
    let made = run_bounded({
        let mut c = bin();
        c.args(["token", "--key"]).arg(&key).args(["--server", &addr, "--out"]).arg(&token);
        c
    });
    assert_ok("making a token", &made);
    let world = scene(&dir.0, "keyed", 0.5, IDLE);
    let with = run_bounded({
        let mut c = bin();
        c.args(["query", "--connect", &addr, "--token"]).arg(&token).arg("--scene").arg(&world).args(["--at", "1,2"]);
        c
    });
    assert_ok("a query with a token", &with);
    // The query's hello gave the server its world (no --scene): fresh snow there.
    assert!(String::from_utf8_lossy(&with.stdout).contains("depth_m 1 2 0.500000"), "{}", String::from_utf8_lossy(&with.stdout));
    let without = run_bounded({
        let mut c = bin();
        c.args(["query", "--connect", &addr, "--scene"]).arg(&world).args(["--at", "1,2"]);
        c
    });
    assert_eq!(without.status.code(), Some(1), "a query without a token: {}", String::from_utf8_lossy(&without.stderr));
    let _ = child.kill();
    let _ = child.wait();

    let bad = dir.0.join("bad.key");
    std::fs::write(&bad, "not a key").expect("a bad key file");
    let refused = run_bounded({
        let mut c = bin();
        c.args(["server", "--listen", "127.0.0.1:0", "--store"]).arg(dir.0.join("w2")).arg("--key").arg(&bad);
        c
    });
    assert_eq!(refused.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("bad.key"), "{}", String::from_utf8_lossy(&refused.stderr));
}

/// Two cars at once against one server, on parallel roads through one
/// window: each run is the other's watcher. Each car's presses travel as
/// its frames (no tile of theirs is sent), the server passes them on to
/// the other run, which presses them, and both windows end with both cars'
/// ruts, texel for texel. Each car drives for its first 2 s and then stands
/// for 8 s more (a frame at rest presses nothing and sends nothing), so
/// each run is connected while the other drives however their starts
/// differ on a busy machine.
#[test]
fn two_cars_at_once_press_each_others_frames_and_end_with_the_same_snow() {
    if !gpu_available() {
        return;
    }
    let dir = Temp::new("shared-cars");
    two_cars_at_once(&dir.0, "[terrain]\nkind = \"flat\"\n", (256, false));
}

/// The same over a heightmap (a 16-bit PNG of bumps up to 12 cm), which a
/// world's identity names by its digest alone: the server, started with
/// the scene (`--scene`), holds the heightmap, says so in its `Welcome`,
/// and presses the cars' frames over it as their windows did.
#[test]
fn over_a_heightmap_the_cars_frames_travel_when_the_server_has_the_scene() {
    if !gpu_available() {
        return;
    }
    let dir = Temp::new("shared-cars-heightmap");
    let side = 48u32;
    let map = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(side, side, |x, y| {
        let (u, v) = (x as f32 * 0.45, y as f32 * 0.6);
        image::Luma([((0.5 + 0.25 * u.sin() + 0.25 * v.cos()) * 65535.0) as u16])
    });
    map.save(dir.0.join("bumps.png")).expect("write the heightmap");
    let terrain = "[terrain]\nkind = \"heightmap\"\npath = \"bumps.png\"\nheight_scale_m = 0.12\nsize_m = [12.0, 12.0]\n";
    // At 6.25 cm texels: a quarter of the flat road's frame time.
    two_cars_at_once(&dir.0, terrain, (128, true));
    // The store keeps the heightmap with the world: a server started on it
    // without the scene (as the server-only build, which loads no PNG,
    // must be) presses there too.
    let again = Server::start(&dir.0.join("world"), PROCESS_LIMIT);
    assert!(again.first_line.contains("presses travel as frames"), "{}", again.first_line);
}

/// [`two_cars_at_once_press_each_others_frames_and_end_with_the_same_snow`]
/// over `terrain` (a scene's `[terrain]` table), in windows of
/// `resolution`², the server started with the first car's scene when
/// `server_scene`.
fn two_cars_at_once(dir: &Path, terrain: &str, (resolution, server_scene): (usize, bool)) {
    // 8 m of 0.3 m snow (3.125 cm texels at 256²); a car crosses the window in 2 s at z.
    let car = |name: &str, z: f32| {
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(
            &path,
            format!(
                "[snow]\nextent_m = 8.0\nresolution = {resolution}\ndepth_m = 0.3\nrefill_m_per_s = 0.0\n\n{terrain}\n[window]\ncenter = [0.0, 0.0]\n\n\
                 [[vehicle]]\nwheelbase_m = 2.6\ntrack_m = 1.55\nwheel_radius_m = 0.33\nwheel_width_m = 0.28\nmass_kg = 1800.0\ntread = \"blocks\"\n\
                 path = [[-3.0, {z}, 0.0], [3.0, {z}, 2.0]]\n\n[sim]\nframes = 300\ndt_s = 0.033333333\n"
            ),
        )
        .expect("write the scene");
        path
    };
    let scenes = [("a", car("a", -1.5)), ("b", car("b", 1.5))];
    let scene_option = [std::ffi::OsStr::new("--scene"), scenes[0].1.as_os_str()];
    let server = Server::start_with(&dir.join("world"), PROCESS_LIMIT, if server_scene { &scene_option } else { &[] });
    let runs: Vec<std::thread::JoinHandle<std::process::Output>> = scenes
        .iter()
        .map(|(name, path)| {
            let (path, out, addr) = (path.clone(), dir.join(name), server.addr);
            std::thread::spawn(move || run_connected(&path, &out, addr))
        })
        .collect();
    for (run, (name, _)) in runs.into_iter().zip(&scenes) {
        assert_ok(&format!("car {name}"), &run.join().expect("the run's thread"));
    }
    let share = |name: &str| -> serde_json::Value {
        let meta: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join(name).join("meta.json")).expect("meta.json")).expect("valid JSON");
        meta["share"].clone()
    };
    let (a, b) = (share("a"), share("b"));
    eprintln!("car a: {a}\ncar b: {b}");
    for s in [&a, &b] {
        let count = |key: &str| s[key].as_u64().unwrap_or(0);
        assert!(count("press_frames_sent") >= 30, "a car sends its presses as frames: {s}");
        assert!(count("tiles_as_presses") > 0 && count("tiles_sent") == 0, "its frames explain its tiles: {s}");
        assert!(count("press_frames_received") >= 30, "each presses the other's frames, passed on by the server: {s}");
    }
    let (sa, sb) = (load_npy(&dir.join("a/snow.npy")), load_npy(&dir.join("b/snow.npy")));
    let differ = sa.iter().zip(&sb).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
    let terrain_m = load_npy(&dir.join("a/terrain.npy"));
    // Both cars' ruts, in rows either side of the middle (z = 0): texels 1
    // cm or more below the rest surface; at least about a seventh of two
    // tyres' widths over 6 m (500 texels at 256²).
    let (n, half) = (resolution, resolution / 2);
    let rutted = |rows: std::ops::Range<usize>| rows.flat_map(|i| (0..n).map(move |j| i * n + j)).filter(|&k| sa[k] - terrain_m[k] < 0.29).count();
    let (first, second) = (rutted(0..half), rutted(half..n));
    let least = 500 * n * n / (256 * 256);
    assert!(first > least && second > least, "the cars left {first} and {second} texels more than 1 cm below the rest surface");
    assert_eq!(differ, 0, "{differ} of {} texels differ between the two cars' windows", sa.len());
}
