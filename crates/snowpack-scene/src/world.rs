//! The scene in motion: still, kinematic and keyframed actors, and the test
//! bed's physics spheres (Wasmut 2019, section 3) on the CPU.
//!
//! Spheres collide with the terrain under the snow (so they plough through
//! it), with each other (a uniform grid keeps that linear in their number),
//! and with the walls of the window area, which keeps them in bounds.

use std::collections::HashMap;

use glam::{Mat4, Quat, Vec2, Vec3};
use snowpack::skin::feet::{FootTracker, FootstepEvent};
use snowpack::skin::AnimationPlayer;
use snowpack::testing::Rng;
use snowpack::{Deformer, TerrainSource};

use crate::scene::{Motion, Scene, ShapeSpec, WindowSpec};

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
}

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
    min: Vec2,
    max: Vec2,
    footsteps: Vec<FootstepEvent>,
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
            min: center - Vec2::splat(half),
            max: center + Vec2::splat(half),
            footsteps: Vec::new(),
        };
        for spec in &scene.actors {
            let body = match (&spec.motion, &spec.shape) {
                (Motion::Physics { position, velocity }, ShapeSpec::Sphere { radius_m }) => {
                    world.bodies.push(Body { pos: *position, vel: *velocity, radius: *radius_m });
                    Some(world.bodies.len() - 1)
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
            world.actors.push(Actor { shape: spec.shape.clone(), motion: spec.motion.clone(), body, anim, heading: 0.0, feet });
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
        // Face the direction of travel from the first frame on.
        world.update_headings();
        world
    }

    fn update_headings(&mut self) {
        for k in 0..self.actors.len() {
            let v = self.actor_velocity(k);
            if Vec2::new(v.x, v.z).length() > 1e-3 {
                self.actors[k].heading = v.x.atan2(v.z);
            }
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
        Some(match (&a.motion, a.body) {
            (_, Some(b)) => self.bodies[b].pos,
            (Motion::Path(keys), None) => path_at(keys, self.time),
            (Motion::Kinematic { position, velocity } | Motion::Physics { position, velocity }, None) => {
                *position + *velocity * self.time
            }
        })
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
            if a.body.is_some() {
                continue; // drawn with the bodies below
            }
            let Some(center) = self.actor_position(i) else { continue };
            out.push(match &a.shape {
                ShapeSpec::Sphere { radius_m } => Deformer::Sphere { center, radius: *radius_m },
                ShapeSpec::Box { size_m, rotation } => {
                    Deformer::Box { center, half_extents: *size_m * 0.5, rotation: *rotation }
                }
                ShapeSpec::Point { scale_per_m } => Deformer::Point { position: center, scale_per_m: *scale_per_m },
                // Characters press the snow with their skinned mesh (see `characters`).
                ShapeSpec::Gltf(_) => continue,
            });
        }
        out.extend(self.bodies.iter().map(|b| Deformer::Sphere { center: b.pos, radius: b.radius }));
        out
    }

    /// Advances time by `dt` seconds.
    pub fn step(&mut self, dt: f32) {
        let h = dt / SUBSTEPS as f32;
        for _ in 0..SUBSTEPS {
            self.substep(h);
        }
        self.time += dt;
        for a in &mut self.actors {
            if let Some(player) = &mut a.anim {
                player.advance(dt);
            }
        }
        self.update_headings();
        self.detect_footsteps();
    }

    /// Footstep events since the last call, oldest first.
    pub fn take_footsteps(&mut self) -> Vec<FootstepEvent> {
        std::mem::take(&mut self.footsteps)
    }

    /// Where each foot's sole is now (world), for every character: (actor, soles).
    #[must_use]
    pub fn soles(&self) -> Vec<(usize, Vec<Vec3>)> {
        self.characters()
            .into_iter()
            .filter_map(|c| {
                let a = &self.actors[c.actor];
                let ShapeSpec::Gltf(g) = &a.shape else { return None };
                let clip = a.anim.as_ref().map_or(g.clip, |p| p.clip);
                let soles = g.feet.iter().map(|f| c.nodes[f.node].w_axis.truncate() - Vec3::Y * f.planted(clip) * g.scale).collect();
                Some((c.actor, soles))
            })
            .collect()
    }

    fn detect_footsteps(&mut self) {
        for (actor, soles) in self.soles() {
            let Some(root) = self.actor_position(actor) else { continue };
            let v = self.actor_velocity(actor);
            let base = self.terrain.height_at(root.x, root.z);
            // The sole's height over the ground the root walks on, following the terrain under each foot.
            let heights: Vec<f32> = soles.iter().map(|p| p.y - (root.y + self.terrain.height_at(p.x, p.z) - base)).collect();
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
                });
            }
        }
    }

    /// Velocity of actor `i` now (m/s).
    fn actor_velocity(&self, i: usize) -> Vec3 {
        let Some(a) = self.actors.get(i) else { return Vec3::ZERO };
        match (&a.motion, a.body) {
            (_, Some(b)) => self.bodies[b].vel,
            (Motion::Path(keys), None) => {
                let h = 0.02;
                (path_at(keys, self.time + h) - path_at(keys, self.time - h)) / (2.0 * h)
            }
            (Motion::Kinematic { velocity, .. } | Motion::Physics { velocity, .. }, None) => *velocity,
        }
    }

    /// The pose of every glTF character now.
    #[must_use]
    pub fn characters(&self) -> Vec<CharacterPose> {
        let mut out = Vec::new();
        for (k, a) in self.actors.iter().enumerate() {
            let (ShapeSpec::Gltf(g), Some(player)) = (&a.shape, &a.anim) else { continue };
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
        let (lo, hi) = if lo <= hi { (lo, hi) } else { let m = 0.5 * (lo + hi); (m, m) };
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
