//! The core window: the deformation's resources and its own passes (window,
//! capture, stamps, update, display, decals, queries), each recorded by one
//! step of [`SnowDeformation::encode`](super::SnowDeformation::encode). The
//! plug-ins (objects, tiles, characters, shared snow) are the orchestrator's;
//! the core takes from them only what a pass's uniforms need (the sky's
//! projection, the shared grid), as arguments. Its state is its own: the
//! orchestrator, the steps and the plug-ins' fronts read it through
//! accessors (`params`, `res`, ...) and change it through named settings
//! and jobs (`set_blur`, `allocate_share_flags`, ...), never field by field.

use crate::deform::displace::{DisplaceParams, DisplacePass};
use crate::deform::erosion::{ErosionParams, ErosionPass};
use glam::DVec2;

use crate::accumulate::OcclusionParams;
use crate::deform::capture::{CaptureParams, CapturePass, ShapeCapture, SweptMesh};
use crate::deform::decal::{DEFAULT_PER_ACTOR, DecalPass, DecalRing};
use crate::deform::display::{DisplayKernel, DisplayParams, DisplayPass};
use crate::deform::params::{RANGE_TEXELS, SnowParamsExt};
use crate::deform::query::{PointAnswers, QueryParams, QueryPass, QueryStats, QueryTicket};
use crate::deform::resources::DeformResources;
use crate::deform::stamp::{StampParams, StampPass, contact_points_into};
use crate::deform::sweep::DeformerHistory;
use crate::deform::update::{UpdateParams, UpdatePass};
use crate::deform::window::{SlidingWindow, TexelRect, WindowParams, WindowPass};
use crate::deform::window_ground::WindowGroundPass;
use crate::error::SnowError;
use crate::frame::{FrameContext, WindowFrame};
use crate::gpu::GpuContext;
use crate::height_depth::SkyTest;
use crate::replicate::flags::ShareGrid;
use crate::snowfall::{Snowfall, SnowfallExt};
use crate::{Deformer, RimStyle, SnowParams, Technique, TerrainSource};

use super::clock::FrameRefill;
use super::reads::WindowLayout;
use crate::deform::technique::TechniqueExt;
use crate::terrain::HeightmapTerrainExt;

/// The capture and footprint height range (low, high) of a window of
/// `params` over terrain whose heights span `tmin..=tmax`: snowpack-share's
/// formula, one for the window and for a world's identity made without one.
pub(super) fn capture_range(params: &SnowParams, terrain_m: (f32, f32)) -> (f32, f32) {
    // Snowfall raises the rest depth by up to `max_m`; footprints are quantised over that range.
    let deepest = params.depth_m + params.snowfall.as_ref().map_or(0.0, |s| s.max_m);
    snowpack_share::replicate::world::footprint_range_m(deepest, terrain_m)
}

/// Whether a window of `params` over `terrain` fits an adapter of `limits`:
/// its texture side and the largest buffer its resources bind (an error
/// naming `resolution` or `heightmap` when not).
pub(super) fn fits_adapter(limits: &wgpu::Limits, params: &SnowParams, terrain: &TerrainSource) -> Result<(), SnowError> {
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
    if let TerrainSource::Heightmap(h) = terrain {
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
    Ok(())
}

/// The deformation window over the terrain and the passes that update it.
pub(super) struct CoreWindow {
    params: SnowParams,
    terrain: TerrainSource,
    res: DeformResources,
    window: SlidingWindow,
    /// Where the window is asked to be centred (world m, f64).
    center: DVec2,
    capture_params: CaptureParams,
    window_pass: WindowPass,
    capture_pass: CapturePass,
    stamp_pass: StampPass,
    decal_pass: DecalPass,
    decals: DecalRing,
    update_pass: UpdatePass,
    /// Built on the first frame with an angle of repose.
    erosion_pass: Option<ErosionPass>,
    /// Built on the first frame that displaces snow; bound again when
    /// sharing allocates the changed-tile flags it writes.
    displace_pass: Option<DisplacePass>,
    display_pass: DisplayPass,
    window_ground_pass: WindowGroundPass,
    query_pass: QueryPass,
    /// Tickets given so far ([`super::SnowFrame::with_queries`]).
    tickets: u64,
    /// The newest point answers taken.
    answers: Option<PointAnswers>,
    /// Texels rewritten by window moves so far.
    exposed_texels: u64,
    /// Whether the window's buffers hold snow (after the first move): what
    /// a move overwrites then left the window (the mass ledger).
    filled: bool,
    /// Whether the ledger counts snowfall and refill (`SnowInspect::set_count_mass`).
    count_mass: bool,
    /// Contact points stamped in the last frame.
    points_last_frame: usize,
    /// Contact points left out because a frame brought more than the stamp pass takes.
    points_dropped: u64,
    /// World (x, z) that deformer and object positions are relative to (f64).
    floating_origin: DVec2,
    /// Last frame's deformers, by index, to sweep this frame's from.
    history: DeformerHistory,
    /// The terrain's lowest and highest height (m), found once.
    terrain_bounds: (f32, f32),
    /// Lists one frame fills, kept for their memory so that a frame after
    /// the first allocates nothing for them (however many deformers).
    scratch: FrameScratch,
}

/// Lists the core's steps fill each frame, cleared and refilled.
struct FrameScratch {
    /// Each deformer's pose to sweep from.
    sweeps: Vec<Option<Deformer>>,
    /// The capture's instances.
    instances: crate::deform::capture::CaptureInstances,
    /// The stamp pass's contact points.
    points: Vec<[f32; 8]>,
    /// The boxes that push snow this frame (displacement), from the capture's sweep.
    pushers: [crate::deform::push::Pusher; crate::deform::push::MOST_PUSHERS],
}

/// Erosion iterations a frame while the window displaces snow.
const EROSION_ITERATIONS_DISPLACING: u32 = 4;

impl Default for FrameScratch {
    fn default() -> Self {
        Self {
            sweeps: Vec::new(),
            instances: crate::deform::capture::CaptureInstances::default(),
            points: Vec::new(),
            pushers: [crate::deform::push::NO_PUSHER; crate::deform::push::MOST_PUSHERS],
        }
    }
}

impl CoreWindow {
    /// The window of `params` over `terrain`, centred on `center`, and its passes.
    pub(super) fn new(ctx: &GpuContext, params: SnowParams, terrain: TerrainSource, center: DVec2) -> Self {
        let (device, queue) = (&ctx.device, &ctx.queue);
        let mut res = DeformResources::new(device, queue, &params, &terrain);
        if params.store_ground {
            // Before the passes: they are built for the terrain as stored.
            res.store_ground(device);
        }
        let (tmin, tmax) = terrain.height_bounds();
        let (low_m, high_m) = capture_range(&params, (tmin, tmax));
        let capture_params = CaptureParams { extent_m: params.extent_m, texel_m: params.texel_m(), low_m, high_m };
        Self {
            window_pass: WindowPass::new(device, &res),
            capture_pass: CapturePass::new(device, ShapeCapture::for_adapter(ctx.summary.is_software())),
            stamp_pass: StampPass::new(device, &res),
            decal_pass: DecalPass::new(device, queue, params.resolution, params.technique == Technique::Decals),
            decals: DecalRing::new(DEFAULT_PER_ACTOR, center),
            update_pass: UpdatePass::new(device, &res),
            erosion_pass: None,
            displace_pass: None,
            display_pass: DisplayPass::new(device, &res),
            window_ground_pass: WindowGroundPass::new(device, &res),
            query_pass: QueryPass::new(device, &res),
            tickets: 0,
            answers: None,
            window: SlidingWindow::new(params.resolution),
            center,
            capture_params,
            params,
            terrain,
            res,
            exposed_texels: 0,
            filled: false,
            count_mass: false,
            points_last_frame: 0,
            points_dropped: 0,
            floating_origin: DVec2::ZERO,
            history: DeformerHistory::new(),
            terrain_bounds: (tmin, tmax),
            scratch: FrameScratch::default(),
        }
    }

    /// Quantisation of the stored footprints: (lowest, highest height, quantum), m.
    pub(super) fn stamp_range(&self) -> (f32, f32, f32) {
        let (low, high) = (self.capture_params.low_m, self.capture_params.high_m);
        (low, high, (high - low) / 65535.0)
    }

    /// The window's origin for its centre, snapped to texels.
    pub(super) fn desired_origin(&self) -> [i64; 2] {
        self.window.snapped_origin(self.center.x, self.center.y, f64::from(self.params.texel_m()))
    }

    /// The parameters in use.
    pub(super) fn params(&self) -> &SnowParams {
        &self.params
    }

    /// The terrain under the snow.
    pub(super) fn terrain(&self) -> &TerrainSource {
        &self.terrain
    }

    /// The window's GPU resources (what plug-in passes bind and readbacks read).
    pub(super) fn res(&self) -> &DeformResources {
        &self.res
    }

    /// Global texel index of the window's corner, once placed.
    pub(super) fn window_origin(&self) -> Option<[i64; 2]> {
        self.window.origin()
    }

    /// How the window's toroidal buffers lie (corner (0, 0) before the
    /// window is placed), to read them window-local.
    pub(super) fn layout(&self) -> WindowLayout {
        WindowLayout { resolution: self.params.resolution, origin: self.window.origin().unwrap_or([0, 0]) }
    }

    /// Where the window is asked to be centred (world m).
    pub(super) fn center(&self) -> DVec2 {
        self.center
    }

    /// World (x, z) that deformer and object positions are relative to.
    pub(super) fn floating_origin(&self) -> DVec2 {
        self.floating_origin
    }

    /// Texels rewritten by window moves so far.
    pub(super) fn exposed_texels(&self) -> u64 {
        self.exposed_texels
    }

    /// Contact points stamped in the last frame.
    pub(super) fn points_last_frame(&self) -> usize {
        self.points_last_frame
    }

    /// Contact points left out so far (a frame brought more than the stamp pass takes).
    pub(super) fn points_dropped(&self) -> u64 {
        self.points_dropped
    }

    /// The point queries' counters.
    pub(super) fn query_stats(&self) -> QueryStats {
        self.query_pass.stats()
    }

    /// The newest point answers taken ([`Self::collect_answers`]).
    pub(super) fn answers(&self) -> Option<&PointAnswers> {
        self.answers.as_ref()
    }

    /// The decal ring (each actor's last contacts).
    pub(super) fn decals(&self) -> &DecalRing {
        &self.decals
    }

    /// The decal layer (a 1x1 placeholder until the decals technique's first frame).
    pub(super) fn decal_layer(&self) -> &wgpu::Texture {
        &self.decal_pass.layer
    }

    /// GPU memory the window holds (bytes): its buffers, the point queries' and the decal layer.
    pub(super) fn memory_total(&self) -> u64 {
        self.res.memory_total() + self.query_pass.memory_bytes() + self.decal_pass.layer_bytes()
    }

    /// [`Self::memory_total`] by resource (bytes).
    pub(super) fn memory_bytes(&self) -> Vec<(&'static str, u64)> {
        let mut list = self.res.memory_bytes();
        list.push(("point queries", self.query_pass.memory_bytes()));
        list.push(("decal layer", self.decal_pass.layer_bytes()));
        list
    }

    /// Changes the snowfall from the next frame on (`None` stops it): an
    /// error, leaving it as it was, when the window was created without
    /// snowfall or `max_m` grows beyond the one the footprints were
    /// quantised for (`SnowDeformation::set_snowfall`).
    pub(super) fn set_snowfall(&mut self, snowfall: Option<Snowfall>) -> Result<(), SnowError> {
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

    /// Sets the floating origin; `true` when it moved (the remembered
    /// deformers moved with it, and meshes' positions must be forgotten).
    pub(super) fn set_floating_origin(&mut self, origin: DVec2) -> bool {
        // Remembered deformers move with the origin (so they still sweep).
        let delta = self.floating_origin - origin;
        if delta != DVec2::ZERO {
            self.history.shift(glam::Vec3::new(delta.x as f32, 0.0, delta.y as f32));
        }
        self.floating_origin = origin;
        delta != DVec2::ZERO
    }

    /// Sets the refill rate (m/s, at least 0) from the next frame.
    pub(super) fn set_refill(&mut self, refill_m_per_s: f32) {
        self.params.refill_m_per_s = refill_m_per_s.max(0.0);
    }

    /// Sets the rim strength (at least 0) from the next frame.
    pub(super) fn set_elevation(&mut self, elevation: f32) {
        self.params.elevation = elevation.max(0.0);
    }

    /// Switches the technique from the next frame (its buffer comes then).
    pub(super) fn set_technique(&mut self, technique: Technique) {
        self.params.technique = technique;
    }

    /// Sets the footprint size (clamped to the points technique's range) and rim formula.
    pub(super) fn set_points(&mut self, range_texels: u32, rim: RimStyle) {
        self.params.range_texels = range_texels.clamp(*RANGE_TEXELS.start(), *RANGE_TEXELS.end());
        self.params.rim = rim;
    }

    /// Turns the displayed-surface blur on or off.
    pub(super) fn set_blur(&mut self, blur: bool) {
        self.params.blur = blur;
    }

    /// Sets the angle of repose; an angle the parameters refuse is an
    /// error naming `repose_deg`, and the angle stays as it was.
    pub(super) fn set_repose(&mut self, repose_deg: Option<f32>) -> Result<(), SnowError> {
        let p = SnowParams { repose_deg, ..self.params.clone() };
        p.validate()?;
        self.params.repose_deg = repose_deg;
        Ok(())
    }

    /// Moves the window's centre; the move happens at the next frame.
    pub(super) fn set_center(&mut self, center: DVec2) {
        self.center = center;
    }

    /// The ticket of the next frame's point queries.
    pub(super) fn next_ticket(&mut self) -> QueryTicket {
        self.tickets += 1;
        QueryTicket(self.tickets)
    }

    /// Takes the point answers that have arrived, keeping the newest.
    pub(super) fn collect_answers(&mut self) {
        if let Some(answers) = self.query_pass.take_answers() {
            self.answers = Some(answers);
        }
    }

    /// Whether a point answer's mapping callback has yet to run.
    pub(super) fn answers_pending(&self) -> bool {
        self.query_pass.callbacks_pending()
    }

    /// The analytic shapes the last capture pressed, as a frame that
    /// travels (`snowpack_share::replicate::press`): the window at `origin`, the
    /// capture's range, the snow's packing and the `clock` after the update.
    pub(super) fn press_frame(&self, origin: [i64; 2], clock: crate::replicate::ShareClock) -> snowpack_share::replicate::press::PressFrame {
        snowpack_share::replicate::press::PressFrame {
            clock,
            origin,
            resolution: self.params.resolution,
            low_m: self.capture_params.low_m,
            high_m: self.capture_params.high_m,
            pack_ratio: self.params.mechanics().pack_ratio(),
            shapes: self.scratch.instances.sweeps.clone(),
        }
    }

    /// How the capture takes the analytic shapes.
    pub(super) fn shape_capture(&self) -> ShapeCapture {
        self.capture_pass.shape_capture()
    }

    /// Takes the analytic shapes `by` compute or drawn from the next frame on.
    pub(super) fn set_shape_capture(&mut self, by: ShapeCapture) {
        self.capture_pass.set_shape_capture(by);
    }

    /// How the display pass maps its work.
    pub(super) fn display_kernel(&self) -> DisplayKernel {
        self.display_pass.kernel()
    }

    /// Displays with `kernel` from the next frame on.
    pub(super) fn set_display_kernel(&mut self, kernel: DisplayKernel) {
        self.display_pass.set_kernel(kernel);
    }

    /// Binds the objects' occlusion map (`sky`; `None` without objects) to the update pass.
    pub(super) fn bind_sky(&mut self, device: &wgpu::Device, sky: Option<&wgpu::TextureView>) {
        self.update_pass.bind_sky(device, &self.res, sky);
    }

    /// Allocates the changed-tile flags of shared snow (`slots` tiles) and
    /// binds them to the passes that write them (stamp, update with the
    /// objects' occlusion map `sky`, displace).
    pub(super) fn allocate_share_flags(&mut self, device: &wgpu::Device, slots: u32, sky: Option<&wgpu::TextureView>) {
        self.res.allocate_share_flags(device, slots);
        self.stamp_pass = StampPass::new(device, &self.res);
        self.update_pass = UpdatePass::new(device, &self.res);
        self.update_pass.bind_sky(device, &self.res, sky);
        if let Some(displace) = &mut self.displace_pass {
            displace.bind_flags(device, &self.res);
        }
    }

    /// Allocates the footprint buffer the first time the technique uses it
    /// (the window's bindings follow; no pass binds it itself); `true` when
    /// it did, so the tiles add a footprint plane.
    pub(super) fn allocate_stamps(&mut self, ctx: &GpuContext) -> bool {
        self.params.technique.uses_stamps() && self.res.allocate_stamps(&ctx.device, &ctx.queue)
    }

    /// Moves the window to `origin`: the rectangles of texels it exposes
    /// (counted) and where the window is this frame, with `fallen_m` of
    /// snowfall so far.
    pub(super) fn move_to(&mut self, origin: [i64; 2], fallen_m: f32) -> (WindowFrame, Vec<TexelRect>) {
        let p = &self.params;
        let texel = f64::from(p.texel_m());
        self.filled = self.window.origin().is_some();
        let rects = self.window.move_to(origin);
        self.exposed_texels += rects.iter().map(|r| u64::from(r[2]) * u64::from(r[3])).sum::<u64>();
        // Deformers and objects are relative to the floating origin; so is the corner they are placed against.
        let corner = DVec2::new(origin[0] as f64 * texel, origin[1] as f64 * texel) - self.floating_origin;
        let window = WindowFrame {
            origin,
            corner,
            resolution: p.resolution,
            extent_m: p.extent_m,
            depth_m: p.depth_m,
            texel_m: p.texel_m(),
            fallen_m,
            max_fallen_m: p.snowfall.as_ref().map_or(0.0, |s| s.max_m),
            low_m: self.capture_params.low_m,
            high_m: self.capture_params.high_m,
            use_fallen: p.keeps_lying_snow(),
            terrain_m: self.terrain_bounds,
        };
        (window, rects)
    }

    /// Whether the ledger counts snowfall and refill from the next frame on.
    pub(super) fn set_count_mass(&mut self, on: bool) {
        self.count_mass = on;
    }

    /// The window pass: fresh snow in the texels a move exposed (when no
    /// tiles are kept; otherwise the tiles' exchange does it).
    pub(super) fn record_window(&self, cx: &mut FrameContext<'_>, window: &WindowFrame, rects: &[TexelRect]) {
        let p = &self.params;
        let params = WindowParams {
            origin: gpu_origin(window.origin),
            resolution: p.resolution,
            texel_m: p.texel_m(),
            depth_m: p.depth_m,
            fallen_m: window.fallen_m,
            flags: if p.keeps_lying_snow() { WindowParams::WRITE_FALLEN } else { 0 }
                | if self.res.has_stamps() { WindowParams::WRITE_STAMPS } else { 0 }
                | if self.filled { WindowParams::COUNT_LEFT } else { 0 },
            ..WindowParams::default()
        };
        self.window_pass.record(cx, &self.res, params, rects);
    }

    /// The terrain under the texels a move exposed, where the window
    /// stores it (noise hills): after the move's snow, whose stash reads the
    /// leaving texels' ground by evaluating it.
    pub(super) fn record_window_ground(&self, cx: &mut FrameContext<'_>, window: &WindowFrame, rects: &[TexelRect]) {
        let p = &self.params;
        let params = WindowParams { origin: gpu_origin(window.origin), resolution: p.resolution, texel_m: p.texel_m(), ..WindowParams::default() };
        self.window_ground_pass.record(cx, params, rects);
    }

    /// Each deformer's pose to sweep from (its last frame's), then this
    /// frame's remembered for the next.
    pub(super) fn sweep(&mut self, deformers: &[Deformer], ids: &[u64]) {
        self.history.sweeps_into(deformers, ids, self.params.teleport_m, &mut self.scratch.sweeps);
        self.history.remember(deformers, ids);
    }

    /// The capture (techniques depth and combined): each deformer's and
    /// mesh's underside, swept over its motion, into the capture depth.
    pub(super) fn record_capture(
        &mut self,
        cx: &mut FrameContext<'_>,
        deformers: &[Deformer],
        corner: DVec2,
        (meshes, mesh_steps): (&[SweptMesh<'_>], &[u32]),
    ) {
        let scratch = &mut self.scratch;
        let instances = &mut scratch.instances;
        instances.fill_swept(deformers, &scratch.sweeps, corner, &self.capture_params);
        scratch.pushers = crate::deform::push::pushers(deformers, &scratch.sweeps, corner, self.params.texel_m());
        instances.mesh_steps.clear();
        instances.mesh_steps.extend_from_slice(mesh_steps);
        // The capture's outputs are made on the first frame that writes them.
        if self.res.allocate_capture(cx.device(), self.capture_pass.writes(instances, meshes)) {
            self.update_pass.rebind(cx.device(), &self.res);
        }
        self.capture_pass.record(cx, &self.res, (&self.capture_params, instances), meshes);
    }

    /// The stamp pass's uniforms at `origin` (the shared grid's, when the snow is shared).
    pub(super) fn stamp_params(&self, origin: [i64; 2], share: Option<ShareGrid>) -> StampParams {
        let p = &self.params;
        StampParams {
            origin: gpu_origin(origin),
            resolution: p.resolution,
            range_texels: p.range_texels,
            texel_m: p.texel_m(),
            low_m: self.capture_params.low_m,
            high_m: self.capture_params.high_m,
            count: 0,
            share_side: share.map_or(0, |g| g.side),
            share_keys: share.map_or(0, |g| g.keys),
            ..StampParams::default()
        }
    }

    /// The stamps (techniques points and combined; none with the others):
    /// each deformer's contact points, swept, as footprints; counts what a
    /// frame brought beyond the pass's limit.
    pub(super) fn record_stamps(&mut self, cx: &mut FrameContext<'_>, deformers: &[Deformer], corner: DVec2, stamp_params: &StampParams) {
        self.points_last_frame = 0;
        if !matches!(self.params.technique, Technique::Points | Technique::Combined) {
            return;
        }
        let points = &mut self.scratch.points;
        contact_points_into(deformers, &self.scratch.sweeps, corner, stamp_params, points);
        let dropped = self.stamp_pass.record(cx, &self.res, stamp_params, points);
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

    /// The update: the persistent snow pressed by this frame's capture and
    /// stamps, refilled by `refill`'s quanta, under `sky` (objects'
    /// shelter) and flagging the tiles of `share` it changes;
    /// `open_fallen_m` is the snowfall so far on open ground with this
    /// frame's (lying snow beyond it is a berm).
    pub(super) fn record_update(
        &self,
        cx: &mut FrameContext<'_>,
        origin: [i64; 2],
        refill: &FrameRefill,
        sky: Option<&OcclusionParams>,
        share: Option<ShareGrid>,
        open_fallen_m: f32,
    ) {
        let p = &self.params;
        let technique = p.technique;
        let captures = matches!(technique, Technique::Depth | Technique::Combined);
        let stamps = matches!(technique, Technique::Points | Technique::Combined);
        let snowfall = p.snowfall.as_ref();
        let params = UpdateParams {
            origin: gpu_origin(origin),
            resolution: p.resolution,
            depth_m: p.depth_m,
            snow_refill_quanta: refill.snow_refill_quanta,
            low_m: self.capture_params.low_m,
            high_m: self.capture_params.high_m,
            flags: if captures { UpdateParams::USE_CAPTURE | self.capture_pass.update_flags() } else { 0 }
                | if stamps { UpdateParams::USE_STAMPS } else { 0 }
                | if p.keeps_lying_snow() { UpdateParams::USE_FALLEN } else { 0 }
                | if sky.is_some() { UpdateParams::USE_SKY } else { 0 }
                | if self.res.has_stamps() { UpdateParams::HAS_STAMPS } else { 0 }
                | if share.is_some() { UpdateParams::SHARE } else { 0 }
                | if self.displaces() { UpdateParams::DISPLACE } else { 0 }
                | if self.displaces() && share.is_none() { UpdateParams::CONSUME } else { 0 }
                // The mass ledger counts what this frame's snowfall and refill add (nothing to count without them).
                | if self.count_mass && (refill.snow_refill_quanta > 0 || refill.fall_m > 0.0) { UpdateParams::LEDGER } else { 0 },
            refill_quanta: refill.refill_quanta,
            fall_m: refill.fall_m,
            max_fallen_m: snowfall.map_or(0.0, |s| s.max_m),
            texel_m: p.texel_m(),
            sky: sky.map_or(SkyTest::NONE, |s| s.sky_test()),
            share_side: share.map_or(0, |g| g.side),
            share_keys: share.map_or(0, |g| g.keys),
            pack_ratio: p.mechanics().pack_ratio(),
            displace_k: (self.capture_params.high_m - self.capture_params.low_m) * 8.0 / p.texel_m(),
            pushers: self.scratch.pushers,
            open_fallen_m,
            ..Default::default()
        };
        self.update_pass.record(cx, &self.res, &params);
    }

    /// Whether presses displace snow into berms: asked for, and a technique
    /// that captures (the capture gives the way out of a press).
    pub(super) fn displaces(&self) -> bool {
        self.params.displace && matches!(self.params.technique, Technique::Depth | Technique::Combined)
    }

    /// The berms: the moves the update chose, gathered at their targets
    /// (`docs/mechanics.md`, "Displacement"), when the window displaces.
    pub(super) fn record_displace(&mut self, cx: &mut FrameContext<'_>, origin: [i64; 2], share: Option<ShareGrid>) {
        if !self.displaces() {
            return;
        }
        let params = DisplaceParams {
            origin: gpu_origin(origin),
            resolution: self.params.resolution,
            flags: if share.is_some() { DisplaceParams::SHARE } else { 0 },
            share_side: share.map_or(0, |g| g.side),
            share_keys: share.map_or(0, |g| g.keys),
            ..DisplaceParams::default()
        };
        let res = &self.res;
        self.displace_pass.get_or_insert_with(|| DisplacePass::new(cx.device(), res)).record(cx, res, &params);
    }

    /// One iteration of erosion where the snow has an angle of repose
    /// (`docs/mechanics.md`, "Erosion").
    pub(super) fn record_erosion(&mut self, cx: &mut FrameContext<'_>, origin: [i64; 2]) {
        let Some(repose_deg) = self.params.repose_deg else { return };
        let p = &self.params;
        let params = ErosionParams {
            origin: gpu_origin(origin),
            resolution: p.resolution,
            texel_m: p.texel_m(),
            depth_m: p.depth_m,
            threshold_q: ErosionParams::threshold_quanta(repose_deg, p.texel_m()),
            use_fallen: u32::from(p.keeps_lying_snow()),
            marks: u32::from(self.displaces()),
            ..ErosionParams::default()
        };
        let res = &self.res;
        // Four while displacing: a plough's windrow arrives faster than one iteration settles it.
        let iterations = if self.displaces() { EROSION_ITERATIONS_DISPLACING } else { 1 };
        self.erosion_pass.get_or_insert_with(|| ErosionPass::new(cx.device(), res)).record(cx, res, &params, iterations);
    }

    /// The display: rims, blur and the displayed half of each snow word.
    pub(super) fn record_display(&self, cx: &mut FrameContext<'_>, origin: [i64; 2], open_fallen_m: f32) {
        let p = &self.params;
        let params = DisplayParams {
            origin: gpu_origin(origin),
            resolution: p.resolution,
            depth_m: p.depth_m,
            elevation: p.elevation,
            mode: DisplayParams::mode_for(p.technique, p.rim),
            low_m: self.capture_params.low_m,
            high_m: self.capture_params.high_m,
            use_fallen: u32::from(p.keeps_lying_snow()),
            texel_m: p.texel_m(),
            blur: u32::from(p.blur),
            open_fallen_m,
            ..Default::default()
        };
        self.display_pass.record(cx, &self.res, &params);
    }

    /// The decals: contacts are kept whatever the technique (so switching
    /// to decals shows the recent ones) and drawn only with decals.
    pub(super) fn record_decals(&mut self, cx: &mut FrameContext<'_>, deformers: &[Deformer], corner: DVec2) {
        let p = &self.params;
        self.decals.observe(deformers, &self.terrain, p.depth_m);
        if p.technique == Technique::Decals {
            self.decal_pass.allocate_layer(cx.device());
            self.decal_pass.record(cx, &mut self.decals, (corner, p.extent_m));
        }
    }

    /// The point queries of `frame` (ticket and points, relative to the
    /// floating origin), gathered at the window at `origin` and copied out.
    pub(super) fn record_queries(
        &mut self,
        cx: &mut FrameContext<'_>,
        (origin, corner): ([i64; 2], DVec2),
        (ticket, points): (QueryTicket, &[glam::Vec2]),
        frame: u64,
    ) {
        let p = &self.params;
        let local: Vec<glam::Vec2> = points.iter().map(|q| glam::Vec2::new((f64::from(q.x) - corner.x) as f32, (f64::from(q.y) - corner.y) as f32)).collect();
        let params = QueryParams {
            origin: gpu_origin(origin),
            resolution: p.resolution,
            count: 0,
            texel_m: p.texel_m(),
            depth_m: p.depth_m,
            use_fallen: u32::from(p.keeps_lying_snow()),
            _pad: 0,
        };
        self.query_pass.record(cx, &self.res, params, &local, (ticket, frame, points.to_vec()));
    }
}

/// Window and tile coordinates stay in i64 on the CPU; the GPU needs only
/// i32 (about 134,000 km of texels at 6.25 cm).
fn gpu_origin(origin: [i64; 2]) -> [i32; 2] {
    [origin[0] as i32, origin[1] as i32]
}
