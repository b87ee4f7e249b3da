//! The scene in motion: still, kinematic and keyframed actors, and the test
//! bed's physics spheres (Wasmut 2019, section 3) on the CPU.
//!
//! Spheres collide with the terrain under the snow (so they plough through
//! it), with each other (a uniform grid keeps that linear in their number),
//! and with the walls of the window area, which keeps them in bounds.

use std::collections::HashMap;

use glam::{Mat4, Quat, Vec2, Vec3};
use snowpack::low_level::skin::AnimationPlayer;
use snowpack::low_level::skin::feet::{FootTracker, FootstepEvent, mean_feet_down};
use snowpack::mechanics::{SnowColumn, SnowMechanics};
use snowpack::{Deformer, PointSample, TerrainSource};
use snowpack_share::testing::Rng;

use crate::scene::{ActorSpec, GltfActor, Motion, Placement, Scene, ShapeSpec, WindowSpec};
use snowpack::low_level::TerrainSourceExt;

/// Gravity (m/s²).
pub const GRAVITY: f32 = 9.81;
/// Fraction of normal speed kept in a bounce.
pub const RESTITUTION: f32 = 0.4;
/// Coulomb friction coefficient against the ground and between spheres.
pub const FRICTION: f32 = 0.3;
/// Substeps per frame: keeps fast spheres from tunnelling into the terrain.
const SUBSTEPS: u32 = 4;
/// Below this normal speed (m/s) a contact does not bounce (no resting jitter).
const BOUNCE_THRESHOLD: f32 = 0.6;

#[derive(Clone, Debug)]
struct Body {
    pos: Vec3,
    vel: Vec3,
    radius: f32,
}

#[derive(Clone, Debug)]
struct Actor {
    shape: ShapeSpec,
    motion: Motion,
    body: Option<usize>,
    /// Characters: the clip playing.
    anim: Option<AnimationPlayer>,
    /// Heading (radians about +y, 0 facing +z), kept while standing still.
    heading: f32,
    /// Characters: touchdown detection per foot.
    feet: Option<FootTracker>,
    /// Characters placed on the ground or the snow: the root's height (m).
    root_y: Option<f32>,
    /// Characters: the height each foot stands on (m), and the load model's
    /// sinkage this frame (m).
    supports: Vec<f32>,
    sink_m: f32,
    /// Characters: index into the gaits of the gait playing.
    gait: Option<usize>,
    /// Characters: feet down on average over each clip (the load's share).
    feet_down: Vec<f32>,
    /// Steered by the game ([`World::steer`]): position and velocity, which
    /// replace the scene's motion.
    steer: Option<(Vec3, Vec3)>,
    /// Off ([`World::set_enabled`]): neither deforms nor is drawn.
    enabled: bool,
}

/// How fast a character turns toward its direction of travel (rad/s).
const TURN_RATE: f32 = 8.0;
/// Time constant of a placed character's root height settling onto its feet (s) ...
const ROOT_SETTLE_S: f32 = 0.06;
/// ... and rising onto them (s): the snow pushes back faster than the body sinks.
const ROOT_RISE_S: f32 = 0.015;
/// How far below its support a planted paw may go while the others average (m).
const PAW_SINK_SLACK_M: f32 = 0.01;
/// Below this speed (m/s) a character with gaits plays its standing clip.
const STAND_SPEED: f32 = 0.05;
/// A gait changes only when the other fits the speed better by this much (log ratio).
const GAIT_HYSTERESIS: f32 = 0.1;

/// A sole within this of the ground is planted (m).
pub const FOOT_PLANT_M: f32 = 0.015;
/// A sole above this is lifted (m).
pub const FOOT_LIFT_M: f32 = 0.04;

/// A character's pose this frame: what the skinning pass needs.
#[derive(Clone, Debug, PartialEq)]
pub struct CharacterPose {
    /// Index of the `[[actor]]`.
    pub actor: usize,
    /// Placement: position, heading, scale.
    pub model: Mat4,
    /// Skinning matrix of each joint.
    pub joints: Vec<Mat4>,
    /// Global matrix of every skeleton node in world space (model applied), for feet.
    pub nodes: Vec<Mat4>,
}

/// Runtime state of a scene's actors.
#[derive(Clone, Debug)]
pub struct World {
    time: f32,
    terrain: TerrainSource,
    actors: Vec<Actor>,
    bodies: Vec<Body>,
    vehicles: Vec<crate::vehicle::VehicleState>,
    min: Vec2,
    max: Vec2,
    footsteps: Vec<FootstepEvent>,
    /// Rest depth and mechanics of the snow characters stand on.
    snow_depth_m: f32,
    mechanics: SnowMechanics,
}

fn path_at(keys: &[[f32; 4]], t: f32) -> Vec3 {
    let v = |k: &[f32; 4]| Vec3::new(k[0], k[1], k[2]);
    let first = &keys[0];
    if t <= first[3] {
        return v(first);
    }
    for w in keys.windows(2) {
        if t <= w[1][3] {
            let f = (t - w[0][3]) / (w[1][3] - w[0][3]);
            return v(&w[0]).lerp(v(&w[1]), f);
        }
    }
    v(&keys[keys.len() - 1])
}

impl World {
    /// The scene's actors at t = 0, with `[[spawn]]` spheres placed at random (seeded).
    #[must_use]
    pub fn new(scene: &Scene) -> Self {
        let half = scene.snow.extent_m * 0.5;
        let center = match &scene.window {
            WindowSpec::Center(c) => Vec2::from(*c),
            WindowSpec::FollowCamera => Vec2::new(scene.camera.position.x, scene.camera.position.z),
            WindowSpec::FollowActor(i) => {
                let a = &scene.actors[*i];
                let p = match &a.motion {
                    Motion::Kinematic { position, .. } | Motion::Physics { position, .. } => *position,
                    Motion::Path(keys) => path_at(keys, 0.0),
                };
                Vec2::new(p.x, p.z)
            }
        };
        let mut world = Self {
            time: 0.0,
            terrain: scene.terrain.clone(),
            actors: Vec::new(),
            bodies: Vec::new(),
            vehicles: scene.vehicles.iter().map(|v| crate::vehicle::VehicleState::new(v, 0.0)).collect(),
            min: center - Vec2::splat(half),
            max: center + Vec2::splat(half),
            footsteps: Vec::new(),
            snow_depth_m: scene.snow.depth_m,
            mechanics: scene.snow.mechanics(),
        };
        for spec in &scene.actors {
            world.push_actor(spec);
        }
        for spawn in &scene.spawns {
            let mut rng = Rng::new(spawn.seed);
            let r = spawn.radius_m;
            for _ in 0..spawn.count {
                let x = rng.range(world.min.x + r, (world.max.x - r).max(world.min.x + r));
                let z = rng.range(world.min.y + r, (world.max.y - r).max(world.min.y + r));
                let y = world.terrain.height_at(x, z) + r + rng.range(2.0, 8.0);
                let vel = Vec3::new(rng.range(-2.0, 2.0), 0.0, rng.range(-2.0, 2.0));
                world.bodies.push(Body { pos: Vec3::new(x, y, z), vel, radius: r });
            }
        }
        // Face the direction of travel, in the gait for the speed and on the
        // snow from the first frame on.
        world.update_headings(None);
        world.update_gaits();
        world.place_characters(0.0, &|_, _| None::<PointSample>);
        world
    }

    fn push_actor(&mut self, spec: &ActorSpec) -> usize {
        let body = match (&spec.motion, &spec.shape) {
            (Motion::Physics { position, velocity }, ShapeSpec::Sphere { radius_m }) => {
                self.bodies.push(Body { pos: *position, vel: *velocity, radius: *radius_m });
                Some(self.bodies.len() - 1)
            }
            _ => None,
        };
        let (anim, feet) = match &spec.shape {
            ShapeSpec::Gltf(g) => {
                let mut player = AnimationPlayer::new(g.clip);
                player.speed = g.speed;
                (Some(player), Some(FootTracker::new(g.feet.len(), FOOT_PLANT_M, FOOT_LIFT_M)))
            }
            _ => (None, None),
        };
        self.actors.push(Actor {
            shape: spec.shape.clone(),
            motion: spec.motion.clone(),
            body,
            anim,
            heading: 0.0,
            feet,
            root_y: None,
            supports: Vec::new(),
            sink_m: 0.0,
            gait: None,
            feet_down: match &spec.shape {
                ShapeSpec::Gltf(g) => g.model.clips.iter().map(|c| mean_feet_down(&g.model.skeleton, c, &g.feet)).collect(),
                _ => Vec::new(),
            },
            steer: None,
            enabled: true,
        });
        self.actors.len() - 1
    }

    /// Adds an actor (a character the player steers, say) now; returns its index.
    pub fn add_actor(&mut self, spec: &ActorSpec) -> usize {
        let k = self.push_actor(spec);
        self.update_headings(None);
        self.update_gaits();
        self.place_characters(0.0, &|_, _| None::<PointSample>);
        k
    }

    /// Steers actor `i` from where it is now at `velocity` (m/s, on the ground
    /// plane) from now on, in place of its scene motion; physics spheres are
    /// not steered. False when there is no such actor.
    pub fn steer(&mut self, i: usize, velocity: Vec2) -> bool {
        let Some(position) = self.actor_position(i) else { return false };
        let a = &mut self.actors[i];
        if a.body.is_some() {
            return false;
        }
        a.steer = Some((position, Vec3::new(velocity.x, 0.0, velocity.y)));
        true
    }

    /// Changes the rest depth (m) and the mechanics (densities, hardness) of
    /// the snow characters stand on.
    pub fn set_snow(&mut self, depth_m: f32, mechanics: SnowMechanics) {
        self.snow_depth_m = depth_m;
        self.mechanics = mechanics;
    }

    /// Takes actor `i` out of the world (`false`: it neither presses the snow,
    /// nor is posed, nor steps) or puts it back; it keeps its state meanwhile.
    pub fn set_enabled(&mut self, i: usize, enabled: bool) {
        if let Some(a) = self.actors.get_mut(i) {
            a.enabled = enabled;
        }
    }

    /// The glTF characters: (actor index, its model and settings).
    pub fn gltf_actors(&self) -> impl Iterator<Item = (usize, &GltfActor)> + '_ {
        self.actors.iter().enumerate().filter_map(|(k, a)| match &a.shape {
            ShapeSpec::Gltf(g) => Some((k, g)),
            _ => None,
        })
    }

    /// Puts actor `i` at `xz` (keeping its height rule); for the game's respawns.
    pub fn teleport(&mut self, i: usize, xz: Vec2) {
        let Some(p) = self.actor_position(i) else { return };
        if let Some(a) = self.actors.get_mut(i).filter(|a| a.body.is_none()) {
            let v = a.steer.map_or(Vec3::ZERO, |s| s.1);
            // A placed character's height comes from its feet again (a steered one has no offset).
            let y = if a.root_y.is_some() { 0.0 } else { p.y };
            a.steer = Some((Vec3::new(xz.x, y, xz.y), v));
            a.root_y = None;
        }
        self.place_characters(0.0, &|_, _| None::<PointSample>);
    }

    /// Turns characters toward their direction of travel, at most
    /// [`TURN_RATE`] over `dt` (at once when `None`).
    fn update_headings(&mut self, dt: Option<f32>) {
        for k in 0..self.actors.len() {
            let v = self.actor_velocity(k);
            if Vec2::new(v.x, v.z).length() > 1e-3 {
                let want = v.x.atan2(v.z);
                let a = &mut self.actors[k];
                a.heading = match dt {
                    None => want,
                    Some(dt) => {
                        let turn = (want - a.heading + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU) - std::f32::consts::PI;
                        a.heading + turn.clamp(-TURN_RATE * dt, TURN_RATE * dt)
                    }
                };
            }
        }
    }

    /// Picks each character's clip and playback speed from its travel speed.
    fn update_gaits(&mut self) {
        for k in 0..self.actors.len() {
            let v = self.actor_velocity(k);
            let speed = Vec2::new(v.x, v.z).length();
            let a = &mut self.actors[k];
            let (ShapeSpec::Gltf(g), Some(player)) = (&a.shape, &mut a.anim) else { continue };
            if g.gaits.is_empty() {
                continue;
            }
            if speed < STAND_SPEED {
                player.play_synced(g.clip, g.fade_s, &g.model.clips);
                player.speed = g.speed;
                a.gait = None;
                continue;
            }
            let misfit = |j: usize| (speed / g.gaits[j].stride_m_per_s).ln().abs();
            let best = (0..g.gaits.len()).min_by(|&x, &y| misfit(x).total_cmp(&misfit(y))).unwrap_or(0);
            let gait = match a.gait {
                Some(now) if now < g.gaits.len() && misfit(best) > misfit(now) - GAIT_HYSTERESIS => now,
                _ => best,
            };
            a.gait = Some(gait);
            player.play_synced(g.gaits[gait].clip, g.fade_s, &g.model.clips);
            player.speed = g.speed * speed / g.gaits[gait].stride_m_per_s;
        }
    }

    /// Puts characters placed on the ground or the snow at the height their
    /// feet stand on. On the snow, each foot sinks into the column under it
    /// (`surface(x, z)`, the snow there when known; else fresh snow) as far
    /// as the load model says (`snowpack::low_level::skin::sinking`): on
    /// fresh snow Bekker's sinkage, in a packed print only what the load
    /// presses beyond the load that packed it, so a second walk in a trail
    /// sinks less, a foot standing in its own print no further (and the
    /// depth does not depend on the frame rate). Never below the ground.
    /// The root follows the feet that are down: up at once, down with a
    /// short time constant.
    fn place_characters(&mut self, dt: f32, surface: &dyn Fn(f32, f32) -> Option<PointSample>) {
        for (actor, soles) in self.soles() {
            let a = &self.actors[actor];
            let ShapeSpec::Gltf(g) = &a.shape else { continue };
            let (placement, load) = (g.placement, g.load);
            let root = a.root_y;
            let planted: Vec<bool> = a.feet.as_ref().map_or_else(|| vec![true; soles.len()], |t| t.planted().to_vec());
            let clip = a.anim.as_ref().map_or(g.clip, |p| p.clip);
            // A character with gaits standing still has every foot down.
            let standing = !g.gaits.is_empty() && !g.gaits.iter().any(|x| x.clip == clip);
            let down = if standing { soles.len() as f32 } else { a.feet_down.get(clip).copied().unwrap_or(soles.len() as f32) };
            let sink = match placement {
                Placement::Snow => load.sinkage_m(down, &self.mechanics, SnowColumn::fresh(self.snow_depth_m)),
                Placement::Path | Placement::Ground => 0.0,
            };
            let supports: Vec<f32> = soles
                .iter()
                .map(|p| {
                    let ground = self.terrain.height_at(p.x, p.z);
                    match placement {
                        Placement::Snow => {
                            let pressed = ground + self.snow_depth_m - sink;
                            match surface(p.x, p.z) {
                                Some(s) => s.height_m - load.sinkage_m(down, &self.mechanics, s.column()),
                                None => pressed,
                            }
                            .max(ground)
                        }
                        Placement::Ground => ground,
                        // Path: the ground the root walks on, carried under each foot.
                        Placement::Path => f32::NAN,
                    }
                })
                .collect();
            self.actors[actor].sink_m = sink;
            if placement == Placement::Path {
                self.actors[actor].supports.clear();
                continue;
            }
            // The root that puts the planted paws on their supports, on average
            // (a clip's paws are not all exactly level).
            let current = root.unwrap_or(0.0);
            let wanted: Vec<f32> =
                soles.iter().zip(&supports).zip(&planted).filter(|(_, down)| **down).map(|((sole, support), _)| support - sole.y + current).collect();
            // No paw down (a run's flight, or a body held too high): it falls
            // until the first paw touches, the highest root that puts a paw on its support.
            let falling = soles.iter().zip(&supports).map(|(sole, support)| support - sole.y + current).reduce(f32::max);
            // The paws' average, but no planted paw deeper than PAW_SINK_SLACK_M
            // below its support: a paw lifting off (planted until it is
            // FOOT_LIFT_M up) must not pull the body, and the paw it stands
            // on, deeper into the snow than the load says.
            let target = if wanted.is_empty() {
                falling
            } else {
                let mean = wanted.iter().sum::<f32>() / wanted.len() as f32;
                let highest = wanted.iter().copied().fold(f32::MIN, f32::max);
                Some(mean.max(highest - PAW_SINK_SLACK_M))
            };
            let a = &mut self.actors[actor];
            a.root_y = match (root, target) {
                // The snow holds a paw up quickly; the body settles into it more slowly.
                (Some(y), Some(t)) if dt > 0.0 => {
                    let tau = if t > y { ROOT_RISE_S } else { ROOT_SETTLE_S };
                    Some(y + (t - y) * (1.0 - (-dt / tau).exp()))
                }
                (_, t) => t,
            };
            a.supports = supports;
        }
    }

    /// Simulated time (s).
    #[must_use]
    pub fn time(&self) -> f32 {
        self.time
    }

    /// Number of `[[actor]]` entries (spawned spheres not included).
    #[must_use]
    pub fn actor_count(&self) -> usize {
        self.actors.len()
    }

    /// Number of physics spheres (physics actors and spawned spheres).
    #[must_use]
    pub fn body_count(&self) -> usize {
        self.bodies.len()
    }

    /// Centre of actor `i` now.
    #[must_use]
    pub fn actor_position(&self, i: usize) -> Option<Vec3> {
        let a = self.actors.get(i)?;
        let mut p = match (&a.motion, a.body, a.steer) {
            (_, Some(b), _) => self.bodies[b].pos,
            (_, None, Some((position, _))) => position,
            (Motion::Path(keys), None, None) => path_at(keys, self.time),
            (Motion::Kinematic { position, velocity } | Motion::Physics { position, velocity }, None, None) => *position + *velocity * self.time,
        };
        if let Some(y) = a.root_y {
            // Placed characters: the scene's height is an offset from their feet's support.
            let offset = if a.steer.is_some() { 0.0 } else { p.y };
            p.y = y + offset;
        }
        Some(p)
    }

    /// Centres of all physics spheres now.
    pub fn body_positions(&self) -> impl Iterator<Item = (Vec3, f32)> + '_ {
        self.bodies.iter().map(|b| (b.pos, b.radius))
    }

    /// Everything that deforms the snow now.
    #[must_use]
    pub fn deformers(&self) -> Vec<Deformer> {
        let mut out = Vec::with_capacity(self.actors.len() + self.bodies.len());
        for (i, a) in self.actors.iter().enumerate() {
            if a.body.is_some() || !a.enabled {
                continue; // bodies are drawn below
            }
            let Some(center) = self.actor_position(i) else { continue };
            out.push(match &a.shape {
                ShapeSpec::Sphere { radius_m } => Deformer::Sphere { center, radius: *radius_m },
                ShapeSpec::Box { size_m, rotation } => Deformer::Box { center, half_extents: *size_m * 0.5, rotation: *rotation },
                ShapeSpec::Blade { width_m, height_m, angle_deg } => Deformer::blade(center, self.actor_velocity(i), *angle_deg, (*width_m, *height_m)),
                ShapeSpec::Point { scale_per_m } => Deformer::Point { position: center, scale_per_m: *scale_per_m },
                // Characters press the snow with their skinned mesh (see
                // `characters`) and, for the points technique, a point under
                // each foot that is down (added below).
                ShapeSpec::Gltf(_) => continue,
            });
        }
        out.extend(self.foot_points());
        out.extend(self.bodies.iter().map(|b| Deformer::Sphere { center: b.pos, radius: b.radius }));
        for v in &self.vehicles {
            out.extend(v.deformers(&self.terrain, self.snow_depth_m, &self.mechanics));
        }
        out
    }

    /// A stable id for each of [`Self::deformers`], in the same order, for
    /// [`snowpack::SnowFrame::with_ids`]: actor i is `i`, the foot points of
    /// actor i's foot k are `1 << 40 | i << 8 | k`, body b is `2 << 40 | b`, wheel k of vehicle v is `3 << 40 | v << 8 | k`;
    /// so each deformer is swept from its own last pose however many feet
    /// are down.
    #[must_use]
    pub fn deformer_ids(&self) -> Vec<u64> {
        let mut out = Vec::with_capacity(self.actors.len() + self.bodies.len());
        for (i, a) in self.actors.iter().enumerate() {
            if a.body.is_some() || !a.enabled || self.actor_position(i).is_none() || matches!(a.shape, ShapeSpec::Gltf(_)) {
                continue;
            }
            out.push(i as u64);
        }
        for (actor, soles) in self.soles() {
            let a = &self.actors[actor];
            let (ShapeSpec::Gltf(_), Some(tracker)) = (&a.shape, &a.feet) else { continue };
            for (k, (_, down)) in soles.iter().zip(tracker.planted()).enumerate() {
                if *down {
                    out.push(1 << 40 | (actor as u64) << 8 | k as u64);
                }
            }
        }
        out.extend((0..self.bodies.len() as u64).map(|b| 2 << 40 | b));
        for v in 0..self.vehicles.len() as u64 {
            out.extend((0..4).map(|k| 3 << 40 | v << 8 | k));
        }
        out
    }

    /// The points technique's contacts of characters: a point under each
    /// foot that is down, as deep as the foot stands, as wide as its sole.
    #[must_use]
    pub fn foot_points(&self) -> Vec<Deformer> {
        let mut out = Vec::new();
        for (actor, soles) in self.soles() {
            let a = &self.actors[actor];
            let (ShapeSpec::Gltf(g), Some(tracker)) = (&a.shape, &a.feet) else { continue };
            // h = foot + d² / (2 r): a sphere of the sole's radius near its bottom.
            let scale_per_m = 0.5 / g.load.foot_radius_m();
            for (k, (p, down)) in soles.iter().zip(tracker.planted()).enumerate() {
                if *down {
                    let y = a.supports.get(k).copied().unwrap_or(p.y);
                    out.push(Deformer::Point { position: Vec3::new(p.x, y, p.z), scale_per_m });
                }
            }
        }
        out
    }

    /// Advances time by `dt` seconds, with the snow undisturbed for characters
    /// placed on it (see [`Self::step_on`]).
    pub fn step(&mut self, dt: f32) {
        self.step_on(dt, &|_, _| None::<PointSample>);
    }

    /// Advances time by `dt` seconds; characters placed on the snow stand in
    /// it as `surface(x, z)` (world height of the snow there, m, `None` where
    /// unknown) says, for example from the deformation's CPU snapshot.
    pub fn step_on(&mut self, dt: f32, surface: &dyn Fn(f32, f32) -> Option<PointSample>) {
        let h = dt / SUBSTEPS as f32;
        for _ in 0..SUBSTEPS {
            self.substep(h);
        }
        self.time += dt;
        for v in &mut self.vehicles {
            v.advance(self.time);
        }
        for a in &mut self.actors {
            if let Some((position, velocity)) = &mut a.steer {
                *position += *velocity * dt;
            }
            if let Some(player) = &mut a.anim {
                player.advance(dt);
            }
        }
        self.update_headings(Some(dt));
        self.update_gaits();
        self.place_characters(dt, surface);
        self.detect_footsteps();
    }

    /// The clip each character plays now and its playback speed: (actor, clip, speed).
    #[must_use]
    pub fn clips(&self) -> Vec<(usize, usize, f32)> {
        self.actors.iter().enumerate().filter_map(|(k, a)| a.anim.as_ref().map(|p| (k, p.clip, p.speed))).collect()
    }

    /// Footstep events since the last call, oldest first.
    pub fn take_footsteps(&mut self) -> Vec<FootstepEvent> {
        std::mem::take(&mut self.footsteps)
    }

    /// Where each foot's sole is now (world), for every character: (actor, soles).
    /// A placed character's soles are its paws' lowest points; a character
    /// at its path's height has its clip grounded: each sole is lifted by the
    /// foot's lowest height over the clip, so it touches y = root when planted.
    #[must_use]
    pub fn soles(&self) -> Vec<(usize, Vec<Vec3>)> {
        self.characters()
            .into_iter()
            .filter_map(|c| {
                let a = &self.actors[c.actor];
                let ShapeSpec::Gltf(g) = &a.shape else { return None };
                let clip = a.anim.as_ref().map_or(g.clip, |p| p.clip);
                let soles = g
                    .feet
                    .iter()
                    .map(|f| {
                        let lowest = f.lowest_point(&g.model.mesh, &c.joints, c.model).unwrap_or_else(|| c.nodes[f.node].w_axis.truncate());
                        let grounding = if g.placement == Placement::Path { f.planted(clip) * g.scale } else { 0.0 };
                        lowest - Vec3::Y * grounding
                    })
                    .collect();
                Some((c.actor, soles))
            })
            .collect()
    }

    fn detect_footsteps(&mut self) {
        for (actor, soles) in self.soles() {
            let Some(root) = self.actor_position(actor) else { continue };
            let v = self.actor_velocity(actor);
            let base = self.terrain.height_at(root.x, root.z);
            let a = &self.actors[actor];
            let sink_m = a.sink_m;
            // The sole's height over what it stands on: the support of a placed
            // character, or else the ground the root walks on, following the
            // terrain under each foot.
            let heights: Vec<f32> =
                soles.iter().enumerate().map(|(k, p)| p.y - a.supports.get(k).copied().unwrap_or(root.y + self.terrain.height_at(p.x, p.z) - base)).collect();
            let Some(tracker) = self.actors[actor].feet.as_mut() else { continue };
            let down = tracker.update(&heights);
            let ShapeSpec::Gltf(g) = &self.actors[actor].shape else { continue };
            for foot in down {
                let p = soles[foot];
                self.footsteps.push(FootstepEvent {
                    actor,
                    foot,
                    name: g.feet[foot].name.clone(),
                    position: Vec3::new(p.x, p.y - heights[foot], p.z),
                    speed_m_per_s: Vec2::new(v.x, v.z).length(),
                    time_s: self.time,
                    snow_depth_m: None,
                    sink_m,
                });
            }
        }
    }

    /// Velocity of actor `i` now (m/s).
    fn actor_velocity(&self, i: usize) -> Vec3 {
        let Some(a) = self.actors.get(i) else { return Vec3::ZERO };
        match (&a.motion, a.body, a.steer) {
            (_, Some(b), _) => self.bodies[b].vel,
            (_, None, Some((_, velocity))) => velocity,
            (Motion::Path(keys), None, None) => {
                let h = 0.02;
                (path_at(keys, self.time + h) - path_at(keys, self.time - h)) / (2.0 * h)
            }
            (Motion::Kinematic { velocity, .. } | Motion::Physics { velocity, .. }, None, None) => *velocity,
        }
    }

    /// The pose of every glTF character now.
    #[must_use]
    pub fn characters(&self) -> Vec<CharacterPose> {
        let mut out = Vec::new();
        for (k, a) in self.actors.iter().enumerate() {
            let (ShapeSpec::Gltf(g), Some(player), true) = (&a.shape, &a.anim, a.enabled) else { continue };
            let Some(position) = self.actor_position(k) else { continue };
            let model = Mat4::from_scale_rotation_translation(Vec3::splat(g.scale), Quat::from_rotation_y(a.heading), position);
            let s = &g.model.skeleton;
            let globals = s.globals(&player.locals(s, &g.model.clips));
            let joints = s.joint_matrices(&globals);
            out.push(CharacterPose { actor: k, model, joints, nodes: globals.iter().map(|m| model * *m).collect() });
        }
        out
    }

    fn substep(&mut self, h: f32) {
        for b in &mut self.bodies {
            b.vel.y -= GRAVITY * h;
            b.pos += b.vel * h;
        }
        self.collide_spheres();
        let terrain = &self.terrain;
        for b in &mut self.bodies {
            ground_contact(terrain, b, h);
            wall_contact(b, self.min, self.max);
            if !(b.pos.is_finite() && b.vel.is_finite()) {
                // Never propagate NaN: put the sphere back on the ground at rest.
                let c = (self.min + self.max) * 0.5;
                b.pos = Vec3::new(c.x, terrain.height_at(c.x, c.y) + b.radius, c.y);
                b.vel = Vec3::ZERO;
            }
        }
    }

    fn collide_spheres(&mut self) {
        let Some(max_r) = self.bodies.iter().map(|b| b.radius).reduce(f32::max) else { return };
        let cell = 2.0 * max_r;
        let key = |p: Vec3| ((p.x / cell).floor() as i32, (p.y / cell).floor() as i32, (p.z / cell).floor() as i32);
        let mut grid: HashMap<(i32, i32, i32), Vec<usize>> = HashMap::with_capacity(self.bodies.len());
        for (k, b) in self.bodies.iter().enumerate() {
            grid.entry(key(b.pos)).or_default().push(k);
        }
        for a in 0..self.bodies.len() {
            let (cx, cy, cz) = key(self.bodies[a].pos);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(list) = grid.get(&(cx + dx, cy + dy, cz + dz)) else { continue };
                        for &b in list {
                            if b > a {
                                self.resolve_pair(a, b);
                            }
                        }
                    }
                }
            }
        }
    }

    fn resolve_pair(&mut self, a: usize, b: usize) {
        let (pa, pb) = (self.bodies[a].pos, self.bodies[b].pos);
        let reach = self.bodies[a].radius + self.bodies[b].radius;
        let d = pb - pa;
        let dist = d.length();
        if dist >= reach || dist < 1e-6 {
            return;
        }
        let n = d / dist;
        let push = n * ((reach - dist) * 0.5);
        self.bodies[a].pos -= push;
        self.bodies[b].pos += push;
        let rel = (self.bodies[b].vel - self.bodies[a].vel).dot(n);
        if rel < 0.0 {
            // Equal masses: each gets half of the exchanged impulse.
            let j = -(1.0 + RESTITUTION) * rel * 0.5;
            self.bodies[a].vel -= n * j;
            self.bodies[b].vel += n * j;
        }
    }
}

fn ground_contact(terrain: &TerrainSource, b: &mut Body, h: f32) {
    let ground = terrain.height_at(b.pos.x, b.pos.z);
    let n = terrain.normal_at(b.pos.x, b.pos.z, 0.05);
    // Distance from the centre to the local tangent plane of the terrain.
    let gap = (b.pos.y - ground) * n.y - b.radius;
    if gap >= 0.0 {
        return;
    }
    b.pos += n * -gap;
    let vn = b.vel.dot(n);
    if vn < 0.0 {
        let e = if -vn > BOUNCE_THRESHOLD { RESTITUTION } else { 0.0 };
        let normal_impulse = -(1.0 + e) * vn;
        b.vel += n * normal_impulse;
        // Coulomb friction on the tangential velocity, bounded by the normal impulse
        // (plus gravity's share this substep, so resting spheres decelerate at mu*g).
        let vt = b.vel - n * b.vel.dot(n);
        let speed = vt.length();
        if speed > 0.0 {
            let drop = FRICTION * (normal_impulse + GRAVITY * h * n.y);
            b.vel -= vt * (drop.min(speed) / speed);
        }
    }
}

fn wall_contact(b: &mut Body, min: Vec2, max: Vec2) {
    let r = b.radius;
    let bounce = |p: &mut f32, v: &mut f32, lo: f32, hi: f32| {
        let (lo, hi) = if lo <= hi {
            (lo, hi)
        } else {
            let m = 0.5 * (lo + hi);
            (m, m)
        };
        if *p < lo {
            *p = lo;
            *v = v.abs() * RESTITUTION;
        } else if *p > hi {
            *p = hi;
            *v = -v.abs() * RESTITUTION;
        }
    };
    bounce(&mut b.pos.x, &mut b.vel.x, min.x + r, max.x - r);
    bounce(&mut b.pos.z, &mut b.vel.z, min.y + r, max.y - r);
}
