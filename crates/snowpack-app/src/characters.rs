//! What the headless runner and the demo (native and web) share between a
//! scene's world and the snow: where the window goes, the characters' skinned
//! meshes and soles, and the scene's tile store.

use anyhow::Context as _;
use glam::DVec2;
use snowpack::{GpuContext, SkinnedId, SkinnedPose, SnowDeformation};
use snowpack_scene::{CharacterPose, Scene, WindowSpec, World};

use crate::BadInput;
use snowpack::low_level::TileStreamerExt;

/// Where the scene's `[window]` puts the window's centre this frame.
pub fn window_center(scene: &Scene, world: &World) -> DVec2 {
    match &scene.window {
        WindowSpec::Center(c) => DVec2::new(f64::from(c[0]), f64::from(c[1])),
        WindowSpec::FollowCamera => DVec2::new(f64::from(scene.camera.position.x), f64::from(scene.camera.position.z)),
        WindowSpec::FollowActor(i) => world.actor_position(*i).map_or(DVec2::ZERO, |p| DVec2::new(f64::from(p.x), f64::from(p.z))),
        // A window kind this runner does not know yet: where the camera is.
        _ => DVec2::new(f64::from(scene.camera.position.x), f64::from(scene.camera.position.z)),
    }
}

/// Uploads the skinned mesh of each glTF character in `world`; the result
/// maps actor index to its mesh.
pub fn register_characters(ctx: &GpuContext, world: &World, snow: &mut SnowDeformation) -> anyhow::Result<Vec<(usize, SkinnedId)>> {
    world
        .gltf_actors()
        .map(|(k, g)| {
            let id = snow.add_skinned_mesh(ctx, &g.model.mesh, g.model.skeleton.joints.len()).with_context(|| format!("uploading {}", g.file.display()))?;
            snow.set_coat(id, g.coat).with_context(|| format!("the snow coat of {}", g.file.display()))?;
            Ok((k, id))
        })
        .collect()
}

/// How far an answered point may be from a foot to stand for it: a foot
/// moves a few centimetres in the frame or two an answer takes.
const SOLE_MATCH_M: f32 = 0.3;

/// Every character's soles (x, z): what the runner and the demo ask the snow
/// about each frame, for the next frames' placement and footstep depths.
pub fn sole_points(world: &World) -> Vec<glam::Vec2> {
    world.soles().into_iter().flat_map(|(_, soles)| soles.into_iter().map(|p| glam::Vec2::new(p.x, p.z))).collect()
}

/// The answered sample nearest to (x, z), if one is close enough.
pub fn sole_sample(answers: Option<&snowpack::PointAnswers>, x: f32, z: f32) -> Option<snowpack::PointSample> {
    answers.and_then(|a| a.nearest(glam::Vec2::new(x, z), SOLE_MATCH_M))
}

/// This frame's poses for the registered characters.
pub fn poses<'a>(skins: &[(usize, SkinnedId)], characters: &'a [CharacterPose]) -> Vec<SkinnedPose<'a>> {
    characters
        .iter()
        .filter_map(|c| skins.iter().find(|(k, _)| *k == c.actor).map(|(_, id)| SkinnedPose { mesh: *id, joints: &c.joints, model: c.model }))
        .collect()
}

/// Creates the deformation window for `scene`. A value the adapter cannot
/// take (a `resolution` or heightmap beyond its texture or buffer limits,
/// named in the message) is the user's input: [`BadInput`] naming the file
/// and key (exit 2). Other failures are the machine's (exit 1).
pub fn new_window(ctx: &GpuContext, scene: &Scene, params: snowpack::SnowParams, center: DVec2, doing: &'static str) -> anyhow::Result<SnowDeformation> {
    match SnowDeformation::new(ctx, params, scene.terrain.clone(), center).map_err(snowpack::low_level::error::SnowError::from) {
        Err(snowpack::low_level::error::SnowError::InvalidParameter { field, why }) => {
            let key = if field == "heightmap" { "[terrain].path".to_owned() } else { format!("[snow].{field}") };
            Err(BadInput(format!("{}: {key}: {why}", scene.path.display())).into())
        }
        other => other.context(doing),
    }
}

// The server-only binary needs it too, so it is the library root's.
pub use crate::machine_fault;

/// A store error at `[store].path` of `scene`: [`BadInput`] (exit 2) unless
/// it is the machine's fault ([`machine_fault`], exit 1); either way the
/// message names the file and key.
fn store_error(scene: &Scene, e: snowpack::StoreError) -> anyhow::Error {
    let key = format!("{}: [store].path", scene.path.display());
    if machine_fault(e.as_ref()) { anyhow::Error::new(e).context(key) } else { BadInput(format!("{key}: {e}")).into() }
}

/// Attaches `[store]`: a disk store (default folder: `store/` in `out`) or,
/// with `keep = "memory"`, a memory keeper of its tile size and budget;
/// `keep = "off"` attaches nothing (the scene's `[snow]` already forgets). A
/// path that names a file, a store of another tile side or format, or a
/// damaged or mismatched save is bad input (exit 2); a store the disk
/// refuses (read-only, failing, not answering) is the machine's (exit 1).
/// `Ok(true)`: a save was loaded. A `batch` run's window moves wait for the
/// disk rather than hold ([`snowpack::StreamerConfig::moves_wait_for_disk`]):
/// its outputs must not depend on the disk's speed or the machine's load.
pub fn attach_store(
    ctx: &GpuContext,
    snow: &mut SnowDeformation,
    scene: &Scene,
    spec: &snowpack_scene::StoreSpec,
    (out, batch): (&std::path::Path, bool),
) -> anyhow::Result<bool> {
    use snowpack::{StoreConfig, StoredWindow as _, StreamerConfig, TileStore, TileStreamer};
    use snowpack_scene::StoreKeep;
    const MIB: f64 = 1024.0 * 1024.0;
    let memory = StreamerConfig { memory_budget_bytes: (f64::from(spec.memory_mb) * MIB) as usize, moves_wait_for_disk: batch, ..StreamerConfig::default() };
    let streamer = match spec.keep {
        StoreKeep::Off => return Ok(false),
        StoreKeep::Memory => TileStreamer::in_memory(spec.tile_texels, memory),
        StoreKeep::Disk => {
            let dir = spec.path.clone().unwrap_or_else(|| out.join("store"));
            let config = StoreConfig { disk_budget_bytes: (f64::from(spec.disk_mb) * MIB) as u64, ..StoreConfig::default() };
            if dir.exists() && !dir.is_dir() {
                return Err(BadInput(format!("{}: [store].path: {} is a file, not a folder", scene.path.display(), dir.display())).into());
            }
            let store = TileStore::open(&dir, spec.tile_texels, config).map_err(|e| store_error(scene, e))?;
            TileStreamer::new(store, memory)
        }
    };
    let loaded = match snow.attach_store(ctx, streamer).map_err(snowpack::low_level::error::SnowError::from) {
        Err(snowpack::low_level::error::SnowError::Store(e)) => return Err(store_error(scene, e.into())),
        Err(snowpack::low_level::error::SnowError::InvalidParameter { field, why }) => {
            return Err(BadInput(format!("{}: [store].{field}: {why}", scene.path.display())).into());
        }
        other => other.context("attaching the tile store")?,
    };
    // The loading screen's wait, here rather than in the first frame's `encode`.
    snow.preload(ctx).context("loading the window's tiles")?;
    Ok(loaded)
}
