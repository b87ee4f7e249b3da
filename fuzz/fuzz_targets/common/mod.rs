//! What the file targets share: a scratch folder per process, loading a scene
//! as the program does (`Scene::load`), and the built world run up to the last
//! CPU-only stage before the GPU (see `build_world`).

#![allow(dead_code, reason = "each target uses the part it needs")]

use std::path::{Path, PathBuf};

use glam::DVec2;
use snowpack::Snowfall;
use snowpack::low_level::accumulate::AtlasLayout;
use snowpack::low_level::deform::capture::{CaptureInstances, CaptureParams};
use snowpack::low_level::{DeformerExt, SnowParamsExt};
use snowpack_scene::{SaveScene, Scene, SceneError, WindowSpec, World};

/// Frames the world is stepped for: enough for gaits, footsteps and physics
/// contacts to start, few enough for thousands of runs a second.
const FRAMES: u32 = 6;
/// Above this many spheres the world is built but not stepped: a scene may
/// legally ask for 100,000 spheres, whose physics costs what it costs.
const MAX_STEPPED_BODIES: usize = 300;
/// Above this the objects' atlas is laid out but not baked: a 4096² atlas is
/// a legal, large allocation, not a bug.
const MAX_BAKED_ATLAS: u32 = 1024;

/// This process's scratch folder for `target`, emptied the first time.
pub fn scratch(target: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("snowpack-fuzz-{target}-{}", std::process::id()));
    if !dir.is_dir() {
        std::fs::create_dir_all(&dir).expect("scratch folder");
    }
    dir
}

/// `body` as `dir/scene.toml`, loaded as the program loads a scene file.
pub fn load(dir: &Path, body: &str) -> Result<Scene, SceneError> {
    let path = dir.join("scene.toml");
    std::fs::write(&path, body).expect("write the scene");
    Scene::load(&path)
}

/// A refusal names the scene file, the file at fault and a key under `table`.
pub fn assert_names(err: &SceneError, file: &str, table: &str) {
    let text = err.to_string();
    assert!(text.contains("scene.toml"), "the error does not name the scene: {text}");
    assert!(text.contains(file), "the error does not name {file}: {text}");
    assert!(err.key.starts_with(table), "the error's key {:?} is not under {table}: {text}", err.key);
}

/// What the program builds from a loaded scene before it touches the GPU:
/// the saved scene parses back to the same scene (when `save` is set: it loads
/// every file again); the `World` is built and stepped; each frame's
/// deformers are finite and become the capture's window-local instances; the
/// objects are laid out (and baked) in their accumulation atlas. Stops where
/// `SnowDeformation::new` needs a device.
pub fn build_world(scene: &Scene, save: bool) {
    scene.snow.validate().expect("a loaded scene's [snow] validates");
    if save {
        round_trip(scene);
    }

    let mut world = World::new(scene);
    let (tmin, tmax) = scene.terrain.height_bounds();
    assert!(tmin.is_finite() && tmax.is_finite() && tmin <= tmax, "terrain height bounds {tmin}..{tmax}");
    let deepest = scene.snow.depth_m + scene.snowfall.as_ref().map_or(0.0, |s| s.max_m);
    let capture = CaptureParams { extent_m: scene.snow.extent_m, texel_m: scene.snow.texel_m(), low_m: tmin - 1.0, high_m: tmax + deepest + 1.0 };
    let frames = if world.body_count() > MAX_STEPPED_BODIES { 0 } else { FRAMES.min(scene.sim.frames) };
    for frame in 0..=frames {
        if frame > 0 {
            world.step(scene.sim.dt_s);
        }
        let center = window_center(scene, &world);
        let half = f64::from(scene.snow.extent_m) * 0.5;
        let deformers = world.deformers();
        for d in &deformers {
            assert!(d.lowest_point().is_finite(), "frame {frame}: a deformer is not finite: {d:?}");
        }
        let _ = CaptureInstances::new(&deformers, center - DVec2::splat(half), &capture);
        for c in world.characters() {
            assert!(c.joints.iter().all(|m| m.is_finite()), "frame {frame}: actor {}'s joint matrices are not finite", c.actor);
        }
        let _ = world.soles();
        let _ = world.take_footsteps();
    }

    let objects: Vec<_> = scene.objects.iter().map(snowpack_scene::ObjectSpec::object).collect();
    if !objects.is_empty() {
        let atlas = scene.snowfall.as_ref().map_or(Snowfall::default().atlas_resolution, |s| s.atlas_resolution);
        // What `SnowAccumulation::new` does before its buffers: an error here is the user's (exit 2).
        if let Ok(layout) = AtlasLayout::new(&objects, atlas, scene.snow.texel_m())
            && atlas <= MAX_BAKED_ATLAS
        {
            let _ = layout.bake();
            let _ = layout.meshes(true);
        }
    }
}

/// Where the window is centred, as the runner computes it.
fn window_center(scene: &Scene, world: &World) -> DVec2 {
    match &scene.window {
        WindowSpec::Center(c) => DVec2::new(f64::from(c[0]), f64::from(c[1])),
        WindowSpec::FollowActor(i) => world.actor_position(*i).map_or(DVec2::ZERO, |p| DVec2::new(f64::from(p.x), f64::from(p.z))),
        _ => DVec2::new(f64::from(scene.camera.position.x), f64::from(scene.camera.position.z)),
    }
}

/// The demo's "save": the scene written back parses to the same scene (the
/// light's sun angles excepted, which go through trigonometry).
fn round_trip(scene: &Scene) {
    let text = scene.to_toml(&scene.path);
    let back = Scene::parse(&text, &scene.path).unwrap_or_else(|e| panic!("the saved scene does not load: {e}\n{text}"));
    assert_eq!(back.snow, scene.snow, "[snow] after a save");
    assert_eq!(back.terrain, scene.terrain, "[terrain] after a save");
    assert_eq!(back.window, scene.window, "[window] after a save");
    assert_eq!(back.actors, scene.actors, "[[actor]] after a save");
    assert_eq!(back.vehicles, scene.vehicles, "[[vehicle]] after a save");
    assert_eq!(back.spawns, scene.spawns, "[[spawn]] after a save");
    assert_eq!(back.objects, scene.objects, "[[object]] after a save");
    assert_eq!(back.snowfall, scene.snowfall, "[snowfall] after a save");
    assert_eq!(back.store, scene.store, "[store] after a save");
    assert_eq!(back.sim, scene.sim, "[sim] after a save");
    assert_eq!(back.camera, scene.camera, "[camera] after a save");
}
