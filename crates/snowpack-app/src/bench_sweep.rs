//! Swept capture (issue 21): the cost of pressing each deformer over its
//! motion since the last frame against pressing it where it stands, for fast
//! spheres (capsules), fast turning boxes (sub-steps), rolling wheels with
//! tread (sub-steps) and the points technique's segments, at a 1024² window.

use std::fmt::Write as _;

use glam::{DVec2, Quat, Vec3};
use snowpack::low_level::SnowInspect;
use snowpack::{Deformer, GpuContext, SnowDeformation, SnowParams, Technique, TerrainSource};

/// One measured set of deformers, swept and not.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepRow {
    /// What moved ("256 spheres at 12 m/s", ...).
    pub scenario: &'static str,
    /// The pass timed ("capture" or "stamp").
    pub pass: &'static str,
    /// Median GPU ms of the pass, each deformer where it stands.
    pub unswept_ms: f64,
    /// Median GPU ms of the pass, each deformer over its motion.
    pub swept_ms: f64,
    /// Median GPU ms of the whole deformation frame, unswept (software
    /// adapters move work between passes' timestamps; the total keeps it).
    pub unswept_frame_ms: f64,
    /// The same, swept.
    pub swept_frame_ms: f64,
}

impl SweepRow {
    /// Swept over unswept.
    #[must_use]
    pub fn ratio(&self) -> f64 {
        if self.unswept_ms > 0.0 { self.swept_ms / self.unswept_ms } else { f64::NAN }
    }

    /// Swept over unswept, whole frames.
    #[must_use]
    pub fn frame_ratio(&self) -> f64 {
        if self.unswept_frame_ms > 0.0 { self.swept_frame_ms / self.unswept_frame_ms } else { f64::NAN }
    }
}

/// The scenarios: (name, technique, pass, deformers at time t).
type Scenario = (&'static str, Technique, &'static str, fn(f32) -> Vec<Deformer>);

/// 256 balls of 15 cm on circles, 12 m/s: 20 cm a frame at 60 Hz.
pub(crate) fn fast_spheres(t: f32) -> Vec<Deformer> {
    (0..256)
        .map(|k| {
            let (a, r) = (k as f32 * 2.399_963, 2.0 + 20.0 * ((k as f32 + 0.5) / 256.0).sqrt());
            let phase = a + t * 12.0 / r;
            Deformer::Sphere { center: Vec3::new(r * phase.cos(), 0.45, r * phase.sin()), radius: 0.15 }
        })
        .collect()
}

/// 64 boxes of 1 x 0.4 x 2 m at 6 m/s, turning 1 rad/s: 10 cm a frame, two sub-steps.
pub(crate) fn fast_boxes(t: f32) -> Vec<Deformer> {
    (0..64)
        .map(|k| {
            let (a, r) = (k as f32 * 2.399_963, 3.0 + 20.0 * ((k as f32 + 0.5) / 64.0).sqrt());
            let phase = a + t * 6.0 / r;
            Deformer::Box {
                center: Vec3::new(r * phase.cos(), 0.5, r * phase.sin()),
                half_extents: Vec3::new(0.5, 0.2, 1.0),
                rotation: Quat::from_rotation_y(t + a),
            }
        })
        .collect()
}

/// 64 wheels of 33 cm with block tread rolling on circles at 12 m/s, 15 cm
/// into the snow: 20 cm a frame, four sub-steps each.
pub(crate) fn fast_wheels(t: f32) -> Vec<Deformer> {
    (0..64)
        .map(|k| {
            let (a, r) = (k as f32 * 2.399_963, 3.0 + 20.0 * ((k as f32 + 0.5) / 64.0).sqrt());
            let phase = a + t * 12.0 / r;
            // Rolling towards growing phase: forward (-sin, cos) = axle x up.
            Deformer::Wheel {
                center: Vec3::new(r * phase.cos(), 0.68, r * phase.sin()),
                axle: Vec3::new(phase.cos(), 0.0, phase.sin()),
                radius: 0.33,
                half_width: 0.11,
                tread: snowpack::low_level::deform::wheel::Tread::default(),
                roll_m: 12.0 * t,
            }
        })
        .collect()
}

const SCENARIOS: [Scenario; 4] = [
    ("256 spheres of 15 cm at 12 m/s (capsules)", Technique::Depth, "capture", fast_spheres),
    ("64 boxes of 1x2 m at 6 m/s, turning (sub-steps)", Technique::Depth, "capture", fast_boxes),
    ("256 contact points at 12 m/s (segments)", Technique::Points, "stamp", fast_spheres),
    ("64 wheels of 33 cm with tread at 12 m/s (sub-steps)", Technique::Depth, "capture", fast_wheels),
];

/// (median ms of `pass`, median ms of the frame's passes together).
fn pass_ms(
    ctx: &GpuContext,
    technique: Technique,
    pass: &str,
    teleport_m: f32,
    at: fn(f32) -> Vec<Deformer>,
    warmup: u32,
    frames: u32,
) -> anyhow::Result<(f64, f64)> {
    let params = SnowParams { technique, teleport_m, tile_memory_bytes: None, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO)?;
    for frame in 0..warmup + frames {
        snow.step(ctx, &at(frame as f32 / 60.0), 1.0 / 60.0)?;
        if frame + 1 == warmup {
            snow.finish(ctx)?;
            snow.clear_timings();
        }
    }
    snow.finish(ctx)?;
    let passes = snow.timings().passes;
    Ok((passes.iter().find(|p| p.0 == pass).map_or(0.0, |p| p.1), passes.iter().map(|p| p.1).sum()))
}

/// Measures every scenario swept and not (default teleport distance against 0).
pub fn measure(ctx: &GpuContext, warmup: u32, frames: u32) -> anyhow::Result<Vec<SweepRow>> {
    SCENARIOS
        .iter()
        .map(|&(scenario, technique, pass, at)| {
            let (unswept_ms, unswept_frame_ms) = pass_ms(ctx, technique, pass, 0.0, at, warmup, frames)?;
            let (swept_ms, swept_frame_ms) = pass_ms(ctx, technique, pass, SnowParams::default().teleport_m, at, warmup, frames)?;
            Ok(SweepRow { scenario, pass, unswept_ms, swept_ms, unswept_frame_ms, swept_frame_ms })
        })
        .collect()
}

/// The table: median ms of the pass unswept and swept, and their ratio.
#[must_use]
pub fn markdown(rows: &[SweepRow], adapter: &str, software: bool) -> String {
    let mut md = format!("\n## Swept capture against unswept ({adapter}, 1024² window, 60 frames a second)\n\n");
    if software {
        md.push_str("A software rasteriser: the ratios are the figures to read, not the milliseconds; its per-pass timestamps also move work between passes, so the frame's total is given too.\n\n");
    }
    md.push_str("| deformers | pass | unswept ms | swept ms | swept / unswept | frame unswept ms | frame swept ms | swept / unswept |\n|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {:.3} | {:.3} | {:.2} | {:.3} | {:.3} | {:.2} |",
            r.scenario,
            r.pass,
            r.unswept_ms,
            r.swept_ms,
            r.ratio(),
            r.unswept_frame_ms,
            r.swept_frame_ms,
            r.frame_ratio()
        );
    }
    md
}

/// `sweep.csv`.
#[must_use]
pub fn csv(rows: &[SweepRow]) -> String {
    let mut csv = String::from("scenario,pass,unswept_ms,swept_ms,ratio,unswept_frame_ms,swept_frame_ms,frame_ratio\n");
    for r in rows {
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{}",
            r.scenario,
            r.pass,
            r.unswept_ms,
            r.swept_ms,
            r.ratio(),
            r.unswept_frame_ms,
            r.swept_frame_ms,
            r.frame_ratio()
        );
    }
    csv
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_gives_the_ratio_of_swept_to_unswept() {
        let rows = vec![SweepRow { scenario: "balls", pass: "capture", unswept_ms: 0.5, swept_ms: 0.75, unswept_frame_ms: 10.0, swept_frame_ms: 11.0 }];
        let md = markdown(&rows, "lavapipe", true);
        assert!(md.contains("| balls | capture | 0.500 | 0.750 | 1.50 | 10.000 | 11.000 | 1.10 |"), "{md}");
        assert!(md.contains("ratios are the figures"));
        assert!(csv(&rows).lines().nth(1).is_some_and(|l| l == "balls,capture,0.5,0.75,1.5,10,11,1.1"));
    }

    #[test]
    fn the_scenarios_move_faster_than_a_texel_a_frame() {
        for (name, _, _, at) in SCENARIOS {
            let (a, b) = (at(0.0), at(1.0 / 60.0));
            let moved = |p: &Deformer, q: &Deformer| match (p, q) {
                (Deformer::Sphere { center: c0, .. }, Deformer::Sphere { center: c1, .. })
                | (Deformer::Box { center: c0, .. }, Deformer::Box { center: c1, .. })
                | (Deformer::Wheel { center: c0, .. }, Deformer::Wheel { center: c1, .. }) => c0.distance(*c1),
                _ => 0.0,
            };
            assert!(a.iter().zip(&b).all(|(p, q)| moved(p, q) > 0.0625), "{name}");
        }
    }
}
