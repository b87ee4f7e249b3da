//! No trail is lost to a slow disk. A tile the disk gives after the window
//! gave up waiting for it (or cannot read for a while) is merged into what
//! the window made there meanwhile (shared snow's merge: the deeper deficit
//! wins), never replaced by fresh snow and never written over the saved one.
//!
//! End to end through `SnowDeformation`, on a `testing::HeldDisk`: a trail
//! (A) is saved; a new window loads the save while the disk is late, hung or
//! failing, so fresh snow stands in for A's tile, and a second trail (B) is
//! pressed in the same tile. Both trails must be there after walking away and
//! back, and after a save and a reload.

use snowpack::StoredWindow as _;
use snowpack::low_level::TileStoreExt;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::{DVec2, Vec2, Vec3};
use snowpack::low_level::SnowInspect;
use snowpack::low_level::error::SnowError;
use snowpack::low_level::persist::StoreError;
use snowpack::{Deformer, GpuContext, SnowDeformation, SnowFrame, SnowParams, TerrainSource};
use snowpack::{StoreConfig, StreamerConfig, TileStore, TileStreamer};
use snowpack_testkit::testing::{self, HeldDisk};

/// Tiles of 1 m (16 texels of 1/16 m); the window is 4 m, 4×4 tiles.
const SIDE: u32 = 16;
/// The streamers' wait limit here: the window gives up on the disk after it.
const LIMIT: Duration = Duration::from_millis(300);
/// Trail A (saved first) and trail B (pressed while the disk is late), both
/// in tile (-1, -1), 0.7 m apart.
const A: Vec2 = Vec2::new(-0.75, -0.75);
const B: Vec2 = Vec2::new(-0.25, -0.25);
/// Snow depth left under a trail's centre is about 0.1 m; untouched, 0.5 m.
const PRESSED: f32 = 0.25;

struct TestDir(PathBuf);

impl TestDir {
    fn new(name: &str) -> Self {
        let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
        let dir = std::env::temp_dir().join(format!("snowpack-late-{name}-{}-{nanos}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create a test directory");
        Self(dir)
    }

    fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TestDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn window(ctx: &GpuContext) -> SnowDeformation {
    let params = SnowParams { extent_m: 4.0, resolution: 64, depth_m: 0.5, refill_m_per_s: 0.0, blur: false, ..SnowParams::default() };
    SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window")
}

/// A window over the store in `dir` on `disk`, its save loaded (if any).
fn attached(ctx: &GpuContext, dir: &Path, disk: &HeldDisk) -> (SnowDeformation, bool) {
    let store = TileStore::open_on(Arc::new(disk.clone()), dir, SIDE, StoreConfig::default()).expect("open");
    let mut d = window(ctx);
    let loaded = d.attach_store(ctx, TileStreamer::new(store, StreamerConfig { wait_limit: LIMIT, ..StreamerConfig::default() })).expect("attach");
    (d, loaded)
}

/// Presses a trail: a ball 0.25 m across sunk to 0.1 m above the ground at `at`.
fn press(ctx: &GpuContext, d: &mut SnowDeformation, at: Vec2) {
    let ball = Deformer::Sphere { center: Vec3::new(at.x, 0.35, at.y), radius: 0.25 };
    for _ in 0..3 {
        d.step(ctx, &[ball], 1.0 / 60.0).expect("frame");
    }
}

/// Snow depth at A and B.
fn depths(ctx: &GpuContext, d: &mut SnowDeformation) -> [f32; 2] {
    let points = [A, B];
    let ticket = d.step_frame(ctx, &SnowFrame::new(1.0 / 60.0, &[]).with_queries(&points)).expect("frame").expect("a ticket");
    d.finish(ctx).expect("finish");
    let answers = d.point_answers().expect("answered");
    assert_eq!(answers.ticket, ticket);
    let depth = |k: usize| answers.samples[k].expect("inside the window").depth_m();
    [depth(0), depth(1)]
}

/// Moves the window's centre to `to` and steps until the window is there
/// (it holds while tiles it left are on their way back from the GPU), within a bound.
fn walk(ctx: &GpuContext, d: &mut SnowDeformation, to: DVec2) {
    d.set_center(to);
    let start = Instant::now();
    loop {
        d.step(ctx, &[], 1.0 / 60.0).expect("frame");
        let origin = d.origin_m().expect("placed");
        if (origin + DVec2::splat(2.0) - to).length() < 0.5 {
            return;
        }
        assert!(start.elapsed() < Duration::from_secs(30), "the window never reached {to} (at {origin})");
    }
}

/// Frames (each followed by 2 ms for the store's worker) within which the
/// tiles fresh snow stands in for are merged once the disk answers: each
/// is merged in the frame after its stored version reaches memory, so here
/// 2 (the disk's read, then the merge); the bound is for a loaded CI machine.
const MERGE_FRAMES: u32 = 600;

/// Steps until no tile of the window awaits its merge, within
/// [`MERGE_FRAMES`].
fn until_merged(ctx: &GpuContext, d: &mut SnowDeformation) {
    let mut frames = 0;
    while d.tile_stats().expect("tiles").awaiting_merge > 0 && frames < MERGE_FRAMES {
        d.step(ctx, &[], 1.0 / 60.0).expect("frame");
        std::thread::sleep(Duration::from_millis(2));
        frames += 1;
    }
    let stats = d.tile_stats().expect("tiles");
    eprintln!("merged live {frames} frames after the disk answered: {stats:?}");
    assert_eq!(stats.awaiting_merge, 0, "not merged within {MERGE_FRAMES} frames: {stats:?}");
}

/// Saves on a disk that works: its many synced writes can take longer than
/// [`LIMIT`] on a loaded machine, so only `TimedOut` is retried (bounded).
fn save(ctx: &GpuContext, d: &mut SnowDeformation, what: &str) {
    let start = Instant::now();
    loop {
        match d.save(ctx).map_err(SnowError::from) {
            Ok(()) => return,
            Err(SnowError::Store(StoreError::TimedOut { .. })) if start.elapsed() < Duration::from_secs(30) => {}
            Err(e) => panic!("{what}: a save on a disk that works: {e}"),
        }
    }
}

/// Saves trail A into `dir` on a disk that works.
fn save_trail_a(ctx: &GpuContext, dir: &Path, disk: &HeldDisk) {
    let (mut d, loaded) = attached(ctx, dir, disk);
    assert!(!loaded);
    press(ctx, &mut d, A);
    let [a, b] = depths(ctx, &mut d);
    assert!(a < PRESSED && b > 0.45, "trail A pressed: depths {a} at A, {b} at B");
    save(ctx, &mut d, "trail A");
}

/// After the fault: both trails there on walking away and back, then after
/// a save and a reload on a working disk.
fn both_trails_survive(ctx: &GpuContext, dir: &Path, disk: &HeldDisk, mut d: SnowDeformation, what: &str) {
    walk(ctx, &mut d, DVec2::new(30.0, 0.0));
    walk(ctx, &mut d, DVec2::ZERO);
    // Fresh snow stands in for the tiles the disk is still reading: until they are merged.
    until_merged(ctx, &mut d);
    let [a, b] = depths(ctx, &mut d);
    assert!(a < PRESSED && b < PRESSED, "{what}: after walking away and back, depths {a} at A and {b} at B: a trail is gone");
    let stats = d.tile_stats().expect("tiles");
    assert!(stats.merged + stats.merged_live >= 1, "{what}: no stored tile was merged with what the window made: {stats:?}");
    save(ctx, &mut d, what);
    drop(d);
    let (mut again, loaded) = attached(ctx, dir, disk);
    assert!(loaded, "{what}: the save loads");
    // The loading screen's wait: the first frame shows the save.
    again.preload(ctx).expect("preload");
    let [a, b] = depths(ctx, &mut again);
    assert!(a < PRESSED && b < PRESSED, "{what}: after a save and a reload, depths {a} at A and {b} at B: a trail is gone");
    assert!(again.take_store_errors().is_empty(), "{what}: the reload reports no error");
}

/// While the window stands in fresh snow for A's tile, B is pressed there: A
/// is not shown (the disk has not given it), B is.
fn press_b_while_a_is_missing(ctx: &GpuContext, d: &mut SnowDeformation, what: &str) {
    press(ctx, d, B);
    let [a, b] = depths(ctx, d);
    assert!(a > 0.45 && b < PRESSED, "{what}: fresh snow stands in for A's tile and takes B: depths {a} at A, {b} at B");
}

/// A disk that answers late: the window does not wait for it (fresh snow
/// stands in for A's tile from the first frame, and takes B); once the disk
/// answers, A's tile is merged live into what the window has there, within
/// a bounded number of frames and without the window moving.
#[test]
fn a_late_tile_is_merged_with_what_the_window_made_meanwhile() {
    let Some(ctx) = testing::gpu() else { return };
    let dir = TestDir::new("slow");
    let disk = HeldDisk::default();
    save_trail_a(ctx, dir.path(), &disk);
    let (mut d, loaded) = attached(ctx, dir.path(), &disk);
    assert!(loaded);
    disk.hold();
    press_b_while_a_is_missing(ctx, &mut d, "slow disk");
    let stats = d.tile_stats().expect("tiles");
    assert!(stats.stood_in >= 1 && stats.awaiting_merge >= 1, "fresh snow stands in for the tiles the disk has not given: {stats:?}");
    assert_eq!((stats.blocking_loads, stats.gpu_waits), (0, 0), "a frame waited: {stats:?}");
    assert!(d.take_store_errors().is_empty(), "nothing waited, so nothing gave up");
    // The disk answers: A's tile arrives while the window still stands in for it.
    disk.release();
    let origin = d.origin_m();
    until_merged(ctx, &mut d);
    let stats = d.tile_stats().expect("tiles");
    assert!(stats.merged_live >= 1, "{stats:?}");
    assert_eq!(d.origin_m(), origin, "the window moved");
    let [a, b] = depths(ctx, &mut d);
    assert!(a < PRESSED && b < PRESSED, "merged live: depths {a} at A, {b} at B");
    both_trails_survive(ctx, dir.path(), &disk, d, "slow disk");
}

/// After the loading screen's wait (`preload`), the first frame reads
/// nothing from the disk: a disk that hangs from then on neither delays it
/// nor costs the saved trail.
#[test]
fn after_a_preload_the_first_frame_does_not_wait_for_the_disk() {
    let Some(ctx) = testing::gpu() else { return };
    let dir = TestDir::new("preload");
    let disk = HeldDisk::default();
    save_trail_a(ctx, dir.path(), &disk);
    let (mut d, loaded) = attached(ctx, dir.path(), &disk);
    assert!(loaded);
    d.preload(ctx).expect("preload");
    disk.hold();
    let [a, b] = depths(ctx, &mut d);
    assert!(a < PRESSED && b > 0.45, "the preloaded trail A is there in the first frame: depths {a} at A, {b} at B");
    let stats = d.tile_stats().expect("tiles");
    assert_eq!((stats.stood_in, stats.blocking_loads, stats.gpu_waits), (0, 0, 0), "the first frame waited or stood in: {stats:?}");
    assert!(d.take_store_errors().is_empty(), "no wait gave up");
    disk.release();
}

/// A disk that hangs: a save meanwhile gives up (the program exits 1 with
/// it) and writes nothing over the stored tile; once the disk answers,
/// nothing is lost.
#[test]
fn a_hung_disk_loses_no_trail_and_a_save_meanwhile_gives_up() {
    let Some(ctx) = testing::gpu() else { return };
    let dir = TestDir::new("hung");
    let disk = HeldDisk::default();
    save_trail_a(ctx, dir.path(), &disk);
    let (mut d, _) = attached(ctx, dir.path(), &disk);
    disk.hold();
    press_b_while_a_is_missing(ctx, &mut d, "hung disk");
    match d.save(ctx).map_err(SnowError::from) {
        Err(SnowError::Store(StoreError::TimedOut { .. })) => {}
        other => panic!("a save while the disk hangs gave {other:?}, not TimedOut"),
    }
    disk.release();
    both_trails_survive(ctx, dir.path(), &disk, d, "hung disk");
}

/// A disk that fails: the errors reach the game, B stays in memory (not
/// written over A, which the disk cannot read), a save meanwhile fails
/// naming the tile; once the disk works, the save merges A in.
#[test]
fn a_failing_disk_keeps_the_trail_in_memory_and_merges_once_it_works() {
    let Some(ctx) = testing::gpu() else { return };
    let dir = TestDir::new("failing");
    let disk = HeldDisk::default();
    save_trail_a(ctx, dir.path(), &disk);
    let (mut d, _) = attached(ctx, dir.path(), &disk);
    disk.fail(true);
    press_b_while_a_is_missing(ctx, &mut d, "failing disk");
    let errors: Vec<StoreError> = d.take_store_errors().into_iter().map(StoreError::from).collect();
    assert!(
        errors.iter().any(|e| matches!(e, StoreError::Io { op: "read", .. }) && e.path().is_some_and(|p| p.extension().is_some_and(|x| x == "tile"))),
        "the failed reads are reported, naming the tile files: {errors:?}"
    );
    // Away and back while it still fails: B comes back from memory; A cannot.
    walk(ctx, &mut d, DVec2::new(30.0, 0.0));
    walk(ctx, &mut d, DVec2::ZERO);
    let [a, b] = depths(ctx, &mut d);
    assert!(a > 0.45 && b < PRESSED, "while the disk fails, B is kept in memory: depths {a} at A, {b} at B");
    match d.save(ctx).map_err(SnowError::from) {
        Err(SnowError::Store(e @ StoreError::Io { .. })) => {
            assert!(e.path().is_some_and(|p| p.extension().is_some_and(|x| x == "tile")), "the save names the tile it could not read: {e}");
        }
        other => panic!("a save while the disk fails gave {other:?}, not an I/O error"),
    }
    disk.fail(false);
    // The save reads A, merges it into the window and the store.
    save(ctx, &mut d, "failing disk, once it works");
    let [a, b] = depths(ctx, &mut d);
    assert!(a < PRESSED && b < PRESSED, "once the disk works, the save merges A in: depths {a} at A, {b} at B");
    both_trails_survive(ctx, dir.path(), &disk, d, "failing disk");
}

/// A window over the save in `dir` on `disk` with a memory budget of one
/// tile (what the window leaves goes to the disk, and coming back reads
/// it), waiting for the disk on its moves or not (`moves_wait_for_disk`).
fn one_tile_window(ctx: &GpuContext, dir: &Path, disk: &HeldDisk, moves_wait_for_disk: bool) -> SnowDeformation {
    let store = TileStore::open_on(Arc::new(disk.clone()), dir, SIDE, StoreConfig::default()).expect("open");
    let config = StreamerConfig { memory_budget_bytes: 1, wait_limit: Duration::from_secs(20), moves_wait_for_disk };
    let mut d = window(ctx);
    assert!(d.attach_store(ctx, TileStreamer::new(store, config)).expect("attach"), "the save loads");
    d
}

/// A batch run's window (`StreamerConfig::moves_wait_for_disk`, as
/// `snowpack run` sets it) is where it was told in the frame it was told:
/// a jump away and one back, each while the disk is held for 200 ms, take
/// one frame each, waiting for the disk where a game's window would hold
/// (`window_waits` unchanged). What a run computes does not depend on the
/// disk's speed; the trail is back.
#[test]
fn a_batch_runs_jump_waits_for_a_slow_disk_instead_of_holding() {
    let Some(ctx) = testing::gpu() else { return };
    let dir = TestDir::new("batch");
    let disk = HeldDisk::default();
    save_trail_a(ctx, dir.path(), &disk);
    let mut d = one_tile_window(ctx, dir.path(), &disk, true);
    let [a, _] = depths(ctx, &mut d);
    assert!(a < PRESSED, "trail A in the first frame: depth {a}");
    let before = d.tile_stats().expect("tiles");
    for to in [DVec2::new(30.0, 0.0), DVec2::ZERO] {
        disk.hold();
        let held = disk.clone();
        let release = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(200));
            held.release();
        });
        d.set_center(to);
        d.step(ctx, &[], 1.0 / 60.0).expect("frame");
        release.join().expect("the release");
        let origin = d.origin_m().expect("placed");
        assert!((origin + DVec2::splat(2.0) - to).length() < 0.5, "one frame after it was told, the window is at {origin}, not around {to}");
    }
    let after = d.tile_stats().expect("tiles");
    assert_eq!(after.window_waits, before.window_waits, "a frame held for the disk: {after:?}");
    assert!(after.blocking_loads > before.blocking_loads, "no move waited for the disk: {after:?}");
    let [a, b] = depths(ctx, &mut d);
    assert!(a < PRESSED && b > 0.45, "trail A is back: depths {a} at A, {b} at B");
    assert!(d.take_store_errors().is_empty(), "no wait gave up");
}

/// A game's window (`moves_wait_for_disk` off) jumps home while the disk is
/// held: it is there in the frame it was told, waiting for nothing; fresh
/// snow stands in for trail A's tile and takes trail B; once the disk
/// answers, A is merged in live, within a bounded number of frames, and B
/// is kept (issue 42, item 7).
#[test]
fn a_jump_onto_tiles_the_disk_has_not_given_moves_at_once_and_merges_them_live() {
    let Some(ctx) = testing::gpu() else { return };
    let dir = TestDir::new("jump-live");
    let disk = HeldDisk::default();
    save_trail_a(ctx, dir.path(), &disk);
    let mut d = one_tile_window(ctx, dir.path(), &disk, false);
    d.preload(ctx).expect("preload");
    let [a, _] = depths(ctx, &mut d);
    assert!(a < PRESSED, "trail A in the first frame after the preload: depth {a}");
    // Away, twice (the memory keeps the tile it took last: one of the
    // first stop's), until what the window left is written (a load of a
    // tile still queued for writing is answered from the queue, held disk
    // or not) and out of memory.
    walk(ctx, &mut d, DVec2::new(30.0, 0.0));
    walk(ctx, &mut d, DVec2::new(60.0, 0.0));
    let start = Instant::now();
    while d.tile_stats().is_some_and(|s| s.evicting > 0 || s.store.writes < s.evicted || s.store.memory_tiles > 1) {
        assert!(start.elapsed() < Duration::from_secs(30), "the tiles left behind never left memory: {:?}", d.tile_stats());
        d.step(ctx, &[], 1.0 / 60.0).expect("frame");
        std::thread::sleep(Duration::from_millis(2));
    }
    let before = d.tile_stats().expect("tiles");
    disk.hold();
    d.set_center(DVec2::ZERO);
    d.step(ctx, &[], 1.0 / 60.0).expect("frame");
    let origin = d.origin_m().expect("placed");
    assert!((origin + DVec2::splat(2.0)).length() < 0.5, "one frame after the jump home, the window is at {origin}");
    press_b_while_a_is_missing(ctx, &mut d, "jump onto a held disk");
    let held = d.tile_stats().expect("tiles");
    assert!(held.awaiting_merge >= 1 && held.stood_in > before.stood_in, "nothing stood in: {held:?}");
    assert_eq!(
        (held.window_waits, held.gpu_waits, held.blocking_loads),
        (before.window_waits, before.gpu_waits, before.blocking_loads),
        "a frame waited or held: {held:?}"
    );
    disk.release();
    until_merged(ctx, &mut d);
    let after = d.tile_stats().expect("tiles");
    assert!(after.merged_live > before.merged_live, "{after:?}");
    let [a, b] = depths(ctx, &mut d);
    assert!(a < PRESSED && b < PRESSED, "A merged live, B kept: depths {a} at A, {b} at B");
    assert!(d.take_store_errors().is_empty(), "nothing waited, so nothing gave up");
}
