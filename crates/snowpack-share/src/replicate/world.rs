//! A world's identity: the settings two machines must share for their snow
//! to merge. A peer of another world is refused, naming what differs.

use crate::SNOW_QUANTUM_M;

use super::tile::ShareClock;

low_level_fields! {
    /// The settings that make a world: tiles from machines that agree on all of
    /// them merge; anything else is refused (the relay names each difference).
    #[derive(Clone, Debug, PartialEq)]
    pub struct WorldIdentity {
        /// Side of a texel (m).
        texel_m: f32,
        /// Texels per tile side.
        tile_side: u32,
        /// The terrain, as `terrain_identity` describes it.
        terrain: String,
        /// Rest depth of fresh snow (m).
        depth_m: f32,
        /// Trail refill (m/s).
        refill_m_per_s: f32,
        /// Snowfall on open ground (m/s); 0 without snowfall.
        snowfall_m_per_s: f32,
        /// The most snowfall a texel keeps (m); 0 without snowfall.
        max_fallen_m: f32,
        /// Whether tiles carry the snowfall plane.
        has_snowfall: bool,
        /// The footprint quantisation range (m): low and high.
        stamp_range_m: [f32; 2],
    }
}

impl WorldIdentity {
    low_level_pub! {
        /// The differences between `self` (here) and `other` (there), one
        /// phrase each ("tile side: 32 here, 64 there"); empty when they are
        /// the same world. Floats compare bit for bit.
        #[must_use]
        fn differences(&self, other: &Self) -> Vec<String> {
            let mut out = Vec::new();
            let mut f = |name: &str, a: f32, b: f32| {
                if a.to_bits() != b.to_bits() {
                    out.push(format!("{name}: {a} here, {b} there"));
                }
            };
            f("texel size (m)", self.texel_m, other.texel_m);
            f("snow depth (m)", self.depth_m, other.depth_m);
            f("refill (m/s)", self.refill_m_per_s, other.refill_m_per_s);
            f("snowfall rate (m/s)", self.snowfall_m_per_s, other.snowfall_m_per_s);
            f("most snowfall kept (m)", self.max_fallen_m, other.max_fallen_m);
            f("footprint range low (m)", self.stamp_range_m[0], other.stamp_range_m[0]);
            f("footprint range high (m)", self.stamp_range_m[1], other.stamp_range_m[1]);
            if self.tile_side != other.tile_side {
                out.push(format!("tile side: {} here, {} there", self.tile_side, other.tile_side));
            }
            if self.has_snowfall != other.has_snowfall {
                out.push(format!("snowfall: {} here, {} there", on_off(self.has_snowfall), on_off(other.has_snowfall)));
            }
            if self.terrain != other.terrain {
                out.push(format!("terrain: {} here, {} there", self.terrain, other.terrain));
            }
            out
        }
    }

    low_level_pub! {
        /// The world clock at `time_s` seconds since the world began: the refill
        /// and snowfall every copy of the snow has had by then.
        #[must_use]
        #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
        fn clock_at(&self, time_s: f64) -> ShareClock {
            let t = time_s.max(0.0);
            let refill_m = f64::from(self.refill_m_per_s.max(0.0)) * t;
            let quantum = f64::from(self.stamp_quantum_m());
            ShareClock {
                time_s: t,
                refill_quanta: (refill_m / f64::from(SNOW_QUANTUM_M)).floor() as u64,
                stamp_quanta: if quantum > 0.0 { (refill_m / quantum).floor() as u64 } else { 0 },
                fallen_m: if self.has_snowfall { (f64::from(self.snowfall_m_per_s.max(0.0)) * t).min(f64::from(self.max_fallen_m)) as f32 } else { 0.0 },
            }
        }
    }

    low_level_pub! {
        /// One footprint quantum (m): the range over 65535 steps.
        #[must_use]
        #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
        fn stamp_quantum_m(&self) -> f32 {
            (self.stamp_range_m[1] - self.stamp_range_m[0]) / 65_535.0
        }
    }
}

fn on_off(b: bool) -> &'static str {
    if b { "on" } else { "off" }
}
