//! A perspective camera with reverse-Z and an infinite far plane (depth
//! precision where it matters, out to the horizon).

use glam::{Mat4, Vec3};

/// Near plane distance (m).
pub const NEAR_M: f32 = 0.05;

/// Where the eye is and what it sees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position (m).
    pub position: Vec3,
    /// Point looked at (m).
    pub target: Vec3,
    /// Vertical field of view (degrees).
    pub fov_deg: f32,
}

impl Camera {
    /// Unit view direction.
    #[must_use]
    pub fn forward(&self) -> Vec3 {
        (self.target - self.position).try_normalize().unwrap_or(Vec3::NEG_Z)
    }

    /// World-to-view matrix (right-handed, y up; z up on screen when looking straight down).
    #[must_use]
    pub fn view(&self) -> Mat4 {
        let f = self.forward();
        let up = if f.cross(Vec3::Y).length_squared() < 1e-8 { Vec3::Z } else { Vec3::Y };
        glam::camera::rh::view::look_to_mat4(self.position, f, up)
    }

    /// View-to-clip matrix for `aspect` (width / height): reverse-Z, infinite far plane.
    #[must_use]
    pub fn projection(&self, aspect: f32) -> Mat4 {
        glam::camera::rh::proj::directx::perspective_infinite_reverse(self.fov_deg.to_radians(), aspect, NEAR_M)
    }

    /// World-to-clip matrix.
    #[must_use]
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        self.projection(aspect) * self.view()
    }

    /// The eight corners of the view frustum between `near` and `far` metres.
    #[must_use]
    pub fn frustum_corners(&self, aspect: f32, near: f32, far: f32) -> [Vec3; 8] {
        let f = self.forward();
        let view = self.view();
        let inv = view.inverse();
        let right = inv.x_axis.truncate();
        let up = inv.y_axis.truncate();
        let t = (self.fov_deg.to_radians() * 0.5).tan();
        let mut out = [Vec3::ZERO; 8];
        for (k, d) in [near, far].into_iter().enumerate() {
            let c = self.position + f * d;
            let (hh, hw) = (d * t, d * t * aspect);
            out[k * 4] = c - right * hw - up * hh;
            out[k * 4 + 1] = c + right * hw - up * hh;
            out[k * 4 + 2] = c + right * hw + up * hh;
            out[k * 4 + 3] = c - right * hw + up * hh;
        }
        out
    }
}
