//! Skinned, animated actors: a node hierarchy with joints, animation clips
//! (step, linear and cubic-spline keys, as glTF 2.0 defines them), playback
//! with speed and cross-fade, GPU skinning ([`skinning::SkinningPass`],
//! CPU twin `cpu::skinning`) and the snow characters carry ([`coat`]). Reading files is the scene crate's job;
//! this module takes decoded data.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

pub mod coat;
pub mod feet;
pub mod sinking;
pub mod skinning;

use glam::{Mat4, Quat, Vec3, Vec4};

/// A node's local transform: translation, rotation, scale (applied S, then R, then T).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Translation.
    pub translation: Vec3,
    /// Rotation (unit quaternion).
    pub rotation: Quat,
    /// Scale.
    pub scale: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self { translation: Vec3::ZERO, rotation: Quat::IDENTITY, scale: Vec3::ONE }
    }
}

impl Transform {
    /// The matrix `T * R * S`.
    #[must_use]
    pub fn matrix(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }

    /// Blend toward `other` by `w` (0 keeps `self`): lerp of translation and
    /// scale, shortest-path slerp of rotation.
    #[must_use]
    pub fn blend(&self, other: &Self, w: f32) -> Self {
        Self {
            translation: self.translation.lerp(other.translation, w),
            rotation: self.rotation.slerp(other.rotation, w).normalize(),
            scale: self.scale.lerp(other.scale, w),
        }
    }
}

/// One node of the hierarchy.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    /// Name (joint names are matched against foot patterns).
    pub name: String,
    /// Parent index; `None` for a root. Parents come before children.
    pub parent: Option<usize>,
    /// Rest transform (what animations without a channel for it keep).
    pub rest: Transform,
}

/// A node hierarchy and the joints of one skin.
#[derive(Clone, Debug, PartialEq)]
pub struct Skeleton {
    /// Every node, parents before children.
    pub nodes: Vec<Node>,
    /// Node index of each joint (the skin's joint order).
    pub joints: Vec<usize>,
    /// Inverse bind matrix of each joint.
    pub inverse_bind: Vec<Mat4>,
}

impl Skeleton {
    /// Checks the hierarchy's order, the joint table and that every matrix and rest transform is finite.
    pub fn validate(&self) -> Result<(), String> {
        for (k, n) in self.nodes.iter().enumerate() {
            if n.parent.is_some_and(|p| p >= k) {
                return Err(format!("node {k} ({}) comes before its parent", n.name));
            }
        }
        if self.joints.len() != self.inverse_bind.len() {
            return Err(format!("{} joints but {} inverse bind matrices", self.joints.len(), self.inverse_bind.len()));
        }
        if let Some(j) = self.joints.iter().find(|&&j| j >= self.nodes.len()) {
            return Err(format!("joint node {j} does not exist"));
        }
        if let Some(k) = self.inverse_bind.iter().position(|m| !m.is_finite()) {
            return Err(format!("the inverse bind matrix of joint {k} is not finite"));
        }
        if let Some((k, n)) =
            self.nodes.iter().enumerate().find(|(_, n)| !(n.rest.translation.is_finite() && n.rest.rotation.is_finite() && n.rest.scale.is_finite()))
        {
            return Err(format!("node {k} ({}) has a rest transform that is not finite", n.name));
        }
        Ok(())
    }

    /// The rest transforms of every node.
    #[must_use]
    pub fn rest_pose(&self) -> Vec<Transform> {
        self.nodes.iter().map(|n| n.rest).collect()
    }

    /// Global matrix of every node for local transforms `locals`.
    #[must_use]
    pub fn globals(&self, locals: &[Transform]) -> Vec<Mat4> {
        let mut out: Vec<Mat4> = Vec::with_capacity(self.nodes.len());
        for (k, n) in self.nodes.iter().enumerate() {
            let local = locals.get(k).copied().unwrap_or(n.rest).matrix();
            let m = match n.parent {
                Some(p) => out[p] * local,
                None => local,
            };
            out.push(m);
        }
        out
    }

    /// Skinning matrix of each joint: its global matrix times its inverse bind matrix.
    #[must_use]
    pub fn joint_matrices(&self, globals: &[Mat4]) -> Vec<Mat4> {
        self.joints.iter().zip(&self.inverse_bind).map(|(&j, ib)| globals[j] * *ib).collect()
    }

    /// Index of the first node whose name contains `pattern` (case-insensitive).
    #[must_use]
    pub fn find(&self, pattern: &str) -> Option<usize> {
        let p = pattern.to_ascii_lowercase();
        self.nodes.iter().position(|n| n.name.to_ascii_lowercase().contains(&p))
    }
}

/// How keys are interpolated (glTF `sampler.interpolation`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// Hold each key until the next.
    Step,
    /// Linear (spherical for rotations).
    Linear,
    /// Hermite spline; each key stores in-tangent, value, out-tangent.
    CubicSpline,
}

/// Which property a channel animates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Property {
    /// Translation (xyz).
    Translation,
    /// Rotation (quaternion xyzw).
    Rotation,
    /// Scale (xyz).
    Scale,
}

/// One animated property of one node.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// Node index.
    pub node: usize,
    /// What it animates.
    pub property: Property,
    /// Interpolation.
    pub interpolation: Interpolation,
    /// Key times (s), increasing.
    pub times: Vec<f32>,
    /// Key values (xyz0 or xyzw); three per key for cubic splines (in-tangent, value, out-tangent).
    pub values: Vec<Vec4>,
}

impl Channel {
    /// Checks key counts, that times are finite and non-decreasing, that values
    /// are finite, and that rotation keys normalise to unit quaternions.
    pub fn validate(&self) -> Result<(), String> {
        let per_key = if self.interpolation == Interpolation::CubicSpline { 3 } else { 1 };
        if self.times.is_empty() {
            return Err("a channel without keys".into());
        }
        if self.values.len() != self.times.len() * per_key {
            return Err(format!("{} keys but {} values", self.times.len(), self.values.len()));
        }
        if self.times.windows(2).any(|w| w[1] < w[0]) || self.times.iter().any(|t| !t.is_finite()) {
            return Err("key times must be finite and increasing".into());
        }
        if let Some(k) = self.values.iter().position(|v| !v.is_finite()) {
            return Err(format!("value {k} is not finite"));
        }
        // A key of length 0 (or one whose length squared leaves f32: 1e-38,
        // 1e20) normalises to NaN or to nothing, and NaN joints reach the
        // capture (found by fuzzing, issue 34). Cubic tangents may be anything.
        if self.property == Property::Rotation {
            let unit = |v: Vec4| (Quat::from_vec4(v).normalize().length() - 1.0).abs() < 1e-3;
            if let Some(k) = (0..self.times.len()).find(|&k| !unit(self.value(k))) {
                return Err(format!("rotation key {k} is {}, not a rotation (it does not normalise to a unit quaternion)", self.value(k)));
            }
        }
        Ok(())
    }

    fn value(&self, key: usize) -> Vec4 {
        if self.interpolation == Interpolation::CubicSpline { self.values[key * 3 + 1] } else { self.values[key] }
    }

    /// The value at time `t` (clamped to the keys' range).
    #[must_use]
    pub fn sample(&self, t: f32) -> Vec4 {
        let n = self.times.len();
        if n == 1 || t <= self.times[0] {
            return self.value(0);
        }
        if t >= self.times[n - 1] {
            return self.value(n - 1);
        }
        let k = self.times.partition_point(|&x| x <= t) - 1;
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let dt = t1 - t0;
        let u = if dt > 0.0 { (t - t0) / dt } else { 0.0 };
        let rotation = self.property == Property::Rotation;
        match self.interpolation {
            Interpolation::Step => self.value(k),
            Interpolation::Linear => {
                let (a, b) = (self.value(k), self.value(k + 1));
                if rotation { Vec4::from(Quat::from_vec4(a).normalize().slerp(Quat::from_vec4(b).normalize(), u)) } else { a.lerp(b, u) }
            }
            Interpolation::CubicSpline => {
                let p0 = self.values[k * 3 + 1];
                let m0 = self.values[k * 3 + 2] * dt;
                let p1 = self.values[(k + 1) * 3 + 1];
                let m1 = self.values[(k + 1) * 3] * dt;
                let (u2, u3) = (u * u, u * u * u);
                let v = p0 * (2.0 * u3 - 3.0 * u2 + 1.0) + m0 * (u3 - 2.0 * u2 + u) + p1 * (-2.0 * u3 + 3.0 * u2) + m1 * (u3 - u2);
                if rotation { v.normalize_or_zero() } else { v }
            }
        }
    }
}

/// A named animation.
#[derive(Clone, Debug, PartialEq)]
pub struct Clip {
    /// Name (scene files select clips by it).
    pub name: String,
    /// Length (s): the last key time of any channel.
    pub duration: f32,
    /// Channels.
    pub channels: Vec<Channel>,
}

impl Clip {
    /// Local transforms of every node of `skeleton` at time `t` (s, wrapped
    /// into the clip when `looping`); nodes without channels keep their rest.
    #[must_use]
    pub fn sample(&self, skeleton: &Skeleton, t: f32, looping: bool) -> Vec<Transform> {
        let t = if looping && self.duration > 0.0 { t.rem_euclid(self.duration) } else { t.clamp(0.0, self.duration) };
        let mut locals = skeleton.rest_pose();
        for c in &self.channels {
            let Some(local) = locals.get_mut(c.node) else { continue };
            let v = c.sample(t);
            match c.property {
                Property::Translation => local.translation = v.truncate(),
                // A cubic spline between valid keys can still pass through 0.
                Property::Rotation => local.rotation = Quat::from_vec4(v.normalize_or(Vec4::W)),
                Property::Scale => local.scale = v.truncate(),
            }
        }
        locals
    }
}

/// Plays clips on one skeleton: a current clip at a speed, and a cross-fade
/// from the previous one when the clip changes (walk to run).
#[derive(Clone, Debug, PartialEq)]
pub struct AnimationPlayer {
    /// Index of the clip playing.
    pub clip: usize,
    /// Time in it (s).
    pub time: f32,
    /// Playback speed (1 = as authored).
    pub speed: f32,
    /// Clip fading out, its time, and the fade's progress and length (s).
    fade: Option<(usize, f32, f32, f32)>,
}

impl AnimationPlayer {
    /// Plays `clip` from its start at speed 1.
    #[must_use]
    pub fn new(clip: usize) -> Self {
        Self { clip, time: 0.0, speed: 1.0, fade: None }
    }

    /// Switches to `clip`, cross-fading over `fade_s` seconds (0: cut).
    pub fn play(&mut self, clip: usize, fade_s: f32) {
        if clip == self.clip {
            return;
        }
        self.fade = (fade_s > 0.0).then_some((self.clip, self.time, 0.0, fade_s));
        self.clip = clip;
        self.time = 0.0;
    }

    /// Switches to `clip` like [`Self::play`], starting it at the phase (the
    /// fraction of its cycle) the current clip has reached, so a walk fades
    /// into a run with the same foot forward.
    pub fn play_synced(&mut self, clip: usize, fade_s: f32, clips: &[Clip]) {
        if clip == self.clip {
            return;
        }
        let phase = clips.get(self.clip).filter(|c| c.duration > 0.0).map_or(0.0, |c| self.time.rem_euclid(c.duration) / c.duration);
        self.play(clip, fade_s);
        self.time = phase * clips.get(clip).map_or(0.0, |c| c.duration);
    }

    /// Advances by `dt` seconds of game time.
    pub fn advance(&mut self, dt: f32) {
        self.time += dt * self.speed;
        if let Some((clip, time, progress, length)) = self.fade {
            let progress = progress + dt;
            self.fade = (progress < length).then_some((clip, time + dt * self.speed, progress, length));
        }
    }

    /// Local transforms now, looping the clips.
    #[must_use]
    pub fn locals(&self, skeleton: &Skeleton, clips: &[Clip]) -> Vec<Transform> {
        let Some(current) = clips.get(self.clip) else { return skeleton.rest_pose() };
        let now = current.sample(skeleton, self.time, true);
        match self.fade {
            Some((from, time, progress, length)) if from < clips.len() => {
                let before = clips[from].sample(skeleton, time, true);
                let w = (progress / length).clamp(0.0, 1.0);
                before.iter().zip(&now).map(|(a, b)| a.blend(b, w)).collect()
            }
            _ => now,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chain() -> Skeleton {
        // root at the origin, a child 1 m up, a grandchild 1 m further.
        let node = |name: &str, parent, y| Node { name: name.into(), parent, rest: Transform { translation: Vec3::Y * y, ..Transform::default() } };
        let nodes = vec![node("root", None, 0.0), node("b_Leg", Some(0), 1.0), node("b_LeftFoot", Some(1), 1.0)];
        let globals = Skeleton { nodes: nodes.clone(), joints: vec![], inverse_bind: vec![] }.globals(&[]);
        Skeleton { nodes, joints: vec![0, 1, 2], inverse_bind: globals.iter().map(|m| m.inverse()).collect() }
    }

    #[test]
    fn the_rest_pose_skins_to_identity() {
        let s = chain();
        s.validate().expect("valid");
        for m in s.joint_matrices(&s.globals(&s.rest_pose())) {
            assert!(m.abs_diff_eq(Mat4::IDENTITY, 1e-6), "{m}");
        }
        assert_eq!(s.find("leftfoot"), Some(2));
    }

    #[test]
    fn keys_interpolate_as_gltf_says() {
        let ch = |interpolation, values: Vec<Vec4>| Channel { node: 0, property: Property::Translation, interpolation, times: vec![0.0, 1.0], values };
        let lin = ch(Interpolation::Linear, vec![Vec4::ZERO, Vec4::new(2.0, 0.0, 0.0, 0.0)]);
        assert!((lin.sample(0.25).x - 0.5).abs() < 1e-6);
        assert_eq!(lin.sample(-1.0).x, 0.0);
        assert_eq!(lin.sample(9.0).x, 2.0);
        let step = ch(Interpolation::Step, vec![Vec4::ZERO, Vec4::ONE]);
        assert_eq!(step.sample(0.99).x, 0.0);
        // Zero tangents: the Hermite curve is smoothstep between the values.
        let cubic = ch(Interpolation::CubicSpline, vec![Vec4::ZERO, Vec4::ZERO, Vec4::ZERO, Vec4::ZERO, Vec4::ONE, Vec4::ZERO]);
        cubic.validate().expect("valid");
        let u = 0.3f32;
        assert!((cubic.sample(u).x - u * u * (3.0 - 2.0 * u)).abs() < 1e-6);
        // Rotations slerp: half way between identity and 90° about y is 45°.
        let q90 = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        let rot = Channel {
            node: 0,
            property: Property::Rotation,
            interpolation: Interpolation::Linear,
            times: vec![0.0, 1.0],
            values: vec![Vec4::from(Quat::IDENTITY), Vec4::from(q90)],
        };
        let half = Quat::from_vec4(rot.sample(0.5));
        assert!(half.angle_between(Quat::from_rotation_y(std::f32::consts::FRAC_PI_4)) < 1e-5);
    }

    #[test]
    fn a_clip_moves_a_joint_and_a_cross_fade_blends() {
        let s = chain();
        let bend = |angle: f32| Clip {
            name: format!("bend{angle}"),
            duration: 1.0,
            channels: vec![Channel {
                node: 1,
                property: Property::Rotation,
                interpolation: Interpolation::Linear,
                times: vec![0.0, 1.0],
                values: vec![Vec4::from(Quat::from_rotation_z(angle)), Vec4::from(Quat::from_rotation_z(angle))],
            }],
        };
        let clips = [bend(0.0), bend(std::f32::consts::FRAC_PI_2)];
        let foot = |locals: &[Transform]| s.globals(locals)[2].transform_point3(Vec3::ZERO);
        let mut player = AnimationPlayer::new(0);
        assert!((foot(&player.locals(&s, &clips)) - Vec3::new(0.0, 2.0, 0.0)).length() < 1e-5);
        player.play(1, 1.0);
        player.advance(0.5);
        // Half way through the fade: the leg is bent 45°.
        let half = foot(&player.locals(&s, &clips));
        let want = Vec3::new(-std::f32::consts::FRAC_1_SQRT_2, 1.0 + std::f32::consts::FRAC_1_SQRT_2, 0.0);
        assert!((half - want).length() < 1e-4, "{half} vs {want}");
        player.advance(0.6);
        assert!((foot(&player.locals(&s, &clips)) - Vec3::new(-1.0, 1.0, 0.0)).length() < 1e-4);
    }
}
