//! Stamp pass: deferred point deformation (`stamp.wgsl`), Rise of the Tomb
//! Raider's technique as Wasmut 2019 (section 4.2.2) describes it.
//!
//! Contact points come from deformers: a sphere's lowest point with the
//! paraboloid that osculates it (`scale = 1 / 2r`), a box's lowest point with
//! its narrower half-width, or an explicit [`Deformer::Point`]. Each writes
//! `h = foot + d^2 * scale` over a `range_texels` square into the packed
//! toroidal stamp buffer (see `shared/stamp.wgsl` for the format). A point
//! swept over the frame stamps the lowest of the footprints along its
//! segment (see [`crate::deform::sweep`]).

use bytemuck::{Pod, Zeroable};
use glam::DVec2;

use crate::frame::FrameContext;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::{Deformer, shaders};

use super::resources::DeformResources;
use crate::deform::shape::DeformerExt;
use crate::pass::window_bindings::WindowAccess;

/// A texel no footprint has touched, in the packed stamp buffer
/// (`STAMP_EMPTY` in `shared/stamp.wgsl`).
pub const STAMP_EMPTY: u32 = u32::MAX;

/// Uniforms of `stamp.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct StampParams {
    /// Global texel index of local (0, 0): `[column, row]`.
    pub origin: [i32; 2],
    /// Texels per side.
    pub resolution: u32,
    /// Side of each footprint square (texels).
    pub range_texels: u32,
    /// Texel size (m).
    pub texel_m: f32,
    /// Height of code 0 (m).
    pub low_m: f32,
    /// Height of code 65535 (m).
    pub high_m: f32,
    /// Points to stamp.
    pub count: u32,
    /// `origin` wrapped into the storage (`super::window::storage_origin`):
    /// [`StampPass::record`] writes it from `origin` and `resolution`, so
    /// the value given here is not used.
    pub storage_origin: [u32; 2],
    /// Tile side of the changed-tile flags (texels); 0: no flags are written.
    pub share_side: u32,
    /// Slots per side of the flags ([`crate::replicate::flags::ShareGrid`]).
    pub share_keys: u32,
}

impl StampParams {
    /// Size of one quantisation step (m); rounding errs by at most half of it.
    #[must_use]
    pub fn quantum_m(&self) -> f32 {
        (self.high_m - self.low_m) / 65535.0
    }
}

/// The contact point of a deformer: (where, foot height, scale).
fn contact(d: &Deformer) -> Option<(glam::Vec3, f32, f32)> {
    match *d {
        Deformer::Sphere { center, radius } if radius > 0.0 => Some((center, center.y - radius, 0.5 / radius)),
        Deformer::Box { center, half_extents, .. } => {
            let half = half_extents.x.min(half_extents.z).max(1e-3);
            Some((center, d.lowest_point(), 0.5 / half))
        }
        Deformer::Point { position, scale_per_m } => Some((position, position.y, scale_per_m)),
        // The lowest point of the tyre, as round as its narrower dimension.
        Deformer::Wheel { center, radius, half_width, .. } => Some((center, d.lowest_point(), 0.5 / radius.min(half_width).max(1e-3))),
        Deformer::Sphere { .. } => None,
    }
}

/// Contact points of `deformers` whose footprint can touch the window, as
/// `[x, foot, z, scale, x0, foot0, z0, 0]`: window-local x, foot height and
/// window-local z now, then where the point was swept from (`previous[k]`
/// for deformer k where it is `Some`, see
/// `crate::deform::sweep::DeformerHistory::sweeps`; otherwise the same
/// point). Points whose foot stays above `high_m` (above any snow) are
/// dropped.
#[must_use]
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
pub fn contact_points(deformers: &[Deformer], previous: &[Option<Deformer>], window_corner_m: DVec2, params: &StampParams) -> Vec<[f32; 8]> {
    let mut points = Vec::new();
    contact_points_into(deformers, previous, window_corner_m, params, &mut points);
    points
}

/// [`contact_points`] into `points` (cleared first), reusing its memory.
pub fn contact_points_into(deformers: &[Deformer], previous: &[Option<Deformer>], window_corner_m: DVec2, params: &StampParams, points: &mut Vec<[f32; 8]>) {
    let extent = f64::from(params.texel_m) * f64::from(params.resolution);
    let reach = f64::from(params.texel_m) * f64::from(params.range_texels);
    points.clear();
    points.extend(deformers.iter().enumerate().filter_map(|(k, d)| {
        let (at, foot, scale) = contact(d)?;
        let (from, foot0) = previous.get(k).copied().flatten().and_then(|p| contact(&p)).map_or((at, foot), |(at, foot, _)| (at, foot));
        let (x, z) = (f64::from(at.x) - window_corner_m.x, f64::from(at.z) - window_corner_m.y);
        let (x0, z0) = (f64::from(from.x) - window_corner_m.x, f64::from(from.z) - window_corner_m.y);
        let outside = x.max(x0) + reach < 0.0 || x.min(x0) - reach > extent || z.max(z0) + reach < 0.0 || z.min(z0) - reach > extent;
        (!outside && foot.min(foot0) < params.high_m && scale.is_finite() && scale >= 0.0)
            .then_some([x as f32, foot, z as f32, scale, x0 as f32, foot0, z0 as f32, 0.0])
    }));
}

/// Largest number of points one frame stamps (65535 x 65535 workgroups would
/// allow more; this bounds the instance buffer).
pub const MAX_POINTS: usize = 1 << 20;

/// Writes this frame's footprints into the stamp buffer.
pub struct StampPass {
    pass: ComputePass<StampParams>,
    points: wgpu::Buffer,
}

fn points_buffer(device: &wgpu::Device, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("stamp points"),
        size: bytes.max(256),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

impl StampPass {
    /// Builds the pipeline and binds it to `res`'s changed-tile flags.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        let shape = PassShape {
            label: "stamp",
            source: shaders::STAMP,
            slots: &[Slot::Read, Slot::ReadWrite],
            specialise_on: None,
            constants: &[],
            window: Some(WindowAccess::Write),
        };
        let mut stamp = Self { pass: ComputePass::new(device, &shape, Some(&res.bindings)), points: points_buffer(device, 32 * 256) };
        stamp.bind(device, res);
        stamp
    }

    fn bind(&mut self, device: &wgpu::Device, res: &DeformResources) {
        self.pass.bind(device, &[self.points.as_entire_binding(), res.share_flags.as_entire_binding()]);
    }

    /// Records the stamping of this frame's `points` (nothing when there are
    /// none), growing the points' buffer when needed. At most [`MAX_POINTS`]
    /// are stamped; returns how many were left out (0 unless a frame brings
    /// more), for the caller to report.
    #[must_use = "points left out must be reported"]
    pub fn record(&mut self, cx: &mut FrameContext<'_>, res: &DeformResources, params: &StampParams, points: &[[f32; 8]]) -> usize {
        let dropped = points.len().saturating_sub(MAX_POINTS);
        let points = &points[..points.len().min(MAX_POINTS)];
        let bytes: &[u8] = bytemuck::cast_slice(points);
        if bytes.len() as u64 > self.points.size() {
            self.points = points_buffer(cx.device(), (bytes.len() as u64).next_power_of_two());
            self.bind(cx.device(), res);
        }
        if bytes.is_empty() {
            return dropped;
        }
        cx.queue().write_buffer(&self.points, 0, bytes);
        let count = points.len() as u32;
        let p = StampParams { count, storage_origin: super::window::storage_origin(params.origin, params.resolution), ..*params };
        let groups = if count <= 65535 { (count, 1) } else { (65535, count.div_ceil(65535)) };
        self.pass.record(cx, Some(&res.bindings), &p, 0, groups);
        dropped
    }
}
