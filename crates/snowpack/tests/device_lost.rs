//! A lost device is reported, not a panic or a hang: after
//! `device.destroy()` the next blocking wait returns
//! `SnowError::DeviceLost`, and so does every frame after it (the demo and
//! the runner print it and exit with an error). On GL the next frame already
//! says so; on Vulkan wgpu reports it only at a poll that waits.

use glam::{DVec2, Vec3};
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::SnowInspect;
use snowpack::{AdapterRequest, Deformer, GpuContext, SnowDeformation, SnowErrorKind, SnowParams, TerrainSource, low_level};
use snowpack_testkit::testing;

#[test]
fn a_destroyed_device_gives_device_lost_to_the_caller() {
    // The shared context picks the adapter; this test destroys a device of its own.
    if testing::gpu().is_none() {
        return;
    }
    let ctx = GpuContext::new_headless(&AdapterRequest::from_env()).expect("a second device on the tests' adapter");
    let params = SnowParams { extent_m: 8.0, resolution: 64, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(&ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    let ball = [Deformer::Sphere { center: Vec3::new(0.0, 0.3, 0.0), radius: 0.3 }];
    snow.step(&ctx, &ball, 1.0 / 60.0).expect("a frame on a working device");

    ctx.device.destroy();
    // Frames go on being asked for (a game loop does not know yet). They
    // must not panic or hang, and may not see the loss yet: wgpu calls the
    // device-lost callback at a poll that finds the queue empty, which on GL
    // is the next frame's poll and on Vulkan the next blocking wait.
    for k in 0..3 {
        match snow.step(&ctx, &ball, 1.0 / 60.0) {
            Ok(()) => {}
            Err(e) if e.kind() == SnowErrorKind::DeviceLost => {}
            Err(other) => panic!("frame {k} after the loss gave {other}, not DeviceLost"),
        }
    }
    // A blocking wait (`finish`, a save, the end of a run) reports it on every
    // backend, and so does every frame after that.
    assert!(matches!(snow.finish(&ctx).map_err(low_level::error::SnowError::from), Err(low_level::error::SnowError::DeviceLost(reason)) if !reason.is_empty()));
    for _ in 0..2 {
        assert!(snow.step(&ctx, &ball, 1.0 / 60.0).is_err_and(|e| e.kind() == SnowErrorKind::DeviceLost));
    }
    assert!(ctx.check("after the loss").is_err_and(|e| e.kind() == SnowErrorKind::DeviceLost));
}
