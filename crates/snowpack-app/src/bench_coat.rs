//! Snow on the characters (issue 35): the snow coat pass against the
//! skinning pass it follows, per character, for the fox and for larger
//! meshes (where the passes' fixed cost no longer hides their per-vertex
//! cost), in a 1024² window with snowfall, half of each mesh under the snow.

use std::fmt::Write as _;

use anyhow::Context as _;
use glam::{DVec2, Mat4, Vec3};
use snowpack::Snowfall;
use snowpack::low_level::SnowInspect;
use snowpack::{GpuContext, SkinnedMesh, SkinnedPose, SnowDeformation, SnowFrame, SnowParams, TerrainSource};

/// One measured character.
#[derive(Clone, Debug, PartialEq)]
pub struct CoatRow {
    /// What was skinned.
    pub mesh: String,
    /// Its vertices.
    pub vertices: usize,
    /// Median GPU ms of its skinning.
    pub skinning_ms: f64,
    /// Median GPU ms of its snow coat.
    pub coat_ms: f64,
}

impl CoatRow {
    /// Coat over skinning.
    #[must_use]
    pub fn ratio(&self) -> f64 {
        if self.skinning_ms > 0.0 { self.coat_ms / self.skinning_ms } else { f64::NAN }
    }
}

/// A flat grid of `side`² vertices, 2 m wide, from 0 to 0.6 m high along z
/// (half of it under 30 cm of snow), bound to one joint.
fn grid(side: u32) -> SkinnedMesh {
    let mut mesh = SkinnedMesh::default();
    for i in 0..side {
        for j in 0..side {
            let (u, v) = (j as f32 / (side - 1) as f32, i as f32 / (side - 1) as f32);
            mesh.positions.push(Vec3::new(2.0 * u - 1.0, 0.6 * v, 2.0 * v - 1.0));
            mesh.joints.push([0; 4]);
            mesh.weights.push([1.0, 0.0, 0.0, 0.0]);
        }
    }
    for i in 0..side - 1 {
        for j in 0..side - 1 {
            let k = i * side + j;
            mesh.indices.extend([k, k + 1, k + side + 1, k, k + side + 1, k + side]);
        }
    }
    mesh
}

fn measure_one(ctx: &GpuContext, name: String, mesh: &SkinnedMesh, joints: usize, scale: f32, (warmup, frames): (u32, u32)) -> anyhow::Result<CoatRow> {
    let params = SnowParams {
        extent_m: 64.0,
        resolution: 1024,
        depth_m: 0.3,
        snowfall: Some(Snowfall { rate_m_per_s: 0.002, ..Snowfall::default() }),
        ..SnowParams::default()
    };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO)?;
    let id = snow.add_skinned_mesh(ctx, mesh, joints)?;
    let identity = vec![Mat4::IDENTITY; joints];
    for frame in 0..warmup + frames {
        // Walking at 1 m/s: the coat's speeds and the capture's sweep see motion.
        let model = Mat4::from_scale_rotation_translation(Vec3::splat(scale), glam::Quat::IDENTITY, Vec3::new(frame as f32 / 60.0 - 2.0, 0.0, 0.0));
        let poses = [SkinnedPose { mesh: id, joints: &identity, model }];
        snow.step_frame(ctx, &SnowFrame::new(1.0 / 60.0, &[]).with_poses(&poses))?;
        if frame + 1 == warmup {
            snow.finish(ctx)?;
            snow.clear_timings();
        }
    }
    snow.finish(ctx)?;
    let passes = snow.timings().passes;
    let ms = |pass: &str| passes.iter().find(|p| p.0 == pass).map_or(f64::NAN, |p| p.1);
    Ok(CoatRow { mesh: name, vertices: mesh.positions.len(), skinning_ms: ms("skinning"), coat_ms: ms("snow coat") })
}

/// Measures the fox and grids of 128² and 512² vertices.
pub fn measure(ctx: &GpuContext, warmup: u32, frames: u32) -> anyhow::Result<Vec<CoatRow>> {
    let file = std::path::PathBuf::from(snowpack_scene::BUILTIN_FOX);
    let fox = snowpack_scene::gltf_file::GltfFile::from_bytes(snowpack_scene::BUILTIN_FOX_GLB, &file)
        .and_then(|g| g.skinned_model())
        .map_err(anyhow::Error::msg)
        .context("the built-in fox")?;
    let mut rows = vec![measure_one(ctx, "the fox".into(), &fox.mesh, fox.skeleton.joints.len(), 0.01, (warmup, frames)).context("the fox")?];
    for side in [128, 512] {
        let name = format!("a grid of {side}² vertices");
        rows.push(measure_one(ctx, name.clone(), &grid(side), 1, 1.0, (warmup, frames)).context(name)?);
    }
    Ok(rows)
}

/// The report's section.
#[must_use]
pub fn markdown(rows: &[CoatRow], adapter: &str, software: bool) -> String {
    let mut md = format!("\n## Snow on the characters: the snow coat against skinning ({adapter}, 1024² window, snowfall, half the mesh in 30 cm of snow)\n\n");
    if software {
        md.push_str("A software rasteriser: the ratios are the figures to read, not the milliseconds.\n\n");
    }
    md.push_str("| mesh | vertices | skinning ms | snow coat ms | coat / skinning |\n|---|---|---|---|---|\n");
    for r in rows {
        let _ = writeln!(md, "| {} | {} | {:.4} | {:.4} | {:.2} |", r.mesh, r.vertices, r.skinning_ms, r.coat_ms, r.ratio());
    }
    md
}

/// `coat.csv`.
#[must_use]
pub fn csv(rows: &[CoatRow]) -> String {
    let mut csv = String::from("mesh,vertices,skinning_ms,coat_ms,ratio\n");
    for r in rows {
        let _ = writeln!(csv, "{},{},{},{},{}", r.mesh, r.vertices, r.skinning_ms, r.coat_ms, r.ratio());
    }
    csv
}
