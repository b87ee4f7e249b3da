//! Snow the game can feel: [`FeelsSnow`] entities get a [`SnowResistance`]
//! from the snow under them (asked through [`SnowQuery`] like the
//! footsteps): a speed factor for walkers, a rolling resistance for wheels.
//!
//! The snow is asked where the entity's next steps land (see
//! [`FeelsSnow`]). Both figures start from the library's snow with mass
//! (`snowpack::mechanics`, `docs/mechanics.md`): a load sinks into the
//! column under it by Bekker's pressure–sinkage curve of the snow, less
//! what the column is already packed (a packed column holds the load that
//! packed it), so in a trail a walker or a wheel sinks only as far as the
//! load that pressed the trail did not.
//!
//! - Walkers: the terrain coefficient of snow of Richmond, Potter and
//!   Santee (2015, for the Pandolf equation), `η = 0.0005 z³ + 0.0001 z² +
//!   0.1072 z + 1.2604` with `z` the sinkage in cm (firm ground is `η = 1`);
//!   in the Pandolf equation the cost of walking at speed `V` on level
//!   ground grows as `η V²`, so at the same effort the speed scales as
//!   `1 / √η` (our derivation): the speed factor.
//! - Wheels: Bekker's compaction resistance, the work of pressing the rut
//!   per metre rolled, `R = b ∫ k zⁿ dz` over the new sinkage
//!   (`SnowMechanics::wheel_resistance_n`).
//!
//! `docs/bevy.md` ("Snow the game can feel") has the sources and figures.

use bevy::prelude::*;
use snowpack::PointSample;

use crate::deformers::SnowWheel;
use crate::query::{SnowQuery, SnowTicket};
use crate::sinkage::{GRAVITY, terrain_coefficient};
use crate::{SnowSystems, SnowpackSettings};
use snowpack::mechanics::SnowMechanics;

/// Put on a character or a vehicle's wheel that the snow should hold back:
/// the plugin keeps its [`SnowResistance`] up to date (a frame or two
/// behind, like every answer from the snow). On a walker it says what
/// presses the snow under its feet; on an entity with a [`SnowWheel`] the
/// wheel's own load and size are used.
///
/// The snow is asked where the next steps land: `reach_m` ahead of the
/// entity along its motion (and a quarter of that to each side), beyond
/// the footprint it is making now (its own fresh print would read as a
/// trail); the most packed of the three is where it steps. A wheel is
/// asked at least its radius ahead, beyond its contact patch.
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Clone, Debug, PartialEq, Default)]
#[require(Transform, SnowResistance)]
pub struct FeelsSnow {
    /// The walker's mass (kg).
    pub mass_kg: f32,
    /// Area of one foot's sole (m²).
    pub foot_area_m2: f32,
    /// Feet sharing the weight on average over the gait (1 for a person walking,
    /// about 2 for a trotting four-legged animal).
    pub feet_down: f32,
    /// How far ahead of the entity's origin its next steps land (m): beyond its own feet.
    pub reach_m: f32,
    /// Where it was last frame.
    #[reflect(ignore)]
    last: Option<Vec2>,
    /// The direction it last moved in (x, z; zero before it has moved).
    #[reflect(ignore)]
    heading: Vec2,
}

impl Default for FeelsSnow {
    /// A person: 75 kg on a 300 cm² boot sole, one foot at a time, steps landing 0.5 m ahead.
    fn default() -> Self {
        Self::walker(75.0, 0.03)
    }
}

impl FeelsSnow {
    /// A walker of `mass_kg` on feet of `foot_area_m2`, one foot at a time, steps landing 0.5 m ahead.
    #[must_use]
    pub fn walker(mass_kg: f32, foot_area_m2: f32) -> Self {
        Self { mass_kg, foot_area_m2, feet_down: 1.0, reach_m: 0.5, last: None, heading: Vec2::ZERO }
    }

    /// A fox: 6 kg on 35 cm² paws (fur included), two down on average,
    /// the snow asked 0.6 m ahead of its origin (beyond its chest and front
    /// paws, which press the snow in front of its origin).
    #[must_use]
    pub fn fox() -> Self {
        Self { feet_down: 2.0, reach_m: 0.6, ..Self::walker(6.0, 0.0035) }
    }

    /// The same walker with `feet_down` feet sharing its weight.
    #[must_use]
    pub fn with_feet_down(mut self, feet_down: f32) -> Self {
        self.feet_down = feet_down;
        self
    }

    /// The same walker with its steps landing `reach_m` ahead.
    #[must_use]
    pub fn with_reach(mut self, reach_m: f32) -> Self {
        self.reach_m = reach_m;
        self
    }

    /// Width of a foot's sole (m): the diameter of a round sole of its
    /// area, the plate of Bekker's curve.
    #[must_use]
    pub fn sole_width_m(&self) -> f32 {
        2.0 * (self.foot_area_m2.max(1e-6) / std::f32::consts::PI).sqrt()
    }

    /// Pressure under each foot (Pa).
    #[must_use]
    pub fn pressure_pa(&self) -> f32 {
        self.mass_kg.max(0.0) * GRAVITY / (self.feet_down.max(1.0) * self.foot_area_m2.max(1e-6))
    }

    /// The direction it last moved in (x, z; zero before it has moved).
    #[must_use]
    pub fn heading(&self) -> Vec2 {
        self.heading
    }
}

/// How the snow under a [`FeelsSnow`] entity holds it back (inserted with
/// it; updated in [`SnowSystems::Footsteps`] when an answer arrives).
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Clone, Debug, PartialEq, Default)]
pub struct SnowResistance {
    /// Multiply a walker's speed on firm ground by this (0 to 1): `1 / √η`.
    /// 1 for a wheel (its resistance is a force, below).
    pub speed_factor: f32,
    /// The terrain coefficient `η` of the Pandolf equation (1 on firm ground).
    pub terrain_coefficient: f32,
    /// Snow depth where it steps (m).
    pub depth_m: f32,
    /// How much of that snow is pressed already (0 untouched, 1 to the ground).
    pub packed: f32,
    /// Mean density of the snow where it steps (kg/m³): fresh snow's where
    /// untouched, up to the final density where packed (`docs/mechanics.md`).
    pub density_kg_m3: f32,
    /// Penetration hardness of that snow (kPa): the pressure that sinks a
    /// 10 cm plate 10 cm further; harder where packed.
    pub hardness_kpa: f32,
    /// How far a step (or the wheel) sinks into it now (m).
    pub sinkage_m: f32,
    /// Where the feet (or the tyre's bottom) come to rest (world y, m): the
    /// snow's height where it steps minus [`Self::sinkage_m`]; `None` until
    /// the snow has answered.
    pub floor_m: Option<f32>,
    /// A wheel's compaction resistance (N) against its rolling; 0 for walkers.
    pub rolling_resistance_n: f32,
    /// That resistance over the wheel's load (`R / (m g)`).
    pub rolling_coefficient: f32,
}

impl Default for SnowResistance {
    /// Nothing holds it back (no answer yet, or no snow).
    fn default() -> Self {
        Self {
            speed_factor: 1.0,
            terrain_coefficient: 1.0,
            depth_m: 0.0,
            packed: 0.0,
            density_kg_m3: 0.0,
            hardness_kpa: 0.0,
            sinkage_m: 0.0,
            floor_m: None,
            rolling_resistance_n: 0.0,
            rolling_coefficient: 0.0,
        }
    }
}

/// The resistance of one answered point for a walker or a wheel, in snow of `mechanics`.
fn resist(sample: &PointSample, walker: &FeelsSnow, wheel: Option<&SnowWheel>, mechanics: &SnowMechanics) -> SnowResistance {
    let depth_m = sample.depth_m().max(0.0);
    let column = sample.column();
    let sinkage_m = match wheel {
        Some(w) => w.sinkage_m(mechanics, column),
        None => mechanics.plate_sinkage_m(walker.pressure_pa(), walker.sole_width_m(), column),
    };
    let here = SnowResistance {
        depth_m,
        packed: sample.compaction(),
        density_kg_m3: sample.density_kg_m3(mechanics),
        hardness_kpa: sample.hardness_kpa(mechanics),
        sinkage_m,
        floor_m: Some(sample.height_m - sinkage_m),
        ..SnowResistance::default()
    };
    match wheel {
        Some(w) => {
            let r = mechanics.wheel_resistance_n(&w.contact(), column);
            SnowResistance { rolling_resistance_n: r, rolling_coefficient: r / (w.load_kg * GRAVITY).max(1e-6), ..here }
        }
        None => {
            let eta = terrain_coefficient(sinkage_m, depth_m);
            SnowResistance { speed_factor: eta.sqrt().recip(), terrain_coefficient: eta, ..here }
        }
    }
}

pub(crate) fn build(app: &mut App) {
    app.add_systems(PostUpdate, sense_snow.in_set(SnowSystems::Footsteps));
}

/// The request in flight: its ticket, the entities it asked about
/// ([`POINTS`] points each), its age in frames.
#[derive(Default)]
struct Asked(Option<(SnowTicket, Vec<Entity>, u32)>);

/// A request unanswered for this many frames was skipped by the GPU side (busy staging): ask anew.
const GIVE_UP_FRAMES: u32 = 6;

/// Points asked per entity: under it, and ahead of it in the middle and to each side.
const POINTS: usize = 4;

/// The points asked for an entity at `p` heading along `heading` (a unit
/// vector, or zero before it has moved): its origin, and `reach` ahead with
/// a quarter of that to each side.
fn points_around(p: Vec2, heading: Vec2, reach: f32) -> [Vec2; POINTS] {
    let ahead = p + heading * reach;
    let side = heading.perp() * 0.25 * reach;
    [p, ahead, ahead + side, ahead - side]
}

/// What the sensing system reads and writes of each entity.
type Sensing = (Entity, &'static GlobalTransform, Option<&'static mut FeelsSnow>, Option<&'static mut SnowWheel>, Option<&'static mut SnowResistance>);

/// The entities that sense the snow: walkers and wheels.
type SensingFilter = Or<(With<FeelsSnow>, With<SnowWheel>)>;

/// Reads the answers for the sensing entities and asks again.
fn sense_snow(mut query: ResMut<SnowQuery>, mut asked: Local<Asked>, settings: Res<SnowpackSettings>, mut sensing: Query<Sensing, SensingFilter>) {
    if let Some((_, _, age)) = &mut asked.0 {
        *age += 1;
        if *age > GIVE_UP_FRAMES {
            asked.0 = None;
        }
    }
    let mechanics = settings.params.mechanics();
    if let Some((ticket, entities, _)) = &asked.0
        && let Some(answers) = query.take(*ticket)
    {
        for (entity, samples) in entities.iter().zip(answers.samples.chunks(POINTS)) {
            let Ok((_, _, feels, mut wheel, resistance)) = sensing.get_mut(*entity) else { continue };
            // The origin's snow places a wheel; the most packed point ahead is where a walker steps.
            if let (Some(w), Some(s)) = (wheel.as_deref_mut(), samples[0]) {
                w.snow_under = Some((s.terrain_m, s.rest_m));
            }
            let (Some(feels), Some(mut resistance)) = (feels, resistance) else { continue };
            let wheel = wheel.as_deref();
            let easiest = samples[1..].iter().flatten().map(|s| resist(s, &feels, wheel, &mechanics)).min_by(|a, b| a.sinkage_m.total_cmp(&b.sinkage_m));
            if let Some(easiest) = easiest {
                *resistance = easiest;
            }
        }
        asked.0 = None;
    }
    let mut entities = Vec::new();
    let mut points = Vec::new();
    for (entity, transform, feels, wheel, _) in &mut sensing {
        let p = transform.translation().xz();
        let reach = match (&feels, &wheel) {
            (Some(f), Some(w)) => f.reach_m.max(w.radius_m),
            (Some(f), None) => f.reach_m,
            (None, _) => 0.0,
        };
        let heading = match feels {
            Some(mut f) => {
                if let Some(moved) = f.last.map(|last| p - last).filter(|m| m.length() > 1e-4) {
                    f.heading = moved.normalize();
                }
                f.last = Some(p);
                f.heading
            }
            None => Vec2::ZERO,
        };
        entities.push(entity);
        points.extend(points_around(p, heading, reach));
    }
    if asked.0.is_none() && !entities.is_empty() {
        asked.0 = Some((query.ask_quietly(&points), entities, 0));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use snowpack::low_level::skin::sinking::FootLoad;
    use snowpack::mechanics::SnowColumn;

    fn sample(height_m: f32, packed_m: f32) -> PointSample {
        PointSample { height_m, surface_m: height_m, terrain_m: 0.0, rest_m: 0.4, normal: Vec3::Y, packed_m }
    }

    #[test]
    fn the_sinkage_is_the_librarys() {
        let snow = SnowMechanics::default();
        let fox = FeelsSnow::fox();
        let library = FootLoad { mass_kg: fox.mass_kg, foot_area_m2: fox.foot_area_m2 }.sinkage_m(fox.feet_down, &snow, SnowColumn::fresh(0.4));
        let ours = resist(&sample(0.4, 0.0), &fox, None, &snow).sinkage_m;
        assert!((ours - library).abs() < 1e-6 && ours > 0.03, "{ours} vs {library}");
    }

    #[test]
    fn deep_fresh_snow_holds_a_walker_back_more_than_a_trail() {
        // Richmond et al.'s coefficient: packed snow 1.26, 10 cm of sinkage 2.43.
        assert!((terrain_coefficient(0.0, 0.4) - 1.2604).abs() < 1e-4);
        assert!((terrain_coefficient(0.1, 0.4) - (0.5 + 0.01 + 1.072 + 1.2604)).abs() < 1e-3);
        assert_eq!(terrain_coefficient(0.0, 0.0), 1.0);
        let (fox, snow) = (FeelsSnow::fox(), SnowMechanics::default());
        let a = resist(&sample(0.4, 0.0), &fox, None, &snow);
        // A trail pressed 20 cm by a heavier load holds the fox.
        let b = resist(&sample(0.2, 0.2), &fox, None, &snow);
        assert!(a.sinkage_m > 0.05, "{a:?}");
        // Packed to twice the fresh density, and harder.
        assert!((a.density_kg_m3 - 100.0).abs() < 1e-3 && (b.density_kg_m3 - 200.0).abs() < 1e-2, "{a:?} {b:?}");
        assert!((a.hardness_kpa - 10.0).abs() < 1e-2 && b.hardness_kpa > 5.0 * a.hardness_kpa, "{a:?} {b:?}");
        assert_eq!(b.sinkage_m, 0.0);
        assert!(a.speed_factor < 0.7 && b.speed_factor > 0.85 && b.speed_factor < 0.9, "{a:?} {b:?}");
    }

    #[test]
    fn a_wheel_rolls_harder_in_fresh_snow_and_not_at_all_in_its_rut() {
        let (wheel, snow) = (SnowWheel::new(0.32, 0.2, 375.0), SnowMechanics::default());
        let fresh = resist(&sample(0.4, 0.0), &FeelsSnow::fox(), Some(&wheel), &snow);
        let z = fresh.sinkage_m;
        assert!(z > 0.01 && fresh.rolling_resistance_n > 1.0, "{fresh:?}");
        // Bekker's integral by the midpoint rule.
        let k = snow.modulus(0.2);
        let steps = 10_000;
        let numeric: f32 = (0..steps).map(|i| (i as f32 + 0.5) * z / steps as f32).map(|zz| 0.2 * k * zz.powf(1.6) * z / steps as f32).sum();
        assert!((fresh.rolling_resistance_n - numeric).abs() < 1e-2 * numeric, "{} vs {numeric}", fresh.rolling_resistance_n);
        let rut = resist(&sample(0.4 - z, z), &FeelsSnow::fox(), Some(&wheel), &snow);
        assert!(rut.sinkage_m < 1e-4 && rut.rolling_resistance_n < 1e-3 * fresh.rolling_resistance_n, "{rut:?}");
        let half = resist(&sample(0.4 - 0.5 * z, 0.5 * z), &FeelsSnow::fox(), Some(&wheel), &snow);
        assert!(half.rolling_resistance_n < fresh.rolling_resistance_n && half.rolling_resistance_n > rut.rolling_resistance_n);
    }
}
