//! Heights drawn as depth: the depth format of the deformation's capture
//! (actors seen from below) and of the accumulation's sky occlusion (objects
//! seen from the sky), both of which the update pass samples.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

/// Format of the capture depth target and the sky occlusion depth: 16-bit
/// unorm, linear in height over the capture range `[low_m, high_m]`, so one
/// code is `(high_m - low_m) / 65535` (92 µm over the 6 m range of flat
/// ground with 0.5 m of snow) and a captured height is within half of that
/// of the actor's surface. The footprints stored by the points technique are
/// quantised over the same range with the same step (`shared/stamp.wgsl`).
pub const CAPTURE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth16Unorm;

/// Codes of the capture depth target ([`CAPTURE_FORMAT`]).
pub const CAPTURE_CODES: f32 = 65535.0;

/// A depth texture bindable where the update pass reads the occlusion depth.
#[must_use]
pub fn sky_depth_texture(device: &wgpu::Device, resolution: u32) -> wgpu::Texture {
    height_depth_texture(device, "sky occlusion depth", resolution)
}

/// A square `resolution`² depth target of [`CAPTURE_FORMAT`] that passes can
/// also read (the capture, the sky occlusion).
#[must_use]
pub(crate) fn height_depth_texture(device: &wgpu::Device, label: &str, resolution: u32) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width: resolution, height: resolution, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: CAPTURE_FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        view_formats: &[],
    })
}
