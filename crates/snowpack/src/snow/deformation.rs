//! [`SnowDeformation`], the snow a game drives: the core window
//! ([`super::core_window`]) and the plug-ins (characters, objects, tiles, shared
//! snow), each owning its state in its own file; one frame is
//! [`SnowDeformation::encode`], whose passes [`super::steps`] records in order.

use glam::DVec2;

use crate::RimStyle;
use crate::accumulate::{SnowAccumulation, SnowObject};
use crate::deform::query::{PointAnswers, QueryTicket};
use crate::error::SnowError;
use crate::frame::FrameContext;
use crate::gpu::{GpuContext, GpuTimer, PassTimings};
use crate::replicate::sharing::Sharing;
use crate::replicate::{ShareClock, SharedSnow, SharedTile};
use crate::skin::coat::CoatSettings;
use crate::skin::skinning::SkinnedMesh;
use crate::snowfall::Snowfall;
use crate::tiles::TileStreaming;
use crate::{SnowParams, Technique, TerrainSource};
use snowpack_share::replicate::WorldIdentityExt;

use super::characters::Characters;
use super::clock::SnowTime;
use super::core_window::{CoreWindow, fits_adapter};
use super::skinned::SkinnedId;
use super::snow_frame::SnowFrame;
use super::steps::FrameSteps;
use super::{objects, share};
use crate::deform::params::SnowParamsExt;
use crate::gpu::context::GpuContextExt;

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
/// away, when the window returns; `StoredWindow::attach_store` (feature
/// `store`) keeps them on disk instead (and makes `StoredWindow::save`
/// possible). Sharing the snow between machines is `SharedWindow`'s
/// (feature `share`).
pub struct SnowDeformation {
    /// The window, its resources and its own passes.
    pub(super) core: CoreWindow,
    /// Time, refill counters and snowfall so far.
    pub(super) time: SnowTime,
    /// The per-pass GPU timer every frame's context carries.
    pub(super) timer: GpuTimer,
    /// Skinned characters and every pressing mesh's history.
    pub(super) characters: Characters,
    /// Objects snow settles on, with their atlas and passes.
    pub(super) accumulation: Option<SnowAccumulation>,
    /// The tile keeper (memory by default, or an attached store) and the
    /// resident tiles; `None` when trails are forgotten.
    pub(super) tiles: Option<TileStreaming>,
    /// [`Self::attach_store`] has been called.
    #[cfg_attr(not(feature = "store"), expect(dead_code, reason = "for `StoredWindow`'s calls (feature `store`)"))]
    pub(super) store_attached: bool,
    /// Shared snow ([`Self::enable_sharing`]): flags, gathers, merges.
    pub(super) sharing: Option<Sharing>,
    /// Frames collect no readback ([`Self::hold_readbacks`]).
    pub(super) readbacks_held: bool,
    /// Frames recorded so far.
    pub(super) frame: u64,
    /// The most GPU memory held after any submitted frame (bytes).
    pub(super) peak_memory_bytes: u64,
}

impl SnowDeformation {
    /// Allocates a window of `params` over `terrain`, centred on world (x, z).
    pub fn new(ctx: &GpuContext, params: SnowParams, terrain: TerrainSource, center: DVec2) -> Result<Self, crate::SnowError> {
        params.validate()?;
        fits_adapter(&ctx.device.limits(), &params, &terrain)?;
        ctx.guarded(|| {
            let this = ctx.capturing(|| Self::allocate(ctx, params, terrain, center))?;
            ctx.check("creating the deformation passes")?;
            Ok(this)
        })
    }

    fn allocate(ctx: &GpuContext, params: SnowParams, terrain: TerrainSource, center: DVec2) -> Result<Self, SnowError> {
        let core = CoreWindow::new(ctx, params, terrain, center);
        let tiles = match core.params().tile_memory_bytes {
            Some(budget) => TileStreaming::keep_in_memory(ctx, core.res(), core.params(), budget)?,
            None => None,
        };
        Ok(Self {
            timer: GpuTimer::new(&ctx.device, &ctx.queue),
            characters: Characters::new(&ctx.device, core.res()),
            core,
            time: SnowTime::default(),
            accumulation: None,
            tiles,
            store_attached: false,
            sharing: None,
            readbacks_held: false,
            frame: 0,
            peak_memory_bytes: 0,
        })
    }

    /// The parameters in use.
    #[must_use]
    pub fn params(&self) -> &SnowParams {
        self.core.params()
    }

    /// Changes the snowfall (rate, direction, stability) from the next frame
    /// on; `None` stops it. A window created without snowfall has no buffer
    /// for it, so starting snow there is an error.
    pub fn set_snowfall(&mut self, snowfall: Option<Snowfall>) -> Result<(), crate::SnowError> {
        Ok(self.core.set_snowfall(snowfall)?)
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
        if self.core.set_floating_origin(origin) {
            self.characters.forget_positions();
        }
    }

    /// Sets the refill rate (m/s); takes effect next frame. The refill
    /// counters go on from now at the new rate.
    pub fn set_refill(&mut self, refill_m_per_s: f32) {
        self.core.set_refill(refill_m_per_s);
        self.time.rebase();
    }

    /// Sets the rim strength; takes effect next frame.
    pub fn set_elevation(&mut self, elevation: f32) {
        self.core.set_elevation(elevation);
    }

    /// Switches the deformation technique from the next frame on; keeps the
    /// snow and the stored footprints.
    ///
    /// A technique whose buffer the window does not have yet (the footprint
    /// buffer for points and combined, the decal layer for decals) gets it
    /// at the next encoded frame: 4 bytes a texel, kept from then on.
    pub fn set_technique(&mut self, technique: Technique) {
        self.core.set_technique(technique);
    }

    /// Sets the points technique's footprint size (clamped to 32..=128 texels) and rim formula.
    pub fn set_points(&mut self, range_texels: u32, rim: RimStyle) {
        self.core.set_points(range_texels, rim);
    }

    /// Turns the displayed-surface blur on or off.
    pub fn set_blur(&mut self, blur: bool) {
        self.core.set_blur(blur);
    }

    /// Sets the snow's angle of repose (degrees, in (0, 90); `None`: walls
    /// stay as presses made them), from the next frame
    /// ([`SnowParams::repose_deg`]).
    ///
    /// An angle outside (0, 90) is an error naming `repose_deg`, and the
    /// angle stays as it was.
    pub fn set_repose(&mut self, repose_deg: Option<f32>) -> Result<(), crate::SnowError> {
        Ok(self.core.set_repose(repose_deg)?)
    }

    /// Moves the window's centre; the move (snapped to texels) happens at the next frame.
    pub fn set_center(&mut self, center: DVec2) {
        self.core.set_center(center);
    }

    /// Frames recorded so far.
    #[must_use]
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// Sets how skinned mesh `id`'s character gathers and loses snow.
    pub fn set_coat(&mut self, id: SkinnedId, settings: CoatSettings) -> Result<(), crate::SnowError> {
        Ok(self.characters.set_coat(id, settings)?)
    }

    /// The snow on skinned mesh `id`'s vertices: one `f32` a vertex (m), in
    /// the mesh's vertex order, usable as `STORAGE` and `VERTEX`. A character
    /// material binds it as a per-vertex attribute (`docs/rendering.md`,
    /// "Snow on characters"); [`Self::encode`] updates it for posed meshes.
    #[must_use]
    pub fn coat_buffer(&self, id: SkinnedId) -> Option<&wgpu::Buffer> {
        self.characters.coat_buffer(id)
    }

    /// Uploads a skinned mesh (a character's) for [`SnowFrame::with_poses`];
    /// `joint_count` is its skin's.
    pub fn add_skinned_mesh(&mut self, ctx: &GpuContext, mesh: &SkinnedMesh, joint_count: usize) -> Result<SkinnedId, crate::SnowError> {
        ctx.guarded(|| self.characters.add(ctx, mesh, joint_count).map_err(Into::into))
    }

    /// Places `objects` for snow to settle on (replacing any before, and their
    /// snow): lays out their atlas and builds the accumulation passes.
    pub fn set_objects(&mut self, ctx: &GpuContext, objects: &[SnowObject]) -> Result<(), crate::SnowError> {
        ctx.guarded(|| objects::place(ctx, &mut self.core, &mut self.accumulation, objects))
    }

    /// The snow on each object (in [`Self::set_objects`] order): read back
    /// from the GPU, so this blocks; for a save, a test or a debug panel, not
    /// every frame. Empty without objects.
    pub fn read_object_stats(&self, ctx: &GpuContext) -> Result<Vec<crate::accumulate::ObjectStats>, crate::SnowError> {
        ctx.guarded(|| objects::read_stats(ctx, self.accumulation.as_ref()))
    }

    /// Moves and turns object `k` (in [`Self::set_objects`] order); its snow goes with it.
    pub fn set_object_pose(&mut self, k: usize, position: glam::Vec3, rotation: glam::Quat) {
        if let Some(acc) = &mut self.accumulation {
            acc.set_pose(k, position, rotation);
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
        self.collect_arrived(ctx);
        let queries = frame.queries.map(|points| (self.core.next_ticket(), points));
        self.timer.begin_frame();
        let mut cx = FrameContext::new(ctx, encoder, &mut self.timer);
        let steps = FrameSteps {
            characters: &mut self.characters,
            core: &mut self.core,
            time: &mut self.time,
            accumulation: self.accumulation.as_mut(),
            tiles: self.tiles.as_mut(),
            sharing: self.sharing.as_mut(),
        };
        steps.record(&mut cx, frame, queries.map(|q| (q, self.frame)));
        self.timer.end_frame(encoder);
        self.frame += 1;
        // With this frame's copy-outs recorded, before they can be collected and dropped.
        self.peak_memory_bytes = self.peak_memory_bytes.max(self.memory_total());
        queries.map(|(t, _)| t)
    }

    /// A convenience for headless tools and tests, not a game's frame
    /// loop: records the frame into an encoder of its own ([`Self::encode`]),
    /// submits it and takes whatever readbacks have already arrived
    /// (without waiting); fails on GPU errors. Returns the ticket of the
    /// frame's point queries, if it asked any.
    pub fn step_frame(&mut self, ctx: &GpuContext, frame: &SnowFrame<'_>) -> Result<Option<QueryTicket>, crate::SnowError> {
        ctx.guarded(|| {
            let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("snow frame") });
            let ticket = ctx.capturing(|| {
                let ticket = self.encode(ctx, &mut encoder, frame);
                ctx.queue.submit([encoder.finish()]);
                ticket
            });
            self.collect_arrived(ctx);
            ctx.check("deformation frame")?;
            Ok(ticket)
        })
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
        self.core.collect_answers();
        if let Some(tiles) = &mut self.tiles {
            tiles.collect(ctx);
        }
        if let Some(sharing) = &mut self.sharing {
            sharing.collect(self.core.params().resolution);
        }
        self.timer.collect();
    }

    /// Waits for every outstanding readback (point answers and timings);
    /// for the end of a headless run or a test, never in a frame loop.
    pub fn finish(&mut self, ctx: &GpuContext) -> Result<(), crate::SnowError> {
        ctx.guarded(|| self.finish_readbacks(ctx))
    }

    fn finish_readbacks(&mut self, ctx: &GpuContext) -> Result<(), crate::SnowError> {
        ctx.wait_idle("finishing readbacks")?;
        // An idle GPU is not enough: another thread polling the same device
        // (a game's loader, parallel tests) may have taken the answers'
        // mapping callbacks and fire them after our poll returned.
        let deadline = std::time::Instant::now() + crate::gpu::context::WAIT_TIMEOUT;
        while self.core.answers_pending() || self.sharing.as_ref().is_some_and(crate::replicate::sharing::Sharing::callbacks_pending) {
            if std::time::Instant::now() > deadline {
                return Err(SnowError::Readback("a point answer's mapping never completed".to_owned()).into());
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
        self.core.answers()
    }

    /// GPU time of each pass in the newest frame whose timestamps came
    /// back (a frame or two ago; empty without timestamp support): what a
    /// game's profiler overlay shows (bevy_snowpack's diagnostics).
    #[must_use]
    pub fn last_timings(&self) -> PassTimings {
        self.timer.latest()
    }

    /// GPU memory the snow holds now (bytes): the window's buffers, the
    /// point queries', the resident tiles, the objects' and the shared snow's.
    #[must_use]
    pub fn gpu_memory_bytes(&self) -> u64 {
        self.memory_total()
    }

    /// Tiles resident on the GPU around the window (0 without a store or memory keeper).
    #[must_use]
    pub fn resident_tiles(&self) -> usize {
        self.tiles.as_ref().map_or(0, |t| t.stats().resident)
    }

    /// [`Self::memory_bytes`] summed (without building the list but for the objects').
    pub(super) fn memory_total(&self) -> u64 {
        self.core.memory_total()
            + self.accumulation.as_ref().map_or(0, |acc| acc.memory_bytes().iter().map(|(_, b)| b).sum())
            + self.tiles.as_ref().map_or(0, TileStreaming::gpu_bytes)
            + self.sharing.as_ref().map_or(0, crate::replicate::sharing::Sharing::memory_bytes)
    }
}

impl SharedSnow for SnowDeformation {
    /// The world clock now: time, refill and footprint quanta, snowfall.
    fn share_clock(&self) -> ShareClock {
        self.time.share_clock()
    }

    /// Sets the world clock (joining a world): time, refill counters and
    /// snowfall; the frames after it go on from there. When the counters are
    /// the world's own at that time (its refill from time 0), they keep
    /// being counted from the world's beginning, as on every other machine.
    fn join_clock(&mut self, clock: ShareClock) {
        let world = share::world_identity(&self.core, self.sharing.as_ref()).clock_at(clock.time_s);
        self.time.join(clock, world, self.core.params().refill_m_per_s);
    }

    fn window(&self) -> Option<([i64; 2], u32)> {
        self.core.window_origin().map(|o| (o, self.core.params().resolution))
    }

    /// The tiles gathered since the last call (empty without sharing):
    /// whole tiles as the GPU had them at the frame gathered, stamped with
    /// that frame's clock.
    fn take_changed_tiles(&mut self) -> Vec<SharedTile> {
        self.sharing.as_mut().map(Sharing::take_outbox).unwrap_or_default()
    }

    /// The analytic shapes each frame since the last call pressed
    /// (spheres, boxes, wheels; empty without sharing or with the points
    /// technique), with the window and clock they pressed at.
    fn take_press_frames(&mut self) -> Vec<snowpack_share::replicate::press::PressFrame> {
        self.sharing.as_mut().map(Sharing::take_presses).unwrap_or_default()
    }

    /// Queues `tiles`; frames merge them (a bounded number each) once the
    /// clock reaches theirs. Without sharing enabled, or of another tile
    /// side, they are dropped with a warning.
    fn merge_tiles(&mut self, tiles: &[SharedTile]) {
        match &mut self.sharing {
            Some(sharing) => sharing.queue(tiles),
            None if !tiles.is_empty() => tracing::warn!("{} shared tiles dropped: sharing is not enabled (enable_sharing)", tiles.len()),
            None => {}
        }
    }
}
