//! The accumulation of one set of objects: their atlas on the GPU, their
//! poses, and the passes of a frame in order.

use std::ops::Range;

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Quat, Vec2, Vec3};

use super::atlas::{AtlasBake, AtlasLayout, NO_OWNER};
use super::increment::{IncrementParams, IncrementPass};
use super::occlusion::{OcclusionParams, OcclusionPass};
use super::scatter::{ScatterParams, ScatterPass};
use super::settle::{SettleBuffers, SettleParams, SettlePass};
use super::surface::{AtlasSurfacePass, SurfaceParams};
use super::{ObjectShape, SnowObject};
use crate::error::SnowError;
use crate::frame::{FrameContext, WindowFrame};
use crate::gpu::GpuContext;
use crate::snowfall::Snowfall;

/// One object as the shaders see it (`shared/objects.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ObjectGpu {
    /// Object to window-local space (x and z from the window's corner), columns.
    pub local: [[f32; 4]; 4],
    /// Object to world space, columns.
    pub world: [[f32; 4]; 4],
    /// Rotation only, columns.
    pub rotation: [[f32; 4]; 4],
    /// Albedo rgb and roughness.
    pub colour: [f32; 4],
    /// x: 1 when dilated.
    pub flags: [u32; 4],
}

/// Snow on one object's upward surfaces (world normal within 60° of up).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ObjectStats {
    /// Area-weighted mean depth (m).
    pub mean_m: f32,
    /// Deepest texel (m).
    pub max_m: f32,
    /// Fraction of the upward area under more than 1 mm of snow (`COVERED_M`).
    pub covered_fraction: f32,
}

/// Depth above which a texel counts as covered (m).
pub const COVERED_M: f32 = 0.001;

/// Albedo and roughness of boxes (weathered wood) and spheres and meshes (granite).
const BOX_COLOUR: [f32; 4] = [0.30, 0.20, 0.12, 0.75];
const SPHERE_COLOUR: [f32; 4] = [0.38, 0.37, 0.36, 0.6];

/// Slopes within this of the angle of repose keep only part of the snow that lands (degrees).
pub const CAPACITY_RAMP_DEG: f32 = 10.0;

/// Margin of the occlusion's height range beyond terrain, snow and objects (m).
const HEIGHT_MARGIN_M: f32 = 1.0;

fn storage(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(4),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

fn init(device: &wgpu::Device, label: &str, usage: wgpu::BufferUsages, contents: &[u8]) -> wgpu::Buffer {
    use wgpu::util::DeviceExt as _;
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
}

/// A small deterministic generator for the flutter and the jitter.
fn next_unit(state: &mut u64) -> f32 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
}

/// `d` tilted by up to `max_deg` in a random direction (uniform over the cone's disc).
#[must_use]
pub fn flutter(d: Vec3, max_deg: f32, u1: f32, u2: f32) -> Vec3 {
    let d = d.normalize();
    let angle = max_deg.to_radians() * u1.sqrt();
    let az = std::f32::consts::TAU * u2;
    let (b1, b2) = d.any_orthonormal_pair();
    let tilted = (d * angle.cos() + (b1 * az.cos() + b2 * az.sin()) * angle.sin()).normalize();
    if tilted.y > -crate::snowfall::MIN_DOWNWARD * 0.5 { d } else { tilted }
}

/// The objects' accumulation: atlas, meshes, poses and passes.
pub struct SnowAccumulation {
    objects: Vec<SnowObject>,
    layout: AtlasLayout,
    bake: AtlasBake,
    /// Every object's mesh (`super::ObjectVertex`), for the occlusion and for drawing.
    pub vertices: wgpu::Buffer,
    /// Triangle indices into `vertices`.
    pub indices: wgpu::Buffer,
    index_count: u32,
    ranges: Vec<Range<u32>>,
    /// The coarse meshes the occlusion draws (flat faces need no more).
    occlusion_vertices: wgpu::Buffer,
    occlusion_indices: wgpu::Buffer,
    occlusion_index_count: u32,
    /// `ObjectGpu` per object, rewritten each frame.
    pub object_buffer: wgpu::Buffer,
    normal_area: wgpu::Buffer,
    owner: wgpu::Buffer,
    hits: wgpu::Buffer,
    fresh: wgpu::Buffer,
    acc: wgpu::Buffer,
    /// (height, slope x, slope y, owned) per atlas texel: what the renderer draws.
    pub surface: wgpu::Buffer,
    occlusion: OcclusionPass,
    scatter: ScatterPass,
    increment: IncrementPass,
    settle: SettlePass,
    surface_pass: AtlasSurfacePass,
    rng: u64,
    frame: u32,
    window_resolution: u32,
    /// Whether the increment buffer may hold non-zero values (the last frame scattered).
    fresh_dirty: bool,
}

impl SnowAccumulation {
    /// Lays out `objects` in an atlas of `atlas_resolution`² and uploads it; the
    /// occlusion map has `window_resolution`² pixels of `pixel_m` over the window.
    pub fn new(device: &wgpu::Device, objects: &[SnowObject], atlas_resolution: u32, window_resolution: u32, pixel_m: f32) -> Result<Self, SnowError> {
        for (k, o) in objects.iter().enumerate() {
            if objects[..k].iter().any(|x| x.name == o.name) {
                return Err(SnowError::InvalidParameter { field: "name", why: format!("two objects are named {:?}", o.name) });
            }
        }
        let layout = AtlasLayout::new(objects, atlas_resolution, pixel_m)?;
        for o in objects {
            if let ObjectShape::Mesh(mesh) = &o.shape {
                let how = if mesh.uvs_usable() { "its own UVs" } else { "a chart per triangle (its UVs are missing, outside the unit square or overlapping)" };
                tracing::info!("object {:?}: {} triangles, charted by {how}", o.name, mesh.indices.len() / 3);
            }
        }
        let bake = layout.bake();
        let (vertices, indices, ranges) = layout.meshes(true);
        let (coarse_vertices, coarse_indices, _) = layout.meshes(false);
        let texels = u64::from(atlas_resolution) * u64::from(atlas_resolution);
        let object_buffer = storage(device, "accumulation objects", (objects.len() * size_of::<ObjectGpu>()) as u64);
        let normal_area = init(device, "atlas normal and area", wgpu::BufferUsages::STORAGE, bytemuck::cast_slice(&bake.normal_area));
        let owner = init(device, "atlas owner", wgpu::BufferUsages::STORAGE, bytemuck::cast_slice(&bake.owner));
        let hits = storage(device, "atlas hits", texels * 4);
        let fresh = storage(device, "atlas increment", texels * 4);
        let acc = storage(device, "accumulation", texels * 4);
        let surface = storage(device, "atlas surface", texels * 16);
        let occlusion = OcclusionPass::new(device, window_resolution, &object_buffer);
        let scatter = ScatterPass::new(device, &occlusion.footprint_view, &hits);
        let increment = IncrementPass::new(device, &normal_area, &hits, &fresh);
        let settle = SettlePass::new(device, &SettleBuffers { objects: &object_buffer, normal_area: &normal_area, owner: &owner, fresh: &fresh, acc: &acc });
        let surface_pass = AtlasSurfacePass::new(device, &object_buffer, &owner, &acc, &surface);
        Ok(Self {
            objects: objects.to_vec(),
            layout,
            bake,
            vertices: init(device, "object vertices", wgpu::BufferUsages::VERTEX, bytemuck::cast_slice(&vertices)),
            indices: init(device, "object indices", wgpu::BufferUsages::INDEX, bytemuck::cast_slice(&indices)),
            index_count: indices.len() as u32,
            ranges,
            occlusion_vertices: init(device, "object occlusion vertices", wgpu::BufferUsages::VERTEX, bytemuck::cast_slice(&coarse_vertices)),
            occlusion_indices: init(device, "object occlusion indices", wgpu::BufferUsages::INDEX, bytemuck::cast_slice(&coarse_indices)),
            occlusion_index_count: coarse_indices.len() as u32,
            object_buffer,
            normal_area,
            owner,
            hits,
            fresh,
            acc,
            surface,
            occlusion,
            scatter,
            increment,
            settle,
            surface_pass,
            rng: 0x5eed_0f5a,
            frame: 0,
            window_resolution,
            fresh_dirty: false,
        })
    }

    /// The objects, in their current poses.
    #[must_use]
    pub fn objects(&self) -> &[SnowObject] {
        &self.objects
    }

    /// The atlas layout.
    #[must_use]
    pub fn layout(&self) -> &AtlasLayout {
        &self.layout
    }

    /// The atlas bake (normals, areas, owners, positions per texel).
    #[must_use]
    pub fn bake(&self) -> &AtlasBake {
        &self.bake
    }

    /// Index range of each object's triangles in `indices`.
    #[must_use]
    pub fn index_ranges(&self) -> &[Range<u32>] {
        &self.ranges
    }

    /// Triangles the occlusion draws (the coarse meshes).
    #[must_use]
    pub fn occlusion_triangles(&self) -> u64 {
        u64::from(self.occlusion_index_count / 3)
    }

    /// Total indices of all objects.
    #[must_use]
    pub fn index_count(&self) -> u32 {
        self.index_count
    }

    /// The occlusion depth (window-local, the window's resolution) for the ground's update.
    #[must_use]
    pub fn sky_view(&self) -> &wgpu::TextureView {
        &self.occlusion.depth_view
    }

    /// Moves and turns object `k`; its snow goes with it.
    pub fn set_pose(&mut self, k: usize, position: Vec3, rotation: Quat) {
        if let Some(o) = self.objects.get_mut(k) {
            o.position = position;
            o.rotation = rotation;
        }
    }

    /// Top of the highest object (m), for height ranges.
    #[must_use]
    pub fn top_m(&self) -> f32 {
        self.objects
            .iter()
            .map(|o| {
                let r = match &o.shape {
                    ObjectShape::Box { size_m } => 0.5 * size_m.length(),
                    ObjectShape::Sphere { radius_m } => *radius_m,
                    ObjectShape::Mesh(mesh) => mesh.radius(),
                };
                o.position.y + r
            })
            .fold(f32::NEG_INFINITY, f32::max)
    }

    /// Uploads the objects' matrices for `window` (placed against its corner).
    pub fn upload_poses(&self, queue: &wgpu::Queue, window: &WindowFrame) {
        let corner = window.corner;
        let list: Vec<ObjectGpu> = self
            .objects
            .iter()
            .map(|o| {
                // Sizes are baked into the meshes; a pose is a rotation and a translation.
                let world = Mat4::from_rotation_translation(o.rotation, o.position);
                // The translation relative to the corner in f64, so far from the origin stays exact.
                let local_t = Vec3::new((f64::from(o.position.x) - corner.x) as f32, o.position.y, (f64::from(o.position.z) - corner.y) as f32);
                let local = Mat4::from_rotation_translation(o.rotation, local_t);
                ObjectGpu {
                    local: local.to_cols_array_2d(),
                    world: world.to_cols_array_2d(),
                    rotation: Mat4::from_quat(o.rotation).to_cols_array_2d(),
                    colour: match o.shape {
                        ObjectShape::Box { .. } => BOX_COLOUR,
                        ObjectShape::Sphere { .. } | ObjectShape::Mesh(_) => SPHERE_COLOUR,
                    },
                    flags: [u32::from(o.dilate), 0, 0, 0],
                }
            })
            .collect();
        queue.write_buffer(&self.object_buffer, 0, bytemuck::cast_slice(&list));
    }

    /// Draws the occlusion over `window` for this frame (flutter and jitter
    /// drawn here), covering the heights from its lowest ground to its
    /// highest snow and the objects, and returns its projection, which the
    /// ground's update uses too. Call [`Self::upload_poses`] first, with the
    /// same window.
    pub fn record_occlusion(&mut self, cx: &mut FrameContext<'_>, window: &WindowFrame, snowfall: &Snowfall) -> OcclusionParams {
        let extent_m = window.extent_m;
        let (ground_low_m, ground_high_m) = window.ground_range_m();
        let d = flutter(snowfall.direction, snowfall.flutter_deg, next_unit(&mut self.rng), next_unit(&mut self.rng));
        let texel = extent_m / self.window_resolution as f32;
        let offset = Vec2::new(next_unit(&mut self.rng), next_unit(&mut self.rng)) * texel;
        let low = ground_low_m - HEIGHT_MARGIN_M;
        let high = ground_high_m.max(self.top_m()) + HEIGHT_MARGIN_M;
        let params = OcclusionParams::new(extent_m, 0.5 * (ground_low_m + ground_high_m), (low, high), d, offset);
        self.occlusion.record(cx, &params, (&self.occlusion_vertices, &self.occlusion_indices, self.occlusion_index_count));
        params
    }

    /// Records the atlas passes: scatter and increment when `fall_volume_m3`
    /// (snow per occlusion pixel this frame) is positive, then settle and surface.
    pub fn record_atlas(&mut self, cx: &mut FrameContext<'_>, snowfall: &Snowfall, fall_volume_m3: f32, dt_s: f32) {
        let n = self.layout.resolution;
        if fall_volume_m3 > 0.0 {
            self.scatter.record(cx, &ScatterParams { resolution: self.window_resolution, atlas_resolution: n, frame: self.frame, noise: snowfall.noise });
            self.frame = self.frame.wrapping_add(1);
        }
        // Without snow the increment is zero: written once after the last
        // scatter (which also clears its hits), then left as it is.
        let rows = self.layout.used_rows();
        let scattered = fall_volume_m3 > 0.0;
        if scattered || self.fresh_dirty {
            self.increment.record(cx, rows, &IncrementParams { atlas_resolution: n, volume_m3: fall_volume_m3.max(0.0), _pad: [0; 2] });
        }
        self.fresh_dirty = scattered;
        self.settle.record(cx, rows, &settle_params(snowfall, n, dt_s));
        self.surface_pass.record(cx, rows, &SurfaceParams { atlas_resolution: n, _pad: [0; 3] });
    }

    /// Records only the surface pass (objects without snowfall).
    pub fn record_surface(&self, cx: &mut FrameContext<'_>) {
        self.surface_pass.record(cx, self.layout.used_rows(), &SurfaceParams { atlas_resolution: self.layout.resolution, _pad: [0; 3] });
    }

    /// The accumulation atlas read back (m per texel, row-major); blocking.
    pub fn read_atlas(&self, ctx: &GpuContext) -> Result<Vec<f32>, SnowError> {
        Ok(bytemuck::pod_collect_to_vec(&crate::gpu::read_buffer(ctx, &self.acc)?))
    }

    /// The atlas surface read back: (height, slope x, slope y, owned) per texel; blocking.
    pub fn read_surface(&self, ctx: &GpuContext) -> Result<Vec<[f32; 4]>, SnowError> {
        Ok(bytemuck::pod_collect_to_vec(&crate::gpu::read_buffer(ctx, &self.surface)?))
    }

    /// Snow on each object's upward surfaces, from an atlas read back with [`Self::read_atlas`].
    #[must_use]
    pub fn stats(&self, acc: &[f32]) -> Vec<ObjectStats> {
        let mut sums = vec![(0.0f64, 0.0f64, 0.0f32, 0.0f64); self.objects.len()];
        for (k, &own) in self.bake.owner.iter().enumerate() {
            if own == NO_OWNER {
                continue;
            }
            let o = &self.objects[own as usize];
            let [nx, ny, nz, area] = self.bake.normal_area[k];
            if (o.rotation * Vec3::new(nx, ny, nz)).y < 0.5 {
                continue;
            }
            let a = acc.get(k).copied().unwrap_or(0.0);
            let s = &mut sums[own as usize];
            s.0 += f64::from(area);
            s.1 += f64::from(area) * f64::from(a);
            s.2 = s.2.max(a);
            if a > COVERED_M {
                s.3 += f64::from(area);
            }
        }
        sums.iter()
            .map(|&(area, depth, max, covered)| {
                if area > 0.0 {
                    ObjectStats { mean_m: (depth / area) as f32, max_m: max, covered_fraction: (covered / area) as f32 }
                } else {
                    ObjectStats::default()
                }
            })
            .collect()
    }

    /// Bytes of GPU memory held, by resource.
    #[must_use]
    pub fn memory_bytes(&self) -> Vec<(&'static str, u64)> {
        let w = u64::from(self.window_resolution) * u64::from(self.window_resolution);
        vec![
            ("occlusion depth", w * 4),
            ("occlusion footprint", w * 8),
            ("atlas normal+area", self.normal_area.size()),
            ("atlas owner", self.owner.size()),
            ("atlas hits", self.hits.size()),
            ("atlas increment", self.fresh.size()),
            ("accumulation", self.acc.size()),
            ("atlas surface", self.surface.size()),
            ("object meshes", self.vertices.size() + self.indices.size() + self.occlusion_vertices.size() + self.occlusion_indices.size()),
        ]
    }
}

/// The settle pass's uniforms for `snowfall` over a frame of `dt_s`.
#[must_use]
pub fn settle_params(snowfall: &Snowfall, atlas_resolution: u32, dt_s: f32) -> SettleParams {
    SettleParams {
        atlas_resolution,
        max_m: snowfall.max_m,
        cos_repose: snowfall.repose_deg.to_radians().cos(),
        falloff: 1.0 - (-snowfall.falloff_per_s * dt_s.max(0.0)).exp(),
        cos_full: (snowfall.repose_deg - CAPACITY_RAMP_DEG).max(0.0).to_radians().cos(),
        _pad: [0; 3],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flutter_stays_within_its_cone_and_covers_it() {
        let d = Vec3::new(0.3, -1.0, 0.1).normalize();
        let mut state = 1u64;
        let mut widest = 0.0f32;
        for _ in 0..2000 {
            let t = flutter(d, 8.0, next_unit(&mut state), next_unit(&mut state));
            let angle = t.dot(d).clamp(-1.0, 1.0).acos().to_degrees();
            assert!(angle <= 8.0 + 1e-3, "tilted {angle} degrees");
            widest = widest.max(angle);
        }
        assert!(widest > 7.5, "the cone is covered (widest {widest})");
    }
}
