//! One frame as a list of steps: `FrameSteps::record` records, in order,
//! the characters' skinning, the core window's passes
//! ([`super::core_window`]) and the plug-ins' (tiles, shared snow, objects),
//! then the characters' snow coats and the copy of the pressing meshes'
//! positions for the next frame, into the frame's [`FrameContext`]. A new
//! pass goes in as a step here, at its place in the list (see
//! `docs/architecture.md`).

use glam::Vec2;

use crate::Technique;
use crate::accumulate::{OcclusionParams, SnowAccumulation};
use crate::deform::query::QueryTicket;
use crate::deform::window::TexelRect;
use crate::frame::{FrameContext, WindowFrame};
use crate::replicate::merge::{FrameRecord, TileMergeParams};
use crate::replicate::sharing::Sharing;
use crate::tiles::TileStreaming;

use super::characters::Characters;
use super::clock::{FrameRefill, SnowTime};
use super::core_window::CoreWindow;
use super::ground_after::GroundAfter;
use super::share;
use super::snow_frame::SnowFrame;

/// What a frame's steps change, borrowed apart from the frame's timer (in
/// the context).
pub(super) struct FrameSteps<'s> {
    /// Skinned characters and every pressing mesh's history.
    pub characters: &'s mut Characters,
    /// The window and its passes.
    pub core: &'s mut CoreWindow,
    /// Time, refill and snowfall so far.
    pub time: &'s mut SnowTime,
    /// Objects snow settles on, when there are any.
    pub accumulation: Option<&'s mut SnowAccumulation>,
    /// The tiles kept while the window is away, when kept.
    pub tiles: Option<&'s mut TileStreaming>,
    /// Shared snow, when enabled.
    pub sharing: Option<&'s mut Sharing>,
}

impl FrameSteps<'_> {
    /// Records one frame: `frame`'s characters, deformers and pressing
    /// meshes, and the point queries (with the frame's number), every pass
    /// at its place in the list.
    pub(super) fn record(mut self, cx: &mut FrameContext<'_>, frame: &SnowFrame<'_>, queries: Option<((QueryTicket, &[Vec2]), u64)>) {
        let (texel_m, teleport_m) = (self.core.params().texel_m(), self.core.params().teleport_m);
        self.characters.record_poses(cx, frame, texel_m, teleport_m);
        let (window, old, rects) = self.place_window(cx);
        self.record_move(cx, &window, old, &rects);
        self.record_shared_merge(cx, &window);
        let sky = self.record_occlusion(cx, &window);
        let technique = self.core.params().technique;
        let stamps = matches!(technique, Technique::Points | Technique::Combined);
        // Each deformer presses over its motion since the last frame.
        self.core.sweep(frame.deformers, frame.ids);
        if matches!(technique, Technique::Depth | Technique::Combined) {
            let (meshes, mesh_steps) = self.characters.swept(frame.meshes);
            self.core.record_capture(cx, frame.deformers, window.corner, (&meshes, mesh_steps));
        }
        let share = self.sharing.as_ref().map(|s| s.grid());
        let stamp_params = self.core.stamp_params(window.origin, share);
        self.core.record_stamps(cx, frame.deformers, window.corner, &stamp_params);
        let refill = self.time.refill(self.core.params(), frame.dt_s, stamp_params.quantum_m());
        // Snowfall so far on open ground with this frame's (as the texels have it after the update).
        let open_fallen_m = (self.time.fallen_m + refill.fall_m).min(window.max_fallen_m);
        self.core.record_update(cx, window.origin, &refill, sky.as_ref(), share, open_fallen_m);
        // Snow squeezed beyond the final density onto the texels beside the press.
        self.core.record_displace(cx, window.origin, share);
        if let Some(tiles) = &mut self.tiles {
            tiles.record_weather(cx, self.core.res(), &window, (refill.refill_m, refill.fall_m), refill.refill_quanta);
        }
        if self.sharing.is_none() {
            // Local relaxation: not applied to shared snow, whose copies merge by the larger deficit.
            self.core.record_erosion(cx, window.origin);
        }
        self.time.advance(&refill, window.max_fallen_m);
        self.record_shared_flags(cx, &window, &refill, stamps);
        self.core.record_display(cx, window.origin, self.time.fallen_m);
        self.record_objects(cx, sky.is_some(), refill.fall_m, frame.dt_s);
        self.core.record_decals(cx, frame.deformers, window.corner);
        if let Some((asked, number)) = queries {
            self.core.record_queries(cx, (window.origin, window.corner), asked, number);
        }
        // The characters' snow, against the ground this frame left.
        let ground = GroundAfter { window, fall_m: refill.fall_m, sky };
        let sky_view = self.accumulation.as_deref().map(SnowAccumulation::sky_view);
        self.characters.record_coats(cx, self.core, sky_view, ground, frame.dt_s);
        // This frame's positions of the pressing meshes are the next frame's
        // previous ones (copied after every pass that reads the old).
        self.characters.remember(cx, frame.meshes);
    }

    /// Where the window is this frame (with a store it may wait for tiles
    /// still loading), the footprint buffer when the technique first needs
    /// it, and the move: this frame's window, the old origin and the
    /// exposed rectangles.
    fn place_window(&mut self, cx: &mut FrameContext<'_>) -> (WindowFrame, Option<[i64; 2]>, Vec<TexelRect>) {
        let desired = self.core.desired_origin();
        let old = self.core.window_origin();
        let origin = match &mut self.tiles {
            Some(tiles) => tiles.plan(cx.gpu, old, desired),
            None => desired,
        };
        if self.core.allocate_stamps(cx.gpu)
            && let Some(tiles) = &mut self.tiles
        {
            tiles.add_stamp_plane(cx.gpu, self.core.res());
        }
        let (window, rects) = self.core.move_to(origin, self.time.fallen_m);
        (window, old, rects)
    }

    /// The move's texels: through the tiles when they are kept (stash,
    /// copy-out, restore, load), else fresh snow in the exposed strips.
    fn record_move(&mut self, cx: &mut FrameContext<'_>, window: &WindowFrame, old: Option<[i64; 2]>, rects: &[TexelRect]) {
        match &mut self.tiles {
            Some(tiles) => tiles.record_move(cx, window, self.core.res(), (old, rects), self.time.clock),
            None => self.core.record_window(cx, window, rects),
        }
        self.core.record_window_ground(cx, window, rects);
    }

    /// Shared snow: tiles from elsewhere, before this frame's presses, so
    /// the update and display see them like the window's own trails.
    fn record_shared_merge(&mut self, cx: &mut FrameContext<'_>, window: &WindowFrame) {
        let Some(sharing) = &mut self.sharing else { return };
        let core = &*self.core;
        let (low, high, _) = core.stamp_range();
        let p = core.params();
        let merge = TileMergeParams {
            depth_m: p.depth_m,
            texel_m: p.texel_m(),
            low_m: low,
            high_m: high,
            max_fallen_m: window.max_fallen_m,
            pack_ratio: p.mechanics().pack_ratio(),
            ..Default::default()
        };
        sharing.record_merge(cx, core.res(), &share::share_window(core, window.origin), merge, (&self.time.share_clock(), share::catch_up_rule(core)));
    }

    /// What the sky sees (drawn while the snowfall is set, even at rate 0,
    /// so refill stays out of shelter too), after the objects' poses are
    /// uploaded; its projection, for the update.
    fn record_occlusion(&mut self, cx: &mut FrameContext<'_>, window: &WindowFrame) -> Option<OcclusionParams> {
        let acc = self.accumulation.as_mut()?;
        acc.upload_poses(cx.queue(), window);
        let snowfall = self.core.params().snowfall.as_ref()?;
        Some(acc.record_occlusion(cx, window, snowfall))
    }

    /// Shared snow after the presses: the changed-tile flags out, and the
    /// dirty tiles as this frame left them.
    fn record_shared_flags(&mut self, cx: &mut FrameContext<'_>, window: &WindowFrame, refill: &FrameRefill, stamps: bool) {
        let Some(sharing) = &mut self.sharing else { return };
        let core = &*self.core;
        let record = FrameRecord {
            after: self.time.share_clock(),
            snow_quanta: refill.snow_refill_quanta,
            stamp_quanta: refill.refill_quanta,
            fall_m: refill.fall_m,
            stamps_pressed: stamps && core.res().has_stamps(),
        };
        sharing.record_after_update(cx, core.res(), &share::share_window(core, window.origin), record);
        if core.params().technique != Technique::Points {
            // The analytic shapes this frame's capture pressed, at the clock its update left.
            sharing.record_presses(core.press_frame(window.origin, self.time.share_clock()));
        }
    }

    /// Snow settling on objects: with snowfall, what falls on them this
    /// frame (one occlusion pixel is one window texel of ground), settled;
    /// without, their surface as it is.
    fn record_objects(&mut self, cx: &mut FrameContext<'_>, sheltered: bool, fall_m: f32, dt_s: f32) {
        let Some(acc) = &mut self.accumulation else { return };
        let p = self.core.params();
        match &p.snowfall {
            Some(s) => acc.record_atlas(cx, s, if sheltered { fall_m * p.texel_m() * p.texel_m() } else { 0.0 }, dt_s),
            None => acc.record_surface(cx),
        }
    }
}
