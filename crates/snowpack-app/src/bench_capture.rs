//! The capture's analytic shapes ray cast by compute against drawn
//! (`ShapeCapture`, issue 44 item 2), side by side on one adapter in one
//! run: the capture pass's median GPU time and the whole deformation
//! frame's, at a 1024² window, for fast spheres (capsules), crowds of
//! spheres, turning boxes and treaded wheels (sub-steps).

use std::fmt::Write as _;

use glam::DVec2;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::deform::capture::ShapeCapture;
use snowpack::{Deformer, GpuContext, SnowDeformation, SnowParams, TerrainSource};

/// One set of deformers, its shapes by compute and drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureRow {
    /// What pressed.
    pub scenario: &'static str,
    /// Median GPU ms of the capture, by compute.
    pub compute_ms: f64,
    /// The same, drawn.
    pub raster_ms: f64,
    /// Median GPU ms of the whole deformation frame, by compute (software
    /// adapters move work between passes' timestamps; the total keeps it).
    pub compute_frame_ms: f64,
    /// The same, drawn.
    pub raster_frame_ms: f64,
}

/// 4,096 spheres of 30 cm circling on a 48 m grid.
fn crowd(t: f32) -> Vec<Deformer> {
    snowpack_testkit::testing::circling_spheres(4096, t)
}

/// 16,384 of them (the techniques table's largest crowd).
fn big_crowd(t: f32) -> Vec<Deformer> {
    snowpack_testkit::testing::circling_spheres(16384, t)
}

/// A scenario: its name and its deformers at time t.
type Scenario = (&'static str, fn(f32) -> Vec<Deformer>);

const SCENARIOS: [Scenario; 5] = [
    ("256 spheres of 15 cm at 12 m/s (capsules)", crate::bench_sweep::fast_spheres),
    ("4,096 spheres of 30 cm", crowd),
    ("16,384 spheres of 30 cm", big_crowd),
    ("64 boxes of 1x2 m at 6 m/s, turning (sub-steps)", crate::bench_sweep::fast_boxes),
    ("64 wheels of 33 cm with tread at 12 m/s (sub-steps)", crate::bench_sweep::fast_wheels),
];

/// (median ms of the capture, median ms of the frame's passes together).
fn capture_ms(ctx: &GpuContext, by: ShapeCapture, at: fn(f32) -> Vec<Deformer>, (warmup, frames): (u32, u32)) -> anyhow::Result<(f64, f64)> {
    let params = SnowParams { tile_memory_bytes: None, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO)?;
    snow.set_shape_capture(by);
    for frame in 0..warmup + frames {
        snow.step(ctx, &at(frame as f32 / 60.0), 1.0 / 60.0)?;
        if frame + 1 == warmup {
            snow.finish(ctx)?;
            snow.clear_timings();
        }
    }
    snow.finish(ctx)?;
    let passes = snow.timings().passes;
    Ok((passes.iter().find(|p| p.0 == "capture").map_or(0.0, |p| p.1), passes.iter().map(|p| p.1).sum()))
}

/// Measures every scenario both ways.
pub fn measure(ctx: &GpuContext, warmup: u32, frames: u32) -> anyhow::Result<Vec<CaptureRow>> {
    SCENARIOS
        .iter()
        .map(|&(scenario, at)| {
            let (compute_ms, compute_frame_ms) = capture_ms(ctx, ShapeCapture::Compute, at, (warmup, frames))?;
            let (raster_ms, raster_frame_ms) = capture_ms(ctx, ShapeCapture::Raster, at, (warmup, frames))?;
            Ok(CaptureRow { scenario, compute_ms, raster_ms, compute_frame_ms, raster_frame_ms })
        })
        .collect()
}

/// Compute over drawn (below 1: compute is cheaper).
fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 { a / b } else { f64::NAN }
}

/// The table: the capture and the frame, by compute and drawn, and their ratios.
#[must_use]
pub fn markdown(rows: &[CaptureRow], adapter: &str, software: bool) -> String {
    let mut md = format!("\n## The capture's shapes by compute against drawn ({adapter}, 1024² window, 60 frames a second)\n\n");
    if software {
        md.push_str("A software rasteriser: the milliseconds are not the figures to read. Its timestamps do not bracket compute work (lavapipe runs it outside them), so the compute columns read low here; `cargo run --release -p snowpack --example capture_cost` gives wall times, where drawing wins on such an adapter (it shades only the texels a shape covers, compute whole 16×16 tiles).\n\n");
    }
    md.push_str("| deformers | capture by compute ms | drawn ms | compute / drawn | frame by compute ms | frame drawn ms | compute / drawn |\n|---|---|---|---|---|---|---|\n");
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {:.3} | {:.3} | {:.2} | {:.3} | {:.3} | {:.2} |",
            r.scenario,
            r.compute_ms,
            r.raster_ms,
            ratio(r.compute_ms, r.raster_ms),
            r.compute_frame_ms,
            r.raster_frame_ms,
            ratio(r.compute_frame_ms, r.raster_frame_ms)
        );
    }
    md
}

/// `capture.csv`.
#[must_use]
pub fn csv(rows: &[CaptureRow]) -> String {
    let mut csv = String::from("scenario,compute_ms,raster_ms,ratio,compute_frame_ms,raster_frame_ms,frame_ratio\n");
    for r in rows {
        let (a, b) = (ratio(r.compute_ms, r.raster_ms), ratio(r.compute_frame_ms, r.raster_frame_ms));
        let _ = writeln!(csv, "{},{},{},{a},{},{},{b}", r.scenario, r.compute_ms, r.raster_ms, r.compute_frame_ms, r.raster_frame_ms);
    }
    csv
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_gives_compute_over_drawn() {
        let rows = vec![CaptureRow { scenario: "balls", compute_ms: 0.25, raster_ms: 0.5, compute_frame_ms: 9.0, raster_frame_ms: 10.0 }];
        let md = markdown(&rows, "lavapipe", true);
        assert!(md.contains("| balls | 0.250 | 0.500 | 0.50 | 9.000 | 10.000 | 0.90 |"), "{md}");
        assert!(md.contains("capture_cost"));
        assert_eq!(csv(&rows).lines().nth(1), Some("balls,0.25,0.5,0.5,9,10,0.9"));
    }
}
