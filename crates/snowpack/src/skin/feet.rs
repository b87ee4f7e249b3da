//! Feet of a character: which joints touch the ground, and footstep events
//! when one touches down (for sounds, particles and gameplay).
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use glam::{Mat4, Vec3};

use super::skinning::SkinnedMesh;
use super::{Clip, Skeleton};

/// Joint-name patterns that mark feet when none are given (case-insensitive).
pub const DEFAULT_FOOT_PATTERNS: [&str; 4] = ["foot", "hand", "paw", "toe"];

/// One foot: its joint, the mesh of its paw and its height when planted.
#[derive(Clone, Debug, PartialEq)]
pub struct Foot {
    /// Node index of the foot joint.
    pub node: usize,
    /// The joint's name.
    pub name: String,
    /// Height of the foot's reference point (the lowest vertex of its paw,
    /// or the joint when it has none) above the root when planted (model
    /// units), per clip: its lowest over that clip's cycle.
    pub planted_height: Vec<f32>,
    /// The paw: vertices bound mostly to the foot joint or a joint below it
    /// (see [`attach_paws`]); empty when unknown.
    pub paw: Vec<u32>,
}

impl Foot {
    /// Planted height while `clip` plays.
    #[must_use]
    pub fn planted(&self, clip: usize) -> f32 {
        self.planted_height.get(clip).or(self.planted_height.first()).copied().unwrap_or(0.0)
    }

    /// The lowest vertex of the paw skinned by `joints` and placed by
    /// `model`; `None` without a paw (use the joint then).
    #[must_use]
    pub fn lowest_point(&self, mesh: &SkinnedMesh, joints: &[Mat4], model: Mat4) -> Option<Vec3> {
        let last = joints.len().saturating_sub(1);
        self.paw
            .iter()
            .filter_map(|&v| {
                let v = v as usize;
                let (p, j, w) = (mesh.positions.get(v)?, mesh.joints.get(v)?, mesh.weights.get(v)?);
                let m = (0..4).fold(Mat4::ZERO, |acc, k| acc + joints[usize::from(j[k]).min(last)] * w[k]);
                Some(model.transform_point3(m.transform_point3(*p)))
            })
            .min_by(|a, b| a.y.total_cmp(&b.y))
    }
}

/// Gives each foot its paw, the vertices of `mesh` whose largest weight is on
/// the foot joint or a joint below it, and measures the planted heights from
/// the paws' lowest vertices instead of the joints (so a paw that points its
/// toes down in a run still stands on the ground, not in it).
pub fn attach_paws(feet: &mut [Foot], skeleton: &Skeleton, clips: &[Clip], mesh: &SkinnedMesh) {
    for foot in feet.iter_mut() {
        foot.paw = mesh
            .weights
            .iter()
            .zip(&mesh.joints)
            .enumerate()
            .filter_map(|(v, (w, j))| {
                let k = (0..4).max_by(|&a, &b| w[a].total_cmp(&w[b]))?;
                let node = *skeleton.joints.get(usize::from(j[k]))?;
                (node == foot.node || is_ancestor(skeleton, foot.node, node)).then_some(v as u32)
            })
            .collect();
        if foot.paw.is_empty() {
            continue;
        }
        foot.planted_height = clips
            .iter()
            .map(|clip| {
                (0..48)
                    .map(|s| {
                        let globals = skeleton.globals(&clip.sample(skeleton, clip.duration * s as f32 / 48.0, true));
                        foot.lowest_point(mesh, &skeleton.joint_matrices(&globals), Mat4::IDENTITY).map_or(0.0, |p| p.y)
                    })
                    .fold(f32::MAX, f32::min)
            })
            .collect();
    }
}

/// Finds the feet of `skeleton`: joints whose names contain one of `patterns`
/// and that have no child joint matching them too (the last bone of each
/// leg), with their planted height from `clips` (model units).
#[must_use]
pub fn find_feet(skeleton: &Skeleton, clips: &[Clip], patterns: &[&str]) -> Vec<Foot> {
    let pats: Vec<String> = patterns.iter().map(|p| p.to_ascii_lowercase()).collect();
    let matches = |k: usize| {
        let n = skeleton.nodes[k].name.to_ascii_lowercase();
        skeleton.joints.contains(&k) && pats.iter().any(|p| n.contains(p.as_str()))
    };
    let candidates: Vec<usize> = (0..skeleton.nodes.len()).filter(|&k| matches(k)).collect();
    let leaves: Vec<usize> = candidates.iter().copied().filter(|&k| !candidates.iter().any(|&c| c != k && is_ancestor(skeleton, k, c))).collect();
    leaves
        .into_iter()
        .map(|node| {
            let planted_height = clips
                .iter()
                .map(|clip| {
                    (0..48).map(|s| skeleton.globals(&clip.sample(skeleton, clip.duration * s as f32 / 48.0, true))[node].w_axis.y).fold(f32::MAX, f32::min)
                })
                .collect();
            Foot { node, name: skeleton.nodes[node].name.clone(), planted_height, paw: Vec::new() }
        })
        .collect()
}

/// The speed (model units per second, along the model's +z) at which `clip`
/// must travel for its planted feet not to slide: the mean backward speed of
/// each foot while it is within 15% of its lift above its lowest. Locomotion
/// plays a clip at `travel speed / stride speed` so paws stay put in stance.
#[must_use]
pub fn stride_speed(skeleton: &Skeleton, clip: &Clip, feet: &[Foot]) -> f32 {
    if clip.duration <= 0.0 || feet.is_empty() {
        return 0.0;
    }
    let dt = clip.duration / CYCLE_SAMPLES as f32;
    let (mut sum, mut count) = (0.0f32, 0u32);
    for track in foot_tracks(skeleton, clip, feet) {
        let (lo, hi) = track.iter().fold((f32::MAX, f32::MIN), |(a, b), p| (a.min(p.y), b.max(p.y)));
        let planted = lo + 0.15 * (hi - lo);
        for s in 0..CYCLE_SAMPLES {
            let (a, b) = (track[s], track[(s + 1) % CYCLE_SAMPLES]);
            if a.y <= planted && b.y <= planted {
                sum += (a.z - b.z) / dt;
                count += 1;
            }
        }
    }
    if count == 0 { 0.0 } else { sum / count as f32 }
}

/// Samples over one cycle of a clip for the gait measures.
const CYCLE_SAMPLES: usize = 96;

/// Each foot joint's model-space position at [`CYCLE_SAMPLES`] even steps over `clip`.
fn foot_tracks(skeleton: &Skeleton, clip: &Clip, feet: &[Foot]) -> Vec<Vec<Vec3>> {
    let dt = clip.duration / CYCLE_SAMPLES as f32;
    let poses: Vec<Vec<Mat4>> = (0..CYCLE_SAMPLES).map(|s| skeleton.globals(&clip.sample(skeleton, dt * s as f32, true))).collect();
    feet.iter().map(|foot| poses.iter().map(|g| g[foot.node].w_axis.truncate()).collect()).collect()
}

/// How many of `feet` are down on average over `clip`'s cycle: each foot
/// counts while it is within 35% of its lift above its lowest (a paw rolls
/// from heel to toe while it is down). The fox's walk has 2.4 paws down (a
/// duty factor of 0.6), its run 1.8; the load model shares the weight among
/// this many.
#[must_use]
pub fn mean_feet_down(skeleton: &Skeleton, clip: &Clip, feet: &[Foot]) -> f32 {
    if clip.duration <= 0.0 || feet.is_empty() {
        return feet.len() as f32;
    }
    let mut down = 0usize;
    for track in foot_tracks(skeleton, clip, feet) {
        let (lo, hi) = track.iter().fold((f32::MAX, f32::MIN), |(a, b), p| (a.min(p.y), b.max(p.y)));
        // A foot that barely moves (standing) is down all the time.
        let band = if hi - lo < 1e-3 { f32::INFINITY } else { lo + 0.35 * (hi - lo) };
        down += track.iter().filter(|p| p.y <= band).count();
    }
    down as f32 / CYCLE_SAMPLES as f32
}

fn is_ancestor(skeleton: &Skeleton, a: usize, mut b: usize) -> bool {
    while let Some(p) = skeleton.nodes[b].parent {
        if p == a {
            return true;
        }
        b = p;
    }
    false
}

/// A foot touched down.
#[derive(Clone, Debug, PartialEq)]
pub struct FootstepEvent {
    /// Index of the actor (scene order).
    pub actor: usize,
    /// Index of the foot among the actor's feet.
    pub foot: usize,
    /// The foot joint's name.
    pub name: String,
    /// Where the sole touched (world, m).
    pub position: Vec3,
    /// Horizontal speed of the actor then (m/s).
    pub speed_m_per_s: f32,
    /// Simulated time (s).
    pub time_s: f32,
    /// Snow depth there (m) from the CPU query, when the caller has one.
    pub snow_depth_m: Option<f32>,
    /// How far the load model sinks the foot into the snow there (m); 0 for
    /// characters not placed on the snow.
    pub sink_m: f32,
}

/// Touchdown detection with hysteresis: a foot is planted when its sole is
/// within `plant_m` of the ground and lifted again above `lift_m`; each
/// lifted → planted transition is one event.
#[derive(Clone, Debug, PartialEq)]
pub struct FootTracker {
    /// Planted below this height of the sole above the ground (m).
    pub plant_m: f32,
    /// Lifted above this height (m).
    pub lift_m: f32,
    planted: Vec<bool>,
}

impl FootTracker {
    /// A tracker for `feet` feet, all taken as planted at the start (no event for the first stance).
    #[must_use]
    pub fn new(feet: usize, plant_m: f32, lift_m: f32) -> Self {
        Self { plant_m, lift_m, planted: vec![true; feet] }
    }

    /// Which feet are down now.
    #[must_use]
    pub fn planted(&self) -> &[bool] {
        &self.planted
    }

    /// Feeds the soles' heights above the ground this frame; returns the feet that touched down.
    pub fn update(&mut self, sole_heights: &[f32]) -> Vec<usize> {
        let mut out = Vec::new();
        for (k, (&h, planted)) in sole_heights.iter().zip(&mut self.planted).enumerate() {
            if *planted && h > self.lift_m {
                *planted = false;
            } else if !*planted && h < self.plant_m {
                *planted = true;
                out.push(k);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_lift_and_plant_is_one_event() {
        let mut t = FootTracker::new(2, 0.01, 0.03);
        // Foot 0 lifts to 5 cm and comes down twice; foot 1 jitters below the lift threshold.
        let heights = [0.0, 0.02, 0.05, 0.02, 0.005, 0.0, 0.04, 0.0, 0.0];
        let mut events = Vec::new();
        for (f, h) in heights.iter().enumerate() {
            let jitter = if f % 2 == 0 { 0.0 } else { 0.025 };
            events.extend(t.update(&[*h, jitter]).into_iter().map(|k| (f, k)));
        }
        assert_eq!(events, vec![(4, 0), (7, 0)]);
    }
}
