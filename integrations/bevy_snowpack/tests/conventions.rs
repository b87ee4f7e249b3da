//! Bevy's conventions: the settings survive a `Reflect` round trip (clone,
//! apply, and Bevy's reflect serializer through RON); the snow's figures
//! reach Bevy's `DiagnosticsStore`; answers and save results come to
//! observers as events (and still to `take`); every deformer kind presses
//! what it should: a capsule, a contact point, a wheel held on the snow by
//! its load (with a rolling resistance), a deformer gets its `Transform`;
//! the plugin's sources use the library's front door alone.

mod common;

use bevy::app::{Plugins, PluginsState};
use bevy::diagnostic::{DiagnosticPath, DiagnosticsStore};
use bevy::prelude::*;
use bevy::reflect::serde::{ReflectDeserializer, ReflectSerializer};
use bevy::reflect::{FromReflect, TypeRegistry};
use bevy::render::RenderApp;
use bevy::render::renderer::RenderDevice;
use bevy::window::ExitCondition;
use bevy_snowpack::prelude::*;
use serde::de::DeserializeSeed;

/// An app with the plugin and `extra` (added before `finish`); `None` (skip) without an adapter.
fn app_with<M>(settings: SnowpackSettings, extra: impl Plugins<M>) -> Option<App> {
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin { primary_window: None, exit_condition: ExitCondition::DontExit, close_when_requested: false, ..default() })
            .disable::<bevy::winit::WinitPlugin>()
            .disable::<bevy::log::LogPlugin>(),
    )
    .add_plugins(SnowpackPlugin::new(settings))
    .add_plugins(extra);
    while app.plugins_state() == PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    app.cleanup();
    if app.get_sub_app(RenderApp).is_none() {
        assert!(!common::gpu_required(), "no GPU adapter for Bevy's renderer, and SNOWPACK_REQUIRE_GPU is set");
        return None;
    }
    Some(app)
}

fn custom_settings() -> SnowpackSettings {
    SnowpackSettings {
        params: SnowParams { extent_m: 12.0, resolution: 256, depth_m: 0.3, refill_m_per_s: 0.05, technique: Technique::Combined, ..SnowParams::default() },
        terrain: TerrainSource::Noise(NoiseTerrain { seed: 7, base_m: 1.0, amplitude_m: 0.5, wavelength_m: 9.0 }),
        center: Vec2::new(3.0, -2.0),
        fixed_dt_s: Some(1.0 / 30.0),
        store: Some(SnowStoreSettings { tile_texels: 48, ..SnowStoreSettings::new("/tmp/snow-store") }),
    }
}

#[test]
fn the_settings_survive_a_reflect_round_trip() {
    let settings = custom_settings();
    // reflect_clone: everything, the library's opaque fields included.
    let cloned = settings.reflect_clone().expect("SnowpackSettings reflects Clone").take::<SnowpackSettings>().expect("the same type");
    assert_eq!(cloned.params, settings.params);
    assert_eq!(cloned.terrain, settings.terrain);
    assert_eq!((cloned.center, cloned.fixed_dt_s), (settings.center, settings.fixed_dt_s));
    assert_eq!(cloned.store.as_ref().map(|s| (s.dir.clone(), s.tile_texels)), Some(("/tmp/snow-store".into(), 48)));

    // apply: the reflected fields onto defaults; the opaque ones stay as they were.
    let mut applied = SnowpackSettings::default();
    applied.apply(settings.as_partial_reflect());
    assert_eq!((applied.center, applied.fixed_dt_s), (settings.center, settings.fixed_dt_s));
    assert_eq!(applied.store.as_ref().map(|s| s.tile_texels), Some(48));
    assert_eq!(applied.params, SnowpackSettings::default().params);

    // Bevy's reflect serializer, through RON and back.
    let mut registry = TypeRegistry::default();
    registry.register::<SnowpackSettings>();
    let text = ron::to_string(&ReflectSerializer::new(&settings, &registry)).expect("serialized");
    assert!(text.contains("bevy_snowpack::SnowpackSettings") && text.contains("snow-store"), "{text}");
    let mut de = ron::Deserializer::from_str(&text).expect("RON");
    let value = ReflectDeserializer::new(&registry).deserialize(&mut de).expect("deserialized");
    let back = SnowpackSettings::from_reflect(value.as_partial_reflect()).expect("a SnowpackSettings");
    assert_eq!((back.center, back.fixed_dt_s), (settings.center, settings.fixed_dt_s));
    assert_eq!(back.store.as_ref().map(|s| (s.dir.clone(), s.tile_texels)), Some(("/tmp/snow-store".into(), 48)));
    // The library's types are not reflected: the settings' defaults come back.
    assert_eq!(back.params, SnowpackSettings::default().params);
    assert_eq!(back.terrain, TerrainSource::Flat { height_m: 0.0 });

    // The plugin's builders make the same settings as a literal.
    let built = SnowpackPlugin::default().with_window(12.0, 256).with_depth(0.3).with_center(Vec2::new(3.0, -2.0)).with_fixed_dt(1.0 / 30.0);
    assert_eq!((built.settings.params.extent_m, built.settings.params.resolution, built.settings.params.depth_m), (12.0, 256, 0.3));
    assert_eq!((built.settings.center, built.settings.fixed_dt_s), (settings.center, settings.fixed_dt_s));
    // Components reflect too.
    let wheel = SnowWheel::new(0.3, 0.2, 200.0).reflect_clone().expect("clone").take::<SnowWheel>().expect("a wheel");
    assert_eq!(wheel, SnowWheel::new(0.3, 0.2, 200.0));
}

#[test]
fn the_snow_figures_reach_the_diagnostics_store() {
    let Some(mut app) = app_with(common::test_settings(), SnowpackDiagnosticsPlugin) else { return };
    app.world_mut().spawn((SnowDeformer::Sphere { radius: 0.3 }, Transform::from_xyz(0.0, 0.35, 0.0)));
    for _ in 0..20 {
        app.update();
    }
    let timestamps = app.get_sub_app(RenderApp).expect("render app").world().resource::<RenderDevice>().features().contains(wgpu::Features::TIMESTAMP_QUERY);
    let store = app.world().resource::<DiagnosticsStore>();
    let value = |path: &DiagnosticPath| -> Option<f64> { store.get_measurement(path).map(|m| m.value) };
    let memory = value(&SnowpackDiagnosticsPlugin::GPU_MEMORY).expect("the snow's GPU memory is measured");
    // 128² texels of several planes: well over a tenth of a MiB, under a GiB.
    assert!(memory > 0.1 && memory < 1024.0, "{memory} MiB");
    assert!(value(&SnowpackDiagnosticsPlugin::RESIDENT_TILES).is_some_and(|t| t >= 0.0), "resident tiles are measured");
    let passes: Vec<(String, f64)> = store
        .iter()
        .filter(|d| d.path().as_str().starts_with("snowpack/gpu_ms/") && *d.path() != SnowpackDiagnosticsPlugin::GPU_MS)
        .filter_map(|d| d.value().map(|v| (d.path().as_str().to_owned(), v)))
        .collect();
    println!("timestamps {timestamps}; memory {memory:.2} MiB; passes {passes:?}; total {:?}", value(&SnowpackDiagnosticsPlugin::GPU_MS));
    if timestamps {
        let total = value(&SnowpackDiagnosticsPlugin::GPU_MS).expect("the passes' GPU time is measured");
        assert!(total > 0.0 && !passes.is_empty(), "total {total} ms, passes {passes:?}");
        assert!(passes.iter().all(|(_, ms)| *ms >= 0.0));
    }
}

/// What the observers saw.
#[derive(Resource, Default)]
struct Seen {
    answers: Vec<SnowAnswers>,
    saves: Vec<Result<u64, String>>,
}

#[test]
fn answers_and_saves_come_to_observers() {
    let Some(mut app) = app_with(common::test_settings(), ()) else { return };
    app.init_resource::<Seen>()
        .add_observer(|answered: On<SnowAnswered>, mut seen: ResMut<Seen>| seen.answers.push(answered.answers.clone()))
        .add_observer(|saved: On<SnowSaved>, mut seen: ResMut<Seen>| seen.saves.push(saved.result.clone()));
    app.update();
    let ticket = app.world_mut().resource_mut::<SnowQuery>().ask(&[Vec2::new(1.0, 1.0)]);
    // No disk store: the save fails, and says so.
    app.world_mut().resource_mut::<SnowControl>().request_save();
    for _ in 0..10 {
        app.update();
    }
    let seen = app.world().resource::<Seen>();
    let answer = seen.answers.iter().find(|a| a.ticket == ticket).expect("the answer came to the observer");
    let depth = answer.samples[0].expect("inside the window").depth_m();
    assert!((depth - 0.4).abs() < 1e-3, "{depth}");
    // Only the game's own question is announced (the plugin asks its own quietly).
    assert_eq!(seen.answers.len(), 1);
    assert!(matches!(seen.saves.as_slice(), [Err(_)]), "{:?}", seen.saves);
    // Polling still works beside the events.
    assert!(app.world_mut().resource_mut::<SnowQuery>().take(ticket).is_some());
    assert!(app.world_mut().resource_mut::<SnowControl>().take_save_result().is_some_and(|r| r.is_err()));
}

#[derive(Component)]
struct Rolling;

#[test]
fn every_deformer_kind_presses_what_it_should() {
    let mut settings = common::test_settings();
    // Contact points press with the points technique; the depth technique presses the rest.
    settings.params.technique = Technique::Combined;
    let Some(mut app) = app_with(settings, ()) else { return };
    let world = app.world_mut();
    // A capsule lying along x, its bottom 0.15 m above the ground.
    world.spawn((
        SnowDeformer::Capsule { radius: 0.2, half_length: 0.3 },
        Transform::from_xyz(-2.0, 0.35, -2.0).with_rotation(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2)),
    ));
    // A contact point 0.2 m above the ground.
    world.spawn((SnowDeformer::Point { scale_per_m: 2.5 }, Transform::from_xyz(2.0, 0.2, -2.0)));
    // A wheel carrying 200 kg, placed on the ground (as a game's physics without snow would), rolling along +z.
    let wheel = SnowWheel::new(0.3, 0.2, 200.0);
    world.spawn((Rolling, wheel, FeelsSnow::default(), Transform::from_xyz(0.0, 0.3, 0.5)));
    // A deformer spawned without a transform gets one.
    let bare = world.spawn(SnowDeformer::Sphere { radius: 0.1 }).id();
    assert!(world.entity(bare).contains::<Transform>());
    world.despawn(bare);
    app.add_systems(Update, |mut frame: Local<u32>, mut w: Single<&mut Transform, With<Rolling>>| {
        w.translation.z = 0.5 + 0.05 * (*frame).min(50) as f32;
        *frame += 1;
    });
    let mut resisted = 0.0f32;
    for _ in 0..60 {
        app.update();
        resisted = resisted.max(app.world_mut().query::<&SnowResistance>().single(app.world()).expect("one").rolling_resistance_n);
    }
    let height = common::snow_heights(&app);
    let capsule = height(-2.0, -2.0);
    assert!((capsule - 0.15).abs() < 0.01, "under the capsule: {capsule} m, want its bottom at 0.15");
    assert!((height(-2.2, -2.0) - 0.15).abs() < 0.01 && (height(-2.8, -2.0) - 0.4).abs() < 1e-3, "the capsule's length");
    let point = height(2.0, -2.0);
    assert!((point - 0.2).abs() < 0.02, "under the contact point: {point} m, want 0.2");
    // The wheel sits where its load holds it: the rut's floor (the lugs) at the untouched snow minus its sinkage.
    let floor = 0.4 - wheel.sinkage_m(&SnowParams::default().mechanics(), snowpack::mechanics::SnowColumn::fresh(0.4));
    let rut = (0..8).map(|k| height(0.0, 1.5 + 0.1 * k as f32)).fold(f32::MAX, f32::min);
    println!("wheel: sinkage {:.3} m, rut floor {rut:.3} m (want {floor:.3}); rolling resistance up to {resisted:.0} N", 0.4 - floor);
    assert!(floor > 0.05 && floor < 0.35, "a 200 kg wheel in 0.4 m of 10 kPa snow: floor {floor}");
    assert!((rut - floor).abs() < 0.015, "rut floor {rut} m, want {floor} m");
    assert!(resisted > 10.0, "rolling resistance {resisted} N in fresh snow");
}

/// The plugin is built on the library's front door: nothing in `src/` names
/// `snowpack::low_level`, which only its tests turn on (a dev-dependency),
/// outside a file's own unit tests.
/// A build of the library alone would refuse such a path; this is that
/// check without a second build of the plugin (docs/ci.md, "A cold run").
#[test]
fn the_plugin_uses_the_librarys_front_door_alone() {
    let mut offenders = Vec::new();
    let mut dirs = vec![std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/src"))];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).expect("the plugin's sources") {
            let path = entry.expect("a directory entry").path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "rs" || e == "wgsl") {
                let text = std::fs::read_to_string(&path).expect("a source file");
                // A file's unit tests (its `#[cfg(test)]` module, last in the file) may compare with the library's internals.
                let library = text.lines().take_while(|l| l.trim() != "#[cfg(test)]");
                offenders.extend(library.enumerate().filter(|(_, l)| l.contains("low_level")).map(|(n, l)| format!("{}:{}: {l}", path.display(), n + 1)));
            }
        }
    }
    assert!(offenders.is_empty(), "the plugin reaches below the library's front door:\n{}", offenders.join("\n"));
}
