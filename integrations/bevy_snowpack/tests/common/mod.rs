//! A headless Bevy app with the plugin: Bevy's render plugins without a window
//! (no winit), updated by hand; and for the examples' tests, a private X
//! server and the example binaries.

use std::path::PathBuf;

use bevy::app::PluginsState;
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::window::ExitCondition;
use bevy_snowpack::{SnowRenderState, SnowpackPlugin, SnowpackSettings};
use snowpack::low_level::SnowInspect;

/// Whether a missing adapter fails the test (CI) instead of skipping it.
pub fn gpu_required() -> bool {
    std::env::var_os("SNOWPACK_REQUIRE_GPU").is_some_and(|v| v != "0")
}

#[allow(dead_code, reason = "each test file uses its own subset of these helpers")]
/// An app with the plugin, ready to update; `None` (skip) when there is no adapter and none is required.
pub fn headless_app(settings: SnowpackSettings) -> Option<App> {
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin { primary_window: None, exit_condition: ExitCondition::DontExit, close_when_requested: false, ..default() })
            .disable::<bevy::winit::WinitPlugin>()
            // Each test's app would install the global logger again.
            .disable::<bevy::log::LogPlugin>(),
    )
    .add_plugins(SnowpackPlugin::new(settings));
    while app.plugins_state() == PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    app.cleanup();
    if app.get_sub_app(RenderApp).is_none() {
        assert!(!gpu_required(), "no GPU adapter for Bevy's renderer, and SNOWPACK_REQUIRE_GPU is set");
        return None;
    }
    Some(app)
}

/// The plugin's deformation in the render world.
#[allow(dead_code, reason = "each test file uses its own subset of these helpers")]
pub fn render_state(app: &App) -> &SnowRenderState {
    app.get_sub_app(RenderApp).expect("render app").world().get_resource::<SnowRenderState>().expect("the plugin created its deformation")
}

/// Settings for the tests: an 8 m window of 128 texels (6.25 cm) in 0.4 m of
/// snow on flat ground, no refill, a fixed 1/60 s step.
#[allow(dead_code, reason = "each test file uses its own subset of these helpers")]
pub fn test_settings() -> SnowpackSettings {
    SnowpackSettings {
        params: snowpack::SnowParams { extent_m: 8.0, resolution: 128, depth_m: 0.4, refill_m_per_s: 0.0, ..snowpack::SnowParams::default() },
        terrain: snowpack::TerrainSource::Flat { height_m: 0.0 },
        center: Vec2::ZERO,
        fixed_dt_s: Some(1.0 / 60.0),
        store: None,
    }
}

/// The plugin's persistent snow heights (row-major, z rows) and a lookup of the texel under world (x, z).
#[allow(dead_code, reason = "each test file uses its own subset of these helpers")]
pub fn snow_heights(app: &App) -> impl Fn(f32, f32) -> f32 {
    let state = render_state(app);
    let snow = state.deformation();
    let heights = snow.read_snow(state.context()).expect("read the plugin's snow");
    let origin = snow.origin_m().expect("the window is placed");
    let (n, texel) = (snow.params().resolution as usize, f64::from(snow.params().texel_m()));
    move |x: f32, z: f32| {
        let j = ((f64::from(x) - origin.x) / texel).floor() as usize;
        let i = ((f64::from(z) - origin.y) / texel).floor() as usize;
        heights[i.min(n - 1) * n + j.min(n - 1)]
    }
}

pub mod xvfb;

#[allow(dead_code, reason = "each test file uses its own subset of these helpers")]
/// The example binary `cargo test` built next to this test's own.
pub fn example(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("the test's path");
    let dir = exe.parent().and_then(|deps| deps.parent()).expect("target/<profile>/deps");
    dir.join("examples").join(name)
}

#[allow(dead_code, reason = "each test file uses its own subset of these helpers")]
/// Mean luma (0..255) of the 9x9 pixels around (x, y).
pub fn patch_luma(image: &image::RgbaImage, x: u32, y: u32) -> f32 {
    let mut sum = 0.0;
    let mut n = 0.0;
    for py in y.saturating_sub(4)..=(y + 4).min(image.height() - 1) {
        for px in x.saturating_sub(4)..=(x + 4).min(image.width() - 1) {
            let [r, g, b, _] = image.get_pixel(px, py).0;
            sum += 0.2126 * f32::from(r) + 0.7152 * f32::from(g) + 0.0722 * f32::from(b);
            n += 1.0;
        }
    }
    sum / n
}
