//! The snow's figures in Bevy's `DiagnosticsStore`, where
//! `LogDiagnosticsPlugin` (or a game's overlay) shows them: the GPU time of
//! each of the library's passes and their sum, the GPU memory the snow
//! holds, the tiles resident around the window, and the shared snow's bytes
//! per second each way (on a client with [`crate::SnowReplicationPlugin`]).
//!
//! The render world reads the deformation after each frame's encode
//! ([`SnowDeformation::last_timings`](snowpack::SnowDeformation::last_timings):
//! the newest frame whose timestamps came back, a frame or two late; none
//! where the device lacks timestamp queries) and sends the figures through
//! a channel of its own; the main world records them in `PreUpdate`, after
//! [`SnowSystems::Receive`].

use std::sync::mpsc::{Receiver, Sender};

use bevy::diagnostic::{Diagnostic, DiagnosticMeasurement, DiagnosticPath, DiagnosticsStore, RegisterDiagnostic};
use bevy::platform::cell::SyncCell;
use bevy::platform::time::Instant;
use bevy::prelude::*;
use bevy::render::{Render, RenderApp, RenderSystems};

#[cfg(feature = "multiplayer")]
use crate::SnowSharing;
use crate::SnowSystems;
use crate::render_state::SnowRenderState;

/// Adds the snow's diagnostics (after [`crate::SnowpackPlugin`]):
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy::diagnostic::LogDiagnosticsPlugin;
/// # use bevy_snowpack::prelude::*;
/// App::new().add_plugins((DefaultPlugins, SnowpackPlugin::default(), SnowpackDiagnosticsPlugin, LogDiagnosticsPlugin::default()));
/// ```
///
/// | path | what |
/// |---|---|
/// | `snowpack/gpu_ms/total` | the sum of the passes' GPU time (ms) |
/// | `snowpack/gpu_ms/<pass>` | one pass's GPU time (ms), by the library's label (`/` and spaces as `_`) |
/// | `snowpack/gpu_memory_mib` | GPU memory the snow holds (MiB) |
/// | `snowpack/resident_tiles` | tiles resident on the GPU around the window |
/// | `snowpack/peer_bytes_in_per_s`, `snowpack/peer_bytes_out_per_s` | shared snow received and sent (bytes/s; clients only) |
#[derive(Default)]
pub struct SnowpackDiagnosticsPlugin;

impl SnowpackDiagnosticsPlugin {
    /// The sum of the passes' GPU time (ms).
    pub const GPU_MS: DiagnosticPath = DiagnosticPath::const_new("snowpack/gpu_ms/total");
    /// GPU memory the snow holds (MiB).
    pub const GPU_MEMORY: DiagnosticPath = DiagnosticPath::const_new("snowpack/gpu_memory_mib");
    /// Tiles resident on the GPU around the window.
    pub const RESIDENT_TILES: DiagnosticPath = DiagnosticPath::const_new("snowpack/resident_tiles");
    /// Shared-snow bytes received per second (a client's peer).
    pub const PEER_BYTES_IN: DiagnosticPath = DiagnosticPath::const_new("snowpack/peer_bytes_in_per_s");
    /// Shared-snow bytes sent per second (a client's peer).
    pub const PEER_BYTES_OUT: DiagnosticPath = DiagnosticPath::const_new("snowpack/peer_bytes_out_per_s");

    /// The path of one pass's GPU time (ms), by the library's label.
    #[must_use]
    pub fn pass(label: &str) -> DiagnosticPath {
        let name: String = label.chars().map(|c| if c == '/' || c.is_whitespace() { '_' } else { c }).collect();
        let name = if name.is_empty() { "unnamed".to_owned() } else { name };
        DiagnosticPath::from_components(["snowpack", "gpu_ms", name.as_str()])
    }
}

impl Plugin for SnowpackDiagnosticsPlugin {
    fn build(&self, app: &mut App) {
        let (to_main, from_render) = std::sync::mpsc::channel();
        app.register_diagnostic(Diagnostic::new(Self::GPU_MS).with_suffix(" ms"))
            .register_diagnostic(Diagnostic::new(Self::GPU_MEMORY).with_suffix(" MiB"))
            .register_diagnostic(Diagnostic::new(Self::RESIDENT_TILES))
            .register_diagnostic(Diagnostic::new(Self::PEER_BYTES_IN).with_suffix(" B/s"))
            .register_diagnostic(Diagnostic::new(Self::PEER_BYTES_OUT).with_suffix(" B/s"))
            .insert_resource(FromRender(SyncCell::new(from_render)))
            .add_systems(PreUpdate, record_render_figures.after(SnowSystems::Receive));
        // A client's byte rates: only a build with shared snow has a client.
        #[cfg(feature = "multiplayer")]
        app.add_systems(PreUpdate, record_peer_rates.after(SnowSystems::Receive));
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render_app.insert_resource(ToMain(to_main)).add_systems(Render, measure.in_set(RenderSystems::Cleanup));
        }
    }
}

/// One frame's figures from the render world.
struct Figures {
    /// (pass label, ms) of the newest timed frame.
    passes: Vec<(String, f64)>,
    total_ms: Option<f64>,
    memory_bytes: u64,
    resident_tiles: usize,
}

/// The render world's end of the channel.
#[derive(Resource)]
struct ToMain(Sender<Figures>);

/// The main world's end.
#[derive(Resource)]
struct FromRender(SyncCell<Receiver<Figures>>);

/// Reads the deformation's figures after the frame (render world).
fn measure(state: Option<Res<SnowRenderState>>, to_main: Res<ToMain>) {
    let Some(state) = state else { return };
    let snow = state.deformation();
    let timings = snow.last_timings();
    let figures = Figures {
        total_ms: (!timings.passes.is_empty()).then(|| timings.total_ms()),
        passes: timings.passes.into_iter().map(|(label, ms, _)| (label, ms)).collect(),
        memory_bytes: snow.gpu_memory_bytes(),
        resident_tiles: snow.resident_tiles(),
    };
    // A main world that has gone (the app is closing) is not an error.
    let _ = to_main.0.send(figures);
}

/// Adds a measurement, registering a pass's diagnostic the first time it is seen.
fn add(store: &mut DiagnosticsStore, path: &DiagnosticPath, suffix: &'static str, value: f64, time: Instant) {
    if store.get(path).is_none() {
        store.add(Diagnostic::new(path.clone()).with_suffix(suffix));
    }
    if let Some(diagnostic) = store.get_mut(path).filter(|d| d.is_enabled) {
        diagnostic.add_measurement(DiagnosticMeasurement { time, value });
    }
}

/// Records what the render world measured (main world).
fn record_render_figures(mut from: ResMut<FromRender>, mut store: ResMut<DiagnosticsStore>) {
    let time = Instant::now();
    for figures in from.0.get().try_iter() {
        for (label, ms) in &figures.passes {
            add(&mut store, &SnowpackDiagnosticsPlugin::pass(label), " ms", *ms, time);
        }
        if let Some(total) = figures.total_ms {
            add(&mut store, &SnowpackDiagnosticsPlugin::GPU_MS, " ms", total, time);
        }
        add(&mut store, &SnowpackDiagnosticsPlugin::GPU_MEMORY, " MiB", figures.memory_bytes as f64 / f64::from(1u32 << 20), time);
        add(&mut store, &SnowpackDiagnosticsPlugin::RESIDENT_TILES, "", figures.resident_tiles as f64, time);
    }
}

/// The shared snow's bytes so far (received, sent) at the last record.
#[cfg(feature = "multiplayer")]
#[derive(Default)]
struct LastBytes(Option<(u64, u64)>);

/// Records the shared snow's byte rates from [`SnowSharing`]'s counters (a client).
#[cfg(feature = "multiplayer")]
fn record_peer_rates(sharing: Option<Res<SnowSharing>>, time: Res<Time<Real>>, mut last: Local<LastBytes>, mut store: ResMut<DiagnosticsStore>) {
    let Some(sharing) = sharing else { return };
    let now = (sharing.bytes_received(), sharing.bytes_sent());
    let dt = time.delta_secs_f64();
    if let Some((received, sent)) = last.0
        && dt > 0.0
    {
        let at = Instant::now();
        add(&mut store, &SnowpackDiagnosticsPlugin::PEER_BYTES_IN, " B/s", now.0.saturating_sub(received) as f64 / dt, at);
        add(&mut store, &SnowpackDiagnosticsPlugin::PEER_BYTES_OUT, " B/s", now.1.saturating_sub(sent) as f64 / dt, at);
    }
    last.0 = Some(now);
}
