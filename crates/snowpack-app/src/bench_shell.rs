//! The shell's part of `snowpack bench`: Leshonkov and Frolov's Figure 5,
//! frame rate against the detail texture's size with and without its mip
//! levels, at 800x800 and 2560x1600, over grass on a trampled snow field; and
//! the pixels and GPU time of each peeling pass (their Figure 3).

use std::fmt::Write as _;
use std::time::Instant;

use anyhow::Context as _;
use glam::{DVec2, Vec3};
use snowpack::ShellSettings;
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::SnowInspect;
use snowpack::{Camera, Deformer, GpuContext, NoiseTerrain, RenderParams, Renderer, SnowDeformation, SnowParams, TerrainSource};

/// Frame sizes of Figure 5.
pub const SIZES: [(u32, u32); 2] = [(800, 800), (2560, 1600)];

/// One measured configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct ShellRow {
    /// Frame size (pixels).
    pub size: (u32, u32),
    /// Detail texture voxels per side.
    pub texture: u32,
    /// Mip levels from the footprint (their method) or level 0 only (basic shell mapping).
    pub lod: bool,
    /// Median wall time of a whole frame, the GPU waited for (ms).
    pub frame_ms: f64,
    /// GPU time of the shell's passes, construction to composite (median ms).
    pub shell_gpu_ms: f64,
    /// GPU time of each peeling pass (median ms).
    pub pass_ms: Vec<f64>,
    /// Pixels each peeling pass shaded.
    pub pass_pixels: Vec<u32>,
    /// Tetrahedra drawn per pass.
    pub tetrahedra: u32,
}

impl ShellRow {
    /// Frames per second from the median frame.
    #[must_use]
    pub fn fps(&self) -> f64 {
        1000.0 / self.frame_ms.max(1e-9)
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// Renders each texture size, with and without mips, at each frame size.
pub fn measure(ctx: &GpuContext, sizes: &[(u32, u32)], textures: &[u32], warmup: u32, frames: u32) -> anyhow::Result<Vec<ShellRow>> {
    let terrain = TerrainSource::Noise(NoiseTerrain { seed: 2, base_m: 0.0, amplitude_m: 0.3, wavelength_m: 12.0 });
    let params = SnowParams { extent_m: 16.0, resolution: 256, depth_m: 0.3, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, terrain.clone(), DVec2::ZERO)?;
    // A sphere ploughing across the field in front of the camera: grass lies flat in its trench.
    for k in 0..=60 {
        let x = -6.0 + 12.0 * k as f32 / 60.0;
        let center = Vec3::new(x, terrain.height_at(x, 1.5) + 0.2, 1.5);
        snow.step(ctx, &[Deformer::Sphere { center, radius: 0.3 }], 1.0 / 30.0)?;
    }
    snow.finish(ctx)?;
    let env = snowpack::EnvironmentMap::from_hdr(snowpack_scene::BUILTIN_SKY_HDR)?;
    // Standing over the field, looking 2 to 7 m ahead: from about 3 m on a
    // pixel covers several voxels of a 128³ texture, where their Figure 5
    // sees the basic method lose its cache and mips pay off.
    let ground = terrain.height_at(0.0, -2.0);
    let camera = Camera { position: Vec3::new(0.0, ground + 1.7, -2.0), target: Vec3::new(0.0, ground - 0.3, 3.0), fov_deg: 60.0 };
    let base = ShellSettings { enabled: true, radius_m: 6.0, ..ShellSettings::default() };
    let mut rows = Vec::new();
    for &size in sizes {
        let (_target, view) = crate::bench_render::frame_target(ctx, size);
        for &texture in textures {
            for lod in [false, true] {
                let shell = ShellSettings { texture_size: texture, lod, ..base };
                let mut renderer = Renderer::new(ctx, &snow, &env, RenderParams { shell, ..RenderParams::default() }, snowpack::IMAGE_FORMAT)
                    .context("creating the renderer")?;
                let mut walls = Vec::new();
                for frame in 0..warmup + frames {
                    let start = Instant::now();
                    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("bench shell") });
                    renderer.encode(ctx, &mut encoder, &snow, &[], &camera, &view, size);
                    ctx.queue.submit([encoder.finish()]);
                    ctx.wait_idle("a shell bench frame")?;
                    if frame >= warmup {
                        walls.push(start.elapsed().as_secs_f64() * 1e3);
                    }
                    if frame + 1 == warmup {
                        renderer.finish(ctx)?;
                        renderer.clear_timings();
                    }
                }
                renderer.finish(ctx)?;
                let timings = renderer.timings().passes;
                let shell_gpu_ms = timings.iter().filter(|(n, _, _)| n.starts_with("shell") || n == "peel count").map(|(_, ms, _)| ms).sum();
                let pass_ms = timings.iter().filter(|(n, _, _)| n.starts_with("shell pass")).map(|(_, ms, _)| *ms).collect();
                let built = renderer.shell().context("the shell was not drawn")?;
                let pass_pixels = built.pass_pixels(ctx)?;
                let tetrahedra = built.tetrahedra();
                rows.push(ShellRow { size, texture, lod, frame_ms: median(walls), shell_gpu_ms, pass_ms, pass_pixels, tetrahedra });
            }
        }
    }
    Ok(rows)
}

/// The shell section of the report.
#[must_use]
pub fn markdown(rows: &[ShellRow], software: bool) -> String {
    let mut md = String::from("\n## Shell mapping: frame rate against detail texture size (Leshonkov & Frolov 2021, Figure 5)\n\n");
    if software {
        md.push_str("A software rasteriser: compare the columns with and without mips and the texture sizes with each other, not the absolute rates.\n\n");
    }
    md.push_str("| frame | texture | FPS basic (level 0) | FPS with mips | shell GPU ms basic | shell GPU ms with mips | pixels per peeling pass (with mips) |\n|---|---|---|---|---|---|---|\n");
    let mut keys: Vec<((u32, u32), u32)> = rows.iter().map(|r| (r.size, r.texture)).collect();
    keys.dedup();
    for (size, texture) in keys {
        let find = |lod: bool| rows.iter().find(|r| r.size == size && r.texture == texture && r.lod == lod);
        let (Some(basic), Some(mips)) = (find(false), find(true)) else { continue };
        let pixels: Vec<String> = mips.pass_pixels.iter().map(u32::to_string).collect();
        let _ = writeln!(
            md,
            "| {}x{} | {texture}³/2 | {:.2} | {:.2} | {:.2} | {:.2} | {} |",
            size.0,
            size.1,
            basic.fps(),
            mips.fps(),
            basic.shell_gpu_ms,
            mips.shell_gpu_ms,
            pixels.join(", ")
        );
    }
    if let Some(row) = rows.iter().find(|r| r.lod && !r.pass_ms.is_empty()) {
        let passes: Vec<String> = row.pass_ms.iter().map(|ms| format!("{ms:.3}")).collect();
        let _ = writeln!(
            md,
            "\nGPU ms per peeling pass ({}x{}, {}³/2 with mips; {} tetrahedra a pass): {}",
            row.size.0,
            row.size.1,
            row.texture,
            row.tetrahedra,
            passes.join(", ")
        );
    }
    md
}

/// `shell.csv`.
#[must_use]
pub fn csv(rows: &[ShellRow]) -> String {
    let mut csv = String::from("width,height,texture,lod,frame_ms,fps,shell_gpu_ms,pass_ms,pass_pixels\n");
    for r in rows {
        let ms: Vec<String> = r.pass_ms.iter().map(|v| format!("{v:.4}")).collect();
        let px: Vec<String> = r.pass_pixels.iter().map(u32::to_string).collect();
        let _ = writeln!(
            csv,
            "{},{},{},{},{:.3},{:.3},{:.4},{},{}",
            r.size.0,
            r.size.1,
            r.texture,
            r.lod,
            r.frame_ms,
            r.fps(),
            r.shell_gpu_ms,
            ms.join(" "),
            px.join(" ")
        );
    }
    csv
}
