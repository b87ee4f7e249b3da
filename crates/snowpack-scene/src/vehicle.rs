//! `[[vehicle]]`: a four-wheeled vehicle driving a curve, its wheels rolling
//! into the snow as deep as their load says (see `docs/scene.md`).
//!
//! The path is the vehicle's centre (midway between its axles) as
//! keyframes `[x, z, t]`, joined by a C1 cubic (Hermite, each key's velocity
//! the slope between its neighbours, Catmull–Rom style), held at the ends.
//! The body faces along the path; each wheel's axle is square to its own
//! velocity (the front wheels steer, none slides sideways), and it turns by
//! the distance it rolls times `1 + slip`. Wheels stand on the snow sunk by
//! [`WheelLoad::sinkage_m`] with a quarter of the mass each; the axles stay
//! level.

use glam::{Vec2, Vec3};
use snowpack::low_level::deform::wheel::{Tread, TreadPattern, forward};
use snowpack::low_level::skin::sinking::WheelLoad;
use snowpack::mechanics::{SnowColumn, SnowMechanics};
use snowpack::{Deformer, TerrainSource};

use crate::error::SceneError;
use crate::fields::Fields;

/// One `[[vehicle]]`.
#[derive(Clone, Debug, PartialEq)]
pub struct VehicleSpec {
    /// Distance between the front and rear axles (m).
    pub wheelbase_m: f32,
    /// Distance between the left and right wheels' centre lines (m).
    pub track_m: f32,
    /// Outer radius of each wheel, lugs included (m).
    pub wheel_radius_m: f32,
    /// Width of each tyre (m).
    pub wheel_width_m: f32,
    /// Mass of the vehicle (kg), a quarter on each wheel.
    pub mass_kg: f32,
    /// The tyres' tread.
    pub tread: Tread,
    /// The tread turns `1 + slip` times as fast as rolling needs (0: rolls;
    /// positive: spins; −1: locked, sliding).
    pub slip: f32,
    /// The centre's keyframes `[x, z, t]`.
    pub path: Vec<[f32; 3]>,
}

impl VehicleSpec {
    /// Reads and validates one `[[vehicle]]` table.
    pub(crate) fn parse(v: &mut Fields<'_>) -> Result<Self, SceneError> {
        let d = Tread::default();
        let wheelbase_m = v.positive("wheelbase_m", 2.6, " of metres")?;
        let track_m = v.positive("track_m", 1.55, " of metres")?;
        let wheel_radius_m = v.positive("wheel_radius_m", 0.33, " of metres")?;
        let wheel_width_m = v.positive("wheel_width_m", 0.2, " of metres")?;
        let mass_kg = v.positive("mass_kg", 1500.0, " of kg")?;
        let names: Vec<&str> = TreadPattern::ALL.iter().map(|(_, n)| *n).collect();
        let pattern = TreadPattern::from_name(&v.choice("tread", d.pattern.as_str(), &names)?).unwrap_or_default();
        let spacing_m = v.positive("tread_spacing_m", d.spacing_m, " of metres")?;
        let depth_m = v.non_negative("tread_depth_m", d.depth_m, " of metres")?;
        let lug_fraction = v.positive("tread_fraction", d.lug_fraction, "")?;
        let slip = v.f32("slip", 0.0)?;
        if track_m <= wheel_width_m {
            return Err(v.err("track_m", format!("{track_m} m must be more than wheel_width_m ({wheel_width_m} m): the wheels would overlap")));
        }
        if depth_m >= wheel_radius_m {
            return Err(v.err("tread_depth_m", format!("{depth_m} m must be less than wheel_radius_m ({wheel_radius_m} m)")));
        }
        if lug_fraction > 1.0 {
            return Err(v.err("tread_fraction", format!("must be in (0, 1] (the lug's share of each spacing), got {lug_fraction}")));
        }
        if !(-1.0..=10.0).contains(&slip) {
            return Err(v.err("slip", format!("must be in -1..=10 (-1 locked, 0 rolling, 1 spinning twice as fast), got {slip}")));
        }
        let path = v.rows3_opt("path")?.ok_or_else(|| v.err("path", "a vehicle needs a path of [x, z, t] keyframes"))?;
        if path.len() < 2 {
            return Err(v.err("path", "needs at least two [x, z, t] keyframes"));
        }
        if path.windows(2).any(|w| w[1][2] <= w[0][2]) {
            return Err(v.err("path", "keyframe times must increase strictly"));
        }
        Ok(Self { wheelbase_m, track_m, wheel_radius_m, wheel_width_m, mass_kg, tread: Tread { pattern, spacing_m, depth_m, lug_fraction }, slip, path })
    }

    /// The load on each wheel.
    #[must_use]
    pub fn wheel_load(&self) -> WheelLoad {
        WheelLoad { mass_kg: self.mass_kg / 4.0, radius_m: self.wheel_radius_m, width_m: self.wheel_width_m }
    }

    /// Velocity of the path at key `k` (m/s): the slope between its neighbours.
    fn key_velocity(&self, k: usize) -> Vec2 {
        let p = &self.path;
        let (a, b) = (k.saturating_sub(1), (k + 1).min(p.len() - 1));
        (Vec2::new(p[b][0], p[b][1]) - Vec2::new(p[a][0], p[a][1])) / (p[b][2] - p[a][2])
    }

    /// The centre (x, z) and its velocity (m/s) at time `t_s`; held at the ends.
    #[must_use]
    pub fn centre_at(&self, t_s: f32) -> (Vec2, Vec2) {
        let p = &self.path;
        let last = p.len() - 1;
        let t = t_s.clamp(p[0][2], p[last][2]);
        let k = p.windows(2).position(|w| t <= w[1][2]).unwrap_or(last - 1);
        let (t0, t1) = (p[k][2], p[k + 1][2]);
        let h = t1 - t0;
        let f = (t - t0) / h;
        let (p0, p1) = (Vec2::new(p[k][0], p[k][1]), Vec2::new(p[k + 1][0], p[k + 1][1]));
        let (m0, m1) = (self.key_velocity(k) * h, self.key_velocity(k + 1) * h);
        let (f2, f3) = (f * f, f * f * f);
        let pos = p0 * (2.0 * f3 - 3.0 * f2 + 1.0) + m0 * (f3 - 2.0 * f2 + f) + p1 * (-2.0 * f3 + 3.0 * f2) + m1 * (f3 - f2);
        let vel = (p0 * (6.0 * f2 - 6.0 * f) + m0 * (3.0 * f2 - 4.0 * f + 1.0) + p1 * (-6.0 * f2 + 6.0 * f) + m1 * (3.0 * f2 - 2.0 * f)) / h;
        let moving = t_s > p[0][2] && t_s < p[last][2];
        (pos, if moving { vel } else { Vec2::ZERO })
    }

    /// Heading (unit x, z) at `t_s`: along the path's velocity there, or at
    /// the nearest end while held.
    #[must_use]
    pub fn heading_at(&self, t_s: f32) -> Vec2 {
        let p = &self.path;
        let (t0, t1) = (p[0][2], p[p.len() - 1][2]);
        let (_, v) = self.centre_at(t_s.clamp(t0 + 1e-4 * (t1 - t0), t1 - 1e-4 * (t1 - t0)));
        v.try_normalize().unwrap_or(Vec2::Y)
    }

    /// Where wheel `k` (0 front left, 1 front right, 2 rear left, 3 rear right) touches down, (x, z), at `t_s`.
    #[must_use]
    pub fn wheel_xz(&self, k: usize, t_s: f32) -> Vec2 {
        let (c, _) = self.centre_at(t_s);
        let h = self.heading_at(t_s);
        let left = Vec2::new(h.y, -h.x);
        let along = if k < 2 { 0.5 } else { -0.5 } * self.wheelbase_m;
        let side = if k.is_multiple_of(2) { 0.5 } else { -0.5 } * self.track_m;
        c + h * along + left * side
    }
}

/// A vehicle in motion: its wheels' axles and roll.
#[derive(Clone, Debug)]
pub(crate) struct VehicleState {
    pub(crate) spec: VehicleSpec,
    /// Per wheel: where it was (x, z), its axle and its roll (m, f64 so a long drive keeps the tread in place).
    wheels: [(Vec2, Vec3, f64); 4],
}

/// Time step for a wheel's velocity (s): short against any path's keys.
const VELOCITY_DT_S: f32 = 1e-3;

impl VehicleState {
    pub(crate) fn new(spec: &VehicleSpec, t_s: f32) -> Self {
        let wheels = std::array::from_fn(|k| {
            let at = spec.wheel_xz(k, t_s);
            let h = spec.heading_at(t_s);
            (at, Self::axle_for(spec, k, t_s).unwrap_or(Vec3::new(h.y, 0.0, -h.x)), 0.0)
        });
        Self { spec: spec.clone(), wheels }
    }

    /// The axle square to wheel `k`'s velocity at `t_s`, rolling forward
    /// along it; `None` while it stands still.
    fn axle_for(spec: &VehicleSpec, k: usize, t_s: f32) -> Option<Vec3> {
        let v = spec.wheel_xz(k, t_s + VELOCITY_DT_S) - spec.wheel_xz(k, t_s - VELOCITY_DT_S);
        let dir = v.try_normalize()?;
        // forward(axle) = axle x up = dir.
        Some(Vec3::new(dir.y, 0.0, -dir.x))
    }

    /// Moves the wheels to time `t_s`: each turns its axle square to its
    /// motion (keeping its sense, so reversing rolls backwards) and rolls by
    /// its forward travel times `1 + slip`.
    pub(crate) fn advance(&mut self, t_s: f32) {
        for (k, (at, axle, roll)) in self.wheels.iter_mut().enumerate() {
            let now = self.spec.wheel_xz(k, t_s);
            if let Some(mut a) = Self::axle_for(&self.spec, k, t_s) {
                if a.dot(*axle) < 0.0 {
                    a = -a;
                }
                *axle = a;
            }
            let moved = now - *at;
            let ahead = forward(*axle);
            *roll += f64::from(moved.x * ahead.x + moved.y * ahead.z) * f64::from(1.0 + self.spec.slip);
            *at = now;
        }
    }

    /// The four wheels as deformers, on fresh snow `depth_m` deep of
    /// `mechanics` over `terrain`, sunk as deep as their load says.
    pub(crate) fn deformers(&self, terrain: &TerrainSource, depth_m: f32, mechanics: &SnowMechanics) -> [Deformer; 4] {
        let s = &self.spec;
        let sink = s.wheel_load().sinkage_m(mechanics, SnowColumn::fresh(depth_m));
        std::array::from_fn(|k| {
            let (at, axle, roll) = self.wheels[k];
            let ground = terrain.height_at(at.x, at.y);
            let support = (ground + depth_m - sink).max(ground);
            // Not wrapped: the sweep takes the roll's change between frames
            // (f32 keeps it to a millimetre over 10 km).
            let roll_m = roll as f32;
            Deformer::Wheel {
                center: Vec3::new(at.x, support + s.wheel_radius_m, at.y),
                axle,
                radius: s.wheel_radius_m,
                half_width: 0.5 * s.wheel_width_m,
                tread: s.tread,
                roll_m,
            }
        })
    }
}
