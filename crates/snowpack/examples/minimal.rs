//! The smallest wgpu game with snowpack: a window, the game's own device,
//! camera and render pass; a ball follows the mouse and ploughs the snow; the
//! snow is drawn into the game's pass; the snow depth under the mouse is
//! printed from a point query.
//!
//! ```text
//! cargo run --release -p snowpack --example minimal [-- --exit-after-frames N]
//! ```

use std::sync::Arc;

use glam::{DVec2, Mat4, Vec2, Vec3};
use snowpack::low_level::GpuContextExt;
use snowpack::{Deformer, GpuContext, GroundCamera, SnowDeformation, SnowFrame, SnowGround, SnowGroundDescriptor, SnowParams, TerrainSource};
use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::window::{Window, WindowId};

const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
const EYE: Vec3 = Vec3::new(0.0, 9.0, -12.0);

/// Everything the game owns once its window is open.
struct Game {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    depth: wgpu::TextureView,
    ctx: GpuContext,
    snow: SnowDeformation,
    ground: SnowGround,
    mouse: Vec2,
    ball: Vec3,
    frames: u64,
}

#[derive(Default)]
struct App {
    game: Option<Game>,
    exit_after: Option<u64>,
}

fn depth_view(device: &wgpu::Device, config: &wgpu::SurfaceConfiguration) -> wgpu::TextureView {
    let size = wgpu::Extent3d { width: config.width, height: config.height, depth_or_array_layers: 1 };
    device
        .create_texture(&wgpu::TextureDescriptor {
            label: Some("game depth"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        })
        .create_view(&wgpu::TextureViewDescriptor::default())
}

impl Game {
    fn new(event_loop: &ActiveEventLoop) -> Result<Self, Box<dyn std::error::Error>> {
        let window = Arc::new(event_loop.create_window(Window::default_attributes().with_title("snowpack minimal"))?);
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_with_display_handle(Box::new(event_loop.owned_display_handle())));
        let surface = instance.create_surface(Arc::clone(&window))?;
        let options = wgpu::RequestAdapterOptions { compatible_surface: Some(&surface), ..Default::default() };
        let adapter = pollster::block_on(instance.request_adapter(&options))?;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor::default()))?;
        let size = window.inner_size();
        let mut config = surface.get_default_config(&adapter, size.width.max(1), size.height.max(1)).ok_or("surface unsupported")?;
        config.format = config.format.add_srgb_suffix();
        surface.configure(&device, &config);
        let depth = depth_view(&device, &config);
        // The game's device and queue, handed to snowpack.
        let ctx = GpuContext::from_device(device, queue);
        let params = SnowParams { extent_m: 32.0, resolution: 512, depth_m: 0.4, ..SnowParams::default() };
        let snow = SnowDeformation::new(&ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO)?;
        let desc = SnowGroundDescriptor::new(config.format).with_depth(DEPTH, wgpu::CompareFunction::Less);
        let ground = SnowGround::new(&ctx.device, &snow, &desc);
        Ok(Self { window, surface, config, depth, ctx, snow, ground, mouse: Vec2::ZERO, ball: Vec3::new(0.0, 0.5, 0.0), frames: 0 })
    }

    fn view_proj(&self) -> Mat4 {
        let aspect = self.config.width as f32 / self.config.height.max(1) as f32;
        glam::camera::rh::proj::directx::perspective(50f32.to_radians(), aspect, 0.1, 200.0) * glam::camera::rh::view::look_at_mat4(EYE, Vec3::ZERO, Vec3::Y)
    }

    /// Where the mouse ray meets the snow surface's plane (y = 0.4).
    fn mouse_on_snow(&self) -> Option<Vec3> {
        let ndc = Vec2::new(2.0 * self.mouse.x / self.config.width as f32 - 1.0, 1.0 - 2.0 * self.mouse.y / self.config.height as f32);
        let inv = self.view_proj().inverse();
        let (near, far) = (inv.project_point3(ndc.extend(0.0)), inv.project_point3(ndc.extend(1.0)));
        let t = (0.4 - near.y) / (far.y - near.y);
        (t > 0.0).then(|| near + (far - near) * t)
    }

    fn frame(&mut self) -> Result<(), Box<dyn std::error::Error>> {
        if let Some(target) = self.mouse_on_snow() {
            // The ball rolls toward the mouse, pressing the 0.4 m of snow down to 0.1 m.
            let to = Vec3::new(target.x, 0.5, target.z);
            self.ball += (to - self.ball).clamp_length_max(0.15);
        }
        let mut encoder = self.ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("game frame") });
        let ball = [Deformer::Sphere { center: self.ball, radius: 0.4 }];
        // Ask for the snow under the ball too; the answer arrives a frame or two later.
        let under_ball = [Vec2::new(self.ball.x, self.ball.z)];
        // Snow call 1 of 2: the frame's deformation.
        self.snow.encode(&self.ctx, &mut encoder, &SnowFrame::new(1.0 / 60.0, &ball).with_queries(&under_ball));
        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            _ => {
                self.surface.configure(&self.ctx.device, &self.config);
                self.ctx.queue.submit([encoder.finish()]);
                return Ok(());
            }
        };
        let view = frame.texture.create_view(&wgpu::TextureViewDescriptor::default());
        let camera = GroundCamera::new(self.view_proj(), EYE);
        {
            // The game's own pass: its targets, its clear; the snow is one draw in it.
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("game pass"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &view,
                    resolve_target: None,
                    depth_slice: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color { r: 0.35, g: 0.45, b: 0.6, a: 1.0 }), store: wgpu::StoreOp::Store },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &self.depth,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            // Snow call 2 of 2: the ground, one draw in the game's pass.
            self.ground.draw(&mut pass, &self.ctx.queue, &self.snow, &camera);
        }
        // Nothing to call after the submit: readbacks come back by themselves.
        self.ctx.queue.submit([encoder.finish()]);
        self.window.pre_present_notify();
        self.ctx.queue.present(frame);
        self.ctx.check("frame")?;
        if let Some(s) = self.snow.point_answers().and_then(|a| a.samples[0]).filter(|_| self.frames.is_multiple_of(30)) {
            println!("snow under the ball: {:.3} m deep, {:.0}% pressed", s.depth_m(), 100.0 * s.compaction());
        }
        self.frames += 1;
        Ok(())
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.game.is_none() {
            match Game::new(event_loop) {
                Ok(game) => self.game = Some(game),
                Err(e) => {
                    eprintln!("cannot start: {e}");
                    event_loop.exit();
                }
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        let Some(game) = &mut self.game else { return };
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::CursorMoved { position, .. } => game.mouse = Vec2::new(position.x as f32, position.y as f32),
            WindowEvent::Resized(size) if size.width > 0 && size.height > 0 => {
                (game.config.width, game.config.height) = (size.width, size.height);
                game.surface.configure(&game.ctx.device, &game.config);
                game.depth = depth_view(&game.ctx.device, &game.config);
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = game.frame() {
                    eprintln!("frame failed: {e}");
                    event_loop.exit();
                }
                if self.exit_after.is_some_and(|n| game.frames >= n) {
                    event_loop.exit();
                }
                game.window.request_redraw();
            }
            _ => {}
        }
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let exit_after = match (args.next().as_deref(), args.next()) {
        (Some("--exit-after-frames"), Some(n)) => Some(n.parse()?),
        _ => None,
    };
    let mut app = App { game: None, exit_after };
    EventLoop::new()?.run_app(&mut app)?;
    Ok(())
}
