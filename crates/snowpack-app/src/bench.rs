//! `snowpack bench`: per-pass GPU medians of the deformation pipeline at
//! several window sizes, written as a Markdown report and CSV.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::Context as _;
use glam::{DVec2, Vec3};
use snowpack::low_level::gpu::timing::median;
use snowpack::{AdapterRequest, Deformer, GpuContext, NoiseTerrain, SnowDeformation, SnowParams, Technique, TerrainSource};

use crate::output::OutputSet;
use snowpack::low_level::AdapterRequestExt;
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::TechniqueExt;

/// One measured configuration.
pub struct BenchRow {
    /// Window resolution (texels per side).
    pub resolution: u32,
    /// Spheres pressing the snow.
    pub spheres: usize,
    /// (pass, median ms).
    pub passes: Vec<(String, f64)>,
    /// Median CPU time to record and submit one frame (ms).
    pub cpu_record_ms: f64,
    /// GPU memory held by the window (bytes).
    pub memory_bytes: u64,
    /// That memory by resource (name, bytes).
    pub memory_parts: Vec<(String, u64)>,
}

fn spheres_at(t: f32, count: usize, extent: f32) -> Vec<Deformer> {
    (0..count)
        .map(|k| {
            let a = k as f32 * 2.399_963 + t * 0.3;
            let r = extent * 0.4 * ((k as f32 + 0.5) / count as f32).sqrt();
            Deformer::Sphere { center: Vec3::new(r * a.cos(), 0.45, r * a.sin()), radius: 0.5 }
        })
        .collect()
}

/// What one measurement runs.
#[derive(Clone, Copy, Debug)]
pub struct Config {
    /// Window resolution (texels per side).
    pub resolution: u32,
    /// Spheres pressing the snow.
    pub spheres: usize,
    /// Deformation technique.
    pub technique: Technique,
    /// Footprint side of the points technique (texels).
    pub range_texels: u32,
}

/// Measures one configuration.
pub fn measure(ctx: &GpuContext, config: Config, warmup: u32, frames: u32) -> anyhow::Result<BenchRow> {
    let Config { resolution, spheres, technique, range_texels } = config;
    let params = SnowParams { extent_m: 64.0 * resolution as f32 / 1024.0, resolution, technique, range_texels, ..SnowParams::default() };
    let terrain = TerrainSource::Noise(NoiseTerrain { seed: 1, base_m: 0.0, amplitude_m: 0.3, wavelength_m: 30.0 });
    let extent = params.extent_m;
    let mut snow = SnowDeformation::new(ctx, params, terrain, DVec2::ZERO)?;
    let mut cpu_ms = Vec::new();
    for frame in 0..warmup + frames {
        let t = frame as f32 / 60.0;
        let deformers = spheres_at(t, spheres, extent);
        // Slide the window slowly so exposure is part of the measured frame.
        snow.set_center(DVec2::new(f64::from(t), 0.0));
        let start = Instant::now();
        snow.step(ctx, &deformers, 1.0 / 60.0)?;
        if frame >= warmup {
            cpu_ms.push(start.elapsed().as_secs_f64() * 1e3);
        }
        if frame + 1 == warmup {
            ctx.wait_idle("bench warm-up")?;
            snow.finish(ctx)?;
            snow.clear_timings();
        }
    }
    snow.finish(ctx)?;
    Ok(BenchRow {
        resolution,
        spheres,
        passes: snow.timings().passes.into_iter().map(|(n, ms, _)| (n, ms)).collect(),
        cpu_record_ms: median(&cpu_ms).unwrap_or(0.0),
        memory_bytes: snow.memory_bytes().iter().map(|m| m.1).sum(),
        memory_parts: snow.memory_bytes().into_iter().map(|(n, b)| (n.to_owned(), b)).collect(),
    })
}

/// The report as Markdown (also what `docs/PERFORMANCE.md` holds).
#[must_use]
pub fn markdown(rows: &[BenchRow], adapter: &str, backend: &str, software: bool, frames: u32) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "## Deformation passes, GPU time per frame (median of {frames} frames after warm-up)\n");
    let _ = writeln!(md, "Adapter: **{adapter}** ({backend}).");
    if software {
        let _ = writeln!(md, "This is a software rasteriser: use these figures for ratios only (pass vs pass, size vs size), not as absolute cost.");
    }
    let mut names: Vec<String> = Vec::new();
    for row in rows {
        for (n, _) in &row.passes {
            if !names.contains(n) {
                names.push(n.clone());
            }
        }
    }
    let _ = write!(md, "\n| window | spheres |");
    for n in &names {
        let _ = write!(md, " {n} ms |");
    }
    let _ = writeln!(md, " total ms | CPU record ms | GPU memory MiB |");
    let _ = write!(md, "|---|---|");
    for _ in &names {
        let _ = write!(md, "---|");
    }
    let _ = writeln!(md, "---|---|---|");
    for row in rows {
        let _ = write!(md, "| {0}² | {1} |", row.resolution, row.spheres);
        for n in &names {
            match row.passes.iter().find(|p| &p.0 == n) {
                Some((_, ms)) => {
                    let _ = write!(md, " {ms:.4} |");
                }
                None => {
                    let _ = write!(md, " n/a |");
                }
            }
        }
        let total: f64 = row.passes.iter().map(|p| p.1).sum();
        let _ = writeln!(md, " {total:.4} | {:.3} | {:.1} |", row.cpu_record_ms, row.memory_bytes as f64 / (1024.0 * 1024.0));
    }
    md
}

/// The physical floor of each pass beside its measured time, per window size:
/// the bytes it must move (`snowpack::low_level::deform::traffic`) over the adapter's
/// memory bandwidth when the adapter is a known GPU.
#[must_use]
pub fn floor_markdown(rows: &[BenchRow], adapter: &str) -> String {
    use snowpack::low_level::deform::traffic::{frame_traffic, known_bandwidth_gb_per_s};
    let bandwidth = known_bandwidth_gb_per_s(adapter);
    let mut md = String::from("\n## The physical floor: bytes each pass must move, against the time it took\n\n");
    match bandwidth {
        Some(gb) => {
            let _ = writeln!(
                md,
                "{adapter}: {gb} GB/s of memory bandwidth (maker's data sheet). Floor = bytes / bandwidth; measured / floor says how far a pass is from streaming at full bandwidth.\n"
            );
        }
        None => {
            let _ = writeln!(md, "{adapter}: memory bandwidth unknown, so bytes only (floors need a known GPU; see `KNOWN_BANDWIDTH_GB_PER_S`).\n");
        }
    }
    let _ = writeln!(md, "| window | pass | MiB moved | floor ms | measured ms | measured / floor |\n|---|---|---|---|---|---|");
    for row in rows {
        let params =
            SnowParams { resolution: row.resolution, extent_m: 64.0 * row.resolution as f32 / 1024.0, technique: Technique::Depth, ..SnowParams::default() };
        for t in frame_traffic(&params) {
            let measured = row.passes.iter().find(|p| p.0 == t.pass).map(|p| p.1);
            let floor = bandwidth.map(|gb| t.floor_ms(gb));
            let cell = |v: Option<f64>, digits: usize| v.map_or("n/a".to_owned(), |v| format!("{v:.digits$}"));
            let ratio = match (measured, floor) {
                (Some(m), Some(f)) if f > 0.0 => format!("{:.1}", m / f),
                _ => "n/a".to_owned(),
            };
            let _ = writeln!(
                md,
                "| {}² | {} | {:.2} | {} | {} | {ratio} |",
                row.resolution,
                t.pass,
                t.total_bytes() as f64 / (1024.0 * 1024.0),
                cell(floor, 4),
                cell(measured, 4)
            );
        }
    }
    md
}

/// Hanák 2021, Table 6.1 (deformation, blur, normals at 1024², his GPUs) with
/// this adapter's figures from the 1024² row beside it, and the capture's
/// cost per object against his 0.01 ms. snowpack fuses rims and blur into
/// one display pass and stores no normals (they are computed where used), so
/// its row gives the update, the display and no normals pass.
#[must_use]
pub fn hanak_markdown(row: &BenchRow, adapter: &str, software: bool) -> String {
    let ms = |names: &[&str]| -> f64 { row.passes.iter().filter(|p| names.contains(&p.0.as_str())).map(|p| p.1).sum() };
    let mut md = format!("\n## Hanák 2021, Table 6.1, beside this adapter ({}² window, {} spheres)\n\n", row.resolution, row.spheres);
    md.push_str("| GPU | deformation ms | Gaussian blur ms | normals ms | capture ms per object |\n|---|---|---|---|---|\n");
    for (gpu, d, b, n) in [
        ("GTX 1060 (Hanák)", 0.07, 0.13, 0.14),
        ("GTX 1070 (Hanák)", 0.05, 0.08, 0.10),
        ("RTX 2070 (Hanák)", 0.04, 0.06, 0.04),
        ("RTX 2070S (Hanák)", 0.03, 0.05, 0.03),
    ] {
        let _ = writeln!(md, "| {gpu} | {d:.2} | {b:.2} | {n:.2} | 0.01 |");
    }
    let per_object = if row.spheres > 0 { ms(&["capture"]) / row.spheres as f64 } else { 0.0 };
    let _ = writeln!(
        md,
        "| {adapter} (snowpack){} | {:.4} | {:.4} | {:.4} | {per_object:.5} |",
        if software { ", software: ratios only" } else { "" },
        ms(&["update"]),
        ms(&["display"]),
        0.0
    );
    md.push_str("\nsnowpack's deformation is its update pass; its blur column is the display pass, the rims and both blur directions fused in workgroup memory; it has no normals pass (normals are central differences of the displayed heights wherever they are used); its capture ray casts spheres exactly by compute, each 16×16-texel tile against the spheres over it, so its cost per object is the capture pass over the sphere count.\n");
    md
}

/// GPU memory per window size by resource, beside the sources' figures.
#[must_use]
pub fn memory_markdown(rows: &[BenchRow]) -> String {
    let mut md = String::from("\n## GPU memory of the deformation window\n\n| resource |");
    for row in rows {
        let _ = write!(md, " {}² MiB |", row.resolution);
    }
    md.push_str(" bytes per texel |\n|---|");
    for _ in rows {
        md.push_str("---|");
    }
    md.push_str("---|\n");
    let mut names: Vec<&str> = Vec::new();
    for row in rows {
        for (n, _) in &row.memory_parts {
            if !names.contains(&n.as_str()) {
                names.push(n);
            }
        }
    }
    let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
    for name in names.iter().copied().chain(std::iter::once("total")) {
        let _ = write!(md, "| {name} |");
        let mut per_texel = None;
        for row in rows {
            let bytes = if name == "total" { Some(row.memory_bytes) } else { row.memory_parts.iter().find(|p| p.0 == name).map(|p| p.1) };
            match bytes {
                Some(b) => {
                    per_texel = Some(b as f64 / f64::from(row.resolution).powi(2));
                    let _ = write!(md, " {:.1} |", mib(b));
                }
                None => md.push_str(" n/a |"),
            }
        }
        let _ = writeln!(md, " {} |", per_texel.map_or("n/a".to_owned(), |b| format!("{b:.1}")));
    }
    md.push_str(
        "\nThe sources, for 64 m at 1024² (6.25 cm texels): Hanák 2021 (section 6.1), 9 MB, plus 2 MB for a 16-bit depth of \
         level geometry; Rise of the Tomb Raider as Wasmut 2019 quotes it, 2 to 4 MB depending on the float precision; Surface \
         Trails, 24 MB (the figure the benchmark issue quotes; not in the source texts). snowpack keeps the persistent snow in \
         one u32 word a texel holding both the persistent snow (a 16-bit deficit below rest) and the displayed height (an f16 above \
         the terrain; rims and blur are fused in one pass, normals computed where used), a 16-bit capture (the analytic shapes' codes, written by compute; a depth target for meshes only once a mesh presses), the terrain evaluated from its source, the point stamps only for points and combined and the decal layer only \
         for decals (switching allocates them once), a few kilobytes for point queries, and the resident tiles that keep \
         trails when the window moves on.\n",
    );
    md
}

/// Techniques against actor count and points against range, as Markdown.
#[must_use]
pub fn technique_markdown(counts: &[usize], rows: &[(String, Vec<f64>)], cpu_rows: &[(String, Vec<f64>)], ranges: &[(u32, f64, f64)]) -> String {
    let mut md = String::from("\n## Techniques: total GPU ms per frame at 1024² against sphere count\n\n| technique |");
    for n in counts {
        let _ = write!(md, " {n} |");
    }
    md.push_str("\n|---|");
    md.push_str(&"---|".repeat(counts.len()));
    md.push('\n');
    let table = |md: &mut String, rows: &[(String, Vec<f64>)]| {
        for (name, cells) in rows {
            let _ = write!(md, "| {name} |");
            for c in cells {
                let _ = write!(md, " {c:.3} |");
            }
            md.push('\n');
        }
    };
    table(&mut md, rows);
    md.push_str("\n## CPU ms to record and submit a frame at 1024² against sphere count\n\n| technique |");
    for n in counts {
        let _ = write!(md, " {n} |");
    }
    md.push_str("\n|---|");
    md.push_str(&"---|".repeat(counts.len()));
    md.push('\n');
    table(&mut md, cpu_rows);
    md.push_str("\n## Points: GPU ms at 1024² with 1024 spheres against footprint range\n\n| range | stamp ms | total ms |\n|---|---|---|\n");
    for (range, stamp, total) in ranges {
        let _ = writeln!(md, "| {range}² | {stamp:.4} | {total:.4} |");
    }
    md
}

/// Everything one benchmark run measured: what the report is made from.
pub struct BenchResults {
    /// Adapter name.
    pub adapter: String,
    /// Backend (vulkan, gl, ...).
    pub backend: String,
    /// Whether the adapter is a software rasteriser (figures are ratios only).
    pub software: bool,
    /// Frames per median of the pass table.
    pub frames: u32,
    /// The passes at each window size.
    pub rows: Vec<BenchRow>,
    /// Sphere counts of the technique tables.
    pub counts: Vec<usize>,
    /// Total GPU ms per technique and count.
    pub technique_rows: Vec<(String, Vec<f64>)>,
    /// CPU ms to record a frame per technique and count.
    pub cpu_rows: Vec<(String, Vec<f64>)>,
    /// Points technique: (range, stamp ms, total ms).
    pub ranges: Vec<(u32, f64, f64)>,
    /// The renderer against camera distance.
    pub render_rows: Vec<crate::bench_render::RenderRow>,
    /// Frames per median of the render table.
    pub render_frames: u32,
    /// Whole frames at 1600x900 (Wasmut's tables).
    pub frame_rows: Vec<crate::bench_frames::FrameRow>,
    /// Dinh's accumulation table.
    pub accum_rows: Vec<crate::bench_accumulation::AccumRow>,
    /// Window moves with and without the tile store.
    pub move_rows: Vec<crate::bench_tiles::MoveRow>,
    /// The tile store's bytes per km and restore latency.
    pub store_row: Option<crate::bench_tiles::StoreRow>,
    /// Shell mapping against texture size, with and without mips.
    pub shell_rows: Vec<crate::bench_shell::ShellRow>,
    /// Swept capture against unswept.
    pub sweep_rows: Vec<crate::bench_sweep::SweepRow>,
    /// The capture's shapes by compute against drawn.
    pub capture_rows: Vec<crate::bench_capture::CaptureRow>,
    /// The display pass's kernels side by side.
    pub display_rows: Vec<crate::bench_display::DisplayRow>,
    /// The snow coat against skinning.
    pub coat_rows: Vec<crate::bench_coat::CoatRow>,
    /// Shared snow: one relay under simulated peers (no GPU).
    pub share_rows: Vec<crate::bench_share::ShareRow>,
    /// A car past a watcher, its presses as tiles and as frames.
    pub car_rows: Vec<crate::bench_share::CarRow>,
}

impl BenchResults {
    /// Nothing measured yet, on `ctx`'s adapter, `frames` a size.
    fn empty(ctx: &GpuContext, frames: u32) -> Self {
        Self {
            adapter: ctx.summary.name.clone(),
            backend: ctx.summary.backend.to_string(),
            software: ctx.summary.is_software(),
            frames,
            rows: Vec::new(),
            counts: Vec::new(),
            technique_rows: Vec::new(),
            cpu_rows: Vec::new(),
            ranges: Vec::new(),
            render_rows: Vec::new(),
            render_frames: 0,
            frame_rows: Vec::new(),
            accum_rows: Vec::new(),
            move_rows: Vec::new(),
            store_row: None,
            shell_rows: Vec::new(),
            sweep_rows: Vec::new(),
            capture_rows: Vec::new(),
            display_rows: Vec::new(),
            coat_rows: Vec::new(),
            share_rows: Vec::new(),
            car_rows: Vec::new(),
        }
    }
}

/// Measures everything `--quick` and `--only` ask for.
pub fn measure_all(ctx: &GpuContext, quick: bool, only: Option<&str>) -> anyhow::Result<BenchResults> {
    let (warmup, frames) = if quick { (10, 30) } else { (60, 300) };
    let sizes: &[u32] = if quick { &[1024, 2048] } else { &[512, 1024, 2048, 4096] };
    let spheres = 256;
    let mut results = BenchResults::empty(ctx, frames);
    for &res in sizes {
        let name = format!("passes-{res}");
        if only.is_some_and(|o| !name.contains(o)) {
            continue;
        }
        let config = Config { resolution: res, spheres, technique: Technique::Depth, range_texels: 64 };
        let row = measure(ctx, config, warmup, frames).with_context(|| format!("measuring {res}²"))?;
        let line: Vec<String> = row.passes.iter().map(|(n, ms)| format!("{n} {ms:.3}")).collect();
        println!("  {res:>5}²  {}  | CPU record {:.3} ms", line.join("  "), row.cpu_record_ms);
        results.rows.push(row);
    }
    if only.is_none_or(|o| "techniques".contains(o)) {
        measure_techniques(ctx, quick, warmup, frames, &mut results)?;
    }
    if only.is_none_or(|o| "render".contains(o)) {
        measure_render(ctx, quick, &mut results)?;
    }
    if only.is_none_or(|o| "accumulation".contains(o)) {
        measure_accumulation(ctx, quick, &mut results)?;
    }
    if only.is_none_or(|o| "tiles".contains(o)) {
        measure_tiles(ctx, quick, &mut results)?;
    }
    if only.is_none_or(|o| "share".contains(o)) {
        measure_share(quick, &mut results)?;
    }
    if only.is_none_or(|o| "sweep".contains(o)) {
        measure_sweep(ctx, quick, &mut results)?;
    }
    if only.is_none_or(|o| "capture".contains(o)) {
        measure_capture(ctx, quick, &mut results)?;
    }
    if only.is_none_or(|o| "display".contains(o)) {
        measure_display(ctx, quick, &mut results)?;
    }
    if only.is_none_or(|o| "coat".contains(o)) {
        measure_coat(ctx, quick, &mut results)?;
    }
    if only.is_none_or(|o| "shell".contains(o)) {
        measure_shell(ctx, quick, &mut results)?;
    }
    if only.is_none_or(|o| "frames".contains(o)) {
        measure_frames(ctx, quick, &mut results)?;
    }
    Ok(results)
}

/// Techniques against actor count (Wasmut Tables 1-2) and points against
/// range (Table 4), at 1024².
fn measure_techniques(ctx: &GpuContext, quick: bool, warmup: u32, frames: u32, results: &mut BenchResults) -> anyhow::Result<()> {
    results.counts = if quick { vec![128, 1024, 4096] } else { vec![128, 256, 512, 1024, 4096, 16384] };
    for technique in Technique::ALL {
        let (mut cells, mut cpu) = (Vec::new(), Vec::new());
        for &n in &results.counts {
            let config = Config { resolution: 1024, spheres: n, technique, range_texels: 64 };
            let row = measure(ctx, config, warmup, frames / 2).with_context(|| format!("{} with {n} spheres", technique.as_str()))?;
            cells.push(row.passes.iter().map(|p| p.1).sum::<f64>());
            cpu.push(row.cpu_record_ms);
        }
        println!("  {:<9} {}", technique.as_str(), cells.iter().map(|c| format!("{c:.3}")).collect::<Vec<_>>().join("  "));
        results.technique_rows.push((technique.as_str().to_owned(), cells));
        results.cpu_rows.push((technique.as_str().to_owned(), cpu));
    }
    for range in [32, 64, 96, 128] {
        let config = Config { resolution: 1024, spheres: 1024, technique: Technique::Points, range_texels: range };
        let row = measure(ctx, config, warmup, frames / 2).with_context(|| format!("points at range {range}"))?;
        let stamp = row.passes.iter().find(|p| p.0 == "stamp").map_or(0.0, |p| p.1);
        results.ranges.push((range, stamp, row.passes.iter().map(|p| p.1).sum::<f64>()));
    }
    Ok(())
}

/// The renderer at 1920x1080 against camera distance (issue: rendering performance).
fn measure_render(ctx: &GpuContext, quick: bool, results: &mut BenchResults) -> anyhow::Result<()> {
    let (render_warmup, render_frames) = if quick { (3, 10) } else { (20, 100) };
    results.render_rows = crate::bench_render::measure(ctx, render_warmup, render_frames).context("measuring the renderer")?;
    results.render_frames = render_frames;
    for row in &results.render_rows {
        let line: Vec<String> = row.passes.iter().map(|(n, ms)| format!("{n} {ms:.3}")).collect();
        println!("  render at {:>6} m: {:>7} triangles  {}", row.distance_m, row.triangles, line.join("  "));
    }
    Ok(())
}

/// Accumulation against map size (Dinh 2021, section 6.2).
fn measure_accumulation(ctx: &GpuContext, quick: bool, results: &mut BenchResults) -> anyhow::Result<()> {
    let (acc_warmup, acc_frames) = if quick { (5, 15) } else { (60, 300) };
    for scenario in crate::bench_accumulation::SCENARIOS {
        for atlas in [512, 1024, 2048] {
            let row = crate::bench_accumulation::measure(ctx, scenario, atlas, acc_warmup, acc_frames)
                .with_context(|| format!("accumulation: {scenario} at {atlas}²"))?;
            println!(
                "  accumulation {scenario:<13} {atlas:>4}²: accumulation {:.3} ms, support {:.3} ms, frame {:.3} ms",
                row.accumulation_ms, row.support_ms, row.frame_ms
            );
            results.accum_rows.push(row);
        }
    }
    Ok(())
}

/// Open worlds: window moves with and without the tile store, store size and latency.
fn measure_tiles(ctx: &GpuContext, quick: bool, results: &mut BenchResults) -> anyhow::Result<()> {
    let scratch = std::env::temp_dir().join(format!("snowpack-bench-tiles-{}", std::process::id()));
    let (tile_warmup, tile_frames) = if quick { (10, 40) } else { (60, 300) };
    let sizes: &[u32] = if quick { &[512, 1024] } else { &[512, 1024, 2048] };
    for &resolution in sizes {
        for store in [false, true] {
            let row = crate::bench_tiles::measure_move(ctx, resolution, store, tile_warmup, tile_frames, &scratch)
                .with_context(|| format!("window moves at {resolution}², store {store}"))?;
            println!(
                "  window move {resolution:>4}² store {:<3}: move {:.3} ms, frame {:.3} ms GPU, record {:.3} ms CPU, wall {:.2} ms",
                if store { "yes" } else { "no" },
                row.move_gpu_ms,
                row.frame_gpu_ms,
                row.record_cpu_ms,
                row.wall_ms
            );
            results.move_rows.push(row);
        }
    }
    let row = crate::bench_tiles::measure_store(ctx, if quick { 100.0 } else { 500.0 }, &scratch).context("tile store size and latency")?;
    println!(
        "  tile store: {:.0} KB/km with a trail, {:.0} KB/km untouched, restore {:.2} ms a tile",
        row.bytes_per_km_with_trail / 1e3,
        row.bytes_per_km_untouched / 1e3,
        row.restore_ms
    );
    results.store_row = Some(row);
    let _ = std::fs::remove_dir_all(&scratch);
    Ok(())
}

/// Shared snow: one relay process and simulated peers on loopback (CPU only).
fn measure_share(quick: bool, results: &mut BenchResults) -> anyhow::Result<()> {
    let (peers, seconds) = if quick { (16, 10.0) } else { (64, 60.0) };
    let row = crate::bench_share::measure_load(peers, seconds).context("shared snow under load")?;
    println!(
        "  shared snow: {} peers for {:.0} s: server {:.3} CPU s per world s, {:.1} MiB peak, {:.3} ms CPU per tile, {:.0} B/s out; late join {:.0} KB in {:.2} s",
        row.peers,
        row.world_s,
        row.cpu_per_world_s(),
        row.server_peak_kib as f64 / 1024.0,
        row.cpu_ms_per_tile(),
        row.bytes_out as f64 / row.world_s,
        row.late_join_bytes as f64 / 1e3,
        row.late_join_s
    );
    results.share_rows.push(row);
    for presses in [false, true] {
        let car = crate::bench_share::measure_car(presses).context("a car past a watcher")?;
        println!(
            "  a car past a watcher, presses as {}: car up {} B ({:.0} B/s), watcher down {} B ({:.0} B/s), server {:.2} CPU s",
            if presses { "frames" } else { "tiles" },
            car.car_up_bytes,
            car.car_up_bytes as f64 / car.world_s,
            car.watcher_down_bytes,
            car.watcher_down_bytes as f64 / car.world_s,
            car.server_cpu_s
        );
        results.car_rows.push(car);
    }
    Ok(())
}

/// The capture's shapes by compute against drawn (issue 44).
fn measure_capture(ctx: &GpuContext, quick: bool, results: &mut BenchResults) -> anyhow::Result<()> {
    let (warmup, frames) = if quick { (5, 20) } else { (30, 120) };
    results.capture_rows = crate::bench_capture::measure(ctx, warmup, frames).context("measuring the capture both ways")?;
    for r in &results.capture_rows {
        println!(
            "  capture {:<52} by compute {:.3} ms, drawn {:.3} ms; frame {:.3} against {:.3} ms",
            r.scenario, r.compute_ms, r.raster_ms, r.compute_frame_ms, r.raster_frame_ms
        );
    }
    Ok(())
}

/// The display pass's kernels side by side (issue 44, item 1).
fn measure_display(ctx: &GpuContext, quick: bool, results: &mut BenchResults) -> anyhow::Result<()> {
    let (sizes, warmup, frames): (&[u32], u32, u32) = if quick { (&[1024], 5, 20) } else { (&[1024, 4096], 30, 120) };
    results.display_rows = crate::bench_display::measure(ctx, sizes, warmup, frames).context("measuring the display's kernels")?;
    for r in &results.display_rows {
        println!(
            "  display {:>5}² {:<20} {:<8?} {:.4} ms GPU, frame {:.2} ms wall{}",
            r.resolution,
            r.terrain,
            r.kernel,
            r.display_ms,
            r.frame_wall_ms,
            if r.same_words { "" } else { ", DIFFERENT WORDS" }
        );
    }
    Ok(())
}

/// Swept capture against unswept (issue 21).
fn measure_sweep(ctx: &GpuContext, quick: bool, results: &mut BenchResults) -> anyhow::Result<()> {
    let (sweep_warmup, sweep_frames) = if quick { (5, 20) } else { (30, 120) };
    results.sweep_rows = crate::bench_sweep::measure(ctx, sweep_warmup, sweep_frames).context("measuring swept capture")?;
    for row in &results.sweep_rows {
        println!(
            "  sweep {:<48} {}: unswept {:.3} ms, swept {:.3} ms ({:.2}x); frame {:.3} against {:.3} ms ({:.2}x)",
            row.scenario,
            row.pass,
            row.unswept_ms,
            row.swept_ms,
            row.ratio(),
            row.unswept_frame_ms,
            row.swept_frame_ms,
            row.frame_ratio()
        );
    }
    Ok(())
}

/// Snow on the characters (issue 35): the coat against the skinning it follows.
fn measure_coat(ctx: &GpuContext, quick: bool, results: &mut BenchResults) -> anyhow::Result<()> {
    let (coat_warmup, coat_frames) = if quick { (5, 20) } else { (30, 120) };
    results.coat_rows = crate::bench_coat::measure(ctx, coat_warmup, coat_frames).context("measuring the snow coat")?;
    for row in &results.coat_rows {
        println!(
            "  coat {:<26} {:>7} vertices: skinning {:.4} ms, snow coat {:.4} ms ({:.2}x)",
            row.mesh,
            row.vertices,
            row.skinning_ms,
            row.coat_ms,
            row.ratio()
        );
    }
    Ok(())
}

/// Shell mapping: Leshonkov and Frolov's Figure 5. Quick: two texture
/// sizes and few frames (a software adapter takes seconds a frame at 2560x1600).
fn measure_shell(ctx: &GpuContext, quick: bool, results: &mut BenchResults) -> anyhow::Result<()> {
    let (shell_warmup, shell_frames) = if quick { (1, 3) } else { (10, 60) };
    let textures: &[u32] = if quick { &[32, 128] } else { &[16, 32, 64, 128, 256] };
    results.shell_rows = crate::bench_shell::measure(ctx, &crate::bench_shell::SIZES, textures, shell_warmup, shell_frames).context("measuring the shell")?;
    for row in &results.shell_rows {
        println!(
            "  shell {}x{} texture {:>3} {:<9}: {:.2} FPS, shell {:.2} ms GPU, pixels per pass {:?}",
            row.size.0,
            row.size.1,
            row.texture,
            if row.lod { "with mips" } else { "level 0" },
            row.fps(),
            row.shell_gpu_ms,
            row.pass_pixels
        );
    }
    Ok(())
}

/// Whole frames at 1600x900 against Wasmut's Tables 1-4. Quick: Table 1 at
/// two counts only (a software adapter takes seconds a frame).
fn measure_frames(ctx: &GpuContext, quick: bool, results: &mut BenchResults) -> anyhow::Result<()> {
    let (frame_warmup, frame_frames) = if quick { (2, 3) } else { (30, 100) };
    let mut configs: Vec<(Technique, usize, u32, u32)> = Vec::new();
    let techniques = [Technique::Points, Technique::Depth, Technique::Decals];
    let counts: &[usize] = if quick { &[128, 1024] } else { &[128, 256, 512, 1024] };
    for t in techniques {
        configs.extend(counts.iter().map(|&n| (t, n, 32, 64)));
        if !quick {
            configs.extend(counts.iter().map(|&n| (t, n, 128, 64)));
            configs.extend([32, 64, 128, 256].iter().map(|&n| (t, n, 512, 64)));
        }
    }
    if !quick {
        for range in [32, 96, 128] {
            configs.extend(counts.iter().map(|&n| (Technique::Points, n, 32, range)));
        }
    }
    for (technique, n, side, range) in configs {
        let row = crate::bench_frames::measure(ctx, technique, n, side, range, frame_warmup, frame_frames)
            .with_context(|| format!("a frame of {} with {n} spheres of {side}² vertices", technique.as_str()))?;
        println!("  frame {:<8} {n:>5} spheres {side:>3}² range {range:>3}: {:.1} FPS", technique.as_str(), row.fps());
        results.frame_rows.push(row);
    }
    Ok(())
}

/// The report's files from `r`: `report.md`, and for what was measured
/// `passes.csv` with `passes.png` (GPU ms per pass against window size),
/// `techniques.csv` with `techniques.png` and `cpu_record.png` (GPU and CPU
/// ms against sphere count), `render.csv` with `render.png` (ms per pass
/// against camera distance).
#[must_use]
pub fn report_files(r: &BenchResults) -> Vec<(&'static str, Vec<u8>)> {
    use crate::plot::{Chart, Series, render_png};
    let by_pass = |rows: Vec<(f64, &[(String, f64)])>| -> Vec<Series> {
        let mut names: Vec<&str> = Vec::new();
        for (_, passes) in &rows {
            for (n, _) in passes.iter() {
                if !names.contains(&n.as_str()) {
                    names.push(n);
                }
            }
        }
        names
            .into_iter()
            .map(|n| Series { name: n.to_owned(), points: rows.iter().filter_map(|(x, p)| p.iter().find(|q| q.0 == n).map(|q| (*x, q.1))).collect() })
            .collect()
    };
    let per_count = |rows: &[(String, Vec<f64>)]| -> Vec<Series> {
        rows.iter().map(|(name, cells)| Series { name: name.clone(), points: r.counts.iter().zip(cells).map(|(n, v)| (*n as f64, *v)).collect() }).collect()
    };
    let tag = if r.software { " (software: ratios only)" } else { "" };
    let chart = |title: String, x_label: &str, y_label: &str, series: Vec<Series>| {
        render_png(&Chart { title, x_label: x_label.into(), y_label: y_label.into(), log_x: true, series }, 960, 540)
    };
    let mut files: Vec<(&'static str, Vec<u8>)> = vec![("report.md", report_markdown(r).into_bytes())];
    if !r.rows.is_empty() {
        let mut csv = String::from("resolution,spheres,pass,median_ms\n");
        for row in &r.rows {
            for (n, ms) in &row.passes {
                let _ = writeln!(csv, "{},{},{n},{ms}", row.resolution, row.spheres);
            }
            let _ = writeln!(csv, "{},{},cpu_record,{}", row.resolution, row.spheres, row.cpu_record_ms);
        }
        files.push(("passes.csv", csv.into_bytes()));
        let series = by_pass(r.rows.iter().map(|row| (f64::from(row.resolution), row.passes.as_slice())).collect());
        files.push(("passes.png", chart(format!("GPU ms per pass against window side, {}{tag}", r.adapter), "texels per side", "ms", series)));
    }
    if !r.technique_rows.is_empty() {
        let mut csv = String::from("technique,spheres,gpu_ms,cpu_record_ms\n");
        for ((name, gpu), (_, cpu)) in r.technique_rows.iter().zip(&r.cpu_rows) {
            for ((n, g), c) in r.counts.iter().zip(gpu).zip(cpu) {
                let _ = writeln!(csv, "{name},{n},{g},{c}");
            }
        }
        for (range, stamp, total) in &r.ranges {
            let _ = writeln!(csv, "points-range-{range},1024,{total},");
            let _ = writeln!(csv, "points-range-{range}-stamp,1024,{stamp},");
        }
        files.push(("techniques.csv", csv.into_bytes()));
        files.push(("techniques.png", chart(format!("GPU ms per frame at 1024² against spheres{tag}"), "spheres", "ms", per_count(&r.technique_rows))));
        files.push(("cpu_record.png", chart(format!("CPU ms to record a frame against spheres{tag}"), "spheres", "ms", per_count(&r.cpu_rows))));
    }
    if !r.render_rows.is_empty() {
        let mut csv = String::from("camera_distance_m,patches,terrain_triangles,pass,median_ms\n");
        for row in &r.render_rows {
            for (n, ms) in &row.passes {
                let _ = writeln!(csv, "{},{},{},{n},{ms}", row.distance_m, row.patches, row.triangles);
            }
        }
        files.push(("render.csv", csv.into_bytes()));
        let series = by_pass(r.render_rows.iter().map(|row| (f64::from(row.distance_m), row.passes.as_slice())).collect());
        files.push(("render.png", chart(format!("Render ms per pass at 1920x1080 against camera distance{tag}"), "camera distance (m)", "ms", series)));
    }
    report_tables(r, &mut files);
    files
}

/// `report.md`: every table measured, each with the adapter under its heading.
fn report_markdown(r: &BenchResults) -> String {
    let mut md = if r.rows.is_empty() {
        let mut md = format!("Adapter: **{}** ({}).\n", r.adapter, r.backend);
        if r.software {
            md.push_str("This is a software rasteriser: use these figures for ratios only, not as absolute cost.\n");
        }
        md
    } else {
        let mut md = markdown(&r.rows, &r.adapter, &r.backend, r.software, r.frames);
        md.push_str(&floor_markdown(&r.rows, &r.adapter));
        md.push_str(&memory_markdown(&r.rows));
        if let Some(row) = r.rows.iter().find(|row| row.resolution == 1024) {
            md.push_str(&hanak_markdown(row, &r.adapter, r.software));
        }
        md
    };
    if !r.technique_rows.is_empty() {
        md.push_str(&technique_markdown(&r.counts, &r.technique_rows, &r.cpu_rows, &r.ranges));
    }
    if !r.render_rows.is_empty() {
        md.push_str(&crate::bench_render::markdown(&r.render_rows, r.render_frames));
    }
    if !r.frame_rows.is_empty() {
        md.push_str(&crate::bench_frames::markdown(&r.frame_rows, &r.adapter, r.software));
    }
    if !r.accum_rows.is_empty() {
        md.push_str(&crate::bench_accumulation::markdown(&r.accum_rows, &r.adapter, r.software));
    }
    if !r.move_rows.is_empty() || r.store_row.is_some() {
        md.push_str(&crate::bench_tiles::markdown(&r.move_rows, r.store_row.as_ref(), &r.adapter, r.software));
    }
    if !r.shell_rows.is_empty() {
        md.push_str(&crate::bench_shell::markdown(&r.shell_rows, r.software));
    }
    if !r.sweep_rows.is_empty() {
        md.push_str(&crate::bench_sweep::markdown(&r.sweep_rows, &r.adapter, r.software));
    }
    if !r.capture_rows.is_empty() {
        md.push_str(&crate::bench_capture::markdown(&r.capture_rows, &r.adapter, r.software));
    }
    if !r.display_rows.is_empty() {
        md.push_str(&crate::bench_display::markdown(&r.display_rows, &r.adapter, r.software));
    }
    if !r.coat_rows.is_empty() {
        md.push_str(&crate::bench_coat::markdown(&r.coat_rows, &r.adapter, r.software));
    }
    if !r.share_rows.is_empty() {
        md.push_str(&crate::bench_share::markdown(&r.share_rows));
    }
    if !r.car_rows.is_empty() {
        md.push_str(&crate::bench_share::car_markdown(&r.car_rows));
    }
    // The adapter and backend under every table's heading, so a table copied
    // alone still says where its figures come from.
    let stamp = format!("_Measured on {} ({}){}._", r.adapter, r.backend, if r.software { ", a software rasteriser: ratios only" } else { "" });
    let md: String = md
        .lines()
        .flat_map(|line| {
            let heading = line.starts_with("## ") || line.starts_with("### ");
            std::iter::once(line.to_owned()).chain(heading.then(|| format!("\n{stamp}")))
        })
        .collect::<Vec<_>>()
        .join("\n");
    format!("# snowpack bench\n\n{stamp}\n\n{md}\n")
}

/// The CSV files of the frame, accumulation, tile, shell, sweep and coat measurements, for those measured.
fn report_tables(r: &BenchResults, files: &mut Vec<(&'static str, Vec<u8>)>) {
    if !r.frame_rows.is_empty() {
        let mut csv = String::from("technique,spheres,mesh_vertices_per_side,range_texels,deform_ms,render_ms,fps\n");
        for f in &r.frame_rows {
            let _ = writeln!(csv, "{},{},{},{},{},{},{}", f.technique.as_str(), f.spheres, f.mesh_side, f.range_texels, f.deform_ms, f.render_ms, f.fps());
        }
        files.push(("frames.csv", csv.into_bytes()));
    }
    if !r.accum_rows.is_empty() {
        let mut csv = String::from("scenario,atlas,objects,occlusion_triangles,atlas_used,accumulation_ms,support_ms,frame_ms,wall_ms,memory_bytes\n");
        for a in &r.accum_rows {
            let _ = writeln!(
                csv,
                "{},{},{},{},{},{},{},{},{},{}",
                a.scenario, a.atlas, a.objects, a.occlusion_triangles, a.atlas_used, a.accumulation_ms, a.support_ms, a.frame_ms, a.wall_ms, a.memory_bytes
            );
        }
        files.push(("accumulation.csv", csv.into_bytes()));
    }
    if !r.move_rows.is_empty() {
        let mut csv = String::from("resolution,store,move_gpu_ms,frame_gpu_ms,record_cpu_ms,wall_ms,resident_bytes\n");
        for m in &r.move_rows {
            let _ = writeln!(csv, "{},{},{},{},{},{},{}", m.resolution, m.store, m.move_gpu_ms, m.frame_gpu_ms, m.record_cpu_ms, m.wall_ms, m.resident_bytes);
        }
        files.push(("tiles.csv", csv.into_bytes()));
    }
    if !r.shell_rows.is_empty() {
        files.push(("shell.csv", crate::bench_shell::csv(&r.shell_rows).into_bytes()));
    }
    if !r.sweep_rows.is_empty() {
        files.push(("sweep.csv", crate::bench_sweep::csv(&r.sweep_rows).into_bytes()));
    }
    if !r.capture_rows.is_empty() {
        files.push(("capture.csv", crate::bench_capture::csv(&r.capture_rows).into_bytes()));
    }
    if !r.display_rows.is_empty() {
        files.push(("display.csv", crate::bench_display::csv(&r.display_rows).into_bytes()));
    }
    if !r.coat_rows.is_empty() {
        files.push(("coat.csv", crate::bench_coat::csv(&r.coat_rows).into_bytes()));
    }
}

/// The parts `--only` picks from: a value selects every part whose name contains it.
const PARTS: [&str; 15] = [
    "passes-512",
    "passes-1024",
    "passes-2048",
    "passes-4096",
    "techniques",
    "render",
    "accumulation",
    "tiles",
    "sweep",
    "capture",
    "display",
    "coat",
    "shell",
    "frames",
    "share",
];

/// `--only`'s value, checked before any GPU work: it must select a part.
fn check_only(only: Option<&str>) -> Result<(), crate::BadInput> {
    match only {
        Some(o) if !PARTS.iter().any(|p| p.contains(o)) => {
            Err(crate::BadInput(format!("--only {o:?} selects no part of the benchmark; the parts are {}", PARTS.join(", "))))
        }
        _ => Ok(()),
    }
}

/// Runs the benchmark and writes its report into `out` (all or nothing).
pub fn run(quick: bool, out: &Path, only: Option<&str>, backend: Option<&str>) -> anyhow::Result<()> {
    check_only(only)?;
    let ctx = GpuContext::new_headless(&AdapterRequest::from_env().with_backends(backend)).context("choosing a GPU adapter")?;
    println!("snowpack bench on {} ({}){}", ctx.summary.name, ctx.summary.backend, if quick { ", quick" } else { "" });
    if !ctx.has_timestamps() {
        println!("this adapter has no timestamp queries: per-pass GPU times are unavailable");
    }
    let results = measure_all(&ctx, quick, only)?;
    let mut files = OutputSet::new(out)?;
    for (name, bytes) in report_files(&results) {
        files.stage(name, &bytes)?;
    }
    for f in files.commit()? {
        println!("wrote {}", f.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_must_select_a_part() {
        for ok in [None, Some("passes"), Some("passes-1024"), Some("sweep"), Some("tech"), Some("frames")] {
            assert!(check_only(ok).is_ok(), "{ok:?}");
        }
        let err = check_only(Some("everything")).expect_err("selects nothing").to_string();
        assert!(err.contains("--only") && err.contains("techniques"), "{err}");
    }

    #[test]
    fn markdown_has_a_column_per_pass_and_flags_software() {
        let rows = vec![BenchRow {
            resolution: 1024,
            spheres: 8,
            passes: vec![("update".into(), 0.5), ("normals".into(), 0.25)],
            cpu_record_ms: 0.1,
            memory_bytes: 1 << 20,
            memory_parts: vec![("snow".into(), 1 << 19), ("terrain".into(), 1 << 19)],
        }];
        let md = markdown(&rows, "llvmpipe", "vulkan", true, 30);
        assert!(md.contains("| update ms | normals ms |"));
        assert!(md.contains("| 1024² | 8 | 0.5000 | 0.2500 | 0.7500 | 0.100 | 1.0 |"));
        assert!(md.contains("ratios only"));
    }

    #[test]
    fn the_floor_table_divides_bytes_by_a_known_bandwidth() {
        let rows = vec![BenchRow {
            resolution: 1024,
            spheres: 8,
            passes: vec![("display".into(), 0.02), ("update".into(), 0.05)],
            cpu_record_ms: 0.1,
            memory_bytes: 1 << 20,
            memory_parts: vec![("snow".into(), 1 << 19), ("terrain".into(), 1 << 19)],
        }];
        // display at 1024²: the snow word read and written (4 B + 4 B per texel) = 8 MiB; at 3350 GB/s, 0.0025 ms.
        let md = floor_markdown(&rows, "NVIDIA H100 80GB HBM3");
        assert!(md.contains("3350 GB/s"), "{md}");
        assert!(md.contains("| 1024² | display | 8.00 | 0.0025 | 0.0200 | 8.0 |"), "{md}");
        // Update (depth): the snow word (4 B) and the 16-bit capture (2 B) read, the word (4 B) written per texel.
        assert!(md.contains("| 1024² | update | 10.00 |"), "{md}");
        // Unknown adapters get bytes and measured times, no floor.
        let md = floor_markdown(&rows, "llvmpipe (LLVM 15.0.6, 256 bits)");
        assert!(md.contains("bandwidth unknown"), "{md}");
        assert!(md.contains("| 1024² | display | 8.00 | n/a | 0.0200 | n/a |"), "{md}");
    }

    #[test]
    fn the_technique_tables_give_gpu_and_cpu_time_against_sphere_count() {
        let gpu = vec![("depth".to_owned(), vec![1.0, 2.0])];
        let cpu = vec![("depth".to_owned(), vec![0.25, 0.5])];
        let md = technique_markdown(&[128, 16384], &gpu, &cpu, &[(64, 0.1, 1.5)]);
        assert!(md.contains("| technique | 128 | 16384 |"), "{md}");
        assert!(md.contains("| depth | 1.000 | 2.000 |"), "{md}");
        assert!(md.contains("CPU ms to record") && md.contains("| depth | 0.250 | 0.500 |"), "{md}");
        assert!(md.contains("| 64² | 0.1000 | 1.5000 |"), "{md}");
    }

    #[test]
    fn hanaks_table_is_reproduced_beside_ours() {
        let row = BenchRow {
            resolution: 1024,
            spheres: 100,
            passes: vec![("capture".into(), 0.5), ("update".into(), 0.04), ("display".into(), 0.05)],
            cpu_record_ms: 0.1,
            memory_bytes: 0,
            memory_parts: vec![],
        };
        let md = hanak_markdown(&row, "NVIDIA H100", false);
        assert!(md.contains("| GTX 1060 (Hanák) | 0.07 | 0.13 | 0.14 | 0.01 |"), "{md}");
        assert!(md.contains("| RTX 2070S (Hanák) | 0.03 | 0.05 | 0.03 | 0.01 |"), "{md}");
        assert!(md.contains("| NVIDIA H100 (snowpack) | 0.0400 | 0.0500 | 0.0000 | 0.00500 |"), "{md}");
        assert!(hanak_markdown(&row, "llvmpipe", true).contains("software: ratios only"));
    }

    /// Results as a full run on an H100 would give them, every part measured.
    fn synthetic_results() -> BenchResults {
        let row = |resolution: u32| BenchRow {
            resolution,
            spheres: 256,
            passes: vec![("capture".into(), 0.2), ("update".into(), 0.03), ("display".into(), 0.04)],
            cpu_record_ms: 0.1,
            memory_bytes: 8 << 20,
            memory_parts: vec![("snow".into(), 4 << 20), ("terrain".into(), 4 << 20)],
        };
        let mut results = BenchResults {
            adapter: "NVIDIA H100 80GB HBM3".into(),
            backend: "vulkan".into(),
            software: false,
            frames: 300,
            rows: vec![row(1024), row(2048)],
            counts: vec![128, 16384],
            technique_rows: vec![("depth".into(), vec![0.3, 0.9]), ("points".into(), vec![0.2, 1.1])],
            cpu_rows: vec![("depth".into(), vec![0.05, 0.4]), ("points".into(), vec![0.06, 0.5])],
            ranges: vec![(32, 0.01, 0.2), (128, 0.05, 0.3)],
            render_rows: vec![crate::bench_render::RenderRow {
                distance_m: 4.0,
                patches: 100,
                triangles: 10_000,
                levels: (0, 3),
                passes: vec![("terrain".into(), 0.5)],
            }],
            render_frames: 100,
            frame_rows: vec![crate::bench_frames::FrameRow {
                technique: Technique::Depth,
                spheres: 128,
                mesh_side: 32,
                range_texels: 64,
                deform_ms: 1.0,
                render_ms: 4.0,
            }],
            accum_rows: vec![],
            move_rows: vec![],
            store_row: None,
            shell_rows: vec![],
            sweep_rows: vec![],
            capture_rows: vec![],
            display_rows: vec![],
            coat_rows: vec![],
            share_rows: vec![],
            car_rows: vec![],
        };
        add_synthetic_world_rows(&mut results);
        results
    }

    /// The accumulation, tile, shell, sweep and coat rows of [`synthetic_results`].
    fn add_synthetic_world_rows(results: &mut BenchResults) {
        results.accum_rows = vec![crate::bench_accumulation::AccumRow {
            scenario: "both".into(),
            atlas: 2048,
            objects: 208,
            occlusion_triangles: 60_000,
            atlas_used: 0.9,
            accumulation_ms: 0.5,
            support_ms: 0.25,
            frame_ms: 2.0,
            wall_ms: 2.5,
            memory_bytes: 100 << 20,
        }];
        results.move_rows = vec![crate::bench_tiles::MoveRow {
            resolution: 1024,
            store: true,
            move_gpu_ms: 0.1,
            frame_gpu_ms: 1.0,
            record_cpu_ms: 0.2,
            wall_ms: 1.5,
            resident_bytes: 21 << 20,
        }];
        results.store_row = Some(crate::bench_tiles::StoreRow {
            trail_m: 500.0,
            swath_m: 16.0,
            bytes_per_km_with_trail: 2e6,
            bytes_per_km_untouched: 1e6,
            mean_tile_bytes: 5000.0,
            restore_ms: 0.5,
            teleport_wait_frames: 3,
            teleport_ms: 50.0,
            teleport_longest_frame_ms: 20.0,
            teleport_gpu_waits: 0,
        });
        results.shell_rows = [false, true]
            .map(|lod| crate::bench_shell::ShellRow {
                size: (800, 800),
                texture: 64,
                lod,
                frame_ms: 20.0,
                shell_gpu_ms: 5.0,
                pass_ms: vec![2.0, 1.0],
                pass_pixels: vec![1000, 300],
                tetrahedra: 1000,
            })
            .to_vec();
        results.sweep_rows = vec![crate::bench_sweep::SweepRow {
            scenario: "balls",
            pass: "capture",
            unswept_ms: 0.5,
            swept_ms: 0.6,
            unswept_frame_ms: 10.0,
            swept_frame_ms: 10.5,
        }];
        results.coat_rows = vec![crate::bench_coat::CoatRow { mesh: "the fox".into(), vertices: 1728, skinning_ms: 0.01, coat_ms: 0.002 }];
    }

    #[test]
    fn a_synthetic_result_set_gives_every_table_and_csv() {
        let results = synthetic_results();
        let files = report_files(&results);
        let names: Vec<&str> = files.iter().map(|f| f.0).collect();
        assert_eq!(
            names,
            [
                "report.md",
                "passes.csv",
                "passes.png",
                "techniques.csv",
                "techniques.png",
                "cpu_record.png",
                "render.csv",
                "render.png",
                "frames.csv",
                "accumulation.csv",
                "tiles.csv",
                "shell.csv",
                "sweep.csv",
                "coat.csv"
            ]
        );
        for (name, bytes) in files.iter().filter(|f| f.0.ends_with(".png")) {
            let img = image::load_from_memory(bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!((img.width(), img.height()), (960, 540), "{name}");
        }
        let text = |name: &str| String::from_utf8(files.iter().find(|f| f.0 == name).expect(name).1.clone()).expect("UTF-8");
        let md = &text("report.md");
        for section in [
            "## Deformation passes",
            "## The physical floor",
            "## GPU memory of the deformation window",
            "## Hanák 2021, Table 6.1",
            "## Techniques: total GPU ms",
            "## CPU ms to record",
            "## Points: GPU ms",
            "## Wasmut 2019, Tables 1–4",
            "## Dinh 2021, section 6.2",
            "## Swept capture against unswept",
        ] {
            assert!(md.contains(section), "no {section:?} in:\n{md}");
        }
        assert!(text("techniques.csv").contains("depth,16384,0.9,0.4"), "{}", text("techniques.csv"));
        assert_eq!(text("passes.csv").lines().count(), 1 + 2 * 4, "{}", text("passes.csv"));
        // Only what was measured: the render table alone gives the report and its CSV.
        assert!(text("frames.csv").contains("depth,128,32,64,1,4,200"), "{}", text("frames.csv"));
        // Every table says where it was measured.
        let lines: Vec<&str> = md.lines().collect();
        for (k, line) in lines.iter().enumerate().filter(|(_, l)| l.starts_with("## ") || l.starts_with("### ")) {
            assert!(lines[k + 2] == "_Measured on NVIDIA H100 80GB HBM3 (vulkan)._", "{line} is not followed by the adapter: {:?}", &lines[k..k + 3]);
        }
        assert!(text("accumulation.csv").contains("both,2048,208,60000,0.9,0.5,0.25,2,2.5,104857600"), "{}", text("accumulation.csv"));
        let render_only = BenchResults {
            rows: vec![],
            counts: vec![],
            technique_rows: vec![],
            cpu_rows: vec![],
            ranges: vec![],
            frame_rows: vec![],
            accum_rows: vec![],
            move_rows: vec![],
            store_row: None,
            shell_rows: vec![],
            sweep_rows: vec![],
            capture_rows: vec![],
            display_rows: vec![],
            coat_rows: vec![],
            software: true,
            ..results
        };
        let names: Vec<&str> = report_files(&render_only).iter().map(|f| f.0).collect();
        assert_eq!(names, ["report.md", "render.csv", "render.png"]);
    }

    #[test]
    fn the_memory_table_lists_each_resource_per_size_with_the_sources() {
        let row = |resolution: u32, k: u64| BenchRow {
            resolution,
            spheres: 8,
            passes: vec![],
            cpu_record_ms: 0.1,
            memory_bytes: 8 * k,
            memory_parts: vec![("snow".into(), 4 * k), ("terrain".into(), 4 * k)],
        };
        let md = memory_markdown(&[row(1024, 1 << 20), row(2048, 4 << 20)]);
        assert!(md.contains("| resource | 1024² MiB | 2048² MiB | bytes per texel |"), "{md}");
        assert!(md.contains("| snow | 4.0 | 16.0 | 4.0 |"), "{md}");
        assert!(md.contains("| total | 8.0 | 32.0 | 8.0 |"), "{md}");
        assert!(md.contains("9 MB") && md.contains("2 to 4 MB") && md.contains("24 MB"), "{md}");
    }
}
