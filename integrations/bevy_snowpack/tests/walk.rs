//! The `walk` example end to end: the real binary (built by `cargo test`
//! beside the tests) opens a window on a private X server (Xvfb, which
//! `.ci/run` installs), runs 120 scripted frames on the software adapter and
//! writes Bevy's screenshot. Where it says a ball's trench is, the picture
//! must differ from untouched snow; the fox's paws must have reported steps;
//! and the fox, held back by the snow (`SnowResistance`), must have walked
//! slower out through the 0.4 m of fresh snow than back in its own packed
//! trail (its speeds measured from its positions frame to frame, at the
//! scripted 1/30 s a frame: no wall time).
//!
//! Without Xvfb this test skips, unless `SNOWPACK_REQUIRE_GPU` is set (CI).

mod common;

use std::process::Command;

use common::xvfb::Xvfb;
use common::{example, patch_luma};

#[test]
fn walk_example_leaves_visible_trails_and_footsteps() {
    let Some(x) = Xvfb::start() else { return };
    let dir = std::env::temp_dir().join(format!("bevy_snowpack_walk_{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    let shot = dir.join("walk.png");
    let out = Command::new(example("walk"))
        .args(["--exit-after-frames", "120", "--screenshot"])
        .arg(&shot)
        .env("DISPLAY", &x.display)
        // Bevy resolves the assets folder from the manifest's directory.
        .env("CARGO_MANIFEST_DIR", env!("CARGO_MANIFEST_DIR"))
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("the walk example runs (cargo test builds it)");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "walk exited with {}\nstdout:\n{stdout}\nstderr:\n{stderr}", out.status);
    let report = stdout.lines().find(|l| l.starts_with("walk: ")).unwrap_or_else(|| panic!("no report line in\n{stdout}\n{stderr}"));
    let words: Vec<&str> = report.split_whitespace().collect();
    // walk: trench pixel X Y fresh pixel X Y footsteps N fox m/s fresh A over n trail B over m
    assert_eq!(words.get(1..3), Some(&["trench", "pixel"][..]), "no trench on screen: {report}");
    assert_eq!(words.get(11..14), Some(&["fox", "m/s", "fresh"][..]), "no fox speeds: {report}");
    let number = |k: usize| words[k].parse::<f32>().unwrap_or_else(|e| panic!("{report}: word {k}: {e}"));
    let (trench, fresh, steps) = ((number(3), number(4)), (number(7), number(8)), number(10));
    let (fresh_speed, fresh_frames, trail_speed, trail_frames) = (number(14), number(16), number(18), number(20));

    let image = image::open(&shot).unwrap_or_else(|e| panic!("{}: {e}", shot.display())).to_rgba8();
    let inside = |(x, y): (f32, f32)| x >= 4.0 && y >= 4.0 && x < image.width() as f32 - 4.0 && y < image.height() as f32 - 4.0;
    assert!(inside(trench) && inside(fresh), "{report}: off the {}x{} picture", image.width(), image.height());
    let luma = |(x, y): (f32, f32)| patch_luma(&image, x as u32, y as u32);
    let (trench_luma, fresh_luma) = (luma(trench), luma(fresh));
    println!("{report}; luma: trench {trench_luma:.1}, fresh {fresh_luma:.1}; picture {}", shot.display());
    // Untouched snow is bright; the trench is shaded apart from it (compacted, its walls shadowing).
    assert!(fresh_luma > 120.0, "untouched snow reads {fresh_luma:.1}: not snow");
    assert!((trench_luma - fresh_luma).abs() > 10.0, "the trench ({trench_luma:.1}) looks like untouched snow ({fresh_luma:.1})");
    // Four paws, about 4 s of walking and running: many steps.
    assert!(steps >= 8.0, "only {steps} footsteps from the fox's paws");
    // The snow holds the fox back: over 10 frames each way, slower wading out than walking back in its trail.
    assert!(fresh_frames >= 10.0 && trail_frames >= 10.0, "too few frames measured: {report}");
    assert!(fresh_speed > 0.05, "the fox did not move out: {report}");
    assert!(trail_speed > 1.3 * fresh_speed, "the fox walked {trail_speed} m/s in its trail and {fresh_speed} m/s in fresh snow: {report}");
    let _ = std::fs::remove_dir_all(&dir);
}
