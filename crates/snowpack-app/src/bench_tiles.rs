//! Open worlds (issue: tile store): the cost of a window move with and
//! without the tile store, the store's compressed bytes per kilometre of
//! trail, and how long a tile takes to come back from disk.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::Context as _;
use glam::{DVec2, Vec3};
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::TileStreamerExt;
use snowpack::low_level::persist::TileKey;
use snowpack::{Deformer, GpuContext, NoiseTerrain, SnowDeformation, SnowParams, TerrainSource};
use snowpack::{StoreConfig, StoredWindow as _, StreamerConfig, TileStore, TileStreamer};

/// Texels per side of a tile in every measurement.
const TILE: u32 = 64;
/// The window moves this many texels per frame (7.5 m/s at 6.25 cm and 60 Hz).
const TEXELS_PER_FRAME: f64 = 2.0;

/// One configuration of the window-move measurement.
#[derive(Clone, Debug, PartialEq)]
pub struct MoveRow {
    /// Window texels per side.
    pub resolution: u32,
    /// Whether a tile store was attached.
    pub store: bool,
    /// Median GPU ms of the passes a move runs: `window` without a store;
    /// `tile stash`, `tile restore`, `tile load` and `tile weather` with one.
    pub move_gpu_ms: f64,
    /// Median GPU ms of the whole deformation frame.
    pub frame_gpu_ms: f64,
    /// Median CPU ms to plan, record and submit a frame.
    pub record_cpu_ms: f64,
    /// Median wall ms of a frame, start of recording to GPU idle.
    pub wall_ms: f64,
    /// GPU memory of the resident tiles (bytes; 0 without a store).
    pub resident_bytes: u64,
}

/// The store's size and speed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StoreRow {
    /// Length of the trail (m).
    pub trail_m: f64,
    /// Width of the swath the window swept (m).
    pub swath_m: f64,
    /// Store bytes per km of swath with a trail down its middle.
    pub bytes_per_km_with_trail: f64,
    /// Store bytes per km of the same swath with no trail.
    pub bytes_per_km_untouched: f64,
    /// Mean compressed bytes of a tile.
    pub mean_tile_bytes: f64,
    /// Median ms from asking for a tile not in memory to having it (read, CRC, inflate).
    pub restore_ms: f64,
    /// Frames the window waited when teleported back to the start (cold cache).
    pub teleport_wait_frames: u64,
    /// Wall ms from that teleport to the window standing at the start.
    pub teleport_ms: f64,
    /// Wall ms of the longest frame of that teleport (`step`: encode,
    /// submit, the readbacks that have arrived): what a game's frame feels.
    pub teleport_longest_frame_ms: f64,
    /// Times a frame of that teleport waited for the GPU (`TileStats::gpu_waits`).
    pub teleport_gpu_waits: u64,
}

fn params(resolution: u32, refill: f32) -> SnowParams {
    SnowParams { extent_m: resolution as f32 / 16.0, resolution, refill_m_per_s: refill, ..SnowParams::default() }
}

fn terrain() -> TerrainSource {
    TerrainSource::Noise(NoiseTerrain { seed: 5, base_m: 0.0, amplitude_m: 0.5, wavelength_m: 40.0 })
}

fn median(v: &[f64]) -> f64 {
    snowpack::low_level::gpu::timing::median(v).unwrap_or(0.0)
}

fn streamer(dir: &Path, memory_mb: usize) -> anyhow::Result<TileStreamer> {
    let store = TileStore::open(dir, TILE, StoreConfig { disk_budget_bytes: 0, ..StoreConfig::default() })
        .with_context(|| format!("opening a bench store in {}", dir.display()))?;
    Ok(TileStreamer::new(store, StreamerConfig { memory_budget_bytes: memory_mb << 20, ..StreamerConfig::default() }))
}

/// A sphere ploughing at the window's centre as it moves along x.
fn plough(center: DVec2) -> Deformer {
    Deformer::Sphere { center: Vec3::new(center.x as f32, 0.3, center.y as f32), radius: 0.5 }
}

/// The window moving steadily along x with a plough at its centre, with or without a store.
pub fn measure_move(ctx: &GpuContext, resolution: u32, store: bool, warmup: u32, frames: u32, scratch: &Path) -> anyhow::Result<MoveRow> {
    // Without a store the window forgets (no memory keeper either): the plain window pass.
    let p = SnowParams { tile_memory_bytes: None, ..params(resolution, 0.001) };
    let texel = f64::from(p.texel_m());
    let mut snow = SnowDeformation::new(ctx, p, terrain(), DVec2::ZERO)?;
    let dir = scratch.join(format!("move-{resolution}"));
    let _ = std::fs::remove_dir_all(&dir);
    if store {
        snow.attach_store(ctx, streamer(&dir, 256)?)?;
    }
    let (mut record, mut wall) = (Vec::new(), Vec::new());
    for frame in 0..warmup + frames {
        let center = DVec2::new(f64::from(frame) * TEXELS_PER_FRAME * texel, 0.0);
        snow.set_center(center);
        let start = Instant::now();
        snow.step(ctx, &[plough(center)], 1.0 / 60.0)?;
        let recorded = start.elapsed();
        ctx.wait_idle("tile bench frame")?;
        if frame == warmup {
            snow.clear_timings();
        }
        if frame >= warmup {
            record.push(recorded.as_secs_f64() * 1e3);
            wall.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    snow.finish(ctx)?;
    let timings = snow.timings();
    let moving = |n: &str| n == "window" || n.starts_with("tile ");
    let row = MoveRow {
        resolution,
        store,
        move_gpu_ms: timings.passes.iter().filter(|p| moving(&p.0)).map(|p| p.1).sum(),
        frame_gpu_ms: timings.total_ms(),
        record_cpu_ms: median(&record),
        wall_ms: median(&wall),
        resident_bytes: snow.tile_stats().map_or(0, |s| s.gpu_bytes),
    };
    drop(snow);
    let _ = std::fs::remove_dir_all(&dir);
    Ok(row)
}

/// Store bytes per km (with and without a trail) and restore latency, in a
/// 256² (16 m) window travelling `trail_m` along x.
pub fn measure_store(ctx: &GpuContext, trail_m: f64, scratch: &Path) -> anyhow::Result<StoreRow> {
    let resolution = 256;
    let texel = f64::from(params(resolution, 0.0).texel_m());
    let mut row = StoreRow { trail_m, swath_m: f64::from(resolution) * texel, ..StoreRow::default() };
    let mut last_dir = None;
    for with_trail in [false, true] {
        let dir = scratch.join(if with_trail { "store-trail" } else { "store-plain" });
        let _ = std::fs::remove_dir_all(&dir);
        let mut snow = SnowDeformation::new(ctx, params(resolution, 0.0), terrain(), DVec2::ZERO)?;
        // No memory cache beyond the tiles asked for: the teleport below reads the disk.
        snow.attach_store(ctx, streamer(&dir, 0)?)?;
        // 4 texels (25 cm) a frame: the plough's 1 m footprint overlaps itself.
        let steps = (trail_m / (4.0 * texel)).ceil() as u32;
        for k in 0..=steps {
            let center = DVec2::new(f64::from(k) * 4.0 * texel, 0.0);
            snow.set_center(center);
            let deformers = if with_trail { vec![plough(center)] } else { Vec::new() };
            snow.step(ctx, &deformers, 1.0 / 60.0)?;
        }
        snow.save(ctx)?;
        let stats = snow.tile_stats().context("store stats")?;
        let per_km = stats.store.disk_bytes as f64 / (trail_m / 1000.0);
        if with_trail {
            row.bytes_per_km_with_trail = per_km;
            row.mean_tile_bytes = stats.store.disk_bytes as f64 / stats.store.disk_tiles.max(1) as f64;
            // Teleport back to the start: the window waits for its tiles.
            let (waits, gpu_waits) = (stats.window_waits, stats.gpu_waits);
            snow.set_center(DVec2::ZERO);
            let start = Instant::now();
            for _ in 0..600 {
                let frame = Instant::now();
                snow.step(ctx, &[], 1.0 / 60.0)?;
                row.teleport_longest_frame_ms = row.teleport_longest_frame_ms.max(frame.elapsed().as_secs_f64() * 1e3);
                if snow.origin_m().is_some_and(|o| o.x < 0.0) {
                    break;
                }
            }
            ctx.wait_idle("tile bench teleport")?;
            row.teleport_ms = start.elapsed().as_secs_f64() * 1e3;
            row.teleport_wait_frames = snow.tile_stats().map_or(0, |s| s.window_waits - waits);
            row.teleport_gpu_waits = snow.tile_stats().map_or(0, |s| s.gpu_waits - gpu_waits);
        } else {
            row.bytes_per_km_untouched = per_km;
        }
        drop(snow);
        if with_trail {
            last_dir = Some(dir);
        } else {
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
    // Restore latency: a cold streamer asked for tiles one at a time.
    let dir = last_dir.context("the trail's store")?;
    let mut cold = streamer(&dir, 64)?;
    let tiles_x = (trail_m / (f64::from(TILE) * texel)) as i64;
    let mut latencies = Vec::new();
    for col in 0..tiles_x.min(64) {
        let key = TileKey { col, row: -1 };
        let start = Instant::now();
        cold.request(key);
        while !cold.is_ready(key) {
            cold.poll();
            std::thread::yield_now();
            if start.elapsed().as_secs() > 5 {
                anyhow::bail!("tile {key:?} never came back from the store");
            }
        }
        latencies.push(start.elapsed().as_secs_f64() * 1e3);
    }
    row.restore_ms = median(&latencies);
    drop(cold);
    let _ = std::fs::remove_dir_all(&dir);
    Ok(row)
}

/// The tables for `report.md`.
#[must_use]
pub fn markdown(moves: &[MoveRow], store: Option<&StoreRow>, adapter: &str, software: bool) -> String {
    let mut md = String::from("\n## Open worlds: window moves with and without the tile store\n\n");
    let _ = writeln!(
        md,
        "The window moves {TEXELS_PER_FRAME} texels (12.5 cm) every frame with a sphere ploughing at its centre and refill on (so the weather pass runs), over noise terrain; tiles of {TILE}². Medians on **{adapter}**{}: GPU ms of the passes a move runs (without a store the window pass; with one the stash, restore, load and weather passes), of the whole deformation frame, CPU ms to plan, record and submit a frame (with a store: slot bookkeeping, uploads, handing copied-out tiles to the worker), and wall ms to GPU idle.\n",
        if software { " (a software rasteriser: ratios only)" } else { "" }
    );
    md.push_str("| window | store | move GPU ms | frame GPU ms | record CPU ms | frame wall ms | resident tiles MB |\n|---|---|---|---|---|---|---|\n");
    for r in moves {
        let _ = writeln!(
            md,
            "| {}² | {} | {:.3} | {:.3} | {:.3} | {:.2} | {:.1} |",
            r.resolution,
            if r.store { "yes" } else { "no" },
            r.move_gpu_ms,
            r.frame_gpu_ms,
            r.record_cpu_ms,
            r.wall_ms,
            r.resident_bytes as f64 / 1e6
        );
    }
    if let Some(s) = store {
        let _ = writeln!(
            md,
            "\nStore size and speed: a 256² ({} m) window travelling {} m with and without a sphere ploughing a 1 m trail down its middle, then saved. {:.0} KB per km of swath with the trail, {:.0} KB per km untouched, so the trail itself costs {:.0} KB per km; {:.0} bytes per tile on average. A tile not in memory comes back (read, CRC, inflate, on the worker) in a median {:.2} ms; teleported back to the start with a cold cache, the window waited {} frames for its tiles and stood there {:.0} ms (wall) after the teleport; its longest frame took {:.1} ms, waiting {} times for the GPU.",
            s.swath_m,
            s.trail_m,
            s.bytes_per_km_with_trail / 1e3,
            s.bytes_per_km_untouched / 1e3,
            (s.bytes_per_km_with_trail - s.bytes_per_km_untouched) / 1e3,
            s.mean_tile_bytes,
            s.restore_ms,
            s.teleport_wait_frames,
            s.teleport_ms,
            s.teleport_longest_frame_ms,
            s.teleport_gpu_waits
        );
    }
    md
}
