//! Where the window goes each frame: the move planner, which asks the
//! streamer for the tiles ahead of the window (the prefetch ring), limits a
//! move to what the slot pool holds in one step, has fresh snow stand in
//! for the tiles the disk has not given yet (merged live when they come),
//! holds the window only while a tile it needs is on its way back from the
//! GPU, and waits for the disk only in an explicit preload or a batch run.

use std::collections::HashSet;

use super::copy_out::CopyOuts;
use super::layout::SlotLayout;
use super::stats::TileCounters;
use crate::gpu::GpuContext;
use crate::persist::streamer::TileStreamerExt;
use crate::persist::{StoreError, TileKey, TileStreamer};
use crate::tiles::grid::PREFETCH_MARGIN_TILES;
use crate::tiles::slots::SlotTable;

/// What the planner works on, lent by `TileStreaming` for one call.
pub(super) struct PlanParts<'a> {
    pub(super) layout: SlotLayout,
    pub(super) slots: &'a SlotTable,
    pub(super) copy_outs: &'a mut CopyOuts,
    pub(super) streamer: &'a mut TileStreamer,
    pub(super) errors: &'a mut Vec<StoreError>,
    pub(super) counters: &'a mut TileCounters,
}

impl PlanParts<'_> {
    /// Whether `key` has a slot.
    fn resident(&self, key: TileKey) -> bool {
        self.slots.contains(key)
    }

    /// Tiles the window at `desired` needs from the streamer when coming
    /// from `current`: those it touches that have no slot and were not in
    /// the window before (a tile the old window touched lives there or in its slot).
    fn needed_from_store(&self, current: Option<[i64; 2]>, desired: [i64; 2]) -> Vec<TileKey> {
        let grid = self.layout.grid;
        grid.nearest_first(desired, 0).into_iter().filter(|&k| !self.resident(k) && !current.is_some_and(|o| grid.touched(k, o))).collect()
    }
}

/// The planner's memory between frames.
#[derive(Debug, Default)]
pub(super) struct MovePlanner {
    /// The tile the prefetch ring was last asked around.
    prefetched_at: Option<TileKey>,
    /// Tiles this frame's move does not wait for (not in memory yet, or a
    /// preload gave up on them): stood in for at once, not waited for one by one.
    gave_up: HashSet<TileKey>,
    /// Where [`Self::preload`] last loaded the window's tiles for: the
    /// first placement there waits for nothing.
    preloaded: Option<[i64; 2]>,
}

impl MovePlanner {
    /// The tiles the last wait gave up on.
    pub(super) fn gave_up(&self) -> &HashSet<TileKey> {
        &self.gave_up
    }

    /// Decides where the window goes this frame: `desired` (a glide at most
    /// a tile side per axis, or a jump), with fresh snow standing in for the
    /// tiles the disk has not given yet; it stays at `current` only while a
    /// tile it needs is on its way back from the GPU. With
    /// `StreamerConfig::moves_wait_for_disk` it waits for the disk instead.
    pub(super) fn plan(&mut self, ctx: &GpuContext, mut p: PlanParts<'_>, current: Option<[i64; 2]>, desired: [i64; 2]) -> [i64; 2] {
        p.streamer.poll();
        // A preload for this very place already waited (and gave up on what did not come).
        let preloaded = self.preloaded.take() == Some(desired);
        if !preloaded {
            self.gave_up.clear();
        }
        let here = p.layout.grid.key_of(desired);
        if self.prefetched_at != Some(here) {
            self.prefetched_at = Some(here);
            for key in p.layout.grid.nearest_first(desired, PREFETCH_MARGIN_TILES) {
                if !p.resident(key) && !p.copy_outs.carries(key) {
                    p.streamer.request(key);
                }
            }
        }
        if current == Some(desired) {
            return desired;
        }
        let desired = current.map_or(desired, |c| reachable(p.layout, c, desired));
        let needed = p.needed_from_store(current, desired);
        if preloaded || needed.iter().all(|&k| !p.copy_outs.carries(k) && p.streamer.is_ready(k)) {
            return desired;
        }
        if p.streamer.moves_wait_for_disk() {
            // A batch run: the move waits (and is counted as a wait) rather
            // than stands in, so its result does not depend on the disk's speed.
            p.counters.gpu_waits += u64::from(needed.iter().any(|&k| p.copy_outs.carries(k)));
            p.counters.blocking_loads += u64::from(current.is_some());
            self.wait_for_needed(ctx, &mut p, &needed);
            return desired;
        }
        if needed.iter().any(|&k| p.copy_outs.carries(k)) {
            // A tile copied out a frame or two ago is still on its way back
            // from the GPU: hold still until it is in (its latest version).
            // Only the first placement, with nowhere to hold, waits for it.
            let Some(current) = current else {
                p.counters.gpu_waits += 1;
                p.copy_outs.collect(ctx, true, p.streamer, p.errors);
                return self.stand_in_for_the_disk(&mut p, &needed, desired);
            };
            for &key in &needed {
                if !p.copy_outs.carries(key) {
                    p.streamer.request(key);
                }
            }
            p.counters.window_waits += 1;
            return current;
        }
        self.stand_in_for_the_disk(&mut p, &needed, desired)
    }

    /// The window goes to `desired` now, without waiting for the disk:
    /// fresh snow stands in for each of `needed` not in memory yet (asked
    /// for, nearest the centre first), and its stored version is merged
    /// in live when it arrives (`TileStreaming::record_live_merges`).
    fn stand_in_for_the_disk(&mut self, p: &mut PlanParts<'_>, needed: &[TileKey], desired: [i64; 2]) -> [i64; 2] {
        for &key in needed {
            if !p.streamer.is_ready(key) {
                p.streamer.request(key);
                self.gave_up.insert(key);
            }
        }
        desired
    }

    /// Waits (blocking) until each of `needed` is in memory: the copies out
    /// of the GPU it is among first, then the disk, within the streamer's
    /// wait limit. Fresh snow stands in for what did not come (see
    /// `arrivals::restore_entry`), its stored version merged in later; the
    /// error is kept for `TileStreaming::take_errors`.
    fn wait_for_needed(&mut self, ctx: &GpuContext, p: &mut PlanParts<'_>, needed: &[TileKey]) {
        if needed.iter().any(|&k| p.copy_outs.carries(k)) {
            p.copy_outs.collect(ctx, true, p.streamer, p.errors);
        }
        if let Err(e) = p.streamer.wait_for(needed) {
            p.errors.push(e);
            self.gave_up.extend(needed.iter().copied().filter(|&k| !p.streamer.is_ready(k)));
        }
    }

    /// The explicit wait a loading screen makes: loads (blocking) every
    /// tile the window moving from `current` to `desired` needs, so the
    /// next [`Self::plan`] for `desired` moves there at once (a jump
    /// instead of holding while the disk reads) and a first placement
    /// waits for nothing. What the disk does not give within the wait
    /// limit is stood in for as in a frame, and reported the same way.
    pub(super) fn preload(&mut self, ctx: &GpuContext, mut p: PlanParts<'_>, current: Option<[i64; 2]>, desired: [i64; 2]) {
        p.streamer.poll();
        self.gave_up.clear();
        let needed = p.needed_from_store(current, desired);
        self.wait_for_needed(ctx, &mut p, &needed);
        self.preloaded = Some(desired);
        // Not the prefetch ring now: its tiles arriving between this wait
        // and the placement could push the ones waited for out of a small
        // memory budget. The ring follows once the window moves on.
        self.prefetched_at = Some(p.layout.grid.key_of(desired));
    }
}

/// Where the window at `current` may go this frame on its way to
/// `desired` without waiting for the GPU: all the way when the new
/// window is a jump away (none of its tiles within the prefetch margin
/// of the old, so none is resident or on its way out of this move), and
/// otherwise at most one tile side along each axis, a step the slot pool
/// always holds (`record_step`). A move of a few tiles thus glides over
/// as many frames instead of copying the old window out and waiting for
/// the copies before restoring the tiles it shares with the new one.
fn reachable(layout: SlotLayout, current: [i64; 2], desired: [i64; 2]) -> [i64; 2] {
    let g = layout.grid;
    if g.around(desired, 0).into_iter().all(|k| !g.near(k, current, PREFETCH_MARGIN_TILES)) {
        return desired;
    }
    let side = i64::from(g.side());
    [0, 1].map(|a| current[a] + (desired[a] - current[a]).clamp(-side, side))
}
