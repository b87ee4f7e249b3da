//! The CPU cost of `SnowDeformation::encode` alone: median time and heap
//! allocations per frame (mean and most) with 0, 128, 1,024 and 4,096
//! spheres moving over a 64 m, 1024² window, after a warm-up. Submitting and
//! the GPU's work are outside the measurement (each frame is waited for
//! before the next, so every frame finds the last one's readbacks back),
//! which makes the figures meaningful on a software adapter too.
//!
//! ```text
//! cargo run --release -p snowpack --example encode_cost [-- --frames N]
//! ```

use std::time::Instant;

use glam::DVec2;
use snowpack::low_level::GpuContextExt;
use snowpack::{AdapterRequest, GpuContext, SnowDeformation, SnowFrame, SnowParams, TerrainSource};
use snowpack_testkit::testing;
use stats_alloc::{INSTRUMENTED_SYSTEM, Region, StatsAlloc};

/// Every allocation of the process counted (`stats_alloc`: no unsafe code here).
#[global_allocator]
static ALLOCATOR: &StatsAlloc<std::alloc::System> = &INSTRUMENTED_SYSTEM;

/// What one configuration cost per measured frame.
struct Cost {
    median_ms: f64,
    mean_allocs: f64,
    max_allocs: u64,
}

fn measure(ctx: &GpuContext, count: usize, warmup: u32, frames: u32) -> Result<Cost, snowpack::SnowError> {
    let params = SnowParams { extent_m: 64.0, resolution: 1024, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO)?;
    let (mut times, mut allocs) = (Vec::new(), Vec::new());
    for frame in 0..warmup + frames {
        let deformers = testing::circling_spheres(count, frame as f32 / 60.0);
        let snow_frame = SnowFrame::new(1.0 / 60.0, &deformers);
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("encode cost") });
        let region = Region::new(ALLOCATOR);
        let start = Instant::now();
        let _ = snow.encode(ctx, &mut encoder, &snow_frame);
        let elapsed = start.elapsed();
        let change = region.change();
        if frame >= warmup {
            times.push(elapsed.as_secs_f64() * 1e3);
            allocs.push((change.allocations + change.reallocations) as u64);
        }
        ctx.queue.submit([encoder.finish()]);
        ctx.wait_idle("an encode-cost frame")?;
    }
    ctx.check("the encode-cost frames")?;
    times.sort_by(f64::total_cmp);
    Ok(Cost {
        median_ms: times[times.len() / 2],
        mean_allocs: allocs.iter().sum::<u64>() as f64 / allocs.len() as f64,
        max_allocs: allocs.iter().copied().max().unwrap_or(0),
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let frames = match (args.next().as_deref(), args.next()) {
        (Some("--frames"), Some(n)) => n.parse()?,
        _ => 200,
    };
    let ctx = GpuContext::new_headless(&AdapterRequest::from_env())?;
    println!("adapter: {} ({}); 64 m, 1024², {frames} frames after 60 of warm-up", ctx.summary.name, ctx.summary.backend);
    println!("{:>8}  {:>12}  {:>12}  {:>11}", "spheres", "encode (ms)", "allocs mean", "allocs max");
    for count in [0, 128, 1024, 4096] {
        let cost = measure(&ctx, count, 60, frames)?;
        println!("{count:>8}  {:>12.3}  {:>12.1}  {:>11}", cost.median_ms, cost.mean_allocs, cost.max_allocs);
    }
    Ok(())
}
