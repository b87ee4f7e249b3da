//! How deep a character's feet and a vehicle's wheels sink into the snow: a
//! load model on the snow's mechanics ([`snowpack_share::mechanics`],
//! `docs/mechanics.md`).
//!
//! The weight `m g` rests on the feet that are down, `n` of them on average
//! over the gait (see [`crate::skin::feet::mean_feet_down`]), each of area
//! `A`, so the foot pressure is `p = m g / (n A)`. The foot sinks as far as
//! Bekker's pressure–sinkage curve of the column under it says, `z = (p /
//! k(ρ))^(1/n)`, the modulus `k` growing with the column's density: a foot
//! in a packed trail sinks less than in fresh snow, and never further than
//! the column can compact. Fewer feet down means more pressure: a running
//! fox with one or two paws down sinks deeper than a walking one. The
//! average over the gait, not the count at each instant, sets the depth:
//! snow compacts plastically and does not spring back between steps, and a
//! body that rose and fell with every change of count would bob.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

pub use snowpack_share::mechanics::GRAVITY;
use snowpack_share::mechanics::{SnowColumn, SnowMechanics, WheelContact};

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

    /// How far a foot sinks (m) into `column` of snow of `mechanics` with
    /// `feet_down` feet down: Bekker's curve for a plate as wide as the sole.
    #[must_use]
    pub fn sinkage_m(&self, feet_down: f32, mechanics: &SnowMechanics, column: SnowColumn) -> f32 {
        mechanics.plate_sinkage_m(self.pressure_pa(feet_down), self.sole_width_m(), column)
    }

    /// Radius of a round sole of this area (m): the footprint the points
    /// technique stamps.
    #[must_use]
    pub fn foot_radius_m(&self) -> f32 {
        (self.foot_area_m2 / std::f32::consts::PI).sqrt()
    }

    /// Width of the sole (m): the diameter of a round sole of this area,
    /// Bekker's plate width.
    #[must_use]
    pub fn sole_width_m(&self) -> f32 {
        2.0 * self.foot_radius_m()
    }
}

/// What a wheel carries and how it meets the snow: Bekker's curve under the
/// contact patch of a rigid wheel ([`SnowMechanics::wheel_sinkage_m`]).
///
/// A wheel of radius `r` and width `b` sunk `z` into the snow touches it over
/// the chord `l = 2 sqrt(2 r z - z²)` (`2 r` once `z >= r`), an area `l b`;
/// its load `m g` then presses `p(z) = m g / (l b)`, and the sinkage is where
/// the snow holds that pressure. A heavier load, a narrower or smaller
/// wheel, or softer snow sinks deeper; a packed rut less; never past what
/// the column can compact.
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
    /// The wheel as the mechanics see it.
    #[must_use]
    pub fn contact(&self) -> WheelContact {
        WheelContact { load_kg: self.mass_kg, radius_m: self.radius_m, width_m: self.width_m }
    }

    /// Pressure under the wheel (Pa) at sinkage `z_m`.
    #[must_use]
    pub fn pressure_pa(&self, z_m: f32) -> f32 {
        self.contact().pressure_pa(z_m)
    }

    /// How far the wheel sinks (m) into `column` of snow of `mechanics`.
    #[must_use]
    pub fn sinkage_m(&self, mechanics: &SnowMechanics, column: SnowColumn) -> f32 {
        mechanics.wheel_sinkage_m(&self.contact(), column)
    }

    /// Bekker's compaction resistance (N) of the wheel rolling through `column`.
    #[must_use]
    pub fn resistance_n(&self, mechanics: &SnowMechanics, column: SnowColumn) -> f32 {
        mechanics.wheel_resistance_n(&self.contact(), column)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn snow(hardness_kpa: f32) -> SnowMechanics {
        SnowMechanics { hardness_kpa, ..SnowMechanics::default() }
    }

    #[test]
    fn a_heavier_or_narrower_wheel_sinks_deeper_and_a_rut_holds_it() {
        let car = WheelLoad { mass_kg: 1500.0 / 4.0, radius_m: 0.32, width_m: 0.2 };
        let truck = WheelLoad { mass_kg: 6000.0 / 4.0, ..car };
        let fresh = SnowColumn::fresh(0.4);
        let (z_car, z_truck) = (car.sinkage_m(&snow(10.0), fresh), truck.sinkage_m(&snow(10.0), fresh));
        assert!(z_car > 0.01 && z_truck > z_car + 0.01 && z_truck < 0.4, "{z_car} {z_truck}");
        let narrow = WheelLoad { width_m: 0.1, ..car };
        assert!(narrow.sinkage_m(&snow(10.0), fresh) > z_car);
        assert!(car.sinkage_m(&snow(100.0), fresh) < z_car, "harder snow");
        assert_eq!(car.sinkage_m(&snow(10.0), SnowColumn::fresh(0.0)), 0.0);
        let (rut, _) = snow(10.0).pressed(fresh, z_car);
        assert!(car.sinkage_m(&snow(10.0), rut) < 0.5 * z_car && car.resistance_n(&snow(10.0), rut) < car.resistance_n(&snow(10.0), fresh));
    }

    #[test]
    fn harder_snow_shallower_prints_fewer_feet_deeper_prints() {
        let fox = FootLoad::default();
        let fresh = SnowColumn::fresh(0.3);
        assert!(fox.sinkage_m(2.0, &snow(3.0), fresh) > fox.sinkage_m(2.0, &snow(30.0), fresh));
        assert!(fox.sinkage_m(1.0, &snow(10.0), fresh) > fox.sinkage_m(4.0, &snow(10.0), fresh));
        assert!(fox.sinkage_m(1.0, &snow(0.01), fresh) <= snow(0.01).compactable_m(fresh) + 1e-6);
        // 6 kg on two 35 cm² paws: 8.4 kPa.
        assert!((fox.pressure_pa(2.0) - 8408.57).abs() < 1.0, "{}", fox.pressure_pa(2.0));
        assert_eq!(fox.pressure_pa(0.0), fox.pressure_pa(1.0));
    }
}
