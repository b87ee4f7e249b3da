//! A headless Bevy app with the plugin: Bevy's render plugins without a window
//! (no winit), updated by hand.

use bevy::app::PluginsState;
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::window::ExitCondition;
use bevy_snowpack::{SnowRenderState, SnowpackPlugin, SnowpackSettings};

/// Whether a missing adapter fails the test (CI) instead of skipping it.
pub fn gpu_required() -> bool {
    std::env::var_os("SNOWPACK_REQUIRE_GPU").is_some_and(|v| v != "0")
}

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
