//! Dinh 2021, section 6.2 (his table of accumulation cost) on the same
//! terms: three scenes (eight simple objects; a forest; both) with 512², 1024²
//! and 2048² accumulation maps, the accumulation pass, the support passes and
//! memory. Dinh renders the occlusion into eight render targets and runs each
//! support pass once per object map; snowpack scatters into one atlas for all
//! objects, so each pass runs once whatever the object count.

use std::fmt::Write as _;

use glam::{DVec2, Quat, Vec3};
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::SnowInspect;
use snowpack::{GpuContext, SnowDeformation, SnowParams, TerrainSource};
use snowpack::{ObjectShape, SnowObject, Snowfall};

/// The three scenes of Dinh's table.
pub const SCENARIOS: [&str; 3] = ["eight objects", "forest", "both"];

/// One measured configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct AccumRow {
    /// Which of [`SCENARIOS`].
    pub scenario: String,
    /// Atlas texels per side.
    pub atlas: u32,
    /// Objects.
    pub objects: usize,
    /// Triangles the occlusion draws.
    pub occlusion_triangles: u64,
    /// Fraction of the atlas inside charts.
    pub atlas_used: f64,
    /// Median GPU ms of the occlusion and the scatter (Dinh's "accumulation pass").
    pub accumulation_ms: f64,
    /// Median GPU ms of increment, settle (blur, stability) and surface (dilation, normals): Dinh's "support pass".
    pub support_ms: f64,
    /// Median GPU ms of the whole deformation frame with the accumulation.
    pub frame_ms: f64,
    /// Median wall ms of a frame, submit to idle (what a software adapter's
    /// timestamps misattribute between passes, this still measures).
    pub wall_ms: f64,
    /// GPU memory of the accumulation (bytes).
    pub memory_bytes: u64,
}

/// Dinh's figures (RTX 3060): scenario, map side, accumulation ms, support ms, FPS, memory MB.
const DINH: [(&str, u32, f64, f64, &str, u32); 9] = [
    ("eight objects", 512, 0.22, 0.12, "72", 300),
    ("eight objects", 1024, 3.58, 0.37, "35", 1100),
    ("eight objects", 2048, 42.68, 1.39, "4.9", 3100),
    ("forest", 512, 0.26, 0.14, "144", 200),
    ("forest", 1024, 0.9, 0.37, "127–140", 500),
    ("forest", 2048, 9.65, 1.39, "20", 1150),
    ("both", 512, 0.23, 0.12, "75", 400),
    ("both", 1024, 2.33, 0.37, "36", 1000),
    ("both", 2048, 54.24, 1.39, "5", 2900),
];

/// Objects in Dinh's scenes: eight simple ones; the ground and the forest
/// mesh; the ground, the forest and six trees.
fn dinh_objects(scenario: &str) -> u32 {
    if scenario == "forest" { 2 } else { 8 }
}

fn thing(name: String, shape: ObjectShape, position: Vec3, yaw: f32) -> SnowObject {
    SnowObject { name, shape, position, rotation: Quat::from_rotation_y(yaw), dilate: true }
}

/// The objects of a scenario: eight benches, boulders and crates near the
/// centre; a forest of 100 trees (trunk and crown) around them.
#[must_use]
pub fn scenario_objects(scenario: &str) -> Vec<SnowObject> {
    let mut list = Vec::new();
    if scenario != "forest" {
        for k in 0..8 {
            let a = k as f32 * std::f32::consts::TAU / 8.0;
            let at = Vec3::new(6.0 * a.cos(), 0.8, 6.0 * a.sin());
            let shape = if k % 2 == 0 { ObjectShape::Box { size_m: Vec3::new(2.0, 0.5, 1.0) } } else { ObjectShape::Sphere { radius_m: 0.9 } };
            list.push(thing(format!("simple{k}"), shape, at, a));
        }
    }
    if scenario != "eight objects" {
        for k in 0..100 {
            let a = k as f32 * 2.399_963;
            let r = 12.0 + 16.0 * ((k as f32 + 0.5) / 100.0).sqrt();
            let (x, z) = (r * a.cos(), r * a.sin());
            list.push(thing(format!("trunk{k}"), ObjectShape::Box { size_m: Vec3::new(0.35, 3.0, 0.35) }, Vec3::new(x, 1.5, z), a));
            list.push(thing(format!("crown{k}"), ObjectShape::Sphere { radius_m: 1.4 }, Vec3::new(x, 3.8, z), 0.0));
        }
    }
    list
}

/// Measures one scenario with an atlas of `atlas`² texels in a 1024², 64 m window.
pub fn measure(ctx: &GpuContext, scenario: &str, atlas: u32, warmup: u32, frames: u32) -> anyhow::Result<AccumRow> {
    let snowfall = Snowfall { atlas_resolution: atlas, rate_m_per_s: 0.002, ..Snowfall::default() };
    let params = SnowParams { snowfall: Some(snowfall), ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO)?;
    let objects = scenario_objects(scenario);
    snow.set_objects(ctx, &objects)?;
    let mut walls = Vec::new();
    for frame in 0..warmup + frames {
        let start = std::time::Instant::now();
        snow.step(ctx, &[], 1.0 / 60.0)?;
        ctx.wait_idle("accumulation bench frame")?;
        if frame >= warmup {
            walls.push(start.elapsed().as_secs_f64() * 1000.0);
        }
        if frame + 1 == warmup {
            snow.finish(ctx)?;
            snow.clear_timings();
        }
    }
    walls.sort_by(f64::total_cmp);
    snow.finish(ctx)?;
    let timings = snow.timings();
    let sum = |names: &[&str]| timings.passes.iter().filter(|p| names.contains(&p.0.as_str())).map(|p| p.1).sum::<f64>();
    let acc = snow.accumulation().ok_or_else(|| anyhow::anyhow!("no accumulation"))?;
    let used: u64 = acc.layout().charts.iter().map(|c| u64::from(c.rect[2]) * u64::from(c.rect[3])).sum();
    Ok(AccumRow {
        scenario: scenario.to_owned(),
        atlas,
        objects: objects.len(),
        occlusion_triangles: acc.occlusion_triangles(),
        atlas_used: used as f64 / (f64::from(atlas) * f64::from(atlas)),
        accumulation_ms: sum(&["occlusion", "scatter"]),
        support_ms: sum(&["increment", "settle", "atlas surface"]),
        frame_ms: timings.passes.iter().map(|p| p.1).sum(),
        wall_ms: walls.get(walls.len() / 2).copied().unwrap_or(0.0),
        memory_bytes: acc.memory_bytes().iter().map(|m| m.1).sum(),
    })
}

/// Dinh's table with snowpack's rows beside his.
#[must_use]
pub fn markdown(rows: &[AccumRow], adapter: &str, software: bool) -> String {
    let mut md = String::from("\n## Dinh 2021, section 6.2: accumulation cost against map size\n\n");
    let _ = writeln!(
        md,
        "Dinh's figures are on an RTX 3060 (NSight; FPS and memory of his whole application). snowpack's are medians of GPU timestamps on **{adapter}**{}, in a 1024², 64 m deformation window, and the wall time of a frame from submit to idle (on a software rasteriser the timestamps misattribute time between consecutive passes; the wall time does not): \"accumulation\" is the occlusion render and the scatter, \"support\" the increment, settle (5x5 blur, stability) and surface (dilation, Scharr slopes) passes; memory is the accumulation's GPU buffers. snowpack's map is one atlas shared by every object (Dinh: one map per object, at most eight), and the atlas is no finer than two texels per occlusion pixel, so small scenes do not fill the larger atlases (the \"atlas used\" column). Our forest is 100 trees of a box trunk and a sphere crown (200 objects), not Dinh's 360,000-triangle mesh: the triangles the occlusion draws are listed.\n",
        if software { " (a software rasteriser: ratios only)" } else { "" }
    );
    md.push_str("| scene | map | source | objects | occlusion triangles | atlas used | accumulation ms | support ms | frame GPU ms / FPS | frame wall ms | memory MB |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
    for scenario in SCENARIOS {
        for size in [512u32, 1024, 2048] {
            if let Some(d) = DINH.iter().find(|d| d.0 == scenario && d.1 == size) {
                let _ = writeln!(
                    md,
                    "| {scenario} | {size}² | Dinh (RTX 3060) | {} | – | – | {:.2} | {:.2} | {} FPS | – | {} |",
                    dinh_objects(scenario),
                    d.2,
                    d.3,
                    d.4,
                    d.5
                );
            }
            if let Some(r) = rows.iter().find(|r| r.scenario == scenario && r.atlas == size) {
                let _ = writeln!(
                    md,
                    "| {scenario} | {size}² | snowpack | {} | {} | {:.0}% | {:.3} | {:.3} | {:.3} ms | {:.1} | {:.1} |",
                    r.objects,
                    r.occlusion_triangles,
                    r.atlas_used * 100.0,
                    r.accumulation_ms,
                    r.support_ms,
                    r.frame_ms,
                    r.wall_ms,
                    r.memory_bytes as f64 / 1e6
                );
            }
        }
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_puts_our_rows_beside_dinhs() {
        let row = AccumRow {
            scenario: "forest".into(),
            atlas: 1024,
            objects: 200,
            occlusion_triangles: 52_000,
            atlas_used: 0.5,
            accumulation_ms: 0.25,
            support_ms: 0.125,
            frame_ms: 1.5,
            wall_ms: 3.25,
            memory_bytes: 60_000_000,
        };
        let md = markdown(&[row], "NVIDIA H100", false);
        assert!(md.contains("| forest | 1024² | Dinh (RTX 3060) | 2 | – | – | 0.90 | 0.37 | 127–140 FPS | – | 500 |"), "{md}");
        assert!(md.contains("| forest | 1024² | snowpack | 200 | 52000 | 50% | 0.250 | 0.125 | 1.500 ms | 3.2 | 60.0 |"), "{md}");
        assert!(md.contains("| both | 2048² | Dinh (RTX 3060) | 8 | – | – | 54.24 | 1.39 | 5 FPS | – | 2900 |"), "{md}");
        assert!(markdown(&[], "llvmpipe", true).contains("ratios only"));
    }

    #[test]
    fn scenarios_have_their_objects() {
        assert_eq!(scenario_objects("eight objects").len(), 8);
        assert_eq!(scenario_objects("forest").len(), 200);
        assert_eq!(scenario_objects("both").len(), 208);
    }
}
