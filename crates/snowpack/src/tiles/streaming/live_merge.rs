//! Live merges: the stored version of a tile the window stood in for with
//! fresh snow (its disk was late when the window moved onto it) arrives
//! while the tile is still in the window, and is folded into what the
//! window has there now, in a submission of its own before the frame's
//! move: no frame waits for the disk, and the trail comes back a few
//! frames after the window got there.

use std::collections::HashSet;

use super::arrivals::{self, Arrival};
use super::layout::SlotLayout;
use super::recording::TilePasses;
use super::stats::TileCounters;
use crate::deform::resources::DeformResources;
use crate::frame::{FrameContext, WindowFrame};
use crate::gpu::{GpuContext, GpuTimer};
use crate::persist::{SnowClock, StoreError, TileKey, TileStreamer};
use crate::tiles::exchange::ExchangeParams;
use crate::tiles::restore::RestoreEntry;
use crate::tiles::slots::SlotTable;

/// Most tiles merged in one frame (the rest the next frames): the size of
/// a long move's batches, so the upload buffer stays as small.
const MERGES_PER_FRAME: usize = 32;

/// What the live merges work on, lent by `TileStreaming` for one call.
pub(super) struct LiveMergeParts<'a> {
    pub(super) layout: SlotLayout,
    pub(super) slots: &'a mut SlotTable,
    pub(super) passes: &'a mut TilePasses,
    pub(super) streamer: &'a mut TileStreamer,
    /// The tiles this frame's move does not wait for (`MovePlanner::gave_up`).
    pub(super) gave_up: &'a HashSet<TileKey>,
    pub(super) counters: &'a mut TileCounters,
    pub(super) errors: &'a mut Vec<StoreError>,
    /// The move count, for the slots borrowed ([`SlotTable::assign`]).
    pub(super) moves: u64,
}

/// Merges the stored versions that have arrived for the tiles the window
/// at `at` stood in for: nearest the window's centre first, at most a
/// batch a frame (the rest the next frames). Each tile's texels in the
/// window are stashed into a slot (a spare one for a tile wholly inside,
/// which holds none), the stored version brought up to `clock` is merged
/// into the slot by the deeper deficit ([`RestoreEntry::IN_SLOT`]), and
/// the texels are loaded back. What leaves and comes back is counted in
/// the mass ledger. Asks the streamer again for the stored versions not
/// here yet (a memory cache may have dropped one; not those whose read
/// failed). Records its own
/// submission: call it before anything of this frame's move is recorded
/// (the passes' uniforms are shared with the move's).
pub(super) fn record_live_merges(t: LiveMergeParts<'_>, ctx: &GpuContext, res: &DeformResources, frame: &WindowFrame, at: [i64; 2], clock: SnowClock) {
    if !t.streamer.stands_in_any() {
        return;
    }
    let g = t.layout.grid;
    let mut candidates = g.nearest_first(at, 0);
    candidates.extend(t.slots.keys().filter(|&k| !g.touched(k, at)));
    let mut arrived = Vec::new();
    let mut spare = t.slots.free_count();
    for key in candidates {
        if !t.streamer.stands_in(key) {
            continue;
        }
        if !t.streamer.stand_in_arrived(key) {
            t.streamer.ask_again_for_stand_in(key);
            continue;
        }
        // A tile wholly inside the window holds no slot: it borrows one.
        let borrows = !t.slots.contains(key);
        if arrived.len() < MERGES_PER_FRAME && (!borrows || spare > 0) {
            spare -= usize::from(borrows);
            arrived.push((key, borrows));
        }
    }
    if arrived.is_empty() {
        return;
    }
    let (mut entries, mut upload) = (Vec::new(), Vec::<u32>::new());
    let mut merged = Vec::new();
    for &(key, borrows) in &arrived {
        if borrows {
            let slot = t.slots.free_slot().expect("spare slots counted");
            t.slots.assign(key, slot, t.moves);
        }
        let slot = t.slots.slot(key).expect("resident or borrowed");
        let arrival = Arrival { grid: g, streamer: &mut *t.streamer, gave_up: t.gave_up, counters: &mut *t.counters, errors: &mut *t.errors };
        let mut entry = arrivals::restore_entry(arrival, key, slot, &mut upload, clock);
        if entry.upload == RestoreEntry::FRESH {
            // The store had no version after all (or an unusable one):
            // the window's snow is the tile; nothing to fold in.
            continue;
        }
        entry.merge = RestoreEntry::IN_SLOT;
        entries.push(entry);
        merged.push(key);
    }
    if !merged.is_empty() {
        // A table of the merged tiles alone: the stash and the load
        // leave every other texel of the window as it is.
        t.slots.write_only(&ctx.queue, &merged);
        let layout = t.layout;
        let rects = layout.batch_rects(&merged, at);
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("tile live merge") });
        let mut timer = GpuTimer::disabled();
        let mut cx = FrameContext::new(ctx, &mut encoder, &mut timer);
        let stash = layout.exchange_params(res, at, at, ExchangeParams::STASH | ExchangeParams::COUNT);
        t.passes.exchange.record(&mut cx, res, stash, &rects);
        let params = layout.restore_params(frame);
        t.passes.restore.record(&mut cx, (res, &t.passes.tiles), params, &entries, &upload);
        t.passes.exchange.record(&mut cx, res, layout.exchange_params(res, at, at, ExchangeParams::COUNT), &rects);
        ctx.queue.submit([encoder.finish()]);
        t.counters.merged_live += merged.len() as u64;
    }
    for (key, borrows) in arrived {
        if borrows {
            t.slots.release(key);
        }
    }
    // The whole table again, for this frame's move (applied at its submission).
    t.slots.write(&ctx.queue);
}
