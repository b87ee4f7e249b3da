//! End-to-end tests of the interactive demo: the real binary opens a real
//! window on an X server (Xvfb, which `.ci/run` installs), renders with the
//! software adapter, follows a script of key and window events, and writes
//! screenshots of the window's own image.
//!
//! Without Xvfb these tests skip, unless `SNOWPACK_REQUIRE_GPU` is set (CI),
//! where a missing X server is a failure.

use std::io::{BufRead as _, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};

mod common;
use common::{Server, Temp};

/// A private X server for one test, stopped on drop.
struct Xvfb {
    child: Child,
    display: String,
}

impl Xvfb {
    fn start() -> Option<Self> {
        let spawned = Command::new("Xvfb")
            .args(["-displayfd", "1", "-screen", "0", "1024x768x24", "-nolisten", "tcp"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn();
        let mut child = match spawned {
            Ok(c) => c,
            Err(e) => {
                assert!(
                    !snowpack_testkit::testing::gpu_required(),
                    "SNOWPACK_REQUIRE_GPU is set but Xvfb cannot start ({e}); install it: apt-get install xvfb"
                );
                eprintln!("skipping the demo test: no Xvfb ({e})");
                return None;
            }
        };
        // Xvfb writes the display number it chose once it accepts connections.
        let mut line = String::new();
        let stdout = child.stdout.take().expect("piped stdout");
        BufReader::new(stdout).read_line(&mut line).expect("reading Xvfb's display number");
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

/// A small scene so a software rasteriser runs it quickly: 24 spheres dropped
/// on gentle hills, a 16 m window at 256², a 512² shadow map.
const SCENE: &str = r#"
[snow]
extent_m = 16.0
resolution = 256
depth_m = 0.5

[terrain]
kind = "noise"
seed = 5
amplitude_m = 0.5
wavelength_m = 12.0

[[spawn]]
kind = "sphere"
count = 24
radius_m = 0.4
seed = 9

[render]
shadow_map_size = 512

[camera]
position = [0.0, 7.0, -11.0]
target = [0.0, 0.0, 0.0]
"#;

struct DemoRun {
    stdout: String,
    stderr: String,
}

/// Runs the demo on a fresh X server with a script; fails the test on a non-zero exit.
fn run_demo(dir: &Path, frames: u32, script: &str, screenshot: Option<&str>) -> Option<DemoRun> {
    run_demo_scene(dir, SCENE, frames, script, screenshot)
}

/// [`run_demo`] with its own scene text.
fn run_demo_scene(dir: &Path, scene_text: &str, frames: u32, script: &str, screenshot: Option<&str>) -> Option<DemoRun> {
    let x = Xvfb::start()?;
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, scene_text).expect("scene");
    let script_path = dir.join("script.txt");
    std::fs::write(&script_path, script).expect("script");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_snowpack"));
    cmd.env("DISPLAY", &x.display)
        .env_remove("WAYLAND_DISPLAY")
        .env("SNOWPACK_LOG", "warn,snowpack=info")
        .args(["--scene".as_ref(), scene.as_os_str()])
        .args(["--script".as_ref(), script_path.as_os_str()])
        .args(["--exit-after-frames", &frames.to_string(), "--window-size", "480x300", "--no-vsync"]);
    if let Some(name) = screenshot {
        cmd.args(["--screenshot".as_ref(), dir.join(name).as_os_str()]);
    }
    let out = cmd.output().expect("running snowpack");
    let run = DemoRun { stdout: String::from_utf8_lossy(&out.stdout).into_owned(), stderr: String::from_utf8_lossy(&out.stderr).into_owned() };
    assert!(out.status.success(), "demo exited with {:?}\nstdout:\n{}\nstderr:\n{}", out.status.code(), run.stdout, run.stderr);
    assert!(!run.stderr.contains("panicked"), "a panic was reported:\n{}", run.stderr);
    Some(run)
}

fn load_rgb(path: &Path) -> (Vec<u8>, u32, u32) {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgb8();
    let (w, h) = img.dimensions();
    (img.into_raw(), w, h)
}

/// Standard deviation of luma: a blank (one-colour) image scores 0.
fn luma_spread(rgb: &[u8]) -> f64 {
    let luma: Vec<f64> = rgb.chunks_exact(3).map(|p| 0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2])).collect();
    let mean = luma.iter().sum::<f64>() / luma.len() as f64;
    (luma.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / luma.len() as f64).sqrt()
}

fn mean_abs_difference(a: &[u8], b: &[u8]) -> f64 {
    a.iter().zip(b).map(|(x, y)| f64::from(x.abs_diff(*y))).sum::<f64>() / a.len() as f64
}

/// The summary line the demo prints at exit: `demo: F frames, S spheres, N simulated ...`.
fn summary_number(stdout: &str, after: &str) -> u64 {
    let line = stdout.lines().find(|l| l.starts_with("demo: ")).unwrap_or_else(|| panic!("no summary in:\n{stdout}"));
    let words: Vec<&str> = line.split([' ', ',']).filter(|w| !w.is_empty()).collect();
    let k = words.iter().position(|w| *w == after).unwrap_or_else(|| panic!("no {after:?} in {line:?}"));
    words[k - 1].parse().unwrap_or_else(|_| panic!("no number before {after:?} in {line:?}"))
}

#[test]
fn the_demo_opens_a_window_runs_90_frames_and_screenshots_it() {
    let dir = Temp::new("demo-open");
    let Some(run) = run_demo(&dir.0, 90, "# no input\n", Some("shot.png")) else { return };
    assert_eq!(summary_number(&run.stdout, "frames"), 90, "{}", run.stdout);
    assert_eq!(summary_number(&run.stdout, "spheres"), 24, "{}", run.stdout);
    assert_eq!(summary_number(&run.stdout, "simulated"), 90, "{}", run.stdout);
    let (rgb, w, h) = load_rgb(&dir.0.join("shot.png"));
    // The window's physical size (480x300 logical at the X server's scale of 1).
    assert_eq!((w, h), (480, 300));
    let spread = luma_spread(&rgb);
    assert!(spread > 20.0, "the screenshot is nearly blank (luma spread {spread:.1})");
    // Snow: many bright pixels right of the panel; the panel: dark pixels on the left.
    let bright = rgb.chunks_exact(3).filter(|p| p.iter().all(|&c| c > 170)).count();
    assert!(bright > (w * h / 20) as usize, "only {bright} bright (snow) pixels");
    let dark_left = (0..h as usize).filter(|&y| rgb[(y * w as usize + 20) * 3] < 60).count();
    assert!(dark_left > h as usize / 2, "no panel on the left ({dark_left} dark rows)");
}

#[test]
fn a_scripted_technique_switch_and_reset_change_the_picture() {
    let dir = Temp::new("demo-switch");
    // Hide the panel so the comparison is of the snow; spheres settle, then
    // the technique switches to decals and the scene resets.
    let script = "0 key H\n40 screenshot before.png\n41 key Digit3\n42 key R\n";
    let Some(run) = run_demo(&dir.0, 70, script, Some("after.png")) else { return };
    assert!(run.stdout.contains("technique decals"), "the switch did not happen:\n{}", run.stdout);
    // The reset at the start of frame 42 restarted the simulation: frames 42..=69 since.
    assert_eq!(summary_number(&run.stdout, "simulated"), 28, "{}", run.stdout);
    assert!(run.stderr.contains("reset: fresh snow, 24 spheres"), "{}", run.stderr);
    let (before, ..) = load_rgb(&dir.0.join("before.png"));
    let (after, ..) = load_rgb(&dir.0.join("after.png"));
    assert!(luma_spread(&before) > 10.0 && luma_spread(&after) > 10.0, "a blank screenshot");
    let diff = mean_abs_difference(&before, &after);
    assert!(diff > 2.0, "the picture barely changed after the switch and reset ({diff:.2}/255)");
}

#[test]
fn minimise_restore_and_a_1x1_window_do_not_crash() {
    let dir = Temp::new("demo-resize");
    let script = "10 resize 1 1\n20 resize 480 300\n25 minimize\n40 restore\n";
    let Some(run) = run_demo(&dir.0, 60, script, Some("shot.png")) else { return };
    // Every frame ran, minimised ones included (the simulation does not stop).
    assert_eq!(summary_number(&run.stdout, "frames"), 60, "{}", run.stdout);
    assert_eq!(summary_number(&run.stdout, "simulated"), 60, "{}", run.stdout);
    let (rgb, w, h) = load_rgb(&dir.0.join("shot.png"));
    assert_eq!((w, h), (480, 300), "the window did not come back to its size");
    assert!(luma_spread(&rgb) > 20.0, "blank after restore");
}

/// Bad demo options are bad input (exit code 2, a message naming the problem),
/// found before any window or GPU is touched.
#[test]
fn bad_demo_options_exit_2_before_opening_anything() {
    let dir = Temp::new("demo-bad");
    let script = dir.0.join("bad.txt");
    std::fs::write(&script, "5 key R\n7 jump 3\n").expect("script");
    let run = |args: &[&std::ffi::OsStr], display: Option<&str>| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_snowpack"));
        cmd.env_remove("WAYLAND_DISPLAY").env_remove("DISPLAY").args(args);
        if let Some(d) = display {
            // A display nobody serves: the checks must come before connecting.
            cmd.env("DISPLAY", d);
        }
        let out = cmd.output().expect("running snowpack");
        (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
    };
    let (code, err) = run(&["demo".as_ref(), "--script".as_ref(), script.as_os_str()], Some(":9999"));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("bad.txt: line 2") && err.contains("jump"), "{err}");
    let (code, err) = run(&["demo".as_ref(), "--screenshot".as_ref(), "x.png".as_ref()], Some(":9999"));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--exit-after-frames"), "{err}");
    let (code, err) = run(&["--exit-after-frames".as_ref(), "5".as_ref()], None);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("display"), "{err}");
}

/// The number after `at` in the summary: the player's x and z (m).
fn summary_position(stdout: &str) -> (f64, f64) {
    let line = stdout.lines().find(|l| l.starts_with("demo: ")).unwrap_or_else(|| panic!("no summary in:\n{stdout}"));
    let rest = &line[line.find(" at ").unwrap_or_else(|| panic!("no position in {line:?}")) + 4..];
    let mut words = rest.split(' ');
    let mut number = || words.next().and_then(|w| w.parse::<f64>().ok()).unwrap_or_else(|| panic!("no position in {line:?}"));
    (number(), number())
}

#[test]
fn the_player_drives_the_fox_and_it_leaves_footsteps() {
    let dir = Temp::new("demo-fox");
    // F: the fox; Tab twice: the follow camera, where W walks the fox forward for 2 s.
    let script = "0 key H\n1 key F\n2 key Tab\n3 key Tab\n5 screenshot before.png\n6 key_down KeyW\n126 key_up KeyW\n";
    let Some(run) = run_demo(&dir.0, 130, script, Some("after.png")) else { return };
    assert!(run.stderr.contains("player: fox"), "{}", run.stderr);
    assert!(run.stdout.contains("player fox"), "{}", run.stdout);
    // 2 s at 1 m/s: the fox walked about 2 m, from the window's centre.
    let (x, z) = summary_position(&run.stdout);
    let walked = x.hypot(z);
    assert!((1.2..3.0).contains(&walked), "the fox is {walked:.2} m from the start, at ({x:.2}, {z:.2})");
    // Three or so steps of each paw (the walk cycle is 0.71 s at 0.91 m/s).
    let steps = summary_number(&run.stdout, "footsteps");
    assert!((6..=16).contains(&steps), "{steps} footsteps in 2 m");
    let (before, ..) = load_rgb(&dir.0.join("before.png"));
    let (after, ..) = load_rgb(&dir.0.join("after.png"));
    let diff = mean_abs_difference(&before, &after);
    assert!(diff > 1.0, "the picture barely changed while the fox walked ({diff:.2}/255)");
}

#[test]
fn the_player_walks_out_of_the_window_and_the_tile_store_keeps_the_snow() {
    let dir = Temp::new("demo-store");
    let scene = format!("{SCENE}\n[store]\npath = \"store\"\ntile_texels = 64\n");
    // Tab twice: the follow camera (the window follows the player), then W for 2 s at 4 m/s.
    let script = "0 key H\n1 key Tab\n2 key Tab\n4 key_down KeyW\n124 key_up KeyW\n";
    let Some(run) = run_demo_scene(&dir.0, &scene, 128, script, None) else { return };
    let line = run.stdout.lines().find(|l| l.starts_with("tile store: ")).unwrap_or_else(|| panic!("no tile store summary:\n{}", run.stdout));
    let evicted: u64 =
        line.split(", ").find_map(|w| w.strip_suffix(" evicted")).and_then(|n| n.parse().ok()).unwrap_or_else(|| panic!("no evicted count: {line}"));
    assert!(evicted > 0, "walking 8 m (two tiles) out of a 16 m window evicted no tile: {line}");
    assert!(line.contains(", 0 errors"), "{line}");
    // [store] save defaults to true: the snow was saved on the way out.
    assert!(dir.0.join("store").join("save.commit").exists(), "no save (window state and generation) in the store folder");
    assert!(run.stdout.contains("saved the snow into"), "{}", run.stdout);
}

#[test]
fn g_turns_the_grass_shell_on_and_it_changes_the_picture() {
    let dir = Temp::new("demo-shell");
    // Close over the snow, so the shell fills the view.
    let scene = SCENE.replace("position = [0.0, 7.0, -11.0]\ntarget = [0.0, 0.0, 0.0]", "position = [0.3, 0.9, -1.6]\ntarget = [0.0, 0.3, 0.6]");
    assert_ne!(scene, SCENE);
    let script = "0 key H\n3 screenshot bare.png\n4 key G\n9 screenshot grass.png\n";
    let Some(run) = run_demo_scene(&dir.0, &scene, 10, script, None) else { return };
    assert!(run.stdout.contains("shell detail on"), "{}", run.stdout);
    let line = run.stdout.lines().find(|l| l.starts_with("shell: ")).unwrap_or_else(|| panic!("no shell summary:\n{}", run.stdout));
    assert!(line.contains(" tetrahedra, pixels per peeling pass ["), "{line}");
    let (bare, _, _) = load_rgb(&dir.0.join("bare.png"));
    let (grass, _, _) = load_rgb(&dir.0.join("grass.png"));
    let diff = mean_abs_difference(&bare, &grass);
    assert!(diff > 5.0, "the grass barely changed the picture (mean difference {diff:.2})");
}

/// The GPU device lost mid-run (the script destroys it, as a driver reset
/// would): the demo says so and exits with an error naming the loss, without
/// a panic or a hang.
#[test]
fn a_lost_device_is_reported_and_the_demo_exits_with_an_error() {
    let dir = Temp::new("demo-lost");
    let Some(x) = Xvfb::start() else { return };
    let scene = dir.0.join("scene.toml");
    std::fs::write(&scene, SCENE).expect("scene");
    let script = dir.0.join("script.txt");
    std::fs::write(&script, "5 lose-device\n").expect("script");
    let out = Command::new(env!("CARGO_BIN_EXE_snowpack"))
        .env("DISPLAY", &x.display)
        .env_remove("WAYLAND_DISPLAY")
        .env("SNOWPACK_LOG", "warn,snowpack=info")
        .args(["--scene".as_ref(), scene.as_os_str(), "--script".as_ref(), script.as_os_str()])
        .args(["--exit-after-frames", "20", "--window-size", "320x200", "--no-vsync"])
        .output()
        .expect("running snowpack");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "the demo exited {:?} after losing its device:\n{stderr}", out.status.code());
    assert!(stderr.contains("device was lost"), "no word of the lost device:\n{stderr}");
    assert!(!stderr.contains("panicked"), "a panic was reported:\n{stderr}");
}

/// The demo joins a shared world: its spheres' trails reach the server,
/// which keeps them in its store (a tile file each) and answers for them.
#[test]
fn the_demo_with_connect_sends_its_trails_to_a_server() {
    let dir = Temp::new("demo-connect");
    let Some(x) = Xvfb::start() else { return };
    let store = dir.0.join("world");
    let server = Server::start(&store, std::time::Duration::from_secs(300));
    let scene = dir.0.join("scene.toml");
    std::fs::write(&scene, SCENE).expect("scene");
    let out = Command::new(env!("CARGO_BIN_EXE_snowpack"))
        .env("DISPLAY", &x.display)
        .env_remove("WAYLAND_DISPLAY")
        .env("SNOWPACK_LOG", "warn")
        .args(["--scene".as_ref(), scene.as_os_str()])
        .args(["--exit-after-frames", "120", "--window-size", "480x300", "--no-vsync", "--connect", &server.addr.to_string()])
        .output()
        .expect("running snowpack");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "demo exited with {:?}\n{stderr}", out.status.code());
    assert!(!stderr.contains("shared snow"), "the link failed: {stderr}");
    // The spheres fell and rolled: their tiles are on the server's disk.
    let tiles = walk_files(&store.join("tiles"));
    assert!(tiles.iter().any(|p| p.extension().is_some_and(|e| e == "tile")), "no tile reached the server's store: {tiles:?}");
}

/// Every file under `dir`, recursively (none if it does not exist).
fn walk_files(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let path = entry.path();
        if path.is_dir() { out.extend(walk_files(&path)) } else { out.push(path) }
    }
    out
}
