//! The demo's camera: orbit around a point, fly with WASD and the mouse, or
//! follow the player's sphere from behind.

use glam::{Vec2, Vec3};
use snowpack::Camera;

/// How the camera moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraMode {
    /// Left drag turns around the target, right drag pans, the wheel zooms.
    Orbit,
    /// Right drag looks, WASD moves, Q/E go down/up, the wheel sets the speed.
    Fly,
    /// Behind the player; WASD drives the player, the wheel zooms.
    Follow,
}

impl CameraMode {
    /// Every mode with its label.
    pub const ALL: [(Self, &'static str); 3] = [(Self::Orbit, "orbit"), (Self::Fly, "fly"), (Self::Follow, "follow player")];

    /// The next mode (Tab).
    #[must_use]
    pub fn next(self) -> Self {
        match self {
            Self::Orbit => Self::Fly,
            Self::Fly => Self::Follow,
            Self::Follow => Self::Orbit,
        }
    }
}

/// Movement keys held this frame, as axes in -1..=1.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MoveInput {
    /// Forward (W) minus back (S).
    pub forward: f32,
    /// Right (D) minus left (A).
    pub right: f32,
    /// Up (E) minus down (Q).
    pub up: f32,
    /// Shift held: faster.
    pub fast: bool,
}

/// The camera's state in every mode.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraRig {
    /// Current mode.
    pub mode: CameraMode,
    /// Orbit and follow: the point looked at.
    pub target: Vec3,
    /// Heading (radians, 0 looks toward +z).
    pub yaw: f32,
    /// Elevation of the view direction (radians, negative looks down).
    pub pitch: f32,
    /// Orbit and follow: distance from the target (m).
    pub distance: f32,
    /// Fly: the eye (m).
    pub eye: Vec3,
    /// Fly: speed (m/s).
    pub speed: f32,
    /// Vertical field of view (degrees).
    pub fov_deg: f32,
}

impl CameraRig {
    /// A rig that starts where the scene's camera is, orbiting its target.
    #[must_use]
    pub fn from_camera(camera: &Camera) -> Self {
        let offset = camera.position - camera.target;
        let distance = offset.length().max(0.5);
        let dir = -offset / distance;
        Self {
            mode: CameraMode::Orbit,
            target: camera.target,
            yaw: dir.x.atan2(dir.z),
            pitch: dir.y.clamp(-1.0, 1.0).asin(),
            distance,
            eye: camera.position,
            speed: 8.0,
            fov_deg: camera.fov_deg,
        }
    }

    /// Unit view direction from yaw and pitch.
    #[must_use]
    pub fn forward(&self) -> Vec3 {
        Vec3::new(self.yaw.sin() * self.pitch.cos(), self.pitch.sin(), self.yaw.cos() * self.pitch.cos())
    }

    /// Horizontal forward and right unit vectors (for driving the player).
    #[must_use]
    pub fn ground_axes(&self) -> (Vec2, Vec2) {
        let f = Vec2::new(self.yaw.sin(), self.yaw.cos());
        (f, Vec2::new(-f.y, f.x))
    }

    /// The camera to draw with; `player` is the followed actor's centre.
    #[must_use]
    pub fn camera(&self, player: Vec3) -> Camera {
        let (position, target) = match self.mode {
            CameraMode::Orbit => (self.target - self.forward() * self.distance, self.target),
            CameraMode::Fly => (self.eye, self.eye + self.forward()),
            CameraMode::Follow => {
                let target = player + Vec3::Y * 0.5;
                (target - self.forward() * self.distance, target)
            }
        };
        Camera { position, target, fov_deg: self.fov_deg }
    }

    /// Switches mode keeping the view where it is.
    pub fn set_mode(&mut self, mode: CameraMode, player: Vec3) {
        let camera = self.camera(player);
        self.mode = mode;
        match mode {
            CameraMode::Fly => self.eye = camera.position,
            CameraMode::Orbit => self.target = camera.position + self.forward() * self.distance,
            CameraMode::Follow => {
                // Third person: a few metres behind and above, looking a little down.
                self.distance = 8.0;
                self.pitch = -0.4;
            }
        }
    }

    /// Mouse drag in pixels with the left (`primary`) or right button.
    pub fn drag(&mut self, delta: Vec2, primary: bool) {
        let turn = 0.005;
        match (self.mode, primary) {
            (CameraMode::Orbit, false) => {
                // Pan in the ground plane, scaled by the distance.
                let (f, r) = self.ground_axes();
                let scale = self.distance * 0.0015;
                let pan = r * -delta.x * scale + f * delta.y * scale;
                self.target += Vec3::new(pan.x, 0.0, pan.y);
            }
            _ => {
                self.yaw -= delta.x * turn;
                self.pitch = (self.pitch - delta.y * turn).clamp(-1.5, 1.5);
            }
        }
    }

    /// Mouse wheel in lines (positive away from the user).
    pub fn wheel(&mut self, lines: f32) {
        match self.mode {
            CameraMode::Fly => self.speed = (self.speed * 1.2f32.powf(lines)).clamp(0.5, 500.0),
            CameraMode::Orbit | CameraMode::Follow => self.distance = (self.distance * 0.9f32.powf(lines)).clamp(1.0, 2000.0),
        }
    }

    /// Fly mode's movement over `dt` seconds.
    pub fn fly(&mut self, input: MoveInput, dt: f32) {
        if self.mode != CameraMode::Fly {
            return;
        }
        let speed = self.speed * if input.fast { 4.0 } else { 1.0 };
        let f = self.forward();
        let r = f.cross(Vec3::Y).normalize_or_zero();
        self.eye += (f * input.forward + r * input.right + Vec3::Y * input.up) * speed * dt;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rig_from_a_camera_gives_that_camera_back() {
        let cam = Camera { position: Vec3::new(3.0, 10.0, -20.0), target: Vec3::new(1.0, 0.0, 2.0), fov_deg: 55.0 };
        let rig = CameraRig::from_camera(&cam);
        let back = rig.camera(Vec3::ZERO);
        assert!((back.position - cam.position).length() < 1e-4, "{} vs {}", back.position, cam.position);
        assert!((back.target - cam.target).length() < 1e-4);
    }

    #[test]
    fn switching_mode_keeps_the_view() {
        let cam = Camera { position: Vec3::new(0.0, 5.0, -10.0), target: Vec3::ZERO, fov_deg: 60.0 };
        let mut rig = CameraRig::from_camera(&cam);
        rig.set_mode(CameraMode::Fly, Vec3::ZERO);
        let fly = rig.camera(Vec3::ZERO);
        assert!((fly.position - cam.position).length() < 1e-4);
        assert!((fly.forward() - cam.forward()).length() < 1e-4);
        rig.fly(MoveInput { forward: 1.0, ..MoveInput::default() }, 1.0);
        assert!((rig.eye - cam.position - cam.forward() * 8.0).length() < 1e-3, "moved to {}", rig.eye);
    }

    #[test]
    fn the_ground_axes_match_the_view() {
        let rig = CameraRig::from_camera(&Camera { position: Vec3::new(0.0, 3.0, -10.0), target: Vec3::new(0.0, 3.0, 0.0), fov_deg: 60.0 });
        let (f, r) = rig.ground_axes();
        assert!((f - Vec2::Y).length() < 1e-5, "{f}");
        // Looking along +z with y up, the screen's right is -x.
        assert!((r - Vec2::NEG_X).length() < 1e-5, "{r}");
    }
}
