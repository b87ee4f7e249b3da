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

/// Below the surface the occlusion saw by less than this, a point still
/// counts as seen by the sky (m): the occlusion depth's own quantisation.
pub const SKY_BIAS_M: f32 = 0.02;

/// The sky test against the objects' occlusion depth
/// (`crate::accumulate::OcclusionParams`): a point of the window is projected
/// along the snowfall onto the occlusion map and is reached by the sky when
/// nothing there is above it. One struct for the passes that test it (the
/// update's snowfall and the snow coat's), each carrying it in its uniform at
/// a 16-byte offset; `shared/sky_test.wgsl`'s `SkyTest`, whose CPU twin is
/// [`Self::reaches`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SkyTest {
    /// The occlusion's shear, `d.xz / -d.y` for the fall direction `d`.
    pub shear: [f32; 2],
    /// The occlusion's jitter against the window (m).
    pub offset_m: [f32; 2],
    /// Height of the occlusion's projection plane (m).
    pub y0_m: f32,
    /// Height at occlusion depth 1 (m).
    pub low_m: f32,
    /// Height at occlusion depth 0 (m).
    pub high_m: f32,
    /// Padding to 16 bytes.
    pub _pad: u32,
}

impl SkyTest {
    /// No objects: a test that is never read (its pass's sky flag is off),
    /// with a range that divides by no zero.
    pub const NONE: Self = Self { shear: [0.0; 2], offset_m: [0.0; 2], y0_m: 0.0, low_m: 0.0, high_m: 1.0, _pad: 0 };

    /// 1 where the sky reaches window-local point `q_m` (m) at height `h_m`,
    /// 0 where the occlusion `depth` (window-local, `resolution`² texels of
    /// `texel_m`) saw something above it; off the map the sky reaches. CPU
    /// twin of `sky_test_pixel` and `sky_test_seen` (`shared/sky_test.wgsl`).
    #[must_use]
    pub fn reaches(&self, q_m: [f32; 2], h_m: f32, texel_m: f32, resolution: u32, depth: &[f32]) -> f32 {
        let x = q_m[0] + self.shear[0] * (h_m - self.y0_m) + self.offset_m[0];
        let z = q_m[1] + self.shear[1] * (h_m - self.y0_m) + self.offset_m[1];
        let (px, pz) = ((x / texel_m).floor(), (z / texel_m).floor());
        let r = resolution as f32;
        if px < 0.0 || pz < 0.0 || px >= r || pz >= r {
            return 1.0;
        }
        let seen = depth[pz as usize * resolution as usize + px as usize];
        let here = (self.high_m - (h_m + SKY_BIAS_M)) / (self.high_m - self.low_m);
        if here <= seen { 1.0 } else { 0.0 }
    }
}

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
