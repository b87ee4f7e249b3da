//! Open worlds: the world's tiles around the sliding window, resident on the
//! GPU, and their traffic with a [`TileStreamer`] (the tile keeper: memory
//! only by default, or a disk store).
//!
//! The world is cut into square tiles of `side` texels on the global texel
//! grid. While tiles are kept, the tiles the window touches, plus one spare
//! ring, are resident in a toroidal grid of slots (`shared/tiles.wgsl`):
//! texels leaving the window are stashed into their tile, texels entering are
//! loaded from theirs, and the tile weather pass lets time pass on the
//! resident texels outside the window. A slot is given up only when another
//! tile needs it; its tile is then copied out in the same command buffer,
//! read back asynchronously and handed to the streamer, which compresses and
//! writes it on its worker thread. A tile coming back is restored in one pass
//! with the refill and snowfall of the time it was away.
//!
//! The frame never waits for the disk: fresh snow stands in for a tile the
//! window needs that is not in memory yet ([`TileStats::stood_in`]; the
//! prefetch ring around the window makes that rare on a walk), and its
//! stored version is merged in live when the streamer has it
//! ([`TileStats::merged_live`], `live_merge.rs`). The window holds still
//! only for a tile still on its way back from the GPU
//! ([`TileStats::window_waits`]). The blocking path is the explicit
//! preload a loading screen calls, and a batch run's
//! `StreamerConfig::moves_wait_for_disk`.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

mod arrivals;
mod copy_out;
mod layout;
mod live_merge;
mod planner;
mod recording;
mod stats;

use crate::deform::params::default_tile_texels;
use crate::deform::resources::DeformResources;
use crate::deform::window::TexelRect;
use crate::error::SnowError;
use crate::frame::{FrameContext, WindowFrame};
use crate::gpu::{GpuContext, GpuTimer};
use crate::persist::{SnowClock, StoreError, StreamerConfig, TileKey, TileStreamer};

use super::exchange::ExchangeParams;
use super::restore::{RestoreEntry, RestoreParams};
use arrivals::Arrival;
use copy_out::CopyOuts;
use layout::SlotLayout;
use live_merge::LiveMergeParts;
use planner::{MovePlanner, PlanParts};
use recording::TilePasses;
use stats::TileCounters;

// The slot layout lives in `planes.rs` (the tile passes below this file need
// it too); it stays reachable here, where the streaming's users look for it.
pub use super::planes::{PLANE_FALLEN, PLANE_SNOW, PLANES, plane_packed, plane_stamps, planes};
// The grid and the slot pool live in files of their own; the grid stays
// reachable here, where the streaming's users look for it.
pub use super::grid::{PREFETCH_MARGIN_TILES, TileGrid};
use super::slots::SlotTable;
use crate::gpu::context::GpuContextExt;
use crate::persist::streamer::TileStreamerExt;
pub use copy_out::tile_from_planes;
pub use stats::TileStats;

/// Most tiles per submission of a batched move or a save.
const BATCH_TILES: usize = 32;

/// The resident tiles, their passes and the streamer behind them.
pub struct TileStreaming {
    /// The grid, the snow's depth and the planes a slot has.
    layout: SlotLayout,
    streamer: TileStreamer,
    /// The slots' buffer and the passes bound to it.
    passes: TilePasses,
    /// The slot pool, its key table and which tile holds each slot.
    slots: SlotTable,
    moves: u64,
    batched_moves: u64,
    /// The copies out of the GPU in flight.
    copy_outs: CopyOuts,
    /// Where the window goes: the prefetch ring, the waits.
    planner: MovePlanner,
    errors: Vec<StoreError>,
    /// The last frame's restore uniforms, for the merges a save does.
    restore_base: RestoreParams,
    /// The traffic counters of [`TileStats`].
    counters: TileCounters,
    /// Where the window is (as of the last move recorded), for
    /// [`TileStats::awaiting_merge`].
    at: Option<[i64; 2]>,
}

impl TileStreaming {
    /// The default tile keeper: tiles of [`default_tile_texels`] kept in
    /// memory up to `budget` bytes. `None` (with a warning) where the
    /// resident ring would not fit in one of this adapter's storage buffers
    /// (resolutions far above the default): the window then forgets, as with
    /// `tile_memory_bytes: None`, rather than failing to be created.
    pub(crate) fn keep_in_memory(ctx: &GpuContext, res: &DeformResources, params: &crate::SnowParams, budget: usize) -> Result<Option<Self>, SnowError> {
        let side = default_tile_texels(params.resolution);
        let grid = TileGrid::new(params.resolution, side)?;
        let bytes = (grid.slot_count() * planes(params.keeps_lying_snow(), true) * grid.area() * 4) as u64;
        let limit = ctx.device.limits().max_storage_buffer_binding_size;
        if bytes > limit {
            tracing::warn!(
                "trails are not kept: {bytes} bytes of resident tiles exceed this adapter's {limit} byte buffers (resolution {})",
                params.resolution
            );
            return Ok(None);
        }
        let streamer = TileStreamer::in_memory(side, StreamerConfig { memory_budget_bytes: budget, ..StreamerConfig::default() });
        Self::new(ctx, res, streamer, (params.depth_m, params.keeps_lying_snow())).map(Some)
    }

    /// After the window's footprint buffer was allocated: gives every slot a
    /// footprint plane (no footprints), keeping the other planes, and binds
    /// the passes to the new slots and to `res`. Copy-outs in flight keep
    /// the old layout (each knows its own): nothing is waited for. Once, on
    /// the first switch to points or combined.
    pub fn add_stamp_plane(&mut self, ctx: &GpuContext, res: &DeformResources) {
        if self.layout.has_stamps || !res.has_stamps() {
            return;
        }
        let area = self.layout.grid.area() as u64;
        let old = self.layout.planes() as u64;
        self.layout.has_stamps = true;
        let new = self.layout.planes() as u64;
        let slots = self.layout.grid.slot_count() as u64;
        let tiles = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("resident tiles"),
            size: slots * new * area * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // No footprint anywhere, then each slot's old planes in front of its new last one.
        let empty = vec![u32::MAX; (slots * new * area) as usize];
        ctx.queue.write_buffer(&tiles, 0, bytemuck::cast_slice(&empty));
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("tile footprint plane") });
        for slot in 0..slots {
            encoder.copy_buffer_to_buffer(&self.passes.tiles, slot * old * area * 4, &tiles, slot * new * area * 4, old * area * 4);
        }
        ctx.queue.submit([encoder.finish()]);
        self.passes.rebind(&ctx.device, res, tiles, &self.slots);
    }

    /// Resident slots for the window of `res`, behind `streamer`.
    pub fn new(ctx: &GpuContext, res: &DeformResources, streamer: TileStreamer, (depth_m, use_fallen): (f32, bool)) -> Result<Self, SnowError> {
        let grid = TileGrid::new(res.resolution, streamer.side())?;
        // Sized for the footprint plane too, so a later switch to points fits.
        let most = (grid.slot_count() * planes(use_fallen, true) * grid.area() * 4) as u64;
        let bytes = (grid.slot_count() * planes(use_fallen, res.has_stamps()) * grid.area() * 4) as u64;
        let limit = ctx.device.limits().max_storage_buffer_binding_size;
        if most > limit {
            let bytes = most;
            return Err(SnowError::InvalidParameter {
                field: "tile_texels",
                why: format!("{} resident tiles of {}² need {bytes} bytes, above this adapter's {limit}; use larger tiles", grid.slot_count(), grid.side()),
            });
        }
        let tiles = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("resident tiles"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let slots = SlotTable::new(&ctx.device, &ctx.queue, grid);
        let this = Self {
            passes: TilePasses::new(&ctx.device, res, tiles, &slots),
            slots,
            moves: 0,
            batched_moves: 0,
            layout: SlotLayout { grid, depth_m, use_fallen, has_stamps: res.has_stamps() },
            streamer,
            copy_outs: CopyOuts::default(),
            planner: MovePlanner::default(),
            errors: Vec::new(),
            restore_base: RestoreParams::default(),
            counters: TileCounters::default(),
            at: None,
        };
        ctx.check("creating the resident tiles")?;
        Ok(this)
    }

    /// The tile layout.
    #[must_use]
    pub fn grid(&self) -> &TileGrid {
        &self.layout.grid
    }

    /// The streamer (the store behind the tiles).
    pub fn streamer(&mut self) -> &mut TileStreamer {
        &mut self.streamer
    }

    /// Whether the tiles are kept in memory only (no disk store behind them).
    #[must_use]
    pub fn is_memory_only(&self) -> bool {
        self.streamer.is_memory_only()
    }

    fn resident(&self, key: TileKey) -> bool {
        self.slots.contains(key)
    }

    /// The planner and what it works on, borrowed apart for one call.
    fn planner_and_parts(&mut self) -> (&mut MovePlanner, PlanParts<'_>) {
        let parts = PlanParts {
            layout: self.layout,
            slots: &self.slots,
            copy_outs: &mut self.copy_outs,
            streamer: &mut self.streamer,
            errors: &mut self.errors,
            counters: &mut self.counters,
        };
        (&mut self.planner, parts)
    }

    /// Decides where the window goes this frame: `desired`, once every tile
    /// it touches can be made resident without waiting for the disk; until
    /// then it stays at `current`. The first placement waits (blocking).
    /// (`MovePlanner::plan`.)
    pub fn plan(&mut self, ctx: &GpuContext, current: Option<[i64; 2]>, desired: [i64; 2]) -> [i64; 2] {
        let (planner, parts) = self.planner_and_parts();
        planner.plan(ctx, parts, current, desired)
    }

    /// The explicit wait a loading screen makes: loads (blocking) every
    /// tile the window moving from `current` to `desired` needs, so the
    /// next [`Self::plan`] for `desired` moves there at once (a jump
    /// instead of holding while the disk reads) and a first placement
    /// waits for nothing. What the disk does not give within the wait
    /// limit is stood in for as in a frame, and reported the same way.
    /// (`MovePlanner::preload`.)
    pub fn preload(&mut self, ctx: &GpuContext, current: Option<[i64; 2]>, desired: [i64; 2]) {
        let (planner, parts) = self.planner_and_parts();
        planner.preload(ctx, parts, current, desired);
    }

    /// Records the tile side of a window move from `old` to `origin` that
    /// exposed `rects`: the stash of the leaving texels, the copy-out of
    /// slots given up, the restore of the tiles now touched, the load of the
    /// entering texels. `clock` is the clock at the start of this frame.
    pub fn record_move(
        &mut self,
        cx: &mut FrameContext<'_>,
        frame @ &WindowFrame { origin, .. }: &WindowFrame,
        res: &DeformResources,
        (old, rects): (Option<[i64; 2]>, &[TexelRect]),
        clock: SnowClock,
    ) {
        if let Some(old) = old {
            // Before anything of the move: the merges submit on their own.
            let parts = LiveMergeParts {
                layout: self.layout,
                slots: &mut self.slots,
                passes: &mut self.passes,
                streamer: &mut self.streamer,
                gave_up: self.planner.gave_up(),
                counters: &mut self.counters,
                errors: &mut self.errors,
                moves: self.moves,
            };
            live_merge::record_live_merges(parts, cx.gpu, res, frame, old, clock);
        }
        self.at = Some(origin);
        if rects.is_empty() {
            return;
        }
        self.moves += 1;
        if let Some(old) = old
            && self.record_step(cx, res, (old, origin, rects), frame, clock)
        {
            return;
        }
        self.batched_moves += 1;
        self.record_batched(cx.gpu, res, (old, origin), frame, clock);
    }

    /// This frame's restore uniforms, kept for the merges a save does.
    fn restore_params(&mut self, frame: &WindowFrame) -> RestoreParams {
        self.restore_base = self.layout.restore_params(frame);
        self.restore_base
    }

    fn assign(&mut self, key: TileKey, slot: usize) {
        self.slots.assign(key, slot, self.moves);
    }

    fn release(&mut self, key: TileKey) {
        self.slots.release(key);
    }

    fn free_slot(&self) -> Option<usize> {
        self.slots.free_slot()
    }

    fn write_table(&self, queue: &wgpu::Queue) {
        self.slots.write(queue);
    }

    /// The restore entry of `key` into `slot`, from the streamer (saved
    /// planes appended to `upload`) or fresh; with what the window made in
    /// the tile's place while the disk was late to merge in, where there is
    /// (`arrivals::restore_entry`).
    fn restore_entry(&mut self, key: TileKey, slot: usize, upload: &mut Vec<u32>, clock: SnowClock) -> RestoreEntry {
        let arrival = Arrival {
            grid: self.layout.grid,
            streamer: &mut self.streamer,
            gave_up: self.planner.gave_up(),
            counters: &mut self.counters,
            errors: &mut self.errors,
        };
        arrivals::restore_entry(arrival, key, slot, upload, clock)
    }

    /// A move of at most a few tiles, in the frame's encoder, when the pool
    /// holds every tile it needs: stash, copy-out, restore, load. The tiles
    /// that need a slot are those that keep or receive texels outside the new
    /// window (stash targets, edge tiles) and those its entering texels come
    /// from. `false` (nothing recorded) when they do not fit.
    fn record_step(
        &mut self,
        cx: &mut FrameContext<'_>,
        res: &DeformResources,
        (old, origin, rects): ([i64; 2], [i64; 2], &[TexelRect]),
        frame: &WindowFrame,
        clock: SnowClock,
    ) -> bool {
        let g = self.layout.grid;
        let mut required: Vec<TileKey> = g.around(old, 0).into_iter().filter(|&k| !g.inside(k, origin)).collect();
        required.extend(g.around(origin, 0).into_iter().filter(|&k| !g.inside(k, old) && !g.touched(k, old)));
        required.extend(g.around(origin, 0).into_iter().filter(|&k| g.touched(k, old) && !g.inside(k, old) && g.inside(k, origin)));
        // Every tile the table maps this frame must lie near the new window.
        if required.len() > g.slot_count() || required.iter().any(|&k| !g.near(k, origin, PREFETCH_MARGIN_TILES)) {
            return false;
        }
        let evicting = self.evict_for(&required, origin);
        // What leaves and enters is counted in the mass ledger.
        let stash = self.layout.exchange_params(res, old, origin, ExchangeParams::STASH | ExchangeParams::COUNT);
        let (mut entries, mut upload) = (Vec::new(), Vec::<u32>::new());
        let mut deferred = Vec::new();
        for &k in &required {
            if self.resident(k) {
                continue;
            }
            let slot = self.free_slot().expect("room was made for every missing tile");
            if g.touched(k, old) {
                // Wholly inside the old window: its texels are all there; the
                // stash fills the ones leaving, nothing reads the others.
                self.assign(k, slot);
            } else {
                deferred.push((k, slot));
                self.assign(k, slot);
            }
        }
        // The stash sees the table with the tiles restored below already
        // mapped; they receive no stashed texels (the old window did not touch them).
        // The evicted tiles were not in the old window (no stashed texels):
        // copied out first, before their slots take stashed or restored texels.
        if !evicting.is_empty() {
            self.record_copy_out(cx, res, &evicting, clock);
        }
        self.write_table(cx.queue());
        self.passes.exchange.record(cx, res, stash, rects);
        for (k, slot) in deferred {
            let entry = self.restore_entry(k, slot, &mut upload, clock);
            entries.push(entry);
        }
        let params = self.restore_params(frame);
        self.passes.restore.record(cx, (res, &self.passes.tiles), params, &entries, &upload);
        self.passes.exchange.record(cx, res, self.layout.exchange_params(res, old, origin, ExchangeParams::COUNT), rects);
        // Tiles now wholly inside the window give their slots up (their
        // texels were all loaded or never left): no copy-out. The GPU table
        // keeps them until the next write, after this frame's load.
        let inside: Vec<TileKey> = self.slots.keys().filter(|&k| g.inside(k, origin)).collect();
        for k in inside {
            self.release(k);
        }
        true
    }

    /// Gives up the slots a step to `origin` needs for the `required`
    /// tiles ([`SlotTable::evict_for`]): the evicted tiles and their slots,
    /// to copy out.
    fn evict_for(&mut self, required: &[TileKey], origin: [i64; 2]) -> Vec<(TileKey, usize)> {
        self.slots.evict_for(required, origin, self.moves)
    }

    /// A jump (or the first placement) in batches of its own submits: every
    /// tile of the old window is stashed whole and copied out (as many at a
    /// time as the pool holds), then every tile of the new window is
    /// restored and loaded whole, and only its edge tiles keep their slots.
    /// The copies out are collected over the next frames; only the first
    /// placement, or an arriving tile still on its way out, waits for them.
    fn record_batched(&mut self, ctx: &GpuContext, res: &DeformResources, (old, origin): (Option<[i64; 2]>, [i64; 2]), frame: &WindowFrame, clock: SnowClock) {
        let (layout, g) = (self.layout, self.layout.grid);
        let mut timer = GpuTimer::disabled();
        let submit = |ctx: &GpuContext, encoder: wgpu::CommandEncoder| ctx.queue.submit([encoder.finish()]);
        let new_encoder = |ctx: &GpuContext| ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("tile batch") });
        // The batches count nothing (a kept edge tile is loaded again by
        // later batches): the ledger sweeps the whole window, before (left)
        // and after (entered).
        if let Some(old) = old {
            self.passes.record_sweep(ctx, res, &layout, old, ExchangeParams::STASH);
        }
        // Leave: every resident tile and every tile of the old window goes to the store.
        let mut leaving: Vec<TileKey> = self.slots.keys().collect();
        if let Some(old) = old {
            leaving.extend(g.around(old, 0).into_iter().filter(|k| !self.resident(*k)));
        }
        // Batches of at most BATCH_TILES keep the staging and upload buffers small.
        for batch in leaving.chunks(BATCH_TILES) {
            for &k in batch {
                if !self.resident(k) {
                    let slot = self.free_slot().expect("the pool is emptied batch by batch");
                    self.assign(k, slot);
                }
            }
            self.write_table(&ctx.queue);
            let mut encoder = new_encoder(ctx);
            let mut cx = FrameContext::new(ctx, &mut encoder, &mut timer);
            if let Some(old) = old {
                self.passes.exchange.record(&mut cx, res, layout.exchange_params(res, old, old, ExchangeParams::STASH), &layout.batch_rects(batch, old));
            }
            let out: Vec<(TileKey, usize)> = batch.iter().filter_map(|&k| self.slots.slot(k).map(|s| (k, s))).collect();
            self.record_copy_out(&mut cx, res, &out, clock);
            submit(ctx, encoder);
            for &k in batch {
                self.release(k);
            }
        }
        let mut arriving: Vec<TileKey> = g.around(origin, 0);
        // The new window's tiles must find their latest versions in the
        // streamer. A jump (`reachable`) arrives on tiles none of which was
        // resident or is on its way out (`plan` waited for those), so the
        // frame goes on; only the first placement (a loading screen), or a
        // move the pool could not hold in one step, waits for the copies
        // out in flight.
        if (old.is_none() || arriving.iter().any(|k| self.copy_outs.carries(*k))) && !self.copy_outs.is_empty() {
            self.counters.gpu_waits += 1;
            self.collect_evictions(ctx, true);
        }
        arriving.sort_by_key(|&k| g.inside(k, origin));
        let keep = arriving.iter().filter(|&&k| !g.inside(k, origin)).count();
        let mut start = 0;
        while start < arriving.len() {
            let room = self.slots.free_count();
            let batch = &arriving[start..(start + room.min(BATCH_TILES)).min(arriving.len())];
            start += batch.len();
            let (mut entries, mut upload) = (Vec::new(), Vec::<u32>::new());
            for &k in batch {
                let slot = self.free_slot().expect("room counted");
                entries.push(self.restore_entry(k, slot, &mut upload, clock));
                self.assign(k, slot);
            }
            self.write_table(&ctx.queue);
            let mut encoder = new_encoder(ctx);
            let mut cx = FrameContext::new(ctx, &mut encoder, &mut timer);
            let params = self.restore_params(frame);
            self.passes.restore.record(&mut cx, (res, &self.passes.tiles), params, &entries, &upload);
            self.passes.exchange.record(&mut cx, res, layout.exchange_params(res, origin, origin, 0), &layout.batch_rects(batch, origin));
            submit(ctx, encoder);
            for &k in batch {
                if g.inside(k, origin) {
                    self.release(k);
                }
            }
        }
        debug_assert_eq!(self.slots.len(), keep);
        self.write_table(&ctx.queue);
        self.passes.record_sweep(ctx, res, &layout, origin, 0);
    }

    /// Seals the slots of `slots` (snow XOR rest height, `tile_seal.wgsl`)
    /// and copies them into a staging buffer for the store.
    fn record_copy_out(&mut self, cx: &mut FrameContext<'_>, res: &DeformResources, slots: &[(TileKey, usize)], clock: SnowClock) {
        let entries: Vec<[i32; 4]> = slots.iter().map(|&(k, slot)| [k.col as i32, k.row as i32, slot as i32, 0]).collect();
        let seal = self.layout.seal_params(res);
        self.passes.seal.record(&mut cx.with_timer(&mut GpuTimer::disabled()), (res, &self.passes.tiles), seal, &entries);
        let (device, encoder) = (cx.device(), &mut *cx.encoder);
        self.copy_outs.record((device, encoder), &self.passes.tiles, slots, self.layout, clock);
        self.counters.evicted += slots.len() as u64;
    }

    /// Records this frame's weather on the resident tiles outside the window
    /// at `origin`: `refill_m`, `fall_m` and `quanta` are this frame's.
    pub fn record_weather(&mut self, cx: &mut FrameContext<'_>, res: &DeformResources, frame: &WindowFrame, refill_fall_m: (f32, f32), quanta: u32) {
        self.passes.record_weather(cx, (res, &self.layout, &self.slots), frame, refill_fall_m, quanta);
    }

    /// Hands the copy-outs that have arrived to the streamer, without
    /// waiting (after a non-blocking `device.poll`); each frame starts with it.
    pub fn collect(&mut self, ctx: &GpuContext) {
        self.collect_evictions(ctx, false);
    }

    /// Hands arrived copy-outs to the streamer; with `wait`, waits for all.
    fn collect_evictions(&mut self, ctx: &GpuContext, wait: bool) {
        self.copy_outs.collect(ctx, wait, &mut self.streamer, &mut self.errors);
    }

    /// Every resident tile and every tile of the window, current at
    /// `clock`, into the streamer: the window's texels are stashed into their
    /// tiles first. Tiles wholly inside the window have no slot: they borrow
    /// free slots, as many at a time as the pool has. Blocking; for saving,
    /// never in a frame loop.
    pub fn checkpoint(&mut self, ctx: &GpuContext, res: &DeformResources, origin: [i64; 2], clock: SnowClock) -> Result<(), SnowError> {
        self.collect_evictions(ctx, true);
        let stash = self.layout.exchange_params(res, origin, origin, ExchangeParams::STASH);
        let seal = self.layout.seal_params(res);
        let mut timer = GpuTimer::disabled();
        let g = self.layout.grid;
        // The resident tiles first (they stay), then the window's inside tiles in batches.
        let mut batches: Vec<Vec<TileKey>> = vec![self.slots.keys().collect()];
        let inside: Vec<TileKey> = g.around(origin, 0).into_iter().filter(|k| !self.resident(*k)).collect();
        let room = self.slots.free_count().clamp(1, BATCH_TILES);
        batches.extend(inside.chunks(room).map(<[TileKey]>::to_vec));
        for (n, batch) in batches.iter().enumerate() {
            let borrowed = n > 0;
            if borrowed {
                for &k in batch {
                    let slot = self.free_slot().expect("a batch fits the free slots");
                    self.assign(k, slot);
                }
            }
            self.write_table(&ctx.queue);
            let entries: Vec<[i32; 4]> = batch.iter().filter_map(|&k| self.slots.slot(k).map(|s| [k.col as i32, k.row as i32, s as i32, 0])).collect();
            let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("tile checkpoint") });
            let mut cx = FrameContext::new(ctx, &mut encoder, &mut timer);
            self.passes.exchange.record(&mut cx, res, stash, &self.layout.batch_rects(batch, origin));
            self.passes.seal.record(&mut cx, (res, &self.passes.tiles), seal, &entries);
            ctx.queue.submit([encoder.finish()]);
            let raw = crate::gpu::read_buffer(ctx, &self.passes.tiles)?;
            let words: Vec<u32> = bytemuck::pod_collect_to_vec(&raw);
            let slot_words = self.layout.planes() * g.area();
            for &k in batch {
                let Some(slot) = self.slots.slot(k) else { continue };
                let planes = &words[slot * slot_words..(slot + 1) * slot_words];
                self.streamer.put(tile_from_planes(k, g.side(), clock, planes, (self.layout.use_fallen, self.layout.has_stamps)));
            }
            if borrowed {
                for &k in batch {
                    self.release(k);
                }
            } else {
                // Sealing again gives the resident slots back (XOR is its own inverse).
                let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("tile unseal") });
                self.passes.seal.record(&mut FrameContext::new(ctx, &mut encoder, &mut timer), (res, &self.passes.tiles), seal, &entries);
                ctx.queue.submit([encoder.finish()]);
            }
        }
        self.write_table(&ctx.queue);
        self.settle_stand_ins(ctx, res, origin, clock)
    }

    /// Merges the tiles the window stood in for (the disk was late or could
    /// not read them) and has made since with their stored versions, so that
    /// a save writes the merge and never what the window made over the stored
    /// version: waits for the stored versions, restores each with a merge
    /// (into its own slot if resident, a borrowed one otherwise), loads the
    /// merged texels into the window where it covers them, and hands the
    /// merged tiles to the streamer as ordinary writes. Blocking. Fails, and
    /// keeps what the window made in memory, when a stored version cannot be
    /// read or does not come within the wait limit.
    fn settle_stand_ins(&mut self, ctx: &GpuContext, res: &DeformResources, origin: [i64; 2], clock: SnowClock) -> Result<(), SnowError> {
        if self.streamer.stand_ins_made().is_empty() {
            return Ok(());
        }
        self.streamer.wait_for(&self.streamer.stand_ins_made())?;
        // Those the store turned out not to have are ordinary tiles by now.
        let owed = self.streamer.stand_ins_made();
        if let Some(e) = owed.iter().find_map(|&k| self.streamer.stand_in_error(k)) {
            return Err(e.into());
        }
        let load = self.layout.exchange_params(res, origin, origin, 0);
        let seal = self.layout.seal_params(res);
        let mut timer = GpuTimer::disabled();
        let room = self.slots.free_count().clamp(1, BATCH_TILES);
        for batch in owed.chunks(room) {
            let (mut entries, mut upload, mut borrowed) = (Vec::new(), Vec::<u32>::new(), Vec::new());
            for &k in batch {
                let slot = if let Some(slot) = self.slots.slot(k) {
                    slot
                } else {
                    let slot = self.free_slot().expect("a batch fits the free slots");
                    self.assign(k, slot);
                    borrowed.push(k);
                    slot
                };
                entries.push(self.restore_entry(k, slot, &mut upload, clock));
            }
            // Only this batch in the table: the load leaves every other texel of the window as it is.
            self.slots.write_only(&ctx.queue, batch);
            let sealed: Vec<[i32; 4]> = entries.iter().map(|e| [e.tile[0], e.tile[1], e.slot as i32, 0]).collect();
            let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("tile merge for a save") });
            {
                let mut cx = FrameContext::new(ctx, &mut encoder, &mut timer);
                self.passes.restore.record(&mut cx, (res, &self.passes.tiles), self.restore_base, &entries, &upload);
                self.passes.exchange.record(&mut cx, res, load, &self.layout.batch_rects(batch, origin));
                self.passes.seal.record(&mut cx, (res, &self.passes.tiles), seal, &sealed);
            }
            ctx.queue.submit([encoder.finish()]);
            let raw = crate::gpu::read_buffer(ctx, &self.passes.tiles)?;
            let words: Vec<u32> = bytemuck::pod_collect_to_vec(&raw);
            let slot_words = self.layout.planes() * self.layout.grid.area();
            for e in &entries {
                let key = TileKey::new(i64::from(e.tile[0]), i64::from(e.tile[1]));
                let slot = e.slot as usize;
                let planes = &words[slot * slot_words..(slot + 1) * slot_words];
                self.streamer.put(tile_from_planes(key, self.layout.grid.side(), clock, planes, (self.layout.use_fallen, self.layout.has_stamps)));
            }
            // Sealing again gives the resident slots back; the borrowed ones go.
            let resident: Vec<[i32; 4]> = sealed.iter().copied().filter(|e| !borrowed.contains(&TileKey::new(i64::from(e[0]), i64::from(e[1])))).collect();
            if !resident.is_empty() {
                let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("tile unseal") });
                self.passes.seal.record(&mut FrameContext::new(ctx, &mut encoder, &mut timer), (res, &self.passes.tiles), seal, &resident);
                ctx.queue.submit([encoder.finish()]);
            }
            for k in borrowed {
                self.release(k);
            }
        }
        self.write_table(&ctx.queue);
        // A stored version dropped from memory and not read again in time: not merged, not saved.
        if let Some(&k) = self.streamer.stand_ins_made().first() {
            return Err(StoreError::Io {
                path: self.streamer.dir().to_path_buf(),
                op: "merge before saving",
                source: std::io::Error::other(format!(
                    "the stored version of tile ({}, {}) did not come back in time; what the window made there is kept in memory",
                    k.col, k.row
                )),
            }
            .into());
        }
        Ok(())
    }

    /// Errors since the last call: the streamer's (I/O, corrupt tiles) and the GPU side's.
    pub fn take_errors(&mut self) -> Vec<StoreError> {
        let mut errors = std::mem::take(&mut self.errors);
        errors.extend(self.streamer.take_errors());
        errors
    }

    /// Traffic so far.
    #[must_use]
    pub fn stats(&self) -> TileStats {
        TileStats {
            store: self.streamer.stats(),
            resident: self.slots.len(),
            batched_moves: self.batched_moves,
            slots: self.slots.capacity(),
            window_waits: self.counters.window_waits,
            gpu_waits: self.counters.gpu_waits,
            restored: self.counters.restored,
            fresh: self.counters.fresh,
            stood_in: self.counters.stood_in,
            merged: self.counters.merged,
            merged_live: self.counters.merged_live,
            awaiting_merge: self.awaiting_merge(),
            evicted: self.counters.evicted,
            evicting: self.copy_outs.tiles(),
            blocking_loads: self.counters.blocking_loads,
            gpu_bytes: self.gpu_bytes(),
            memory_only: self.streamer.is_memory_only(),
        }
    }

    /// [`TileStats::awaiting_merge`]: the tiles of the window and the
    /// resident ring that fresh snow stands in for.
    fn awaiting_merge(&self) -> usize {
        let Some(at) = self.at else { return 0 };
        let g = self.layout.grid;
        let ring = self.slots.keys().filter(|&k| !g.touched(k, at));
        g.around(at, 0).into_iter().chain(ring).filter(|&k| self.streamer.stands_in(k)).count()
    }

    /// [`TileStats::gpu_bytes`] alone.
    #[must_use]
    pub fn gpu_bytes(&self) -> u64 {
        self.passes.gpu_bytes() + self.slots.gpu_bytes() + self.copy_outs.gpu_bytes()
    }
}
