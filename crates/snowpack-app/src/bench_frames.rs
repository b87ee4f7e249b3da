//! Wasmut 2019, Tables 1–4 on the same terms: frames per second of a whole
//! frame (deformation and rendering at 1600x900) for each technique against
//! sphere count, with the drawn spheres' meshes at 32², 128² and 512²
//! vertices, and the points technique against its footprint range. FPS here
//! is `1000 / (deformation GPU ms + render GPU ms)`, medians after warm-up.

use std::fmt::Write as _;

use anyhow::Context as _;
use glam::{DVec2, Vec3};
use snowpack::IMAGE_FORMAT;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::TechniqueExt;
use snowpack::{Camera, Deformer, GpuContext, NoiseTerrain, RenderParams, Renderer, SnowDeformation, SnowParams, Technique, TerrainSource};

/// Frame size of Wasmut's measurements.
pub const SIZE: (u32, u32) = (1600, 900);

/// One measured configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameRow {
    /// Technique.
    pub technique: Technique,
    /// Spheres (2 m across, as Wasmut's).
    pub spheres: usize,
    /// Vertices per side of the drawn sphere mesh.
    pub mesh_side: u32,
    /// Footprint range of the points technique (texels).
    pub range_texels: u32,
    /// Median GPU ms of the deformation passes.
    pub deform_ms: f64,
    /// Median GPU ms of the render passes.
    pub render_ms: f64,
}

impl FrameRow {
    /// Frames per second the GPU time allows.
    #[must_use]
    pub fn fps(&self) -> f64 {
        let ms = self.deform_ms + self.render_ms;
        if ms > 0.0 { 1000.0 / ms } else { 0.0 }
    }
}

/// Spheres 2 m across circling over the window (Wasmut's test bed, moved on a path instead of by physics).
fn spheres(t: f32, count: usize, terrain: &TerrainSource, extent: f32) -> Vec<Deformer> {
    (0..count)
        .map(|k| {
            let a = k as f32 * 2.399_963 + t * 0.3;
            let r = extent * 0.45 * ((k as f32 + 0.5) / count as f32).sqrt();
            let (x, z) = (r * a.cos(), r * a.sin());
            Deformer::Sphere { center: Vec3::new(x, terrain.height_at(x, z) + 0.7, z), radius: 1.0 }
        })
        .collect()
}

/// Measures one configuration: a 1024² window at 4 cm a texel (Wasmut's), the camera at a corner facing the centre.
pub fn measure(ctx: &GpuContext, technique: Technique, count: usize, mesh_side: u32, range_texels: u32, warmup: u32, frames: u32) -> anyhow::Result<FrameRow> {
    let params = SnowParams { extent_m: 40.96, resolution: 1024, technique, range_texels, ..SnowParams::default() };
    let terrain = TerrainSource::Noise(NoiseTerrain { seed: 4, base_m: 0.0, amplitude_m: 0.5, wavelength_m: 30.0 });
    let mut snow = SnowDeformation::new(ctx, params, terrain.clone(), DVec2::ZERO)?;
    let env = snowpack::EnvironmentMap::from_hdr(snowpack_scene::BUILTIN_SKY_HDR)?;
    let side = mesh_side.max(3);
    let render_params = RenderParams { sphere_mesh: [side - 1, side - 1], ..RenderParams::default() };
    let mut renderer = Renderer::new(ctx, &snow, &env, render_params, IMAGE_FORMAT).context("creating the renderer")?;
    let (_target, view) = crate::bench_render::frame_target(ctx, SIZE);
    let camera = Camera { position: Vec3::new(-19.0, 9.0, -19.0), target: Vec3::ZERO, fov_deg: 60.0 };
    for frame in 0..warmup + frames {
        let actors = spheres(frame as f32 / 60.0, count, &terrain, 40.96);
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("bench frame") });
        snow.encode(ctx, &mut encoder, &snowpack::SnowFrame::new(1.0 / 60.0, &actors));
        renderer.encode(ctx, &mut encoder, &snow, &actors, &camera, &view, SIZE);
        ctx.queue.submit([encoder.finish()]);
        if frame + 1 == warmup {
            snow.finish(ctx)?;
            renderer.finish(ctx)?;
            snow.clear_timings();
            renderer.clear_timings();
        }
    }
    snow.finish(ctx)?;
    renderer.finish(ctx)?;
    let total = |t: snowpack::PassTimings| t.passes.iter().map(|p| p.1).sum::<f64>();
    Ok(FrameRow { technique, spheres: count, mesh_side: side, range_texels, deform_ms: total(snow.timings()), render_ms: total(renderer.timings()) })
}

/// Wasmut's FPS (section 5.2: GeForce GTX 960, i7-3700k, Windows 10) for
/// (table, technique or range, counts, figures).
const WASMUT: [(u32, &str, [usize; 4], [f64; 4]); 13] = [
    (1, "points", [128, 256, 512, 1024], [91.75, 91.5, 87.5, 77.25]),
    (1, "depth", [128, 256, 512, 1024], [101.5, 96.75, 93.0, 86.5]),
    (1, "decals", [128, 256, 512, 1024], [99.75, 90.875, 76.5, 60.5]),
    (2, "points", [128, 256, 512, 1024], [93.5, 91.25, 85.25, 76.25]),
    (2, "depth", [128, 256, 512, 1024], [82.75, 71.125, 56.375, 39.5]),
    (2, "decals", [128, 256, 512, 1024], [100.5, 92.5, 76.75, 62.5]),
    (3, "points", [32, 64, 128, 256], [94.5, 95.0, 91.5, 88.125]),
    (3, "depth", [32, 64, 128, 256], [55.5, 37.125, 23.5, 13.5]),
    (3, "decals", [32, 64, 128, 256], [105.5, 106.375, 99.625, 92.875]),
    (4, "32", [128, 256, 512, 1024], [94.5, 90.0, 84.0, 79.5]),
    (4, "64", [128, 256, 512, 1024], [93.5, 91.25, 85.25, 76.25]),
    (4, "96", [128, 256, 512, 1024], [85.0, 75.5, 70.625, 58.375]),
    (4, "128", [128, 256, 512, 1024], [77.6, 68.25, 59.5, 47.125]),
];

/// Which table a row belongs to: 1–3 by mesh side (32, 128, 512) at range 64, 4 for the points technique's other ranges.
fn table_of(row: &FrameRow) -> u32 {
    match (row.mesh_side, row.range_texels, row.technique) {
        (32, 64, _) => 1,
        (128, 64, _) => 2,
        (512, 64, _) => 3,
        (32, _, Technique::Points) => 4,
        _ => 0,
    }
}

/// The four tables, Wasmut's figures beside snowpack's.
#[must_use]
pub fn markdown(rows: &[FrameRow], adapter: &str, software: bool) -> String {
    let mut md = format!("\n## Wasmut 2019, Tables 1–4: frames per second at {}x{} (deformation + render GPU time)\n\n", SIZE.0, SIZE.1);
    let _ = writeln!(
        md,
        "Wasmut's figures are whole-application FPS on a GeForce GTX 960 (section 5.2); snowpack's are `1000 / GPU ms` on **{adapter}**{}. snowpack ray casts spheres exactly by compute in the capture, so the mesh size changes only their drawing, not the capture (Wasmut's render target drew the meshes into the capture).",
        if software { " (a software adapter: ratios only)" } else { "" }
    );
    let titles = [
        "",
        "Table 1: spheres drawn with 32x32 vertices",
        "Table 2: 128x128 vertices",
        "Table 3: 512x512 vertices",
        "Table 4: points technique against footprint range",
    ];
    for table in 1..=4u32 {
        let ours: Vec<&FrameRow> = rows.iter().filter(|r| table_of(r) == table).collect();
        let theirs: Vec<_> = WASMUT.iter().filter(|w| w.0 == table).collect();
        let counts = theirs[0].2;
        let _ =
            write!(md, "\n### {}\n\n| source | {} |", titles[table as usize], if table == 4 { "range, against spheres" } else { "technique, against spheres" });
        for n in counts {
            let _ = write!(md, " {n} |");
        }
        md.push_str("\n|---|---|---|---|---|---|\n");
        for (_, name, _, fps) in &theirs {
            let label = if table == 4 { format!("range {name}²") } else { (*name).to_owned() };
            let _ = writeln!(md, "| Wasmut | {label} | {} |", fps.map(|f| format!("{f:.1}")).join(" | "));
            let cells: Vec<String> = counts
                .iter()
                .map(|n| {
                    ours.iter()
                        .find(|r| r.spheres == *n && if table == 4 { r.range_texels.to_string() == *name } else { r.technique.as_str() == *name })
                        .map_or("–".to_owned(), |r| format!("{:.1}", r.fps()))
                })
                .collect();
            let _ = writeln!(md, "| snowpack | {label} | {} |", cells.join(" | "));
        }
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tables_put_our_fps_beside_wasmuts() {
        let row = |technique, spheres, mesh_side, range_texels, ms: f64| FrameRow {
            technique,
            spheres,
            mesh_side,
            range_texels,
            deform_ms: ms * 0.25,
            render_ms: ms * 0.75,
        };
        let rows = [
            row(Technique::Depth, 128, 32, 64, 5.0),
            row(Technique::Points, 1024, 128, 64, 20.0),
            row(Technique::Decals, 32, 512, 64, 10.0),
            row(Technique::Points, 512, 32, 96, 8.0),
        ];
        let md = markdown(&rows, "NVIDIA H100", false);
        assert!(md.contains("| Wasmut | depth | 101.5 | 96.8 | 93.0 | 86.5 |"), "{md}");
        assert!(md.contains("| snowpack | depth | 200.0 | – | – | – |"), "{md}");
        assert!(md.contains("| snowpack | points | – | – | – | 50.0 |"), "{md}");
        assert!(md.contains("| snowpack | decals | 100.0 | – | – | – |"), "{md}");
        assert!(md.contains("| snowpack | range 96² | – | – | 125.0 | – |"), "{md}");
        assert!(md.contains("| Wasmut | range 128² | 77.6 | 68.2 | 59.5 | 47.1 |"), "{md}");
        assert!(markdown(&rows, "llvmpipe", true).contains("ratios only"));
        assert_eq!(row(Technique::Depth, 1, 32, 64, 0.0).fps(), 0.0);
    }
}
