//! Feet of a character: which joints touch the ground, and footstep events
//! when one touches down (for sounds, particles and gameplay).

use glam::Vec3;

use super::{Clip, Skeleton};

/// Joint-name patterns that mark feet when none are given (case-insensitive).
pub const DEFAULT_FOOT_PATTERNS: [&str; 4] = ["foot", "hand", "paw", "toe"];

/// One foot: its joint and its height when planted.
#[derive(Clone, Debug, PartialEq)]
pub struct Foot {
    /// Node index of the foot joint.
    pub node: usize,
    /// The joint's name.
    pub name: String,
    /// Height of the joint above the sole when planted (model units), per
    /// clip: its lowest over that clip's cycle.
    pub planted_height: Vec<f32>,
}

impl Foot {
    /// Planted height while `clip` plays.
    #[must_use]
    pub fn planted(&self, clip: usize) -> f32 {
        self.planted_height.get(clip).or(self.planted_height.first()).copied().unwrap_or(0.0)
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
    let leaves: Vec<usize> = candidates
        .iter()
        .copied()
        .filter(|&k| !candidates.iter().any(|&c| c != k && is_ancestor(skeleton, k, c)))
        .collect();
    leaves
        .into_iter()
        .map(|node| {
            let planted_height = clips
                .iter()
                .map(|clip| {
                    (0..48)
                        .map(|s| skeleton.globals(&clip.sample(skeleton, clip.duration * s as f32 / 48.0, true))[node].w_axis.y)
                        .fold(f32::MAX, f32::min)
                })
                .collect();
            Foot { node, name: skeleton.nodes[node].name.clone(), planted_height }
        })
        .collect()
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
