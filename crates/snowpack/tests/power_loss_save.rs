//! A power cut at any point of a whole save, through `SnowDeformation::save`
//! and the streamer, on `testing::PowerLossDisk` (strict POSIX: what was not
//! synced may be lost, kept or torn): the world then loads as the old save
//! or the new one, every tile and the window state from the same save, and
//! as the new one whenever the save had returned.
//!
//! The world: a trail saved (the old save), then the window walks away, so
//! tiles are written between the saves, presses a second trail and saves
//! again (the new save). The run is replayed with the power cut after each
//! disk operation of the second save in turn.

use snowpack::StoredWindow as _;
use snowpack::low_level::TileStoreExt;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use glam::{DVec2, Vec2, Vec3};
use snowpack::low_level::SnowInspect;
use snowpack::low_level::persist::{TileData, TileKey};
use snowpack::{Deformer, GpuContext, SnowDeformation, SnowError, SnowParams, TerrainSource};
use snowpack::{StoreConfig, StreamerConfig, TileStore, TileStreamer};
use snowpack_testkit::testing::{self, PowerLossDisk, Rng, Unsynced};

const SIDE: u32 = 16;
const DIR: &str = "/games/snow/save";

/// A world as a store holds it: the saved window state and every tile's
/// planes. (A tile's clock says when it was copied out of the GPU, which
/// depends on when the disk answered; its planes and the window state, after
/// a fixed number of frames, do not.)
#[derive(Debug, PartialEq)]
struct World {
    state: Option<Vec<u8>>,
    tiles: BTreeMap<TileKey, Vec<u32>>,
}

fn bits(t: &TileData) -> Vec<u32> {
    t.snow_xor_rest.iter().copied().chain(t.stamps.iter().copied()).chain(t.fallen.iter().map(|f| f.to_bits())).collect()
}

/// The world on `disk` as a game opening it would load it.
fn world(disk: &PowerLossDisk, what: &str) -> World {
    let mut store = TileStore::open_on(Arc::new(disk.clone()), Path::new(DIR), SIDE, StoreConfig::default())
        .unwrap_or_else(|e| panic!("{what}: the store does not open after the power cut: {e}"));
    let state = store.read_state("window").unwrap_or_else(|e| panic!("{what}: the window state does not read: {e}"));
    let keys: Vec<TileKey> = store.keys().collect();
    let mut tiles = BTreeMap::new();
    for key in keys {
        let tile = store.read(key).unwrap_or_else(|e| panic!("{what}: {key:?} does not read back: {e}"));
        tiles.insert(key, bits(&tile.unwrap_or_else(|| panic!("{what}: {key:?} is indexed but missing"))));
    }
    World { state, tiles }
}

fn press(ctx: &GpuContext, d: &mut SnowDeformation, at: Vec2) {
    let ball = Deformer::Sphere { center: Vec3::new(at.x, 0.35, at.y), radius: 0.25 };
    for _ in 0..3 {
        d.step(ctx, &[ball], 1.0 / 60.0).expect("frame");
    }
}

/// Moves the window to `to` in a fixed number of frames (it waits while
/// the tiles it needs load, for as many frames as that takes), so that the
/// clock and the window state do not depend on how fast the disk answered.
fn walk(ctx: &GpuContext, d: &mut SnowDeformation, to: DVec2) {
    d.set_center(to);
    for _ in 0..40 {
        d.step(ctx, &[], 1.0 / 60.0).expect("frame");
        if (d.origin_m().expect("placed") + DVec2::splat(2.0) - to).length() > 0.5 {
            // Not there yet: the tiles it waits for are loading.
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    assert!((d.origin_m().expect("placed") + DVec2::splat(2.0) - to).length() < 0.5, "the window did not reach {to} in 40 frames");
}

/// The run on `disk`: the old save, tiles written between the saves, then
/// the new save with the power cut after `cut` more disk operations (none:
/// uncut). Returns what the second save answered and the disk operations it took.
fn run(ctx: &GpuContext, disk: &PowerLossDisk, cut: Option<u64>, after_old_save: impl FnOnce()) -> (Result<(), SnowError>, u64) {
    let store = TileStore::open_on(Arc::new(disk.clone()), Path::new(DIR), SIDE, StoreConfig::default()).expect("open");
    let params = SnowParams { extent_m: 4.0, resolution: 64, depth_m: 0.5, refill_m_per_s: 0.0, blur: false, ..SnowParams::default() };
    let mut d = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    d.attach_store(ctx, TileStreamer::new(store, StreamerConfig::default())).expect("attach");
    press(ctx, &mut d, Vec2::new(0.5, 0.5));
    d.save(ctx).expect("the old save");
    after_old_save();
    // Tiles leave the window (written between the saves), a second trail.
    walk(ctx, &mut d, DVec2::new(12.0, 0.0));
    press(ctx, &mut d, Vec2::new(12.5, -0.5));
    walk(ctx, &mut d, DVec2::new(6.0, 0.0));
    if let Some(cut) = cut {
        disk.cut_power_after(cut);
    }
    let start = disk.ops();
    let saved = d.save(ctx);
    let ops = disk.ops() - start;
    drop(d);
    (saved, ops)
}

#[test]
fn a_power_cut_at_any_point_of_a_save_leaves_the_old_save_or_the_new_one() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("a_power_cut_at_any_point_of_a_save_leaves_the_old_save_or_the_new_one");
    let mut rng = Rng::new(seed);

    // The worlds of the two saves, from a run without a cut.
    let disk = PowerLossDisk::new();
    let mut old = None;
    let (saved, total) = run(ctx, &disk, None, || old = Some(world(&disk.crash(Unsynced::Lost), "the old save")));
    saved.expect("the new save, uncut");
    let old = old.expect("taken");
    let new = world(&disk.crash(Unsynced::Lost), "the new save");
    assert!(old.state.is_some() && new.state.is_some() && old.state != new.state, "two different saves");
    let changed = new.tiles.iter().filter(|(k, t)| old.tiles.get(*k) != Some(*t)).count();
    assert!(changed > 4 && new.tiles.len() > old.tiles.len(), "the new save changes and adds tiles ({changed} differ)");
    eprintln!(
        "the old save holds {} tiles, the new one {} ({changed} new or changed); the second save takes {total} disk operations",
        old.tiles.len(),
        new.tiles.len()
    );

    let (mut cuts, mut as_old, mut as_new) = (0, 0, 0);
    for k in 0..=total {
        let disk = PowerLossDisk::new();
        let (saved, _) = run(ctx, &disk, Some(k), || {});
        for unsynced in [Unsynced::Lost, Unsynced::Kept, Unsynced::Random(rng.next_u64())] {
            let what = format!("seed {seed}, cut after {k} of {total} operations of the save, {unsynced:?}");
            let after = world(&disk.crash(unsynced), &what);
            let diff = |other: &World| {
                let differ = after.tiles.iter().filter(|(k, t)| other.tiles.get(*k) != Some(*t)).count();
                let missing = other.tiles.keys().filter(|k| !after.tiles.contains_key(k)).count();
                format!("state {}, {differ} tiles differ, {missing} missing", if after.state == other.state { "same" } else { "differs" })
            };
            if saved.is_ok() {
                assert!(after == new, "{what}: the save returned, yet the world is not the new save: {}", diff(&new));
            } else {
                assert!(after == old || after == new, "{what}: the world is neither the old save ({}) nor the new one ({})", diff(&old), diff(&new));
            }
            cuts += 1;
            as_old += usize::from(after == old);
            as_new += usize::from(after == new);
        }
    }
    eprintln!("{cuts} power cuts recovered: {as_old} as the old save, {as_new} as the new one");
    // A cut after each of the save's operations (and before the first), each crashed three ways.
    assert_eq!(cuts, 3 * (total + 1), "every cut point of the save was tried");
    assert!(total >= 8, "the save took only {total} disk operations: the cuts cover too little");
    assert!(as_old > 0 && as_new > 0, "the cuts reach both sides of the commit");
}
