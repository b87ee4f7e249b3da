//! Stress on the software adapter: 4,000 bouncing spheres for 600 frames
//! and 16,384 point actors for 300 frames, carried along with a window that
//! moves across tiles the whole run (round a circle, so that after the first
//! lap every tile it passes is one it has kept before). The snow stays
//! finite and between the terrain and the rest height, the actors do press
//! it, and memory stays flat after warm-up, measured two ways:
//!
//! - the Rust heap (a counting global allocator: the library's and wgpu's
//!   own memory), within [`HEAP_BOUND`] on every adapter;
//! - the process's resident memory (`/proc/self/status`, VmRSS: on a
//!   software adapter the GPU's buffers and the driver's own memory are in
//!   it), within [`RSS_BOUND`]. This is what found the decal rings filling
//!   with a crowd's contacts (500 MiB for 16,384 actors) and Mesa 22's
//!   lavapipe keeping a compiled copy of a shader at every dispatch when
//!   one of its branches tests uniforms alone (docs/PERFORMANCE.md,
//!   "Stress"). `.ci/run` runs these tests on the system's adapter (Debian
//!   12's lavapipe, the driver that keeps those copies); the figures on
//!   llvmpipe's GL and on lavapipe from Mesa 25 are in the same section.
//!
//! Prints the wall time per frame and the memory figures (software
//! adapters: ratios only).

use std::time::Instant;

use glam::{DVec2, Vec3};
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::SnowInspect;
use snowpack::{Deformer, GpuContext, SnowDeformation, SnowParams, Technique, TerrainSource};
use snowpack_testkit::testing::{self, Rng};
use stats_alloc::{INSTRUMENTED_SYSTEM, StatsAlloc};

#[global_allocator]
static ALLOCATOR: &StatsAlloc<std::alloc::System> = &INSTRUMENTED_SYSTEM;

fn memory(snow: &SnowDeformation) -> u64 {
    snow.memory_bytes().iter().map(|(_, b)| b).sum()
}

/// The process's resident memory (bytes), from `/proc/self/status`.
fn resident_bytes() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status (the stress test measures memory on Linux)");
    let kb: u64 = status.lines().find_map(|l| l.strip_prefix("VmRSS:")).and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok()).expect("VmRSS in kB");
    kb * 1024
}

/// Bytes the Rust heap holds now, as the counting allocator saw them:
/// allocated less freed (its byte counts take in each reallocation's growth
/// or shrinking already).
fn heap_bytes() -> i64 {
    let stats = ALLOCATOR.stats();
    stats.bytes_allocated as i64 - stats.bytes_deallocated as i64
}

/// Most the Rust heap may grow after warm-up (bytes). Measured: within a
/// few hundred KiB on every adapter (docs/PERFORMANCE.md, "Stress"); a tile
/// record or a staging buffer kept each frame would pass it within the run.
const HEAP_BOUND: i64 = 2 << 20;

/// Most the resident memory may grow after warm-up (bytes): measured
/// within 1 MiB on Mesa 22's lavapipe and GL and on Mesa 25's lavapipe
/// (docs/PERFORMANCE.md, "Stress"). A tile of the points' window (64 KiB)
/// kept each frame, or a decal ring per actor filling, would pass it within
/// the 150 frames after warm-up.
const RSS_BOUND: u64 = 8 << 20;

/// One stress test at a time: both run in one process, whose resident
/// memory each measures.
static ALONE: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The window's centre at `frame`: round a circle of `radius_m` in `lap` frames.
fn circling(frame: usize, radius_m: f64, lap: usize) -> DVec2 {
    let a = std::f64::consts::TAU * frame as f64 / lap as f64;
    DVec2::new(radius_m * a.cos(), radius_m * a.sin())
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

/// Runs `frames` frames of `deformers_at(frame, centre)` with the window
/// centred at `centre_at(frame)`; asserts the Rust heap stays within
/// [`HEAP_BOUND`] and the resident memory within `rss_bound` bytes of their
/// levels after `warmup` frames, and returns the mean wall time per frame
/// after it (ms).
fn run(
    ctx: &GpuContext,
    snow: &mut SnowDeformation,
    (frames, warmup, rss_bound): (usize, usize, u64),
    centre_at: impl Fn(usize) -> DVec2,
    mut deformers_at: impl FnMut(usize, DVec2) -> Vec<Deformer>,
    what: &str,
) -> f64 {
    let (mut settled, mut highest, mut ledger) = (0, 0, 0);
    let (mut heap_settled, mut heap_highest) = (0, 0);
    // The resident memory (MiB) and the Rust heap (KiB) every 50 frames, warm-up included, for the report.
    let mut trace = Vec::new();
    let mut start = Instant::now();
    let first_origin = snow.origin_m();
    for frame in 0..frames {
        let centre = centre_at(frame);
        snow.set_center(centre);
        let deformers = deformers_at(frame, centre);
        snow.step(ctx, &deformers, 1.0 / 60.0).unwrap_or_else(|e| panic!("{what}: frame {frame}: {e}"));
        let rss = resident_bytes();
        if frame % 50 == 0 {
            trace.push((rss >> 20, heap_bytes() >> 10));
        }
        if frame + 1 == warmup {
            ctx.wait_idle("warm-up").expect("idle");
            settled = resident_bytes();
            heap_settled = heap_bytes();
            heap_highest = heap_settled;
            start = Instant::now();
        } else if frame + 1 > warmup {
            highest = highest.max(rss);
            ledger = ledger.max(memory(snow));
            let heap = heap_bytes();
            heap_highest = heap_highest.max(heap);
            assert!(
                heap <= heap_settled + HEAP_BOUND,
                "{what}: the Rust heap grew by {} KiB by frame {frame} (bound {} KiB): the library or wgpu keeps memory frame after frame",
                (heap - heap_settled) >> 10,
                HEAP_BOUND >> 10
            );
            assert!(
                rss <= settled + rss_bound,
                "{what}: resident memory grew by {} MiB by frame {frame} (bound {} MiB; every 50 frames: {trace:?} (MiB, KiB))",
                (rss - settled) >> 20,
                rss_bound >> 20
            );
        }
    }
    snow.finish(ctx).expect("finish");
    let ms = start.elapsed().as_secs_f64() * 1000.0 / (frames - warmup) as f64;
    let tiles = snow.tile_stats().expect("tiles are kept");
    assert!(snow.origin_m() != first_origin && tiles.evicted > 100 && tiles.restored > 100, "{what}: the window did not travel across tiles: {tiles:?}");
    let mib = |b: u64| b as f64 / f64::from(1 << 20);
    eprintln!(
        "{what} on {} ({}, {}): resident memory {:.1} MiB after warm-up, at most {:.1} MiB after ({:+.1} MiB, bound {} MiB; every 50 frames: {trace:?} (MiB, KiB)); the Rust heap {:+.0} KiB at most; the library's GPU ledger at most {:.1} MiB; {} tiles copied out, {} restored, {} window waits",
        ctx.summary.name,
        ctx.summary.backend,
        ctx.summary.driver,
        mib(settled),
        mib(highest),
        mib(highest) - mib(settled),
        rss_bound >> 20,
        (heap_highest - heap_settled) as f64 / 1024.0,
        mib(ledger),
        tiles.evicted,
        tiles.restored,
        tiles.window_waits
    );
    ms
}

#[test]
fn four_thousand_bouncing_spheres_for_600_frames() {
    let _alone = ALONE.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let Some(ctx) = testing::gpu() else { return };
    let mut rng = Rng::new(testing::seed("stress spheres"));
    let depth = 0.5;
    let params = SnowParams { extent_m: 64.0, resolution: 256, depth_m: depth, refill_m_per_s: 0.01, ..SnowParams::default() };
    let terrain = TerrainSource::Noise(snowpack::NoiseTerrain { seed: 7, base_m: 0.0, amplitude_m: 1.0, wavelength_m: 12.0 });
    let mut snow = SnowDeformation::new(ctx, params, terrain.clone(), DVec2::ZERO).expect("window");
    // Each sphere bounces where it is in the window, which carries it round
    // a circle of 40 m (a lap in 200 frames, 1.3 m a frame: a tile of 8 m
    // every 6 frames), its lowest point from 0.6 m above the snow to 0.3 m
    // into it, with its own phase. Warm-up: the first lap and a half.
    let balls: Vec<(f32, f32, f32, f32)> =
        (0..4000).map(|_| (rng.range(-30.0, 30.0), rng.range(-30.0, 30.0), rng.range(0.2, 0.5), rng.range(0.0, std::f32::consts::TAU))).collect();
    let ms = run(
        ctx,
        &mut snow,
        (600, 300, RSS_BOUND),
        |frame| circling(frame, 40.0, 200),
        |frame, centre| {
            let t = frame as f32 / 60.0;
            balls
                .iter()
                .map(|&(dx, dz, r, phase)| {
                    let (x, z) = (centre.x as f32 + dx, centre.y as f32 + dz);
                    let bottom = terrain.height_at(x, z) + depth - 0.3 + 0.9 * (t * 3.0 + phase).sin().abs();
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
    let _alone = ALONE.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let Some(ctx) = testing::gpu() else { return };
    let mut rng = Rng::new(testing::seed("stress points"));
    let depth = 0.4;
    let params = SnowParams { extent_m: 32.0, resolution: 256, depth_m: depth, technique: Technique::Points, range_texels: 32, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    // Feet walking in straight lines at their own speeds within the window,
    // which carries them round a circle of 20 m (a lap in 100 frames),
    // planted 0.2 m into the snow. Warm-up: the first lap and a half.
    let feet: Vec<(f32, f32, f32, f32)> =
        (0..16_384).map(|_| (rng.range(-15.0, 15.0), rng.range(-15.0, 15.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0))).collect();
    let ms = run(
        ctx,
        &mut snow,
        (300, 150, RSS_BOUND),
        |frame| circling(frame, 20.0, 100),
        |frame, centre| {
            let t = frame as f32 / 60.0;
            feet.iter()
                .map(|&(x, z, vx, vz)| Deformer::Point {
                    position: Vec3::new(centre.x as f32 + (x + vx * t).clamp(-15.5, 15.5), depth - 0.2, centre.y as f32 + (z + vz * t).clamp(-15.5, 15.5)),
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
