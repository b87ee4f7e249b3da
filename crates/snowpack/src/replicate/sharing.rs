//! What a [`crate::SnowDeformation`] keeps to share its snow: the gather
//! and merge passes, the readbacks of the changed-tile flags and of the
//! gathered tiles, the dirty tiles, the tiles waiting to be merged and the
//! gathered ones waiting to be taken. The orchestrator records its steps
//! at their places in the frame (`docs/deformation.md`, "Shared snow on the
//! GPU"); nothing here waits for the GPU.

use snowpack_share::replicate::press::PressFrame;
use std::collections::{BTreeMap, VecDeque};

use crate::deform::resources::DeformResources;
use crate::frame::FrameContext;
use crate::gpu::readback::ReadbackRing;
use crate::persist::TileKey;

use super::flags::ShareGrid;
use super::gather::{TileGatherParams, TileGatherPass, gpu_keys, packed_tile_bytes, unpack_tiles};
use super::merge::{FrameRecord, HISTORY_FRAMES, TileMergeParams, TileMergePass, pack_tiles};
use super::tile::{CatchUp, ShareClock, SharedTile};

/// Most tiles gathered, or merged, in one frame.
pub const MAX_TILES_PER_FRAME: u32 = 32;
/// A changed tile is gathered once quiet for an interval, or at the latest
/// this many intervals after its first change.
pub const QUIET_LIMIT: f64 = 4.0;
/// Staging memory one gather or merge dispatch may use (bytes); with large
/// tiles fewer than [`MAX_TILES_PER_FRAME`] go per frame.
pub const STAGING_BUDGET_BYTES: u64 = 1 << 20;
/// A tile this far (s) ahead of the window's clock is merged without
/// waiting for the clock to reach it (its sender's clock runs ahead).
pub const AHEAD_LIMIT_S: f64 = 2.0;
/// Staging buffers per readback ring: a frame or two in flight, and one spare.
const RING_SLOTS: usize = 3;

/// The window a frame's sharing steps work on.
#[derive(Clone, Copy, Debug)]
pub struct ShareWindow {
    /// Global texel of window-local (0, 0): `[column, row]`.
    pub origin: [i64; 2],
    /// Texels per side.
    pub resolution: u32,
    /// The window has a footprint buffer.
    pub has_stamps: bool,
    /// The window has snowfall.
    pub use_fallen: bool,
}

impl ShareWindow {
    fn gpu_origin(&self) -> [i32; 2] {
        [self.origin[0] as i32, self.origin[1] as i32]
    }
}

/// What a gathered copy is: its tiles and the clock they are at.
struct Gathered {
    keys: Vec<TileKey>,
    clock: ShareClock,
    planes: (bool, bool),
}

/// The sharing state of one window.
pub struct Sharing {
    grid: ShareGrid,
    interval_s: f64,
    gather: TileGatherPass,
    merge: TileMergePass,
    /// The flags copied out, with the window origin and world time of their frame.
    flag_ring: ReadbackRing<([i64; 2], f64)>,
    gather_ring: ReadbackRing<Gathered>,
    /// Tiles changed and not gathered since, with the world time they were
    /// first and last flagged.
    dirty: BTreeMap<TileKey, (f64, f64)>,
    /// The next gather takes every dirty tile, quiet or not.
    gather_all: bool,
    /// World time of the last gather.
    last_gather_s: Option<f64>,
    /// Gathered tiles not taken yet.
    outbox: Vec<SharedTile>,
    /// Tiles to merge, in arrival order.
    incoming: VecDeque<SharedTile>,
    /// The window's last frames (at most [`HISTORY_FRAMES`]), oldest first.
    history: VecDeque<FrameRecord>,
    /// The analytic presses of the frames since the last take (at most
    /// [`PRESS_FRAMES_KEPT`], oldest dropped: their presses go as tiles).
    presses: VecDeque<PressFrame>,
    /// The last frame of presses, kept or not: a frame repeating it is not kept.
    last_press: Option<PressFrame>,
}

/// The most press frames kept for the peer: a few seconds of frames; a
/// snow shared without a peer taking them keeps no more.
const PRESS_FRAMES_KEPT: usize = 256;

/// Whether tile `key` of `side` has a texel in `window`.
fn overlaps(window: &ShareWindow, key: TileKey, side: u32) -> bool {
    let first = key.first_texel(side);
    let side = i64::from(side);
    let r = i64::from(window.resolution);
    (0..2).all(|a| first[a] < window.origin[a].saturating_add(r) && first[a].saturating_add(side) > window.origin[a])
}

/// Tiles of `side` one dispatch takes: [`MAX_TILES_PER_FRAME`] within
/// [`STAGING_BUDGET_BYTES`], at least one.
#[must_use]
pub fn tiles_per_frame(side: u32) -> u32 {
    let fit = STAGING_BUDGET_BYTES / packed_tile_bytes(side).max(1);
    u32::try_from(fit).unwrap_or(u32::MAX).clamp(1, MAX_TILES_PER_FRAME)
}

impl Sharing {
    /// Sharing in tiles of `side` texels for the window of `res`, gathering
    /// changed tiles at most every `interval_s` of world time. The flags
    /// buffer (`res.share_flags`) must have [`ShareGrid::slots`] slots.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources, side: u32, interval_s: f64) -> Self {
        let grid = ShareGrid::new(res.resolution, side);
        let capacity = tiles_per_frame(side);
        Self {
            grid,
            interval_s,
            gather: TileGatherPass::new(device, res, side, capacity),
            merge: TileMergePass::new(device, res, side, capacity),
            flag_ring: ReadbackRing::new(device, "changed-tile flags", u64::from(grid.slots()) * 4, RING_SLOTS),
            gather_ring: ReadbackRing::new(device, "gathered tiles", packed_tile_bytes(side) * u64::from(capacity), RING_SLOTS),
            dirty: BTreeMap::new(),
            gather_all: false,
            last_gather_s: None,
            outbox: Vec::new(),
            incoming: VecDeque::new(),
            history: VecDeque::with_capacity(HISTORY_FRAMES),
            presses: VecDeque::new(),
            last_press: None,
        }
    }

    /// The flags' layout (tile side, slots).
    #[must_use]
    pub fn grid(&self) -> ShareGrid {
        self.grid
    }

    /// Tiles changed and not gathered yet.
    #[must_use]
    pub fn dirty_tiles(&self) -> usize {
        self.dirty.len()
    }

    /// Tiles waiting to be merged.
    #[must_use]
    pub fn waiting_tiles(&self) -> usize {
        self.incoming.len()
    }

    /// GPU memory held (bytes), the flags buffer aside (it is the window's).
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        self.gather.memory_bytes() + self.merge.memory_bytes() + self.flag_ring.memory_bytes() + self.gather_ring.memory_bytes()
    }

    /// Queues `tiles` to be merged (tiles of another side, or with planes
    /// of the wrong size, are dropped, with a warning).
    pub fn queue(&mut self, tiles: &[SharedTile]) {
        let before = self.incoming.len();
        self.incoming.extend(tiles.iter().filter(|t| t.side == self.grid.side && t.is_consistent()).cloned());
        let dropped = tiles.len() - (self.incoming.len() - before);
        if dropped > 0 {
            tracing::warn!("{dropped} shared tiles dropped: not of this world's side {} or with planes of the wrong size", self.grid.side);
        }
    }

    /// The tiles ready to merge at `clock`, one per key, at most a
    /// dispatch's worth, each with the first frame of the history the
    /// merge pass replays on it: a tile whose clock is the clock after one
    /// of the remembered frames is replayed from the next one (exact where
    /// the sender ran the same frames); any other is caught up here in one
    /// step and replays nothing. Further copies of a key and tiles beyond a
    /// dispatch stay queued for later frames (merging is idempotent, so
    /// copies merged one after the other end as if merged together). A tile
    /// ahead of `clock` waits for it, unless it is more than
    /// [`AHEAD_LIMIT_S`] ahead.
    fn ready(&mut self, window: &ShareWindow, clock: &ShareClock, catch: CatchUp) -> Vec<(SharedTile, i32)> {
        let capacity = self.merge.capacity() as usize;
        let frames = self.history.len();
        let mut batch: BTreeMap<TileKey, (SharedTile, i32)> = BTreeMap::new();
        let mut held = VecDeque::new();
        while let Some(mut tile) = self.incoming.pop_front() {
            if !overlaps(window, tile.key, self.grid.side) {
                // Nothing of it is in the window (the peer merges it again
                // when the window reaches it), and its key may not fit the
                // passes' i32 coordinates.
                continue;
            }
            let ahead = !clock.covers(&tile.clock);
            if (ahead && tile.clock.time_s <= clock.time_s + AHEAD_LIMIT_S) || batch.contains_key(&tile.key) || batch.len() >= capacity {
                held.push_back(tile);
                continue;
            }
            let first = match self.history.iter().position(|f| f.after == tile.clock) {
                Some(k) => k + 1,
                None => {
                    tile.catch_up(clock, catch);
                    frames
                }
            };
            batch.insert(tile.key, (tile, first as i32));
        }
        self.incoming = held;
        batch.into_values().collect()
    }

    /// Records the merge of the tiles ready at `clock` into the window
    /// (after the window's move, before this frame's presses).
    pub fn record_merge(
        &mut self,
        cx: &mut FrameContext<'_>,
        res: &DeformResources,
        window: &ShareWindow,
        params: TileMergeParams,
        (clock, catch): (&ShareClock, CatchUp),
    ) {
        let tiles = self.ready(window, clock, catch);
        if tiles.is_empty() {
            return;
        }
        let keys: Vec<[i32; 4]> = tiles.iter().map(|(t, first)| [t.key.col as i32, t.key.row as i32, *first, super::merge::carries_packed(t)]).collect();
        let history: Vec<[u32; 4]> = self.history.iter().map(FrameRecord::gpu).collect();
        let refs: Vec<&SharedTile> = tiles.iter().map(|(t, _)| t).collect();
        let flags = if window.has_stamps { TileMergeParams::HAS_STAMPS } else { 0 } | if window.use_fallen { TileMergeParams::USE_FALLEN } else { 0 };
        let params = TileMergeParams { origin: window.gpu_origin(), resolution: window.resolution, side: self.grid.side, flags, ..params };
        self.merge.record(cx, res, params, (&keys, &history), &pack_tiles(&refs));
    }

    /// Records, after this frame's presses (`frame`, with the clock after
    /// it), the copy of the changed-tile flags out (then clears them) and,
    /// when the interval has passed, the gather of dirty tiles as they are
    /// at that clock. A step whose readback has no free staging buffer is
    /// left for a later frame (flags keep accumulating; dirty tiles stay
    /// dirty).
    pub fn record_after_update(&mut self, cx: &mut FrameContext<'_>, res: &DeformResources, window: &ShareWindow, frame: FrameRecord) {
        if self.history.len() == HISTORY_FRAMES {
            self.history.pop_front();
        }
        self.history.push_back(frame);
        let clock = &frame.after;
        if self.flag_ring.has_free_slot() {
            self.flag_ring.record_copy(cx.encoder, &res.share_flags, (window.origin, clock.time_s));
            cx.encoder.clear_buffer(&res.share_flags, 0, None);
        }
        let due = self.last_gather_s.is_none_or(|t| clock.time_s - t >= self.interval_s);
        if self.dirty.is_empty() || !(due || self.gather_all) || !self.gather_ring.has_free_slot() {
            return;
        }
        // A tile still being pressed waits until it has been quiet for an
        // interval (a wheel or a paw crosses a tile in a fraction of a
        // second, and sending each stage of it costs the wire), but never
        // longer than QUIET_LIMIT intervals after its first change.
        let now = clock.time_s;
        let ready = |&(first, last): &(f64, f64)| now - last >= self.interval_s || now - first >= QUIET_LIMIT * self.interval_s;
        let all = std::mem::take(&mut self.gather_all);
        let keys: Vec<TileKey> = self.dirty.iter().filter(|(_, t)| all || ready(t)).map(|(k, _)| *k).take(self.gather.capacity() as usize).collect();
        if keys.is_empty() {
            return;
        }
        for k in &keys {
            self.dirty.remove(k);
        }
        let flags = if window.has_stamps { TileGatherParams::HAS_STAMPS } else { 0 } | if window.use_fallen { TileGatherParams::USE_FALLEN } else { 0 };
        let params = TileGatherParams { origin: window.gpu_origin(), resolution: window.resolution, side: self.grid.side, flags, ..Default::default() };
        let count = self.gather.record(cx, res, params, &gpu_keys(&keys));
        let bytes = packed_tile_bytes(self.grid.side) * u64::from(count);
        let meta = Gathered { keys, clock: *clock, planes: (window.has_stamps, window.use_fallen) };
        self.gather_ring.record_copy_len(cx.encoder, self.gather.packed(), bytes, meta);
        self.last_gather_s = Some(clock.time_s);
    }

    /// Lets the next frame gather dirty tiles whatever the interval (the end
    /// of a run: its last changes go out without waiting for world time to
    /// pass).
    pub fn gather_now(&mut self) {
        self.gather_all = true;
    }

    /// Whether a readback's mapping callback has not run yet.
    #[must_use]
    pub fn callbacks_pending(&self) -> bool {
        self.flag_ring.callbacks_pending() || self.gather_ring.callbacks_pending()
    }

    /// Takes what has come back (after a non-blocking poll): flagged tiles
    /// become dirty, gathered ones wait in the outbox.
    pub fn collect(&mut self, resolution: u32) {
        for ((origin, time_s), bytes) in self.flag_ring.take_arrived() {
            let flags: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes);
            for key in self.grid.flagged(origin, resolution, &flags) {
                self.dirty.entry(key).and_modify(|t| t.1 = t.1.max(time_s)).or_insert((time_s, time_s));
            }
        }
        for (meta, bytes) in self.gather_ring.take_arrived() {
            let packed: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes);
            self.outbox.extend(unpack_tiles(&meta.keys, self.grid.side, meta.clock, &packed, meta.planes));
        }
    }

    /// The gathered tiles since the last call.
    pub fn take_outbox(&mut self) -> Vec<SharedTile> {
        std::mem::take(&mut self.outbox)
    }

    /// Keeps a frame's analytic presses for the peer: not a frame without
    /// shapes, nor one that repeats the frame before it
    /// ([`PressFrame::repeats`]: shapes at rest, no refill since).
    pub fn record_presses(&mut self, frame: PressFrame) {
        let repeats = self.last_press.as_ref().is_some_and(|last| frame.repeats(last));
        if frame.shapes.is_empty() || repeats {
            self.last_press = (!frame.shapes.is_empty()).then_some(frame);
            return;
        }
        if self.presses.len() >= PRESS_FRAMES_KEPT {
            self.presses.pop_front();
        }
        self.last_press = Some(frame.clone());
        self.presses.push_back(frame);
    }

    /// The press frames kept since the last call, oldest first.
    pub fn take_presses(&mut self) -> Vec<PressFrame> {
        self.presses.drain(..).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_tiles_with_a_texel_in_the_window_overlap_it() {
        let window = ShareWindow { origin: [-20, 5], resolution: 40, has_stamps: false, use_fallen: false };
        // Columns -20..20, rows 5..45; tiles of 16.
        assert!(overlaps(&window, TileKey::new(-2, 0), 16)); // columns -32..-16, rows 0..16
        assert!(!overlaps(&window, TileKey::new(-3, 0), 16)); // ends at column -32
        assert!(overlaps(&window, TileKey::new(1, 2), 16)); // columns 16..32, rows 32..48
        assert!(!overlaps(&window, TileKey::new(2, 2), 16)); // starts at column 32
        assert!(!overlaps(&window, TileKey::new(0, -1), 16)); // rows -16..0
        assert!(!overlaps(&window, TileKey::new(i64::MAX / 4, 0), 16));
        assert!(!overlaps(&window, TileKey::new(i64::MIN / 4, 0), 16));
        assert_eq!(tiles_per_frame(16), MAX_TILES_PER_FRAME);
        assert_eq!(tiles_per_frame(256), 1);
    }
}
