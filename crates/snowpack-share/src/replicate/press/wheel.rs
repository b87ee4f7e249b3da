//! Wheels (snowpack's `Deformer::Wheel`): a tyre with a tread, rolling about its axle.
//!
//! The tyre is a cylinder of the outer radius `r` (lugs included) and width
//! `2 half_width` around the axle; the tread is a pattern over its surface in
//! the coordinates `(s, u)`: `s` the arc length around the tyre at the outer
//! radius, `u` across it (−1 to 1 from one side to the other). Where the
//! pattern has a lug the surface is at `r`, elsewhere (the tyre's grooves) at
//! `r − depth_m`, so raised lugs press grooves into the floor of the rut and
//! the snow between them stays as ridges.
//!
//! The arc coordinate of a point on the tyre at angle θ ahead of its lowest
//! point (towards [`forward`]) is `s = roll_m + r θ`: rolling without slip a
//! distance `D` turns the tyre by `D / r`, so `roll_m` grows by `D` and the
//! tread touching the snow stays where it touched, whatever the frame rate.
//! With slip the tread turns `1 + slip` times as fast (`slip = −1`: a locked
//! wheel sliding): the contact moves over the snow and the sub-steps of the
//! sweep smear the pattern along the rut.
//!
//! The capture ray casts one tyre per sub-step (`shared/capture_shapes.wgsl`,
//! [`super::cast::wheel_bottom`] on the CPU); the sub-steps are spaced so
//! that neither the tyre nor its tread at the contact moves more than
//! [`super::sweep::SWEEP_STEP_TEXELS`] texels between them.

use glam::Vec3;

/// The procedural tread patterns.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub enum TreadPattern {
    /// A slick tyre: the whole surface at the outer radius.
    None,
    /// Two rows of blocks across the tyre, staggered by half a spacing.
    #[default]
    Blocks,
    /// Lugs in a V across the tyre (45 degrees each side of the centre line).
    Chevron,
}

impl TreadPattern {
    /// Every pattern and its name in scene files.
    pub const ALL: [(Self, &'static str); 3] = [(Self::None, "none"), (Self::Blocks, "blocks"), (Self::Chevron, "chevron")];

    /// The name in scene files.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        Self::ALL.iter().find(|(p, _)| *p == self).map_or("blocks", |(_, s)| s)
    }

    /// The pattern with this name.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().find(|(_, s)| *s == name).map(|(p, _)| *p)
    }

    /// The code the shader switches on.
    #[must_use]
    pub fn code(self) -> f32 {
        match self {
            Self::None => 0.0,
            Self::Blocks => 1.0,
            Self::Chevron => 2.0,
        }
    }
}

/// A tyre's tread.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tread {
    /// The pattern.
    pub pattern: TreadPattern,
    /// Distance between consecutive lugs around the tyre (m).
    pub spacing_m: f32,
    /// How far the lugs stand out of the tyre (m).
    pub depth_m: f32,
    /// Fraction of each spacing that is lug (0 to 1).
    pub lug_fraction: f32,
}

impl Default for Tread {
    /// Blocks 12 cm apart, 2 cm deep, 40 % lug.
    fn default() -> Self {
        Self { pattern: TreadPattern::Blocks, spacing_m: 0.12, depth_m: 0.02, lug_fraction: 0.4 }
    }
}

impl Tread {
    /// A slick tyre.
    pub const NONE: Self = Self { pattern: TreadPattern::None, spacing_m: 1.0, depth_m: 0.0, lug_fraction: 1.0 };
}

/// The direction a wheel with this axle rolls to as its roll grows:
/// `axle x up`, horizontal (zero for a vertical axle).
#[must_use]
pub fn forward(axle: Vec3) -> Vec3 {
    axle.cross(Vec3::Y).normalize_or_zero()
}

/// How far a wheel's surface reaches below its centre (m): the support
/// function of the cylinder in −Y.
#[must_use]
pub fn extent_below(axle: Vec3, radius: f32, half_width: f32) -> f32 {
    let ay = axle.normalize_or_zero().y.abs();
    radius * (1.0 - ay * ay).max(0.0).sqrt() + half_width * ay
}

/// One pose of a wheel: (centre, axle, roll).
pub type WheelPose = (Vec3, Vec3, f32);

/// How far anything that matters moves between two poses of a wheel of
/// radius `r` and half width `w` (m): the centre, plus the rim from turning
/// the axle, plus the tread sliding at the contact (the roll that the
/// centre's forward motion does not account for: slip).
#[must_use]
pub fn wheel_travel(a: WheelPose, b: WheelPose, r: f32, w: f32) -> f32 {
    let moved = b.0 - a.0;
    let rolled = b.2 - a.2;
    let slide = rolled - moved.dot(forward(a.1.lerp(b.1, 0.5)));
    moved.length() + (b.1 - a.1).length() * (r + w) + slide.abs()
}

/// The poses a wheel swept from `a` to `b` is drawn in: `a`, then `steps`
/// evenly spaced poses up to and including `b`; centre and roll linear, the
/// axle normalised linear.
#[cfg(test)]
#[must_use]
pub fn wheel_poses(a: WheelPose, b: WheelPose, steps: u32) -> Vec<WheelPose> {
    (0..=steps.max(1)).map(|k| wheel_pose(a, b, k, steps)).collect()
}

/// Pose `k` (0 ..= `steps`, 0 being `a`) of the poses a wheel swept from `a` to `b` is drawn in (`wheel_poses` in the tests).
#[must_use]
pub fn wheel_pose(a: WheelPose, b: WheelPose, k: u32, steps: u32) -> WheelPose {
    let t = k as f32 / steps.max(1) as f32;
    (a.0.lerp(b.0, t), a.1.lerp(b.1, t).normalize_or(b.1), a.2 + (b.2 - a.2) * t)
}

/// The capture's instance of one wheel pose (`capture_shapes.wgsl`):
/// `[cx, cy, cz, r, ax, ay, az, half_width, roll, spacing, depth, pattern,
/// lug_fraction, 0, 0, 0]`, the centre window-local (x, z relative to the
/// window's corner). The roll is reduced modulo the spacing (in f64) so that
/// f32 keeps its precision after any distance.
#[must_use]
pub fn instance(center_local: Vec3, axle: Vec3, radius: f32, half_width: f32, tread: &Tread, roll_m: f64) -> [f32; 16] {
    let a = axle.normalize_or(Vec3::X);
    let spacing = tread.spacing_m.max(1e-4);
    let roll = roll_m.rem_euclid(f64::from(spacing)) as f32;
    [
        center_local.x,
        center_local.y,
        center_local.z,
        radius,
        a.x,
        a.y,
        a.z,
        half_width,
        roll,
        spacing,
        tread.depth_m.clamp(0.0, radius),
        tread.pattern.code(),
        tread.lug_fraction.clamp(0.0, 1.0),
        0.0,
        0.0,
        0.0,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forward_is_axle_cross_up_and_the_extent_below_is_the_radius_for_a_level_axle() {
        assert!((forward(Vec3::X) - Vec3::Z).length() < 1e-6);
        assert!((forward(Vec3::Z) + Vec3::X).length() < 1e-6);
        assert!((extent_below(Vec3::X, 0.3, 0.1) - 0.3).abs() < 1e-6);
        assert!((extent_below(Vec3::Y, 0.3, 0.1) - 0.1).abs() < 1e-6);
    }

    #[test]
    fn rolling_without_slip_travels_only_the_centre() {
        let a = (Vec3::ZERO, Vec3::X, 0.0);
        let b = (Vec3::new(0.0, 0.0, 0.5), Vec3::X, 0.5);
        assert!((wheel_travel(a, b, 0.3, 0.1) - 0.5).abs() < 1e-6);
        // Spinning in place (slip): the tread slides 0.2 m over the snow.
        assert!((wheel_travel(a, (Vec3::ZERO, Vec3::X, 0.2), 0.3, 0.1) - 0.2).abs() < 1e-6);
        let poses = wheel_poses(a, b, 4);
        assert_eq!(poses.len(), 5);
        assert!((poses[2].2 - 0.25).abs() < 1e-6);
    }

    #[test]
    fn instance_roll_is_reduced_to_one_spacing() {
        let t = Tread::default();
        let i = instance(Vec3::ZERO, Vec3::X, 0.3, 0.1, &t, 1200.05);
        assert!((i[8] - 0.05).abs() < 1e-4, "{}", i[8]);
    }
}
