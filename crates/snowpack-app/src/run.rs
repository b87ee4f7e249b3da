//! The headless runner: a scene file in, `snow.npy`, `surface.npy`,
//! `terrain.npy`, `frame.png` and `meta.json` out (see DESIGN.md).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context as _;
use snowpack::PassTimings;
use snowpack::StoredWindow as _;
use snowpack::{AdapterRequest, Camera, GpuContext, Renderer, SnowDeformation};
use snowpack::{DebugView, IMAGE_FORMAT, MaterialPreset};
use snowpack_scene::{Scene, Technique, World};

use crate::output::OutputSet;
use snowpack_app::BadInput;
use snowpack_app::characters::{attach_store, new_window, poses, register_characters, sole_points, sole_sample, window_center};

use crate::npy;
use snowpack::low_level::AdapterRequestExt;
use snowpack::low_level::SkinnedMeshExt;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::TechniqueExt;

/// Size of `frame.png` without `--size`.
pub const DEFAULT_FRAME_SIZE: (u32, u32) = (1280, 720);

/// What the command line asked for beyond the scene file.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Frames to simulate (overrides `[sim] frames`).
    pub frames: Option<u32>,
    /// Output directory.
    pub out: PathBuf,
    /// Size of `frame.png` (width, height).
    pub size: Option<(u32, u32)>,
    /// Technique override.
    pub technique: Option<String>,
    /// Backend override (`SNOWPACK_BACKEND` syntax).
    pub backend: Option<String>,
    /// Debug view override for `frame.png` (`[render] debug_view` names).
    pub view: Option<String>,
    /// Material preset override (`[render] material` names).
    pub material: Option<String>,
    /// A `snowpack server` to share the snow with.
    pub connect: Option<std::net::SocketAddr>,
    /// Connect token for a server with a key.
    pub token: Option<PathBuf>,
}

/// The scene's render parameters with the command line's view and material applied.
fn render_params(scene: &Scene, opts: &RunOptions) -> anyhow::Result<snowpack::RenderParams> {
    let mut params = scene.render.params;
    if let Some(name) = &opts.view {
        params.debug_view = DebugView::from_name(name).ok_or_else(|| {
            let names: Vec<&str> = DebugView::ALL.iter().map(|(_, n)| *n).collect();
            BadInput(format!("--view: {name:?} is not one of {}", names.join(", ")))
        })?;
    }
    if let Some(name) = &opts.material {
        params.material = MaterialPreset::from_name(name)
            .ok_or_else(|| {
                let names: Vec<&str> = MaterialPreset::ALL.iter().map(|(_, n)| *n).collect();
                BadInput(format!("--material: {name:?} is not one of {}", names.join(", ")))
            })?
            .material();
    }
    Ok(params)
}

/// What a run produced, for the caller to print or test.
pub struct RunReport {
    /// Files written.
    pub files: Vec<PathBuf>,
    /// Median GPU time per pass.
    pub timings: PassTimings,
    /// Adapter name and backend.
    pub adapter: (String, String),
    /// Frames simulated.
    pub frames: u32,
    /// Wall time of the simulation loop (s).
    pub wall_s: f64,
}

/// Runs `scene` headless and writes its outputs.
pub fn run_scene(scene: &Scene, opts: &RunOptions) -> anyhow::Result<RunReport> {
    let technique = match &opts.technique {
        Some(name) => name.parse::<Technique>().map_err(|e| BadInput(format!("--technique: {e}")))?,
        None => scene.snow.technique,
    };
    let render_params = render_params(scene, opts)?;
    let frames = opts.frames.unwrap_or(scene.sim.frames);
    let size = opts.size.unwrap_or(DEFAULT_FRAME_SIZE);

    let ctx = GpuContext::new_headless(&AdapterRequest::from_env().with_backends(opts.backend.as_deref())).context("choosing a GPU adapter")?;
    let mut world = World::new(scene);
    let params = snowpack::SnowParams { technique, ..scene.snow.clone() };
    let mut snow = new_window(&ctx, scene, params, window_center(scene, &world), "creating the deformation window")?;
    snow.set_count_mass(true); // meta.json's mass ledger counts snowfall and refill too
    let skins = register_characters(&ctx, &world, &mut snow)?;
    let objects: Vec<_> = scene.objects.iter().map(snowpack_scene::ObjectSpec::object).collect();
    match snow.set_objects(&ctx, &objects).map_err(snowpack::low_level::error::SnowError::from) {
        Err(snowpack::low_level::error::SnowError::InvalidParameter { field, why }) => {
            return Err(BadInput(format!("{}: [[object]] / [snowfall].{field}: {why}", scene.path.display())).into());
        }
        other => other.context("placing the [[object]]s")?,
    }
    let resumed = match &scene.store {
        Some(spec) => attach_store(&ctx, &mut snow, scene, spec, (&opts.out, true))?,
        None => false,
    };
    let mut link = match opts.connect {
        Some(addr) => Some(crate::net::join(&ctx, &mut snow, addr, opts.token.as_deref(), &scene.path.display().to_string())?),
        None => None,
    };
    let start = Instant::now();
    let footsteps = simulate(&ctx, scene, &mut world, &mut snow, &skins, frames, link.as_mut())?;
    snow.finish(&ctx)?;
    // Everything this run changed acknowledged by the server, everything it
    // has for this window merged here, before anything is written.
    let share = match &mut link {
        Some(link) => Some(crate::net::settle(&ctx, &mut snow, link)?),
        None => None,
    };
    let wall_s = start.elapsed().as_secs_f64();
    if scene.store.as_ref().is_some_and(|spec| spec.keep == snowpack_scene::StoreKeep::Disk && spec.save) {
        snow.save(&ctx).context("saving the snow into [store]")?;
    }
    for e in snow.take_store_errors() {
        tracing::warn!("tile store: {e}");
    }

    let accumulation = snow.accumulation().map(|acc| acc.read_atlas(&ctx).map(|atlas| (acc.stats(&atlas), atlas))).transpose()?;
    let (png, render_meta) = render_frame(&ctx, scene, &snow, &world, render_params, size)?;
    let timings = snow.timings();
    let origin = snow.origin_m().unwrap_or_default();
    let mass = mass_meta(&ctx, &snow)?;
    let meta = serde_json::json!({
        "origin_m": [origin.x, origin.y],
        "texel_m": scene.snow.texel_m(),
        "resolution": scene.snow.resolution,
        "extent_m": scene.snow.extent_m,
        "technique": technique.as_str(),
        "frames": frames,
        "dt_s": scene.sim.dt_s,
        "scene": scene.path.display().to_string(),
        "adapter": {"name": ctx.summary.name, "backend": ctx.summary.backend, "software": ctx.summary.is_software()},
        "timings_ms": timings.passes.iter().map(|(k, v, _)| (k.clone(), serde_json::json!(v))).collect::<serde_json::Map<_, _>>(),
        "objects": object_meta(&snow, accumulation.as_ref().map(|(stats, _)| stats.as_slice())),
        "fallen_m": snow.fallen_m(),
        "mass": mass,
        "store": store_meta(&snow, resumed),
        "render": render_meta,
        // The deformation's GPU memory (the renderer's is under "render"), in all and by resource.
        "gpu_memory_bytes": snow.memory_bytes().iter().map(|(_, v)| v).sum::<u64>(),
        "gpu_memory_peak_bytes": snow.peak_memory_bytes(),
        "share": share.map_or(serde_json::Value::Null, |s| s.to_json()),
        "points_dropped": snow.points_dropped(),
        "gpu_memory_by_resource": snow.memory_bytes().iter().map(|(k, v)| (k.to_string(), serde_json::json!(v))).collect::<serde_json::Map<_, _>>(),
    });

    let outputs = Outputs { snow: &snow, world: &world, skins: &skins, accumulation: accumulation.as_ref().map(|(_, atlas)| atlas.as_slice()) };
    let files = stage_outputs(&ctx, scene, opts, &outputs, &png, &meta, &footsteps)?;
    Ok(RunReport { files, timings, adapter: (ctx.summary.name.clone(), ctx.summary.backend.clone()), frames, wall_s })
}

/// Simulates `frames` frames: actors move, objects turn, the snow is pressed,
/// characters stand in the answers of the frame before, and the snow is
/// shared over `link`. Returns the footsteps, with the depth stepped into.
fn simulate(
    ctx: &GpuContext,
    scene: &Scene,
    world: &mut World,
    snow: &mut SnowDeformation,
    skins: &[(usize, snowpack::SkinnedId)],
    frames: u32,
    mut link: Option<&mut crate::net::SnowLink>,
) -> anyhow::Result<Vec<snowpack::low_level::skin::feet::FootstepEvent>> {
    let warmup = frames.min(10) as u64;
    let mut footsteps = Vec::new();
    // The characters' soles, asked with the next frame.
    let mut asked: Option<Vec<glam::Vec2>> = None;
    for frame in 0..frames {
        snow.set_center(window_center(scene, world));
        let t = frame as f32 * scene.sim.dt_s;
        for (k, o) in scene.objects.iter().enumerate() {
            let (position, rotation) = o.pose_at(t);
            snow.set_object_pose(k, position, rotation);
        }
        let characters = world.characters();
        let (deformers, ids, poses) = (world.deformers(), world.deformer_ids(), poses(skins, &characters));
        let frame_in = snowpack::SnowFrame::new(scene.sim.dt_s, &deformers).with_ids(&ids).with_poses(&poses);
        let frame_in = asked.as_deref().map_or(frame_in, |points| frame_in.with_queries(points));
        snow.step_frame(ctx, &frame_in).with_context(|| format!("GPU frame {frame}"))?;
        if u64::from(frame) + 1 == warmup {
            snow.clear_timings();
        }
        // Characters on the snow stand in it as the latest answers show it (older trails).
        let answers = snow.point_answers();
        world.step_on(scene.sim.dt_s, &|x, z| sole_sample(answers, x, z));
        for mut step in world.take_footsteps() {
            // Answered a frame or two late: the snow the foot stepped into.
            step.snow_depth_m = sole_sample(answers, step.position.x, step.position.z).map(|s| s.depth_m());
            footsteps.push(step);
        }
        asked = Some(sole_points(world));
        if let Some(link) = link.as_deref_mut() {
            link.peer.set_deformers(&crate::net::deformer_positions(world));
            link.pump(snow)?;
        }
    }
    Ok(footsteps)
}

/// `frame.png` from the scene's camera, and `meta.json`'s `render`.
fn render_frame(
    ctx: &GpuContext,
    scene: &Scene,
    snow: &SnowDeformation,
    world: &World,
    render_params: snowpack::RenderParams,
    (width, height): (u32, u32),
) -> anyhow::Result<(Vec<u8>, serde_json::Value)> {
    let env = scene.render.environment_map();
    let mut renderer = Renderer::new(ctx, snow, &env, render_params, IMAGE_FORMAT).context("creating the renderer")?;
    let camera = Camera { position: scene.camera.position, target: scene.camera.target, fov_deg: scene.camera.fov_deg };
    let rgba = renderer.render_image(ctx, snow, &world.deformers(), &camera, (width, height)).context("rendering frame.png")?;
    renderer.finish(ctx)?;
    let image = image::RgbaImage::from_raw(width, height, rgba).context("frame size")?;
    let mut png = Vec::new();
    image::DynamicImage::ImageRgba8(image).to_rgb8().write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).context("encoding frame.png")?;
    let stats = renderer.stats();
    let render_timings = renderer.timings();
    let shell = match renderer.shell() {
        Some(shell) => serde_json::json!({
            "tetrahedra": shell.tetrahedra(),
            "pass_pixels": shell.pass_pixels(ctx).context("reading the shell's pass counts")?,
            "gpu_memory_bytes": shell.memory_bytes(),
        }),
        None => serde_json::Value::Null,
    };

    let meta = serde_json::json!({
        "size": [width, height],
        "patches": stats.patches,
        "terrain_triangles": stats.terrain_triangles,
        "shadow_patches": stats.shadow_patches,
        "actors": stats.actors,
        "timings_ms": render_timings.passes.iter().map(|(k, v, _)| (k.clone(), serde_json::json!(v))).collect::<serde_json::Map<_, _>>(),
        "gpu_memory_bytes": renderer.memory_bytes(),
        "shell": shell,
    });
    Ok((png, meta))
}

/// What [`stage_outputs`] reads the arrays from.
struct Outputs<'a> {
    snow: &'a SnowDeformation,
    world: &'a World,
    skins: &'a [(usize, snowpack::SkinnedId)],
    /// The accumulation atlas, when the scene has objects.
    accumulation: Option<&'a [f32]>,
}

/// Writes the run's files (DESIGN.md) into `opts.out` all at once.
fn stage_outputs(
    ctx: &GpuContext,
    scene: &Scene,
    opts: &RunOptions,
    o: &Outputs<'_>,
    png: &[u8],
    meta: &serde_json::Value,
    footsteps: &[snowpack::low_level::skin::feet::FootstepEvent],
) -> anyhow::Result<Vec<PathBuf>> {
    let (snow, world, skins) = (o.snow, o.world, o.skins);
    let res = scene.snow.resolution as usize;
    let snow_h = snow.read_snow(ctx)?;
    let terrain_h = snow.read_terrain(ctx)?;
    let (surface_h, _normals) = snow.read_surface(ctx)?;
    let mut out = OutputSet::new(&opts.out)?;
    out.stage("snow.npy", &npy::encode_f32(&snow_h, &[res, res]))?;
    out.stage("surface.npy", &npy::encode_f32(&surface_h, &[res, res]))?;
    out.stage("terrain.npy", &npy::encode_f32(&terrain_h, &[res, res]))?;
    // Snow with mass (docs/mechanics.md): the packed snow per texel (m), which
    // with snow.npy and terrain.npy gives each column's density and hardness.
    out.stage("packed.npy", &npy::encode_f32(&snow.read_packed(ctx)?, &[res, res]))?;
    if let (Some(acc), Some(atlas)) = (snow.accumulation(), o.accumulation) {
        let n = acc.layout().resolution as usize;
        out.stage("accumulation.npy", &npy::encode_f32(atlas, &[n, n]))?;
    }
    // The snow on each glTF character's vertices (DESIGN.md: `actor_snow_K.npy`).
    for (k, ((_, actor), (_, id))) in world.gltf_actors().zip(skins).enumerate() {
        let coat = snow.read_coat(ctx, *id).context("reading the characters' snow")?;
        let mesh = &actor.model.mesh;
        let rows: Vec<f32> = mesh.positions.iter().zip(mesh.vertex_normals()).zip(&coat).flat_map(|((p, n), c)| [p.x, p.y, p.z, n.y, *c]).collect();
        out.stage(&format!("actor_snow_{k}.npy"), &npy::encode_f32(&rows, &[mesh.positions.len(), 5]))?;
    }
    out.stage("frame.png", png)?;
    out.stage("meta.json", serde_json::to_string_pretty(meta)?.as_bytes())?;
    if !footsteps.is_empty() {
        let steps: Vec<serde_json::Value> = footsteps
            .iter()
            .map(|e| {
                serde_json::json!({
                    "actor": e.actor, "foot": e.foot, "name": e.name,
                    "position": [e.position.x, e.position.y, e.position.z],
                    "speed_m_per_s": e.speed_m_per_s, "time_s": e.time_s, "snow_depth_m": e.snow_depth_m, "sink_m": e.sink_m,
                })
            })
            .collect();
        out.stage("footsteps.json", serde_json::to_string_pretty(&steps)?.as_bytes())?;
    }
    let files = out.commit()?;
    Ok(files)
}

/// `meta.json`'s `store`: tile traffic and the keeper's figures (null when
/// trails are forgotten); `keep` is `"memory"` or `"disk"`.
/// Snow with mass (docs/mechanics.md): what the window holds at the end,
/// what presses displaced beyond the final density, and the rest of the
/// mass ledger (what entered and left with the window's moves, what
/// snowfall and refill added, and their sum), for `meta.json`.
fn mass_meta(ctx: &GpuContext, snow: &SnowDeformation) -> anyhow::Result<serde_json::Value> {
    let mass = snow.read_mass(ctx).context("reading the snow's mass")?;
    Ok(serde_json::json!({
        "window_kg": mass.total_kg,
        "displaced_kg": mass.displaced_kg,
        "entered_kg": mass.entered_kg,
        "left_kg": mass.left_kg,
        "snowfall_kg": mass.snowfall_kg,
        "refill_kg": mass.refill_kg,
        "ledger_kg": mass.ledger_kg(),
    }))
}

fn store_meta(snow: &SnowDeformation, resumed: bool) -> serde_json::Value {
    let Some(t) = snow.tile_stats() else { return serde_json::Value::Null };
    serde_json::json!({
        "keep": if t.memory_only { "memory" } else { "disk" },
        "resumed": resumed,
        "time_s": snow.clock().time_s,
        "resident_tiles": t.resident,
        "restored_tiles": t.restored,
        "fresh_tiles": t.fresh,
        "evicted_tiles": t.evicted,
        "window_waits": t.window_waits,
        "stood_in_tiles": t.stood_in,
        "merged_live_tiles": t.merged_live,
        "blocking_loads": t.blocking_loads,
        "memory_tiles": t.store.memory_tiles,
        "memory_bytes": t.store.memory_bytes,
        "disk_tiles": t.store.disk_tiles,
        "disk_bytes": t.store.disk_bytes,
        "bytes_written": t.store.bytes_written,
        "hit_rate": t.store.hit_rate(),
        "errors": t.store.errors,
        "corrupt": t.store.corrupt,
        "lost": t.store.lost,
    })
}

/// `meta.json`'s `objects`: per object name, the snow on its upward surfaces
/// and where its charts lie in `accumulation.npy`.
fn object_meta(snow: &SnowDeformation, stats: Option<&[snowpack::ObjectStats]>) -> serde_json::Value {
    let (Some(acc), Some(stats)) = (snow.accumulation(), stats) else { return serde_json::json!({}) };
    acc.objects()
        .iter()
        .zip(stats)
        .enumerate()
        .map(|(k, (o, s))| {
            let charts: Vec<[u32; 4]> = acc.layout().charts.iter().filter(|c| c.object == k as u32).map(|c| c.rect).collect();
            (
                o.name.clone(),
                serde_json::json!({
                    "mean_m": s.mean_m, "max_m": s.max_m, "covered_fraction": s.covered_fraction,
                    "atlas_charts": charts,
                }),
            )
        })
        .collect::<serde_json::Map<_, _>>()
        .into()
}

/// Prints what a run wrote and how long each pass took.
pub fn print_report(report: &RunReport, out: &Path) {
    println!("ran {} frames in {:.2} s on {} ({})", report.frames, report.wall_s, report.adapter.0, report.adapter.1);
    println!("wrote into {}:", out.display());
    for f in &report.files {
        println!("  {}", f.display());
    }
    if report.timings.passes.is_empty() {
        println!("GPU timings: not available on this adapter (no timestamp queries)");
    } else {
        println!("GPU time per pass (median over frames after warm-up):");
        for (name, ms, n) in &report.timings.passes {
            println!("  {name:<10} {ms:>9.4} ms  ({n} samples)");
        }
        println!("  {:<10} {:>9.4} ms", "total", report.timings.total_ms());
    }
}
