//! One frame of deformation, as an explicit list of passes.

use glam::DVec2;

use crate::RimStyle;
use crate::accumulate::{SnowAccumulation, SnowObject};
use crate::deform::capture::{CaptureInstances, CaptureMesh, CaptureParams, CapturePass, SweptMesh};
use crate::deform::decal::{DEFAULT_PER_ACTOR, DecalPass, DecalRing};
use crate::deform::display::{DisplayParams, DisplayPass};
use crate::deform::params::RANGE_TEXELS;
use crate::deform::params::default_tile_texels;
use crate::deform::query::{PointAnswers, QueryParams, QueryPass, QueryStats, QueryTicket};
use crate::deform::resources::DeformResources;
#[cfg(feature = "low_level")]
use crate::deform::snow_word;
use crate::deform::snow_word::SNOW_QUANTUM_M;
use crate::deform::stamp::{StampParams, StampPass, contact_points_into};
use crate::deform::sweep::DeformerHistory;
use crate::deform::update::{UpdateParams, UpdatePass};
use crate::deform::window::{SlidingWindow, WindowParams, WindowPass};
use crate::error::SnowError;
use crate::frame::{FrameContext, WindowFrame};
#[cfg(feature = "low_level")]
use crate::gpu::PassTimings;
use crate::gpu::{GpuContext, GpuTimer, read_buffer};
use crate::persist::{SnowClock, StoreError, StreamerConfig, TileStreamer};
use crate::skin::skinning::{SkinnedInstance, SkinnedMesh, SkinningPass};
use crate::snowfall::Snowfall;
use crate::tiles::streaming::planes;
use crate::tiles::{TileGrid, TileStats, TileStreaming};
use crate::{Deformer, SnowParams, Technique, TerrainSource};

use super::saved::{STATE_NAME, SavedWindow};

/// Margin of the capture depth range beyond the terrain and the snow (m).
const CAPTURE_MARGIN_M: f32 = 1.0;

/// Top of the capture and footprint height range. Above the snow by the
/// margin, and high enough that a stored footprint's rim has fallen to zero
/// below it: the rounded rim ends where `h = foot + 4 (rest - foot)`, at most
/// `4 rest - 3 low`. A footprint clipped at a lower top would keep a
/// non-zero rim out to the edge of its range and leave a ridge there.
fn capture_top(tmin: f32, tmax: f32, depth_m: f32) -> f32 {
    let low = tmin - CAPTURE_MARGIN_M;
    let rest = tmax + depth_m;
    (rest + CAPTURE_MARGIN_M).max(4.0 * rest - 3.0 * low)
}

/// The default tile keeper: tiles of [`default_tile_texels`] kept in memory
/// up to `budget` bytes. `None` (with a warning) where the resident ring
/// would not fit in one of this adapter's storage buffers (resolutions far
/// above the default): the window then forgets, as with
/// `tile_memory_bytes: None`, rather than failing to be created.
fn keep_in_memory(ctx: &GpuContext, res: &DeformResources, params: &SnowParams, budget: usize) -> Result<Option<TileStreaming>, SnowError> {
    let side = default_tile_texels(params.resolution);
    let grid = TileGrid::new(params.resolution, side)?;
    let bytes = (grid.slot_count() * planes(params.snowfall.is_some(), true) * grid.area() * 4) as u64;
    let limit = ctx.device.limits().max_storage_buffer_binding_size;
    if bytes > limit {
        tracing::warn!("trails are not kept: {bytes} bytes of resident tiles exceed this adapter's {limit} byte buffers (resolution {})", params.resolution);
        return Ok(None);
    }
    let streamer = TileStreamer::in_memory(side, StreamerConfig { memory_budget_bytes: budget, ..StreamerConfig::default() });
    TileStreaming::new(ctx, res, streamer, (params.depth_m, params.snowfall.is_some())).map(Some)
}

/// A deformation window and the passes that update it.
///
/// Per frame: `WindowPass` (newly exposed texels), `CapturePass` (actors
/// from below; techniques depth and combined), `StampPass` (contact points'
/// footprints; points and combined), `UpdatePass` (persistent height with
/// refill), `DisplayPass` (Hanák's remap or point rims, then the optional
/// blur, into the displayed half of each snow word), then `QueryPass` (the
/// points asked with `SnowFrame::with_queries`, answered a frame or two later).
/// Normals are computed where they are used, from the displayed heights.
///
/// Buffers exist only for the techniques used so far: the footprint buffer
/// (`stamps`, 4 bytes a texel) for points and combined, the decal layer (4
/// bytes a texel) for decals. Switching technique ([`Self::set_technique`])
/// to one whose buffer is not there yet allocates it at the next encoded
/// frame (and rebinds the passes and, for the decal layer, renderers that
/// compare `Self::decal_layer`); nothing is freed by switching back. A
/// switch keeps the persistent snow (so trails made by any technique stay)
/// and the stored footprints (rims come back when points do); it changes
/// only which deformers write from the next frame on and how rims are shown.
///
/// Trails stay: texels leaving the window are kept in memory by default
/// ([`SnowParams::tile_memory_bytes`]) and come back, refilled by the time
/// away, when the window returns; [`Self::attach_store`] keeps them on disk
/// instead (and makes [`Self::save`] possible).
pub struct SnowDeformation {
    pub(super) params: SnowParams,
    pub(super) terrain: TerrainSource,
    pub(super) res: DeformResources,
    pub(super) window: SlidingWindow,
    center: DVec2,
    pub(super) capture_params: CaptureParams,
    window_pass: WindowPass,
    capture_pass: CapturePass,
    pub(super) stamp_pass: StampPass,
    decal_pass: DecalPass,
    decals: DecalRing,
    pub(super) update_pass: UpdatePass,
    display_pass: DisplayPass,
    pub(super) timer: GpuTimer,
    query_pass: QueryPass,
    /// Tickets given so far ([`SnowFrame::with_queries`]).
    tickets: u64,
    /// Frames collect no readback ([`Self::hold_readbacks`]).
    readbacks_held: bool,
    answers: Option<PointAnswers>,
    frame: u64,
    exposed_texels: u64,
    /// Snow refill so far, in deficit quanta: the world clock's counter
    /// ([`Self::share_clock`]); the stamp quanta are `clock.stamp_quanta`.
    pub(super) snow_quanta: u64,
    /// Where the refill counters are counted from: they are a function of
    /// the time since (see [`RefillBase`]).
    pub(super) refill_base: RefillBase,
    /// Shared snow ([`Self::enable_sharing`]): flags, gathers, merges.
    pub(super) sharing: Option<crate::replicate::sharing::Sharing>,
    /// The most GPU memory held after any submitted frame (bytes).
    peak_memory_bytes: u64,
    points_last_frame: usize,
    /// Contact points left out because a frame brought more than the stamp pass takes.
    points_dropped: u64,
    skinning: SkinningPass,
    skinned: Vec<SkinnedInstance>,
    /// Skinned meshes posed in the last encoded frame (indices into `skinned`).
    posed: Vec<usize>,
    /// Objects snow settles on, with their atlas and passes.
    pub(super) accumulation: Option<SnowAccumulation>,
    /// Snowfall so far on open ground (m), given to texels the window exposes.
    pub(super) fallen_total_m: f32,
    /// Time, refill and snowfall so far: what a tile away from the window missed.
    pub(super) clock: SnowClock,
    /// The tile keeper (memory by default, or an attached store) and the
    /// resident tiles; `None` when trails are forgotten.
    tiles: Option<TileStreaming>,
    /// [`Self::attach_store`] has been called.
    store_attached: bool,
    /// World (x, z) that deformer and object positions are relative to (f64).
    floating_origin: DVec2,
    /// Last frame's deformers, by index, to sweep this frame's from.
    history: DeformerHistory,
    /// Last frame's positions of the meshes, to sweep them.
    mesh_history: super::sweep::MeshHistory,
    /// The terrain's lowest and highest height (m), found once.
    terrain_bounds: (f32, f32),
    /// Lists one frame fills, kept for their memory so that a frame after
    /// the first allocates nothing for them (however many deformers).
    scratch: FrameScratch,
}

/// Lists [`SnowDeformation::encode`] fills each frame, cleared and refilled.
#[derive(Default)]
struct FrameScratch {
    /// Each deformer's pose to sweep from.
    sweeps: Vec<Option<Deformer>>,
    /// The capture's instances.
    instances: CaptureInstances,
    /// The stamp pass's contact points.
    points: Vec<[f32; 8]>,
    /// Sub-steps of each mesh (posed characters, then the caller's).
    mesh_steps: Vec<u32>,
}

/// Where the cumulative refill counters are counted from: at world time
/// `t` they are `base + floor(rate * (t - time_s) / quantum)` (f64), so two
/// machines agree whatever their frame times; set when the rate changes or a
/// clock is joined or loaded. The world's own base is (0, 0, 0)
/// ([`crate::replicate::WorldIdentity::clock_at`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct RefillBase {
    /// World time the counters start from (s).
    pub time_s: f64,
    /// Snow quanta at `time_s`.
    pub snow_quanta: u64,
    /// Stamp quanta at `time_s`.
    pub stamp_quanta: u64,
}

impl RefillBase {
    /// Quanta counted from `base` by `time_s` at `rate_m_per_s`, `quantum_m` each.
    pub(super) fn quanta_at(&self, base: u64, time_s: f64, rate_m_per_s: f32, quantum_m: f32) -> u64 {
        let quantum = f64::from(quantum_m);
        if quantum <= 0.0 {
            return base;
        }
        // The same expression as `WorldIdentity::clock_at` with a zero base.
        let refill_m = f64::from(rate_m_per_s.max(0.0)) * (time_s - self.time_s).max(0.0);
        base + (refill_m / quantum).floor() as u64
    }
}

/// What presses the snow in one frame: the input of [`SnowDeformation::encode`].
#[derive(Clone, Copy, Debug, Default)]
pub struct SnowFrame<'a> {
    /// Seconds since the last frame (refill and snowfall advance by it).
    pub dt_s: f32,
    /// Spheres, boxes and contact points.
    pub deformers: &'a [Deformer],
    /// Characters: registered skinned meshes in this frame's pose.
    pub poses: &'a [SkinnedPose<'a>],
    /// World-space triangle meshes the caller has already posed this frame
    /// (recorded into the same encoder before [`SnowDeformation::encode`]).
    pub meshes: &'a [CaptureMesh<'a>],
    /// How far (m) any vertex of `meshes[k]` moved since the last frame, an
    /// upper bound: mesh k is swept over that motion when it has one here,
    /// its vertex buffer has `COPY_SRC` usage and it had as many vertices
    /// last frame ([`Self::with_mesh_travel`]); otherwise only its current
    /// pose presses.
    pub mesh_travel_m: &'a [f32],
    /// A stable id per deformer (the same body has the same id every frame),
    /// to find each one's last pose when the list's length or order changes
    /// ([`Self::with_ids`]); empty (or of another length): deformer k is
    /// the same body as last frame's deformer k.
    pub ids: &'a [u64],
    /// Points (x, z relative to the floating origin, like deformers) to
    /// ask the snow at, as this frame leaves it ([`Self::with_queries`]);
    /// `None`: nothing asked.
    pub queries: Option<&'a [glam::Vec2]>,
}

impl<'a> SnowFrame<'a> {
    /// A frame of `dt_s` seconds with `deformers` and nothing else.
    #[must_use]
    pub fn new(dt_s: f32, deformers: &'a [Deformer]) -> Self {
        Self { dt_s, deformers, poses: &[], meshes: &[], mesh_travel_m: &[], ids: &[], queries: None }
    }

    /// The same frame with characters in pose.
    #[must_use]
    pub fn with_poses(mut self, poses: &'a [SkinnedPose<'a>]) -> Self {
        self.poses = poses;
        self
    }

    /// The same frame with caller-posed meshes.
    #[must_use]
    pub fn with_meshes(mut self, meshes: &'a [CaptureMesh<'a>]) -> Self {
        self.meshes = meshes;
        self
    }

    /// The same frame with the motion of each caller mesh since the last
    /// frame (see [`Self::mesh_travel_m`]), so they are swept.
    #[must_use]
    pub fn with_mesh_travel(mut self, travel_m: &'a [f32]) -> Self {
        self.mesh_travel_m = travel_m;
        self
    }

    /// The same frame with a stable id per deformer (see [`Self::ids`]), so
    /// each is swept from its own last pose (see `crate::deform::sweep`).
    #[must_use]
    pub fn with_ids(mut self, ids: &'a [u64]) -> Self {
        self.ids = ids;
        self
    }

    /// The same frame asking for the snow at `points` (world x, z relative
    /// to the floating origin, like deformers) as this frame leaves it.
    /// [`SnowDeformation::encode`] returns the request's ticket; the
    /// answer, tagged with it, arrives a frame or two later in
    /// [`SnowDeformation::point_answers`], and a frame never waits for it.
    /// If the GPU is so far behind that every staging buffer is in flight,
    /// the request is dropped and counted in [`QueryStats::skipped`]: ask
    /// again (games ask every frame).
    #[must_use]
    pub fn with_queries(mut self, points: &'a [glam::Vec2]) -> Self {
        self.queries = Some(points);
        self
    }
}

/// A skinned mesh registered with [`SnowDeformation::add_skinned_mesh`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SkinnedId(usize);

/// One character's pose for a frame: which mesh, its joint matrices and its placement.
#[derive(Clone, Copy, Debug)]
pub struct SkinnedPose<'a> {
    /// The registered mesh.
    pub mesh: SkinnedId,
    /// Skinning matrix of each joint (`crate::skin::Skeleton::joint_matrices`).
    pub joints: &'a [glam::Mat4],
    /// Position, heading and scale in the world.
    pub model: glam::Mat4,
}

impl SnowDeformation {
    /// Allocates a window of `params` over `terrain`, centred on world (x, z).
    pub fn new(ctx: &GpuContext, params: SnowParams, terrain: TerrainSource, center: DVec2) -> Result<Self, SnowError> {
        params.validate()?;
        let limits = ctx.device.limits();
        if params.resolution > limits.max_texture_dimension_2d {
            return Err(SnowError::InvalidParameter {
                field: "resolution",
                why: format!("{} exceeds this adapter's texture limit (max_texture_dimension_2d) of {}", params.resolution, limits.max_texture_dimension_2d),
            });
        }
        let buffer_bytes = params.texel_count() as u64 * 4;
        let buffer_limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        if buffer_bytes > buffer_limit {
            return Err(SnowError::InvalidParameter {
                field: "resolution",
                why: format!(
                    "{} needs {buffer_bytes} byte buffers, above this adapter's buffer limit (max_storage_buffer_binding_size) of {buffer_limit} bytes",
                    params.resolution
                ),
            });
        }
        if let TerrainSource::Heightmap(h) = &terrain {
            let bytes = h.heights_m().len() as u64 * 4;
            if bytes > buffer_limit {
                return Err(SnowError::InvalidParameter {
                    field: "heightmap",
                    why: format!(
                        "{}x{} samples need a {bytes} byte buffer, above this adapter's buffer limit (max_storage_buffer_binding_size) of {buffer_limit} bytes",
                        h.width(),
                        h.height()
                    ),
                });
            }
        }
        let this = ctx.capturing(|| Self::allocate(ctx, params, terrain, center))?;
        ctx.check("creating the deformation passes")?;
        Ok(this)
    }

    fn allocate(ctx: &GpuContext, params: SnowParams, terrain: TerrainSource, center: DVec2) -> Result<Self, SnowError> {
        let (device, queue) = (&ctx.device, &ctx.queue);
        let res = DeformResources::new(device, queue, &params, &terrain);
        let (tmin, tmax) = terrain.height_bounds();
        // Snowfall raises the rest depth by up to `max_m`; footprints are quantised over that range.
        let deepest = params.depth_m + params.snowfall.as_ref().map_or(0.0, |s| s.max_m);
        let capture_params =
            CaptureParams { extent_m: params.extent_m, texel_m: params.texel_m(), low_m: tmin - CAPTURE_MARGIN_M, high_m: capture_top(tmin, tmax, deepest) };
        let tiles = match params.tile_memory_bytes {
            Some(budget) => keep_in_memory(ctx, &res, &params, budget)?,
            None => None,
        };
        Ok(Self {
            window_pass: WindowPass::new(device, &res),
            capture_pass: CapturePass::new(device),
            stamp_pass: StampPass::new(device, &res),
            decal_pass: DecalPass::new(device, queue, params.resolution, params.technique == Technique::Decals),
            decals: DecalRing::new(DEFAULT_PER_ACTOR, center),
            update_pass: UpdatePass::new(device, &res),
            display_pass: DisplayPass::new(device, &res),
            timer: GpuTimer::new(device, queue),
            query_pass: QueryPass::new(device, &res),
            tickets: 0,
            readbacks_held: false,
            answers: None,
            window: SlidingWindow::new(params.resolution),
            center,
            capture_params,
            params,
            terrain,
            res,
            frame: 0,
            exposed_texels: 0,
            snow_quanta: 0,
            refill_base: RefillBase::default(),
            sharing: None,
            peak_memory_bytes: 0,
            points_last_frame: 0,
            points_dropped: 0,
            skinning: SkinningPass::new(device),
            skinned: Vec::new(),
            posed: Vec::new(),
            accumulation: None,
            fallen_total_m: 0.0,
            clock: SnowClock::default(),
            tiles,
            store_attached: false,
            floating_origin: DVec2::ZERO,
            history: DeformerHistory::new(),
            mesh_history: super::sweep::MeshHistory::default(),
            terrain_bounds: (tmin, tmax),
            scratch: FrameScratch::default(),
        })
    }

    /// The parameters in use.
    #[must_use]
    pub fn params(&self) -> &SnowParams {
        &self.params
    }

    /// The terrain under the snow.
    #[must_use]
    pub fn terrain(&self) -> &TerrainSource {
        &self.terrain
    }

    low_level_pub! {
        /// The GPU resources, for renderers (`surface`) and tools.
        #[must_use]
        fn resources(&self) -> &DeformResources {
            &self.res
        }
    }

    /// Places `objects` for snow to settle on (replacing any before, and their
    /// snow): lays out their atlas and builds the accumulation passes.
    pub fn set_objects(&mut self, ctx: &GpuContext, objects: &[SnowObject]) -> Result<(), SnowError> {
        if objects.is_empty() {
            self.accumulation = None;
            self.update_pass.bind_sky(&ctx.device, &self.res, None);
            return Ok(());
        }
        let atlas = self.params.snowfall.as_ref().map_or(Snowfall::default().atlas_resolution, |s| s.atlas_resolution);
        let acc = SnowAccumulation::new(&ctx.device, objects, atlas, self.params.resolution, self.params.texel_m())?;
        self.update_pass.bind_sky(&ctx.device, &self.res, Some(acc.sky_view()));
        self.accumulation = Some(acc);
        ctx.check("creating the accumulation passes")
    }

    low_level_pub! {
        /// The objects' accumulation, when there are objects.
        #[must_use]
        #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
        fn accumulation(&self) -> Option<&SnowAccumulation> {
            self.accumulation.as_ref()
        }
    }

    /// The snow on each object (in [`Self::set_objects`] order): read back
    /// from the GPU, so this blocks; for a save, a test or a debug panel, not
    /// every frame. Empty without objects.
    pub fn read_object_stats(&self, ctx: &GpuContext) -> Result<Vec<crate::accumulate::ObjectStats>, SnowError> {
        match &self.accumulation {
            Some(acc) => Ok(acc.stats(&acc.read_atlas(ctx)?)),
            None => Ok(Vec::new()),
        }
    }

    /// Moves and turns object `k` (in [`Self::set_objects`] order); its snow goes with it.
    pub fn set_object_pose(&mut self, k: usize, position: glam::Vec3, rotation: glam::Quat) {
        if let Some(acc) = &mut self.accumulation {
            acc.set_pose(k, position, rotation);
        }
    }

    /// Changes the snowfall (rate, direction, stability) from the next frame
    /// on; `None` stops it. A window created without snowfall has no buffer
    /// for it, so starting snow there is an error.
    pub fn set_snowfall(&mut self, snowfall: Option<Snowfall>) -> Result<(), SnowError> {
        if let Some(s) = &snowfall {
            s.validate()?;
            if self.params.snowfall.is_none() {
                return Err(SnowError::InvalidParameter {
                    field: "snowfall",
                    why: "the window was created without snowfall; create it with `SnowParams::snowfall` set".into(),
                });
            }
        }
        // The footprint quantisation was fixed at creation from `max_m`.
        if let (Some(new), Some(old)) = (&snowfall, &self.params.snowfall)
            && new.max_m > old.max_m
        {
            return Err(SnowError::InvalidParameter { field: "max_m", why: format!("{} is above the {} m the window was created with", new.max_m, old.max_m) });
        }
        if snowfall.is_some() {
            self.params.snowfall = snowfall;
        } else if let Some(s) = &mut self.params.snowfall {
            s.rate_m_per_s = 0.0;
        }
        Ok(())
    }

    /// Snowfall so far on open ground (m).
    #[must_use]
    pub fn fallen_m(&self) -> f32 {
        self.fallen_total_m
    }

    /// Attaches a tile store: from now on texels leaving the window are kept
    /// through `streamer` (in memory, then on disk; or in memory alone for
    /// [`TileStreamer::in_memory`]) and come back when the window returns,
    /// brought up to the time then. It replaces the memory keeper the window
    /// was created with ([`SnowParams::tile_memory_bytes`]). Call before the
    /// first frame, once. When the store holds a save ([`Self::save`]), the
    /// window's clock, snowfall and position are loaded from it and `true`
    /// returned.
    pub fn attach_store(&mut self, ctx: &GpuContext, mut streamer: TileStreamer) -> Result<bool, SnowError> {
        if self.frame > 0 || self.store_attached {
            return Err(SnowError::InvalidParameter { field: "store", why: "a tile store is attached before the first frame, once".into() });
        }
        let side = streamer.side();
        let saved = match streamer.read_state(STATE_NAME)? {
            Some(bytes) => Some(SavedWindow::decode(&bytes, &streamer.dir().join(STATE_NAME))?),
            None => None,
        };
        // Tiles given up from now on belong to the next save: a crash leaves the last one whole.
        streamer.begin_saves();
        let (low, high, _) = self.stamp_range();
        if let Some(s) = &saved {
            let path = streamer.dir().join(STATE_NAME);
            let mismatch = |why: String| SnowError::Store(StoreError::Mismatch { path: path.clone(), why });
            if s.resolution != self.params.resolution || s.tile_side != side {
                return Err(mismatch(format!(
                    "saved with resolution {} and tiles of {}, the window has {} and {side}",
                    s.resolution, s.tile_side, self.params.resolution
                )));
            }
            if s.texel_m != self.params.texel_m() || s.depth_m != self.params.depth_m || s.stamp_range_m != [low, high] {
                return Err(mismatch(format!(
                    "saved with texel {} m, depth {} m, footprint range {:?}; the window has {} m, {} m, {:?} (extent_m, depth_m, terrain or snowfall max_m changed)",
                    s.texel_m,
                    s.depth_m,
                    s.stamp_range_m,
                    self.params.texel_m(),
                    self.params.depth_m,
                    [low, high]
                )));
            }
        }
        // The memory keeper's resident tiles go first: two rings need not coexist.
        self.tiles = None;
        self.tiles = Some(TileStreaming::new(ctx, &self.res, streamer, (self.params.depth_m, self.params.snowfall.is_some()))?);
        self.store_attached = true;
        if let Some(s) = saved {
            self.clock = s.clock;
            self.fallen_total_m = s.fallen_m;
            // The refill counters go on from the saved clock.
            self.snow_quanta = (s.clock.refill_m / f64::from(SNOW_QUANTUM_M)).floor() as u64;
            self.refill_base = RefillBase { time_s: s.clock.time_s, snow_quanta: self.snow_quanta, stamp_quanta: s.clock.stamp_quanta };
            self.center = s.center;
            self.frame = s.frame;
            return Ok(true);
        }
        Ok(false)
    }

    /// Saves the whole snow state into the attached store: every tile (the
    /// window's texels included) and the window's clock and position; when
    /// it returns `Ok`, the store directory is a complete save that
    /// [`Self::attach_store`] loads. Blocking (a save point, not a frame).
    /// Saving needs a disk store: with tiles kept in memory only (the
    /// default) or not at all it is an error naming `store`.
    pub fn save(&mut self, ctx: &GpuContext) -> Result<(), SnowError> {
        let (low, high, _) = self.stamp_range();
        let origin = self.window.origin();
        let Some(tiles) = self.tiles.as_mut().filter(|t| !t.is_memory_only()) else {
            return Err(SnowError::InvalidParameter {
                field: "store",
                why: "saving needs a disk store (attach_store with a TileStreamer over a TileStore); tiles are kept in memory only or not at all".into(),
            });
        };
        if let Some(origin) = origin {
            tiles.checkpoint(ctx, &self.res, origin, self.clock)?;
        }
        let state = SavedWindow {
            resolution: self.params.resolution,
            tile_side: tiles.grid().side(),
            texel_m: self.params.texel_m(),
            depth_m: self.params.depth_m,
            stamp_range_m: [low, high],
            origin: origin.unwrap_or_default(),
            center: self.center,
            clock: self.clock,
            fallen_m: self.fallen_total_m,
            stamp_carry_m: 0.0,
            frame: self.frame,
        };
        let streamer = tiles.streamer();
        streamer.flush()?;
        // The state goes last, in the save's one atomic commit: a save is
        // complete, every tile with it, once it is there.
        streamer.commit_save(STATE_NAME, state.encode())?;
        Ok(())
    }

    /// Tile traffic and store figures, when tiles are kept (in memory or in
    /// an attached store).
    #[must_use]
    pub fn tile_stats(&self) -> Option<TileStats> {
        self.tiles.as_ref().map(TileStreaming::stats)
    }

    /// Store errors since the last call (disk full, read-only, corrupt tiles
    /// replaced by fresh snow): the frame goes on; the game decides what to tell.
    pub fn take_store_errors(&mut self) -> Vec<StoreError> {
        self.tiles.as_mut().map(TileStreaming::take_errors).unwrap_or_default()
    }

    /// Time, refill and snowfall so far.
    #[must_use]
    pub fn clock(&self) -> SnowClock {
        self.clock
    }

    /// Sets the world (x, z) that deformer and object positions are given
    /// relative to, for worlds far from the origin: f32 positions keep
    /// millimetres only within a few kilometres, so a game 100 km out passes
    /// positions relative to a nearby floating origin, and the window and
    /// tiles, on integer texels, stay exact. The window centre stays in world
    /// coordinates (f64).
    pub fn set_floating_origin(&mut self, origin: DVec2) {
        // Remembered deformers move with the origin (so they still sweep);
        // remembered mesh positions are on the GPU and are forgotten instead.
        let delta = self.floating_origin - origin;
        if delta != DVec2::ZERO {
            self.history.shift(glam::Vec3::new(delta.x as f32, 0.0, delta.y as f32));
            self.mesh_history.clear();
        }
        self.floating_origin = origin;
    }

    /// The floating origin (world m).
    #[must_use]
    pub fn floating_origin(&self) -> DVec2 {
        self.floating_origin
    }

    /// Sets the refill rate (m/s); takes effect next frame. The refill
    /// counters go on from now at the new rate.
    pub fn set_refill(&mut self, refill_m_per_s: f32) {
        self.params.refill_m_per_s = refill_m_per_s.max(0.0);
        self.refill_base = RefillBase { time_s: self.clock.time_s, snow_quanta: self.snow_quanta, stamp_quanta: self.clock.stamp_quanta };
    }

    /// Sets the rim strength; takes effect next frame.
    pub fn set_elevation(&mut self, elevation: f32) {
        self.params.elevation = elevation.max(0.0);
    }

    /// Switches the deformation technique from the next frame on; keeps the
    /// snow and the stored footprints.
    ///
    /// A technique whose buffer the window does not have yet (the footprint
    /// buffer for points and combined, the decal layer for decals) gets it
    /// at the next encoded frame: 4 bytes a texel, kept from then on.
    pub fn set_technique(&mut self, technique: Technique) {
        self.params.technique = technique;
    }

    /// The technique in use.
    #[must_use]
    pub fn technique(&self) -> Technique {
        self.params.technique
    }

    /// Sets the points technique's footprint size (clamped to 32..=128 texels) and rim formula.
    pub fn set_points(&mut self, range_texels: u32, rim: RimStyle) {
        self.params.range_texels = range_texels.clamp(*RANGE_TEXELS.start(), *RANGE_TEXELS.end());
        self.params.rim = rim;
    }

    #[cfg(feature = "low_level")]
    /// Contact points stamped in the last frame.
    #[must_use]
    pub fn points_last_frame(&self) -> usize {
        self.points_last_frame
    }

    #[cfg(feature = "low_level")]
    /// Contact points left out so far because a frame brought more than the
    /// stamp pass takes ([`crate::deform::stamp::MAX_POINTS`], about a
    /// million); each time the total doubles a warning says so.
    #[must_use]
    pub fn points_dropped(&self) -> u64 {
        self.points_dropped
    }

    low_level_pub! {
        /// Quantisation of the stored footprints: (lowest, highest height, quantum), m.
        #[must_use]
        fn stamp_range(&self) -> (f32, f32, f32) {
            let (low, high) = (self.capture_params.low_m, self.capture_params.high_m);
            (low, high, (high - low) / 65535.0)
        }
    }

    #[cfg(feature = "low_level")]
    /// The decal ring (each actor's last contacts).
    #[must_use]
    pub fn decals(&self) -> &DecalRing {
        &self.decals
    }

    low_level_pub! {
        /// The decal layer (window-local RGBA8: normal x, z, tint, coverage), drawn
        /// with the decals technique; transparent otherwise. Until the decals
        /// technique's first frame it is a transparent 1x1 placeholder; that
        /// frame replaces it with the full layer, so a renderer that bound it
        /// rebinds when the texture returned here changes (wgpu textures compare
        /// by identity).
        #[must_use]
        #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
        fn decal_layer(&self) -> &wgpu::Texture {
            &self.decal_pass.layer
        }
    }

    #[cfg(feature = "low_level")]
    /// The decal layer read back, window-local row-major; blocking. All
    /// transparent before the decals technique's first frame.
    pub fn read_decals(&self, ctx: &GpuContext) -> Result<Vec<[u8; 4]>, SnowError> {
        let r = self.params.resolution;
        if self.decal_pass.layer.width() != r {
            return Ok(vec![[0; 4]; (r * r) as usize]);
        }
        let row = (r * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("decal layer copy"),
            size: u64::from(row) * u64::from(r),
            usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("decal layer copy") });
        encoder.copy_texture_to_buffer(
            self.decal_pass.layer.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row), rows_per_image: Some(r) },
            },
            wgpu::Extent3d { width: r, height: r, depth_or_array_layers: 1 },
        );
        ctx.queue.submit([encoder.finish()]);
        let raw = read_buffer(ctx, &staging)?;
        Ok(raw.chunks_exact(row as usize).flat_map(|line| line[..(r * 4) as usize].chunks_exact(4).map(|p| [p[0], p[1], p[2], p[3]])).collect())
    }

    /// Turns the displayed-surface blur on or off.
    pub fn set_blur(&mut self, blur: bool) {
        self.params.blur = blur;
    }

    /// Moves the window's centre; the move (snapped to texels) happens at the next frame.
    pub fn set_center(&mut self, center: DVec2) {
        self.center = center;
    }

    /// World (x, z) of the window's corner (local texel (0, 0)'s outer corner), once placed.
    #[must_use]
    pub fn origin_m(&self) -> Option<DVec2> {
        let texel = f64::from(self.params.texel_m());
        self.window.origin().map(|o| DVec2::new(o[0] as f64 * texel, o[1] as f64 * texel))
    }

    low_level_pub! {
        /// Global texel index `[column, row]` of local (0, 0), once placed.
        #[must_use]
        fn origin_texel(&self) -> Option<[i64; 2]> {
            self.window.origin()
        }
    }

    /// Frames recorded so far.
    #[must_use]
    pub fn frame(&self) -> u64 {
        self.frame
    }

    #[cfg(feature = "low_level")]
    /// Texels rewritten by window moves so far (the whole window once, then only new strips).
    #[must_use]
    pub fn exposed_texels(&self) -> u64 {
        self.exposed_texels
    }

    /// Uploads a skinned mesh (a character's) for [`SnowFrame::poses`];
    /// `joint_count` is its skin's.
    pub fn add_skinned_mesh(&mut self, ctx: &GpuContext, mesh: &SkinnedMesh, joint_count: usize) -> Result<SkinnedId, SnowError> {
        let instance = self.skinning.instance(&ctx.device, &ctx.queue, mesh, joint_count)?;
        self.skinned.push(instance);
        let reach = crate::deform::sweep::JointReach::of_skin(&mesh.positions, &mesh.joints, &mesh.weights, joint_count);
        self.mesh_history.register_skinned(self.skinned.len() - 1, reach);
        Ok(SkinnedId(self.skinned.len() - 1))
    }

    low_level_pub! {
        /// The skinned meshes posed in the last encoded frame, in world space
        /// (what a renderer draws for the characters).
        #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
        fn posed_meshes(&self) -> impl Iterator<Item = &SkinnedInstance> + '_ {
            self.posed.iter().filter_map(|&k| self.skinned.get(k))
        }
    }

    /// Records one frame of deformation into `encoder`: the one per-frame
    /// entry point. Characters in `frame.poses` are skinned on the GPU (the
    /// `skinning` pass) and their posed meshes press the snow with
    /// `frame.meshes` and the deformers; the points of
    /// [`SnowFrame::with_queries`] are gathered, and their ticket returned
    /// (`None` when the frame asked nothing).
    ///
    /// Nothing is called after the submit: the frame's readbacks (point
    /// answers, timings, tiles leaving the window, shared snow) are mapped
    /// by wgpu when the encoder is submitted, and the next `encode` takes
    /// what has arrived (a non-blocking `device.poll`, never a wait).
    pub fn encode(&mut self, ctx: &GpuContext, encoder: &mut wgpu::CommandEncoder, frame: &SnowFrame<'_>) -> Option<QueryTicket> {
        use super::sweep::MeshKey;
        self.collect_arrived(ctx);
        let queries = frame.queries.map(|points| {
            self.tickets += 1;
            (QueryTicket(self.tickets), points)
        });
        let ticket = queries.map(|(t, _)| t);
        self.posed.clear();
        self.timer.begin_frame();
        let (texel_m, teleport_m) = (self.params.texel_m(), self.params.teleport_m);
        let mut steps = std::mem::take(&mut self.scratch.mesh_steps);
        steps.clear();
        for pose in frame.poses {
            let Some(instance) = self.skinned.get(pose.mesh.0) else { continue };
            self.skinning.record(FrameContext::new(ctx, encoder, &mut self.timer), instance, pose.joints, pose.model);
            self.posed.push(pose.mesh.0);
            let world = pose.joints.iter().map(|j| pose.model * *j).collect();
            steps.push(self.mesh_history.skinned_steps(pose.mesh.0, world, texel_m, teleport_m));
        }
        for k in 0..frame.meshes.len() {
            // No travel given (NaN) compares false: not swept.
            let travel = frame.mesh_travel_m.get(k).copied().unwrap_or(f32::NAN);
            steps.push(if teleport_m > 0.0 && travel <= teleport_m { crate::deform::sweep::steps_for(travel, texel_m) } else { 0 });
        }
        let skinned = std::mem::take(&mut self.skinned);
        let mut history = std::mem::take(&mut self.mesh_history);
        let keys: Vec<MeshKey> = self.posed.iter().map(|&k| MeshKey::Skinned(k)).chain((0..frame.meshes.len()).map(MeshKey::Caller)).collect();
        let current: Vec<CaptureMesh<'_>> = self
            .posed
            .iter()
            .map(|&k| CaptureMesh {
                vertices: &skinned[k].skinned,
                indices: &skinned[k].indices,
                index_count: skinned[k].index_count,
                vertex_count: skinned[k].vertex_count,
            })
            .chain(frame.meshes.iter().copied())
            .collect();
        let meshes: Vec<SweptMesh<'_>> =
            current.iter().zip(&keys).map(|(&mesh, &key)| SweptMesh { mesh, previous: history.previous(key, u64::from(mesh.vertex_count) * 12) }).collect();
        self.encode_frame(ctx, encoder, (frame.deformers, frame.ids, frame.dt_s), (&meshes, &steps), queries);
        self.scratch.mesh_steps = steps;
        drop(meshes);
        // This frame's positions are the next frame's previous ones.
        history.age();
        for (mesh, key) in current.iter().zip(keys) {
            history.remember(&ctx.device, encoder, key, mesh.vertices, u64::from(mesh.vertex_count) * 12);
        }
        drop(current);
        self.mesh_history = history;
        self.skinned = skinned;
        // With this frame's copy-outs recorded, before they can be collected and dropped.
        self.peak_memory_bytes = self.peak_memory_bytes.max(self.memory_total());
        ticket
    }

    /// A convenience for headless tools and tests, not a game's frame
    /// loop: records the frame into an encoder of its own ([`Self::encode`]),
    /// submits it and takes whatever readbacks have already arrived
    /// (without waiting); fails on GPU errors. Returns the ticket of the
    /// frame's point queries, if it asked any.
    pub fn step_frame(&mut self, ctx: &GpuContext, frame: &SnowFrame<'_>) -> Result<Option<QueryTicket>, SnowError> {
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("snow frame") });
        let ticket = ctx.capturing(|| {
            let ticket = self.encode(ctx, &mut encoder, frame);
            ctx.queue.submit([encoder.finish()]);
            ticket
        });
        self.collect_arrived(ctx);
        ctx.check("deformation frame")?;
        Ok(ticket)
    }

    /// [`Self::step_frame`] with only `deformers` pressing the snow (headless tools and tests).
    pub fn step(&mut self, ctx: &GpuContext, deformers: &[Deformer], dt_s: f32) -> Result<(), SnowError> {
        self.step_frame(ctx, &SnowFrame::new(dt_s, deformers)).map(|_| ())
    }

    fn encode_frame(
        &mut self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        (deformers, ids, dt_s): (&[Deformer], &[u64], f32),
        (meshes, mesh_steps): (&[SweptMesh<'_>], &[u32]),
        queries: Option<(QueryTicket, &[glam::Vec2])>,
    ) {
        let (device, queue) = (&ctx.device, &ctx.queue);
        let p = &self.params;
        let texel = f64::from(p.texel_m());
        let desired = self.window.snapped_origin(self.center.x, self.center.y, texel);
        let old = self.window.origin();
        // With a store, the window may wait for tiles still loading.
        let origin = match &mut self.tiles {
            Some(tiles) => tiles.plan(ctx, old, desired),
            None => desired,
        };
        if p.technique.uses_stamps() && self.res.allocate_stamps(device, queue) {
            // Every pass bound to the 4-byte stand-in binds the new buffer.
            self.window_pass = WindowPass::new(device, &self.res);
            self.stamp_pass = StampPass::new(device, &self.res);
            self.display_pass = DisplayPass::new(device, &self.res);
            self.update_pass = UpdatePass::new(device, &self.res);
            self.update_pass.bind_sky(device, &self.res, self.accumulation.as_ref().map(SnowAccumulation::sky_view));
            if let Some(tiles) = &mut self.tiles {
                tiles.add_stamp_plane(ctx, &self.res);
            }
            if let Some(sharing) = &mut self.sharing {
                sharing.rebind(device, &self.res);
            }
        }
        let rects = self.window.move_to(origin);
        self.exposed_texels += rects.iter().map(|r| u64::from(r[2]) * u64::from(r[3])).sum::<u64>();
        // Window and tile coordinates stay in i64 on the CPU; the GPU needs only
        // i32 (about 134,000 km of texels at 6.25 cm).
        let origin_i32 = [origin[0] as i32, origin[1] as i32];
        // Deformers and objects are relative to the floating origin; so is the corner they are placed against.
        let corner = DVec2::new(origin[0] as f64 * texel, origin[1] as f64 * texel) - self.floating_origin;

        let window = WindowFrame {
            origin,
            corner,
            resolution: p.resolution,
            extent_m: p.extent_m,
            depth_m: p.depth_m,
            texel_m: p.texel_m(),
            fallen_m: self.fallen_total_m,
            max_fallen_m: p.snowfall.as_ref().map_or(0.0, |s| s.max_m),
            low_m: self.capture_params.low_m,
            high_m: self.capture_params.high_m,
            use_fallen: p.snowfall.is_some(),
            terrain_m: self.terrain_bounds,
        };
        if let Some(tiles) = &mut self.tiles {
            tiles.record_move(FrameContext::new(ctx, encoder, &mut self.timer), &window, &self.res, (old, &rects), self.clock);
        } else {
            self.window_pass.record(
                queue,
                encoder,
                &mut self.timer,
                WindowParams {
                    origin: origin_i32,
                    resolution: p.resolution,
                    texel_m: p.texel_m(),
                    depth_m: p.depth_m,
                    fallen_m: self.fallen_total_m,
                    flags: if p.snowfall.is_some() { WindowParams::WRITE_FALLEN } else { 0 }
                        | if self.res.has_stamps() { WindowParams::WRITE_STAMPS } else { 0 },
                    ..WindowParams::default()
                },
                &rects,
            );
        }
        // Shared snow: tiles from elsewhere, before this frame's presses, so
        // the update and display see them like the window's own trails.
        if self.sharing.is_some() {
            let share_window = self.share_window(origin);
            let clock = self.share_clock();
            let (low, high, _) = self.stamp_range();
            let merge = crate::replicate::merge::TileMergeParams {
                depth_m: self.params.depth_m,
                texel_m: self.params.texel_m(),
                low_m: low,
                high_m: high,
                max_fallen_m: self.params.snowfall.as_ref().map_or(0.0, |s| s.max_m),
                ..Default::default()
            };
            let catch = self.catch_up_rule();
            if let Some(sharing) = &mut self.sharing {
                sharing.record_merge(queue, encoder, &mut self.timer, &share_window, merge, (&clock, catch));
            }
        }
        let p = &self.params;
        // Snowfall: this frame's depth on open ground, and what the sky sees
        // (drawn while the snowfall is set, even at rate 0, so refill stays
        // out of shelter too).
        let snowfall = p.snowfall.clone();
        let fall_m = snowfall.as_ref().map_or(0.0, |s| s.rate_m_per_s * dt_s.max(0.0));
        if let Some(acc) = &self.accumulation {
            acc.upload_poses(queue, &window);
        }
        let sky = match (&snowfall, &mut self.accumulation) {
            (Some(s), Some(acc)) => Some(acc.record_occlusion(FrameContext::new(ctx, encoder, &mut self.timer), &window, s)),
            _ => None,
        };
        let max_fallen_m = snowfall.as_ref().map_or(0.0, |s| s.max_m);
        let technique = p.technique;
        let captures = matches!(technique, Technique::Depth | Technique::Combined);
        let stamps = matches!(technique, Technique::Points | Technique::Combined);
        // Each deformer presses over its motion since the last frame.
        let scratch = &mut self.scratch;
        self.history.sweeps_into(deformers, ids, p.teleport_m, &mut scratch.sweeps);
        self.history.remember(deformers, ids);
        let sweeps = &scratch.sweeps;
        if captures {
            let instances = &mut scratch.instances;
            instances.fill_swept(deformers, sweeps, corner, &self.capture_params);
            instances.mesh_steps.clear();
            instances.mesh_steps.extend_from_slice(mesh_steps);
            self.capture_pass.prepare(device, queue, &self.capture_params, instances);
            self.capture_pass.record_swept(encoder, &mut self.timer, &self.res, meshes);
        }
        let stamp_params = StampParams {
            origin: origin_i32,
            resolution: p.resolution,
            range_texels: p.range_texels,
            texel_m: p.texel_m(),
            low_m: self.capture_params.low_m,
            high_m: self.capture_params.high_m,
            count: 0,
            share_side: self.sharing.as_ref().map_or(0, |s| s.grid().side),
            share_keys: self.sharing.as_ref().map_or(0, |s| s.grid().keys),
            ..StampParams::default()
        };
        self.points_last_frame = 0;
        if stamps {
            let points = &mut scratch.points;
            contact_points_into(deformers, sweeps, corner, &stamp_params, points);
            let dropped = self.stamp_pass.prepare(device, queue, &self.res, &stamp_params, points);
            self.stamp_pass.record(encoder, &mut self.timer);
            self.points_last_frame = points.len() - dropped;
            if dropped > 0 {
                // Said once per doubling of the total, so a scene that always
                // brings too many is reported without flooding the log.
                let before = self.points_dropped;
                self.points_dropped += dropped as u64;
                if before == 0 || self.points_dropped.ilog2() > before.ilog2() {
                    tracing::warn!(
                        "{} contact points this frame, above the stamp pass's {}: {dropped} left out ({} so far; see points_dropped)",
                        points.len(),
                        crate::deform::stamp::MAX_POINTS,
                        self.points_dropped
                    );
                }
            }
        }
        // Footprints and the snow refill by whole quanta, counted from the
        // world time (RefillBase): the frame applies what the counters
        // gained, so machines with different frame times agree.
        let refill_m = p.refill_m_per_s * dt_s.max(0.0);
        let time_after = self.clock.time_s + f64::from(dt_s.max(0.0));
        let base = self.refill_base;
        let stamp_total = base.quanta_at(base.stamp_quanta, time_after, p.refill_m_per_s, stamp_params.quantum_m()).max(self.clock.stamp_quanta);
        let snow_total = base.quanta_at(base.snow_quanta, time_after, p.refill_m_per_s, SNOW_QUANTUM_M).max(self.snow_quanta);
        // A footprint is gone after 65536 quanta and a deficit after 65535,
        // so larger steps (a long pause) change nothing more.
        let refill_quanta = (stamp_total - self.clock.stamp_quanta).min(65_536) as u32;
        let snow_refill_quanta = (snow_total - self.snow_quanta).min(65_535) as u32;
        let sharing = self.sharing.as_ref().map(|s| s.grid());
        self.update_pass.record(
            queue,
            encoder,
            &mut self.timer,
            &UpdateParams {
                origin: origin_i32,
                resolution: p.resolution,
                depth_m: p.depth_m,
                snow_refill_quanta,
                low_m: self.capture_params.low_m,
                high_m: self.capture_params.high_m,
                flags: if captures { UpdateParams::USE_CAPTURE } else { 0 }
                    | if stamps { UpdateParams::USE_STAMPS } else { 0 }
                    | if snowfall.is_some() { UpdateParams::USE_FALLEN } else { 0 }
                    | if sky.is_some() { UpdateParams::USE_SKY } else { 0 }
                    | if self.res.has_stamps() { UpdateParams::HAS_STAMPS } else { 0 }
                    | if sharing.is_some() { UpdateParams::SHARE } else { 0 },
                refill_quanta,
                fall_m,
                max_fallen_m,
                texel_m: p.texel_m(),
                sky_shear: sky.map_or([0.0; 2], |s| s.shear),
                sky_offset_m: sky.map_or([0.0; 2], |s| s.offset_m),
                sky_y0_m: sky.map_or(0.0, |s| s.y0_m),
                sky_low_m: sky.map_or(0.0, |s| s.low_m),
                sky_high_m: sky.map_or(1.0, |s| s.high_m),
                share_side: sharing.map_or(0, |g| g.side),
                share_keys: sharing.map_or(0, |g| g.keys),
                ..Default::default()
            },
        );
        if let Some(tiles) = &mut self.tiles {
            tiles.record_weather(FrameContext::new(ctx, encoder, &mut self.timer), &window, (refill_m, fall_m), refill_quanta);
        }
        self.clock.time_s = time_after;
        self.clock.refill_m += f64::from(refill_m);
        self.clock.fallen_m += f64::from(fall_m);
        self.clock.stamp_quanta = stamp_total;
        self.snow_quanta = snow_total;
        self.fallen_total_m = (self.fallen_total_m + fall_m).min(max_fallen_m);
        // Shared snow: the flags out, and the dirty tiles as this frame left them.
        if self.sharing.is_some() {
            let share_window = self.share_window(origin);
            let record = crate::replicate::merge::FrameRecord {
                after: self.share_clock(),
                snow_quanta: snow_refill_quanta,
                stamp_quanta: refill_quanta,
                fall_m,
                stamps_pressed: stamps && self.res.has_stamps(),
            };
            if let Some(sharing) = &mut self.sharing {
                sharing.record_after_update(queue, encoder, &mut self.timer, &self.res, &share_window, record);
            }
        }
        let p = &self.params;
        self.display_pass.record(
            queue,
            encoder,
            &mut self.timer,
            &DisplayParams {
                origin: origin_i32,
                resolution: p.resolution,
                depth_m: p.depth_m,
                elevation: p.elevation,
                mode: DisplayParams::mode_for(technique, p.rim),
                low_m: self.capture_params.low_m,
                high_m: self.capture_params.high_m,
                use_fallen: u32::from(snowfall.is_some()),
                texel_m: p.texel_m(),
                blur: u32::from(p.blur),
                ..Default::default()
            },
        );
        if let Some(acc) = &mut self.accumulation {
            match &snowfall {
                // One occlusion pixel is one window texel of ground.
                Some(s) => acc.record_atlas(
                    FrameContext::new(ctx, encoder, &mut self.timer),
                    s,
                    if sky.is_some() { fall_m * p.texel_m() * p.texel_m() } else { 0.0 },
                    dt_s,
                ),
                None => acc.record_surface(FrameContext::new(ctx, encoder, &mut self.timer)),
            }
        }
        // Contacts are recorded whatever the technique, so switching to decals
        // shows the recent ones; they are drawn only with the decals technique.
        self.decals.observe(deformers, &self.terrain, p.depth_m);
        if technique == Technique::Decals {
            self.decal_pass.allocate_layer(device);
            self.decal_pass.prepare(device, queue, &mut self.decals, corner, p.extent_m);
            self.decal_pass.record(encoder, &mut self.timer);
        }
        if let Some((ticket, points)) = queries {
            let local: Vec<glam::Vec2> =
                points.iter().map(|p| glam::Vec2::new((f64::from(p.x) - corner.x) as f32, (f64::from(p.y) - corner.y) as f32)).collect();
            let params = QueryParams {
                origin: origin_i32,
                resolution: p.resolution,
                count: 0,
                texel_m: p.texel_m(),
                depth_m: p.depth_m,
                use_fallen: u32::from(snowfall.is_some()),
                _pad: 0,
            };
            self.query_pass.record(device, queue, encoder, &mut self.timer, &self.res, params, &local, (ticket, self.frame, points.to_vec()));
        }
        self.timer.end_frame(encoder);
        self.frame += 1;
    }

    /// Takes the readbacks that have arrived, without waiting (unless held,
    /// [`Self::hold_readbacks`]).
    fn collect_arrived(&mut self, ctx: &GpuContext) {
        if self.readbacks_held {
            return;
        }
        // A non-blocking poll runs mapping callbacks that are due; an error
        // here surfaces through `ctx.check` as well.
        let _ = ctx.device.poll(wgpu::PollType::Poll);
        self.collect(ctx);
    }

    fn collect(&mut self, ctx: &GpuContext) {
        if let Some(answers) = self.query_pass.take_answers() {
            self.answers = Some(answers);
        }
        if let Some(tiles) = &mut self.tiles {
            tiles.collect(ctx);
        }
        if let Some(sharing) = &mut self.sharing {
            sharing.collect(self.params.resolution);
        }
        self.timer.collect();
    }

    /// For tests: while `held`, frames take none of the readbacks that
    /// arrive (point answers, timings, tiles leaving the window, shared
    /// snow), as if the GPU never finished them, so their staging buffers
    /// stay busy; [`Self::finish`] still waits for and takes them.
    #[cfg(feature = "low_level")]
    pub fn hold_readbacks(&mut self, held: bool) {
        self.readbacks_held = held;
    }

    /// Waits for every outstanding readback (point answers and timings);
    /// for the end of a headless run or a test, never in a frame loop.
    pub fn finish(&mut self, ctx: &GpuContext) -> Result<(), SnowError> {
        ctx.wait_idle("finishing readbacks")?;
        // An idle GPU is not enough: another thread polling the same device
        // (a game's loader, parallel tests) may have taken the answers'
        // mapping callbacks and fire them after our poll returned.
        let deadline = std::time::Instant::now() + crate::gpu::context::WAIT_TIMEOUT;
        while self.query_pass.callbacks_pending() || self.sharing.as_ref().is_some_and(crate::replicate::sharing::Sharing::callbacks_pending) {
            if std::time::Instant::now() > deadline {
                return Err(SnowError::Readback("a point answer's mapping never completed".to_owned()));
            }
            std::thread::yield_now();
            let _ = ctx.device.poll(wgpu::PollType::Poll);
        }
        self.collect(ctx);
        Ok(())
    }

    /// The newest answer to a frame's [`SnowFrame::with_queries`] that has
    /// come back (taken at the start of each [`Self::encode`]).
    #[must_use]
    pub fn point_answers(&self) -> Option<&PointAnswers> {
        self.answers.as_ref()
    }

    /// Requests gathered, answered and skipped so far.
    #[must_use]
    pub fn query_stats(&self) -> QueryStats {
        self.query_pass.stats()
    }

    #[cfg(feature = "low_level")]
    /// Median GPU time per pass so far (empty without timestamp support).
    #[must_use]
    pub fn timings(&self) -> PassTimings {
        self.timer.medians()
    }

    #[cfg(feature = "low_level")]
    /// Forgets timing samples (call after warm-up).
    pub fn clear_timings(&mut self) {
        self.timer.clear();
    }

    #[cfg(feature = "low_level")]
    /// The most GPU memory [`Self::memory_bytes`] summed to after any frame
    /// so far (bytes): with tiles on their way to the CPU, the copy-out
    /// staging they hold for a frame or two.
    #[must_use]
    pub fn peak_memory_bytes(&self) -> u64 {
        self.peak_memory_bytes.max(self.memory_total())
    }

    /// [`Self::memory_bytes`] summed (without building the list but for the objects').
    fn memory_total(&self) -> u64 {
        self.res.memory_total()
            + self.query_pass.memory_bytes()
            + self.decal_pass.layer_bytes()
            + self.accumulation.as_ref().map_or(0, |acc| acc.memory_bytes().iter().map(|(_, b)| b).sum())
            + self.tiles.as_ref().map_or(0, TileStreaming::gpu_bytes)
            + self.sharing.as_ref().map_or(0, crate::replicate::sharing::Sharing::memory_bytes)
    }

    low_level_pub! {
        /// GPU memory held, by resource (bytes), including the point queries' buffers.
        #[must_use]
        #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
        fn memory_bytes(&self) -> Vec<(&'static str, u64)> {
            let mut list = self.res.memory_bytes();
            list.push(("point queries", self.query_pass.memory_bytes()));
            list.push(("decal layer", self.decal_pass.layer_bytes()));
            if let Some(acc) = &self.accumulation {
                list.extend(acc.memory_bytes());
            }
            if let Some(tiles) = &self.tiles {
                list.push(("resident tiles", tiles.stats().gpu_bytes));
            }
            if let Some(sharing) = &self.sharing {
                list.push(("shared snow", sharing.memory_bytes()));
            }
            list
        }
    }

    #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
    fn untorus<T: Copy + Default>(&self, toroidal: &[T]) -> Vec<T> {
        untorus(self.params.resolution, self.window.origin().unwrap_or([0, 0]), toroidal)
    }

    low_level_pub! {
        /// The snow words ([`crate::deform::snow_word`]), window-local row-major (row i
        /// = +z); blocking. [`Self::read_snow`] and [`Self::read_surface`]
        /// decode them.
        #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
        fn read_snow_words(&self, ctx: &GpuContext) -> Result<Vec<u32>, SnowError> {
            let raw = read_buffer(ctx, &self.res.snow)?;
            Ok(self.untorus(&bytemuck::pod_collect_to_vec::<u8, u32>(&raw)))
        }
    }

    #[cfg(feature = "low_level")]
    /// [`Self::read_snow_words`] without blocking: the words as the GPU has
    /// them once the frames submitted so far are done (the browser build's
    /// path; see [`crate::gpu::readback::MappedRead`]).
    pub fn read_snow_words_async(&self, ctx: &GpuContext) -> impl std::future::Future<Output = Result<Vec<u32>, SnowError>> + 'static {
        let mapped = crate::gpu::readback::read_buffer_async(ctx, &self.res.snow);
        let (resolution, origin) = (self.params.resolution, self.window.origin().unwrap_or([0, 0]));
        async move { Ok(untorus(resolution, origin, &bytemuck::pod_collect_to_vec::<u8, u32>(&mapped.await?))) }
    }

    #[cfg(feature = "low_level")]
    /// Persistent snow height (m), window-local row-major (row i = +z); blocking.
    pub fn read_snow(&self, ctx: &GpuContext) -> Result<Vec<f32>, SnowError> {
        let words = self.read_snow_words(ctx)?;
        let terrain = self.read_terrain(ctx)?;
        let fallen: Vec<f32> = if self.params.snowfall.is_some() {
            self.untorus(&bytemuck::pod_collect_to_vec::<u8, f32>(&read_buffer(ctx, &self.res.fallen)?))
        } else {
            vec![0.0; words.len()]
        };
        Ok(words.iter().zip(&terrain).zip(&fallen).map(|((&w, &g), &l)| snow_word::height(w, g + self.params.depth_m + l, g)).collect())
    }

    low_level_pub! {
    /// Terrain height (m) at the texel centres, window-local row-major; for
    /// mesh terrain blocking. Evaluated on the CPU with the GPU's formula
    /// (`texel_ground`), so they agree to rounding: from the terrain's
    /// description, and for a mesh terrain from the grid the GPU baked (read
    /// back), which is what the passes sample. No GPU buffer holds the
    /// terrain per texel.
    #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
    fn read_terrain(&self, ctx: &GpuContext) -> Result<Vec<f32>, SnowError> {
        let baked;
        let source = match &self.terrain {
            TerrainSource::Mesh(mesh) => {
                let n = (mesh.grid.width() * mesh.grid.height()) as usize;
                let heights: Vec<f32> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &self.res.heightmap)?);
                baked = TerrainSource::Heightmap(mesh.grid.with_heights(heights[..n].to_vec())?);
                &baked
            }
            other => other,
        };
        let r = self.params.resolution;
        let origin = self.window.origin().unwrap_or([0, 0]);
        let o = [origin[0] as i32, origin[1] as i32];
        let texel = self.params.texel_m();
        Ok((0..r)
            .flat_map(|i| (0..r).map(move |j| (i, j)))
            .map(|(i, j)| crate::terrain::texel_ground(source, [o[0] + j as i32, o[1] + i as i32], texel))
            .collect())
    }
    }

    #[cfg(feature = "low_level")]
    /// Displayed height (m) and unit normal per texel, window-local; blocking.
    /// The normals are central differences of the displayed heights, as the
    /// renderer and the point queries compute them.
    pub fn read_surface(&self, ctx: &GpuContext) -> Result<(Vec<f32>, Vec<[f32; 3]>), SnowError> {
        let words = self.read_snow_words(ctx)?;
        let terrain = self.read_terrain(ctx)?;
        let heights: Vec<f32> = words.iter().zip(&terrain).map(|(&w, &g)| snow_word::shown(w, g)).collect();
        let normals = crate::deform::display::normals_of(&heights, self.params.resolution, self.params.texel_m());
        Ok((heights, normals))
    }
}

/// A toroidal window buffer (origin texel `origin`) laid out window-local row-major.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
fn untorus<T: Copy + Default>(resolution: u32, origin: [i64; 2], toroidal: &[T]) -> Vec<T> {
    let r = resolution as usize;
    let ri = r as i64;
    let (oc, or) = (origin[0].rem_euclid(ri) as usize, origin[1].rem_euclid(ri) as usize);
    let mut out = vec![T::default(); r * r];
    for i in 0..r {
        let si = (or + i) % r;
        for j in 0..r {
            out[i * r + j] = toroidal[si * r + (oc + j) % r];
        }
    }
    out
}
