//! A tile arriving in a slot: its stored version from the streamer (or
//! fresh snow standing in for it), with what the window made in its place
//! to merge in, as the restore pass's entry and upload.

use std::collections::HashSet;

use super::stats::TileCounters;
use crate::persist::streamer::TileStreamerExt;
use crate::persist::{SnowClock, StoreError, TileData, TileKey, TileLookup, TileStreamer};
use crate::tiles::grid::TileGrid;
use crate::tiles::restore::RestoreEntry;

/// What an arrival works on, lent by `TileStreaming` for one tile.
pub(super) struct Arrival<'a> {
    pub(super) grid: TileGrid,
    pub(super) streamer: &'a mut TileStreamer,
    /// The tiles the last wait gave up on (`MovePlanner::gave_up`).
    pub(super) gave_up: &'a HashSet<TileKey>,
    pub(super) counters: &'a mut TileCounters,
    pub(super) errors: &'a mut Vec<StoreError>,
}

/// The restore entry of `key` into `slot`, from the streamer (saved
/// planes appended to `upload`) or fresh; with what the window made in
/// the tile's place while the disk was late to merge in, where there is.
pub(super) fn restore_entry(a: Arrival<'_>, key: TileKey, slot: usize, upload: &mut Vec<u32>, clock: SnowClock) -> RestoreEntry {
    let (saved, made) = take_tile(a.streamer, a.gave_up, a.counters, a.errors, key);
    let area = a.grid.area();
    let mut entry = RestoreEntry { tile: [key.col as i32, key.row as i32], slot: slot as u32, ..RestoreEntry::default() };
    let usable = |tile: &TileData| tile.side == a.grid.side() && tile.snow_xor_rest.len() == area && tile.stamps.len() == area;
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
            a.counters.restored += 1;
        }
        Some(tile) => {
            a.errors.push(StoreError::Mismatch {
                path: a.streamer.dir().to_path_buf(),
                why: format!("tile ({}, {}) has side {}, the window uses {}; fresh snow used", key.col, key.row, tile.side, a.grid.side()),
            });
            a.counters.fresh += 1;
        }
        None => a.counters.fresh += 1,
    }
    if let Some(made) = made.filter(|t| usable(t)) {
        let (at, refill_m, fall_m, quanta) = push(&made, upload);
        (entry.merge, entry.merge_refill_m, entry.merge_fall_m, entry.merge_quanta) = (at, refill_m, fall_m, quanta);
        a.counters.merged += 1;
    }
    entry
}

/// The stored version of `key` and what the window made in its place, from
/// the streamer: read again (blocking; counted) if the memory cache dropped
/// it since `plan` saw it ready, fresh snow standing in when the disk is
/// late or could not read it.
fn take_tile(
    streamer: &mut TileStreamer,
    gave_up: &HashSet<TileKey>,
    counters: &mut TileCounters,
    errors: &mut Vec<StoreError>,
    key: TileKey,
) -> (Option<TileData>, Option<TileData>) {
    match streamer.take_for_restore(key) {
        (TileLookup::Ready(saved), made) => {
            if made.is_none() && streamer.stands_in(key) {
                // Its read failed: fresh snow (or what the window made here) stands in.
                counters.stood_in += 1;
            }
            (saved, made)
        }
        // `plan` saw it ready, but handing out the tiles before it let
        // the memory cache drop it. A batch run reads it again (blocking;
        // counted); a game's frame stands in for it and merges it live
        // when it comes back. Not for the tiles the move already gave up
        // on: one wait each would add up.
        (TileLookup::Pending, _) => {
            if !gave_up.contains(&key) && streamer.moves_wait_for_disk() {
                counters.blocking_loads += 1;
                if let Err(e) = streamer.wait_for(&[key]) {
                    errors.push(e);
                }
            }
            match streamer.take_for_restore(key) {
                (TileLookup::Ready(saved), made) => (saved, made),
                (TileLookup::Pending, _) => {
                    // The disk is late: fresh snow (or what the window made
                    // here before) stands in; the stored version is merged
                    // in later, never written over.
                    counters.stood_in += 1;
                    (streamer.stand_in(key), None)
                }
            }
        }
    }
}
