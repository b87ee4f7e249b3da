//! The demo's control panel (egui): every deformation, refill, rim, blur,
//! material and light parameter with its unit, the technique, the test bed,
//! debug views, scene load/save, and live GPU timings.

use std::collections::VecDeque;

use egui::{Color32, ComboBox, RichText, Slider, Stroke};
use glam::Vec3;
use snowpack::low_level::render::params::sun_from_angles;
use snowpack::low_level::render::shell::DetailKind;
use snowpack::{DebugView, Material, MaterialPreset};
use snowpack::{RimStyle, Technique};
use snowpack_scene::SaveScene;

use crate::camera::{CameraMode, CameraRig};
use crate::session::{FOX_RUN_M_PER_S, FOX_WALK_M_PER_S, PlayerBody, Session, WindowFollow};
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::RimStyleExt;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::TechniqueExt;

/// In a browser (the `wasm32` build) there is no disk: no disk tile store,
/// no scene files.
const WEB: bool = cfg!(target_arch = "wasm32");

/// What the panel asks the app to do after this frame.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// Fresh snow and this many test-bed spheres at new random places.
    Reset(u32),
    /// Rebuild the window and renderer with the edited sizes.
    Rebuild,
    /// Load a scene file.
    Load(String),
    /// Save the scene (edits and camera included) to a file.
    Save(String),
    /// Change the camera mode.
    CameraMode(CameraMode),
    /// Turn waiting for vertical sync on or off.
    Vsync(bool),
    /// Make the player a sphere or the fox.
    PlayerBody(PlayerBody),
    /// Keep trails on disk, in memory or not at all (rebuilds).
    Store(snowpack_scene::StoreKeep),
    /// Save the snow into the tile store.
    SaveStore,
}

/// The snow the characters carry (docs/characters.md): applied to every
/// character when a slider moves.
fn coat_controls(ui: &mut egui::Ui, session: &mut Session) {
    ui.collapsing("snow on the characters", |ui| {
        let mut coat = session.coat.unwrap_or_default();
        ui.add(Slider::new(&mut coat.cling_per_s, 0.0..=20.0).text("cling").suffix(" /s"))
            .on_hover_text("snow gained wading, per second and per metre under the snow around");
        ui.add(Slider::new(&mut coat.cap_m, 0.0..=0.1).text("most carried").suffix(" m"));
        ui.add(Slider::new(&mut coat.melt_m_per_s, 0.0..=0.01).logarithmic(true).text("melt").suffix(" m/s"));
        ui.add(Slider::new(&mut coat.shake_speed_m_per_s, 0.0..=10.0).text("shakes off above").suffix(" m/s"));
        ui.add(Slider::new(&mut coat.shake_per_s, 0.0..=10.0).text("shake-off rate").suffix(" /s"));
        ui.add(Slider::new(&mut coat.wade_radius_m, 0.0..=1.0).text("wading reads within").suffix(" m"));
        if session.coat.unwrap_or_default() != coat || (session.coat.is_none() && ui.button("apply to every character").clicked()) {
            session.coat = Some(coat);
            if let Err(e) = session.apply_coat() {
                tracing::warn!("{e:#}");
            }
        }
    });
}

/// State the panel keeps between frames.
pub struct PanelState {
    /// Shown at all (H toggles).
    pub visible: bool,
    /// Spheres for the next reset.
    pub sphere_count: u32,
    /// Scene file path for load/save.
    pub scene_path: String,
    /// Last message (load/save result, errors), with whether it is an error.
    pub status: Option<(String, bool)>,
    /// Recent frame times (ms), newest last.
    pub frame_ms: VecDeque<f32>,
    /// Adapter in words.
    pub adapter: String,
    /// Whether timestamps are available.
    pub timestamps: bool,
    /// Surface size in pixels.
    pub surface: (u32, u32),
    /// Vsync on.
    pub vsync: bool,
}

impl PanelState {
    /// Frame times kept for the graph.
    pub const HISTORY: usize = 240;

    /// A visible panel for `session` on `ctx`, whose adapter is `adapter` in
    /// words, drawing into `surface` pixels.
    #[must_use]
    pub fn new(session: &Session, ctx: &snowpack::GpuContext, adapter: String, surface: (u32, u32), vsync: bool) -> Self {
        Self {
            visible: true,
            sphere_count: session.sphere_count() as u32,
            scene_path: session.scene.path.display().to_string(),
            status: None,
            frame_ms: VecDeque::new(),
            adapter,
            timestamps: ctx.has_timestamps(),
            surface,
            vsync,
        }
    }

    /// Records one frame's time.
    pub fn push_frame_time(&mut self, ms: f32) {
        if self.frame_ms.len() == Self::HISTORY {
            self.frame_ms.pop_front();
        }
        self.frame_ms.push_back(ms);
    }
}

fn sun_angles(sun: Vec3) -> (f32, f32) {
    let sun = sun.normalize();
    (sun.y.clamp(-1.0, 1.0).asin().to_degrees(), sun.x.atan2(sun.z).to_degrees().rem_euclid(360.0))
}

fn colour(ui: &mut egui::Ui, label: &str, c: &mut Vec3) {
    ui.horizontal(|ui| {
        let mut rgb = c.to_array();
        ui.color_edit_button_rgb(&mut rgb);
        ui.label(label);
        *c = Vec3::from_array(rgb);
    });
}

fn material_ui(ui: &mut egui::Ui, m: &mut Material) {
    let mut preset = m.preset;
    ComboBox::from_label("preset").selected_text(preset.as_str()).show_ui(ui, |ui| {
        for (p, name) in MaterialPreset::ALL {
            ui.selectable_value(&mut preset, p, name);
        }
    });
    if preset != m.preset {
        *m = preset.material();
    }
    colour(ui, "fresh albedo (linear)", &mut m.fresh_albedo);
    ui.add(Slider::new(&mut m.fresh_roughness, 0.05..=1.0).text("fresh roughness"));
    colour(ui, "packed albedo (trails)", &mut m.packed_albedo);
    ui.add(Slider::new(&mut m.packed_roughness, 0.05..=1.0).text("packed roughness"));
    ui.add(Slider::new(&mut m.compaction_full, 0.05..=1.0).text("fully packed at (fraction of depth)"));
    ui.add(Slider::new(&mut m.packed_detail, 0.0..=1.0).text("packed detail kept"));
    ui.add(Slider::new(&mut m.packed_sparkle, 0.0..=1.0).text("packed sparkle kept"));
    ui.add(Slider::new(&mut m.ground_show_through, 0.0..=1.0).text("ground through deep prints"));
    colour(ui, "ground albedo", &mut m.ground_albedo);
    ui.add(Slider::new(&mut m.ground_roughness, 0.05..=1.0).text("ground roughness"));
    colour(ui, "scatter tint", &mut m.scatter);
    ui.add(Slider::new(&mut m.wrap, 0.0..=1.0).text("wrap (subsurface)"));
    ui.add(Slider::new(&mut m.sparkle, 0.0..=4.0).text("sparkle"));
    ui.add(Slider::new(&mut m.detail_strength, 0.0..=1.0).text("detail normal strength"));
    ui.add(Slider::new(&mut m.detail_frequency, 0.05..=4.0).logarithmic(true).text("detail frequency").suffix(" /m"));
    ui.add(Slider::new(&mut m.macro_variation, 0.0..=0.5).text("macro variation"));
}

fn timing_table(ui: &mut egui::Ui, title: &str, rows: &[(String, f64)]) {
    ui.label(RichText::new(title).strong());
    if rows.is_empty() {
        ui.label("(collecting…)");
        return;
    }
    egui::Grid::new(title).striped(true).show(ui, |ui| {
        for (name, ms) in rows {
            ui.label(name);
            ui.label(format!("{ms:.3} ms"));
            ui.end_row();
        }
        ui.label(RichText::new("total").strong());
        ui.label(RichText::new(format!("{:.3} ms", rows.iter().map(|r| r.1).sum::<f64>())).strong());
        ui.end_row();
    });
}

fn frame_graph(ui: &mut egui::Ui, frames: &VecDeque<f32>) {
    let (rect, _) = ui.allocate_exact_size(egui::vec2(ui.available_width(), 60.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, Color32::from_black_alpha(80));
    let top = frames.iter().copied().fold(1.0f32, f32::max) * 1.1;
    for ms in [16.7f32, 33.3] {
        if ms < top {
            let y = rect.bottom() - rect.height() * ms / top;
            painter.line_segment([egui::pos2(rect.left(), y), egui::pos2(rect.right(), y)], Stroke::new(1.0, Color32::from_gray(90)));
        }
    }
    let n = PanelState::HISTORY as f32;
    let points: Vec<egui::Pos2> =
        frames.iter().enumerate().map(|(k, ms)| egui::pos2(rect.left() + rect.width() * k as f32 / n, rect.bottom() - rect.height() * ms / top)).collect();
    painter.add(egui::Shape::line(points, Stroke::new(1.5, Color32::LIGHT_GREEN)));
    painter.text(rect.left_top() + egui::vec2(4.0, 2.0), egui::Align2::LEFT_TOP, format!("max {top:.1} ms"), egui::FontId::monospace(10.0), Color32::GRAY);
}

/// Draws the panel; returns what to do after the frame.
pub fn show(ui: &mut egui::Ui, session: &mut Session, rig: &mut CameraRig, state: &mut PanelState) -> Vec<Action> {
    let mut actions = Vec::new();
    if !state.visible {
        return actions;
    }
    egui::Panel::left("controls").resizable(true).default_size(330.0).show(ui, |ui| {
        egui::ScrollArea::vertical().show(ui, |ui| {
            ui.heading("snowpack");
            let last = state.frame_ms.back().copied().unwrap_or(0.0);
            ui.label(format!("{} · {:.1} ms/frame · {:.0} fps", state.adapter, last, 1000.0 / last.max(0.01)));
            if let Some((msg, error)) = &state.status {
                ui.colored_label(if *error { Color32::LIGHT_RED } else { Color32::LIGHT_GREEN }, msg);
            }

            egui::CollapsingHeader::new("Simulation").default_open(true).show(ui, |ui| simulation_section(ui, session, state, &mut actions));

            egui::CollapsingHeader::new("Snowfall").default_open(session.snow_params.snowfall.is_some()).show(ui, |ui| snowfall_section(ui, session));

            egui::CollapsingHeader::new("Open world (tile store)")
                .default_open(session.scene.store.is_some())
                .show(ui, |ui| open_world_section(ui, session, &mut actions));

            egui::CollapsingHeader::new("Technique").default_open(true).show(ui, |ui| technique_section(ui, session));

            egui::CollapsingHeader::new("Deformation").default_open(true).show(ui, |ui| deformation_section(ui, session, &mut actions));

            egui::CollapsingHeader::new("Material").default_open(false).show(ui, |ui| material_ui(ui, &mut session.render_params.material));

            egui::CollapsingHeader::new("Light").default_open(false).show(ui, |ui| light_section(ui, session));

            egui::CollapsingHeader::new("Shell detail (grass, crust)")
                .default_open(session.render_params.shell.enabled)
                .show(ui, |ui| shell_detail_section(ui, session));

            egui::CollapsingHeader::new("Debug view (V)").default_open(false).show(ui, |ui| debug_view_section(ui, session));

            egui::CollapsingHeader::new("Camera (Tab)").default_open(false).show(ui, |ui| camera_section(ui, rig, state, &mut actions));

            egui::CollapsingHeader::new("Scene file").default_open(false).show(ui, |ui| scene_file_section(ui, state, &mut actions));

            egui::CollapsingHeader::new("Timings").default_open(true).show(ui, |ui| timings_section(ui, session, state));

            egui::CollapsingHeader::new("Keys").default_open(false).show(ui, keys_section);
        });
    });
    actions
}

/// The panel's "Simulation" section.
fn simulation_section(ui: &mut egui::Ui, session: &mut Session, state: &mut PanelState, actions: &mut Vec<Action>) {
    ui.horizontal(|ui| {
        if ui.button(if session.paused { "▶ run (P)" } else { "⏸ pause (P)" }).clicked() {
            session.paused = !session.paused;
        }
        if ui.button("step (N)").clicked() {
            session.single_step();
        }
        ui.checkbox(&mut session.physics, "physics");
    });
    ui.horizontal(|ui| {
        ui.add(Slider::new(&mut state.sphere_count, 0..=4096).logarithmic(true).text("spheres"));
        if ui.button("reset (R)").on_hover_text("fresh snow, spheres at new random places").clicked() {
            actions.push(Action::Reset(state.sphere_count));
        }
    });
    ui.horizontal(|ui| {
        ui.checkbox(&mut session.player.enabled, "player (WASD in follow mode)");
        let mut body = session.player.body;
        ComboBox::from_id_salt("player body").selected_text(PlayerBody::ALL.iter().find(|b| b.0 == body).map_or("", |b| b.1)).show_ui(ui, |ui| {
            for (b, name) in PlayerBody::ALL {
                ui.selectable_value(&mut body, b, name);
            }
        });
        if body != session.player.body {
            actions.push(Action::PlayerBody(body));
        }
    });
    match session.player.body {
        PlayerBody::Sphere => {
            ui.add(Slider::new(&mut session.player.radius, 0.1..=2.0).text("player radius").suffix(" m"));
            ui.add(Slider::new(&mut session.player.sink, 0.0..=1.0).text("player sinks").suffix(" × depth"));
            ui.add(Slider::new(&mut session.player.speed, 0.5..=20.0).text("player speed").suffix(" m/s"));
        }
        PlayerBody::Blade => {
            ui.add(Slider::new(&mut session.player.speed, 0.5..=20.0).text("blade speed").suffix(" m/s"));
            let (w, h, a) = crate::session::PLAYER_BLADE;
            ui.label(format!("a {w} m blade, {h} m tall, turned {a}° from its travel: turn on \"displace into berms\" (Deformation) for a windrow"));
        }
        PlayerBody::Fox => {
            ui.label(format!("the fox walks at {FOX_WALK_M_PER_S} m/s, runs at {FOX_RUN_M_PER_S} m/s with Shift"));
        }
    }
    coat_controls(ui, session);
    ui.add(Slider::new(&mut session.snow_params.hardness_kpa, 0.5..=200.0).logarithmic(true).text("snow hardness").suffix(" kPa"))
        .on_hover_text("how hard the snow is to press: characters on the snow sink half its depth where their foot pressure equals it");
    match &session.footsteps.1 {
        Some(f) => ui.label(format!(
            "footsteps: {} · last {} at ({:.1}, {:.1}) m, {} snow, sank {:.0} cm",
            session.footsteps.0,
            f.name,
            f.position.x,
            f.position.z,
            f.snow_depth_m.map_or("? m of".to_owned(), |d| format!("{d:.2} m of")),
            f.sink_m * 100.0
        )),
        None => ui.label("footsteps: none yet"),
    };
    ComboBox::from_label("window follows").selected_text(WindowFollow::ALL.iter().find(|f| f.0 == session.follow).map_or("", |f| f.1)).show_ui(ui, |ui| {
        for (f, name) in WindowFollow::ALL {
            ui.selectable_value(&mut session.follow, f, name);
        }
    });
}

/// The panel's "Snowfall" section.
fn snowfall_section(ui: &mut egui::Ui, session: &mut Session) {
    let mut on = session.snow_params.snowfall.is_some();
    if ui.checkbox(&mut on, "it snows (toggling rebuilds the window)").changed() {
        session.snow_params.snowfall = on.then(snowpack::Snowfall::default);
    }
    if let Some(f) = &mut session.snow_params.snowfall {
        ui.add(Slider::new(&mut f.rate_m_per_s, 0.0..=0.05).logarithmic(true).smallest_positive(1e-4).max_decimals(4).text("rate").suffix(" m/s"));
        let mut lean = glam::Vec2::new(f.direction.x, f.direction.z) / -f.direction.y;
        let before = lean;
        ui.add(Slider::new(&mut lean.x, -2.0..=2.0).text("wind x (lean)"));
        ui.add(Slider::new(&mut lean.y, -2.0..=2.0).text("wind z (lean)"));
        if lean != before {
            f.direction = glam::Vec3::new(lean.x, -1.0, lean.y).normalize();
        }
        ui.add(Slider::new(&mut f.flutter_deg, 0.0..=20.0).text("flutter").suffix("°"));
        ui.add(Slider::new(&mut f.repose_deg, 0.0..=90.0).text("angle of repose").suffix("°"));
        ui.add(Slider::new(&mut f.noise, 0.0..=1.0).text("noise"));
        ui.label(format!("fallen on open ground: {:.1} cm", session.snow_fallen_m() * 100.0));
        if let Some(acc) = session.accumulation_objects() {
            ui.label(format!("{acc} objects gathering snow"));
        }
    }
}

/// The panel's "Open world (tile store)" section.
fn open_world_section(ui: &mut egui::Ui, session: &mut Session, actions: &mut Vec<Action>) {
    use snowpack_scene::StoreKeep;
    let keep = session.store_keep();
    ui.horizontal(|ui| {
        ui.label("keep trails (rebuilds):");
        let hints = [
            (StoreKeep::Memory, "texels leaving the window go to resident tiles, then to memory (a bounded budget), and come back refilled by the time away"),
            (StoreKeep::Disk, "as memory, then compressed on disk; the snow can be saved and a later start resumes it"),
            (StoreKeep::Off, "texels leaving the window are forgotten"),
        ];
        for (choice, hint) in hints {
            // A browser page has no folder to keep tiles in.
            if WEB && choice == StoreKeep::Disk {
                continue;
            }
            if ui.radio(keep == choice, choice.as_str()).on_hover_text(hint).clicked() && keep != choice {
                actions.push(Action::Store(choice));
            }
        }
    });
    if let Some(t) = session.snow.tile_stats() {
        let s = &t.store;
        ui.label(format!(
            "GPU: {} of {} slots resident ({:.1} MB) · {} restored · {} fresh · {} evicted",
            t.resident,
            t.slots,
            t.gpu_bytes as f64 / 1e6,
            t.restored,
            t.fresh,
            t.evicted
        ));
        ui.label(format!("memory: {} tiles, {:.1} MB · hit rate {:.0}%", s.memory_tiles, s.memory_bytes as f64 / 1e6, s.hit_rate() * 100.0));
        ui.label(format!(
            "disk: {} tiles, {:.2} MB · {:.2} MB written · {} evicted",
            s.disk_tiles,
            s.disk_bytes as f64 / 1e6,
            s.bytes_written as f64 / 1e6,
            s.evicted
        ));
        ui.label(format!(
            "window held {} frames for tiles · {} stood in, {} merged live, {} awaiting · {} blocking loads",
            t.window_waits, t.stood_in, t.merged_live, t.awaiting_merge, t.blocking_loads
        ));
        ui.label(format!("{} errors · {} corrupt · {} lost", s.errors, s.corrupt, s.lost));
        ui.label(format!("time {:.1} s", session.snow.clock().time_s));
        for e in &session.store_errors {
            ui.colored_label(Color32::LIGHT_RED, e);
        }
        if !t.memory_only
            && ui
                .button("save the snow")
                .on_hover_text("every tile and the window's clock and position into the store; the next start with this store resumes there")
                .clicked()
        {
            actions.push(Action::SaveStore);
        }
    }
}

/// The panel's "Technique" section.
fn technique_section(ui: &mut egui::Ui, session: &mut Session) {
    ui.horizontal(|ui| {
        for (k, t) in Technique::ALL.iter().enumerate() {
            ui.radio_value(&mut session.snow_params.technique, *t, format!("{} ({})", t.as_str(), k + 1));
        }
    });
}

/// The panel's "Deformation" section.
fn deformation_section(ui: &mut egui::Ui, session: &mut Session, actions: &mut Vec<Action>) {
    let p = &mut session.snow_params;
    ui.add(Slider::new(&mut p.refill_m_per_s, 0.0..=0.1).logarithmic(true).smallest_positive(1e-4).max_decimals(4).text("refill").suffix(" m/s"));
    ui.add(Slider::new(&mut p.elevation, 0.0..=4.0).text("rim elevation"));
    ui.checkbox(&mut p.blur, "5x5 Gaussian blur");
    ui.add(Slider::new(&mut p.range_texels, 32..=128).text("point range").suffix(" texels"));
    ComboBox::from_label("point rim").selected_text(p.rim.as_str()).show_ui(ui, |ui| {
        ui.selectable_value(&mut p.rim, RimStyle::Rounded, RimStyle::Rounded.as_str());
        ui.selectable_value(&mut p.rim, RimStyle::Ms16, RimStyle::Ms16.as_str());
    });
    let mut repose = p.repose_deg.is_some();
    ui.horizontal(|ui| {
        ui.checkbox(&mut repose, "walls slide")
            .on_hover_text("erosion: walls steeper than the angle of repose slide into the trench beside them (off while sharing)");
        let mut deg = p.repose_deg.unwrap_or(38.0);
        ui.add_enabled(repose, Slider::new(&mut deg, 10.0..=80.0).text("angle of repose").suffix("°"));
        p.repose_deg = repose.then_some(deg);
    });
    ui.separator();
    ui.label("These rebuild the window (fresh snow):");
    ui.checkbox(&mut p.displace, "displace into berms")
        .on_hover_text("snow squeezed beyond the final density (a blade's cut) moves aside into berms and windrows (docs/mechanics.md)");
    ui.add(Slider::new(&mut p.depth_m, 0.0..=3.0).text("snow depth").suffix(" m"));
    ui.add(Slider::new(&mut p.extent_m, 4.0..=256.0).logarithmic(true).text("window").suffix(" m"));
    let mut log2 = p.resolution.ilog2();
    ui.add(Slider::new(&mut log2, 6..=12).text("resolution").custom_formatter(|v, _| format!("{}²", 1u32 << v as u32)));
    p.resolution = 1 << log2;
    ui.label(format!("{:.1} cm per texel", p.extent_m / p.resolution as f32 * 100.0));
    let rp = &mut session.render_params;
    ui.add(Slider::new(&mut rp.shadow_map_size, 512..=8192).logarithmic(true).text("shadow map").suffix(" texels"));
    if ui.add_enabled(session.needs_rebuild(), egui::Button::new("apply (fresh snow)")).clicked() {
        actions.push(Action::Rebuild);
    }
}

/// The panel's "Light" section.
fn light_section(ui: &mut egui::Ui, session: &mut Session) {
    let light = &mut session.render_params.light;
    let mut from_sky = light.sun_direction.is_none();
    ui.checkbox(&mut from_sky, "sun from the sky's brightest point");
    if from_sky {
        light.sun_direction = None;
    } else {
        let (mut elevation, mut azimuth) = sun_angles(light.sun_direction.unwrap_or_else(|| session.renderer.sun_direction()));
        ui.add(Slider::new(&mut elevation, 0.5..=90.0).text("sun elevation").suffix("°"));
        ui.add(Slider::new(&mut azimuth, 0.0..=360.0).text("sun azimuth").suffix("°"));
        light.sun_direction = Some(sun_from_angles(elevation, azimuth));
    }
    ui.add(Slider::new(&mut light.sun_intensity, 0.0..=10.0).text("sun intensity"));
    ui.add(Slider::new(&mut light.sky_intensity, 0.0..=4.0).text("sky intensity"));
    ui.add(Slider::new(&mut light.exposure_ev, -6.0..=6.0).text("exposure").suffix(" EV"));
    let rp = &mut session.render_params;
    ui.add(Slider::new(&mut rp.ao_strength, 0.0..=2.0).text("ambient occlusion"));
    ui.add(Slider::new(&mut rp.shadow_distance_m, 10.0..=500.0).logarithmic(true).text("shadow distance").suffix(" m"));
    ui.add(Slider::new(&mut rp.view_distance_m, 50.0..=5000.0).logarithmic(true).text("view distance").suffix(" m"));
}

/// The panel's "Shell detail (grass, crust)" section.
fn shell_detail_section(ui: &mut egui::Ui, session: &mut Session) {
    let shell = &mut session.render_params.shell;
    ui.checkbox(&mut shell.enabled, "volumetric detail near the camera");
    ui.horizontal(|ui| {
        for kind in [DetailKind::Grass, DetailKind::Crust] {
            ui.radio_value(&mut shell.texture, kind, kind.name());
        }
    });
    let mut exponent = shell.texture_size.trailing_zeros();
    ui.add(Slider::new(&mut exponent, 4..=8).text("texture size (2^n)"));
    shell.texture_size = 1 << exponent;
    ui.add(Slider::new(&mut shell.thickness_m, 0.01..=0.4).text("thickness").suffix(" m"));
    ui.add(Slider::new(&mut shell.tile_m, 0.05..=2.0).logarithmic(true).text("texture repeat").suffix(" m"));
    ui.add(Slider::new(&mut shell.radius_m, 1.0..=16.0).text("radius").suffix(" m"));
    ui.add(Slider::new(&mut shell.flatten_m, 0.01..=0.5).text("pressing that flattens it").suffix(" m"));
    ui.checkbox(&mut shell.lod, "mip levels from the footprint");
    ui.add(Slider::new(&mut shell.passes, 1..=16).text("peeling passes"));
    ui.add(Slider::new(&mut shell.opacity, 0.5..=1.0).text("opacity that ends peeling"));
    ui.add(Slider::new(&mut shell.debug_pass, 0..=shell.passes).text("show pixels of pass (0 off)"));
    shell.debug_pass = shell.debug_pass.min(shell.passes);
}

/// The panel's "Debug view (V)" section.
fn debug_view_section(ui: &mut egui::Ui, session: &mut Session) {
    for (v, name) in DebugView::ALL {
        ui.radio_value(&mut session.render_params.debug_view, v, name);
    }
}

/// The panel's "Camera (Tab)" section.
fn camera_section(ui: &mut egui::Ui, rig: &mut CameraRig, state: &mut PanelState, actions: &mut Vec<Action>) {
    let mut mode = rig.mode;
    for (m, name) in CameraMode::ALL {
        ui.radio_value(&mut mode, m, name);
    }
    if mode != rig.mode {
        actions.push(Action::CameraMode(mode));
    }
    ui.add(Slider::new(&mut rig.fov_deg, 20.0..=110.0).text("field of view").suffix("°"));
    ui.add(Slider::new(&mut rig.speed, 0.5..=500.0).logarithmic(true).text("fly speed").suffix(" m/s"));
    let mut vsync = state.vsync;
    if ui.checkbox(&mut vsync, "vsync").changed() {
        actions.push(Action::Vsync(vsync));
    }
}

/// The panel's "Scene file" section.
fn scene_file_section(ui: &mut egui::Ui, state: &mut PanelState, actions: &mut Vec<Action>) {
    if WEB {
        ui.label("the browser build runs the built-in default scene: a page has no files to load or save");
        return;
    }
    ui.text_edit_singleline(&mut state.scene_path);
    ui.horizontal(|ui| {
        if ui.button("load").clicked() {
            actions.push(Action::Load(state.scene_path.clone()));
        }
        if ui.button("save").clicked() {
            actions.push(Action::Save(state.scene_path.clone()));
        }
    });
}

/// The panel's "Timings" section.
fn timings_section(ui: &mut egui::Ui, session: &mut Session, state: &mut PanelState) {
    frame_graph(ui, &state.frame_ms);
    if state.timestamps {
        timing_table(ui, "deformation (GPU)", &session.timings.deform);
        timing_table(ui, "rendering (GPU)", &session.timings.render);
    } else {
        ui.label("GPU timings: this adapter has no timestamp queries");
    }
    let stats = session.renderer.stats();
    let p = session.snow.params();
    ui.label(format!(
        "actors {} (spheres {}) · window {}² over {} m · surface {}x{} · vsync {}",
        session.deformers().len(),
        session.sphere_count(),
        p.resolution,
        p.extent_m,
        state.surface.0,
        state.surface.1,
        if state.vsync { "on" } else { "off" }
    ));
    ui.label(format!(
        "terrain {} patches, {} triangles, levels {}–{} · GPU memory {:.1} MiB",
        stats.patches,
        stats.terrain_triangles,
        stats.levels.0,
        stats.levels.1,
        session.memory_bytes() as f64 / (1024.0 * 1024.0)
    ));
}

/// The panel's "Keys" section.
fn keys_section(ui: &mut egui::Ui) {
    ui.label("1–4 technique · R reset · P pause · N step · Tab camera · V view · G grass · H panel");
    ui.label("orbit: left drag turn, right drag pan, wheel zoom");
    ui.label("fly: right drag look, WASD move, Q/E down/up, wheel speed, Shift fast");
    ui.label("follow: WASD drives the player (Shift: the fox runs), right drag turns, wheel zoom · F sphere/fox");
}

/// Carries out a panel action that needs no window (all but
/// [`Action::Vsync`], which the window's owner applies; here it only records
/// the choice) and says what happened in words for the status line.
pub fn apply(action: Action, ctx: &snowpack::GpuContext, session: &mut Session, rig: &mut CameraRig, state: &mut PanelState) -> anyhow::Result<String> {
    match action {
        Action::Reset(count) => session.reset(ctx, count).map(|()| format!("reset: fresh snow, {count} spheres")),
        Action::Rebuild => session.rebuild(ctx).map(|()| "rebuilt the window (fresh snow)".to_owned()),
        Action::Store(keep) => session.set_store(ctx, keep).map(|()| match keep {
            snowpack_scene::StoreKeep::Disk => "trails kept on disk: they stay when the window moves on, and the snow can be saved".to_owned(),
            snowpack_scene::StoreKeep::Memory => "trails kept in memory: they stay when the window moves on".to_owned(),
            snowpack_scene::StoreKeep::Off => "trails are forgotten when the window moves on".to_owned(),
        }),
        Action::SaveStore => session.save_store(ctx),
        Action::CameraMode(mode) => {
            rig.set_mode(mode, session.player.position);
            if mode == CameraMode::Follow {
                session.follow = WindowFollow::Player;
            }
            Ok(format!("camera: {}", CameraMode::ALL.iter().find(|m| m.0 == mode).map_or("", |m| m.1)))
        }
        Action::Load(path) => snowpack_scene::Scene::load(std::path::Path::new(&path)).map_err(anyhow::Error::from).and_then(|scene| {
            let camera = snowpack::Camera { position: scene.camera.position, target: scene.camera.target, fov_deg: scene.camera.fov_deg };
            session.load(ctx, scene)?;
            *rig = CameraRig::from_camera(&camera);
            state.sphere_count = session.sphere_count() as u32;
            Ok(format!("loaded {path}"))
        }),
        Action::PlayerBody(body) => {
            session.set_body(ctx, body).map(|()| format!("player: {}", PlayerBody::ALL.iter().find(|b| b.0 == body).map_or("", |b| b.1)))
        }
        Action::Vsync(on) => {
            state.vsync = on;
            Ok(format!("vsync {}", if on { "on" } else { "off" }))
        }
        Action::Save(path) => {
            let camera = rig.camera(session.player.position);
            session
                .scene_to_save(&camera)
                .save(std::path::Path::new(&path))
                .map(|()| format!("saved {path}"))
                .map_err(|e| anyhow::anyhow!("saving {path}: {e}"))
        }
    }
}
