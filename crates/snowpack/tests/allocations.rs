//! A frame's heap allocations do not grow with its work: after a warm-up,
//! `SnowDeformation::encode` with 4,096 moving spheres allocates no more per
//! frame than with 128, and at most a small constant more than an empty
//! frame does: each list a frame uploads is one `queue.write_buffer`, whose
//! staging buffer costs wgpu about ten allocations (the capture's shapes;
//! with points or combined also the stamp pass's points), and the capture
//! records its compute pass only when there are shapes, while snowpack's
//! own lists and buffers are reused. Counted with a
//! counting global allocator, so this is a test binary of its own (one
//! test: nothing else allocates meanwhile). No timings are asserted
//! (`examples/encode_cost.rs` measures those).

use glam::DVec2;
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::TechniqueExt;
use snowpack::{GpuContext, SnowDeformation, SnowFrame, SnowParams, Technique, TerrainSource};
use snowpack_testkit::testing;
use stats_alloc::{INSTRUMENTED_SYSTEM, Region, StatsAlloc};

#[global_allocator]
static ALLOCATOR: &StatsAlloc<std::alloc::System> = &INSTRUMENTED_SYSTEM;

/// Allocations a frame with deformers may make beyond the empty frame's
/// most: wgpu's staging for up to two uploads, the capture's compute pass
/// (an empty frame records none: it has no shape to ray cast), and a few
/// more.
const SLACK: u64 = 32;
/// Allocations 4,096 deformers may make beyond 128's most.
const GROWTH: u64 = 2;
const WARMUP: u32 = 30;
const FRAMES: u32 = 40;

/// (mean, most) allocations per frame of `encode` alone after the warm-up.
fn allocations(ctx: &GpuContext, technique: Technique, count: usize) -> (f64, u64) {
    let params = SnowParams { extent_m: 64.0, resolution: 256, technique, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    let mut counts = Vec::new();
    for frame in 0..WARMUP + FRAMES {
        let deformers = testing::circling_spheres(count, frame as f32 / 60.0);
        let snow_frame = SnowFrame::new(1.0 / 60.0, &deformers);
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("allocation frame") });
        let region = Region::new(ALLOCATOR);
        let ticket = snow.encode(ctx, &mut encoder, &snow_frame);
        let change = region.change();
        // The frame asked no points, so `encode` hands back no query ticket.
        assert!(ticket.is_none(), "frame {frame}: a query ticket for a frame that asked nothing");
        if frame >= WARMUP {
            counts.push((change.allocations + change.reallocations) as u64);
        }
        ctx.queue.submit([encoder.finish()]);
        // The next frame finds this one's readbacks back, as a game's would.
        ctx.wait_idle("an allocation frame").expect("wait");
    }
    ctx.check("the allocation frames").expect("no GPU error");
    assert!(snow.points_last_frame() > 0 || !technique.uses_stamps() || count == 0, "the spheres pressed no point");
    (counts.iter().sum::<u64>() as f64 / counts.len() as f64, counts.iter().copied().max().unwrap_or(0))
}

#[test]
fn a_frame_with_thousands_of_deformers_allocates_as_little_as_an_empty_one() {
    let Some(ctx) = testing::gpu() else { return };
    for technique in [Technique::Depth, Technique::Combined] {
        let (empty_mean, empty_max) = allocations(ctx, technique, 0);
        let (few_mean, few_max) = allocations(ctx, technique, 128);
        let (mean, max) = allocations(ctx, technique, 4096);
        eprintln!(
            "{technique:?}: allocations per frame, mean (most): empty {empty_mean:.1} ({empty_max}), 128 spheres {few_mean:.1} ({few_max}), 4,096 spheres {mean:.1} ({max})"
        );
        assert!(max <= few_max + GROWTH, "{technique:?}: a frame of 4,096 spheres made {max} allocations, of 128 at most {few_max}");
        assert!(max <= empty_max + SLACK, "{technique:?}: a frame of 4,096 spheres made {max} allocations, an empty one at most {empty_max}");
    }
}
