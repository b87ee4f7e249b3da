//! Image-based sky light: an equirectangular HDR environment (a file, or a
//! procedural sky), prefiltered on the GPU into irradiance and GGX levels
//! that the lit passes sample, with the sun found as its brightest direction.

use glam::Vec3;

use crate::error::SnowError;
use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::shaders;

/// Direction of equirect coordinates (u, v) (same as `equirect_dir` in `shared/frame.wgsl`).
#[must_use]
pub fn equirect_dir(u: f32, v: f32) -> Vec3 {
    let phi = (u - 0.5) * 2.0 * std::f32::consts::PI;
    let theta = v * std::f32::consts::PI;
    Vec3::new(theta.sin() * phi.sin(), theta.cos(), -theta.sin() * phi.cos())
}

/// Equirect coordinates (u, v) of a unit direction (same as `dir_equirect`).
#[must_use]
pub fn dir_equirect(d: Vec3) -> (f32, f32) {
    let u = d.x.atan2(-d.z) / (2.0 * std::f32::consts::PI) + 0.5;
    let v = d.y.clamp(-1.0, 1.0).acos() / std::f32::consts::PI;
    (u, v)
}

/// Widest environment image accepted (texels).
pub const ENVIRONMENT_MAX_W: u32 = 16384;
/// Tallest environment image accepted (texels).
pub const ENVIRONMENT_MAX_H: u32 = 8192;

/// Width of the downsampled map the prefilter integrates.
pub const DOWNSAMPLED_W: u32 = 64;
/// Height of the downsampled map.
pub const DOWNSAMPLED_H: u32 = 32;
/// Width of each prefiltered level (`ENV_W` in `shared/lighting.wgsl`).
pub const PREFILTERED_W: u32 = 32;
/// Height of each prefiltered level (`ENV_H`).
pub const PREFILTERED_H: u32 = 16;
/// Irradiance plus five GGX roughness levels (`ENV_SPECULAR_LEVELS` + 1).
pub const PREFILTERED_LEVELS: u32 = 6;
/// Luminance above which texels are clamped before prefiltering (the sun is lit directly).
pub const CLAMP_LUMINANCE: f32 = 8.0;

/// An equirectangular radiance map (linear RGB, row 0 at the zenith).
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Radiance per texel (rgb, 1).
    pub texels: Vec<[f32; 4]>,
}

impl EnvironmentMap {
    /// Decodes a Radiance `.hdr` image. Its size is checked from the header
    /// before anything is decoded (from `DOWNSAMPLED_W` x `DOWNSAMPLED_H` to
    /// `ENVIRONMENT_MAX_W` x `ENVIRONMENT_MAX_H`), and every decoded value
    /// must be finite.
    pub fn from_hdr(bytes: &[u8]) -> Result<Self, crate::SnowError> {
        use image::ImageDecoder as _;
        let bad = |why: String| SnowError::Environment(why);
        let reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), image::ImageFormat::Hdr);
        let decoder = reader.into_decoder().map_err(|e| bad(format!("not a readable Radiance HDR image: {e}")))?;
        let (width, height) = decoder.dimensions();
        if width < DOWNSAMPLED_W || height < DOWNSAMPLED_H {
            return Err(bad(format!("{width}x{height} is smaller than {DOWNSAMPLED_W}x{DOWNSAMPLED_H}")).into());
        }
        if width > ENVIRONMENT_MAX_W || height > ENVIRONMENT_MAX_H {
            return Err(bad(format!("{width}x{height} is larger than {ENVIRONMENT_MAX_W}x{ENVIRONMENT_MAX_H}")).into());
        }
        let image = image::DynamicImage::from_decoder(decoder).map_err(|e| bad(e.to_string()))?.into_rgb32f();
        if let Some((k, p)) = image.pixels().enumerate().find(|(_, p)| !p.0.iter().all(|c| c.is_finite())) {
            return Err(bad(format!("pixel ({}, {}) is {:?}, not finite", k as u32 % width, k as u32 / width, p.0)).into());
        }
        let texels = image.pixels().map(|p| [p[0].max(0.0), p[1].max(0.0), p[2].max(0.0), 1.0]).collect();
        Ok(Self { width, height, texels })
    }

    /// A clear procedural sky: blue zenith, pale horizon, grey ground, a sun
    /// disc with a glow toward `sun` (unit, toward the sun).
    #[must_use]
    pub fn procedural(sun: Vec3) -> Self {
        let (width, height) = (256u32, 128u32);
        let sun = sun.normalize();
        let mut texels = Vec::with_capacity((width * height) as usize);
        for y in 0..height {
            for x in 0..width {
                let d = equirect_dir((x as f32 + 0.5) / width as f32, (y as f32 + 0.5) / height as f32);
                let up = d.y.max(0.0);
                let sky = Vec3::new(0.75, 0.85, 1.0).lerp(Vec3::new(0.22, 0.42, 0.9), up.powf(0.5));
                let ground = Vec3::new(0.3, 0.3, 0.32);
                let mut c = if d.y >= 0.0 { sky } else { ground.lerp(sky, (1.0 + d.y * 8.0).max(0.0)) };
                let cos = d.dot(sun);
                c += Vec3::new(1.0, 0.9, 0.7) * (cos.max(0.0).powf(64.0) * 0.8);
                if cos > 0.9995 {
                    c += Vec3::new(1.0, 0.95, 0.85) * 500.0;
                }
                texels.push([c.x, c.y, c.z, 1.0]);
            }
        }
        Self { width, height, texels }
    }

    /// The brightest direction above the horizon (the sun) and its colour
    /// normalised to a maximum channel of 1.
    #[must_use]
    pub fn brightest(&self) -> (Vec3, Vec3) {
        let mut best = (0usize, f32::NEG_INFINITY);
        for (k, t) in self.texels.iter().enumerate() {
            let row = k as u32 / self.width;
            if row >= self.height / 2 {
                break;
            }
            let lum = 0.2126 * t[0] + 0.7152 * t[1] + 0.0722 * t[2];
            if lum > best.1 {
                best = (k, lum);
            }
        }
        let (x, y) = (best.0 as u32 % self.width, best.0 as u32 / self.width);
        let mut dir = equirect_dir((x as f32 + 0.5) / self.width as f32, (y as f32 + 0.5) / self.height as f32);
        // A sun right on the horizon lights nothing; keep it a little above.
        dir.y = dir.y.max(0.05);
        let t = self.texels[best.0];
        let colour = Vec3::new(t[0], t[1], t[2]);
        let colour = colour / colour.max_element().max(1e-6);
        (dir.normalize(), colour)
    }

    /// Radiance looked up along a direction (nearest texel), for tests and tools.
    #[must_use]
    pub fn radiance(&self, d: Vec3) -> Vec3 {
        let (u, v) = dir_equirect(d);
        let x = ((u * self.width as f32) as u32).min(self.width - 1);
        let y = ((v * self.height as f32) as u32).min(self.height - 1);
        let t = self.texels[(y * self.width + x) as usize];
        Vec3::new(t[0], t[1], t[2])
    }
}

/// Parameters of both environment passes (`EnvParams` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct EnvParams {
    /// Source width.
    pub src_w: u32,
    /// Source height.
    pub src_h: u32,
    /// Destination width.
    pub dst_w: u32,
    /// Destination height.
    pub dst_h: u32,
    /// Luminance clamp of the downsample.
    pub clamp_luminance: f32,
    /// Levels the prefilter writes.
    pub levels: u32,
    /// Padding.
    pub _pad: [u32; 2],
}

/// The environment on the GPU: the full map (for the sky), the downsampled
/// one and the prefiltered levels (for lighting), and the passes that make them.
pub struct EnvironmentPass {
    /// Full-resolution radiance, row-major vec4.
    pub full: wgpu::Buffer,
    /// Downsampled radiance.
    pub downsampled: wgpu::Buffer,
    /// Prefiltered levels (irradiance, then GGX).
    pub prefiltered: wgpu::Buffer,
    /// Full map's size.
    pub size: (u32, u32),
    downsample: (wgpu::ComputePipeline, wgpu::BindGroup),
    prefilter: (wgpu::ComputePipeline, wgpu::BindGroup),
}

fn storage_buffer(device: &wgpu::Device, label: &str, texels: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: texels * 16,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

impl EnvironmentPass {
    /// Uploads `env` and builds both passes (record them with [`Self::record`]).
    #[must_use]
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, env: &EnvironmentMap) -> Self {
        let full = storage_buffer(device, "environment", u64::from(env.width) * u64::from(env.height));
        queue.write_buffer(&full, 0, bytemuck::cast_slice(&env.texels));
        let downsampled = storage_buffer(device, "environment downsampled", u64::from(DOWNSAMPLED_W * DOWNSAMPLED_H));
        let prefiltered = storage_buffer(device, "environment prefiltered", u64::from(PREFILTERED_W * PREFILTERED_H * PREFILTERED_LEVELS));
        let entries = [layout::uniform(0, wgpu::ShaderStages::COMPUTE), layout::storage(1, true), layout::storage(2, false)];
        let make = |label: &str, source: &str, params: EnvParams, src: &wgpu::Buffer, dst: &wgpu::Buffer| {
            let (pipeline, bgl) = layout::compute_pipeline(device, label, source, &entries);
            let uniform = layout::uniform_buffer::<EnvParams>(device, label);
            queue.write_buffer(&uniform, 0, bytemuck::bytes_of(&params));
            let bg = layout::bind_group(device, label, &bgl, &[uniform.as_entire_binding(), src.as_entire_binding(), dst.as_entire_binding()]);
            (pipeline, bg)
        };
        let downsample = make(
            "env downsample",
            shaders::ENV_DOWNSAMPLE,
            EnvParams {
                src_w: env.width,
                src_h: env.height,
                dst_w: DOWNSAMPLED_W,
                dst_h: DOWNSAMPLED_H,
                clamp_luminance: CLAMP_LUMINANCE,
                levels: 1,
                _pad: [0; 2],
            },
            &full,
            &downsampled,
        );
        let prefilter = make(
            "env prefilter",
            shaders::ENV_PREFILTER,
            EnvParams {
                src_w: DOWNSAMPLED_W,
                src_h: DOWNSAMPLED_H,
                dst_w: PREFILTERED_W,
                dst_h: PREFILTERED_H,
                clamp_luminance: CLAMP_LUMINANCE,
                levels: PREFILTERED_LEVELS,
                _pad: [0; 2],
            },
            &downsampled,
            &prefiltered,
        );
        Self { full, downsampled, prefiltered, size: (env.width, env.height), downsample, prefilter }
    }

    /// Records the downsample and the prefilter (once per environment).
    pub fn record(&self, cx: &mut FrameContext<'_>) {
        let (encoder, timer) = (&mut *cx.encoder, &mut *cx.timer);
        let (p, bg) = &self.downsample;
        layout::dispatch(encoder, timer, "env downsample", p, bg, (layout::groups(DOWNSAMPLED_W, 8), layout::groups(DOWNSAMPLED_H, 8)));
        let (p, bg) = &self.prefilter;
        let slot = timer.reserve("env prefilter");
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("env prefilter"), timestamp_writes: timer.compute_writes(slot) });
        pass.set_pipeline(p);
        pass.set_bind_group(0, bg, &[]);
        pass.dispatch_workgroups(layout::groups(PREFILTERED_W, 8), layout::groups(PREFILTERED_H, 8), PREFILTERED_LEVELS);
    }

    /// Bytes of GPU memory held.
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        self.full.size() + self.downsampled.size() + self.prefiltered.size()
    }
}
