//! Stress on the software adapter: 4,000 bouncing spheres for 600 frames
//! and 16,384 point actors for 300 frames. The snow stays finite and between
//! the terrain and the rest height, the spheres do press it, and GPU memory
//! is flat after warm-up (no growth frame over frame). Prints the wall time
//! per frame (lavapipe: ratios only; recorded in docs/PERFORMANCE.md).

use std::time::Instant;

use glam::{DVec2, Vec3};
use snowpack::low_level::testing::{self, Rng};
use snowpack::{Deformer, GpuContext, NoiseTerrain, SnowDeformation, SnowParams, Technique, TerrainSource};

fn memory(snow: &SnowDeformation) -> u64 {
    snow.memory_bytes().iter().map(|(_, b)| b).sum()
}

/// Checks every texel: finite, within terrain..rest (rest = terrain + depth,
/// no snowfall), and returns how many are pressed by more than 5 cm.
fn check_snow(ctx: &GpuContext, snow: &SnowDeformation, depth_m: f32, what: &str) -> usize {
    let heights = snow.read_snow(ctx).expect("snow");
    let terrain = snow.read_terrain(ctx).expect("terrain");
    let (shown, normals) = snow.read_surface(ctx).expect("surface");
    let mut pressed = 0;
    for k in 0..heights.len() {
        let (h, t) = (heights[k], terrain[k]);
        assert!(h.is_finite() && shown[k].is_finite() && normals[k].iter().all(|c| c.is_finite()), "{what}: texel {k} is not finite");
        assert!(h >= t - 1e-5 && h <= t + depth_m + 1e-4, "{what}: snow {h} outside terrain {t} .. rest {} at {k}", t + depth_m);
        pressed += usize::from(h < t + depth_m - 0.05);
    }
    pressed
}

/// Runs `frames` frames of `deformers_at(frame)`; asserts memory is flat
/// after `warmup` frames and returns the mean wall time per frame after it (ms).
fn run(ctx: &GpuContext, snow: &mut SnowDeformation, frames: usize, warmup: usize, mut deformers_at: impl FnMut(usize) -> Vec<Deformer>, what: &str) -> f64 {
    let mut settled = 0;
    let mut start = Instant::now();
    for frame in 0..frames {
        let deformers = deformers_at(frame);
        snow.step(ctx, &deformers, 1.0 / 60.0).unwrap_or_else(|e| panic!("{what}: frame {frame}: {e}"));
        if frame + 1 == warmup {
            ctx.wait_idle("warm-up").expect("idle");
            settled = memory(snow);
            start = Instant::now();
        } else if frame + 1 > warmup {
            assert_eq!(memory(snow), settled, "{what}: GPU memory grew at frame {frame}: {:?}", snow.memory_bytes());
        }
    }
    snow.finish(ctx).expect("finish");
    start.elapsed().as_secs_f64() * 1000.0 / (frames - warmup) as f64
}

#[test]
fn four_thousand_bouncing_spheres_for_600_frames() {
    let Some(ctx) = testing::gpu() else { return };
    let mut rng = Rng::new(testing::seed("stress spheres"));
    let depth = 0.5;
    let params = SnowParams { extent_m: 64.0, resolution: 256, depth_m: depth, refill_m_per_s: 0.01, tile_memory_bytes: None, ..SnowParams::default() };
    let terrain = TerrainSource::Noise(NoiseTerrain { seed: 11, base_m: 0.0, amplitude_m: 3.0, wavelength_m: 24.0 });
    let mut snow = SnowDeformation::new(ctx, params, terrain.clone(), DVec2::ZERO).expect("window");
    // Each sphere bounces on the spot above its own ground, its lowest point
    // from 0.6 m above the snow to 0.3 m into it, with its own phase.
    let balls: Vec<(f32, f32, f32, f32, f32)> = (0..4000)
        .map(|_| {
            let (x, z) = (rng.range(-30.0, 30.0), rng.range(-30.0, 30.0));
            (x, z, terrain.height_at(x, z), rng.range(0.2, 0.5), rng.range(0.0, std::f32::consts::TAU))
        })
        .collect();
    let ms = run(
        ctx,
        &mut snow,
        600,
        60,
        |frame| {
            let t = frame as f32 / 60.0;
            balls
                .iter()
                .map(|&(x, z, ground, r, phase)| {
                    let bottom = ground + depth - 0.3 + 0.9 * (t * 3.0 + phase).sin().abs();
                    Deformer::Sphere { center: Vec3::new(x, bottom + r, z), radius: r }
                })
                .collect()
        },
        "4,000 spheres",
    );
    let pressed = check_snow(ctx, &snow, depth, "4,000 spheres");
    eprintln!("4,000 spheres, 256², 600 frames: {ms:.1} ms a frame after warm-up (wall, submit to the next frame), {pressed} texels pressed over 5 cm");
    assert!(pressed > 2000, "only {pressed} texels pressed: the spheres did not reach the snow");
}

#[test]
fn sixteen_thousand_point_actors_for_300_frames() {
    let Some(ctx) = testing::gpu() else { return };
    let mut rng = Rng::new(testing::seed("stress points"));
    let depth = 0.4;
    let params = SnowParams {
        extent_m: 32.0,
        resolution: 256,
        depth_m: depth,
        technique: Technique::Points,
        range_texels: 32,
        tile_memory_bytes: None,
        ..SnowParams::default()
    };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    // Feet walking in straight lines at their own speeds, planted 0.2 m into the snow.
    let feet: Vec<(f32, f32, f32, f32)> =
        (0..16_384).map(|_| (rng.range(-15.0, 15.0), rng.range(-15.0, 15.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0))).collect();
    let ms = run(
        ctx,
        &mut snow,
        300,
        30,
        |frame| {
            let t = frame as f32 / 60.0;
            feet.iter()
                .map(|&(x, z, vx, vz)| Deformer::Point {
                    position: Vec3::new((x + vx * t).clamp(-15.5, 15.5), depth - 0.2, (z + vz * t).clamp(-15.5, 15.5)),
                    scale_per_m: 4.0,
                })
                .collect()
        },
        "16,384 points",
    );
    assert_eq!(snow.points_last_frame(), 16_384, "every foot is a contact point");
    assert_eq!(snow.points_dropped(), 0);
    let pressed = check_snow(ctx, &snow, depth, "16,384 points");
    eprintln!("16,384 points, 256², 300 frames: {ms:.1} ms a frame after warm-up (wall), {pressed} texels pressed over 5 cm");
    assert!(pressed > 5000, "only {pressed} texels pressed");
}
