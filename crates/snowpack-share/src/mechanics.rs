//! Snow with mass: how dense a column of snow is after presses, how hard it
//! is, how far a load sinks into it and what pressing it costs
//! (`docs/mechanics.md` in the repository has the model and its sources).
//!
//! A texel's column is its height above the terrain `h` and its *packed
//! snow* `q`: metres of fresh snow squeezed into the column by presses. The
//! column holds `ρ0 (h + q)` kilograms a square metre, `ρ0` the density of
//! fresh snow, so its density is `ρ0 (1 + q / h)`:
//!
//! - a press from `h` to `h − Δ` adds `Δ` to `q` (the mass stays);
//! - refill and snowfall add fresh snow on top: `h` grows, `q` does not;
//! - `q` never grows past `(ρmax / ρ0 − 1) h`, the column at the final
//!   density `ρmax`; what a press squeezes beyond that is displaced (Richmond
//!   1995, CRREL Report 95-7: snow under a wheel compacts to a final density
//!   of 500 kg/m³ for contact pressures up to 210 kPa, so a rut is
//!   `h (1 − ρ0 / ρf)` deep).
//!
//! Pure compaction only ever raises the deficit and `q` together, so copies
//! of a tile merge by taking the larger of each, as the deficit alone did.
//!
//! Sinkage is Bekker's pressure–sinkage law `p = k z^n` with
//! `k = kc / b + kφ` of snow from Wong's *Theory of Ground Vehicles*
//! (Table 2.3, "Snow (U.S.)": `n = 1.6`, `kc = 4.37 kN/m^(n+1)`,
//! `kφ = 196.72 kN/m^(n+2)`), scaled by the fresh snow's penetration
//! hardness. A packed column reloads: it holds the pressure that packed it
//! and gives way only beyond, along the same curve (Wong's repetitive
//! loading, its elastic part left out). So its hardness grows with its
//! density, a second walk or wheel in a trail sinks less than the first
//! (not at all under the same load), and nothing sinks past the final
//! density. A wheel's compaction resistance is Bekker's `b ∫ k z^n dz`,
//! the work of pressing its rut per metre rolled.

/// Standard gravity (m/s²).
#[cfg_attr(not(feature = "low_level"), doc(hidden))]
pub const GRAVITY: f32 = 9.81;

/// Bekker's pressure–sinkage parameters of a snow: `p = (kc / b + kφ) z^n`
/// for a plate of width `b` (m), pressure in Pa. Hidden from the docs
/// without `low_level`: a game sets the snow by its hardness.
#[cfg_attr(not(feature = "low_level"), doc(hidden))]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bekker {
    /// Sinkage exponent.
    pub n: f32,
    /// Cohesive modulus (N/m^(n+1)).
    pub kc: f32,
    /// Frictional modulus (N/m^(n+2)).
    pub kphi: f32,
}

impl Bekker {
    /// Wong, *Theory of Ground Vehicles*, Table 2.3, "Snow (U.S.)".
    pub const SNOW_US: Self = Self { n: 1.6, kc: 4_370.0, kphi: 196_720.0 };

    /// The modulus `kc / b + kφ` for a plate `width_m` wide.
    #[must_use]
    pub fn modulus(&self, width_m: f32) -> f32 {
        self.kc / width_m.max(1e-3) + self.kphi
    }
}

/// Width (m) and sinkage (m) of the plate test that defines
/// [`SnowMechanics::hardness_kpa`]: the pressure that sinks a 10 cm plate
/// 10 cm.
#[cfg_attr(not(feature = "low_level"), doc(hidden))]
pub const HARDNESS_PLATE_M: f32 = 0.1;

/// The snow's mechanics: its densities, its hardness when fresh, and the
/// pressure–sinkage curve it follows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SnowMechanics {
    /// Density of fresh snow: the initial cover, refill and snowfall (kg/m³).
    pub fresh_density_kg_m3: f32,
    /// Density at which snow stops compacting (kg/m³); a press beyond it
    /// displaces snow instead.
    pub max_density_kg_m3: f32,
    /// Penetration hardness of fresh snow (kPa): the pressure that sinks a
    /// 10 cm plate 10 cm into it ([`HARDNESS_PLATE_M`]).
    pub hardness_kpa: f32,
    /// The shape of the pressure–sinkage curve (its exponent and the ratio
    /// of its moduli); its scale is set by the hardness.
    #[cfg_attr(not(feature = "low_level"), doc(hidden))]
    pub bekker: Bekker,
}

impl Default for SnowMechanics {
    /// Fresh snow of 100 kg/m³ that packs to 500 kg/m³, 10 kPa hard, on Wong's "Snow (U.S.)" curve.
    fn default() -> Self {
        Self { fresh_density_kg_m3: 100.0, max_density_kg_m3: 500.0, hardness_kpa: 10.0, bekker: Bekker::SNOW_US }
    }
}

/// One texel's column of snow: how high it stands above the terrain and how
/// much fresh snow presses have squeezed into it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SnowColumn {
    /// Height of the snow above the terrain (m).
    pub depth_m: f32,
    /// Fresh snow squeezed into the column by presses (m of fresh snow).
    pub packed_m: f32,
}

impl SnowColumn {
    /// An untouched column of fresh snow `depth_m` deep.
    #[must_use]
    pub fn fresh(depth_m: f32) -> Self {
        Self { depth_m: depth_m.max(0.0), packed_m: 0.0 }
    }
}

impl SnowMechanics {
    /// `ρmax / ρ0 − 1`: the most packed snow a column holds per metre of its height.
    #[must_use]
    #[cfg_attr(not(feature = "low_level"), doc(hidden))]
    pub fn pack_ratio(&self) -> f32 {
        (self.max_density_kg_m3 / self.fresh_density_kg_m3.max(1e-3) - 1.0).max(0.0)
    }

    /// Mass of a column (kg/m²): `ρ0 (h + q)`.
    #[must_use]
    pub fn mass_kg_m2(&self, column: SnowColumn) -> f32 {
        self.fresh_density_kg_m3 * (column.depth_m.max(0.0) + column.packed_m.max(0.0))
    }

    /// Mean density of a column (kg/m³): `ρ0 (1 + q / h)`, at most `ρmax`;
    /// fresh snow's where there is no snow.
    #[must_use]
    pub fn density_kg_m3(&self, column: SnowColumn) -> f32 {
        if column.depth_m <= 1e-6 {
            return self.fresh_density_kg_m3;
        }
        (self.fresh_density_kg_m3 * (1.0 + column.packed_m.max(0.0) / column.depth_m)).min(self.max_density_kg_m3.max(self.fresh_density_kg_m3))
    }

    /// Bekker's modulus `k` (N/m^(n+2)) of fresh snow for a plate `width_m`
    /// wide: the curve's `kc / b + kφ`, scaled so that a 10 cm plate meets
    /// the fresh snow's hardness at 10 cm.
    #[must_use]
    #[cfg_attr(not(feature = "low_level"), doc(hidden))]
    pub fn modulus(&self, width_m: f32) -> f32 {
        let b = &self.bekker;
        let at_plate = b.modulus(HARDNESS_PLATE_M) * HARDNESS_PLATE_M.powf(b.n);
        b.modulus(width_m) * self.hardness_kpa.max(0.0) * 1000.0 / at_plate
    }

    /// Penetration hardness (kPa) of `column`: the pressure that sinks a
    /// 10 cm plate 10 cm further into it. A column packed by `q` reloads to
    /// the pressure that packed it before it gives way again, so this is
    /// Bekker's curve at `q + 10 cm`: the fresh snow's hardness where
    /// untouched, growing as the column packs (2.6 times at 7.5 cm packed,
    /// 10 times at 32 cm, with Wong's `n = 1.6`).
    #[must_use]
    pub fn hardness_kpa(&self, column: SnowColumn) -> f32 {
        self.modulus(HARDNESS_PLATE_M) * (column.packed_m.max(0.0) + HARDNESS_PLATE_M).powf(self.bekker.n) / 1000.0
    }

    /// How far the column can still be pressed (m) before it reaches `ρmax`:
    /// `h − ρ0 (h + q) / ρmax`.
    #[must_use]
    #[cfg_attr(not(feature = "low_level"), doc(hidden))]
    pub fn compactable_m(&self, column: SnowColumn) -> f32 {
        let packed_height = self.mass_kg_m2(column) / self.max_density_kg_m3.max(1e-3);
        (column.depth_m - packed_height).max(0.0)
    }

    /// The column before its presses: as much snow at fresh density,
    /// `h + q` deep.
    #[must_use]
    fn unpressed(&self, column: SnowColumn) -> SnowColumn {
        SnowColumn::fresh(column.depth_m.max(0.0) + column.packed_m.max(0.0))
    }

    /// Sinkage (m) of a plate `width_m` wide pressing `pressure_pa` into
    /// `column`. On fresh snow, Bekker's `z = (p / k)^(1/n)`; a column packed
    /// by `q` first holds what packed it, so a load sinks `z − q` further
    /// (Wong's reloading, with its small elastic part left out): a second
    /// walk in a print sinks less than the first, and a load no heavier than
    /// the one that made it not at all. At most what the column can compact.
    #[must_use]
    pub fn plate_sinkage_m(&self, pressure_pa: f32, width_m: f32, column: SnowColumn) -> f32 {
        let k = self.modulus(width_m);
        if pressure_pa <= 0.0 || k <= 0.0 || column.depth_m <= 0.0 {
            return 0.0;
        }
        ((pressure_pa / k).powf(1.0 / self.bekker.n) - column.packed_m.max(0.0)).clamp(0.0, self.compactable_m(column))
    }

    /// The column after a press `sinkage_m` deep: lower by as much, holding
    /// the snow it lost as packed snow, up to `ρmax`. Also returns the snow
    /// (m of fresh snow) the press displaced beyond that.
    #[must_use]
    #[cfg_attr(not(feature = "low_level"), doc(hidden))]
    pub fn pressed(&self, column: SnowColumn, sinkage_m: f32) -> (SnowColumn, f32) {
        let z = sinkage_m.clamp(0.0, column.depth_m.max(0.0));
        let depth_m = column.depth_m - z;
        let packed = column.packed_m + z;
        let cap = self.pack_ratio() * depth_m;
        (SnowColumn { depth_m, packed_m: packed.min(cap) }, (packed - cap).max(0.0))
    }

    /// Sinkage (m) of a rigid wheel into `column`. On the column as it was
    /// before its presses, the wheel's load over its contact patch (chord
    /// `2 √(2 r z − z²)` times its width) is the pressure, and the total
    /// sinkage is where Bekker's curve holds it (bisection); the wheel sinks
    /// that less what the column is already packed, so a wheel in its own
    /// rut sinks no further. At most what the column can compact.
    #[must_use]
    pub fn wheel_sinkage_m(&self, wheel: &WheelContact, column: SnowColumn) -> f32 {
        let virgin = self.unpressed(column);
        let most = self.compactable_m(virgin);
        if most <= 0.0 || wheel.load_kg <= 0.0 {
            return 0.0;
        }
        // f(z) = z − sinkage(p(z)) rises from below 0 at z = 0 to above 0 at z = most.
        let (mut lo, mut hi) = (0.0_f32, most);
        for _ in 0..48 {
            let mid = 0.5 * (lo + hi);
            if mid < self.plate_sinkage_m(wheel.pressure_pa(mid), wheel.width_m, virgin) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        (0.5 * (lo + hi) - column.packed_m.max(0.0)).clamp(0.0, self.compactable_m(column))
    }

    /// Bekker's compaction resistance (N) of a wheel rolling through
    /// `column`: the work of pressing its rut per metre rolled, `b k (Z^(n+1)
    /// − q^(n+1)) / (n + 1)` from the column's packed `q` to the wheel's
    /// total sinkage `Z`. None in its own rut.
    #[must_use]
    pub fn wheel_resistance_n(&self, wheel: &WheelContact, column: SnowColumn) -> f32 {
        let q = column.packed_m.max(0.0);
        let z = q + self.wheel_sinkage_m(wheel, column);
        let n = self.bekker.n;
        wheel.width_m * self.modulus(wheel.width_m) * (z.powf(n + 1.0) - q.powf(n + 1.0)) / (n + 1.0)
    }

    /// Checks every value; the error names the offending field and says why.
    ///
    /// # Errors
    /// The first field that is not finite and positive, or a maximum
    /// density below the fresh one.
    #[cfg_attr(not(feature = "low_level"), doc(hidden))]
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        for (field, v) in [("density_kg_m3", self.fresh_density_kg_m3), ("max_density_kg_m3", self.max_density_kg_m3), ("hardness_kpa", self.hardness_kpa)] {
            if !(v.is_finite() && v > 0.0) {
                return Err((field, format!("{v} must be a positive number")));
            }
        }
        if self.max_density_kg_m3 < self.fresh_density_kg_m3 {
            return Err(("max_density_kg_m3", format!("{} is below the fresh density {}", self.max_density_kg_m3, self.fresh_density_kg_m3)));
        }
        if self.max_density_kg_m3 > ICE_DENSITY_KG_M3 {
            return Err(("max_density_kg_m3", format!("{} is denser than ice ({ICE_DENSITY_KG_M3})", self.max_density_kg_m3)));
        }
        Ok(())
    }
}

/// Density of ice (kg/m³): no snow packs denser.
#[cfg_attr(not(feature = "low_level"), doc(hidden))]
pub const ICE_DENSITY_KG_M3: f32 = 917.0;

/// A rigid wheel meeting the snow: the load it carries and its size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WheelContact {
    /// Mass resting on this wheel (kg).
    pub load_kg: f32,
    /// Outer radius (m).
    pub radius_m: f32,
    /// Width of the tyre (m).
    pub width_m: f32,
}

impl WheelContact {
    /// Length of the contact patch (m) at sinkage `z_m`: the chord `2 √(2 r z − z²)`.
    #[must_use]
    #[cfg_attr(not(feature = "low_level"), doc(hidden))]
    pub fn patch_length_m(&self, z_m: f32) -> f32 {
        let (r, z) = (self.radius_m.max(1e-6), z_m.max(0.0));
        if z >= r { 2.0 * r } else { 2.0 * (2.0 * r * z - z * z).sqrt() }
    }

    /// Pressure under the wheel (Pa) at sinkage `z_m`.
    #[must_use]
    #[cfg_attr(not(feature = "low_level"), doc(hidden))]
    pub fn pressure_pa(&self, z_m: f32) -> f32 {
        self.load_kg.max(0.0) * GRAVITY / (self.patch_length_m(z_m) * self.width_m.max(1e-6)).max(1e-9)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FOX_PRESSURE_PA: f32 = 6.0 * GRAVITY / (2.5 * 0.0035);
    const FOX_SOLE_M: f32 = 0.067;

    #[test]
    fn a_press_keeps_the_mass_until_the_final_density_then_displaces() {
        let m = SnowMechanics::default();
        let fresh = SnowColumn::fresh(0.5);
        let (after, displaced) = m.pressed(fresh, 0.3);
        assert!((m.mass_kg_m2(after) - m.mass_kg_m2(fresh)).abs() < 1e-3 && displaced == 0.0);
        assert!((m.density_kg_m3(after) - 250.0).abs() < 0.1, "{after:?}");
        // 0.5 m at 100 kg/m³ packs into 0.1 m at 500: deeper than 0.4 displaces.
        assert!((m.compactable_m(fresh) - 0.4).abs() < 1e-6);
        let (deep, displaced) = m.pressed(fresh, 0.45);
        assert!((m.density_kg_m3(deep) - 500.0).abs() < 0.1 && (displaced - 0.25).abs() < 1e-5, "{deep:?} {displaced}");
        assert!((m.mass_kg_m2(deep) + displaced * 100.0 - 50.0).abs() < 1e-3);
    }

    #[test]
    fn hardness_grows_as_the_column_packs_and_the_plate_test_holds() {
        let m = SnowMechanics::default();
        assert!((m.hardness_kpa(SnowColumn::fresh(0.5)) - 10.0).abs() < 1e-3);
        // The defining plate test: a 10 cm plate at the hardness sinks 10 cm into deep fresh snow.
        let deep = SnowColumn::fresh(10.0);
        assert!((m.plate_sinkage_m(10_000.0, 0.1, deep) - 0.1).abs() < 1e-4);
        let (packed, _) = m.pressed(SnowColumn::fresh(0.5), 0.2);
        assert!(m.density_kg_m3(packed) > 160.0 && m.hardness_kpa(packed) > 5.0 * m.hardness_kpa(SnowColumn::fresh(0.5)));
    }

    #[test]
    fn a_second_walk_in_a_packed_trail_sinks_less() {
        let m = SnowMechanics::default();
        let fresh = SnowColumn::fresh(0.5);
        let first = m.plate_sinkage_m(FOX_PRESSURE_PA, FOX_SOLE_M, fresh);
        let (print, _) = m.pressed(fresh, first);
        // The same load in its print: no further; a heavier one only the difference.
        assert!(first > 0.03 && first < 0.4, "{first}");
        assert_eq!(m.plate_sinkage_m(FOX_PRESSURE_PA, FOX_SOLE_M, print), 0.0);
        let heavier = m.plate_sinkage_m(2.0 * FOX_PRESSURE_PA, FOX_SOLE_M, print);
        let heavier_fresh = m.plate_sinkage_m(2.0 * FOX_PRESSURE_PA, FOX_SOLE_M, fresh);
        assert!((heavier - (heavier_fresh - first)).abs() < 1e-5 && heavier > 0.0, "{heavier} {heavier_fresh}");
        // A print half refilled with fresh snow is deeper than the print, packed below.
        let refilled = SnowColumn { depth_m: print.depth_m + 0.5 * first, ..print };
        assert!(m.density_kg_m3(refilled) > m.fresh_density_kg_m3 && m.density_kg_m3(refilled) < m.density_kg_m3(print));
        // Softer snow, or more pressure, sinks deeper; never past the final density.
        assert!(SnowMechanics { hardness_kpa: 2.0, ..m }.plate_sinkage_m(FOX_PRESSURE_PA, FOX_SOLE_M, fresh) > first);
        assert!(m.plate_sinkage_m(1e9, FOX_SOLE_M, fresh) <= m.compactable_m(fresh) + 1e-6);
    }

    #[test]
    fn a_wheel_in_its_own_rut_sinks_and_costs_nothing_more() {
        let m = SnowMechanics::default();
        let car = WheelContact { load_kg: 375.0, radius_m: 0.32, width_m: 0.2 };
        let fresh = SnowColumn::fresh(0.4);
        let z = m.wheel_sinkage_m(&car, fresh);
        // The root: the snow holds the wheel's pressure at that sinkage.
        assert!(z > 0.01 && z < 0.4 && (m.plate_sinkage_m(car.pressure_pa(z), 0.2, fresh) - z).abs() < 1e-4, "{z}");
        let r = m.wheel_resistance_n(&car, fresh);
        let (rut, _) = m.pressed(fresh, z);
        assert!(m.wheel_sinkage_m(&car, rut) < 1e-4 && m.wheel_resistance_n(&car, rut) < 1e-3 * r && r > 1.0, "{z} {r}");
        // A truck in the car's rut sinks and costs less than in fresh snow.
        let truck = WheelContact { load_kg: 1500.0, ..car };
        let (zt, rt) = (m.wheel_sinkage_m(&truck, fresh), m.wheel_resistance_n(&truck, fresh));
        assert!(zt > z && rt > r);
        let (zt_rut, rt_rut) = (m.wheel_sinkage_m(&truck, rut), m.wheel_resistance_n(&truck, rut));
        assert!(zt_rut < zt && rt_rut < rt && (zt_rut - (zt - z)).abs() < 1e-3, "{zt} {zt_rut}");
    }

    #[test]
    fn bad_values_name_their_field() {
        let m = SnowMechanics::default();
        assert_eq!(SnowMechanics { fresh_density_kg_m3: 0.0, ..m }.validate().unwrap_err().0, "density_kg_m3");
        assert_eq!(SnowMechanics { max_density_kg_m3: 50.0, ..m }.validate().unwrap_err().0, "max_density_kg_m3");
        assert_eq!(SnowMechanics { max_density_kg_m3: 1000.0, ..m }.validate().unwrap_err().0, "max_density_kg_m3");
        assert_eq!(SnowMechanics { hardness_kpa: f32::NAN, ..m }.validate().unwrap_err().0, "hardness_kpa");
        assert!(m.validate().is_ok());
    }
}
