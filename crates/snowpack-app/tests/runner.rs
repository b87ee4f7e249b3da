//! Scene-level tests: the `snowpack` binary runs scenes headless and the
//! physics is checked on its `.npy` outputs.

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::Temp;

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_snowpack"));
    c.env("SNOWPACK_LOG", "error");
    c
}

fn gpu_available() -> bool {
    snowpack_testkit::testing::gpu().is_some()
}

struct Grid {
    res: usize,
    data: Vec<f32>,
}

impl Grid {
    fn load(path: &Path) -> Self {
        let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!(&bytes[..6], b"\x93NUMPY");
        let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        let header = std::str::from_utf8(&bytes[10..10 + len]).expect("ascii header");
        assert!(header.contains("'descr': '<f4'") && header.contains("'fortran_order': False"), "{header}");
        let data: Vec<f32> = bytes[10 + len..].chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
        let res = (data.len() as f64).sqrt() as usize;
        assert_eq!(res * res, data.len());
        assert!(header.contains(&format!("'shape': ({res}, {res})")), "{header}");
        Self { res, data }
    }

    fn at(&self, i: usize, j: usize) -> f32 {
        self.data[i * self.res + j]
    }
}

struct Run {
    _dir: Temp,
    out: PathBuf,
    meta: serde_json::Value,
}

impl Run {
    fn grid(&self, name: &str) -> Grid {
        Grid::load(&self.out.join(name))
    }

    /// World (x, z) of texel (i, j)'s centre.
    fn world(&self, i: usize, j: usize) -> (f64, f64) {
        let o = &self.meta["origin_m"];
        let t = self.meta["texel_m"].as_f64().expect("texel_m");
        (o[0].as_f64().expect("x") + (j as f64 + 0.5) * t, o[1].as_f64().expect("z") + (i as f64 + 0.5) * t)
    }
}

fn run_scene(name: &str, toml: &str, extra: &[&str]) -> Run {
    let dir = Temp::new(name);
    let scene = dir.0.join("scene.toml");
    std::fs::write(&scene, toml).expect("write scene");
    let out = dir.0.join("out");
    let output = bin().args(["run", "--headless", "--scene"]).arg(&scene).arg("--out").arg(&out).args(extra).output().expect("run snowpack");
    assert!(output.status.success(), "snowpack run failed: {}\n{}", String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    let meta: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("meta.json")).expect("meta.json")).expect("valid JSON");
    Run { _dir: dir, out, meta }
}

#[test]
fn still_sphere_leaves_exactly_its_lower_surface() {
    if !gpu_available() {
        return;
    }
    // Sphere of radius 0.5 m whose bottom is 0.3 m below the 0.5 m snow surface (terrain at 0).
    let run = run_scene(
        "still",
        r#"
[snow]
extent_m = 8.0
resolution = 256
depth_m = 0.5
blur = true
[terrain]
kind = "flat"
height_m = 0.0
[window]
center = [0.3, -0.2]
[[actor]]
kind = "sphere"
radius_m = 0.5
position = [0.3, 0.7, -0.2]
[sim]
frames = 5
"#,
        &[],
    );
    let snow = run.grid("snow.npy");
    let terrain = run.grid("terrain.npy");
    let (mut inside, mut outside) = (0, 0);
    for i in 0..snow.res {
        for j in 0..snow.res {
            let (x, z) = run.world(i, j);
            let d2 = (x - 0.3).powi(2) + (z + 0.2).powi(2);
            let h = snow.at(i, j);
            assert!(terrain.at(i, j).abs() < 1e-6);
            if d2 < 0.25 {
                let bottom = (0.7 - (0.25 - d2).sqrt()) as f32;
                let expected = bottom.min(0.5);
                assert!((h - expected).abs() < 0.02, "inside footprint at ({x:.3}, {z:.3}): {h} vs {expected}");
                inside += 1;
            } else {
                assert!((h - 0.5).abs() < 0.002, "outside footprint at ({x:.3}, {z:.3}): {h}");
                outside += 1;
            }
        }
    }
    // The footprint is where the sphere dips below 0.5 m: radius sqrt(0.25 - 0.04) = 0.458 m.
    let deepest = snow.data.iter().copied().fold(f32::INFINITY, f32::min);
    assert!((deepest - 0.2).abs() < 0.005, "deepest point {deepest}, expected 0.2");
    // Footprint of radius 0.458 m at 3.125 cm texels: about 680 texels.
    assert!(inside > 600 && outside > 60_000, "inside {inside}, outside {outside}");
    let surface = run.grid("surface.npy");
    assert!(surface.data.iter().all(|v| v.is_finite()));
    assert_eq!(run.meta["resolution"], 256);
    assert_eq!(run.meta["technique"], "depth");
    assert!(run.out.join("frame.png").exists());
}

#[test]
fn dragged_sphere_leaves_a_groove_at_its_world_position_while_the_window_follows() {
    if !gpu_available() {
        return;
    }
    // The sphere moves 12 m along +x in a 16 m window that follows it, so the
    // window slides and exposes fresh snow ahead.
    let run = run_scene(
        "drag",
        r#"
[snow]
extent_m = 16.0
resolution = 256
depth_m = 0.5
elevation = 0.0
[terrain]
kind = "flat"
height_m = 1.0
[window]
follow = "actor:0"
[[actor]]
kind = "sphere"
radius_m = 0.4
path = [[-6.0, 1.6, 2.0, 0.0], [6.0, 1.6, 2.0, 2.0]]
[sim]
frames = 150
dt_s = 0.016666667
"#,
        &[],
    );
    let snow = run.grid("snow.npy");
    let origin_x = run.meta["origin_m"][0].as_f64().expect("origin");
    // The window followed the sphere: at the end it is centred near x = 6.
    assert!((origin_x + 8.0 - 6.0).abs() < 0.2, "window origin x {origin_x}");
    // Sphere bottom is at 1.2; snow rest height 1.5; the groove along z = 2
    // from x = -2 (window's left edge) to x = 6 is 0.3 m deep at its centre.
    for i in 0..snow.res {
        for j in 0..snow.res {
            let (x, z) = run.world(i, j);
            let h = snow.at(i, j);
            assert!((1.0..=1.5 + 1e-6).contains(&h), "({x}, {z}): {h} outside terrain..rest");
            let dz = (z - 2.0).abs();
            if x < 5.5 && dz < 0.05 {
                assert!((h - 1.2).abs() < 0.02, "groove centre at ({x:.2}, {z:.2}) is {h}");
            }
            if dz > 0.45 {
                // Everything away from the groove, including the newly exposed strips, is fresh.
                assert!((h - 1.5).abs() < 1e-5, "fresh snow expected at ({x:.2}, {z:.2}), got {h}");
            }
        }
    }
}

#[test]
fn refill_raises_a_trail_at_the_rate_and_never_above_rest() {
    if !gpu_available() {
        return;
    }
    // A box presses a trench to the terrain for 0.5 s and is lifted away; the
    // trench then refills at 0.1 m/s. After 120 frames at 1/60 s (2 s): the
    // pressed snow (at terrain, 0.0) has refilled for 1.5 s - one frame ->
    // 0.15 m - 0.1/60; snow elsewhere stays at rest (0.4).
    let run = run_scene(
        "refill",
        r#"
[snow]
extent_m = 8.0
resolution = 128
depth_m = 0.4
refill_m_per_s = 0.1
[terrain]
kind = "flat"
[window]
center = [0.0, 0.0]
[[actor]]
kind = "box"
size_m = [2.0, 1.0, 2.0]
path = [[0.0, 0.4, 0.0, 0.0], [0.0, 0.4, 0.0, 0.5], [0.0, 5.0, 0.0, 0.51]]
[sim]
frames = 120
dt_s = 0.016666667
"#,
        &[],
    );
    let snow = run.grid("snow.npy");
    let c = snow.res / 2;
    let trail = snow.at(c, c);
    // Frames 0..=30 have the box at t <= 0.5 s (pressing to 0); frames 31..119
    // refill: 89 frames of 0.1/60 m.
    let expected = 89.0 * 0.1 / 60.0;
    assert!((trail - expected).abs() < 2e-3, "trail {trail}, expected {expected}");
    let max = snow.data.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    assert!(max <= 0.4 + 1e-6, "snow above rest height: {max}");
    assert!((snow.at(2, 2) - 0.4).abs() < 1e-6);

    // Refill for long enough and the trail is back at (not above) rest height.
    let run = run_scene(
        "refill-long",
        r#"
[snow]
extent_m = 8.0
resolution = 64
depth_m = 0.4
refill_m_per_s = 0.5
[terrain]
kind = "flat"
[[actor]]
kind = "box"
size_m = [2.0, 1.0, 2.0]
path = [[0.0, 0.4, 0.0, 0.0], [0.0, 0.4, 0.0, 0.1], [0.0, 5.0, 0.0, 0.11]]
[sim]
frames = 120
"#,
        &[],
    );
    let snow = run.grid("snow.npy");
    assert!(snow.data.iter().all(|h| (h - 0.4).abs() < 1e-6), "trail did not refill exactly to rest");
}

#[test]
fn two_thousand_bouncing_spheres_keep_snow_between_terrain_and_rest() {
    if !gpu_available() {
        return;
    }
    let run = run_scene(
        "testbed",
        r#"
[snow]
extent_m = 64.0
resolution = 256
depth_m = 0.5
refill_m_per_s = 0.01
[terrain]
kind = "noise"
seed = 11
amplitude_m = 3.0
wavelength_m = 24.0
[[spawn]]
kind = "sphere"
count = 2000
radius_m = 0.4
seed = 7
[sim]
frames = 400
"#,
        &[],
    );
    let snow = run.grid("snow.npy");
    let terrain = run.grid("terrain.npy");
    let surface = run.grid("surface.npy");
    let mut pressed = 0;
    for k in 0..snow.data.len() {
        let (h, t) = (snow.data[k], terrain.data[k]);
        assert!(h.is_finite() && t.is_finite() && surface.data[k].is_finite());
        assert!(h >= t - 1e-5, "snow {h} below terrain {t} at {k}");
        assert!(h <= t + 0.5 + 1e-4, "snow {h} above rest {} at {k}", t + 0.5);
        if h < t + 0.45 {
            pressed += 1;
        }
    }
    // The spheres did deform the snow (the test would pass vacuously otherwise).
    assert!(pressed > snow.data.len() / 100, "only {pressed} texels pressed");
}

fn expect_bad_input(name: &str, toml: &str, must_mention: &str) {
    let dir = Temp::new(name);
    let scene = dir.0.join(format!("{name}.toml"));
    std::fs::write(&scene, toml).expect("write scene");
    let out = dir.0.join("out");
    let output = bin().args(["run", "--headless", "--scene"]).arg(&scene).arg("--out").arg(&out).output().expect("run");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{name}: expected exit 2, got {:?}: {stderr}", output.status);
    assert!(stderr.contains(&format!("{name}.toml")), "{name}: message does not name the file: {stderr}");
    assert!(stderr.contains(must_mention), "{name}: message does not mention {must_mention:?}: {stderr}");
    assert!(!stderr.contains("panicked"), "{name}: panic: {stderr}");
    assert!(!out.join("snow.npy").exists(), "{name}: output written despite the error");
}

#[test]
fn bad_scene_values_exit_2_naming_file_and_key() {
    let cases: &[(&str, &str, &str)] = &[
        ("zero-resolution", "[snow]\nresolution = 0\n", "resolution"),
        ("huge-resolution", "[snow]\nresolution = 1000000\n", "resolution"),
        ("negative-radius", "[[actor]]\nkind = \"sphere\"\nradius_m = -1.0\n", "radius_m"),
        ("unknown-key", "[snow]\nbogus_key = 1\n", "bogus_key"),
        ("wrong-type", "[snow]\ndepth_m = \"deep\"\n", "depth_m"),
        ("unknown-technique", "[snow]\ntechnique = \"magic\"\n", "technique"),
        ("missing-heightmap", "[terrain]\nkind = \"heightmap\"\npath = \"nowhere.png\"\n", "nowhere.png"),
        ("nan-depth", "[snow]\ndepth_m = nan\n", "depth_m"),
        ("malformed", "[snow\nresolution = 64\n", "malformed"),
        ("missing-mesh", "[terrain]\nkind = \"mesh\"\npath = \"nowhere.glb\"\n", "nowhere.glb"),
        // The scene file itself is not glTF.
        ("malformed-mesh", "[terrain]\nkind = \"mesh\"\npath = \"malformed-mesh.toml\"\n", "not valid glTF"),
    ];
    for (name, toml, key) in cases {
        expect_bad_input(name, toml, key);
    }
    // A scene file that does not exist.
    let output = bin().args(["check-scene", "/nonexistent/scene.toml"]).output().expect("run");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("/nonexistent/scene.toml"), "{stderr}");
}

#[test]
fn check_scene_prints_what_it_understood() {
    let dir = Temp::new("check");
    let scene = dir.0.join("ok.toml");
    std::fs::write(&scene, "[snow]\nresolution = 512\ndepth_m = 0.3\n[[actor]]\nkind = \"sphere\"\nradius_m = 0.7\n").expect("write");
    let output = bin().arg("check-scene").arg(&scene).output().expect("run");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{stdout}{}", String::from_utf8_lossy(&output.stderr));
    assert!(stdout.contains("512") && stdout.contains("0.3") && stdout.contains("0.7"), "{stdout}");
}

#[test]
fn mesh_terrain_is_drawn_from_above_and_carries_the_snow() {
    if !gpu_available() {
        return;
    }
    // scenes/assets/mound.gltf: y = 2.5 exp(-((x-10)^2 + (z+6)^2) / 120) + 0.04 x on a
    // 48x48-cell grid over 64 m, and a terrace whose top is at 1.5 m over
    // x in [-20, -8], z in [4, 16] with vertical walls down to -1 m.
    let gltf = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/assets/mound.gltf");
    let toml = format!(
        "[snow]\nextent_m = 32.0\nresolution = 256\ndepth_m = 0.5\n\
         [terrain]\nkind = \"mesh\"\npath = {:?}\n\
         [window]\ncenter = [-8.0, 6.0]\n\
         [[actor]]\nkind = \"sphere\"\nradius_m = 0.4\nposition = [-14.0, 2.1, 10.0]\n\
         [sim]\nframes = 3\n",
        gltf.display().to_string()
    );
    let run = run_scene("mesh-terrain", &toml, &[]);
    let terrain = run.grid("terrain.npy");
    let snow = run.grid("snow.npy");
    let mound = |x: f64, z: f64| 2.5 * (-((x - 10.0).powi(2) + (z + 6.0).powi(2)) / 120.0).exp() + 0.04 * x;
    let (mut on_terrace, mut on_mound) = (0, 0);
    for i in 0..terrain.res {
        for j in 0..terrain.res {
            let (x, z) = run.world(i, j);
            let t = f64::from(terrain.at(i, j));
            if (-19.8..=-8.2).contains(&x) && (4.2..=15.8).contains(&z) {
                assert!((t - 1.5).abs() < 1e-3, "terrace top at ({x}, {z}) is {t} m");
                on_terrace += 1;
            } else if !(-20.3..=-7.7).contains(&x) || !(3.7..=16.3).contains(&z) {
                // Linear triangles over a curved mound: within 3 cm of the formula.
                assert!((t - mound(x, z)).abs() < 0.03, "ground at ({x}, {z}) is {t} m, formula {}", mound(x, z));
                on_mound += 1;
            }
            let dist = ((x + 14.0).powi(2) + (z - 10.0).powi(2)).sqrt();
            if dist > 0.6 {
                let s = f64::from(snow.at(i, j));
                assert!((s - t - 0.5).abs() < 1e-4, "fresh snow at ({x}, {z}): {s} over terrain {t}");
            }
        }
    }
    assert!(on_terrace > 5000 && on_mound > 30000, "{on_terrace} terrace and {on_mound} ground texels checked");
    // The sphere on the terrace presses to its lowest point, 1.7 m.
    let texel = run.meta["texel_m"].as_f64().expect("texel");
    let o = &run.meta["origin_m"];
    let j = ((-14.0 - o[0].as_f64().expect("x")) / texel) as usize;
    let i = ((10.0 - o[1].as_f64().expect("z")) / texel) as usize;
    let lowest = (0..2).flat_map(|di| (0..2).map(move |dj| (i + di - 1, j + dj - 1))).map(|(a, b)| snow.at(a, b)).fold(f32::INFINITY, f32::min);
    assert!((lowest - 1.7).abs() < 0.01, "print on the terrace at {lowest} m, want 1.7 m");
}

#[test]
fn one_point_presses_a_quadratic_footprint_with_rims() {
    if !gpu_available() {
        return;
    }
    // A foot 0.3 m deep in 0.5 m of snow on flat ground; 6.25 cm texels,
    // a 64-texel (4 m) footprint square.
    let toml = "[snow]\nextent_m = 16.0\nresolution = 256\ndepth_m = 0.5\ntechnique = \"points\"\nrange_texels = 64\nelevation = 1.0\n\
                [[actor]]\nkind = \"point\"\nposition = [0.03125, 0.2, 0.03125]\nscale_per_m = 1.5\n[sim]\nframes = 2\n";
    let run = run_scene("one-point", toml, &[]);
    let snow = run.grid("snow.npy");
    let surface = run.grid("surface.npy");
    let (mut xs, mut ys) = (Vec::new(), Vec::new());
    let mut deepest = f32::INFINITY;
    for i in 0..snow.res {
        for j in 0..snow.res {
            let (x, z) = run.world(i, j);
            let d2 = (x - 0.03125).powi(2) + (z - 0.03125).powi(2);
            let h = snow.at(i, j);
            deepest = deepest.min(h);
            // The square spans 32 texels (2 m) either side of the point's texel.
            let inside = (x - 0.03125).abs() < 2.0 && (z - 0.03125).abs() < 2.0;
            if !inside {
                assert!((h - 0.5).abs() < 1e-6, "snow beyond the range at ({x}, {z}): {h}");
                assert!((surface.at(i, j) - 0.5).abs() < 1e-6, "surface beyond the range at ({x}, {z})");
            }
            if h < 0.49 {
                xs.push(d2);
                ys.push(f64::from(h));
            }
        }
    }
    // At the contact the snow is the foot height (to the 16-bit quantum, ~0.1 mm here).
    assert!((deepest - 0.2).abs() < 1e-3, "depth at the contact {deepest}, foot 0.2");
    // h = a + b d^2: a least-squares fit must explain the profile.
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    let b = sxy / sxx;
    let a = my - b * mx;
    let ss_res: f64 = xs.iter().zip(&ys).map(|(x, y)| (y - a - b * x).powi(2)).sum();
    let ss_tot: f64 = ys.iter().map(|y| (y - my).powi(2)).sum();
    let r2 = 1.0 - ss_res / ss_tot;
    assert!(n > 100.0 && r2 > 0.97, "quadratic fit R^2 {r2} over {n} texels");
    assert!((b - 1.5).abs() < 0.05 && (a - 0.2).abs() < 0.005, "fit h = {a} + {b} d^2, want 0.2 + 1.5 d^2");
    let top = surface.data.iter().fold(f32::NEG_INFINITY, |m, v| m.max(*v));
    assert!(top > 0.51, "no rim above the rest height: highest surface {top}");
}

const PRESS_SCENE: &str = "[snow]\nextent_m = 16.0\nresolution = 128\ndepth_m = 0.5\nblur = false\n\
    [[actor]]\nkind = \"sphere\"\nradius_m = 0.5\npath = [[-5.0, 0.65, 1.0, 0.0], [5.0, 0.55, -1.0, 1.5]]\n\
    [[actor]]\nkind = \"box\"\nsize_m = [1.0, 1.0, 3.0]\nrotation_deg = [0.0, 30.0, 0.0]\nposition = [3.0, 0.7, 4.0]\n\
    [sim]\nframes = 100\n";

#[test]
fn decals_leave_the_snow_unchanged() {
    if !gpu_available() {
        return;
    }
    let run = run_scene("decals", PRESS_SCENE, &["--technique", "decals"]);
    let snow = run.grid("snow.npy");
    let terrain = run.grid("terrain.npy");
    for (s, t) in snow.data.iter().zip(&terrain.data) {
        assert!((s - t - 0.5).abs() < 1e-6, "decals changed the snow: {s} over {t}");
    }
    assert_eq!(run.meta["technique"], "decals");
    // The same scene with depth does press the snow, so the check above is not vacuous.
    let depth = run_scene("decals-control", PRESS_SCENE, &["--technique", "depth"]);
    assert!(depth.grid("snow.npy").data.iter().any(|s| *s < 0.3));
}

#[test]
fn combined_is_the_lower_of_depth_and_points() {
    if !gpu_available() {
        return;
    }
    let depth = run_scene("tech-depth", PRESS_SCENE, &["--technique", "depth"]).grid("snow.npy");
    let points = run_scene("tech-points", PRESS_SCENE, &["--technique", "points"]).grid("snow.npy");
    let combined = run_scene("tech-combined", PRESS_SCENE, &["--technique", "combined"]).grid("snow.npy");
    let mut differs = 0;
    for k in 0..combined.data.len() {
        let want = depth.data[k].min(points.data[k]);
        assert!((combined.data[k] - want).abs() < 1e-6, "texel {k}: combined {} vs min({}, {})", combined.data[k], depth.data[k], points.data[k]);
        differs += usize::from((depth.data[k] - points.data[k]).abs() > 1e-3);
    }
    // The two techniques disagree somewhere (the box, the sphere's flanks), so the min is a real test.
    assert!(differs > 100, "depth and points agree almost everywhere ({differs} texels differ)");
}

/// Prints of one side of a character's trail: 4-connected groups of pressed
/// texels, merged along x when closer than `merge_m` (a front and a hind paw
/// landing together), as (x_min, x_max) in metres.
fn prints_along_x(run: &Run, pressed: &[bool], side: impl Fn(f64) -> bool, merge_m: f64) -> Vec<(f64, f64)> {
    let res = run.meta["resolution"].as_u64().expect("resolution") as usize;
    let mut seen = vec![false; pressed.len()];
    let mut spans = Vec::new();
    for start in 0..pressed.len() {
        if !pressed[start] || seen[start] || !side(run.world(start / res, start % res).1) {
            continue;
        }
        let (mut lo, mut hi, mut stack) = (f64::MAX, f64::MIN, vec![start]);
        seen[start] = true;
        while let Some(k) = stack.pop() {
            let (x, _) = run.world(k / res, k % res);
            (lo, hi) = (lo.min(x), hi.max(x));
            let (i, j) = (k / res, k % res);
            for (di, dj) in [(0i64, 1i64), (0, -1), (1, 0), (-1, 0)] {
                let (ni, nj) = (i as i64 + di, j as i64 + dj);
                if ni < 0 || nj < 0 || ni >= res as i64 || nj >= res as i64 {
                    continue;
                }
                let n = ni as usize * res + nj as usize;
                if pressed[n] && !seen[n] {
                    seen[n] = true;
                    stack.push(n);
                }
            }
        }
        spans.push((lo, hi));
    }
    spans.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut merged: Vec<(f64, f64)> = Vec::new();
    for s in spans {
        match merged.last_mut() {
            Some(last) if s.0 - last.1 < merge_m => last.1 = last.1.max(s.1),
            _ => merged.push(s),
        }
    }
    merged
}

#[test]
fn the_fox_leaves_separate_paw_prints_along_its_whole_path() {
    if !gpu_available() {
        return;
    }
    let fox = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/Fox.glb");
    // 8 m at the walk's own pace (1 m/s) over 4 cm of snow: paws lift ~11 cm, so they print, not plough.
    let scene = format!(
        r#"
[snow]
extent_m = 12.0
resolution = 512
depth_m = 0.04
[[actor]]
kind = "gltf"
file = "{}"
animation = "Walk"
scale = 0.01
path = [[-4.0, 0.0, 0.0, 0.0], [4.0, 0.0, 0.0, 8.0]]
[sim]
frames = 470
"#,
        fox.display()
    );
    let run = run_scene("fox-walk", &scene, &["--size", "64x36"]);
    let snow = run.grid("snow.npy");
    let pressed: Vec<bool> = snow.data.iter().map(|h| 0.04 - h > 0.005).collect();
    let res = snow.res;
    let mut count = 0;
    for (k, _) in pressed.iter().enumerate().filter(|(_, p)| **p) {
        let (x, z) = run.world(k / res, k % res);
        assert!(z.abs() < 0.25 && (-4.6..4.6).contains(&x), "a print at ({x:.2}, {z:.2}), away from the path along z = 0");
        count += 1;
    }
    assert!(count > 100, "only {count} pressed texels");
    // Walking time over the clip's length: the steps each foot took (the first stance included).
    let walked_s = 470.0 / 60.0;
    let steps = (walked_s / 0.708_333_f64).ceil() as usize;
    for (name, side) in [("left", -1.0), ("right", 1.0)] {
        // Prints closer than 8 cm are one: swept paws (issue 21) press their
        // landing and lift-off slides, so the gaps between steps are 12-17 cm.
        let prints = prints_along_x(&run, &pressed, |z| z * side > 0.0, 0.08);
        let summary: Vec<String> = prints.iter().map(|p| format!("{:.2}..{:.2}", p.0, p.1)).collect();
        assert!(prints.len().abs_diff(steps) <= 1, "{name} side: {} prints for {steps} steps: {summary:?}", prints.len());
        assert!(prints.iter().all(|p| p.1 - p.0 < 0.6), "{name} side: a print longer than 0.6 m (a groove, not prints): {summary:?}");
        // Along the whole path: every metre from the start to the end has a print.
        for m in -4..3 {
            let (a, b) = (f64::from(m), f64::from(m) + 1.0);
            assert!(prints.iter().any(|p| p.1 > a && p.0 < b), "{name} side: no print between x = {a} and {b}: {summary:?}");
        }
    }

    // Footstep events: once per touchdown per foot (no event for the first
    // stance), each where a print is.
    let events: serde_json::Value = serde_json::from_slice(&std::fs::read(run.out.join("footsteps.json")).expect("footsteps.json")).expect("JSON");
    let events = events.as_array().expect("a list");
    let mut per_foot: std::collections::BTreeMap<String, usize> = std::collections::BTreeMap::new();
    for e in events {
        *per_foot.entry(e["name"].as_str().expect("name").to_owned()).or_default() += 1;
        let p = &e["position"];
        let (x, z) = (p[0].as_f64().expect("x"), p[2].as_f64().expect("z"));
        let near = pressed.iter().enumerate().any(|(k, &on)| {
            let (px, pz) = run.world(k / res, k % res);
            on && (px - x).hypot(pz - z) < 0.06
        });
        assert!(near, "footstep of {} at ({x:.2}, {z:.2}) has no print within 6 cm", e["name"]);
        let depth = e["snow_depth_m"].as_f64().expect("a snow depth from the CPU query");
        assert!((0.0..=0.0401).contains(&depth), "snow depth {depth} at a footstep");
    }
    let touchdowns = (walked_s / 0.708_333_f64) as usize;
    assert_eq!(per_foot.len(), 4, "feet: {per_foot:?}");
    for (foot, n) in &per_foot {
        assert!(n.abs_diff(touchdowns) <= 1, "{foot}: {n} footsteps for {touchdowns} touchdowns");
    }
}

#[test]
fn bad_gltf_actors_name_the_file_and_key() {
    let dir = Temp::new("fox-bad");
    let fox = std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/Fox.glb")).expect("fox");
    std::fs::write(dir.0.join("cut.glb"), &fox[..fox.len() / 2]).expect("write");
    std::fs::write(dir.0.join("fox.glb"), &fox).expect("write");
    // A glTF with meshes but no skin: the mound terrain.
    let mound = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/assets/mound.gltf");
    let unskinned = format!("file = {:?}", mound.display().to_string());
    for (actor, key, words) in [
        ("file = \"cut.glb\"", "[[actor]][0].file", "cut.glb"),
        ("file = \"fox.glb\"\nanimation = \"Dance\"", "[[actor]][0].animation", "Dance"),
        ("file = \"missing.glb\"", "[[actor]][0].file", "missing.glb"),
        (unskinned.as_str(), "[[actor]][0].file", "skin"),
        ("file = \"fox.glb\"\ngaits = [\"Walk\", \"Fly\"]", "[[actor]][0].gaits", "Fly"),
        ("file = \"builtin:fox\"\nplacement = \"air\"", "[[actor]][0].placement", "air"),
        ("file = \"builtin:fox\"\nmass_kg = -6", "[[actor]][0].mass_kg", "-6"),
    ] {
        let scene = dir.0.join("scene.toml");
        std::fs::write(&scene, format!("[[actor]]\nkind = \"gltf\"\n{actor}\n")).expect("scene");
        let out = bin().args(["run", "--scene"]).arg(&scene).arg("--out").arg(dir.0.join("out")).output().expect("run");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{actor}: {err}");
        assert!(err.contains(key) && err.contains(words), "{actor}: {err}");
        assert!(!dir.0.join("out").exists(), "{actor}: output written for a bad scene");
    }
}

/// A fox on 0.2 m of snow of `hardness` kPa, walking 3 m at 0.9 m/s and
/// running 4.8 m at 2.4 m/s, placed on the snow by the load model.
fn fox_on_snow(name: &str, hardness: f32, extra: &[&str]) -> (Run, Vec<serde_json::Value>) {
    let scene = format!(
        r#"
[snow]
extent_m = 12.0
resolution = 512
depth_m = 0.2
hardness_kpa = {hardness}
[[actor]]
kind = "gltf"
file = "builtin:fox"
animation = "Survey"
gaits = ["Walk", "Run"]
scale = 0.01
placement = "snow"
path = [[-5.0, 0.0, 0.0, 0.0], [-2.3, 0.0, 0.0, 3.0], [2.5, 0.0, 0.0, 5.0], [5.0, 0.0, 0.0, 6.05]]
[sim]
frames = 355
"#
    );
    let run = run_scene(name, &scene, &[&["--size", "64x36"], extra].concat());
    let events: serde_json::Value = serde_json::from_slice(&std::fs::read(run.out.join("footsteps.json")).expect("footsteps.json")).expect("JSON");
    let events = events.as_array().expect("a list").clone();
    (run, events)
}

/// The value of `grid` at the texel whose centre is nearest world (x, z).
fn nearest(run: &Run, grid: &Grid, (x, z): (f64, f64)) -> f32 {
    let k = grid.data.iter().enumerate().min_by(|a, b| {
        let (pa, pb) = (run.world(a.0 / grid.res, a.0 % grid.res), run.world(b.0 / grid.res, b.0 % grid.res));
        (pa.0 - x).hypot(pa.1 - z).total_cmp(&(pb.0 - x).hypot(pb.1 - z))
    });
    *k.expect("a texel").1
}

/// The lowest snow of `snow` (a grid of `run`) within `radius_m` of (x, z).
fn lowest_within(run: &Run, snow: &Grid, (x, z): (f64, f64), radius_m: f64) -> f32 {
    snow.data
        .iter()
        .enumerate()
        .filter(|(k, _)| {
            let (px, pz) = run.world(k / snow.res, k % snow.res);
            (px - x).hypot(pz - z) < radius_m
        })
        .map(|(_, h)| *h)
        .fold(f32::MAX, f32::min)
}

/// Depth of the print at each footstep (rest less the lowest snow within
/// 5 cm) beside the load model's sinkage there and whether the fox was running.
fn prints_at_footsteps(run: &Run, events: &[serde_json::Value], depth: f32) -> Vec<(f32, f32, bool)> {
    let snow = run.grid("snow.npy");
    events
        .iter()
        .filter(|e| e["time_s"].as_f64().expect("time") < 6.0)
        .map(|e| {
            let p = &e["position"];
            let (x, z) = (p[0].as_f64().expect("x"), p[2].as_f64().expect("z"));
            let lowest = lowest_within(run, &snow, (x, z), 0.05);
            let running = e["speed_m_per_s"].as_f64().expect("speed") > 2.0;
            (depth - lowest, e["sink_m"].as_f64().expect("sink_m") as f32, running)
        })
        .collect()
}

#[test]
fn a_fox_on_the_snow_sinks_as_deep_as_its_load_model_says() {
    if !gpu_available() {
        return;
    }
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len().max(1) as f32;
    let mut by_hardness = Vec::new();
    for hardness in [5.0f32, 30.0] {
        let (run, events) = fox_on_snow(&format!("fox-sink-{hardness}"), hardness, &[]);
        let prints = prints_at_footsteps(&run, &events, 0.2);
        assert!(prints.len() >= 16, "{hardness} kPa: {} footsteps", prints.len());
        // 6 kg on 35 cm² paws: 4.2 kPa with four paws down, 16.8 with one.
        let load = snowpack::low_level::skin::sinking::FootLoad::default();
        let snow = snowpack::SnowParams { hardness_kpa: hardness, ..snowpack::SnowParams::default() }.mechanics();
        let fresh = snowpack::mechanics::SnowColumn::fresh(0.2);
        let (least, most) = (load.sinkage_m(4.0, &snow, fresh), load.sinkage_m(1.0, &snow, fresh));
        for (print, sink, _) in &prints {
            assert!(
                (least - 0.02..most + 0.025).contains(print),
                "{hardness} kPa: a print {print:.3} m deep; the model allows {least:.3}..{most:.3} (sink {sink:.3} at touchdown)"
            );
        }
        let error = mean(&prints.iter().map(|(p, s, _)| (p - s).abs()).collect::<Vec<_>>());
        assert!(error < 0.02, "{hardness} kPa: prints differ from the model's sinkage by {error:.3} m on average: {prints:?}");
        let walk = mean(&prints.iter().filter(|p| !p.2).map(|p| p.0).collect::<Vec<_>>());
        let run_ = mean(&prints.iter().filter(|p| p.2).map(|p| p.0).collect::<Vec<_>>());
        // Running puts the weight on fewer paws at once: deeper prints.
        assert!(run_ > walk + 0.005, "{hardness} kPa: running prints {run_:.3} m, walking {walk:.3} m");
        // Never through the snow to the ground.
        let snow = run.grid("snow.npy");
        assert!(snow.data.iter().all(|h| *h > 0.01), "{hardness} kPa: a paw reached the ground");
        by_hardness.push(mean(&prints.iter().map(|p| p.0).collect::<Vec<_>>()));
    }
    assert!(by_hardness[0] > by_hardness[1] + 0.05, "soft snow prints {:.3} m, hard {:.3} m", by_hardness[0], by_hardness[1]);
}

/// Snow with mass (`docs/mechanics.md`): a second fox walking the first
/// one's path 3 s behind it steps into packed prints, which hold the load
/// that made them, and deepens the first fox's trail far less than the
/// first fox's own steps did. Prints the table of both (mean print depth
/// at the first fox's footsteps, alone and with the second behind it).
#[test]
fn a_second_fox_in_the_first_ones_trail_sinks_less() {
    if !gpu_available() {
        return;
    }
    let fox = |path: &str| {
        format!(
            "[[actor]]\nkind = \"gltf\"\nfile = \"builtin:fox\"\nanimation = \"Survey\"\ngaits = [\"Walk\", \"Run\"]\nscale = 0.01\nplacement = \"snow\"\npath = {path}\n"
        )
    };
    let first = fox("[[-4.0, 0.0, 0.0, 0.0], [3.0, 0.0, 0.0, 7.5]]");
    let second = fox("[[-4.0, 0.0, 0.0, 3.0], [3.0, 0.0, 0.0, 10.5]]");
    let scene =
        |actors: &str| format!("[snow]\nextent_m = 12.0\nresolution = 384\ndepth_m = 0.5\n[window]\ncenter = [0.0, 0.0]\n\n{actors}[sim]\nframes = 640\n");
    let alone = run_scene("first-fox", &scene(&first), &["--size", "64x36"]);
    let both = run_scene("second-fox", &scene(&format!("{first}{second}")), &["--size", "64x36"]);
    let events: serde_json::Value = serde_json::from_slice(&std::fs::read(alone.out.join("footsteps.json")).expect("footsteps.json")).expect("JSON");
    // The first fox's footsteps on the way (not standing at the ends).
    let steps: Vec<(f64, f64)> = events
        .as_array()
        .expect("a list")
        .iter()
        .filter(|e| e["speed_m_per_s"].as_f64().is_some_and(|v| v > 0.5) && e["position"][0].as_f64().is_some_and(|x| (-3.0..2.5).contains(&x)))
        .map(|e| (e["position"][0].as_f64().expect("x"), e["position"][2].as_f64().expect("z")))
        .collect();
    let print_depth = |run: &Run, (x, z): (f64, f64)| -> f64 { 0.5 - f64::from(lowest_within(run, &run.grid("snow.npy"), (x, z), 0.03)) };
    let (first_walk, second_walk): (Vec<f64>, Vec<f64>) = steps
        .iter()
        .map(|&p| {
            let (a, b) = (print_depth(&alone, p), print_depth(&both, p));
            (a, b - a)
        })
        .unzip();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    eprintln!("| at the first fox's {} footsteps | mean depth |", steps.len());
    eprintln!("|---|---|");
    eprintln!("| the first fox's print (fresh snow, {} kg/m³) | {:.1} cm |", 100, 100.0 * mean(&first_walk));
    eprintln!("| what the second fox, 3 s behind, added | {:.1} cm |", 100.0 * mean(&second_walk));
    assert!(steps.len() >= 10, "{} footsteps", steps.len());
    assert!(mean(&first_walk) > 0.03, "the first fox's prints are {:.3} m deep", mean(&first_walk));
    assert!(
        mean(&second_walk) < 0.5 * mean(&first_walk),
        "the second fox deepened the prints by {:.3} m, the first made them {:.3} m deep",
        mean(&second_walk),
        mean(&first_walk)
    );
    // Packed, not removed: no paw went through to the ground.
    assert!(both.grid("snow.npy").data.iter().all(|h| *h > 0.05), "a paw went through the packed snow to the ground");
}

/// The plough scene with snowfall (issue 43): the blade scrapes its cut to
/// the ground, the windrow beside the cut rises well above the snow, the
/// windrow holds what the cut lost, and the window's mass is the start plus
/// the snowfall (`meta.json` "mass"), within 0.5 %.
#[test]
fn a_plough_pushes_its_cut_into_a_windrow_and_the_mass_stays() {
    if !gpu_available() {
        return;
    }
    let plough = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/plough.toml")).expect("scenes/plough.toml");
    // max_m above the windrow: snowfall stops on lying snow deeper than it (docs/mechanics.md).
    let scene = format!("{plough}\n[snowfall]\nrate_m_per_s = 0.002\nmax_m = 3.0\n");
    let run = run_scene("plough", &scene, &["--size", "64x36"]);
    let (extent, fallen) = (run.meta["extent_m"].as_f64().expect("extent"), run.meta["fallen_m"].as_f64().expect("fallen"));
    let (depth, density) = (0.4, 100.0);
    let expected = density * extent * extent * (depth + fallen);
    let mass = &run.meta["mass"];
    let (window, displaced) = (mass["window_kg"].as_f64().expect("window_kg"), mass["displaced_kg"].as_f64().expect("displaced_kg"));
    eprintln!(
        "plough: window {window:.1} kg, displaced (gone) {displaced:.1} kg, start + snowfall {expected:.1} kg ({:+.3} %)",
        100.0 * (window / expected - 1.0)
    );
    assert!(fallen > 0.01, "snowfall so far {fallen} m");
    assert!((window / expected - 1.0).abs() < 0.005, "window {window} kg against {expected} kg");
    // The ledger counted it: the snowfall on every texel, and a window
    // that holds what the counts add up to.
    let (snowfall, ledger) = (mass["snowfall_kg"].as_f64().expect("snowfall_kg"), mass["ledger_kg"].as_f64().expect("ledger_kg"));
    let fell = density * extent * extent * fallen;
    eprintln!("plough: ledger {ledger:.1} kg, snowfall counted {snowfall:.2} kg of {fell:.2} kg");
    assert!((snowfall / fell - 1.0).abs() < 0.005, "snowfall counted {snowfall} kg, {fell} kg fell");
    assert!((window / ledger - 1.0).abs() < 5e-4, "window {window} kg, ledger {ledger} kg");
    let snow = run.grid("snow.npy");
    let rest = (depth + fallen) as f32;
    let at = |x: f64, z: f64| nearest(&run, &snow, (x, z));
    // The cut along the blade's path (edge at z = -1.5, 2.5 m wide turned 30
    // degrees: z -2.6 to -0.4, the windrow's foot and the near wall at its sides).
    for x in [-4.0, -1.0, 2.0] {
        for z in [-1.5, -1.2, -0.95] {
            let h = at(x, z);
            assert!(h < 0.06, "the cut at ({x}, {z}) holds {h} m of snow");
        }
    }
    // The windrow beside it, on the side the blade turns snow off.
    for x in [-4.0, -1.0, 2.0] {
        let top = (0..24).map(|k| at(x, -2.2 - 0.06 * f64::from(k))).fold(0.0f32, f32::max);
        assert!(top > rest + 0.4, "the windrow at x = {x} tops at {top} m over {rest} m of snow");
    }
    // What the cut lost, the windrow and the pile ahead of the blade hold.
    let above: f64 = snow.data.iter().map(|&h| f64::from((h - rest).max(0.0))).sum();
    let below: f64 = snow.data.iter().map(|&h| f64::from((rest - h).max(0.0))).sum();
    eprintln!("plough: above the snow {above:.1}, below it {below:.1} (texel metres), {:.1} %", 100.0 * above / below);
    assert!(below > 1000.0 && (above / below - 1.0).abs() < 0.02, "berms {above} against the cut's {below} texel metres");
}

/// Berms persist (issue 43): a blade cuts a windrow, the window follows a
/// marker 300 m away and back (the tiles keep the lying snow, as they keep
/// snowfall), and the cut and the windrow are there again.
#[test]
fn a_windrow_comes_back_with_its_tiles_after_the_window_went_away() {
    if !gpu_available() {
        return;
    }
    let scene = "[snow]\nextent_m = 16.0\nresolution = 256\ndepth_m = 0.4\ndisplace = true\nrepose_deg = 38.0\n\
        [terrain]\nkind = \"flat\"\n[window]\nfollow = \"actor:1\"\n\
        [[actor]]\nkind = \"blade\"\nwidth_m = 2.0\nheight_m = 0.9\nangle_deg = 30.0\npath = [[-4.0, -0.02, 0.0, 0.0], [4.0, -0.02, 0.0, 4.0], [30.0, -0.02, 300.0, 4.5]]\n\
        [[actor]]\nkind = \"sphere\"\nradius_m = 0.1\npath = [[0.0, 5.0, 0.0, 0.0], [0.0, 5.0, 0.0, 5.0], [300.0, 5.0, 0.0, 6.0], [300.0, 5.0, 0.0, 7.0], [0.0, 5.0, 0.0, 8.0]]\n\
        [sim]\nframes = 600\n";
    let run = run_scene("windrow-back", scene, &["--size", "64x36"]);
    let snow = run.grid("snow.npy");
    let at = |x: f64, z: f64| nearest(&run, &snow, (x, z));
    let o = &run.meta["origin_m"];
    assert!(o[0].as_f64().expect("x").abs() < 20.0, "the window is not back: origin {o}");
    // It went: the windrow's tiles were kept and came back from memory.
    let restored = run.meta["store"]["restored_tiles"].as_u64().expect("restored_tiles");
    assert!(restored > 10, "{restored} tiles came back: the window did not leave");
    // The cut along the path (the blade spans z -0.87..0.87 turned 30 degrees; the windrow spills to -0.5).
    for x in [-2.0, 0.0, 2.0] {
        let cut = at(x, 0.3);
        let top = (0..20).map(|k| at(x, -0.8 - 0.06 * f64::from(k))).fold(0.0f32, f32::max);
        assert!(cut < 0.06, "the cut at x = {x} holds {cut} m after the window came back");
        assert!(top > 0.6, "the windrow at x = {x} tops at {top} m after the window came back");
    }
    // The ledger followed the window 300 m away and back: what left, what
    // entered, and the windrow's snow that went and came back with its tiles.
    let mass = &run.meta["mass"];
    let [window, ledger, left] = ["window_kg", "ledger_kg", "left_kg"].map(|k| mass[k].as_f64().unwrap_or_else(|| panic!("{k}")));
    eprintln!("windrow back: window {window:.1} kg, ledger {ledger:.1} kg, left {left:.1} kg");
    assert!(left > window && (window / ledger - 1.0).abs() < 5e-4, "window {window} kg, ledger {ledger} kg, left {left} kg");
}

#[test]
fn with_the_points_technique_each_planted_paw_is_a_contact_point() {
    if !gpu_available() {
        return;
    }
    let (run, events) = fox_on_snow("fox-points", 5.0, &["--technique", "points"]);
    let prints = prints_at_footsteps(&run, &events, 0.2);
    assert!(prints.len() >= 16, "{} footsteps", prints.len());
    for (print, sink, _) in &prints {
        assert!((print - sink).abs() < 0.03, "a point print {print:.3} m deep where the paw sank {sink:.3} m");
    }
    // Only paws press: nothing away from the path, no snow pressed more than the deepest sinkage.
    let snow = run.grid("snow.npy");
    let snow_5_kpa = snowpack::SnowParams { hardness_kpa: 5.0, ..snowpack::SnowParams::default() }.mechanics();
    let most = snowpack::low_level::skin::sinking::FootLoad::default().sinkage_m(1.0, &snow_5_kpa, snowpack::mechanics::SnowColumn::fresh(0.2));
    for (k, h) in snow.data.iter().enumerate() {
        let (x, z) = run.world(k / snow.res, k % snow.res);
        if 0.2 - h > 0.005 {
            assert!(z.abs() < 0.3 && (-5.6..5.6).contains(&x), "pressed at ({x:.2}, {z:.2}), away from the path");
        }
        assert!(0.2 - h < most + 0.01, "pressed {:.3} m at ({x:.2}, {z:.2})", 0.2 - h);
    }
}

#[test]
fn snowfall_settles_on_a_table_top_and_the_open_ground_but_not_under_the_table() {
    if !gpu_available() {
        return;
    }
    // 2 s of straight-down snow at 1 cm/s: 2 cm in the open and on the table top.
    let run = run_scene(
        "snowfall",
        r#"
[snow]
extent_m = 12.0
resolution = 96
depth_m = 0.2
[terrain]
kind = "flat"
[snowfall]
direction = [0.0, -1.0, 0.0]
rate_m_per_s = 0.01
flutter_deg = 0.0
noise = 0.0
atlas_resolution = 128
[[object]]
name = "table"
kind = "box"
position = [0.0, 1.0, 0.0]
size_m = [2.0, 0.1, 1.2]
[[object]]
name = "pole"
kind = "box"
position = [3.0, 1.0, 3.0]
size_m = [0.2, 2.0, 0.2]
rotation_deg = [0.0, 0.0, 0.0]
dilate = false
[sim]
frames = 40
dt_s = 0.05
"#,
        &[],
    );
    let fallen = 0.02;
    assert!((run.meta["fallen_m"].as_f64().expect("fallen_m") - fallen).abs() < 1e-4);
    let table = &run.meta["objects"]["table"];
    let mean = table["mean_m"].as_f64().expect("mean_m");
    assert!((mean - fallen).abs() < 0.1 * fallen, "table top: {table}");
    assert!(table["covered_fraction"].as_f64().expect("covered") > 0.95, "{table}");
    assert!(table["max_m"].as_f64().expect("max") < 2.0 * fallen, "{table}");
    // The pole's top is 0.2 m square; its sides are vertical and hold nothing.
    assert!(run.meta["objects"]["pole"]["mean_m"].as_f64().expect("pole") > 0.5 * fallen);
    let snow = run.grid("snow.npy");
    let terrain = run.grid("terrain.npy");
    let atlas = run.grid("accumulation.npy");
    assert_eq!(atlas.res, 128);
    assert!(atlas.data.iter().all(|a| a.is_finite() && *a >= 0.0));
    let (mut open, mut under) = (0, 0);
    for i in 0..snow.res {
        for j in 0..snow.res {
            let (x, z) = run.world(i, j);
            let depth = snow.at(i, j) - terrain.at(i, j);
            if x.abs() < 0.85 && z.abs() < 0.45 {
                assert!((depth - 0.2).abs() < 1e-4, "under the table at ({x:.2}, {z:.2}): {depth} m");
                under += 1;
            } else if x.abs() > 1.3 || z.abs() > 0.9 {
                if (x - 3.0).abs() < 0.3 && (z - 3.0).abs() < 0.3 {
                    continue; // under the pole
                }
                assert!((depth - 0.22).abs() < 1e-4, "open ground at ({x:.2}, {z:.2}): {depth} m");
                open += 1;
            }
        }
    }
    assert!(under > 100 && open > 5000, "{under} texels under the table, {open} in the open");
    // And a direction that does not fall is bad input.
    expect_bad_input("bad-spin", "[[object]]\nname = \"s\"\nspin_deg_per_s = [0, nan, 0]\n", "spin_deg_per_s");
    expect_bad_input("upward-snow", "[snowfall]\ndirection = [0.0, 1.0, 0.0]\n", "direction");
}

#[test]
fn objects_carry_their_snow_as_they_move_and_shed_it_when_turned_over() {
    if !gpu_available() {
        return;
    }
    // 2 s of snow at 1 cm/s. One slab slides 2 m and spins about y (its top
    // stays up, so it keeps all its snow); one rolls about x at 90 degrees a
    // second (its first top faces down halfway through and sheds); one stays.
    let slab = |name: &str, x: f32, extra: &str| {
        format!("[[object]]\nname = \"{name}\"\nkind = \"box\"\nposition = [{x}, 1.5, 0.0]\nsize_m = [1.0, 0.1, 1.0]\n{extra}\n")
    };
    let scene = format!(
        "[snow]\nextent_m = 12.0\nresolution = 96\ndepth_m = 0.2\n[terrain]\nkind = \"flat\"\n[snowfall]\nrate_m_per_s = 0.01\nflutter_deg = 0.0\nnoise = 0.0\natlas_resolution = 256\n{}{}{}[sim]\nframes = 40\ndt_s = 0.05\n",
        slab("still", -3.0, ""),
        slab("carried", 0.0, "velocity = [0.0, 0.0, 1.0]\nspin_deg_per_s = [0.0, 90.0, 0.0]"),
        slab("rolled", 3.0, "spin_deg_per_s = [90.0, 0.0, 0.0]"),
    );
    let run = run_scene("moving-objects", &scene, &[]);
    let mean = |name: &str| run.meta["objects"][name]["mean_m"].as_f64().unwrap_or_else(|| panic!("{name}: {}", run.meta["objects"]));
    let still = mean("still");
    assert!((still - 0.02).abs() < 0.002, "still: {still}");
    assert!((mean("carried") - still).abs() < 0.1 * still, "carried {} against still {still}", mean("carried"));
    // Rolled 180 degrees: what faces up now only had the last part of the snow.
    assert!(mean("rolled") < 0.5 * still, "rolled {} against still {still}", mean("rolled"));
}

#[test]
fn a_gltf_object_gathers_snow_on_its_back() {
    if !gpu_available() {
        return;
    }
    let fox = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/Fox.glb");
    let run = run_scene(
        "gltf-object",
        &format!(
            r#"
[snow]
extent_m = 8.0
resolution = 128
depth_m = 0.1
[terrain]
kind = "flat"
[snowfall]
rate_m_per_s = 0.01
flutter_deg = 2.0
atlas_resolution = 256
[[object]]
name = "statue"
kind = "gltf"
file = {fox:?}
scale = 0.02
position = [0.0, 0.0, 0.0]
[sim]
frames = 40
dt_s = 0.05
"#
        ),
        &[],
    );
    let statue = &run.meta["objects"]["statue"];
    let mean = statue["mean_m"].as_f64().expect("mean_m");
    // Its back and head face the sky; flanks steeper than the angle of repose shed.
    assert!(mean > 0.004 && mean < 0.025, "{statue}");
    assert!(statue["covered_fraction"].as_f64().expect("covered") > 0.3, "{statue}");
    expect_bad_input("gltf-object-missing", "[[object]]\nname = \"s\"\nkind = \"gltf\"\nfile = \"nowhere.glb\"\n", "nowhere.glb");
}

const OPEN_WORLD: &str = r#"
[snow]
extent_m = 8.0
resolution = 128
depth_m = 0.4
refill_m_per_s = 0.01
blur = false
[terrain]
kind = "noise"
seed = 4
height_m = 0.0
amplitude_m = 0.2
wavelength_m = 12.0
[window]
follow = "actor:1"
# A crate presses a trench to the ground for 0.2 s and is lifted away.
[[actor]]
kind = "box"
size_m = [1.0, 2.0, 1.0]
path = [[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.2], [0.0, 8.0, 0.0, 0.21]]
# The window follows a bird 40 m out and back (five window widths).
[[actor]]
kind = "sphere"
radius_m = 0.1
path = [[0.0, 10.0, 0.0, 0.0], [0.0, 10.0, 0.0, 0.3], [40.0, 10.0, 0.0, 2.3], [0.0, 10.0, 0.0, 4.3]]
[sim]
frames = 300
"#;

/// The memory budget, as `meta.json` reports it: a default-sized window
/// (64 m at 1024²) that presses a trench and walks more than a window width,
/// trails kept in memory (the default), holds at most 10 MiB of GPU memory
/// with the depth technique and 15 MiB with combined: the adoption issue's
/// 8 and 12 MiB, each with the 2 MiB of packed snow that snow with mass
/// adds and the 0.88 MiB of the resident slots' packed-snow plane (its
/// issue's budget: 10 MiB for depth).
/// `[snow] store_ground` over noise hills: the window keeps the terrain
/// under each texel (4 bytes a texel, named in the memory list) and the
/// passes read it instead of evaluating the noise; the snow, its packing
/// and the displayed surface come out the same, bit for bit, through a
/// window that walks (the texels its moves expose stored as they come).
#[test]
fn a_stored_ground_leaves_the_same_snow_as_an_evaluated_one() {
    if !gpu_available() {
        return;
    }
    let runs: Vec<Run> = [false, true]
        .into_iter()
        .map(|store| {
            let scene = format!(
                r#"
[snow]
extent_m = 16.0
resolution = 256
depth_m = 0.4
elevation = 1.0
store_ground = {store}
[terrain]
kind = "noise"
seed = 5
amplitude_m = 0.8
wavelength_m = 6.0
[window]
follow = "actor:0"
[[actor]]
kind = "sphere"
radius_m = 0.4
path = [[0.0, 0.5, 0.0, 0.0], [12.0, 0.5, 3.0, 1.0]]
[sim]
frames = 60
"#
            );
            run_scene(&format!("ground-stored-{store}"), &scene, &["--size", "64x64"])
        })
        .collect();
    let memory = |r: &Run| r.meta["gpu_memory_by_resource"]["window ground"].as_u64();
    assert_eq!(memory(&runs[0]), None, "{}", runs[0].meta["gpu_memory_by_resource"]);
    assert_eq!(memory(&runs[1]), Some(256 * 256 * 4), "{}", runs[1].meta["gpu_memory_by_resource"]);
    // It started with its corner at -8 m and followed the sphere 12 m.
    assert!(runs[1].meta["origin_m"][0].as_f64() > Some(0.0), "the window did not walk: {}", runs[1].meta["origin_m"]);
    for name in ["snow.npy", "packed.npy", "surface.npy"] {
        let (a, b) = (runs[0].grid(name), runs[1].grid(name));
        let differ = a.data.iter().zip(&b.data).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
        assert_eq!(differ, 0, "{name}: {differ} texels differ between the evaluated and the stored ground");
    }
    let pressed = runs[0].grid("snow.npy");
    let terrain = runs[0].grid("terrain.npy");
    let deep = pressed.data.iter().zip(&terrain.data).filter(|(s, t)| **s - **t < 0.3).count();
    assert!(deep > 100, "the sphere pressed only {deep} texels below 30 cm of snow");
}

#[test]
fn a_default_sized_window_stays_within_10_mib_for_depth_and_15_for_combined() {
    if !gpu_available() {
        return;
    }
    for (technique, budget) in [("depth", 10u64 << 20), ("combined", 15 << 20)] {
        let scene = format!(
            r#"
[snow]
extent_m = 64.0
resolution = 1024
depth_m = 0.4
technique = "{technique}"
[terrain]
kind = "noise"
seed = 9
height_m = 0.0
amplitude_m = 0.3
wavelength_m = 30.0
[window]
follow = "actor:0"
[[actor]]
kind = "sphere"
radius_m = 0.5
path = [[0.0, 0.3, 0.0, 0.0], [90.0, 0.3, 0.0, 0.5]]
[sim]
frames = 40
"#
        );
        let run = run_scene(&format!("budget-{technique}"), &scene, &["--size", "64x64"]);
        let bytes = run.meta["gpu_memory_bytes"].as_u64().expect("gpu_memory_bytes");
        assert!(bytes <= budget, "{technique}: {bytes} bytes, over {budget}: {}", run.meta["gpu_memory_by_resource"]);
        // The peak includes tiles on their way to the CPU (staging for a frame
        // or two); at 180 m/s a column of 33 tiles leaves every frame, so the
        // copy-outs in flight add up to an eighth of the budget here (a
        // runner at 10 m/s sends a column every twelve frames).
        let peak = run.meta["gpu_memory_peak_bytes"].as_u64().expect("gpu_memory_peak_bytes");
        eprintln!("{technique}: {bytes} bytes at the end, {peak} at the peak");
        assert!(peak >= bytes && peak <= budget + (budget >> 3), "{technique}: peak {peak}");
        // The window walked and tiles went out: the figure is not a standing window's.
        assert!(run.meta["origin_m"][0].as_f64() > Some(40.0), "{technique}: the window did not walk: {}", run.meta["origin_m"]);
        assert!(run.meta["store"]["evicted_tiles"].as_u64() > Some(0), "{technique}: {}", run.meta["store"]);
    }
}

#[test]
fn a_trail_left_behind_comes_back_from_the_store_refilled_and_a_run_resumes_from_it() {
    if !gpu_available() {
        return;
    }
    let store = format!("{OPEN_WORLD}[store]\ntile_texels = 16\nmemory_mb = 0.05\n");
    let run = run_scene("open-world", &store, &[]);
    let (snow, terrain) = (run.grid("snow.npy"), run.grid("terrain.npy"));
    assert_eq!(run.meta["origin_m"][0].as_f64(), Some(-4.0), "the window did not come back: {}", run.meta);
    let meta = &run.meta["store"];
    assert!(meta["disk_tiles"].as_u64() > Some(50) && meta["restored_tiles"].as_u64() > Some(10), "{meta}");
    assert_eq!(meta["errors"].as_u64(), Some(0));
    // The trench (pressed to the ground until 0.2 s) has refilled for the
    // rest of the 5 s, most of it while the window was 40 m away.
    let c = snow.res / 2;
    let (trench, ground) = (snow.at(c, c), terrain.at(c, c));
    let expected = 0.01 * (300.0 / 60.0 - 0.2 - 1.0 / 60.0);
    assert!((trench - ground - expected).abs() < 2e-3, "trench {} m above ground, expected {expected}", trench - ground);
    // Outside it the snow is at rest.
    assert!((snow.at(4, 4) - terrain.at(4, 4) - 0.4).abs() < 1e-5);
    // With `keep = "off"` the trench is forgotten.
    let forgetful = run_scene("open-world-keep-off", &format!("{OPEN_WORLD}[store]\nkeep = \"off\"\n"), &[]);
    let (s, t) = (forgetful.grid("snow.npy"), forgetful.grid("terrain.npy"));
    assert!((s.at(c, c) - t.at(c, c) - 0.4).abs() < 1e-5, "with keep = \"off\" the trench should be fresh snow");
    assert!(forgetful.meta["store"].is_null(), "{}", forgetful.meta["store"]);
    // Running again into the same output resumes from the save: the clock
    // goes on and the trench keeps refilling (5 s more; the crate stays up).
    let scene = run.out.parent().expect("dir").join("scene-again.toml");
    let lifted = store.replace("path = [[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.2], [0.0, 8.0, 0.0, 0.21]]", "position = [0.0, 8.0, 0.0]");
    assert_ne!(lifted, store);
    std::fs::write(&scene, lifted).expect("write scene");
    let output = bin().args(["run", "--headless", "--scene"]).arg(&scene).arg("--out").arg(&run.out).output().expect("run");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let meta: serde_json::Value = serde_json::from_slice(&std::fs::read(run.out.join("meta.json")).expect("meta")).expect("json");
    assert_eq!(meta["store"]["resumed"].as_bool(), Some(true), "{meta}");
    assert_eq!(meta["origin_m"][0].as_f64(), Some(-4.0), "the window did not come back: {meta}");
    assert!((meta["store"]["time_s"].as_f64().unwrap_or(0.0) - 10.0).abs() < 1e-3, "{meta}");
    let again = Grid::load(&run.out.join("snow.npy"));
    let raised = again.at(c, c) - ground;
    assert!((raised - (expected + 0.05)).abs() < 3e-3, "after the second run the trench is {raised} m above ground, expected {}", expected + 0.05);
}

#[test]
fn a_trail_left_behind_comes_back_from_memory_with_no_store_table() {
    if !gpu_available() {
        return;
    }
    let run = run_scene("open-world-memory", OPEN_WORLD, &[]);
    let (snow, terrain) = (run.grid("snow.npy"), run.grid("terrain.npy"));
    assert_eq!(run.meta["origin_m"][0].as_f64(), Some(-4.0), "the window did not come back: {}", run.meta);
    let meta = &run.meta["store"];
    assert_eq!(meta["keep"].as_str(), Some("memory"), "{meta}");
    // The trench's tiles came back from memory (untouched ones are not kept: fresh snow is the same).
    assert!(meta["restored_tiles"].as_u64() > Some(0) && meta["evicted_tiles"].as_u64() > Some(50), "{meta}");
    assert_eq!((meta["disk_tiles"].as_u64(), meta["errors"].as_u64(), meta["lost"].as_u64()), (Some(0), Some(0), Some(0)), "{meta}");
    assert!(!run.out.join("store").exists(), "a memory keeper wrote a store folder");
    // The trench, refilled for the time since it was pressed, as with a disk store.
    let c = snow.res / 2;
    let expected = 0.01 * (300.0 / 60.0 - 0.2 - 1.0 / 60.0);
    let trench = snow.at(c, c) - terrain.at(c, c);
    assert!((trench - expected).abs() < 2e-3, "trench {trench} m above ground, expected {expected}");
    assert!((snow.at(4, 4) - terrain.at(4, 4) - 0.4).abs() < 1e-5);
    // `keep = "memory"` with its own tiles and budget does the same.
    let memory = run_scene("open-world-keep-memory", &format!("{OPEN_WORLD}[store]\nkeep = \"memory\"\ntile_texels = 16\nmemory_mb = 4\n"), &[]);
    let (s, t) = (memory.grid("snow.npy"), memory.grid("terrain.npy"));
    assert!((s.at(c, c) - t.at(c, c) - expected).abs() < 2e-3, "keep = \"memory\": trench {} m above ground", s.at(c, c) - t.at(c, c));
    assert_eq!(memory.meta["store"]["keep"].as_str(), Some("memory"));
}

#[test]
fn snowfall_on_bare_ground_lies_at_its_rate_and_a_deformer_leaves_it_bare() {
    if !gpu_available() {
        return;
    }
    // depth_m = 0: all the snow comes from the sky (0.02 m/s for 60 frames of 1/30 s).
    let scene = r#"
[snow]
extent_m = 8.0
resolution = 128
depth_m = 0.0
[terrain]
kind = "flat"
height_m = 0.3
[snowfall]
rate_m_per_s = 0.02
[[actor]]
kind = "sphere"
radius_m = 0.4
position = [0.0, 0.4, 0.0]
[sim]
frames = 60
dt_s = 0.033333335
"#;
    let run = run_scene("bare-ground", scene, &[]);
    let (snow, terrain, surface) = (run.grid("snow.npy"), run.grid("terrain.npy"), run.grid("surface.npy"));
    let expected = 0.02 * 60.0 * 0.033333335;
    assert!((run.meta["fallen_m"].as_f64().expect("fallen_m") - f64::from(expected)).abs() < 1e-5, "{}", run.meta["fallen_m"]);
    let (mut open, mut under) = (0, 0);
    for i in 0..snow.res {
        for j in 0..snow.res {
            let (depth, shown) = (snow.at(i, j) - terrain.at(i, j), surface.at(i, j));
            assert!(depth.is_finite() && shown.is_finite(), "NaN at ({i}, {j})");
            let (x, z) = run.world(i, j);
            let r = x.hypot(z);
            // Away from the sphere: the snowfall, within f32 rounding of its sum over frames.
            if r > 0.6 {
                assert!((depth - expected).abs() < 1e-5, "({i}, {j}): {depth} m of snow, expected {expected}");
                open += 1;
            }
            // Under it (below the ground within 0.39 m of its axis): bare ground.
            if r < 0.2 {
                assert_eq!(depth, 0.0, "({i}, {j}) under the sphere holds {depth} m of snow");
                under += 1;
            }
        }
    }
    assert!(open > snow.res * snow.res / 2 && under > 20, "{open} open, {under} under the sphere");
}

#[test]
fn bare_ground_is_accepted_and_a_negative_depth_exits_2() {
    let dir = Temp::new("bare-ground-check");
    let scene = dir.0.join("bare.toml");
    std::fs::write(&scene, "[snow]\ndepth_m = 0\n").expect("write scene");
    let output = bin().arg("check-scene").arg(&scene).output().expect("check");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    expect_bad_input("negative-depth", "[snow]\ndepth_m = -0.1\n", "[snow].depth_m");
}

#[test]
fn bad_store_values_exit_2_naming_file_and_key() {
    expect_bad_input("store-tile", "[snow]\nresolution = 128\n[store]\ntile_texels = 48\n", "tile_texels");
    expect_bad_input("store-key", "[store]\nbogus = 1\n", "bogus");
    expect_bad_input("store-keep", "[store]\nkeep = \"cloud\"\n", "[store].keep");
    expect_bad_input("store-keep-memory-save", "[store]\nkeep = \"memory\"\nsave = true\n", "[store].save");
    // A store path that is a file, not a folder.
    expect_bad_input("store-path", "[snow]\nresolution = 128\n[store]\npath = \"store-path.toml\"\n", "path");
}

/// A resolution the adapter cannot hold (its texture or buffer limits) is
/// the user's input: exit 2 naming the file, the key and the limit. The
/// smallest such resolution is found from the same adapter the binary picks.
#[test]
fn a_resolution_beyond_the_adapter_exits_2_naming_the_limit() {
    let Some(ctx) = snowpack_testkit::testing::gpu() else { return };
    let limits = ctx.device.limits();
    let buffer_limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
    let range = snowpack::low_level::deform::params::RESOLUTION_RANGE;
    let too_big = (*range.start()..=*range.end()).step_by(16).find(|&r| r > limits.max_texture_dimension_2d || u64::from(r) * u64::from(r) * 4 > buffer_limit);
    let Some(resolution) = too_big else {
        eprintln!("skipping: this adapter holds every resolution the scene format allows");
        return;
    };
    let limit = if resolution > limits.max_texture_dimension_2d { "max_texture_dimension_2d" } else { "max_storage_buffer_binding_size" };
    expect_bad_input("beyond-adapter", &format!("[snow]\nresolution = {resolution}\n"), "[snow].resolution");
    expect_bad_input("beyond-adapter-limit", &format!("[snow]\nresolution = {resolution}\n"), limit);
}

/// A store the disk refuses (here a file where its `tiles` folder should be,
/// as `persist.rs` fails a disk) is the machine's fault: exit 1, naming the
/// file and key, no panic. (A `[store].path` that is itself a file is the
/// user's: `bad_store_values_exit_2_naming_file_and_key`.)
#[test]
fn a_store_the_disk_refuses_exits_1() {
    if !gpu_available() {
        return;
    }
    let dir = Temp::new("store-refused");
    let store = dir.0.join("store");
    std::fs::create_dir_all(&store).expect("store folder");
    std::fs::write(store.join("tiles"), b"in the way").expect("a file where the tiles go");
    let scene = dir.0.join("store-refused.toml");
    std::fs::write(&scene, format!("[snow]\nresolution = 128\n[store]\npath = {:?}\n", store.display().to_string())).expect("write scene");
    let output = bin().args(["run", "--headless", "--frames", "2", "--scene"]).arg(&scene).arg("--out").arg(dir.0.join("out")).output().expect("run");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "a refused store should exit 1 (the machine's fault), got {:?}: {stderr}", output.status);
    assert!(stderr.contains("store-refused.toml") && stderr.contains("[store].path"), "the message names the file and key: {stderr}");
    assert!(stderr.contains("tiles"), "the message names the folder that failed: {stderr}");
    assert!(!stderr.contains("panicked"), "panic: {stderr}");
}

#[test]
fn grass_in_a_shell_over_the_snow_peels_in_passes_that_shade_fewer_pixels() {
    if !gpu_available() {
        return;
    }
    let scene = r#"
[snow]
extent_m = 8.0
resolution = 128
depth_m = 0.3
[[actor]]
kind = "sphere"
radius_m = 0.25
path = [[-3.0, 0.15, 0.5, 0.0], [3.0, 0.15, 0.5, 0.3]]
[sim]
frames = 20
[camera]
position = [0.3, 0.6, -1.6]
target = [0.0, 0.1, 0.6]
[shell]
radius_m = 3.0
passes = 6
"#;
    let run = run_scene("shell-grass", scene, &["--size", "160x120"]);
    let shell = &run.meta["render"]["shell"];
    assert!(shell["tetrahedra"].as_u64() > Some(1000), "{shell}");
    let pixels: Vec<u64> = shell["pass_pixels"].as_array().expect("pass_pixels").iter().filter_map(serde_json::Value::as_u64).collect();
    assert_eq!(pixels.len(), 6, "{shell}");
    assert!(pixels[0] > 160 * 120 / 4, "the grass covers too little of the frame: {pixels:?}");
    assert!(pixels.windows(2).all(|w| w[1] < w[0] || w[0] == 0), "{pixels:?}");
    // Without [shell] there is none.
    let bare = run_scene("shell-none", &scene.replace("[shell]\nradius_m = 3.0\npasses = 6\n", ""), &["--size", "160x120"]);
    assert!(bare.meta["render"]["shell"].is_null());
}

#[test]
fn bad_shell_values_exit_2_naming_file_and_key() {
    expect_bad_input("shell-passes", "[shell]\npasses = 40\n", "passes");
    expect_bad_input("shell-texture", "[shell]\ntexture = \"moss\"\n", "texture");
    expect_bad_input("shell-size", "[shell]\ntexture_size = 48\n", "texture_size");
    expect_bad_input("shell-debug", "[shell]\npasses = 2\ndebug_pass = 3\n", "debug_pass");
}

#[test]
fn a_bad_backend_exits_2_naming_the_option_for_every_command() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/default.toml");
    let dir = Temp::new("bad-backend");
    for args in [
        vec!["run", "--headless", "--backend", "voodoo", "--scene"],
        vec!["bench", "--quick", "--backend", "voodoo", "--out"],
        vec!["demo", "--backend", "vulkan,voodoo", "--scene"],
    ] {
        let target = if args[0] == "bench" { dir.0.join("bench") } else { scene.clone() };
        let output = bin().args(&args).arg(&target).output().expect("run");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains("--backend") && stderr.contains("voodoo"), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
    assert!(!dir.0.join("bench").exists(), "nothing written for a bad backend");
}

/// Every option of every command given a bad value, and a missing or bad
/// input file, exits 2 with a message naming the option (or file and key),
/// never a panic, and writes nothing.
#[test]
fn every_bad_option_exits_2_naming_it() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/default.toml");
    let scene = scene.to_str().expect("a UTF-8 path");
    let dir = Temp::new("bad-options");
    let out = dir.0.join("out");
    let out = out.to_str().expect("a UTF-8 path");
    let bad_scene = dir.0.join("bad.toml");
    std::fs::write(&bad_scene, "[snow]\nresolution = -3\n").expect("write");
    let bad_scene = bad_scene.to_str().expect("a UTF-8 path");
    let missing = dir.0.join("missing.toml");
    let missing = missing.to_str().expect("a UTF-8 path");
    // (arguments, what the message must name)
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["run", "--scene", scene, "--out", out, "--frames", "many"], "--frames"),
        (vec!["run", "--scene", scene, "--out", out, "--frames=-4"], "--frames"),
        (vec!["run", "--scene", scene, "--out", out, "--size", "0x10"], "--size"),
        (vec!["run", "--scene", scene, "--out", out, "--size", "big"], "--size"),
        (vec!["run", "--scene", scene, "--out", out, "--technique", "magic"], "technique"),
        (vec!["run", "--scene", scene, "--out", out, "--view", "xray"], "view"),
        (vec!["run", "--scene", scene, "--out", out, "--material", "plastic"], "material"),
        (vec!["run", "--scene", scene, "--out", out, "--backend", "voodoo"], "--backend"),
        (vec!["run", "--scene", scene, "--out", out, "--bogus"], "--bogus"),
        (vec!["run", "--out", out], "--scene"),
        (vec!["run", "--scene", missing, "--out", out], "missing.toml"),
        (vec!["run", "--scene", bad_scene, "--out", out], "resolution"),
        (vec!["bench", "--out", out, "--only", "everything"], "only"),
        (vec!["bench", "--out", out, "--backend", "voodoo"], "--backend"),
        (vec!["check-scene", missing], "missing.toml"),
        (vec!["check-scene", bad_scene], "resolution"),
        (vec!["check-scene"], "FILE"),
        (vec!["demo", "--window-size", "0x0"], "--window-size"),
        (vec!["demo", "--exit-after-frames", "soon"], "--exit-after-frames"),
        (vec!["frobnicate"], "frobnicate"),
    ];
    for (args, names) in &cases {
        let output = bin().env_remove("DISPLAY").env_remove("WAYLAND_DISPLAY").args(args).output().expect("run snowpack");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{args:?} exited {:?}: {stderr}", output.status.code());
        assert!(stderr.contains(names), "{args:?}: the message does not name {names:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert!(!Path::new(out).exists(), "{args:?} wrote its output folder");
    }
}

/// A clean headless run on a machine without `XDG_RUNTIME_DIR` (CI, servers)
/// says nothing on stderr that reads as a failure: Mesa's device-select layer
/// used to make libwayland print "error: XDG_RUNTIME_DIR is invalid or not set"
/// twice (the binary now switches that layer off there).
#[test]
fn a_clean_headless_run_prints_no_error_lines() {
    if !gpu_available() {
        return;
    }
    let dir = Temp::new("quiet");
    let scene = dir.0.join("scene.toml");
    std::fs::write(&scene, "[snow]\nextent_m = 4.0\nresolution = 64\ndepth_m = 0.3\n[sim]\nframes = 3\n").expect("write scene");
    let output = Command::new(env!("CARGO_BIN_EXE_snowpack"))
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("NODEVICE_SELECT")
        .env_remove("SNOWPACK_LOG")
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .args(["run", "--headless", "--scene"])
        .arg(&scene)
        .arg("--out")
        .arg(dir.0.join("out"))
        .output()
        .expect("run snowpack");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "snowpack run failed: {stderr}");
    assert!(!stderr.contains("error") && !stderr.contains("XDG_RUNTIME_DIR"), "a clean run printed:\n{stderr}");
}

/// A scene with one `[[vehicle]]` (its keys `vehicle`, then `path`) on 30 cm
/// of snow of 40 kPa over flat ground, in an 8 m window of 512² (1.6 cm texels).
fn vehicle_scene(vehicle: &str, path: &str, dt_s: f64, frames: u32, snow: &str) -> String {
    format!(
        "[snow]\nextent_m = 8.0\nresolution = 512\ndepth_m = 0.3\nhardness_kpa = 40.0\nelevation = 0.0\n{snow}\n[terrain]\nkind = \"flat\"\n\n[window]\ncenter = [0.0, 0.0]\n\n\
         [[vehicle]]\nwheelbase_m = 2.6\ntrack_m = 1.6\nwheel_radius_m = 0.33\nwheel_width_m = 0.22\n{vehicle}\npath = {path}\n\n[sim]\nframes = {frames}\ndt_s = {dt_s}\n"
    )
}

/// Depth below the rest snow (m) along z = `z` for x in `x0..x1`, one sample per texel.
fn rut_profile(run: &Run, z: f64, x0: f64, x1: f64) -> Vec<(f64, f32)> {
    let snow = run.grid("snow.npy");
    let texel = run.meta["texel_m"].as_f64().expect("texel_m");
    let oz = run.meta["origin_m"][1].as_f64().expect("z");
    let i = ((z - oz) / texel).floor() as usize;
    (0..snow.res)
        .filter_map(|j| {
            let (x, _) = run.world(i, j);
            (x0..=x1).contains(&x).then(|| (x, 0.3 - snow.at(i, j)))
        })
        .collect()
}

#[test]
fn a_fast_vehicle_leaves_continuous_ruts_as_deep_as_its_load_says() {
    if !gpu_available() {
        return;
    }
    use snowpack::low_level::skin::sinking::WheelLoad;
    // 15 m/s at 30 frames a second: 50 cm a frame, so each frame's wheels
    // stand 50 cm from the last; a straight line through the window.
    let path = "[[-12.0, 0.0, 0.0], [12.0, 0.0, 1.6]]";
    let run_with = |name: &str, mass: f32, snow: &str| {
        let toml = vehicle_scene(&format!("mass_kg = {mass}\ntread = \"none\""), path, 1.0 / 30.0, 48, snow);
        run_scene(name, &toml, &[])
    };
    let mut floors = Vec::new();
    for mass in [800.0_f32, 3200.0] {
        let run = run_with(&format!("vehicle-fast-{mass}"), mass, "");
        let snow = snowpack::SnowParams { hardness_kpa: 40.0, ..snowpack::SnowParams::default() }.mechanics();
        let sink = WheelLoad { mass_kg: mass / 4.0, radius_m: 0.33, width_m: 0.22 }.sinkage_m(&snow, snowpack::mechanics::SnowColumn::fresh(0.3));
        for z in [-0.8, 0.8] {
            let rut = rut_profile(&run, z, -3.5, 3.5);
            assert!(rut.len() > 400, "{} samples", rut.len());
            let shallowest = rut.iter().map(|r| r.1).fold(f32::MAX, f32::min);
            let deepest = rut.iter().map(|r| r.1).fold(f32::MIN, f32::max);
            println!("{mass} kg, rut at z = {z}: {shallowest:.4} to {deepest:.4} m deep, load model {sink:.4} m");
            // Continuous: the floor never comes up between frames (the
            // swept shape of a rolling cylinder is flat along its path).
            assert!(deepest - shallowest < 0.002, "{mass} kg: rut floor from {shallowest} to {deepest} m deep along z = {z}");
            // As deep as the load model says (the capture's 16-bit code is 0.1 mm here).
            assert!((deepest - sink).abs() < 0.002, "{mass} kg: rut {deepest} m deep, load model {sink} m");
            floors.push(deepest);
        }
    }
    // Four times the mass: deeper ruts.
    assert!(floors[2] > floors[0] + 0.02 && floors[3] > floors[1] + 0.02, "rut depths {floors:?}");
    // Unswept, the same frames leave a chain of prints 50 cm apart, the
    // floor rising by centimetres between them: the test sees gaps.
    let run = run_with("vehicle-fast-unswept", 800.0, "teleport_m = 0.0\n");
    let rut = rut_profile(&run, 0.8, -3.5, 3.5);
    let shallowest = rut.iter().map(|r| r.1).fold(f32::MAX, f32::min);
    println!("unswept: the floor rises to {shallowest:.4} m deep between prints");
    assert!(floors[0] - shallowest > 0.03, "unswept ruts are continuous too ({shallowest} vs {} m): the test cannot see gaps", floors[0]);
}

/// Strength of the period `period_m` in an evenly sampled signal (a DFT bin at that period).
fn period_power(samples: &[(f64, f32)], period_m: f64) -> f64 {
    let mean = samples.iter().map(|s| f64::from(s.1)).sum::<f64>() / samples.len() as f64;
    let (mut re, mut im) = (0.0, 0.0);
    for &(x, v) in samples {
        let phase = std::f64::consts::TAU * x / period_m;
        re += (f64::from(v) - mean) * phase.cos();
        im += (f64::from(v) - mean) * phase.sin();
    }
    (re * re + im * im).sqrt() / samples.len() as f64
}

/// The strongest period between 4 cm and 40 cm (m), and its amplitude (m).
fn strongest_period(samples: &[(f64, f32)]) -> (f64, f64) {
    (0..=720).map(|k| 0.04 + f64::from(k) * 0.0005).map(|p| (p, period_power(samples, p))).fold((0.0, 0.0), |a, b| if b.1 > a.1 { b } else { a })
}

#[test]
fn the_tread_prints_its_lug_spacing_along_the_rut_floor_and_slip_smears_it() {
    if !gpu_available() {
        return;
    }
    // 1.5 m/s in a straight line; block tread, lugs every 10 cm, 3 cm deep.
    let path = "[[-4.5, 0.0, 0.0], [4.5, 0.0, 6.0]]";
    let run_with = |name: &str, slip: f32| {
        let vehicle = format!("mass_kg = 1800.0\ntread = \"blocks\"\ntread_spacing_m = 0.1\ntread_depth_m = 0.03\ntread_fraction = 0.4\nslip = {slip}");
        run_scene(name, &vehicle_scene(&vehicle, path, 1.0 / 30.0, 180, ""), &[])
    };
    let rolling = run_with("vehicle-tread", 0.0);
    // Along a row of blocks (a quarter of the tyre's width from its centre line), where both axles passed.
    let rut = rut_profile(&rolling, 0.8 + 0.055, -3.0, 3.0);
    let (period, amplitude) = strongest_period(&rut);
    let range = rut.iter().map(|r| r.1).fold(f32::MIN, f32::max) - rut.iter().map(|r| r.1).fold(f32::MAX, f32::min);
    println!("rolling: strongest period {period:.4} m (lugs every 0.1 m), amplitude {amplitude:.4} m, floor range {range:.4} m");
    assert!((period - 0.1).abs() < 0.002, "strongest period along the rut {period} m, lugs every 0.1 m");
    // Grooves as deep as the lugs stand out (blur off in snow.npy; the square wave's fundamental is a fraction of it).
    assert!(range > 0.025 && range < 0.035, "floor range {range} m for 3 cm lugs");
    assert!(amplitude > 0.005, "amplitude {amplitude} m");
    // Spinning (slip 1): the tread slides over the snow while it presses,
    // and the lugs near the contact fill the ridges between the grooves.
    let spinning = run_with("vehicle-tread-slip", 1.0);
    let rut = rut_profile(&spinning, 0.8 + 0.055, -3.0, 3.0);
    let range_slip = rut.iter().map(|r| r.1).fold(f32::MIN, f32::max) - rut.iter().map(|r| r.1).fold(f32::MAX, f32::min);
    println!("spinning: floor range {range_slip:.4} m");
    assert!(range_slip < 0.4 * range, "slip 1 leaves the tread {range_slip} m deep against {range} m rolling");
}

#[test]
fn one_vehicle_path_at_30_and_240_frames_a_second_leaves_the_same_ruts() {
    if !gpu_available() {
        return;
    }
    // A curve at about 4 m/s with some slip, blocks; it stops at 1.8 s, before
    // either run's last frame (1.967 s and 1.996 s), so both end on the same pose.
    let path = "[[-5.0, -1.5, 0.0], [-1.0, 0.5, 1.0], [2.5, -0.5, 1.8]]";
    let vehicle = "mass_kg = 1800.0\ntread = \"blocks\"\ntread_spacing_m = 0.1\ntread_depth_m = 0.03\nslip = 0.1";
    let at = |fps: u32| {
        let run = run_scene(&format!("vehicle-{fps}fps"), &vehicle_scene(vehicle, path, 1.0 / f64::from(fps), 2 * fps, ""), &[]);
        run.grid("snow.npy").data
    };
    let (slow, fast) = (at(30), at(240));
    let res = (slow.len() as f64).sqrt() as usize;
    let pressed = slow.iter().filter(|h| **h < 0.29).count();
    let over = slow.iter().zip(&fast).filter(|(a, b)| (*a - *b).abs() > 0.005).count();
    // The rut's walls and the lugs' edges are vertical faces: a shift far
    // below a texel (the chords a frame's sub-steps follow lie up to 0.5 mm
    // inside the curve at 30 frames a second) moves a texel centre from one
    // side to the other, a difference of a lug's depth or the whole rut in
    // that texel. So each texel is compared with the other run's range over
    // its 3x3 neighbourhood (the ruts agree up to a shift within a texel).
    let beyond = |a: &[f32], b: &[f32]| -> (usize, f32) {
        let mut count = 0;
        let mut worst = 0.0_f32;
        for i in 1..res - 1 {
            for j in 1..res - 1 {
                let v = a[i * res + j];
                let around = (0..9).map(|k| b[(i + k / 3 - 1) * res + j + k % 3 - 1]);
                let (lo, hi) = around.fold((f32::MAX, f32::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)));
                let e = (lo - v).max(v - hi).max(0.0);
                count += usize::from(e > 0.005);
                worst = worst.max(e);
            }
        }
        (count, worst)
    };
    let (a, b) = (beyond(&slow, &fast), beyond(&fast, &slow));
    let mean = |h: &[f32]| h.iter().map(|x| f64::from(0.3 - x)).sum::<f64>() / h.len() as f64;
    let (pressed_fast, mean_slow, mean_fast) = (fast.iter().filter(|h| **h < 0.29).count(), mean(&slow), mean(&fast));
    println!(
        "{pressed} texels pressed over 1 cm at 30 fps, {pressed_fast} at 240; {over} differ by more than 5 mm texel by texel; \
         beyond 5 mm of the other run's 3x3 range: {} (worst {:.4} m) and {} (worst {:.4} m); mean depth {mean_slow:.6} and {mean_fast:.6} m",
        a.0, a.1, b.0, b.1
    );
    assert!(pressed > 20_000, "only {pressed} texels pressed");
    assert!(pressed.abs_diff(pressed_fast) * 100 <= pressed, "{pressed} against {pressed_fast} texels pressed");
    assert!((mean_slow - mean_fast).abs() < 5e-4, "mean depth {mean_slow} against {mean_fast} m");
    assert!((a.0 + b.0) * 200 <= pressed, "{} and {} of {pressed} texels beyond 5 mm of the other run's 3x3 range", a.0, b.0);
}

#[test]
fn bad_vehicle_values_exit_2_naming_file_and_key() {
    let ok = "path = [[0.0, 0.0, 0.0], [1.0, 0.0, 1.0]]\n";
    let cases: &[(&str, String, &str)] = &[
        ("vehicle-negative-mass", format!("[[vehicle]]\nmass_kg = -5.0\n{ok}"), "[[vehicle]][0].mass_kg"),
        ("vehicle-zero-radius", format!("[[vehicle]]\nwheel_radius_m = 0.0\n{ok}"), "[[vehicle]][0].wheel_radius_m"),
        ("vehicle-narrow-track", format!("[[vehicle]]\ntrack_m = 0.1\nwheel_width_m = 0.2\n{ok}"), "[[vehicle]][0].track_m"),
        ("vehicle-bad-tread", format!("[[vehicle]]\ntread = \"zigzag\"\n{ok}"), "[[vehicle]][0].tread"),
        ("vehicle-deep-tread", format!("[[vehicle]]\ntread_depth_m = 0.5\nwheel_radius_m = 0.3\n{ok}"), "[[vehicle]][0].tread_depth_m"),
        ("vehicle-tread-fraction", format!("[[vehicle]]\ntread_fraction = 1.5\n{ok}"), "[[vehicle]][0].tread_fraction"),
        ("vehicle-zero-spacing", format!("[[vehicle]]\ntread_spacing_m = 0.0\n{ok}"), "[[vehicle]][0].tread_spacing_m"),
        ("vehicle-slip", format!("[[vehicle]]\nslip = -2.0\n{ok}"), "[[vehicle]][0].slip"),
        ("vehicle-no-path", "[[vehicle]]\nmass_kg = 1000.0\n".to_owned(), "[[vehicle]][0].path"),
        ("vehicle-one-key", "[[vehicle]]\npath = [[0.0, 0.0, 0.0]]\n".to_owned(), "[[vehicle]][0].path"),
        ("vehicle-time-order", "[[vehicle]]\npath = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.5]]\n".to_owned(), "[[vehicle]][0].path"),
        ("vehicle-path-row", "[[vehicle]]\npath = [[0.0, 0.0], [1.0, 0.0]]\n".to_owned(), "[[vehicle]][0].path[0]"),
        ("vehicle-wheelbase-type", format!("[[vehicle]]\nwheelbase_m = \"long\"\n{ok}"), "[[vehicle]][0].wheelbase_m"),
        ("vehicle-unknown", format!("[[vehicle]]\nwheels = 6\n{ok}"), "[[vehicle]][0].wheels"),
    ];
    for (name, toml, key) in cases {
        expect_bad_input(name, toml, key);
    }
}

/// `actor_snow_K.npy` rows: bind-pose x, y, z, bind-pose normal y, snow (m).
fn actor_snow(run: &Run, k: usize) -> Vec<[f32; 5]> {
    let path = run.out.join(format!("actor_snow_{k}.npy"));
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(&bytes[..6], b"\x93NUMPY");
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(&bytes[10..10 + len]).expect("ascii header");
    let data: Vec<f32> = bytes[10 + len..].chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    assert!(header.contains(&format!("'shape': ({}, 5)", data.len() / 5)), "{header}");
    data.chunks_exact(5).map(|r| [r[0], r[1], r[2], r[3], r[4]]).collect()
}

/// The fraction of `rows` carrying more than `min_m` of snow.
fn snowy(rows: &[&[f32; 5]], min_m: f32) -> f32 {
    rows.iter().filter(|r| r[4] > min_m).count() as f32 / rows.len().max(1) as f32
}

#[test]
fn a_fox_wading_through_deep_snow_comes_out_with_snowy_legs_and_a_clean_back() {
    if !gpu_available() {
        return;
    }
    // 3 m through 20 cm of snow at the walk's pace; the fox's own units are centimetres.
    let run = run_scene(
        "fox-wade",
        r#"
[snow]
extent_m = 8.0
resolution = 256
depth_m = 0.2
[[actor]]
kind = "gltf"
file = "builtin:fox"
animation = "Walk"
scale = 0.01
path = [[-1.5, 0.0, 0.0, 0.0], [1.5, 0.0, 0.0, 3.0]]
[sim]
frames = 180
"#,
        &["--size", "64x36"],
    );
    let rows = actor_snow(&run, 0);
    assert!(rows.len() > 1000, "{} vertices", rows.len());
    let height = |r: &[f32; 5]| r[1] * 0.01;
    let low: Vec<_> = rows.iter().filter(|r| height(r) < 0.08).collect();
    let back: Vec<_> = rows.iter().filter(|r| height(r) > 0.35).collect();
    assert!(low.len() > 50 && back.len() > 50, "{} low and {} back vertices", low.len(), back.len());
    assert!(snowy(&low, 0.001) > 0.9, "only {:.0} % of the vertices under 8 cm carry snow after wading through 20 cm", 100.0 * snowy(&low, 0.001));
    assert!(snowy(&back, 0.0005) == 0.0, "{:.0} % of the back (above 35 cm, over snow 20 cm deep, no snowfall) carries snow", 100.0 * snowy(&back, 0.0005));
    for r in &rows {
        assert!(r[4] >= 0.0 && r[4] <= snowpack::CoatSettings::default().cap_m + 1e-6, "a vertex carries {} m", r[4]);
    }
}

#[test]
fn a_fox_standing_in_snowfall_gets_a_white_back_and_a_clean_belly() {
    if !gpu_available() {
        return;
    }
    // 5 s of 4 mm/s onto bare ground: 2 cm on what faces straight up.
    let run = run_scene(
        "fox-snowfall",
        r#"
[snow]
extent_m = 8.0
resolution = 128
depth_m = 0.0
[snowfall]
rate_m_per_s = 0.004
max_m = 0.05
[[actor]]
kind = "gltf"
file = "builtin:fox"
animation = "Survey"
scale = 0.01
position = [0.0, 0.0, 0.0]
[sim]
frames = 300
"#,
        &["--size", "64x36"],
    );
    let rows = actor_snow(&run, 0);
    let height = |r: &[f32; 5]| r[1] * 0.01;
    // Above the 2 cm that fell on the ground, so no vertex here wades.
    let up: Vec<_> = rows.iter().filter(|r| r[3] > 0.7 && height(r) > 0.2).collect();
    let down: Vec<_> = rows.iter().filter(|r| r[3] < -0.7 && height(r) > 0.2).collect();
    assert!(up.len() > 20 && down.len() > 20, "{} up and {} down vertices", up.len(), down.len());
    assert!(snowy(&up, 0.005) > 0.8, "only {:.0} % of the upward faces carry 5 mm after 5 s of 4 mm/s", 100.0 * snowy(&up, 0.005));
    assert!(snowy(&down, 0.0005) < 0.05, "{:.0} % of the downward faces carry snow", 100.0 * snowy(&down, 0.0005));
}
