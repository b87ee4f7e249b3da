//! The renderer's part of `snowpack bench`: per-pass GPU time at 1920x1080
//! over a 64 m window (1024²) with a 1 km view, and the terrain's triangle
//! count against the camera's distance from the window.

use std::fmt::Write as _;

use anyhow::Context as _;
use glam::{DVec2, Vec3};
use snowpack::IMAGE_FORMAT;
use snowpack::low_level::SnowInspect;
use snowpack::{Camera, Deformer, GpuContext, NoiseTerrain, RenderParams, Renderer, SnowDeformation, SnowParams, TerrainSource};

/// Frame size of the render bench.
pub const SIZE: (u32, u32) = (1920, 1080);

/// Camera distances from the window centre (m) the bench measures.
pub const DISTANCES_M: [f32; 5] = [4.0, 16.0, 64.0, 256.0, 1024.0];

/// One measured camera placement.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderRow {
    /// Camera distance from the window centre (m).
    pub distance_m: f32,
    /// Terrain patches drawn.
    pub patches: u32,
    /// Terrain triangles drawn.
    pub triangles: u64,
    /// Finest and coarsest level in view.
    pub levels: (u32, u32),
    /// (pass, median ms).
    pub passes: Vec<(String, f64)>,
}

/// The camera `distance` metres from the window centre, 30° above it, looking at it.
fn camera_at(distance: f32, ground: f32) -> Camera {
    let dir = Vec3::new(0.3, 0.5, -0.81).normalize();
    let target = Vec3::new(0.0, ground, 0.0);
    Camera { position: target + dir * distance, target, fov_deg: 60.0 }
}

/// An offscreen colour target of `size` in the bench's image format, and its view.
pub fn frame_target(ctx: &GpuContext, size: (u32, u32)) -> (wgpu::Texture, wgpu::TextureView) {
    let target = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("bench frame"),
        size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: IMAGE_FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        view_formats: &[],
    });
    let view = target.create_view(&wgpu::TextureViewDescriptor::default());
    (target, view)
}

/// Renders `frames` frames (after `warmup`) at each distance and returns the medians.
pub fn measure(ctx: &GpuContext, warmup: u32, frames: u32) -> anyhow::Result<Vec<RenderRow>> {
    let terrain = TerrainSource::Noise(NoiseTerrain { seed: 2, base_m: 0.0, amplitude_m: 3.0, wavelength_m: 40.0 });
    let params = SnowParams { extent_m: 64.0, resolution: 1024, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, terrain.clone(), DVec2::ZERO)?;
    // 64 spheres ploughing short trails, so the surface has rims and the AO has work.
    let mut actors = Vec::new();
    for step in 0..8 {
        actors = (0..64)
            .map(|k| {
                let a = k as f32 * 2.399_963;
                let r = 28.0 * ((k as f32 + 0.5) / 64.0).sqrt();
                let (x, z) = (r * a.cos() + step as f32 * 0.2, r * a.sin());
                Deformer::Sphere { center: Vec3::new(x, terrain.height_at(x, z) + 0.5, z), radius: 0.6 }
            })
            .collect();
        snow.step(ctx, &actors, 1.0 / 60.0)?;
    }
    snow.finish(ctx)?;
    let env = snowpack::EnvironmentMap::from_hdr(snowpack_scene::BUILTIN_SKY_HDR)?;
    let mut renderer = Renderer::new(ctx, &snow, &env, RenderParams::default(), IMAGE_FORMAT).context("creating the renderer")?;
    let (_target, view) = frame_target(ctx, SIZE);
    let ground = terrain.height_at(0.0, 0.0);
    let mut rows = Vec::new();
    for distance in DISTANCES_M {
        let camera = camera_at(distance, ground);
        for frame in 0..warmup + frames {
            let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("bench render") });
            renderer.encode(ctx, &mut encoder, &snow, &actors, &camera, &view, SIZE);
            ctx.queue.submit([encoder.finish()]);
            if frame + 1 == warmup {
                renderer.finish(ctx)?;
                renderer.clear_timings();
            }
        }
        renderer.finish(ctx)?;
        let stats = renderer.stats();
        rows.push(RenderRow {
            distance_m: distance,
            patches: stats.patches,
            triangles: stats.terrain_triangles,
            levels: stats.levels,
            passes: renderer.timings().passes.into_iter().map(|(n, ms, _)| (n, ms)).collect(),
        });
    }
    Ok(rows)
}

/// The render section of the report.
#[must_use]
pub fn markdown(rows: &[RenderRow], frames: u32) -> String {
    let mut md = format!("\n## Rendering at {}x{}: 64 m window (1024²), 1 km view, GPU ms per pass (median of {frames} frames)\n\n", SIZE.0, SIZE.1);
    let mut names: Vec<&str> = Vec::new();
    for row in rows {
        for (n, _) in &row.passes {
            if !names.contains(&n.as_str()) {
                names.push(n);
            }
        }
    }
    md.push_str("| camera distance | patches | terrain triangles | levels |");
    for n in &names {
        let _ = write!(md, " {n} ms |");
    }
    md.push_str(" total ms |\n|---|---|---|---|");
    md.push_str(&"---|".repeat(names.len() + 1));
    md.push('\n');
    for row in rows {
        let _ = write!(md, "| {} m | {} | {} | {}–{} |", row.distance_m, row.patches, row.triangles, row.levels.0, row.levels.1);
        for n in &names {
            match row.passes.iter().find(|p| p.0 == *n) {
                Some((_, ms)) => {
                    let _ = write!(md, " {ms:.3} |");
                }
                None => md.push_str(" n/a |"),
            }
        }
        let _ = writeln!(md, " {:.3} |", row.passes.iter().map(|p| p.1).sum::<f64>());
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markdown_lists_every_distance_and_pass() {
        let rows = vec![
            RenderRow { distance_m: 4.0, patches: 10, triangles: 5120, levels: (0, 3), passes: vec![("terrain".into(), 1.5), ("shadow".into(), 0.5)] },
            RenderRow { distance_m: 64.0, patches: 7, triangles: 3584, levels: (2, 5), passes: vec![("terrain".into(), 1.0)] },
        ];
        let md = markdown(&rows, 30);
        assert!(md.contains("| camera distance | patches | terrain triangles | levels | terrain ms | shadow ms | total ms |"));
        assert!(md.contains("| 4 m | 10 | 5120 | 0–3 | 1.500 | 0.500 | 2.000 |"));
        assert!(md.contains("| 64 m | 7 | 3584 | 2–5 | 1.000 | n/a | 1.000 |"));
    }
}
