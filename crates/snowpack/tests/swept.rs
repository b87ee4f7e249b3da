//! Swept capture: a deformer presses the snow over its whole motion since the
//! last frame, so a trail is the union of its poses over time and does not
//! depend on the frame rate (`docs/deformation.md`, "Swept capture").

use glam::{DVec2, Quat, Vec3};
use snowpack::low_level::SnowInspect;
use snowpack::{Deformer, GpuContext, SnowDeformation, SnowParams, Technique, TerrainSource};
use snowpack_testkit::testing;

const DEPTH_M: f32 = 0.5;

fn window(ctx: &GpuContext, extent_m: f32, resolution: u32, center: DVec2, technique: Technique, teleport_m: f32) -> SnowDeformation {
    let params = SnowParams { extent_m, resolution, depth_m: DEPTH_M, technique, teleport_m, tile_memory_bytes: None, ..SnowParams::default() };
    SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, center).expect("window")
}

/// A ball rolling on a 6 m circle at 6 m/s, bobbing 4 cm, and a turned box
/// sliding and sinking, at time `t` (s). Frames sample the circle by chords
/// (0.8 mm inside the arc at 30 frames a second), so the ball's centre stays
/// above the snow: where it sank below, its trench walls would be vertical
/// and that sub-millimetre shift would move a texel centre on the wall from
/// the bottom to the top.
fn bodies(t: f32) -> Vec<Deformer> {
    let (r, w) = (6.0, 1.0);
    vec![
        Deformer::Sphere { center: Vec3::new(r * (w * t).sin(), 0.6 + 0.04 * (3.0 * t).sin(), r * (1.0 - (w * t).cos())), radius: 0.25 },
        Deformer::Box { center: Vec3::new(-4.0 + 5.0 * t, 0.6 - 0.05 * t, -3.0), half_extents: Vec3::new(0.3, 0.2, 0.5), rotation: Quat::from_rotation_y(0.3) },
    ]
}

/// The snow after the bodies' 2 s path sampled at `fps` frames a second.
fn run_path(ctx: &GpuContext, fps: u32, technique: Technique, teleport_m: f32) -> Vec<f32> {
    let mut snow = window(ctx, 16.0, 256, DVec2::new(1.0, 2.0), technique, teleport_m);
    let frames = 2 * fps;
    for k in 0..=frames {
        snow.step(ctx, &bodies(k as f32 / fps as f32), 1.0 / fps as f32).expect("frame");
    }
    snow.finish(ctx).expect("finish");
    snow.read_snow(ctx).expect("snow")
}

fn max_difference(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
}

#[test]
fn one_path_at_30_60_and_240_frames_a_second_leaves_the_same_snow() {
    let Some(ctx) = testing::gpu() else { return };
    for technique in [Technique::Depth, Technique::Points] {
        let fine = run_path(ctx, 240, technique, 4.0);
        assert!(fine.iter().any(|&h| h < DEPTH_M - 0.1), "{technique:?}: nothing pressed");
        for fps in [30, 60] {
            let coarse = run_path(ctx, fps, technique, 4.0);
            let diff = max_difference(&coarse, &fine);
            println!("{technique:?}: {fps} against 240 frames a second, largest difference {:.2} mm", diff * 1000.0);
            assert!(diff <= 0.005, "{technique:?}: {fps} fps differs from 240 fps by {diff} m");
        }
        // Unswept, the same path at 30 fps is a chain of dimples: the test has teeth.
        let unswept = max_difference(&run_path(ctx, 30, technique, 0.0), &fine);
        println!("{technique:?}: unswept at 30 fps, largest difference {:.1} mm", unswept * 1000.0);
        assert!(unswept > 0.02, "{technique:?}: unswept only {unswept} m off");
    }
}

/// The lowest height of a capsule of radius `r` around a..b over (x, z), by
/// sampling the segment finely (independent of the analytic capture).
fn capsule_by_sampling(x: f32, z: f32, a: Vec3, b: Vec3, r: f32) -> Option<f32> {
    let n = 4000;
    (0..=n)
        .filter_map(|k| {
            let c = a.lerp(b, k as f32 / n as f32);
            let d2 = (x - c.x).powi(2) + (z - c.z).powi(2);
            (d2 <= r * r).then(|| c.y - (r * r - d2).sqrt())
        })
        .reduce(f32::min)
}

#[test]
fn a_fast_small_ball_leaves_its_swept_shape() {
    let Some(ctx) = testing::gpu() else { return };
    // 15 cm at 12 m/s, 60 frames a second: 20 cm a frame, more than its radius.
    let (radius, speed, fps) = (0.15_f32, 12.0_f32, 60.0_f32);
    let (extent, res) = (8.0_f32, 128_u32);
    let texel = extent / res as f32;
    // The centre line runs along a row of texel centres, 5 cm into the snow's rest height.
    let z = 0.5 * texel;
    let y = DEPTH_M - 0.05 - 0.5 * radius;
    let start = Vec3::new(-3.0, y, z);
    let frames = 30;
    let end = start + Vec3::X * speed * frames as f32 / fps;
    let mut trench = Vec::new();
    for teleport_m in [4.0, 0.0] {
        let mut snow = window(ctx, extent, res, DVec2::new(0.0, 0.0), Technique::Depth, teleport_m);
        for k in 0..=frames {
            let center = start + Vec3::X * speed * k as f32 / fps;
            snow.step(ctx, &[Deformer::Sphere { center, radius }], 1.0 / fps).expect("frame");
        }
        snow.finish(ctx).expect("finish");
        trench.push((snow.origin_m().expect("placed"), snow.read_snow(ctx).expect("snow")));
    }
    let (origin, swept) = &trench[0];
    let (_, unswept) = &trench[1];
    let n = res as usize;
    let centre = |i: usize, j: usize| ((origin.x + (j as f64 + 0.5) * f64::from(texel)) as f32, (origin.y + (i as f64 + 0.5) * f64::from(texel)) as f32);
    let mut worst: f32 = 0.0;
    for i in 0..n {
        for j in 0..n {
            let (x, zc) = centre(i, j);
            let expected = capsule_by_sampling(x, zc, start, end, radius).map_or(DEPTH_M, |b| b.clamp(0.0, DEPTH_M));
            worst = worst.max((swept[i * n + j] - expected).abs());
        }
    }
    // The centre line, away from the ends: flat.
    let row = n / 2;
    assert!((centre(row, 0).1 - z).abs() < 1e-4, "row {row} is not the centre line");
    let line = |snow: &[f32]| -> (f32, f32) {
        let cols = (0..n).filter(|&j| {
            let x = centre(row, j).0;
            x > start.x + radius && x < end.x - radius
        });
        cols.map(|j| snow[row * n + j]).fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), h| (lo.min(h), hi.max(h)))
    };
    let (lo, hi) = line(swept);
    let (ulo, uhi) = line(unswept);
    println!(
        "fast ball: swept trench within {:.2} mm of its swept shape, centre line ripple {:.2} mm (unswept: {:.1} mm)",
        worst * 1000.0,
        (hi - lo) * 1000.0,
        (uhi - ulo) * 1000.0
    );
    assert!(worst <= 0.02, "trench {worst} m from its swept shape");
    assert!(hi - lo <= 0.01, "centre line ripples {} m", hi - lo);
    assert!((lo - (y - radius)).abs() < 0.002, "centre line at {lo}, the ball's bottom at {}", y - radius);
    assert!(uhi - ulo > 0.02, "unswept centre line is flat too ({} m): the test has no teeth", uhi - ulo);
}

#[test]
fn a_teleport_and_a_new_deformer_do_not_sweep() {
    let Some(ctx) = testing::gpu() else { return };
    let (extent, res) = (8.0_f32, 128_u32);
    let mut snow = window(ctx, extent, res, DVec2::ZERO, Technique::Depth, 1.0);
    let ball = |x: f32| Deformer::Sphere { center: Vec3::new(x, 0.4, 0.0), radius: 0.2 };
    // A jump of 3 m (more than the 1 m teleport distance), then a new ball
    // appearing at index 1 beside a ball that stays.
    snow.step(ctx, &[ball(-2.5)], 1.0 / 60.0).expect("frame");
    snow.step(ctx, &[ball(0.5)], 1.0 / 60.0).expect("frame");
    snow.step(ctx, &[ball(0.5), ball(2.5)], 1.0 / 60.0).expect("frame");
    snow.finish(ctx).expect("finish");
    let origin = snow.origin_m().expect("placed");
    let h = snow.read_snow(ctx).expect("snow");
    let texel = extent / res as f32;
    let at = |x: f32| {
        let j = ((f64::from(x) - origin.x) / f64::from(texel)) as usize;
        let i = ((0.0 - origin.y) / f64::from(texel)) as usize;
        h[i * res as usize + j]
    };
    for x in [-2.5, 0.5, 2.5] {
        assert!(at(x) < DEPTH_M - 0.05, "no print at {x}");
    }
    for x in [-1.5, -0.5, 1.5] {
        assert!((at(x) - DEPTH_M).abs() < 1e-3, "a sweep pressed {x}: {}", at(x));
    }
}
