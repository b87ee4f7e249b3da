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

#[cfg(test)]
mod tests {
    use super::*;

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
