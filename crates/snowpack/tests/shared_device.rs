//! A game's own device: snowpack works on it, answers point queries, reports
//! its own GPU errors through `check`, and leaves the game's error handler in
//! place (the game's errors stay the game's).

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{DVec2, Vec2, Vec3};
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::SnowInspect;
use snowpack::{AdapterRequest, Deformer, GpuContext, SnowDeformation, SnowFrame, SnowParams, TerrainSource};
use snowpack_testkit::testing;

/// A device made the way a game makes it, on the adapter the tests use.
/// `None` (the test skips) only where no GPU is required: with
/// `SNOWPACK_REQUIRE_GPU` set, failing to make it fails the test.
fn game_device() -> Option<(wgpu::Device, wgpu::Queue)> {
    // The tests' context picks the adapter (honouring SNOWPACK_BACKEND); the game asks that adapter for its own device.
    testing::gpu()?;
    let made = (|| {
        let ours = GpuContext::new_headless(&AdapterRequest::from_env()).map_err(|e| format!("no adapter: {e}"))?;
        let adapter = ours.adapter().ok_or("the context has no adapter")?;
        pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor { label: Some("the game's device"), ..Default::default() }))
            .map_err(|e| format!("the adapter gives no device: {e}"))
    })();
    match made {
        Ok(device) => Some(device),
        Err(why) => {
            assert!(!testing::gpu_required(), "SNOWPACK_REQUIRE_GPU is set but the game's device could not be made: {why}");
            eprintln!("skipping: {why}");
            None
        }
    }
}

fn invalid_buffer(device: &wgpu::Device) -> wgpu::Buffer {
    // Mapping for both reading and writing is not allowed on one buffer: a validation error.
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("invalid on purpose"),
        size: 16,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::MAP_WRITE,
        mapped_at_creation: false,
    })
}

#[test]
fn snow_on_a_games_device_keeps_the_games_error_handler_and_reports_its_own_errors() {
    let Some((device, queue)) = game_device() else { return };
    let games_errors = Arc::new(AtomicUsize::new(0));
    let counter = Arc::clone(&games_errors);
    device.on_uncaptured_error(Arc::new(move |_: wgpu::Error| {
        counter.fetch_add(1, Ordering::SeqCst);
    }));

    let ctx = GpuContext::from_device(device.clone(), queue.clone());
    assert!(ctx.adapter().is_none() && ctx.instance().is_none());
    let params = SnowParams { extent_m: 8.0, resolution: 128, depth_m: 0.5, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(&ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("a window on the game's device");
    let ball = Deformer::Sphere { center: Vec3::new(0.5, 0.6, 0.5), radius: 0.4 };
    let ticket = snow.step_frame(&ctx, &SnowFrame::new(1.0 / 60.0, &[ball]).with_queries(&[Vec2::new(0.5, 0.5)])).expect("frame").expect("a ticket");
    for _ in 0..2 {
        snow.step(&ctx, &[ball], 1.0 / 60.0).expect("frame");
    }
    snow.finish(&ctx).expect("finish");
    let answers = snow.point_answers().expect("answered");
    assert_eq!(answers.ticket, ticket);
    let under = answers.samples[0].expect("inside");
    assert!((under.depth_m() - 0.2).abs() < 0.01, "the ball's print: {} m left", under.depth_m());
    assert_eq!(games_errors.load(Ordering::SeqCst), 0, "snowpack's frames raised no errors");

    // The game's own mistake goes to the game's handler, not to snowpack.
    drop(invalid_buffer(&device));
    ctx.wait_idle("after the game's error").expect("snowpack has no error of its own");
    assert_eq!(games_errors.load(Ordering::SeqCst), 1, "the game's handler is still installed");

    // An error in work snowpack does on the game's device is snowpack's: caught and returned.
    ctx.capturing(|| drop(invalid_buffer(&ctx.device)));
    match ctx.check("test").map_err(snowpack::low_level::error::SnowError::from) {
        Err(snowpack::low_level::error::SnowError::Gpu { message, .. }) => assert!(!message.is_empty()),
        other => panic!("expected snowpack's own GPU error, got {other:?}"),
    }
    assert_eq!(games_errors.load(Ordering::SeqCst), 1, "snowpack's error did not reach the game's handler");
    ctx.check("after").expect("reported once");
}
