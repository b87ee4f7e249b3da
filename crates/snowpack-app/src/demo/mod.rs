//! The interactive demo: a winit window with an egui panel over the snow.
//! Wasmut's system model (section 3): spheres bounce and slide over a snow
//! landscape, every deformation property and the technique change while it
//! runs, and the scene resets with a new sphere count. Test hooks
//! (`--exit-after-frames`, `--screenshot`, `--script`) drive it end to end.
//!
//! One frame, in order: scripted events → input → simulation step
//! (deformation encoded) → panel (egui) → snow rendered into the window →
//! panel drawn over it → submit, present → readbacks and error check.

pub mod script;

use std::collections::HashSet;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use glam::{Vec2, Vec3};
use snowpack::DebugView;
use snowpack::low_level::gpu::readback::TextureReadback;
use snowpack::{AdapterRequest, GpuContext, Technique};
use snowpack_scene::Scene;
use winit::application::ApplicationHandler;
use winit::dpi::{LogicalSize, PhysicalSize};
use winit::event::{DeviceEvent, DeviceId, ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use snowpack_app::BadInput;
use snowpack_app::camera::{CameraMode, CameraRig, MoveInput};
use snowpack_app::panel::{self, Action, PanelState};
use snowpack_app::session::{PlayerBody, Session, WindowFollow};

use self::script::{Script, ScriptEvent};
use snowpack::low_level::AdapterRequestExt;
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::TechniqueExt;

/// What the command line asked of the demo.
#[derive(Clone, Debug, Default)]
pub struct DemoOptions {
    /// Scene file (default: the built-in default scene).
    pub scene: Option<PathBuf>,
    /// Exit (code 0) after this many frames.
    pub exit_after_frames: Option<u64>,
    /// Write the window's image here after the last frame (needs `exit_after_frames`).
    pub screenshot: Option<PathBuf>,
    /// Scripted input file (see [`script`]).
    pub script: Option<PathBuf>,
    /// Wait for vertical sync.
    pub vsync: bool,
    /// GPU backend(s).
    pub backend: Option<String>,
    /// Initial window size (logical pixels).
    pub size: (u32, u32),
    /// A `snowpack server` to share the snow with.
    pub connect: Option<std::net::SocketAddr>,
    /// Connect token for a server with a key.
    pub token: Option<PathBuf>,
}

/// Whether a window can be opened here (a display server is named, or the
/// platform always has one).
#[must_use]
pub fn display_available() -> bool {
    if cfg!(any(target_os = "windows", target_os = "macos")) {
        return true;
    }
    ["DISPLAY", "WAYLAND_DISPLAY"].iter().any(|k| std::env::var_os(k).is_some_and(|v| !v.is_empty()))
}

/// Opens the window and runs until it is closed (or `exit_after_frames`).
pub fn run(opts: DemoOptions) -> anyhow::Result<()> {
    if opts.screenshot.is_some() && opts.exit_after_frames.is_none() {
        return Err(BadInput("--screenshot needs --exit-after-frames (the frame to capture)".into()).into());
    }
    let scene = match &opts.scene {
        Some(path) => Scene::load(path)?,
        None => Scene::default_scene()?,
    };
    let script = match &opts.script {
        Some(path) => Script::load(path).map_err(BadInput)?,
        None => Script::default(),
    };
    if let Some(n) = opts.exit_after_frames
        && script.last_frame() >= n
    {
        tracing::warn!("the script has events at frame {} and later, after the last frame ({n}); they will not run", n);
    }
    let event_loop = EventLoop::new().map_err(|e| DisplayUnavailable(e.to_string()))?;
    let mut app = App { opts, pending_scene: Some(scene), script, gfx: None, frame: 0, result: Ok(()) };
    event_loop.run_app(&mut app).context("running the window's event loop")?;
    if let Some(reason) = app.gfx.as_ref().and_then(|g| g.lost.clone()) {
        anyhow::bail!("the GPU device was lost: {reason}");
    }
    if let (Ok(()), Some(gfx)) = (&app.result, &mut app.gfx)
        && gfx.session.scene.store.as_ref().is_some_and(|s| s.keep == snowpack_scene::StoreKeep::Disk && s.save)
    {
        // `[store] save = true`: the snow is saved on the way out, as a run does.
        match gfx.session.save_store(&gfx.ctx) {
            Ok(msg) => println!("{msg}"),
            Err(e) => app.result = Err(e),
        }
    }
    if let (Ok(()), Some(gfx)) = (&app.result, &app.gfx) {
        if let Some(t) = gfx.session.snow.tile_stats() {
            println!(
                "tile store: {} resident, {} restored, {} fresh, {} evicted, {} on disk ({} bytes), window waited {} frames, {} errors",
                t.resident, t.restored, t.fresh, t.evicted, t.store.disk_tiles, t.store.disk_bytes, t.window_waits, t.store.errors
            );
        }
        if let Some(shell) = gfx.session.renderer.shell() {
            match shell.pass_pixels(&gfx.ctx) {
                Ok(pixels) => println!("shell: {} tetrahedra, pixels per peeling pass {pixels:?}", shell.tetrahedra()),
                Err(e) => app.result = Err(e.into()),
            }
        }
        // A summary for people and for the end-to-end tests.
        println!(
            "demo: {} frames, {} spheres, {} simulated frames since the last reset, technique {}, player {} at {:.2} {:.2} m, {} footsteps, adapter {} ({})",
            app.frame,
            gfx.session.sphere_count(),
            gfx.session.frames,
            gfx.session.snow_params.technique.as_str(),
            PlayerBody::ALL.iter().find(|b| b.0 == gfx.session.player.body).map_or("", |b| b.1),
            gfx.session.player.position.x,
            gfx.session.player.position.z,
            gfx.session.footsteps.0,
            gfx.ctx.summary.name,
            gfx.ctx.summary.backend
        );
    }
    app.result
}

/// No window could be opened (no display server, or it refused the connection).
#[derive(Debug)]
pub struct DisplayUnavailable(pub String);

impl std::fmt::Display for DisplayUnavailable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "cannot connect to a display: {}", self.0)
    }
}

impl std::error::Error for DisplayUnavailable {}

/// Buttons and keys held.
#[derive(Default)]
struct InputState {
    keys: HashSet<KeyCode>,
    left: bool,
    right: bool,
    cursor: Option<Vec2>,
}

impl InputState {
    fn axis(&self, plus: KeyCode, minus: KeyCode) -> f32 {
        f32::from(u8::from(self.keys.contains(&plus))) - f32::from(u8::from(self.keys.contains(&minus)))
    }

    fn movement(&self) -> MoveInput {
        MoveInput {
            forward: self.axis(KeyCode::KeyW, KeyCode::KeyS),
            right: self.axis(KeyCode::KeyD, KeyCode::KeyA),
            up: self.axis(KeyCode::KeyE, KeyCode::KeyQ),
            fast: self.keys.contains(&KeyCode::ShiftLeft) || self.keys.contains(&KeyCode::ShiftRight),
        }
    }
}

/// Everything that exists once the window does.
struct Gfx {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    copy_src: bool,
    ctx: GpuContext,
    session: Session,
    rig: CameraRig,
    panel: PanelState,
    input: InputState,
    egui_ctx: egui::Context,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
    /// The surface is zero-sized (minimised): simulate, draw nothing.
    hidden: bool,
    /// The size to go back to on `restore`.
    restore_size: Option<PhysicalSize<u32>>,
    /// The device was lost: shown in the window title and the log; nothing more is drawn.
    lost: Option<String>,
    last: Instant,
    screenshot: Option<PathBuf>,
    /// The shared world (`--connect`), while linked.
    link: Option<crate::net::SnowLink>,
    /// The connect token the link was made with (to join again).
    link_token: Option<PathBuf>,
}

struct App {
    opts: DemoOptions,
    pending_scene: Option<Scene>,
    script: Script,
    gfx: Option<Gfx>,
    frame: u64,
    result: anyhow::Result<()>,
}

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, err: anyhow::Error) {
        tracing::error!("{err:#}");
        self.result = Err(err);
        event_loop.exit();
    }

    fn create(&mut self, event_loop: &ActiveEventLoop) -> anyhow::Result<Gfx> {
        let scene = self.pending_scene.take().context("the scene was already used")?;
        let (w, h) = self.opts.size;
        let attrs = Window::default_attributes().with_title("snowpack").with_inner_size(LogicalSize::new(w, h));
        let window = Arc::new(event_loop.create_window(attrs).context("opening the window")?);
        let request = AdapterRequest::from_env().with_backends(self.opts.backend.as_deref());
        let desc = GpuContext::instance_descriptor(wgpu::InstanceDescriptor::new_with_display_handle(Box::new(event_loop.owned_display_handle())), &request)?;
        let instance = wgpu::Instance::new(desc);
        let surface = instance.create_surface(Arc::clone(&window)).context("creating the window's surface")?;
        let ctx = GpuContext::choose(instance, Some(&surface), &request).context("choosing a GPU adapter for the window")?;
        let caps = surface.get_capabilities(ctx.adapter().context("the demo chose its own adapter")?);
        let format = caps
            .formats
            .iter()
            .copied()
            .find(wgpu::TextureFormat::is_srgb)
            .or_else(|| caps.formats.first().copied())
            .context("the surface offers no formats")?;
        let copy_src = caps.usages.contains(wgpu::TextureUsages::COPY_SRC);
        let size = window.inner_size();
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | if copy_src { wgpu::TextureUsages::COPY_SRC } else { wgpu::TextureUsages::empty() },
            format,
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode: if self.opts.vsync { wgpu::PresentMode::AutoVsync } else { wgpu::PresentMode::AutoNoVsync },
            alpha_mode: caps.alpha_modes.first().copied().unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: vec![],
            desired_maximum_frame_latency: 2,
            color_space: wgpu::SurfaceColorSpace::Auto,
        };
        let hidden = size.width == 0 || size.height == 0;
        if !hidden {
            surface.configure(&ctx.device, &config);
        }
        tracing::info!("window {}x{} ({format:?}), {}", size.width, size.height, ctx.summary.name);
        let mut session = Session::new(&ctx, scene, format)?;
        if session.scene.window == snowpack_scene::WindowSpec::FollowCamera {
            session.follow = WindowFollow::Camera;
        }
        let scene_camera =
            snowpack::Camera { position: session.scene.camera.position, target: session.scene.camera.target, fov_deg: session.scene.camera.fov_deg };
        let rig = CameraRig::from_camera(&scene_camera);
        let egui_ctx = egui::Context::default();
        let max_side = ctx.device.limits().max_texture_dimension_2d as usize;
        let egui_state = egui_winit::State::new(egui_ctx.clone(), egui::ViewportId::ROOT, &window, Some(window.scale_factor() as f32), None, Some(max_side));
        let egui_renderer = egui_wgpu::Renderer::new(&ctx.device, format, egui_wgpu::RendererOptions::default());
        let adapter = format!("{} ({})", ctx.summary.name, ctx.summary.backend);
        let panel = PanelState::new(&session, &ctx, adapter, (size.width, size.height), self.opts.vsync);
        let link = match self.opts.connect {
            Some(addr) => Some(crate::net::join(&ctx, &mut session.snow, addr, self.opts.token.as_deref(), "demo")?),
            None => None,
        };
        Ok(Gfx {
            window,
            surface,
            config,
            copy_src,
            ctx,
            session,
            rig,
            panel,
            input: InputState::default(),
            egui_ctx,
            egui_state,
            egui_renderer,
            hidden,
            restore_size: None,
            lost: None,
            last: Instant::now(),
            screenshot: None,
            link,
            link_token: self.opts.token.clone(),
        })
    }
}

impl Gfx {
    fn resize(&mut self, size: PhysicalSize<u32>) {
        self.panel.surface = (size.width, size.height);
        // A minimised window reports 0x0: configuring a zero-sized surface is
        // an error, so stop drawing until it has an area again.
        self.hidden = size.width == 0 || size.height == 0;
        if !self.hidden {
            self.config.width = size.width;
            self.config.height = size.height;
            self.surface.configure(&self.ctx.device, &self.config);
        }
    }

    fn player(&self) -> Vec3 {
        self.session.player.position
    }

    fn key(&mut self, code: KeyCode, pressed: bool) {
        if pressed {
            self.input.keys.insert(code);
        } else {
            self.input.keys.remove(&code);
            return;
        }
        let technique = |k: usize| Technique::ALL[k];
        match code {
            KeyCode::Digit1 => self.session.snow_params.technique = technique(0),
            KeyCode::Digit2 => self.session.snow_params.technique = technique(1),
            KeyCode::Digit3 => self.session.snow_params.technique = technique(2),
            KeyCode::Digit4 => self.session.snow_params.technique = technique(3),
            KeyCode::KeyR => self.act(Action::Reset(self.panel.sphere_count)),
            KeyCode::KeyP | KeyCode::Space => self.session.paused = !self.session.paused,
            KeyCode::KeyN => self.session.single_step(),
            KeyCode::KeyH => self.panel.visible = !self.panel.visible,
            KeyCode::KeyF => {
                let body = if self.session.player.body == PlayerBody::Fox { PlayerBody::Sphere } else { PlayerBody::Fox };
                self.act(Action::PlayerBody(body));
            }
            KeyCode::Tab => {
                let next = self.rig.mode.next();
                self.act(Action::CameraMode(next));
            }
            KeyCode::KeyG => {
                let shell = &mut self.session.render_params.shell;
                shell.enabled = !shell.enabled;
                println!("shell detail {}", if shell.enabled { "on" } else { "off" });
            }
            KeyCode::KeyV => {
                let views = DebugView::ALL;
                let k = views.iter().position(|v| v.0 == self.session.render_params.debug_view).unwrap_or(0);
                self.session.render_params.debug_view = views[(k + 1) % views.len()].0;
            }
            _ => {}
        }
    }

    fn act(&mut self, action: Action) {
        let result = match action {
            Action::Vsync(on) => {
                self.panel.vsync = on;
                self.config.present_mode = if on { wgpu::PresentMode::AutoVsync } else { wgpu::PresentMode::AutoNoVsync };
                if !self.hidden {
                    self.surface.configure(&self.ctx.device, &self.config);
                }
                Ok(format!("vsync {}", if on { "on" } else { "off" }))
            }
            other => panel::apply(other, &self.ctx, &mut self.session, &mut self.rig, &mut self.panel),
        };
        match result {
            Ok(msg) => {
                tracing::info!("{msg}");
                self.panel.status = Some((msg, false));
            }
            Err(e) => {
                tracing::error!("{e:#}");
                self.panel.status = Some((format!("{e:#}"), true));
            }
        }
    }

    fn script_event(&mut self, event: ScriptEvent) {
        match event {
            ScriptEvent::Key(k) => {
                self.key(k, true);
                self.key(k, false);
            }
            ScriptEvent::KeyDown(k) => self.key(k, true),
            ScriptEvent::KeyUp(k) => self.key(k, false),
            ScriptEvent::Drag { dx, dy, primary } => self.rig.drag(Vec2::new(dx, dy), primary),
            ScriptEvent::Wheel(lines) => self.rig.wheel(lines),
            ScriptEvent::Resize(w, h) => {
                let size = PhysicalSize::new(w, h);
                if let Some(actual) = self.window.request_inner_size(size) {
                    self.resize(actual);
                }
            }
            ScriptEvent::LoseDevice => {
                tracing::warn!("the script destroys the GPU device");
                self.ctx.device.destroy();
            }
            ScriptEvent::Minimize => {
                self.restore_size = Some(self.window.inner_size());
                self.window.set_minimized(true);
                // Without a window manager (Xvfb) nothing iconifies; feed the
                // zero size a minimised window reports so that path runs too.
                self.resize(PhysicalSize::new(0, 0));
            }
            ScriptEvent::Restore => {
                self.window.set_minimized(false);
                let size = self.restore_size.take().unwrap_or_else(|| self.window.inner_size());
                self.resize(size);
            }
            ScriptEvent::Screenshot(path) => self.screenshot = Some(path),
        }
    }

    fn window_event(&mut self, event: &WindowEvent) {
        let response = self.egui_state.on_window_event(&self.window, event);
        match event {
            WindowEvent::Resized(size) => self.resize(*size),
            WindowEvent::ScaleFactorChanged { .. } => self.resize(self.window.inner_size()),
            WindowEvent::KeyboardInput { event, .. } => {
                if let PhysicalKey::Code(code) = event.physical_key {
                    let pressed = event.state == ElementState::Pressed;
                    // Releases always count, so a key pressed before focus moved to a text field does not stick.
                    if !pressed || (!self.egui_ctx.egui_wants_keyboard_input() && !event.repeat) {
                        self.key(code, pressed);
                    }
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                let pressed = *state == ElementState::Pressed;
                if pressed && response.consumed {
                    return;
                }
                match button {
                    MouseButton::Left => self.input.left = pressed && !self.egui_ctx.egui_wants_pointer_input(),
                    MouseButton::Right => self.input.right = pressed && !self.egui_ctx.egui_wants_pointer_input(),
                    _ => {}
                }
            }
            WindowEvent::CursorMoved { position, .. } => {
                let p = Vec2::new(position.x as f32, position.y as f32);
                if let Some(last) = self.input.cursor
                    && (self.input.left || self.input.right)
                {
                    self.rig.drag(p - last, self.input.left);
                }
                self.input.cursor = Some(p);
            }
            WindowEvent::MouseWheel { delta, .. } => {
                if response.consumed || self.egui_ctx.egui_wants_pointer_input() {
                    return;
                }
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => *y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.rig.wheel(lines);
            }
            _ => {}
        }
    }

    /// Stops drawing, says why in the log and the title; the run then ends with an error.
    fn device_lost(&mut self, reason: String) {
        tracing::error!("GPU device lost: {reason}; close the window and start again");
        self.window.set_title(&format!("snowpack — the GPU device was lost ({reason}); close and restart"));
        self.lost = Some(reason);
    }

    /// Simulates, draws and presents one frame.
    fn frame(&mut self) -> anyhow::Result<()> {
        let now = Instant::now();
        let elapsed = (now - self.last).as_secs_f32();
        self.last = now;
        self.panel.push_frame_time(elapsed * 1000.0);
        // Camera and player move by wall time, capped so a stall does not teleport them.
        let dt = elapsed.min(0.1);
        if self.lost.is_some() {
            // Nothing can be drawn without a device; the title says why until the window is closed.
            return Ok(());
        }
        // A lost device can fail the surface first (the frame then returns early below), so
        // ask before drawing.
        if let Some(reason) = self.ctx.lost_reason() {
            self.device_lost(reason);
            return Ok(());
        }

        self.steer(dt);

        let mut encoder = self.ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("demo frame") });
        let camera_now = self.rig.camera(self.player());
        self.session.encode_step(&self.ctx, &mut encoder, camera_now.position);

        let (actions, output, freed) = self.run_panel();

        if self.hidden {
            // Minimised: the simulation goes on, nothing is drawn.
            self.ctx.queue.submit([encoder.finish()]);
            self.release(&freed, actions);
            return Ok(());
        }

        let Some(frame) = self.acquire() else {
            // No texture this time (the surface is reconfigured when it must be): the simulation still runs.
            self.ctx.queue.submit([encoder.finish()]);
            return Ok(());
        };
        let device = &self.ctx.device;
        let view = frame.texture.create_view(&wgpu::TextureViewDescriptor::default());
        let size = (self.config.width, self.config.height);
        let camera = self.rig.camera(self.player());
        let deformers = self.session.deformers();
        self.session.renderer.encode(&self.ctx, &mut encoder, &self.session.snow, &deformers, &camera, &view, size);

        let ppp = output.pixels_per_point;
        let jobs = self.egui_ctx.tessellate(output.shapes, ppp);
        let screen = egui_wgpu::ScreenDescriptor { size_in_pixels: [size.0, size.1], pixels_per_point: ppp };
        let extra = self.egui_renderer.update_buffers(device, &self.ctx.queue, &mut encoder, &jobs, &screen);
        draw_panel(&self.egui_renderer, &mut encoder, &view, &jobs, &screen);
        let capture = self.screenshot.take().map(|path| {
            let copy = self.copy_src.then(|| TextureReadback::record(device, &mut encoder, &frame.texture));
            (path, copy)
        });
        self.ctx.queue.submit(extra.into_iter().chain([encoder.finish()]));
        if let Some((path, capture)) = capture {
            let capture = match capture {
                Some(c) => c,
                // No COPY_SRC on this surface: draw the same frame again into an image.
                None => self.offscreen_capture(&camera, &deformers, &jobs, &screen)?,
            };
            save_screenshot(&self.ctx, &capture, &path, self.config.format)?;
            tracing::info!("screenshot written to {}", path.display());
        }
        self.window.pre_present_notify();
        self.ctx.queue.present(frame);
        match self.ctx.check("demo frame").map_err(snowpack::low_level::error::SnowError::from) {
            Ok(()) => {}
            Err(snowpack::low_level::error::SnowError::DeviceLost(reason)) => self.device_lost(reason),
            Err(e) => {
                tracing::error!("{e}");
                self.panel.status = Some((e.to_string(), true));
            }
        }
        self.release(&freed, actions);
        self.share();
        Ok(())
    }

    /// Input: the camera, and the player in follow mode.
    fn steer(&mut self, dt: f32) {
        let movement = self.input.movement();
        self.rig.fly(movement, dt);
        if self.rig.mode == CameraMode::Follow {
            let (f, r) = self.rig.ground_axes();
            let dir = f * movement.forward + r * movement.right;
            self.session.drive_player(dir, movement.fast, dt);
        } else {
            // The keys move the camera: a steered fox stands still.
            self.session.drive_player(Vec2::ZERO, false, dt);
        }
    }

    /// The panel (it may change parameters, which apply next frame): its
    /// actions, egui's output, and the textures to free once this frame is submitted.
    fn run_panel(&mut self) -> (Vec<Action>, egui::FullOutput, Vec<egui::TextureId>) {
        let raw = self.egui_state.take_egui_input(&self.window);
        let mut actions = Vec::new();
        let (session, rig, panel) = (&mut self.session, &mut self.rig, &mut self.panel);
        let mut output = self.egui_ctx.run_ui(raw, |ui| actions = panel::show(ui, session, rig, panel));
        self.egui_state.handle_platform_output(&self.window, std::mem::take(&mut output.platform_output));
        // Texture uploads apply even when nothing is drawn (the font atlas must not be lost);
        // frees wait until the frame that last used them is submitted.
        for (id, deltas) in &output.textures_delta.set {
            for delta in deltas {
                self.egui_renderer.update_texture(&self.ctx.device, &self.ctx.queue, *id, delta);
            }
        }
        let freed = std::mem::take(&mut output.textures_delta.free).into_iter().collect();
        output.textures_delta.clear();
        (actions, output, freed)
    }

    /// The surface's next texture; `None` when there is none this frame
    /// (timed out or occluded, or outdated or lost, and then reconfigured).
    fn acquire(&mut self) -> Option<wgpu::SurfaceTexture> {
        match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) | wgpu::CurrentSurfaceTexture::Suboptimal(t) => Some(t),
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => None,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost | wgpu::CurrentSurfaceTexture::Validation => {
                self.surface.configure(&self.ctx.device, &self.config);
                None
            }
        }
    }

    /// After a frame is submitted: the textures it last used freed, the panel's actions applied.
    fn release(&mut self, freed: &[egui::TextureId], actions: Vec<Action>) {
        for id in freed {
            self.egui_renderer.free_texture(id);
        }
        for action in actions {
            self.act(action);
        }
    }

    /// One exchange with the shared world: this frame's deformers reported,
    /// changed tiles out, tiles from the others merged. A panel change that
    /// made the snow anew (another depth, resolution, terrain) joins again
    /// with the new snow; a server that refuses it, or a lost connection,
    /// is said in the panel and the demo goes on alone.
    fn share(&mut self) {
        let Some(link) = &mut self.link else { return };
        let addr = link.addr();
        if !self.session.snow.is_sharing() {
            self.link = None;
            match crate::net::join(&self.ctx, &mut self.session.snow, addr, self.link_token.as_deref(), "demo") {
                Ok(l) => self.link = Some(l),
                Err(e) => self.panel.status = Some((format!("shared snow: {e:#}"), true)),
            }
            return;
        }
        let mut positions: Vec<[f64; 2]> = self.session.deformers().iter().filter_map(crate::net::deformer_xz).collect();
        let p = self.session.player.position;
        positions.push([f64::from(p.x), f64::from(p.z)]);
        link.peer.set_deformers(&positions);
        if let Err(e) = link.pump(&mut self.session.snow) {
            self.panel.status = Some((format!("shared snow: {e}; going on alone"), true));
            self.link = None;
        }
    }

    fn offscreen_capture(
        &mut self,
        camera: &snowpack::Camera,
        deformers: &[snowpack::Deformer],
        jobs: &[egui::ClippedPrimitive],
        screen: &egui_wgpu::ScreenDescriptor,
    ) -> anyhow::Result<TextureReadback> {
        let device = &self.ctx.device;
        let size = (self.config.width, self.config.height);
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("screenshot"),
            size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: self.config.format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("screenshot") });
        self.session.renderer.encode(&self.ctx, &mut encoder, &self.session.snow, deformers, camera, &view, size);
        let extra = self.egui_renderer.update_buffers(device, &self.ctx.queue, &mut encoder, jobs, screen);
        draw_panel(&self.egui_renderer, &mut encoder, &view, jobs, screen);
        let capture = TextureReadback::record(device, &mut encoder, &texture);
        self.ctx.queue.submit(extra.into_iter().chain([encoder.finish()]));
        Ok(capture)
    }
}

/// Draws the panel over what `view` holds.
fn draw_panel(
    renderer: &egui_wgpu::Renderer,
    encoder: &mut wgpu::CommandEncoder,
    view: &wgpu::TextureView,
    jobs: &[egui::ClippedPrimitive],
    screen: &egui_wgpu::ScreenDescriptor,
) {
    let pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("panel"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations { load: wgpu::LoadOp::Load, store: wgpu::StoreOp::Store },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    renderer.render(&mut pass.forget_lifetime(), jobs, screen);
}

/// Waits for a recorded copy of the window's image and writes it as an RGB
/// PNG (BGRA surfaces swizzled), atomically.
fn save_screenshot(ctx: &GpuContext, capture: &TextureReadback, path: &std::path::Path, format: wgpu::TextureFormat) -> anyhow::Result<()> {
    let texels = capture.read(ctx)?;
    let bgra = matches!(format, wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb);
    let rgb: Vec<u8> = texels.chunks_exact(4).flat_map(|p| if bgra { [p[2], p[1], p[0]] } else { [p[0], p[1], p[2]] }).collect();
    let (w, h) = capture.size();
    let image = image::RgbImage::from_raw(w, h, rgb).context("screenshot size")?;
    let tmp = path.with_extension("png.tmp");
    image.save_with_format(&tmp, image::ImageFormat::Png).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_some() {
            return;
        }
        match self.create(event_loop) {
            Ok(gfx) => {
                gfx.window.request_redraw();
                self.gfx = Some(gfx);
            }
            Err(e) => self.fail(event_loop, e),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(gfx) = self.gfx.as_mut() else { return };
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::RedrawRequested => {
                for e in self.script.due(self.frame) {
                    gfx.script_event(e);
                }
                let last = self.opts.exit_after_frames.is_some_and(|n| self.frame + 1 >= n);
                if last && let Some(path) = &self.opts.screenshot {
                    gfx.screenshot = Some(path.clone());
                }
                if let Err(e) = gfx.frame() {
                    self.fail(event_loop, e);
                    return;
                }
                self.frame += 1;
                if last {
                    event_loop.exit();
                }
            }
            other => gfx.window_event(&other),
        }
    }

    fn device_event(&mut self, _event_loop: &ActiveEventLoop, _id: DeviceId, _event: DeviceEvent) {}

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        let Some(gfx) = self.gfx.as_ref() else { return };
        if gfx.lost.is_some() && self.opts.exit_after_frames.is_none() {
            // The device is gone: wait for the user to close the window, without spinning.
            event_loop.set_control_flow(ControlFlow::Wait);
        } else if gfx.hidden {
            // Minimised: tick the simulation from a timer at its own rate
            // (see `new_events`) instead of spinning on redraws.
            let dt = Duration::from_secs_f32(gfx.session.scene.sim.dt_s);
            event_loop.set_control_flow(ControlFlow::WaitUntil(Instant::now() + dt));
        } else {
            event_loop.set_control_flow(ControlFlow::Poll);
            gfx.window.request_redraw();
        }
    }

    fn new_events(&mut self, event_loop: &ActiveEventLoop, cause: winit::event::StartCause) {
        // While minimised, frames run from the timer (RedrawRequested may never come).
        if let winit::event::StartCause::ResumeTimeReached { .. } = cause
            && let Some(gfx) = self.gfx.as_ref()
            && gfx.hidden
        {
            let id = gfx.window.id();
            self.window_event(event_loop, id, WindowEvent::RedrawRequested);
        }
    }
}
