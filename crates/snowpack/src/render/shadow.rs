//! The sun's shadow map: one orthographic depth map fitted around the part
//! of the view frustum that receives shadows, stable as the camera turns.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use glam::{Mat4, Vec3};

use super::camera::{Camera, NEAR_M};

/// Depth format of the shadow map.
pub const SHADOW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// How far toward the sun beyond the fitted volume casters are still drawn (m).
pub const CASTER_REACH_M: f32 = 300.0;

/// The light's world-to-clip matrix and the world size of one shadow texel.
///
/// The map covers the bounding sphere of the frustum slice out to `distance`
/// (so its size does not change as the camera rotates) and its centre snaps
/// to whole texels in light space (so edges do not crawl as the camera moves).
#[must_use]
pub fn fit_shadow(camera: &Camera, aspect: f32, sun: Vec3, distance: f32, map_size: u32) -> (Mat4, f32) {
    let corners = camera.frustum_corners(aspect, NEAR_M, distance);
    let center = corners.iter().copied().sum::<Vec3>() / 8.0;
    let radius = corners.iter().map(|c| c.distance(center)).fold(0.0f32, f32::max).ceil().max(1.0);
    let up = if sun.cross(Vec3::Y).length_squared() < 1e-6 { Vec3::Z } else { Vec3::Y };
    let light_view = glam::camera::rh::view::look_to_mat4(Vec3::ZERO, -sun, up);
    let c = light_view.transform_point3(center);
    let texel = 2.0 * radius / map_size as f32;
    let (cx, cy) = ((c.x / texel).round() * texel, (c.y / texel).round() * texel);
    // Light view looks down -z: the near plane toward the sun, past the casters.
    let near = -c.z - radius - CASTER_REACH_M;
    let far = -c.z + radius;
    let proj = glam::camera::rh::proj::directx::orthographic(cx - radius, cx + radius, cy - radius, cy + radius, near, far);
    (proj * light_view, texel)
}

/// The shadow map texture and its views.
pub struct ShadowMap {
    /// Side (texels).
    pub size: u32,
    /// The depth texture's view for rendering and sampling (it keeps the texture alive).
    pub view: wgpu::TextureView,
    /// Comparison sampler with hardware 2x2 filtering.
    pub sampler: wgpu::Sampler,
}

impl ShadowMap {
    /// A `size`² shadow map.
    #[must_use]
    pub fn new(device: &wgpu::Device, size: u32) -> Self {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("shadow map"),
            size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: SHADOW_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("shadow compare"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            compare: Some(wgpu::CompareFunction::LessEqual),
            ..Default::default()
        });
        Self { size, view, sampler }
    }

    /// Bytes of GPU memory held.
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        u64::from(self.size) * u64::from(self.size) * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fitted_map_contains_the_view_and_snaps() {
        let cam = Camera { position: Vec3::new(3.0, 5.0, -10.0), target: Vec3::ZERO, fov_deg: 60.0 };
        let sun = Vec3::new(-0.5, 0.6, 0.4).normalize();
        let (m, texel) = fit_shadow(&cam, 1.5, sun, 60.0, 2048);
        for c in cam.frustum_corners(1.5, NEAR_M, 60.0) {
            let p = m.project_point3(c);
            assert!(p.x.abs() <= 1.0 && p.y.abs() <= 1.0 && (0.0..=1.0).contains(&p.z), "corner {c} at {p}");
        }
        // A small camera move shifts the map by whole texels only.
        let moved = Camera { position: cam.position + Vec3::new(0.013, 0.0, 0.007), target: cam.target + Vec3::new(0.013, 0.0, 0.007), ..cam };
        let (m2, _) = fit_shadow(&moved, 1.5, sun, 60.0, 2048);
        let shift = (m2.project_point3(Vec3::ZERO) - m.project_point3(Vec3::ZERO)) * 2048.0 / 2.0;
        assert!((shift.x - shift.x.round()).abs() < 1e-2 && (shift.y - shift.y.round()).abs() < 1e-2, "shift {shift} texels; texel {texel} m");
    }
}
