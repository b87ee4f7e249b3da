//! The streamer's tests: the cache, the worker's ordering, stand-ins, failures and the memory-only streamer.

use std::sync::mpsc;
use std::time::{Duration, Instant};

use super::config::WAIT_LIMIT;
use super::*;
use crate::persist::test_dir::TestDir;
use crate::persist::{SnowClock, StoreConfig, decode};

const SIDE: u32 = 8;

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

fn streamer(dir: &TestDir, tiles_in_memory: usize) -> TileStreamer {
    let store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
    let budget = tiles_in_memory * tile(0, 0, 0.0).memory_bytes();
    TileStreamer::new(store, StreamerConfig { memory_budget_bytes: budget, ..StreamerConfig::default() })
}

/// Polls until the lookup is ready (bounded, so a bug fails instead of hanging).
fn ready(s: &mut TileStreamer, key: TileKey) -> Option<TileData> {
    let start = Instant::now();
    loop {
        if let TileLookup::Ready(tile) = s.lookup(key) {
            return tile;
        }
        assert!(start.elapsed() < Duration::from_secs(10), "{key:?} never became ready");
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn pending_then_ready_and_hits() {
    let dir = TestDir::new("streamer-pending");
    {
        let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
        store.write(&tile(1, -1, 3.0)).expect("write");
    }
    let mut s = streamer(&dir, 16);
    assert_eq!(s.side(), SIDE);
    assert_eq!(s.stats().disk_tiles, 1);
    let key = TileKey::new(1, -1);
    assert!(!s.is_ready(key));
    assert_eq!(s.lookup(key), TileLookup::Pending, "the first lookup cannot be in memory");
    assert_eq!(ready(&mut s, key), Some(tile(1, -1, 3.0)));
    assert!(s.is_ready(key));
    assert_eq!(s.lookup(key), TileLookup::Ready(Some(tile(1, -1, 3.0))));
    let stats = s.stats();
    assert_eq!((stats.misses, stats.hits, stats.loads), (1, 2, 1));
    assert_eq!(stats.memory_tiles, 1);

    // Never written: Pending, then known absent without another load.
    let never = TileKey::new(50, 50);
    s.request(never);
    assert_eq!(ready(&mut s, never), None);
    assert_eq!(s.lookup(never), TileLookup::Ready(None));
    let stats = s.stats();
    assert_eq!((stats.loads, stats.misses), (2, 1), "request() is a prefetch, not a miss");
    assert!((stats.hit_rate() - stats.hits as f64 / (stats.hits + 1) as f64).abs() < 1e-12);
    assert!(s.take_errors().is_empty());
}

#[test]
fn memory_budget_is_respected() {
    let dir = TestDir::new("streamer-budget");
    let mut s = streamer(&dir, 3);
    let budget = 3 * tile(0, 0, 0.0).memory_bytes();
    for col in 0..10 {
        s.put(tile(col, 0, col as f32));
        assert!(s.stats().memory_bytes <= budget);
        assert!(s.stats().memory_tiles <= 3);
    }
    s.flush().expect("flush");
    for col in 0..10 {
        assert_eq!(ready(&mut s, TileKey::new(col, 0)), Some(tile(col, 0, col as f32)));
        assert!(s.stats().memory_bytes <= budget);
    }
    let stats = s.stats();
    assert_eq!((stats.writes, stats.disk_tiles, stats.lost), (10, 10, 0));
}

#[test]
fn tiles_asked_for_wait_for_their_lookup() {
    let dir = TestDir::new("streamer-wanted");
    let keys: Vec<TileKey> = (0..6).map(|k| TileKey::new(k, -k)).collect();
    {
        let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
        for key in &keys {
            store.write(&tile(key.col, key.row, key.col as f32)).expect("write");
        }
    }
    // Room for one tile, but the window needs six at once.
    let mut s = streamer(&dir, 1);
    s.wait_for(&keys).expect("wait");
    assert!(keys.iter().all(|&k| s.is_ready(k)), "every tile asked for is still there");
    for key in &keys {
        assert_eq!(s.lookup(*key), TileLookup::Ready(Some(tile(key.col, key.row, key.col as f32))));
    }
    // Handed out, they no longer hold memory beyond the budget.
    let stats = s.stats();
    assert_eq!((stats.memory_tiles, stats.loads, stats.misses), (1, 6, 0));
    // Once taken, a tile is an ordinary cache entry and may be dropped.
    s.put(tile(9, 9, 1.0));
    assert_eq!(s.stats().memory_tiles, 1);
    assert_eq!(s.lookup(keys[0]), TileLookup::Pending);
}

#[test]
fn put_then_evict_then_lookup_returns_the_newest() {
    let dir = TestDir::new("streamer-newest");
    {
        let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
        store.write(&tile(0, 0, 1.0)).expect("write");
    }
    let mut s = streamer(&dir, 1);
    let a = TileKey::new(0, 0);
    // A load of the old version is queued before the put...
    s.request(a);
    s.put(tile(0, 0, 2.0));
    // ...and the new version leaves memory before anything was written.
    s.put(tile(1, 0, 9.0));
    assert_eq!(s.stats().memory_tiles, 1);
    s.wait_for(&[a]).expect("wait");
    assert_eq!(s.lookup(a), TileLookup::Ready(Some(tile(0, 0, 2.0))));
    assert_eq!(ready(&mut s, TileKey::new(1, 0)), Some(tile(1, 0, 9.0)));
    assert_eq!(s.stats().lost, 0);
}

#[test]
fn loads_go_ahead_of_queued_writes_and_see_the_newest_version() {
    let dir = TestDir::new("streamer-loads-first");
    let mut s = streamer(&dir, 1);
    let a = TileKey::new(0, 0);
    // Hold the worker, as a disk that syncs slowly would, while writes queue up.
    let (release, gate) = mpsc::channel();
    s.send(|seq| Request::Pause { seq, gate, entered: None }).expect("send");
    s.put(tile(0, 0, 1.0));
    s.put(tile(0, 0, 2.0));
    for col in 1..20 {
        s.put(tile(col, 0, 9.0));
    }
    // The newest version of `a` has left memory; only its queued write holds it.
    assert_eq!(s.lookup(a), TileLookup::Pending);
    drop(release);
    s.wait_for(&[a]).expect("wait");
    // The load was answered before any of the 21 writes...
    assert_eq!(s.stats().writes, 0);
    // ...from the newest queued write, which is still dirty until written.
    assert_eq!(s.lookup(a), TileLookup::Ready(Some(tile(0, 0, 2.0))));
    s.flush().expect("flush");
    assert_eq!(s.stats().writes, 21);
    assert_eq!(s.stats().lost, 0);
    drop(s);
    let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
    assert_eq!(store.read(a).expect("read"), Some(tile(0, 0, 2.0)));
}

/// A blocking wait on a disk that stops answering gives up after its limit
/// with `TimedOut` instead of freezing the caller; the load goes on, and
/// once the disk answers the tile is there.
#[test]
fn a_wait_on_a_hung_disk_gives_up_and_the_tile_arrives_later() {
    let dir = TestDir::new("streamer-hung");
    {
        let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
        store.write(&tile(3, 4, 5.0)).expect("write");
    }
    let mut s = streamer(&dir, 4);
    let a = TileKey::new(3, 4);
    // The worker is held, as a disk that hangs would hold it (loads jump the queue,
    // so the wait starts once the worker is inside the pause).
    let (release, gate) = mpsc::channel();
    let (entered, held) = mpsc::channel();
    s.send(|seq| Request::Pause { seq, gate, entered: Some(entered) }).expect("send");
    held.recv().expect("the worker is held");
    let limit = Duration::from_millis(200);
    match s.wait_for_within(&[a], limit) {
        Err(StoreError::TimedOut { what, waited }) => {
            assert!(what.contains("1 tile"), "{what}");
            assert!(waited >= limit, "gave up after {waited:?}, before its limit");
        }
        other => panic!("a wait on a held worker gave {other:?}, not TimedOut"),
    }
    assert!(!s.is_ready(a));
    drop(release);
    s.wait_for(&[a]).expect("the disk answers again");
    assert_eq!(s.lookup(a), TileLookup::Ready(Some(tile(3, 4, 5.0))));
    assert!(WAIT_LIMIT <= Duration::from_secs(60), "the default bound is a bound");
}

/// Fresh snow the window stood in for a late tile with is never written
/// over the stored tile: it is held until the stored version is here and
/// both go to the restore to merge; where the store has none, it is the tile.
#[test]
fn a_stand_in_is_held_for_its_merge_not_written_over_the_stored_tile() {
    let dir = TestDir::new("streamer-stand-in");
    let (stored, never) = (TileKey::new(1, 1), TileKey::new(2, 1));
    {
        let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("open");
        store.write(&tile(1, 1, 1.0)).expect("write");
    }
    let mut s = streamer(&dir, 8);
    // The disk is late: the window stands in for both tiles, then hands back what it made there.
    let (release, gate) = mpsc::channel();
    let (entered, held) = mpsc::channel();
    s.send(|seq| Request::Pause { seq, gate, entered: Some(entered) }).expect("send");
    held.recv().expect("the worker is held");
    assert_eq!(s.stand_in(stored), None, "nothing made there yet");
    assert_eq!(s.stand_in(never), None);
    s.put(tile(1, 1, 7.0));
    s.put(tile(2, 1, 8.0));
    assert_eq!(s.stand_ins_made(), vec![stored, never]);
    assert_eq!(s.take_for_restore(stored), (TileLookup::Pending, None), "the stored version is still loading");
    drop(release);
    s.wait_for(&[stored, never]).expect("the disk answers");
    s.flush().expect("flush");
    // The store has no version of `never`: what the window made is the tile, written.
    assert_eq!(s.stats().writes, 1);
    assert_eq!(s.stand_ins_made(), vec![stored]);
    // Both versions of `stored` go to the restore, which merges them; then it is an ordinary tile.
    assert_eq!(s.take_for_restore(stored), (TileLookup::Ready(Some(tile(1, 1, 1.0))), Some(tile(1, 1, 7.0))));
    assert!(s.stand_ins_made().is_empty());
    assert_eq!(s.take_for_restore(stored), (TileLookup::Ready(Some(tile(1, 1, 1.0))), None));
    assert!(s.take_errors().is_empty());
    drop(s);
    let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("reopen");
    assert_eq!(store.read(stored).expect("read"), Some(tile(1, 1, 1.0)), "never written over");
    assert_eq!(store.read(never).expect("read"), Some(tile(2, 1, 8.0)));
}

#[test]
fn flush_writes_everything_and_state_is_ordered() {
    let dir = TestDir::new("streamer-flush");
    let mut s = streamer(&dir, 64);
    for col in -5..5 {
        s.put(tile(col, 7, col as f32 + 10.0));
    }
    // State requests are ordered after the tile writes before them.
    s.write_state("clock", vec![1, 2, 3]).expect("write state");
    assert_eq!(s.stats().writes, 10);
    s.flush().expect("flush");
    assert_eq!(s.read_state("clock").expect("read state"), Some(vec![1, 2, 3]));
    assert_eq!(s.read_state("nothing").expect("read state"), None);
    assert!(s.write_state("../escape", Vec::new()).is_err());
    let stats = s.stats();
    assert_eq!((stats.writes, stats.disk_tiles, stats.errors), (10, 10, 0));
    assert_eq!(stats.bytes_written, stats.disk_bytes);
    for col in -5..5 {
        let bytes = std::fs::read(tile_path(dir.path(), TileKey::new(col, 7))).expect("the tile's file");
        assert_eq!(decode(&bytes).expect("decode"), tile(col, 7, col as f32 + 10.0));
    }
    // Dropping writes what is queued.
    s.put(tile(100, 100, 1.0));
    drop(s);
    let mut store = TileStore::open(dir.path(), SIDE, StoreConfig::default()).expect("reopen");
    assert_eq!(store.read(TileKey::new(100, 100)).expect("read"), Some(tile(100, 100, 1.0)));
}

#[test]
fn failed_writes_stay_dirty_and_are_retried() {
    let dir = TestDir::new("streamer-retry");
    let mut s = streamer(&dir, 2);
    let tiles = dir.path().join("tiles");
    // A file where the directory was: every tile write fails, as root too.
    std::fs::remove_dir_all(&tiles).expect("remove tiles");
    std::fs::write(&tiles, b"in the way").expect("block tiles");
    s.put(tile(0, 0, 1.0));
    // Let the worker answer that write (it fails) before a flush looks at
    // the cache: whether flush's own poll saw the failure, and so retried
    // the write once more, depended on timing (1 in 60 runs).
    let seq = s.send(|seq| Request::Flush { seq }).expect("send");
    s.wait(seq, || "the test's flush".to_owned()).expect("answered");
    assert_eq!(s.stats().errors, 1);
    assert_eq!(s.take_errors().len(), 1, "the failed write is reported");
    // A flush retries the failed write, which fails again: that error is
    // flush's answer, and is not repeated in take_errors.
    assert!(matches!(s.flush().map_err(StoreError::from), Err(StoreError::Io { .. })));
    assert_eq!(s.stats().errors, 2);
    assert!(s.take_errors().is_empty(), "the error flush returned is not repeated");
    // Still answered from memory, and written once the disk is back.
    assert_eq!(s.lookup(TileKey::new(0, 0)), TileLookup::Ready(Some(tile(0, 0, 1.0))));
    std::fs::remove_file(&tiles).expect("unblock");
    std::fs::create_dir(&tiles).expect("tiles again");
    s.flush().expect("the retry succeeds");
    assert_eq!((s.stats().writes, s.stats().disk_tiles), (1, 1));

    // Dropping a failed tile from memory loses it, and says so.
    std::fs::remove_dir_all(&tiles).expect("remove tiles");
    std::fs::write(&tiles, b"in the way").expect("block tiles");
    s.put(tile(1, 0, 1.0));
    s.put(tile(2, 0, 1.0));
    assert!(s.flush().is_err());
    // One error was returned; the other write's (and any earlier attempt's) are here.
    let errors = s.take_errors();
    assert!(!errors.is_empty() && errors.iter().all(|e| matches!(e, StoreError::Io { .. })), "{errors:?}");
    s.put(tile(3, 0, 1.0));
    s.put(tile(4, 0, 1.0));
    let stats = s.stats();
    assert_eq!(stats.lost, 2, "tiles 1 and 2 were dropped unwritten");
    assert_eq!(stats.memory_tiles, 2);
    // Pushed out while their writes are queued: not lost until those fail.
    s.put(tile(5, 0, 1.0));
    s.put(tile(6, 0, 1.0));
    assert!(s.flush().is_err());
    assert_eq!(s.stats().lost, 4, "tiles 3 and 4 failed after leaving memory");
    assert!(s.lookup(TileKey::new(6, 0)) == TileLookup::Ready(Some(tile(6, 0, 1.0))));
}

#[test]
fn a_dead_worker_is_reported_not_panicked() {
    let dir = TestDir::new("streamer-dead");
    let mut s = streamer(&dir, 4);
    s.put(tile(0, 0, 1.0));
    s.send(|_| Request::Panic).expect("send");
    assert!(matches!(s.flush().map_err(StoreError::from), Err(StoreError::WorkerGone)));
    assert!(matches!(s.wait_for(&[TileKey::new(5, 5)]), Err(StoreError::WorkerGone)));
    assert!(matches!(s.read_state("x"), Err(StoreError::WorkerGone)));
    assert_eq!(s.lookup(TileKey::new(5, 5)), TileLookup::Ready(None));
    assert_eq!(s.lookup(TileKey::new(0, 0)), TileLookup::Ready(Some(tile(0, 0, 1.0))));
    s.put(tile(1, 0, 1.0));
    let errors = s.take_errors();
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(matches!(errors[0], StoreError::WorkerGone));
    drop(s); // Must not panic.
}

fn memory(tiles_in_memory: usize) -> TileStreamer {
    let budget = tiles_in_memory * tile(0, 0, 0.0).memory_bytes();
    TileStreamer::in_memory(SIDE, StreamerConfig { memory_budget_bytes: budget, ..StreamerConfig::default() })
}

#[test]
fn in_memory_keeps_tiles_within_the_budget_and_forgets_the_oldest() {
    let mut s = memory(3);
    assert!(s.is_memory_only() && s.dir().as_os_str().is_empty());
    let key = |col| TileKey::new(col, 2);
    // Never put: fresh snow at once, no load, no worker.
    assert!(s.is_ready(key(0)));
    assert_eq!(s.lookup(key(0)), TileLookup::Ready(None));
    s.wait_for(&[key(0), key(1)]).expect("nothing to wait for");
    for col in 0..5 {
        s.put(tile(col, 2, col as f32 + 1.0));
        assert!(s.stats().memory_tiles <= 3);
    }
    let stats = s.stats();
    assert_eq!((stats.memory_tiles, stats.memory_bytes), (3, 3 * tile(0, 0, 0.0).memory_bytes()));
    assert_eq!(stats.lost, 2, "tiles 0 and 1 were forgotten for the budget");
    assert_eq!((stats.writes, stats.disk_tiles, stats.errors), (0, 0, 0));
    // The two oldest are fresh snow; the newest three come back as put.
    assert_eq!(s.lookup(key(0)), TileLookup::Ready(None));
    assert_eq!(s.lookup(key(1)), TileLookup::Ready(None));
    for col in 2..5 {
        assert_eq!(s.lookup(key(col)), TileLookup::Ready(Some(tile(col, 2, col as f32 + 1.0))));
    }
    // Handed out once: the window holds them now.
    assert_eq!(s.stats().memory_tiles, 0);
    assert_eq!(s.lookup(key(4)), TileLookup::Ready(None));
    s.flush().expect("nothing to flush");
    assert!(s.take_errors().is_empty());
}

#[test]
fn in_memory_keeps_the_newest_version_and_not_untouched_tiles() {
    let mut s = memory(8);
    let key = TileKey::new(-3, 7);
    s.put(tile(-3, 7, 1.0));
    s.put(tile(-3, 7, 2.0));
    assert_eq!(s.stats().memory_tiles, 1);
    // Snow at rest everywhere, no footprint, no snowfall: the same as fresh snow.
    let untouched = TileData { snow_xor_rest: vec![0; 64], stamps: vec![STAMP_EMPTY; 64], ..tile(-3, 7, 0.0) };
    s.put(untouched.clone());
    assert_eq!(s.stats().memory_tiles, 0, "an untouched tile replaces what was kept and is not kept");
    assert_eq!(s.lookup(key), TileLookup::Ready(None));
    // With a snowfall plane it is kept (snowfall may differ from the fresh snow's).
    s.put(TileData { fallen: vec![0.0; 64], ..untouched });
    assert_eq!(s.stats().memory_tiles, 1);
    s.put(tile(-3, 7, 5.0));
    assert_eq!(s.lookup(key), TileLookup::Ready(Some(tile(-3, 7, 5.0))));
    assert_eq!(s.stats().lost, 0);
}

#[test]
fn in_memory_has_no_state_to_save() {
    let mut s = memory(2);
    assert_eq!(s.read_state("window.state").expect("read"), None);
    let err = s.write_state("window.state", vec![1]).expect_err("no disk");
    assert!(matches!(err, StoreError::NoDisk) && err.path().is_none());
    assert!(err.to_string().contains("disk store"), "{err}");
    let mut short = tile(0, 0, 1.0);
    short.stamps.pop();
    s.put(short);
    assert_eq!(s.take_errors().len(), 1, "a wrong tile is refused in memory too");
    drop(s); // No worker to join, nothing to write.
}

#[test]
fn a_wrong_tile_is_refused() {
    let dir = TestDir::new("streamer-wrong");
    let mut s = streamer(&dir, 4);
    let mut short = tile(0, 0, 1.0);
    short.snow_xor_rest.pop();
    s.put(short);
    let mut big = tile(1, 0, 1.0);
    big.side = 16;
    s.put(big);
    let errors = s.take_errors();
    assert_eq!(errors.len(), 2);
    assert!(errors.iter().all(|e| matches!(e, StoreError::Mismatch { .. }) && e.path().is_some()));
    assert_eq!(s.stats().memory_tiles, 0);
}
