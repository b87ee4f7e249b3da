//! How deep a character's feet sink into the snow: a load model.
//!
//! The weight `m g` rests on the feet that are down, `n` of them on average
//! over the gait (see [`crate::skin::feet::mean_feet_down`]), each of area
//! `A`, so the foot pressure is `p = m g / (n A)`. Against a snow of
//! penetration hardness `H` and depth `D` the foot sinks
//!
//! ```text
//! z = D p / (p + H)
//! ```
//!
//! half the depth when `p = H`, almost nothing on a crust (`H >> p`) and
//! almost to the ground in powder (`H << p`), never through it. This is the
//! hyperbolic form of a pressure–sinkage curve (Bekker's `p = k z^n` bounded
//! by the layer's depth): simple enough to tune by eye, monotone in every
//! input, and bounded. Fewer feet down means more pressure: a running fox
//! with one or two paws down sinks deeper than a walking one. The average
//! over the gait, not the count at each instant, sets the depth: snow
//! compacts plastically and does not spring back between steps, and a body
//! that rose and fell with every change of count would bob.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

/// Standard gravity (m/s²).
pub const GRAVITY: f32 = 9.81;

/// What a character weighs and what it stands on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FootLoad {
    /// Mass of the character (kg).
    pub mass_kg: f32,
    /// Area of one foot's sole (m²).
    pub foot_area_m2: f32,
}

impl Default for FootLoad {
    /// A fox: 6 kg on 35 cm² paws (fur included).
    fn default() -> Self {
        Self { mass_kg: 6.0, foot_area_m2: 0.0035 }
    }
}

impl FootLoad {
    /// Pressure under each foot (Pa) with `feet_down` feet sharing the weight
    /// (at least one: a foot touching down takes the whole weight).
    #[must_use]
    pub fn pressure_pa(&self, feet_down: f32) -> f32 {
        self.mass_kg * GRAVITY / (feet_down.max(1.0) * self.foot_area_m2)
    }

    /// How far a foot sinks (m) below the surface of `depth_m` of snow of
    /// `hardness_kpa` with `feet_down` feet down.
    #[must_use]
    pub fn sinkage_m(&self, feet_down: f32, depth_m: f32, hardness_kpa: f32) -> f32 {
        sinkage_m(self.pressure_pa(feet_down), depth_m, hardness_kpa)
    }

    /// Radius of a round sole of this area (m): the footprint the points
    /// technique stamps.
    #[must_use]
    pub fn foot_radius_m(&self) -> f32 {
        (self.foot_area_m2 / std::f32::consts::PI).sqrt()
    }
}

/// Sinkage (m) of a foot pressing `pressure_pa` into `depth_m` of snow of
/// penetration hardness `hardness_kpa`: `D p / (p + H)`; 0 for no snow.
#[must_use]
pub fn sinkage_m(pressure_pa: f32, depth_m: f32, hardness_kpa: f32) -> f32 {
    let p = pressure_pa.max(0.0);
    let h = hardness_kpa.max(1e-6) * 1000.0;
    depth_m.max(0.0) * p / (p + h)
}

/// What a wheel carries and how it meets the snow: the same pressure–sinkage
/// curve as feet, with the contact patch of a rigid wheel.
///
/// A wheel of radius `r` and width `b` sunk `z` into the snow touches it over
/// the chord `l = 2 sqrt(2 r z - z²)` (`2 r` once `z >= r`), an area `l b`;
/// its load `m g` then presses `p(z) = m g / (l b)`. The sinkage is where the
/// snow holds that pressure, `z = D p(z) / (p(z) + H)`: the left side grows
/// with z and the right side shrinks (a deeper wheel spreads its load over a
/// longer patch), so there is one root, found by bisection. A heavier load,
/// a narrower or smaller wheel, or softer snow sinks deeper; never through
/// the layer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WheelLoad {
    /// Mass resting on this wheel (kg): a vehicle's mass over its wheels.
    pub mass_kg: f32,
    /// Outer radius of the wheel (m).
    pub radius_m: f32,
    /// Width of the tyre (m).
    pub width_m: f32,
}

impl WheelLoad {
    /// Length of the contact patch (m) at sinkage `z_m`.
    #[must_use]
    pub fn patch_length_m(&self, z_m: f32) -> f32 {
        let (r, z) = (self.radius_m.max(1e-6), z_m.max(0.0));
        if z >= r { 2.0 * r } else { 2.0 * (2.0 * r * z - z * z).sqrt() }
    }

    /// Pressure under the wheel (Pa) at sinkage `z_m`.
    #[must_use]
    pub fn pressure_pa(&self, z_m: f32) -> f32 {
        self.mass_kg.max(0.0) * GRAVITY / (self.patch_length_m(z_m) * self.width_m.max(1e-6)).max(1e-9)
    }

    /// How far the wheel sinks (m) into `depth_m` of snow of `hardness_kpa`.
    #[must_use]
    pub fn sinkage_m(&self, depth_m: f32, hardness_kpa: f32) -> f32 {
        let depth = depth_m.max(0.0);
        if depth == 0.0 || self.mass_kg <= 0.0 {
            return 0.0;
        }
        // f(z) = z - sinkage(p(z)) rises from below 0 at z = 0 to above 0 at z = depth.
        let (mut lo, mut hi) = (0.0_f32, depth);
        for _ in 0..48 {
            let mid = 0.5 * (lo + hi);
            if mid < sinkage_m(self.pressure_pa(mid), depth, hardness_kpa) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_heavier_or_narrower_wheel_sinks_deeper_and_the_patch_holds_it() {
        let car = WheelLoad { mass_kg: 1500.0 / 4.0, radius_m: 0.32, width_m: 0.2 };
        let truck = WheelLoad { mass_kg: 6000.0 / 4.0, ..car };
        let (z_car, z_truck) = (car.sinkage_m(0.4, 30.0), truck.sinkage_m(0.4, 30.0));
        assert!(z_car > 0.01 && z_truck > z_car + 0.02 && z_truck < 0.4, "{z_car} {z_truck}");
        // The root: the snow holds the pressure at that sinkage.
        assert!((sinkage_m(car.pressure_pa(z_car), 0.4, 30.0) - z_car).abs() < 1e-5);
        let narrow = WheelLoad { width_m: 0.1, ..car };
        assert!(narrow.sinkage_m(0.4, 30.0) > z_car);
        assert!(car.sinkage_m(0.4, 300.0) < z_car, "harder snow");
        assert_eq!(car.sinkage_m(0.0, 30.0), 0.0);
    }

    #[test]
    fn sinkage_is_half_the_depth_at_the_hardness_and_bounded_by_the_depth() {
        assert!((sinkage_m(5000.0, 0.4, 5.0) - 0.2).abs() < 1e-6);
        assert_eq!(sinkage_m(5000.0, 0.0, 5.0), 0.0);
        assert!(sinkage_m(1e9, 0.4, 5.0) < 0.4);
        assert!(sinkage_m(1e9, 0.4, 5.0) > 0.399);
        // Harder snow, shallower prints; fewer feet down, deeper prints.
        let fox = FootLoad::default();
        assert!(fox.sinkage_m(2.0, 0.3, 3.0) > fox.sinkage_m(2.0, 0.3, 30.0));
        assert!(fox.sinkage_m(1.0, 0.3, 10.0) > fox.sinkage_m(4.0, 0.3, 10.0));
        // 6 kg on two 35 cm² paws: 8.4 kPa.
        assert!((fox.pressure_pa(2.0) - 8408.57).abs() < 1.0, "{}", fox.pressure_pa(2.0));
        assert_eq!(fox.pressure_pa(0.0), fox.pressure_pa(1.0));
    }
}
