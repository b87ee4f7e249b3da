//! wgpu's GL backend panics ("Could not lock adapter context") when a call
//! waits more than 6 s for the context another thread holds. On llvmpipe a
//! submission runs in the submitting thread with the context held, so one
//! long submission of another thread is enough, in the middle of a frame.
//! The library's calls turn that panic into `SnowErrorKind::DeviceLost`
//! (the interrupted call left wgpu's state unknown), and every later call
//! on the same context fails the same way at once, never panicking.
//!
//! GL only (Vulkan has no context lock): on another backend the test says
//! so and returns; `.ci/run` runs the library's tests on GL as well. It owns
//! its context, which it leaves unusable, and takes about 15 s.

use std::sync::mpsc;
use std::time::{Duration, Instant};

use glam::{DVec2, Vec3};
use snowpack::low_level::GpuContextExt;
use snowpack::{AdapterRequest, Deformer, GpuContext, SnowDeformation, SnowErrorKind, SnowParams, TerrainSource};
use snowpack_testkit::testing;

/// A compute pass that runs `iterations` dependent steps per invocation
/// over 65,536 invocations: long on a CPU rasteriser, in one submission.
const BUSY: &str = "
@group(0) @binding(0) var<storage, read_write> out: array<f32>;
@group(0) @binding(1) var<uniform> iterations: vec4<u32>;
@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    var s = f32(id.x + id.y);
    for (var i = 0u; i < iterations.x; i++) { s = sin(s) + f32(i & 7u); }
    out[id.y * 256u + id.x] = s;
}";

/// How long the other thread's submission is made to take (s): well over
/// wgpu's 6 s lock timeout, so that a machine three times faster than the
/// calibration found it still holds the context long enough.
const HOLD_S: f64 = 14.0;

/// One dispatch of [`BUSY`] on `ctx`'s device.
struct Busy {
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    iterations: wgpu::Buffer,
}

impl Busy {
    fn new(ctx: &GpuContext) -> Self {
        let device = &ctx.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("busy"), source: wgpu::ShaderSource::Wgsl(BUSY.into()) });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("busy"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            cache: None,
        });
        let out = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("busy out"),
            size: 256 * 256 * 4,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let iterations = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("busy iterations"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("busy"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: out.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: iterations.as_entire_binding() },
            ],
        });
        Self { pipeline, bind_group, iterations }
    }

    /// Submits `dispatches` dispatches of `iterations` steps in one
    /// submission; on GL (llvmpipe) the submit returns when the work is done.
    fn submit(&self, ctx: &GpuContext, iterations: u32, dispatches: u32) {
        ctx.queue.write_buffer(&self.iterations, 0, bytemuck::cast_slice(&[iterations, 0, 0, 0]));
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("busy") });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("busy"), timestamp_writes: None });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            for _ in 0..dispatches {
                pass.dispatch_workgroups(32, 32, 1);
            }
        }
        ctx.queue.submit([encoder.finish()]);
    }
}

#[test]
fn a_frame_that_cannot_lock_the_gl_context_fails_with_an_error() {
    let Some(shared) = testing::gpu() else { return };
    if shared.summary.backend != "gl" {
        eprintln!("the GL context lock is GL's: skipped on {} (run with SNOWPACK_BACKEND=gl)", shared.summary.backend);
        return;
    }
    let ctx = GpuContext::new_headless(&AdapterRequest::from_env()).expect("a GL context of the test's own");
    let params = SnowParams { extent_m: 8.0, resolution: 64, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(&ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    let ball = [Deformer::Sphere { center: Vec3::new(0.0, 0.3, 0.0), radius: 0.3 }];
    snow.step_frame(&ctx, &snowpack::SnowFrame::new(1.0 / 60.0, &ball)).expect("a frame while nothing holds the context");
    ctx.wait_idle("before the calibration").expect("idle");

    // Calibrate: dispatches of doubling length (the submit is the work on
    // GL) until one takes half a second, then enough of that one in a
    // single submission for HOLD_S (a dispatch's time does not grow in
    // proportion to its iterations; the submission's grows with its
    // dispatches).
    let busy = Busy::new(&ctx);
    let (mut probe, mut took) = (1000_u32, 0.0);
    while took < 0.5 && probe < 1 << 30 {
        probe *= 2;
        let start = Instant::now();
        busy.submit(&ctx, probe, 1);
        took = start.elapsed().as_secs_f64();
    }
    let dispatches = (HOLD_S / took).ceil() as u32;
    eprintln!("{probe} iterations took {took:.2} s; the other thread submits {dispatches} of them");

    let (started, wait_started) = mpsc::channel();
    let outcome = std::thread::scope(|scope| {
        let holder = scope.spawn(|| {
            started.send(()).expect("the frame's thread waits for this");
            let start = Instant::now();
            busy.submit(&ctx, probe, dispatches);
            start.elapsed()
        });
        wait_started.recv().expect("the other thread started");
        // Let its submission take the context first.
        std::thread::sleep(Duration::from_millis(300));
        let frame = snow.step_frame(&ctx, &snowpack::SnowFrame::new(1.0 / 60.0, &ball)).map(|_| ());
        let held = holder.join().expect("the submitting thread");
        (frame, held)
    });
    let (frame, held) = outcome;
    eprintln!("the other thread's submission held the context {:.1} s", held.as_secs_f64());
    assert!(held > Duration::from_secs(7), "the calibration missed: the submission took {held:?}, not over wgpu's 6 s, so nothing was tested");
    let error = frame.expect_err("a frame that waited over 6 s for the GL context");
    assert_eq!(error.kind(), SnowErrorKind::DeviceLost, "{error}");
    assert!(error.to_string().contains("OpenGL context could not be locked"), "{error}");

    // The context is left unusable: later calls fail with the same error, at once.
    let again = snow.step_frame(&ctx, &snowpack::SnowFrame::new(1.0 / 60.0, &ball)).expect_err("a frame after the lock failed");
    assert_eq!(again.kind(), SnowErrorKind::DeviceLost, "{again}");
    assert!(snow.finish(&ctx).is_err_and(|e| e.kind() == SnowErrorKind::DeviceLost));
    assert!(ctx.check("after the lock failed").is_err_and(|e| e.kind() == SnowErrorKind::DeviceLost));
}
