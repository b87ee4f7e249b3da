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
//! The frame never waits for the disk: a tile the window needs that is not in
//! memory yet keeps the window where it is (it waits, counted in
//! [`TileStats::window_waits`]) while the streamer loads it; the prefetch ring
//! around the window makes that rare. Only the first placement (start-up, a
//! loaded save) blocks, as a loading screen would.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use std::collections::HashSet;

use crate::deform::params::default_tile_texels;
use crate::deform::resources::DeformResources;
use crate::deform::window::TexelRect;
use crate::error::SnowError;
use crate::frame::{FrameContext, WindowFrame};
use crate::gpu::readback::{MapFlag, MapState};
use crate::gpu::{GpuContext, GpuTimer};
use crate::persist::{SnowClock, StoreError, StoreStats, StreamerConfig, TileData, TileKey, TileLookup, TileStreamer};

use super::exchange::{ExchangeParams, ExchangePass};
use super::restore::{RestoreEntry, RestoreParams, TileRestorePass};
use super::seal::{SealParams, TileSealPass};
use super::weather::{TileWeatherPass, WeatherParams};

// The slot layout lives in `planes.rs` (the tile passes below this file need
// it too); it stays reachable here, where the streaming's users look for it.
pub use super::planes::{PLANE_FALLEN, PLANE_SNOW, PLANES, plane_packed, plane_stamps, planes};
// The grid and the slot pool live in files of their own; the grid stays
// reachable here, where the streaming's users look for it.
pub use super::grid::{PREFETCH_MARGIN_TILES, TileGrid};
use super::slots::SlotTable;
use crate::gpu::context::GpuContextExt;
use crate::persist::streamer::TileStreamerExt;

/// Most tiles per submission of a batched move or a save.
const BATCH_TILES: usize = 32;

/// Tile traffic so far, with the store's own figures.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TileStats {
    /// The streamer's memory cache and disk store.
    pub store: StoreStats,
    /// Tiles resident on the GPU.
    pub resident: usize,
    /// Slots on the GPU.
    pub slots: usize,
    /// Frames the window stayed put because a tile it needed was still loading.
    pub window_waits: u64,
    /// Window moves too long for the slot pool in one frame, done in
    /// batches of their own submissions (blocking): the first placement,
    /// jumps, moves of more than a tile or two.
    pub batched_moves: u64,
    /// Times a frame waited for the GPU: a batched move for the copies out
    /// in flight, the first placement onto tiles still in flight, and
    /// adding the footprint plane. A save (`SnowDeformation::save`) waits
    /// by design and is not counted.
    pub gpu_waits: u64,
    /// Tiles restored from the store.
    pub restored: u64,
    /// Tiles made resident with fresh snow (never seen before).
    pub fresh: u64,
    /// Tiles the window stood in for with fresh snow (or what it had made
    /// there before) because the disk did not give the stored version in time
    /// or could not read it; what it makes there is merged with the stored
    /// version later, never written over it.
    pub stood_in: u64,
    /// Restores that merged a stored tile into what the window had made in
    /// its place (shared snow's merge: the deeper deficit wins).
    pub merged: u64,
    /// Tiles copied out of the GPU for the store.
    pub evicted: u64,
    /// Tiles on their way back from the GPU.
    pub evicting: usize,
    /// Tiles the memory cache dropped between being found ready and being
    /// used, read again from disk within the frame (blocking; rare, with a
    /// memory budget smaller than the tiles the window needs at once).
    pub blocking_loads: u64,
    /// GPU memory of the resident tiles, their upload buffers and the
    /// copy-out staging buffers still in flight (bytes).
    pub gpu_bytes: u64,
    /// The tiles are kept in memory only (no disk store behind them).
    pub memory_only: bool,
}

/// Tiles copied out of their slots in one frame, on their way to the CPU.
struct Eviction {
    buffer: wgpu::Buffer,
    keys: Vec<TileKey>,
    clock: SnowClock,
    /// Its mapping, started when the encoder holding the copy is submitted.
    flag: MapFlag,
}

/// The resident tiles, their passes and the streamer behind them.
pub struct TileStreaming {
    grid: TileGrid,
    depth_m: f32,
    use_fallen: bool,
    /// Whether the slots have a footprint plane (the window a footprint buffer).
    has_stamps: bool,
    streamer: TileStreamer,
    tiles: wgpu::Buffer,
    /// The slot pool, its key table and which tile holds each slot.
    slots: SlotTable,
    moves: u64,
    batched_moves: u64,
    exchange: ExchangePass,
    restore: TileRestorePass,
    seal: TileSealPass,
    weather: TileWeatherPass,
    evictions: Vec<Eviction>,
    /// Staging buffers of finished copy-outs, reused by the next ones.
    /// The weather pass's slot list, rebuilt each frame in place.
    weather_slots: Vec<u32>,
    in_flight: HashSet<TileKey>,
    prefetched_at: Option<TileKey>,
    errors: Vec<StoreError>,
    /// Tiles the first placement (or a preload) gave up waiting for: stood
    /// in for at once, not waited for again one by one.
    gave_up: HashSet<TileKey>,
    /// Where [`Self::preload`] last loaded the window's tiles for: the
    /// first placement there waits for nothing.
    preloaded: Option<[i64; 2]>,
    /// The last frame's restore uniforms, for the merges a save does.
    restore_base: RestoreParams,
    window_waits: u64,
    gpu_waits: u64,
    blocking_loads: u64,
    restored: u64,
    fresh: u64,
    stood_in: u64,
    merged: u64,
    evicted: u64,
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

    /// Planes per slot now.
    fn planes(&self) -> usize {
        planes(self.use_fallen, self.has_stamps)
    }

    /// After the window's footprint buffer was allocated: gives every slot a
    /// footprint plane (no footprints), keeping the other planes, and binds
    /// the passes to the new slots and to `res`. Waits for the copy-outs in
    /// flight (they have the old layout). Once, on the first switch to
    /// points or combined.
    pub fn add_stamp_plane(&mut self, ctx: &GpuContext, res: &DeformResources) {
        if self.has_stamps || !res.has_stamps() {
            return;
        }
        self.gpu_waits += u64::from(!self.evictions.is_empty());
        self.collect_evictions(ctx, true);
        let area = self.grid.area() as u64;
        let old = self.planes() as u64;
        self.has_stamps = true;
        let new = self.planes() as u64;
        let slots = self.grid.slot_count() as u64;
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
            encoder.copy_buffer_to_buffer(&self.tiles, slot * old * area * 4, &tiles, slot * new * area * 4, old * area * 4);
        }
        ctx.queue.submit([encoder.finish()]);
        self.tiles = tiles;
        self.exchange = ExchangePass::new(&ctx.device, res, &self.tiles, self.slots.table_buffer());
        self.restore = TileRestorePass::new(&ctx.device, res, &self.tiles);
        self.seal = TileSealPass::new(&ctx.device, res, &self.tiles);
        self.weather = TileWeatherPass::new(&ctx.device, res, self.slots.owners_buffer(), &self.tiles);
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
            exchange: ExchangePass::new(&ctx.device, res, &tiles, slots.table_buffer()),
            restore: TileRestorePass::new(&ctx.device, res, &tiles),
            seal: TileSealPass::new(&ctx.device, res, &tiles),
            weather: TileWeatherPass::new(&ctx.device, res, slots.owners_buffer(), &tiles),
            slots,
            moves: 0,
            batched_moves: 0,
            grid,
            depth_m,
            use_fallen,
            has_stamps: res.has_stamps(),
            streamer,
            tiles,
            evictions: Vec::new(),
            weather_slots: Vec::new(),
            in_flight: HashSet::new(),
            prefetched_at: None,
            errors: Vec::new(),
            gave_up: HashSet::new(),
            preloaded: None,
            restore_base: RestoreParams::default(),
            window_waits: 0,
            gpu_waits: 0,
            blocking_loads: 0,
            restored: 0,
            fresh: 0,
            stood_in: 0,
            merged: 0,
            evicted: 0,
        };
        ctx.check("creating the resident tiles")?;
        Ok(this)
    }

    /// The tile layout.
    #[must_use]
    pub fn grid(&self) -> &TileGrid {
        &self.grid
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

    /// Tiles the window at `desired` needs from the streamer when coming
    /// from `current`: those it touches that have no slot and were not in
    /// the window before (a tile the old window touched lives there or in its slot).
    fn needed_from_store(&self, current: Option<[i64; 2]>, desired: [i64; 2]) -> Vec<TileKey> {
        self.grid.around(desired, 0).into_iter().filter(|&k| !self.resident(k) && !current.is_some_and(|o| self.grid.touched(k, o))).collect()
    }

    /// Decides where the window goes this frame: `desired`, once every tile
    /// it touches can be made resident without waiting for the disk; until
    /// then it stays at `current`. The first placement waits (blocking).
    pub fn plan(&mut self, ctx: &GpuContext, current: Option<[i64; 2]>, desired: [i64; 2]) -> [i64; 2] {
        self.streamer.poll();
        // A preload for this very place already waited (and gave up on what did not come).
        let preloaded = self.preloaded.take() == Some(desired);
        if !preloaded {
            self.gave_up.clear();
        }
        let here = self.grid.key_of(desired);
        if self.prefetched_at != Some(here) {
            self.prefetched_at = Some(here);
            for key in self.grid.around(desired, PREFETCH_MARGIN_TILES) {
                if !self.resident(key) && !self.in_flight.contains(&key) {
                    self.streamer.request(key);
                }
            }
        }
        if current == Some(desired) {
            return desired;
        }
        let desired = current.map_or(desired, |c| self.reachable(c, desired));
        let needed = self.needed_from_store(current, desired);
        if current.is_none() {
            // First placement without a preload: the first frame is a
            // loading screen's, so waiting is allowed (and counted).
            if !preloaded {
                self.gpu_waits += u64::from(needed.iter().any(|k| self.in_flight.contains(k)));
                self.wait_for_needed(ctx, &needed);
            }
            return desired;
        }
        let ready = needed.iter().all(|&k| !self.in_flight.contains(&k) && self.streamer.is_ready(k));
        if ready {
            return desired;
        }
        // Ask again for what is missing: a tile that came back from the GPU
        // after the prefetch may have left memory for the disk since.
        for &key in &needed {
            if !self.in_flight.contains(&key) {
                self.streamer.request(key);
            }
        }
        self.window_waits += 1;
        current.unwrap_or(desired)
    }

    /// Waits (blocking) until each of `needed` is in memory: the copies out
    /// of the GPU it is among first, then the disk, within the streamer's
    /// wait limit. Fresh snow stands in for what did not come (see
    /// `restore_entry`), its stored version merged in later; the error is
    /// kept for [`Self::take_errors`].
    fn wait_for_needed(&mut self, ctx: &GpuContext, needed: &[TileKey]) {
        if needed.iter().any(|k| self.in_flight.contains(k)) {
            self.collect_evictions(ctx, true);
        }
        if let Err(e) = self.streamer.wait_for(needed) {
            self.errors.push(e);
            self.gave_up.extend(needed.iter().copied().filter(|&k| !self.streamer.is_ready(k)));
        }
    }

    /// The explicit wait a loading screen makes: loads (blocking) every
    /// tile the window moving from `current` to `desired` needs, so the
    /// next [`Self::plan`] for `desired` moves there at once (a jump
    /// instead of holding while the disk reads) and a first placement
    /// waits for nothing. What the disk does not give within the wait
    /// limit is stood in for as in a frame, and reported the same way.
    pub fn preload(&mut self, ctx: &GpuContext, current: Option<[i64; 2]>, desired: [i64; 2]) {
        self.streamer.poll();
        self.gave_up.clear();
        let needed = self.needed_from_store(current, desired);
        self.wait_for_needed(ctx, &needed);
        self.preloaded = Some(desired);
        // Not the prefetch ring now: its tiles arriving between this wait
        // and the placement could push the ones waited for out of a small
        // memory budget. The ring follows once the window moves on.
        self.prefetched_at = Some(self.grid.key_of(desired));
    }

    /// Where the window at `current` may go this frame on its way to
    /// `desired` without waiting for the GPU: all the way when the new
    /// window is a jump away (none of its tiles within the prefetch margin
    /// of the old, so none is resident or on its way out of this move), and
    /// otherwise at most one tile side along each axis, a step the slot pool
    /// always holds (`record_step`). A move of a few tiles thus glides over
    /// as many frames instead of copying the old window out and waiting for
    /// the copies before restoring the tiles it shares with the new one.
    fn reachable(&self, current: [i64; 2], desired: [i64; 2]) -> [i64; 2] {
        let g = self.grid;
        if g.around(desired, 0).into_iter().all(|k| !g.near(k, current, PREFETCH_MARGIN_TILES)) {
            return desired;
        }
        let side = i64::from(g.side());
        [0, 1].map(|a| current[a] + (desired[a] - current[a]).clamp(-side, side))
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

    /// The exchange's uniforms; `kind` is [`ExchangeParams::STASH`],
    /// [`ExchangeParams::COUNT`] and [`ExchangeParams::SWEEP`] as the step needs.
    fn exchange_params(&self, res: &DeformResources, old: [i64; 2], origin: [i64; 2], kind: u32) -> ExchangeParams {
        let flags = if self.use_fallen { ExchangeParams::USE_FALLEN } else { 0 } | if res.has_stamps() { ExchangeParams::HAS_STAMPS } else { 0 } | kind;
        ExchangeParams {
            origin: [origin[0] as i32, origin[1] as i32],
            old_origin: [old[0] as i32, old[1] as i32],
            resolution: res.resolution,
            side: self.grid.side(),
            keys_per_side: self.grid.keys_per_side(),
            flags,
            texel_m: res.texel_m,
            planes: self.planes() as u32,
            depth_m: self.depth_m,
            ..ExchangeParams::default()
        }
    }

    fn restore_params(&mut self, frame: &WindowFrame) -> RestoreParams {
        self.restore_base = RestoreParams {
            side: self.grid.side(),
            flags: if frame.use_fallen { RestoreParams::USE_FALLEN } else { 0 },
            planes: self.planes() as u32,
            texel_m: frame.texel_m,
            depth_m: frame.depth_m,
            fallen_m: frame.fallen_m,
            max_fallen_m: frame.max_fallen_m,
            low_m: frame.low_m,
            high_m: frame.high_m,
            ..RestoreParams::default()
        };
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
    /// the tile's place while the disk was late to merge in, where there is.
    fn restore_entry(&mut self, key: TileKey, slot: usize, upload: &mut Vec<u32>, clock: SnowClock) -> RestoreEntry {
        let area = self.grid.area();
        let (saved, made) = match self.streamer.take_for_restore(key) {
            (TileLookup::Ready(saved), made) => {
                if made.is_none() && self.streamer.stands_in(key) {
                    // Its read failed: fresh snow (or what the window made here) stands in.
                    self.stood_in += 1;
                }
                (saved, made)
            }
            // `plan` saw it ready, but handing out the tiles before it let
            // the memory cache drop it: read it again rather than lose it
            // to fresh snow (blocking; counted). Not for the tiles the first
            // placement already gave up on: one wait each would add up.
            (TileLookup::Pending, _) => {
                if !self.gave_up.contains(&key) {
                    self.blocking_loads += 1;
                    if let Err(e) = self.streamer.wait_for(&[key]) {
                        self.errors.push(e);
                    }
                }
                match self.streamer.take_for_restore(key) {
                    (TileLookup::Ready(saved), made) => (saved, made),
                    (TileLookup::Pending, _) => {
                        // The disk is late: fresh snow (or what the window made
                        // here before) stands in; the stored version is merged
                        // in later, never written over.
                        self.stood_in += 1;
                        (self.streamer.stand_in(key), None)
                    }
                }
            }
        };
        let mut entry = RestoreEntry { tile: [key.col as i32, key.row as i32], slot: slot as u32, ..RestoreEntry::default() };
        let usable = |tile: &TileData| tile.side == self.grid.side() && tile.snow_xor_rest.len() == area && tile.stamps.len() == area;
        // Appends a tile's planes to `upload`; its offset and time away.
        let push = |tile: &TileData, upload: &mut Vec<u32>| {
            let at = upload.len() as u32;
            upload.extend_from_slice(&tile.snow_xor_rest);
            upload.extend_from_slice(&tile.stamps);
            if tile.fallen.len() == area {
                upload.extend(tile.fallen.iter().map(|v| v.to_bits()));
            } else {
                upload.extend(std::iter::repeat_n(0, area));
            }
            // Tiles written before the plane existed hold fresh snow.
            if tile.packed.len() == area {
                upload.extend(tile.packed.iter().map(|&q| u32::from(q)));
            } else {
                upload.extend(std::iter::repeat_n(0, area));
            }
            let refill = (clock.refill_m - tile.clock.refill_m).max(0.0);
            let fall = (clock.fallen_m - tile.clock.fallen_m).max(0.0);
            let quanta = clock.stamp_quanta.saturating_sub(tile.clock.stamp_quanta);
            (at, refill as f32, fall as f32, quanta.min(u64::from(u32::MAX)) as u32)
        };
        match saved {
            Some(tile) if usable(&tile) => {
                let (at, refill_m, fall_m, quanta) = push(&tile, upload);
                entry.upload = at;
                (entry.refill_m, entry.fall_m, entry.quanta) = (refill_m, fall_m, quanta);
                entry.elapsed = u32::from(refill_m > 0.0 || fall_m > 0.0 || quanta > 0);
                self.restored += 1;
            }
            Some(tile) => {
                self.errors.push(StoreError::Mismatch {
                    path: self.streamer.dir().to_path_buf(),
                    why: format!("tile ({}, {}) has side {}, the window uses {}; fresh snow used", key.col, key.row, tile.side, self.grid.side()),
                });
                self.fresh += 1;
            }
            None => self.fresh += 1,
        }
        if let Some(made) = made.filter(|t| usable(t)) {
            let (at, refill_m, fall_m, quanta) = push(&made, upload);
            (entry.merge, entry.merge_refill_m, entry.merge_fall_m, entry.merge_quanta) = (at, refill_m, fall_m, quanta);
            self.merged += 1;
        }
        entry
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
        let g = self.grid;
        let mut required: Vec<TileKey> = g.around(old, 0).into_iter().filter(|&k| !g.inside(k, origin)).collect();
        required.extend(g.around(origin, 0).into_iter().filter(|&k| !g.inside(k, old) && !g.touched(k, old)));
        required.extend(g.around(origin, 0).into_iter().filter(|&k| g.touched(k, old) && !g.inside(k, old) && g.inside(k, origin)));
        // Every tile the table maps this frame must lie near the new window.
        if required.len() > g.slot_count() || required.iter().any(|&k| !g.near(k, origin, PREFETCH_MARGIN_TILES)) {
            return false;
        }
        let evicting = self.evict_for(&required, origin);
        // What leaves and enters is counted in the mass ledger.
        let stash = self.exchange_params(res, old, origin, ExchangeParams::STASH | ExchangeParams::COUNT);
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
        self.exchange.record(cx, res, stash, rects);
        for (k, slot) in deferred {
            let entry = self.restore_entry(k, slot, &mut upload, clock);
            entries.push(entry);
        }
        let params = self.restore_params(frame);
        self.restore.record(cx, (res, &self.tiles), params, &entries, &upload);
        self.exchange.record(cx, res, self.exchange_params(res, old, origin, ExchangeParams::COUNT), rects);
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
        let g = self.grid;
        let mut timer = GpuTimer::disabled();
        let submit = |ctx: &GpuContext, encoder: wgpu::CommandEncoder| ctx.queue.submit([encoder.finish()]);
        let new_encoder = |ctx: &GpuContext| ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("tile batch") });
        // The batches count nothing (a kept edge tile is loaded again by
        // later batches): the ledger sweeps the whole window, before (left)
        // and after (entered).
        if let Some(old) = old {
            self.record_sweep(ctx, res, old, ExchangeParams::STASH);
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
                self.exchange.record(&mut cx, res, self.exchange_params(res, old, old, ExchangeParams::STASH), &self.batch_rects(batch, old));
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
        if (old.is_none() || arriving.iter().any(|k| self.in_flight.contains(k))) && !self.evictions.is_empty() {
            self.gpu_waits += 1;
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
            self.restore.record(&mut cx, (res, &self.tiles), params, &entries, &upload);
            self.exchange.record(&mut cx, res, self.exchange_params(res, origin, origin, 0), &self.batch_rects(batch, origin));
            submit(ctx, encoder);
            for &k in batch {
                if g.inside(k, origin) {
                    self.release(k);
                }
            }
        }
        debug_assert_eq!(self.slots.len(), keep);
        self.write_table(&ctx.queue);
        self.record_sweep(ctx, res, origin, 0);
    }

    /// The window-local rectangles (at most two, as the exchange takes)
    /// that cover the texels of `batch`'s tiles in the window at `origin`:
    /// the bounds of its tiles left of the window's middle and of those
    /// right of it. A batch of a jump is a run of rows or the edge columns,
    /// so a batch's stash or load reads a strip of the window, not all of it
    /// (64 passes over the whole window made a jump at 1024² take 2 s on
    /// lavapipe).
    fn batch_rects(&self, batch: &[TileKey], origin: [i64; 2]) -> Vec<TexelRect> {
        let (s, n) = (i64::from(self.grid.side()), i64::from(self.grid.resolution()));
        let mut bounds: [Option<[i64; 4]>; 2] = [None, None];
        for k in batch {
            // The tile's texels in window-local coordinates, clipped to the window.
            let (c0, c1) = ((k.col * s - origin[0]).max(0), ((k.col + 1) * s - origin[0]).min(n));
            let (r0, r1) = ((k.row * s - origin[1]).max(0), ((k.row + 1) * s - origin[1]).min(n));
            if c0 >= c1 || r0 >= r1 {
                continue;
            }
            let half = usize::from(c0 + c1 > n);
            let b = bounds[half].get_or_insert([r0, c0, r1, c1]);
            *b = [b[0].min(r0), b[1].min(c0), b[2].max(r1), b[3].max(c1)];
        }
        bounds.into_iter().flatten().map(|[r0, c0, r1, c1]| [r0 as u32, c0 as u32, (r1 - r0) as u32, (c1 - c0) as u32]).collect()
    }

    /// Counts the whole window at `at` in the mass ledger, as left (`kind`
    /// [`ExchangeParams::STASH`]) or entered (0), in a submission of its own
    /// (the sweep's uniform is its own).
    fn record_sweep(&self, ctx: &GpuContext, res: &DeformResources, at: [i64; 2], kind: u32) {
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("ledger sweep") });
        let params = self.exchange_params(res, at, at, ExchangeParams::SWEEP | ExchangeParams::COUNT | kind);
        self.exchange.record(&mut FrameContext::new(ctx, &mut encoder, &mut GpuTimer::disabled()), res, params, &[[0, 0, res.resolution, res.resolution]]);
        ctx.queue.submit([encoder.finish()]);
    }

    /// The seal's uniforms for the window of `res`.
    fn seal_params(&self, res: &DeformResources) -> SealParams {
        SealParams {
            side: self.grid.side(),
            planes: self.planes() as u32,
            flags: if self.use_fallen { SealParams::USE_FALLEN } else { 0 },
            texel_m: res.texel_m,
            depth_m: self.depth_m,
            ..SealParams::default()
        }
    }

    /// Seals the slots of `slots` (snow XOR rest height, `tile_seal.wgsl`)
    /// and copies them into a staging buffer for the store.
    fn record_copy_out(&mut self, cx: &mut FrameContext<'_>, res: &DeformResources, slots: &[(TileKey, usize)], clock: SnowClock) {
        let entries: Vec<[i32; 4]> = slots.iter().map(|&(k, slot)| [k.col as i32, k.row as i32, slot as i32, 0]).collect();
        let seal = self.seal_params(res);
        self.seal.record(&mut cx.with_timer(&mut GpuTimer::disabled()), (res, &self.tiles), seal, &entries);
        let (device, encoder) = (cx.device(), &mut *cx.encoder);
        let slot_bytes = (self.planes() * self.grid.area() * 4) as u64;
        let size = slot_bytes * slots.len() as u64;
        // Exactly this copy-out's size, dropped once read back: GPU memory
        // only while tiles are on their way to the CPU (counted in
        // `TileStats::gpu_bytes` meanwhile), none kept for reuse.
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("tile copy-out"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        for (k, &(key, slot)) in slots.iter().enumerate() {
            encoder.copy_buffer_to_buffer(&self.tiles, slot as u64 * slot_bytes, &buffer, k as u64 * slot_bytes, slot_bytes);
            self.in_flight.insert(key);
        }
        self.evicted += slots.len() as u64;
        let flag = MapFlag::on_submit(encoder, &buffer, size);
        self.evictions.push(Eviction { buffer, keys: slots.iter().map(|s| s.0).collect(), clock, flag });
    }

    /// Records this frame's weather on the resident tiles outside the window
    /// at `origin`: `refill_m`, `fall_m` and `quanta` are this frame's.
    pub fn record_weather(
        &mut self,
        cx: &mut FrameContext<'_>,
        res: &DeformResources,
        frame @ &WindowFrame { origin, .. }: &WindowFrame,
        (refill_m, fall_m): (f32, f32),
        quanta: u32,
    ) {
        // Only tiles reaching outside the window: the update has the rest.
        let (side, n) = (i64::from(self.grid.side()), i64::from(self.grid.resolution()));
        let inside =
            |k: TileKey| k.col * side >= origin[0] && (k.col + 1) * side <= origin[0] + n && k.row * side >= origin[1] && (k.row + 1) * side <= origin[1] + n;
        self.weather_slots.clear();
        self.weather_slots.extend(self.slots.owned().filter(|&(_, k)| !inside(k)).map(|(s, _)| s as u32));
        self.weather.record(
            cx,
            res,
            &WeatherParams {
                origin: [origin[0] as i32, origin[1] as i32],
                resolution: self.grid.resolution(),
                side: self.grid.side(),
                texel_m: frame.texel_m,
                flags: if frame.use_fallen { WeatherParams::USE_FALLEN } else { 0 },
                planes: self.planes() as u32,
                depth_m: frame.depth_m,
                refill_m,
                fall_m,
                max_fallen_m: frame.max_fallen_m,
                quanta,
                low_m: frame.low_m,
                high_m: frame.high_m,
                count: 0,
                _pad: 0,
            },
            &self.weather_slots,
        );
    }

    /// Hands the copy-outs that have arrived to the streamer, without
    /// waiting (after a non-blocking `device.poll`); each frame starts with it.
    pub fn collect(&mut self, ctx: &GpuContext) {
        self.collect_evictions(ctx, false);
    }

    /// Hands arrived copy-outs to the streamer; with `wait`, waits for all.
    fn collect_evictions(&mut self, ctx: &GpuContext, wait: bool) {
        if wait
            && !self.evictions.is_empty()
            && let Err(e) = ctx.wait_idle("reading back tiles for the store")
        {
            tracing::warn!("{e}");
        }
        let area = self.grid.area();
        let side = self.grid.side();
        let mut k = 0;
        while k < self.evictions.len() {
            let state = self.evictions[k].flag.state();
            if state == MapState::Pending {
                k += 1;
                continue;
            }
            let eviction = self.evictions.swap_remove(k);
            let used = (eviction.keys.len() * self.planes() * area * 4) as u64;
            let words: Option<Vec<u32>> =
                if state == MapState::Mapped { eviction.buffer.slice(..used).get_mapped_range().map(|v| bytemuck::pod_collect_to_vec(&v)).ok() } else { None };
            for key in &eviction.keys {
                self.in_flight.remove(key);
            }
            let Some(words) = words else {
                self.errors.push(StoreError::Mismatch {
                    path: self.streamer.dir().to_path_buf(),
                    why: format!("{} tiles could not be read back from the GPU and are lost", eviction.keys.len()),
                });
                continue;
            };
            eviction.buffer.unmap();
            for (t, key) in eviction.keys.iter().enumerate() {
                let n = self.planes();
                let planes = &words[t * n * area..(t + 1) * n * area];
                self.streamer.put(tile_from_planes(*key, side, eviction.clock, planes, (self.use_fallen, self.has_stamps)));
            }
        }
    }

    /// Every resident tile and every tile of the window, current at
    /// `clock`, into the streamer: the window's texels are stashed into their
    /// tiles first. Tiles wholly inside the window have no slot: they borrow
    /// free slots, as many at a time as the pool has. Blocking; for saving,
    /// never in a frame loop.
    pub fn checkpoint(&mut self, ctx: &GpuContext, res: &DeformResources, origin: [i64; 2], clock: SnowClock) -> Result<(), SnowError> {
        self.collect_evictions(ctx, true);
        let stash = self.exchange_params(res, origin, origin, ExchangeParams::STASH);
        let seal = self.seal_params(res);
        let mut timer = GpuTimer::disabled();
        let g = self.grid;
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
            self.exchange.record(&mut cx, res, stash, &self.batch_rects(batch, origin));
            self.seal.record(&mut cx, (res, &self.tiles), seal, &entries);
            ctx.queue.submit([encoder.finish()]);
            let raw = crate::gpu::read_buffer(ctx, &self.tiles)?;
            let words: Vec<u32> = bytemuck::pod_collect_to_vec(&raw);
            let slot_words = self.planes() * g.area();
            for &k in batch {
                let Some(slot) = self.slots.slot(k) else { continue };
                let planes = &words[slot * slot_words..(slot + 1) * slot_words];
                self.streamer.put(tile_from_planes(k, g.side(), clock, planes, (self.use_fallen, self.has_stamps)));
            }
            if borrowed {
                for &k in batch {
                    self.release(k);
                }
            } else {
                // Sealing again gives the resident slots back (XOR is its own inverse).
                let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("tile unseal") });
                self.seal.record(&mut FrameContext::new(ctx, &mut encoder, &mut timer), (res, &self.tiles), seal, &entries);
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
        let load = self.exchange_params(res, origin, origin, 0);
        let seal = self.seal_params(res);
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
                self.restore.record(&mut cx, (res, &self.tiles), self.restore_base, &entries, &upload);
                self.exchange.record(&mut cx, res, load, &self.batch_rects(batch, origin));
                self.seal.record(&mut cx, (res, &self.tiles), seal, &sealed);
            }
            ctx.queue.submit([encoder.finish()]);
            let raw = crate::gpu::read_buffer(ctx, &self.tiles)?;
            let words: Vec<u32> = bytemuck::pod_collect_to_vec(&raw);
            let slot_words = self.planes() * self.grid.area();
            for e in &entries {
                let key = TileKey::new(i64::from(e.tile[0]), i64::from(e.tile[1]));
                let slot = e.slot as usize;
                let planes = &words[slot * slot_words..(slot + 1) * slot_words];
                self.streamer.put(tile_from_planes(key, self.grid.side(), clock, planes, (self.use_fallen, self.has_stamps)));
            }
            // Sealing again gives the resident slots back; the borrowed ones go.
            let resident: Vec<[i32; 4]> = sealed.iter().copied().filter(|e| !borrowed.contains(&TileKey::new(i64::from(e[0]), i64::from(e[1])))).collect();
            if !resident.is_empty() {
                let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("tile unseal") });
                self.seal.record(&mut FrameContext::new(ctx, &mut encoder, &mut timer), (res, &self.tiles), seal, &resident);
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
            window_waits: self.window_waits,
            gpu_waits: self.gpu_waits,
            restored: self.restored,
            fresh: self.fresh,
            stood_in: self.stood_in,
            merged: self.merged,
            evicted: self.evicted,
            evicting: self.in_flight.len(),
            blocking_loads: self.blocking_loads,
            gpu_bytes: self.gpu_bytes(),
            memory_only: self.streamer.is_memory_only(),
        }
    }

    /// [`TileStats::gpu_bytes`] alone.
    #[must_use]
    pub fn gpu_bytes(&self) -> u64 {
        self.tiles.size()
            + self.slots.gpu_bytes()
            + self.weather.memory_bytes()
            + self.seal.memory_bytes()
            + self.restore.memory_bytes()
            + self.evictions.iter().map(|e| e.buffer.size()).sum::<u64>()
    }
}

/// A tile from its sealed slot's planes (snow XOR rest height, fallen where
/// the world has snowfall, packed snow, stamps where the window has
/// footprints: [`planes`]), for the store. The seal (`tile_seal.wgsl`) XORed the heights
/// with their rest height (terrain + depth + fallen, as `tile_restore.wgsl`
/// recomputes it) on the GPU, so untouched snow is 0 and the round trip is
/// exact on any terrain. Without a footprint plane the tile has no footprints.
#[must_use]
pub fn tile_from_planes(key: TileKey, side: u32, clock: SnowClock, planes: &[u32], (use_fallen, has_stamps): (bool, bool)) -> TileData {
    let area = (side * side) as usize;
    let plane = |p: usize| &planes[p * area..(p + 1) * area];
    let fallen: Vec<f32> = if use_fallen { plane(PLANE_FALLEN).iter().map(|&b| f32::from_bits(b)).collect() } else { Vec::new() };
    let stamps = if has_stamps { plane(plane_stamps(self::planes(use_fallen, true))).to_vec() } else { vec![u32::MAX; area] };
    // The plane holds u16 values (the exchange and the restore clamp them).
    let packed = plane(plane_packed(use_fallen)).iter().map(|&q| q.min(0xffff) as u16).collect();
    TileData { key, side, clock, snow_xor_rest: plane(PLANE_SNOW).to_vec(), stamps, fallen, packed }
}
