//! The capture pass alone, from submission to idle, with its analytic
//! shapes ray cast by compute and drawn (`ShapeCapture`), side by side: the
//! median wall time of recording only `CapturePass` over a 64 m, 1024²
//! window, after a warm-up, for 1, 256, 4,096 and 16,384 spheres swept over
//! the frame, 64 turning boxes and 64 treaded wheels (each swept in
//! sub-steps). Every capture is its own submission, waited for, so on a
//! software adapter (lavapipe, llvmpipe) the figure is the work the pass
//! makes the CPU do, and the two columns compare the two ways on the same
//! machine (ratios only); on a real GPU it includes the submission's
//! overhead, and `snowpack bench --only capture`'s timestamps are the
//! figure to read. Then whole frames (`SnowDeformation::step`, 30 after 10
//! of warm-up, waited for at the end): the wall time a frame takes either
//! way, which on a software adapter is the truth its per-pass timestamps
//! are not (it moves work between them).
//!
//! ```text
//! cargo run --release -p snowpack --example capture_cost [-- --frames N]
//! ```

use std::time::Instant;

use glam::{DVec2, Quat, Vec3};
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::deform::capture::{CaptureInstances, CaptureParams, CapturePass, ShapeCapture};
use snowpack::low_level::deform::resources::DeformResources;
use snowpack::low_level::deform::wheel::{Tread, TreadPattern};
use snowpack::low_level::frame::FrameContext;
use snowpack::low_level::gpu::GpuTimer;
use snowpack::{AdapterRequest, Deformer, GpuContext, SnowDeformation, SnowParams, TerrainSource};
use snowpack_testkit::testing;

/// The deformers of scenario `name` at time `t` (s).
fn deformers(name: &str, count: usize, t: f32) -> Vec<Deformer> {
    match name {
        "boxes" => (0..count)
            .map(|k| {
                let (x, z) = ((k % 8) as f32 * 6.0 - 21.0 + 6.0 * t, (k / 8) as f32 * 6.0 - 21.0);
                Deformer::Box { center: Vec3::new(x, 0.8, z), half_extents: Vec3::new(0.5, 1.0, 1.0), rotation: Quat::from_rotation_y(t + k as f32) }
            })
            .collect(),
        "wheels" => (0..count)
            .map(|k| {
                let (x, z) = ((k % 8) as f32 * 6.0 - 21.0 + 12.0 * t, (k / 8) as f32 * 6.0 - 21.0);
                let tread = Tread { pattern: TreadPattern::Chevron, spacing_m: 0.12, depth_m: 0.03, lug_fraction: 0.5 };
                Deformer::Wheel { center: Vec3::new(x, 0.43, z), axle: Vec3::Z, radius: 0.33, half_width: 0.12, tread, roll_m: 12.0 * t }
            })
            .collect(),
        _ => testing::circling_spheres(count, t),
    }
}

/// Median milliseconds of one capture, submission to idle.
fn measure(ctx: &GpuContext, (name, count): (&str, usize), by: ShapeCapture, (warmup, frames): (u32, u32)) -> Result<f64, snowpack::SnowError> {
    let params = SnowParams { extent_m: 64.0, resolution: 1024, ..SnowParams::default() };
    let mut res = DeformResources::new(&ctx.device, &ctx.queue, &params, &TerrainSource::Flat { height_m: 0.0 });
    res.allocate_capture(&ctx.device, (true, true));
    let cparams = CaptureParams { extent_m: 64.0, texel_m: params.extent_m / params.resolution as f32, low_m: -1.0, high_m: 2.0 };
    let mut capture = CapturePass::new(&ctx.device, by);
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut times = Vec::new();
    for frame in 0..warmup + frames {
        let t = frame as f32 / 60.0;
        let previous: Vec<Option<Deformer>> = deformers(name, count, t - 1.0 / 60.0).into_iter().map(Some).collect();
        let instances = CaptureInstances::swept(&deformers(name, count, t), &previous, DVec2::new(-32.0, -32.0), &cparams);
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("capture cost") });
        let start = Instant::now();
        capture.record(&mut FrameContext::new(ctx, &mut encoder, &mut timer), &res, (&cparams, &instances), &[]);
        ctx.queue.submit([encoder.finish()]);
        ctx.wait_idle("a capture")?;
        if frame >= warmup {
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    ctx.check("the captures")?;
    times.sort_by(f64::total_cmp);
    Ok(times[times.len() / 2])
}

/// Wall milliseconds a whole frame of `count` circling spheres takes, the shapes taken `by`.
fn frame_ms(ctx: &GpuContext, count: usize, by: ShapeCapture) -> Result<f64, snowpack::SnowError> {
    let params = SnowParams { tile_memory_bytes: None, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO)?;
    snow.set_shape_capture(by);
    let step = |snow: &mut SnowDeformation, frame: u32| snow.step(ctx, &testing::circling_spheres(count, frame as f32 / 60.0), 1.0 / 60.0);
    for frame in 0..10 {
        step(&mut snow, frame)?;
    }
    snow.finish(ctx)?;
    let start = Instant::now();
    for frame in 10..40 {
        step(&mut snow, frame)?;
    }
    snow.finish(ctx)?;
    Ok(start.elapsed().as_secs_f64() * 1e3 / 30.0)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let frames = args.iter().position(|a| a == "--frames").and_then(|i| args.get(i + 1)).and_then(|s| s.parse().ok()).unwrap_or(30);
    let ctx = GpuContext::new_headless(&AdapterRequest::from_env())?;
    println!("adapter: {} ({}); {frames} captures after 10 of warm-up, median ms from submission to idle", ctx.summary.name, ctx.summary.backend);
    println!("{:>15} {:>10} {:>10}", "shapes", "compute", "raster");
    for scenario in [("spheres", 1), ("spheres", 256), ("spheres", 4096), ("spheres", 16384), ("boxes", 64), ("wheels", 64)] {
        let compute = measure(&ctx, scenario, ShapeCapture::Compute, (10, frames))?;
        let raster = measure(&ctx, scenario, ShapeCapture::Raster, (10, frames))?;
        println!("{:>6} {:<8} {compute:>10.3} {raster:>10.3}", scenario.1, scenario.0);
    }
    println!("whole frames, wall ms (64 m, 1024² window, circling spheres)");
    for count in [1, 256, 4096] {
        let (compute, raster) = (frame_ms(&ctx, count, ShapeCapture::Compute)?, frame_ms(&ctx, count, ShapeCapture::Raster)?);
        println!("{count:>6} spheres {compute:>10.3} {raster:>10.3}");
    }
    Ok(())
}
