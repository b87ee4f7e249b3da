//! Every wait on the tile store has a limit: with a disk that stops
//! answering (`testing::HeldDisk`), `flush`, `write_state`, `read_state`,
//! `wait_for`, dropping the streamer and `SnowDeformation::save` and
//! `attach_store` give up with `StoreError::TimedOut` instead of hanging,
//! and releasing the disk afterwards breaks nothing.
//!
//! The bounds asserted are generous (seconds for a limit of a fraction of
//! one): they tell a wait that gives up from one that hangs, not how fast.

use snowpack::StoredWindow as _;
use snowpack::low_level::TileStoreExt;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::DVec2;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::TileStreamerExt;
use snowpack::low_level::error::SnowError;
use snowpack::low_level::persist::{SnowClock, StoreError, TileData, TileKey, TileLookup};
use snowpack::{SnowDeformation, SnowParams, TerrainSource};
use snowpack::{StoreConfig, StreamerConfig, TileStore, TileStreamer};
use snowpack_testkit::testing::{self, HeldDisk};

const SIDE: u32 = 16;
/// The streamers' wait limit in these tests.
const LIMIT: Duration = Duration::from_millis(300);
/// Far beyond `LIMIT`: a call that takes this long did not give up.
const HUNG: Duration = Duration::from_secs(20);

/// A fresh directory, removed on drop.
struct TestDir(PathBuf);

impl TestDir {
    fn new(name: &str) -> Self {
        let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
        let dir = std::env::temp_dir().join(format!("snowpack-held-{name}-{}-{nanos}", std::process::id()));
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

fn tile(col: i64, row: i64, v: f32) -> TileData {
    let n = (SIDE * SIDE) as usize;
    TileData {
        key: TileKey::new(col, row),
        side: SIDE,
        clock: SnowClock { time_s: f64::from(v), ..SnowClock::default() },
        snow_xor_rest: vec![v.to_bits(); n],
        stamps: vec![v as u32; n],
        fallen: Vec::new(),
        packed: Vec::new(),
    }
}

/// A streamer over a store in `dir` on `disk` (not held yet), giving up after [`LIMIT`].
fn held_streamer(dir: &Path, disk: &HeldDisk, side: u32) -> TileStreamer {
    let store = TileStore::open_on(Arc::new(disk.clone()), dir, side, StoreConfig::default()).expect("open");
    TileStreamer::new(store, StreamerConfig { wait_limit: LIMIT, ..StreamerConfig::default() })
}

/// Runs `call` and gives its answer, failing the test if it has not
/// returned within [`HUNG`] (then the disk is released, so that a call that
/// waits without a limit ends and the test fails rather than hangs).
fn bounded<T: Send>(disk: &HeldDisk, what: &str, call: impl FnOnce() -> T + Send) -> T {
    let (done, finished) = std::sync::mpsc::channel();
    std::thread::scope(|scope| {
        let running = scope.spawn(move || {
            let answer = call();
            let _ = done.send(());
            answer
        });
        let returned = finished.recv_timeout(HUNG).is_ok();
        if !returned {
            disk.release();
        }
        let answer = running.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        assert!(returned, "{what} did not return within {HUNG:?} with a wait limit of {LIMIT:?}: it waits without a limit");
        answer
    })
}

fn assert_timed_out(what: &str, result: Result<impl std::fmt::Debug, StoreError>, names: &str) {
    match result {
        Err(e @ StoreError::TimedOut { .. }) => {
            let StoreError::TimedOut { what: waited_for, waited } = &e else { unreachable!() };
            assert!(*waited >= LIMIT, "{what} gave up after {waited:?}, before its limit");
            assert!(waited_for.contains(names), "{what}: `{waited_for}` does not say it waited for {names}");
            let shown = e.to_string();
            assert!(shown.contains("gave up after") && shown.contains("not answering"), "{shown}");
        }
        other => panic!("{what} on a held disk gave {other:?}, not TimedOut"),
    }
}

/// Calls `call` until it succeeds, within [`HUNG`]: on a loaded machine a
/// disk that answers (and, after a release, catches up on the held
/// operations) can still take longer than [`LIMIT`]; only `TimedOut` is
/// expected meanwhile.
fn until_ok<T, E: std::fmt::Debug>(what: &str, mut call: impl FnMut() -> Result<T, E>, timed_out: impl Fn(&E) -> bool) -> T {
    let start = Instant::now();
    loop {
        match call() {
            Ok(answer) => return answer,
            Err(e) if timed_out(&e) && start.elapsed() < HUNG => {}
            Err(e) => panic!("{what} on a disk that answers: {e:?}"),
        }
    }
}

fn store_timed_out(e: &StoreError) -> bool {
    matches!(e, StoreError::TimedOut { .. })
}

/// Polls until `key` is ready, within [`HUNG`].
fn ready(s: &mut TileStreamer, key: TileKey) -> Option<TileData> {
    let start = Instant::now();
    loop {
        if let TileLookup::Ready(tile) = s.lookup(key) {
            return tile;
        }
        assert!(start.elapsed() < HUNG, "{key:?} never became ready");
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn flush_gives_up_on_a_held_disk_and_writes_once_released() {
    let dir = TestDir::new("flush");
    let disk = HeldDisk::default();
    let mut s = held_streamer(dir.path(), &disk, SIDE);
    disk.hold();
    s.put(tile(0, 0, 1.0));
    assert!(disk.wait_until_blocked(HUNG), "the tile's write reaches the disk");
    assert_timed_out("flush", bounded(&disk, "flush", || s.flush().map_err(StoreError::from)), "flush");
    // Still answered from memory while the disk hangs.
    assert_eq!(s.lookup(TileKey::new(0, 0)), TileLookup::Ready(Some(tile(0, 0, 1.0))));
    disk.release();
    until_ok("flush", || s.flush().map_err(StoreError::from), store_timed_out);
    assert_eq!(s.stats().writes, 1);
    drop(s);
    let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("reopen");
    assert_eq!(store.read(TileKey::new(0, 0)).expect("read"), Some(tile(0, 0, 1.0)));
}

#[test]
fn state_writes_and_reads_give_up_on_a_held_disk() {
    let dir = TestDir::new("state");
    let disk = HeldDisk::default();
    let mut s = held_streamer(dir.path(), &disk, SIDE);
    until_ok("write_state", || s.write_state("clock", vec![1, 2, 3]), store_timed_out);
    disk.hold();
    assert_timed_out("write_state", bounded(&disk, "write_state", || s.write_state("clock", vec![4, 5, 6])), "`clock` to be written");
    // The worker is still inside that write: the read queues behind it.
    assert_timed_out("read_state", bounded(&disk, "read_state", || s.read_state("clock")), "`clock` to be read");
    assert_timed_out("wait_for", bounded(&disk, "wait_for", || s.wait_for(&[TileKey::new(7, 7)])), "1 tile(s) to load");
    disk.release();
    // The queued write is done once the disk answers, before the next read.
    let state = until_ok("read_state", || s.read_state("clock"), store_timed_out);
    assert_eq!(state, Some(vec![4, 5, 6]));
    assert_eq!(ready(&mut s, TileKey::new(7, 7)), None);
    assert!(s.take_errors().is_empty(), "a late answer is not an error");
}

#[test]
fn a_read_on_a_held_disk_gives_up() {
    let dir = TestDir::new("read");
    let disk = HeldDisk::default();
    let mut s = held_streamer(dir.path(), &disk, SIDE);
    until_ok("write_state", || s.write_state("clock", vec![9]), store_timed_out);
    disk.hold();
    assert_timed_out("read_state", bounded(&disk, "read_state", || s.read_state("clock")), "`clock` to be read");
    disk.release();
    assert_eq!(until_ok("read_state", || s.read_state("clock"), store_timed_out), Some(vec![9]));
}

#[test]
fn dropping_the_streamer_on_a_held_disk_gives_up_and_releasing_it_later_is_harmless() {
    let dir = TestDir::new("drop");
    let disk = HeldDisk::default();
    let mut s = held_streamer(dir.path(), &disk, SIDE);
    disk.hold();
    s.put(tile(2, 3, 4.0));
    s.put(tile(3, 3, 5.0));
    assert!(disk.wait_until_blocked(HUNG), "the first write reaches the disk");
    // The worker is left behind, stuck in the first write; dropping returns.
    bounded(&disk, "drop", move || drop(s));
    assert_eq!(disk.blocked(), 1, "the detached worker is still waiting on the disk");
    disk.release();
    // The detached worker finishes its queue and lets go of the store (its
    // lock): the store then opens, with both tiles written.
    let start = Instant::now();
    let mut store = loop {
        match TileStore::open(dir.path(), SIDE, StoreConfig::default()) {
            Ok(store) => break store,
            Err(e) => {
                assert!(start.elapsed() < HUNG, "the detached worker never let go of the store: {e}");
                std::thread::sleep(Duration::from_millis(10));
            }
        }
    };
    assert_eq!(store.read(TileKey::new(2, 3)).expect("read"), Some(tile(2, 3, 4.0)));
    assert_eq!(store.read(TileKey::new(3, 3)).expect("read"), Some(tile(3, 3, 5.0)));
}

/// Through the orchestrator: a save on a hung disk is an error naming the
/// wait (the program exits with it), and so is loading one.
#[test]
fn save_and_attach_store_give_up_on_a_held_disk() {
    let Some(ctx) = testing::gpu() else { return };
    let dir = TestDir::new("save");
    let disk = HeldDisk::default();
    let params = SnowParams { extent_m: 4.0, resolution: 64, depth_m: 0.5, blur: false, ..SnowParams::default() };
    let terrain = TerrainSource::Flat { height_m: 0.0 };
    let side = 16;
    let mut d = SnowDeformation::new(ctx, params.clone(), terrain.clone(), DVec2::ZERO).expect("window");
    assert!(!d.attach_store(ctx, held_streamer(dir.path(), &disk, side)).expect("attach"));
    d.step(ctx, &[], 1.0 / 60.0).expect("frame");
    disk.hold();
    match bounded(&disk, "save", || d.save(ctx).map_err(SnowError::from)) {
        Err(SnowError::Store(StoreError::TimedOut { .. })) => {}
        other => panic!("a save on a held disk gave {other:?}, not a TimedOut store error"),
    }
    disk.release();
    until_ok("save", || d.save(ctx).map_err(SnowError::from), |e| matches!(e, SnowError::Store(StoreError::TimedOut { .. })));
    drop(d);

    let mut loaded = SnowDeformation::new(ctx, params, terrain, DVec2::ZERO).expect("window");
    let streamer = held_streamer(dir.path(), &disk, side);
    disk.hold();
    match bounded(&disk, "attach_store", || loaded.attach_store(ctx, streamer).map_err(SnowError::from)) {
        Err(SnowError::Store(StoreError::TimedOut { what, .. })) => assert!(what.contains("window"), "{what}"),
        other => panic!("loading a save from a held disk gave {other:?}, not a TimedOut store error"),
    }
    disk.release();
}
