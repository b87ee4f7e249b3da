//! The page: eframe's web runner owns the canvas, the WebGPU device and the
//! egui pass; each frame the session steps the snow and draws it into a
//! texture of the central area's size, which egui shows under the panel.
//!
//! Nothing here waits on the GPU: the deformation's readbacks (point answers)
//! arrive between frames when the browser runs their mapping callbacks, and
//! the test run reads its frame back with `TextureReadback::read_async`.
//!
//! Test run (`?frames=N` in the page's address): the player's sphere is driven
//! along +x at the scene's fixed step for N frames while the snow is asked
//! about a point on its trail and points that nothing reaches; then the last
//! frame is read back and the page gets `window.snowpackReport` (JSON) and
//! `window.snowpackPng` (the frame as PNG bytes), or `window.snowpackError`.

use std::cell::RefCell;

use anyhow::Context as _;
use glam::{Vec2, Vec3};
use snowpack::low_level::gpu::readback::TextureReadback;
use snowpack::low_level::{GpuContextExt, TechniqueExt};
use snowpack::{GpuContext, PointAnswers};
use snowpack_app::camera::{CameraMode, CameraRig, MoveInput};
use snowpack_app::panel::{self, Action, PanelState};
use snowpack_app::session::{PlayerBody, Session};
use snowpack_scene::Scene;
use wasm_bindgen::prelude::*;

use crate::report;

/// The snow's own target: sRGB, as egui's textures are, so egui samples linear colour.
const SNOW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

thread_local! {
    // The runner must outlive `start`: it owns the page's event handlers.
    static RUNNER: RefCell<Option<eframe::WebRunner>> = const { RefCell::new(None) };
}

/// Starts the demo on the page's canvas with id `canvas_id`. A test run
/// (`?frames=N`) reports through `window.snowpackReport` / `snowpackError`.
#[wasm_bindgen]
pub async fn start(canvas_id: String) -> Result<(), JsValue> {
    // Errors from the library (tracing → log) and wgpu reach the console.
    let _ = eframe::WebLogger::init(log::LevelFilter::Warn);
    let window = web_sys::window().ok_or("no window")?;
    let canvas = window
        .document()
        .ok_or("no document")?
        .get_element_by_id(&canvas_id)
        .ok_or_else(|| format!("no element with id {canvas_id}"))?
        .dyn_into::<web_sys::HtmlCanvasElement>()?;
    let search = web_sys::UrlSearchParams::new_with_str(&window.location().search()?)?;
    let number = |key: &str| search.get(key).and_then(|v| v.parse::<u32>().ok());
    let page = PageOptions {
        test_frames: number("frames").map(u64::from),
        resolution: number("resolution"),
        spheres: number("spheres"),
        shadow_map: number("shadow"),
        patch_quads: number("quads"),
    };

    let mut options = eframe::WebOptions::default();
    options.wgpu_options.wgpu_setup = wgpu_setup();
    let runner = eframe::WebRunner::new();
    let started = runner
        .start(
            canvas,
            options,
            Box::new(move |cc| {
                let app = WebApp::new(cc, page).map_err(|e| {
                    let message = format!("{e:#}");
                    fail(&message);
                    message
                })?;
                Ok(Box::new(app))
            }),
        )
        .await;
    if let Err(e) = &started {
        fail(&format!("the page could not start: {e:?}"));
    }
    RUNNER.with(|r| *r.borrow_mut() = Some(runner));
    started
}

/// WebGPU only (the snow's compute passes need it), with the adapter's own
/// limits: the window's storage buffers are larger than WebGPU's defaults.
fn wgpu_setup() -> egui_wgpu::WgpuSetup {
    let mut setup = egui_wgpu::WgpuSetupCreateNew::without_display_handle();
    setup.instance_descriptor.backends = wgpu::Backends::BROWSER_WEBGPU;
    setup.device_descriptor = std::sync::Arc::new(|adapter: &wgpu::Adapter| wgpu::DeviceDescriptor {
        label: Some("snowpack web"),
        required_features: adapter.features() & wgpu::Features::TIMESTAMP_QUERY,
        required_limits: adapter.limits(),
        ..Default::default()
    });
    egui_wgpu::WgpuSetup::CreateNew(setup)
}

/// Says why the page stopped, in the console and to a test.
fn fail(message: &str) {
    log::error!("snowpack: {message}");
    if let Some(window) = web_sys::window() {
        let _ = js_sys::Reflect::set(&window, &"snowpackError".into(), &message.into());
    }
}

/// What the page's address asks for (`?frames=120&resolution=128&spheres=4&shadow=512&quads=4`).
#[derive(Clone, Copy, Debug, Default)]
struct PageOptions {
    /// A test run of this many frames.
    test_frames: Option<u64>,
    /// The snow window's texels per side instead of the scene's.
    resolution: Option<u32>,
    /// Test-bed spheres instead of the scene's.
    spheres: Option<u32>,
    /// The shadow map's side (texels) instead of the scene's.
    shadow_map: Option<u32>,
    /// Quads per ground patch side instead of the scene's (even).
    patch_quads: Option<u32>,
}

/// The scripted test run's state.
struct TestRun {
    frames: u64,
    /// Where the trail probe and the candidates for untouched snow are.
    trail: Vec2,
    captured: bool,
}

/// The snow's render target and its egui texture.
struct Target {
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    id: egui::TextureId,
}

struct WebApp {
    ctx: GpuContext,
    adapter: wgpu::AdapterInfo,
    session: Session,
    rig: CameraRig,
    panel: PanelState,
    target: Option<Target>,
    frame: u64,
    test: Option<TestRun>,
}

/// Where nothing of the default scene goes in a short run: the test's
/// untouched snow is whichever of these the snow itself answers is deepest.
const UNTOUCHED_CANDIDATES: [[f32; 2]; 6] = [[-10.0, 12.0], [10.0, 12.0], [-13.0, 2.0], [13.0, -2.0], [-6.0, 6.0], [6.0, 4.0]];

impl WebApp {
    fn new(cc: &eframe::CreationContext<'_>, page: PageOptions) -> anyhow::Result<Self> {
        let rs = cc.wgpu_render_state.as_ref().context("no WebGPU adapter: the page needs a browser with WebGPU")?;
        let adapter = rs.adapter.get_info();
        let ctx = GpuContext::adopt_device(rs.device.clone(), rs.queue.clone());
        let mut scene = Scene::default_scene()?;
        if let Some(r) = page.resolution {
            scene.snow.resolution = r.clamp(64, 2048);
        }
        if let (Some(n), Some(spawn)) = (page.spheres, scene.spawns.first_mut()) {
            spawn.count = n;
        }
        if let Some(side) = page.shadow_map {
            scene.render.params.shadow_map_size = side.clamp(256, 4096);
        }
        if let Some(q) = page.patch_quads {
            scene.render.params.patch_quads = (q.clamp(2, 64) / 2) * 2;
        }
        let test_frames = page.test_frames;
        let mut session = Session::new(&ctx, scene, SNOW_FORMAT)?;
        let scene_camera =
            snowpack::Camera { position: session.scene.camera.position, target: session.scene.camera.target, fov_deg: session.scene.camera.fov_deg };
        let rig = CameraRig::from_camera(&scene_camera);
        let test = test_frames.map(|frames| {
            // The sphere moves at its speed for half the run: the trail's middle.
            let start = Vec2::new(session.player.position.x, session.player.position.z);
            let trail = start + Vec2::X * session.player.speed * session.scene.sim.dt_s * frames as f32 * 0.5;
            session.probes = std::iter::once(trail).chain(UNTOUCHED_CANDIDATES.iter().map(|&[x, z]| Vec2::new(x, z))).collect();
            TestRun { frames, trail, captured: false }
        });
        let panel = PanelState::new(&session, &ctx, format!("{} ({})", adapter_name(&adapter), adapter.backend.to_str()), (0, 0), true);
        log::info!("snowpack on {}", panel.adapter);
        Ok(Self { ctx, adapter, session, rig, panel, target: None, frame: 0, test })
    }

    /// The render target at `size`, made or remade (and registered with egui).
    fn target(&mut self, frame: &eframe::Frame, size: (u32, u32)) -> Option<&Target> {
        let rs = frame.wgpu_render_state()?;
        let stale = self.target.as_ref().is_none_or(|t| (t.texture.width(), t.texture.height()) != size);
        if stale {
            let texture = self.ctx.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("snow view"),
                size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: SNOW_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            });
            let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
            let mut renderer = rs.renderer.write();
            let id = match &self.target {
                Some(old) => {
                    renderer.update_egui_texture_from_wgpu_texture(&self.ctx.device, &view, wgpu::FilterMode::Linear, old.id);
                    old.id
                }
                None => renderer.register_native_texture(&self.ctx.device, &view, wgpu::FilterMode::Linear),
            };
            self.target = Some(Target { texture, view, id });
        }
        self.target.as_ref()
    }

    fn keys(&mut self, input: &egui::InputState) {
        use egui::Key;
        for (key, k) in [(Key::Num1, 0), (Key::Num2, 1), (Key::Num3, 2), (Key::Num4, 3)] {
            if input.key_pressed(key) {
                self.session.snow_params.technique = snowpack::Technique::ALL[k];
            }
        }
        if input.key_pressed(Key::P) || input.key_pressed(Key::Space) {
            self.session.paused = !self.session.paused;
        }
        if input.key_pressed(Key::H) {
            self.panel.visible = !self.panel.visible;
        }
        if input.key_pressed(Key::R) {
            self.act(Action::Reset(self.panel.sphere_count));
        }
        if input.key_pressed(Key::F) {
            let body = if self.session.player.body == PlayerBody::Fox { PlayerBody::Sphere } else { PlayerBody::Fox };
            self.act(Action::PlayerBody(body));
        }
        if input.key_pressed(Key::Tab) {
            self.act(Action::CameraMode(self.rig.mode.next()));
        }
    }

    fn movement(input: &egui::InputState) -> MoveInput {
        use egui::Key;
        let axis = |plus: Key, minus: Key| f32::from(u8::from(input.key_down(plus))) - f32::from(u8::from(input.key_down(minus)));
        MoveInput { forward: axis(Key::W, Key::S), right: axis(Key::D, Key::A), up: axis(Key::E, Key::Q), fast: input.modifiers.shift }
    }

    fn act(&mut self, action: Action) {
        let result = panel::apply(action, &self.ctx, &mut self.session, &mut self.rig, &mut self.panel);
        self.panel.status = Some(match result {
            Ok(msg) => (msg, false),
            Err(e) => {
                log::error!("{e:#}");
                (format!("{e:#}"), true)
            }
        });
    }

    /// Steps the snow and draws it into the target; in a test run, reads the
    /// last frame back and hands the report to the page.
    fn draw(&mut self, frame: &eframe::Frame, size: (u32, u32), dt: f32, movement: MoveInput) {
        let scripted = self.test.as_ref().is_some_and(|t| self.frame < t.frames);
        self.rig.fly(movement, dt);
        if scripted {
            self.session.drive_player(Vec2::X, false, dt);
        } else if self.rig.mode == CameraMode::Follow {
            let (f, r) = self.rig.ground_axes();
            self.session.drive_player(f * movement.forward + r * movement.right, movement.fast, dt);
        } else {
            self.session.drive_player(Vec2::ZERO, false, dt);
        }
        let mut encoder = self.ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("web frame") });
        let camera = self.rig.camera(self.session.player.position);
        self.session.encode_step(&self.ctx, &mut encoder, camera.position);
        let Some(target) = self.target(frame, size) else { return };
        let view = target.view.clone();
        let texture = target.texture.clone();
        let deformers = self.session.deformers();
        self.session.renderer.encode(&self.ctx, &mut encoder, &self.session.snow, &deformers, &camera, &view, size);
        let capture = match &mut self.test {
            Some(t) if self.frame + 1 >= t.frames && !t.captured => {
                t.captured = true;
                Some(TextureReadback::record(&self.ctx.device, &mut encoder, &texture))
            }
            _ => None,
        };
        self.ctx.queue.submit([encoder.finish()]);
        if let Err(e) = self.ctx.check("web frame") {
            log::error!("{e}");
            self.panel.status = Some((e.to_string(), true));
        }
        self.frame += 1;
        if self.test.is_some()
            && let Some(window) = web_sys::window()
        {
            // Progress for the test driver (it reports how far a slow run got).
            let _ = js_sys::Reflect::set(&window, &"snowpackFrame".into(), &JsValue::from_f64(self.frame as f64));
            let t = &self.session.timings;
            let passes = serde_json::json!({ "deform": t.deform, "render": t.render, "timestamps": self.ctx.has_timestamps() });
            let _ = js_sys::Reflect::set(&window, &"snowpackTimings".into(), &passes.to_string().into());
        }
        if let Some(capture) = capture {
            // The run ends here: the snow stays as it is for the report (and the viewer).
            self.session.paused = true;
            let pending = PendingReport {
                frames: self.frame,
                size,
                view_proj: camera.view_proj(size.0 as f32 / size.1 as f32),
                adapter: self.adapter.clone(),
                answers: self.session.snow.point_answers().cloned(),
                trail: self.test.as_ref().map_or(Vec2::ZERO, |t| t.trail),
                footsteps: self.session.footsteps.0,
                spheres: self.session.sphere_count(),
                technique: self.session.snow_params.technique.as_str().to_owned(),
            };
            let read = capture.read_async(&self.ctx);
            wasm_bindgen_futures::spawn_local(async move {
                match read.await.map_err(anyhow::Error::from).and_then(|rgba| pending.publish(&rgba)) {
                    Ok(()) => log::info!("snowpack: test frame read back"),
                    Err(e) => fail(&format!("reading the test frame back: {e:#}")),
                }
            });
        }
    }
}

fn adapter_name(info: &wgpu::AdapterInfo) -> String {
    // Browsers often hide the name; the vendor and architecture are what they tell.
    let driver = format!("{} {}", info.driver, info.driver_info).trim().to_owned();
    match (info.name.is_empty(), driver.is_empty()) {
        (false, _) => info.name.clone(),
        (true, false) => driver,
        (true, true) => format!("{:?} adapter (the browser names no more)", info.device_type).to_lowercase(),
    }
}

impl eframe::App for WebApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let wall_dt = ui.input(|i| i.unstable_dt).clamp(0.0, 0.1);
        self.panel.push_frame_time(wall_dt * 1000.0);
        // A test run moves by the scene's fixed step, so its trail does not depend on the frame rate.
        let dt = if self.test.is_some() { self.session.scene.sim.dt_s } else { wall_dt };
        if let Some(reason) = self.ctx.lost_reason() {
            egui::CentralPanel::default().show(ui, |ui| ui.heading(format!("the GPU device was lost ({reason}); reload the page")));
            return;
        }
        let wants_keys = ui.ctx().egui_wants_keyboard_input();
        let movement = if wants_keys { MoveInput::default() } else { ui.input(Self::movement) };
        if !wants_keys {
            ui.input(|i| self.keys(i));
        }
        let actions = panel::show(ui, &mut self.session, &mut self.rig, &mut self.panel);
        egui::CentralPanel::no_frame().show(ui, |ui| {
            let rect = ui.max_rect();
            let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
            if response.dragged() {
                let primary = ui.input(|i| i.pointer.primary_down());
                let d = response.drag_delta();
                self.rig.drag(Vec2::new(d.x, d.y), primary);
            }
            if response.hovered() {
                let scroll = ui.input(|i| i.smooth_scroll_delta.y);
                if scroll != 0.0 {
                    self.rig.wheel(scroll / 40.0);
                }
            }
            let ppp = ui.ctx().pixels_per_point();
            let size = (((rect.width() * ppp).round() as u32).max(1), ((rect.height() * ppp).round() as u32).max(1));
            self.panel.surface = size;
            self.draw(frame, size, dt, movement);
            if let Some(t) = &self.target {
                let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
                ui.painter().image(t.id, rect, uv, egui::Color32::WHITE);
            }
        });
        for action in actions {
            self.act(action);
        }
        ui.ctx().request_repaint();
    }
}

/// What the report needs from the frame it was read back from.
struct PendingReport {
    frames: u64,
    size: (u32, u32),
    view_proj: glam::Mat4,
    adapter: wgpu::AdapterInfo,
    answers: Option<PointAnswers>,
    trail: Vec2,
    footsteps: u64,
    spheres: usize,
    technique: String,
}

impl PendingReport {
    /// Builds the report on the read-back pixels and hands it, with the
    /// frame as PNG, to the page.
    fn publish(self, rgba: &[u8]) -> anyhow::Result<()> {
        let answers = self.answers.context("no point answer came back during the run")?;
        let sample = |p: Vec2| answers.nearest(p, 0.01);
        let trail = sample(self.trail).context("the trail probe was not answered")?;
        let untouched = UNTOUCHED_CANDIDATES
            .iter()
            .map(|&[x, z]| Vec2::new(x, z))
            .filter_map(|p| sample(p).map(|s| (p, s)))
            .max_by(|a, b| (a.1.height_m - a.1.rest_m).total_cmp(&(b.1.height_m - b.1.rest_m)))
            .context("no untouched-snow probe was answered")?;
        let pixel = |p: Vec2, height: f32| report::pixel_of(self.view_proj, Vec3::new(p.x, height, p.y), self.size);
        let trail_px = pixel(self.trail, trail.surface_m);
        let untouched_px = pixel(untouched.0, untouched.1.surface_m);
        let patch = |px: Option<Vec2>| px.and_then(|p| report::patch_luma(rgba, self.size, p, 3));
        let probe = |p: Vec2, s: &snowpack::PointSample, px: Option<Vec2>| {
            serde_json::json!({
                "x": p.x, "z": p.y,
                "height_m": s.height_m, "surface_m": s.surface_m, "rest_m": s.rest_m, "terrain_m": s.terrain_m,
                "pressed_m": s.rest_m - s.height_m,
                "pixel": px.map(|v| [v.x, v.y]),
                "patch_luma": patch(px),
            })
        };
        let json = serde_json::json!({
            "adapter": {
                "name": adapter_name(&self.adapter),
                "backend": self.adapter.backend.to_str(),
                "vendor": self.adapter.vendor,
                "device_type": format!("{:?}", self.adapter.device_type),
                "driver": self.adapter.driver,
                "driver_info": self.adapter.driver_info,
            },
            "frames": self.frames,
            "answered_frame": answers.frame,
            "size": [self.size.0, self.size.1],
            "technique": self.technique,
            "spheres": self.spheres,
            "footsteps": self.footsteps,
            "luma_spread": report::luma_spread(rgba),
            "trail": probe(self.trail, &trail, trail_px),
            "untouched": probe(untouched.0, &untouched.1, untouched_px),
        });
        let mut png = Vec::new();
        let rgb: Vec<u8> = rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
        image::RgbImage::from_raw(self.size.0, self.size.1, rgb)
            .context("frame size")?
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .context("encoding the frame as PNG")?;
        let window = web_sys::window().context("no window")?;
        let set = |key: &str, value: &JsValue| js_sys::Reflect::set(&window, &key.into(), value).map_err(|e| anyhow::anyhow!("{e:?}"));
        set("snowpackPng", &js_sys::Uint8Array::from(png.as_slice()).into())?;
        set("snowpackReport", &json.to_string().into())?;
        Ok(())
    }
}
