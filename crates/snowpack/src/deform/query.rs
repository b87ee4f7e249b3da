//! Point queries: the game asks for the snow at a few points (feet, wheels,
//! AI probes; up to thousands) and gets depth, compaction and normal a frame
//! or two later, without stalling. A compute pass gathers the points into a
//! small buffer (`query.wgsl`, CPU twin `cpu/query.rs`) and a ring of staging
//! buffers brings it back; a frame whose staging buffers are all still in
//! flight (the GPU is behind) skips its gather instead of waiting.

use bytemuck::{Pod, Zeroable};
use glam::{Vec2, Vec3};
use snowpack_share::mechanics::{SnowColumn, SnowMechanics};

use crate::frame::FrameContext;
use crate::gpu::{ReadbackRing, layout};
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::shaders;

use super::resources::DeformResources;
use crate::pass::window_bindings::WindowAccess;

/// Staging buffers of the answer ring: one being written, one in flight, one
/// arriving. More would only add latency.
const ANSWER_SLOTS: usize = 3;
/// Points the pass holds before it first grows.
const INITIAL_CAPACITY: u32 = 256;

/// Uniforms of `query.wgsl`.
#[doc(hidden)]
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct QueryParams {
    /// Global texel index of the window's local (0, 0).
    pub origin: [i32; 2],
    /// Texels per side.
    pub resolution: u32,
    /// Points asked.
    pub count: u32,
    /// Texel size (m).
    pub texel_m: f32,
    /// Rest depth of fresh snow (m).
    pub depth_m: f32,
    /// 1 when the window has snowfall (a per-texel `fallen` buffer).
    pub use_fallen: u32,
    /// Padding.
    pub _pad: u32,
}

/// One answer as the GPU writes it (`Sample` in `query.wgsl`).
#[doc(hidden)]
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RawSample {
    /// Persistent snow height (m).
    pub height_m: f32,
    /// Displayed surface height (m).
    pub surface_m: f32,
    /// Terrain height (m).
    pub terrain_m: f32,
    /// Untouched snow height (m).
    pub rest_m: f32,
    /// Displayed surface normal.
    pub normal: [f32; 3],
    /// 1 inside the window, 0 outside.
    pub inside: f32,
    /// Packed snow (m of fresh snow squeezed into the column).
    pub packed_m: f32,
}

/// Which request an answer belongs to: returned by
/// [`crate::SnowDeformation::encode`] for a frame that asked points
/// ([`crate::SnowFrame::with_queries`]), counting from 1.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct QueryTicket(pub u64);

/// The snow at one asked point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointSample {
    /// Persistent snow surface height (m): the trails, without rims or blur.
    pub height_m: f32,
    /// Displayed surface height (m): with rims and blur, what is drawn.
    pub surface_m: f32,
    /// Terrain height under the snow (m).
    pub terrain_m: f32,
    /// Height of untouched snow here (m): terrain + rest depth + snowfall so far.
    pub rest_m: f32,
    /// Unit normal of the displayed surface.
    pub normal: Vec3,
    /// Fresh snow that presses squeezed into the column here (m of fresh
    /// snow; 0 where untouched): with [`Self::depth_m`], its mass and
    /// density ([`Self::density_kg_m3`]).
    pub packed_m: f32,
}

impl PointSample {
    /// The column of snow here: its depth and packed snow, for the
    /// mechanics' sinkage and resistance
    /// ([`snowpack_share::mechanics::SnowMechanics`], from
    /// [`crate::SnowParams::mechanics`]).
    #[must_use]
    pub fn column(&self) -> SnowColumn {
        SnowColumn { depth_m: self.depth_m(), packed_m: self.packed_m.max(0.0) }
    }

    /// Mean density of the snow here (kg/m³) for the snow's `mechanics`:
    /// fresh snow's where untouched, up to the final density where packed.
    #[must_use]
    pub fn density_kg_m3(&self, mechanics: &SnowMechanics) -> f32 {
        mechanics.density_kg_m3(self.column())
    }

    /// Penetration hardness of the snow here (kPa): the pressure that
    /// sinks a 10 cm plate 10 cm further; harder where packed.
    #[must_use]
    pub fn hardness_kpa(&self, mechanics: &SnowMechanics) -> f32 {
        mechanics.hardness_kpa(self.column())
    }

    /// Snow depth above the terrain (m).
    #[must_use]
    pub fn depth_m(&self) -> f32 {
        (self.height_m - self.terrain_m).max(0.0)
    }

    /// How much of the snow has been pressed out: 0 untouched, 1 pressed to
    /// the ground; `(rest - height) / (rest - terrain)`, 0 where there is no snow to press.
    #[must_use]
    pub fn compaction(&self) -> f32 {
        let column = self.rest_m - self.terrain_m;
        if column <= 1e-6 { 0.0 } else { ((self.rest_m - self.height_m) / column).clamp(0.0, 1.0) }
    }

    /// How far the snow here is pressed below its rest height (m).
    #[must_use]
    pub fn sinkage_m(&self) -> f32 {
        (self.rest_m - self.height_m).max(0.0)
    }
}

impl RawSample {
    /// The sample, or `None` outside the window.
    #[must_use]
    pub fn sample(&self) -> Option<PointSample> {
        (self.inside > 0.5).then(|| PointSample {
            height_m: self.height_m,
            surface_m: self.surface_m,
            terrain_m: self.terrain_m,
            rest_m: self.rest_m,
            normal: Vec3::from(self.normal),
            packed_m: self.packed_m,
        })
    }
}

/// The answer to one request: the points as asked and the snow at each
/// (`None` outside the window or within half a texel of its edge).
#[derive(Clone, Debug, PartialEq)]
pub struct PointAnswers {
    /// The request answered.
    pub ticket: QueryTicket,
    /// The frame whose snow this is (counting from 0).
    pub frame: u64,
    /// The points asked (relative to the floating origin, like deformers).
    pub points: Vec<Vec2>,
    /// The snow at each point, in the same order.
    pub samples: Vec<Option<PointSample>>,
}

impl PointAnswers {
    /// The answered point nearest to `p` within `within_m`, with its sample:
    /// how a game reads a moving foot's snow from an answer a frame or two old.
    #[must_use]
    pub fn nearest(&self, p: Vec2, within_m: f32) -> Option<PointSample> {
        let (k, d2) = self.points.iter().enumerate().map(|(k, q)| (k, q.distance_squared(p))).min_by(|a, b| a.1.total_cmp(&b.1))?;
        if d2 > within_m * within_m {
            return None;
        }
        self.samples[k]
    }
}

/// Counts of the query pipeline since the window was made. The counts
/// beside `skipped` are the tools' (`QueryStatsExt` in `low_level`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct QueryStats {
    /// Requests gathered on the GPU.
    pub(crate) gathered: u64,
    /// Requests answered (delivered to [`crate::SnowDeformation::point_answers`]).
    pub(crate) answered: u64,
    /// Requests not gathered because every staging buffer was still in flight
    /// (the GPU was behind): the frame went on; a later request is answered.
    pub skipped: u64,
    /// Points the pass holds now (it grows to the largest request).
    pub(crate) capacity: u32,
}

/// The tools' view of [`QueryStats`] beyond `skipped` (a named extension
/// trait, so the type has one shape with or without `low_level`).
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait QueryStatsExt {
    /// Requests gathered on the GPU.
    #[must_use]
    fn gathered(&self) -> u64;
    /// Requests answered (delivered to [`crate::SnowDeformation::point_answers`]).
    #[must_use]
    fn answered(&self) -> u64;
    /// Points the pass holds now (it grows to the largest request).
    #[must_use]
    fn capacity(&self) -> u32;
}

impl QueryStatsExt for QueryStats {
    fn gathered(&self) -> u64 {
        self.gathered
    }

    fn answered(&self) -> u64 {
        self.answered
    }

    fn capacity(&self) -> u32 {
        self.capacity
    }
}

/// Gathers asked points on the GPU and brings the answers back through a ring.
#[doc(hidden)]
pub struct QueryPass {
    /// One pipeline with snowfall in the rest height, one without (as used).
    pass: ComputePass<QueryParams>,
    points: wgpu::Buffer,
    samples: wgpu::Buffer,
    ring: ReadbackRing<(QueryTicket, u64, Vec<Vec2>)>,
    capacity: u32,
    stats: QueryStats,
}

fn buffers(device: &wgpu::Device, capacity: u32) -> (wgpu::Buffer, wgpu::Buffer) {
    let points = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("query points"),
        size: u64::from(capacity) * 8,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let samples = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("query samples"),
        size: u64::from(capacity) * size_of::<RawSample>() as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    (points, samples)
}

impl QueryPass {
    /// Builds the pipeline over `res` with room for a first few hundred points.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        let shape = PassShape {
            label: "query",
            source: shaders::QUERY,
            // points, samples, packed snow
            slots: &[Slot::Read, Slot::ReadWrite, Slot::Read],
            specialise_on: Some("QUERY_USE_FALLEN"),
            constants: &res.terrain_constants(),
            window: Some(WindowAccess::Read),
        };
        let mut pass = ComputePass::new(device, &shape, Some(&res.bindings));
        let (points, samples) = buffers(device, INITIAL_CAPACITY);
        pass.bind(device, &[points.as_entire_binding(), samples.as_entire_binding(), res.packed.as_entire_binding()]);
        let ring = ReadbackRing::new(device, "query answers", samples.size(), ANSWER_SLOTS);
        Self { pass, points, samples, ring, capacity: INITIAL_CAPACITY, stats: QueryStats::default() }
    }

    /// Records the gather of `points` (metres from the window's corner, `local`)
    /// and the copy of its answers, tagged with `ticket`, `frame` and the points
    /// as asked. Grows the buffers for a larger request (answers in flight
    /// from before are then dropped). Returns false, recording nothing, when
    /// every staging buffer is in flight.
    pub fn record(
        &mut self,
        cx: &mut FrameContext<'_>,
        res: &DeformResources,
        params: QueryParams,
        local: &[Vec2],
        tag: (QueryTicket, u64, Vec<Vec2>),
    ) -> bool {
        let (device, queue) = (cx.device(), cx.queue());
        let count = local.len() as u32;
        if count > self.capacity {
            self.capacity = count.next_power_of_two();
            let (points, samples) = buffers(device, self.capacity);
            self.pass.bind(device, &[points.as_entire_binding(), samples.as_entire_binding(), res.packed.as_entire_binding()]);
            self.ring = ReadbackRing::new(device, "query answers", samples.size(), ANSWER_SLOTS);
            (self.points, self.samples) = (points, samples);
        }
        let len = u64::from(count) * size_of::<RawSample>() as u64;
        if !self.ring.has_free_slot() {
            self.stats.skipped += 1;
            return false;
        }
        if count > 0 {
            queue.write_buffer(&self.points, 0, bytemuck::cast_slice(local));
            let variant = u32::from(params.use_fallen != 0);
            self.pass.record(cx, Some(&res.bindings), &QueryParams { count, ..params }, variant, (layout::groups(count, 64), 1));
        }
        self.ring.record_copy_len(cx.encoder, &self.samples, len, tag);
        self.stats.gathered += 1;
        true
    }

    /// The newest answer that has arrived since the last call, if any.
    pub fn take_answers(&mut self) -> Option<PointAnswers> {
        let ((ticket, frame, points), bytes) = self.ring.take_latest()?;
        self.stats.answered += 1;
        let raw: Vec<RawSample> = bytemuck::pod_collect_to_vec(&bytes);
        Some(PointAnswers { ticket, frame, points, samples: raw.iter().map(RawSample::sample).collect() })
    }

    /// Whether an answer's mapping callback has yet to run.
    #[must_use]
    pub fn callbacks_pending(&self) -> bool {
        self.ring.callbacks_pending()
    }

    /// Counts so far.
    #[must_use]
    #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "read through `SnowInspect` (`low_level`)"))]
    pub fn stats(&self) -> QueryStats {
        QueryStats { capacity: self.capacity, ..self.stats }
    }

    /// Bytes of GPU memory held: point and answer buffers and the staging ring.
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        self.points.size() + self.samples.size() + self.ring.memory_bytes()
    }
}
