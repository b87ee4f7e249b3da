//! The display pass's kernels side by side (`DisplayKernel`, issue 44
//! item 1): the same window, pressed by the same spheres over the same
//! terrain, displayed by each kernel in one run on one adapter. Each row
//! gives the display's median GPU time, its bandwidth floor where the
//! adapter's bandwidth is known, the median wall time of a whole frame
//! waited for (what a software adapter, whose timestamps do not bracket
//! compute work, can be read by), and whether the kernel left the same
//! snow words as the first, bit for bit.

use std::fmt::Write as _;
use std::time::Instant;

use glam::DVec2;
use snowpack::low_level::deform::display::DisplayKernel;
use snowpack::low_level::deform::traffic::{frame_traffic, known_bandwidth_gb_per_s};
use snowpack::low_level::gpu::timing::median;
use snowpack::low_level::{GpuContextExt, SnowInspect};
use snowpack::{GpuContext, NoiseTerrain, SnowDeformation, SnowParams, Technique, TerrainSource};

/// One kernel on one window and terrain.
#[derive(Clone, Debug, PartialEq)]
pub struct DisplayRow {
    /// Texels per side.
    pub resolution: u32,
    /// The terrain under the window.
    pub terrain: &'static str,
    /// The kernel.
    pub kernel: DisplayKernel,
    /// Median GPU ms of the display pass.
    pub display_ms: f64,
    /// Median wall ms of a whole frame, stepped and waited for.
    pub frame_wall_ms: f64,
    /// Whether the window's snow words equal the first kernel's, every bit.
    pub same_words: bool,
}

/// The terrains: flat (the ground a constant) and the passes table's
/// hills (the ground a four-octave noise), evaluated per texel read (the
/// default) or stored by the window (`SnowParams::store_ground`).
fn terrains() -> [(&'static str, TerrainSource, bool); 3] {
    let hills = TerrainSource::Noise(NoiseTerrain { seed: 1, base_m: 0.0, amplitude_m: 0.3, wavelength_m: 30.0 });
    [("flat", TerrainSource::Flat { height_m: 0.0 }, false), ("noise hills", hills.clone(), false), ("hills, ground stored", hills, true)]
}

/// (display median GPU ms, frame median wall ms, the final snow words).
fn run_kernel(
    ctx: &GpuContext,
    (resolution, terrain, store_ground): (u32, &TerrainSource, bool),
    kernel: DisplayKernel,
    (warmup, frames): (u32, u32),
) -> anyhow::Result<(f64, f64, Vec<u32>)> {
    let extent_m = 64.0 * resolution as f32 / 1024.0;
    let params = SnowParams { extent_m, resolution, technique: Technique::Depth, tile_memory_bytes: None, store_ground, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, terrain.clone(), DVec2::ZERO)?;
    snow.set_display_kernel(kernel);
    let mut wall = Vec::new();
    for frame in 0..warmup + frames {
        let t = frame as f32 / 60.0;
        let deformers = snowpack_testkit::testing::circling_spheres(256, t);
        let start = Instant::now();
        snow.step(ctx, &deformers, 1.0 / 60.0)?;
        ctx.wait_idle("the display bench's frame")?;
        if frame >= warmup {
            wall.push(start.elapsed().as_secs_f64() * 1e3);
        }
        if frame + 1 == warmup {
            snow.finish(ctx)?;
            snow.clear_timings();
        }
    }
    snow.finish(ctx)?;
    let display = snow.timings().passes.iter().find(|p| p.0 == "display").map_or(0.0, |p| p.1);
    Ok((display, median(&wall).unwrap_or(0.0), snow.read_snow_words(ctx)?))
}

/// Every kernel at each of `sizes` over each terrain.
pub fn measure(ctx: &GpuContext, sizes: &[u32], warmup: u32, frames: u32) -> anyhow::Result<Vec<DisplayRow>> {
    let mut rows = Vec::new();
    for &resolution in sizes {
        for (name, terrain, store_ground) in terrains() {
            let mut first: Option<Vec<u32>> = None;
            for kernel in DisplayKernel::ALL {
                let (display_ms, frame_wall_ms, words) = run_kernel(ctx, (resolution, &terrain, store_ground), kernel, (warmup, frames))?;
                let same_words = first.as_ref().is_none_or(|f| *f == words);
                first.get_or_insert(words);
                rows.push(DisplayRow { resolution, terrain: name, kernel, display_ms, frame_wall_ms, same_words });
            }
        }
    }
    Ok(rows)
}

/// The display pass's floor (ms) at `resolution` on `adapter`, where its bandwidth is known.
fn floor_ms(resolution: u32, adapter: &str) -> Option<f64> {
    let params = SnowParams { resolution, extent_m: 64.0 * resolution as f32 / 1024.0, technique: Technique::Depth, ..SnowParams::default() };
    let bandwidth = known_bandwidth_gb_per_s(adapter)?;
    frame_traffic(&params).iter().find(|t| t.pass == "display").map(|t| t.floor_ms(bandwidth))
}

/// The table.
#[must_use]
pub fn markdown(rows: &[DisplayRow], adapter: &str, software: bool) -> String {
    let mut md = format!("\n## The display pass's kernels side by side ({adapter}, 256 spheres, 60 frames a second)\n\n");
    if software {
        md.push_str("A software adapter: its timestamps do not bracket compute work, so read the frames' wall times (ratios only).\n\n");
    }
    md.push_str("| window | terrain | kernel | display ms | × floor | frame wall ms | same words as blur4 |\n|---|---|---|---|---|---|---|\n");
    for r in rows {
        let floor = floor_ms(r.resolution, adapter).filter(|f| *f > 0.0).map_or("n/a".to_owned(), |f| format!("{:.1}", r.display_ms / f));
        let _ = writeln!(
            md,
            "| {}² | {} | {:?} | {:.4} | {floor} | {:.2} | {} |",
            r.resolution,
            r.terrain,
            r.kernel,
            r.display_ms,
            r.frame_wall_ms,
            if r.same_words { "yes" } else { "**no**" }
        );
    }
    md
}

/// `display.csv`.
#[must_use]
pub fn csv(rows: &[DisplayRow]) -> String {
    let mut csv = String::from("resolution,terrain,kernel,display_ms,frame_wall_ms,same_words\n");
    for r in rows {
        let _ = writeln!(csv, "{},{},{:?},{},{},{}", r.resolution, r.terrain, r.kernel, r.display_ms, r.frame_wall_ms, r.same_words);
    }
    csv
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_gives_each_kernel_and_its_floor_on_a_known_gpu() {
        let row = |kernel, display_ms, same_words| DisplayRow { resolution: 1024, terrain: "flat", kernel, display_ms, frame_wall_ms: 2.5, same_words };
        let rows = vec![row(DisplayKernel::Blur4, 0.05, true), row(DisplayKernel::PerTexel, 0.025, false)];
        let md = markdown(&rows, "NVIDIA H200", false);
        // 8 bytes a texel of 1024² at 4,800 GB/s: 0.00175 ms.
        assert!(md.contains("| 1024² | flat | Blur4 | 0.0500 | 28.6 | 2.50 | yes |"), "{md}");
        assert!(md.contains("| PerTexel | 0.0250 | 14.3 | 2.50 | **no** |"), "{md}");
        assert!(markdown(&rows, "llvmpipe", true).contains("| n/a |"));
        assert_eq!(csv(&rows).lines().nth(2), Some("1024,flat,PerTexel,0.025,2.5,false"));
    }
}
