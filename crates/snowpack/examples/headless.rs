//! Headless snowpack: a ball rolls a trench into fresh snow on a game's own
//! wgpu device, the game asks where its "feet" are standing, and the frame
//! is written to a PNG. No window, no snowpack environment variables.
//!
//! ```text
//! cargo run --release -p snowpack --example headless -- [OUT.png]
//! ```

use glam::{DVec2, Vec2, Vec3};
use snowpack::{Camera, Deformer, EnvironmentMap, GpuContext, RenderParams, Renderer, SnowDeformation, SnowFrame, SnowParams, TerrainSource};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "snowpack-headless.png".to_owned());

    // The game's device: snowpack only borrows it.
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor::default()))?;
    let ctx = GpuContext::from_device(device, queue);
    println!("GPU: {} ({})", ctx.summary.name, ctx.summary.backend);

    // A 16 m window of 0.4 m snow, 256 texels a side (6.25 cm), over flat ground.
    let params = SnowParams { extent_m: 16.0, resolution: 256, depth_m: 0.4, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(&ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO)?;

    // A 0.3 m ball rolls 10 m in 2 s along a gentle curve, its bottom 0.25 m into the snow.
    let dt = 1.0 / 60.0;
    for frame in 0..120 {
        let t = frame as f32 * dt;
        let center = Vec3::new(-5.0 + 5.0 * t, 0.45, 2.0 * (t * 1.5).sin());
        // Ask where the ball is and a point on untouched snow; answers come back a frame or two later.
        let points = [Vec2::new(center.x, center.z), Vec2::new(0.0, -6.0)];
        let ball = [Deformer::Sphere { center, radius: 0.3 }];
        // `step_frame` encodes and submits in one call (no encoder of our own here).
        snow.step_frame(&ctx, &SnowFrame::new(dt, &ball).with_queries(&points))?;
    }
    snow.finish(&ctx)?;
    if let Some(answers) = snow.point_answers() {
        for (p, sample) in answers.points.iter().zip(&answers.samples) {
            match sample {
                Some(s) => println!("snow at ({:.2}, {:.2}): depth {:.3} m, compaction {:.2}, normal {:.2}", p.x, p.y, s.depth_m(), s.compaction(), s.normal),
                None => println!("({:.2}, {:.2}) is outside the window", p.x, p.y),
            }
        }
    }

    // Draw it with snowpack's full renderer (a game would draw the ground in its own pass).
    let env = EnvironmentMap::procedural(Vec3::new(0.4, 0.5, -0.3).normalize());
    let mut renderer = Renderer::new(&ctx, &snow, &env, RenderParams::default(), snowpack::IMAGE_FORMAT)?;
    let camera = Camera { position: Vec3::new(1.0, 3.0, -7.0), target: Vec3::new(0.0, 0.0, 1.0), fov_deg: 55.0 };
    let (width, height) = (640, 400);
    let rgba = renderer.render_image(&ctx, &snow, &[], &camera, (width, height))?;
    let image = image::RgbaImage::from_raw(width, height, rgba).ok_or("frame size")?;
    image.save(&out)?;
    println!("wrote {out}");
    Ok(())
}
