//! The store's tests: writes and reads, saves, regions, the budget, reopening, damage and locks.

use std::fs;

use super::*;
use crate::persist::SnowClock;
use crate::persist::codec::FORMAT_VERSION;
use crate::persist::test_dir::TestDir;

const SIDE: u32 = 16;

/// A tile whose every texel holds `v` (stamps `v`, fallen `v`).
fn tile(col: i64, row: i64, v: f32) -> TileData {
    let n = (SIDE * SIDE) as usize;
    TileData {
        key: TileKey::new(col, row),
        side: SIDE,
        clock: SnowClock { time_s: f64::from(v), ..SnowClock::default() },
        // A little variation so sizes are realistic rather than minimal.
        snow_xor_rest: (0..n).map(|k| (v + (k % 7) as f32 * 0.001).to_bits()).collect(),
        stamps: vec![v as u32; n],
        fallen: vec![v; n],
        packed: vec![v as u16; n],
    }
}

fn open(dir: &Path, budget: u64) -> TileStore {
    TileStore::open(dir, SIDE, StoreConfig { disk_budget_bytes: budget, ..StoreConfig::default() }).expect("open the store")
}

#[test]
fn write_read_overwrite() {
    let dir = TestDir::new("store-rw");
    let mut store = open(dir.path(), 0);
    assert_eq!(store.read(TileKey::new(0, 0)).expect("read"), None);
    let a = tile(0, 0, 1.0);
    store.write(&a).expect("write");
    assert_eq!(store.read(a.key).expect("read"), Some(a.clone()));
    let b = tile(0, 0, 2.0);
    store.write(&b).expect("overwrite");
    assert_eq!(store.read(a.key).expect("read"), Some(b));
    assert_eq!(store.disk_tiles(), 1);
    let on_disk = fs::metadata(store.tile_path(a.key)).expect("the tile file").len();
    assert_eq!(store.disk_bytes(), on_disk);
    assert_eq!(store.tile_bytes(a.key), Some(on_disk));
    // A tile of another side is refused, naming the file.
    let mut wrong = tile(1, 0, 1.0);
    wrong.side = 8;
    match store.write(&wrong) {
        Err(StoreError::Mismatch { path, .. }) => assert_eq!(path, store.tile_path(wrong.key)),
        other => panic!("expected Mismatch, got {other:?}"),
    }
    let mut short = tile(1, 0, 1.0);
    short.stamps.pop();
    assert!(matches!(store.write(&short), Err(StoreError::Mismatch { .. })));
    assert_eq!(store.disk_tiles(), 1);
}

/// While saving, tiles are written beside their saved versions: until the
/// commit, reopening finds the last save (the later files deleted); after
/// it, the new one (the files in place).
#[test]
fn tiles_written_after_a_save_belong_to_the_next_one() {
    let dir = TestDir::new("store-saves");
    let (a, b) = (TileKey::new(0, 0), TileKey::new(-40, 3));
    {
        let mut store = open(dir.path(), 0);
        store.begin_saves();
        store.write(&tile(0, 0, 1.0)).expect("write");
        store.commit(&[("window", b"one")]).expect("commit the first save");
        store.write(&tile(0, 0, 2.0)).expect("write for the next save");
        store.write(&tile(-40, 3, 2.0)).expect("write for the next save");
        // The newest version is what reads back meanwhile.
        assert_eq!(store.read(a).expect("read"), Some(tile(0, 0, 2.0)));
        assert_eq!(store.read_state("window").expect("state"), Some(b"one".to_vec()));
    }
    // Not committed: the store holds the first save, whole.
    {
        let mut store = open(dir.path(), 0);
        assert_eq!(store.read(a).expect("read"), Some(tile(0, 0, 1.0)));
        assert_eq!(store.read(b).expect("read"), None);
        assert_eq!(store.disk_tiles(), 1);
        assert_eq!(store.read_state("window").expect("state"), Some(b"one".to_vec()));
        // Opened holding a save, it saves on: this write belongs to the next one.
        store.write(&tile(-40, 3, 3.0)).expect("write");
        store.commit(&[("window", b"two")]).expect("commit the second save");
        assert!(!store.live_path(b).to_string_lossy().contains(".g"), "committed files are in place");
    }
    let mut store = open(dir.path(), 0);
    assert_eq!(store.read(a).expect("read"), Some(tile(0, 0, 1.0)));
    assert_eq!(store.read(b).expect("read"), Some(tile(-40, 3, 3.0)));
    assert_eq!(store.read_state("window").expect("state"), Some(b"two".to_vec()));
    let leftovers: Vec<_> = walk(dir.path()).into_iter().filter(|p| p.to_string_lossy().contains(".g")).collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    // A damaged save record is an error naming it.
    fs::write(dir.path().join(SAVE_FILE), b"SNOWSAVE and then nonsense").expect("damage");
    drop(store);
    assert!(
        matches!(TileStore::open(dir.path(), SIDE, StoreConfig::default()).map_err(StoreError::from), Err(StoreError::Corrupt { path, .. }) if path.ends_with(SAVE_FILE))
    );
}

/// Every file under `dir`.
fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in fs::read_dir(dir).into_iter().flatten().flatten() {
        let path = entry.path();
        if path.is_dir() {
            out.extend(walk(&path));
        } else {
            out.push(path);
        }
    }
    out
}

#[test]
fn negative_keys_have_their_own_regions() {
    let dir = TestDir::new("store-negative");
    let mut store = open(dir.path(), 0);
    let keys = [(-1, -1), (-32, 0), (-33, 5), (31, -32), (32, 31), (0, 0), (i64::MIN, i64::MAX)];
    for (k, &(col, row)) in keys.iter().enumerate() {
        store.write(&tile(col, row, k as f32)).expect("write");
    }
    assert_eq!(store.tile_path(TileKey::new(-1, -1)), dir.path().join("tiles/r-1_-1/-1_-1.tile"));
    assert_eq!(store.tile_path(TileKey::new(-33, 5)), dir.path().join("tiles/r-2_0/-33_5.tile"));
    assert_eq!(store.tile_path(TileKey::new(32, 31)), dir.path().join("tiles/r1_0/32_31.tile"));
    for (k, &(col, row)) in keys.iter().enumerate() {
        let back = store.read(TileKey::new(col, row)).expect("read").expect("written");
        assert_eq!(back, tile(col, row, k as f32));
    }
    drop(store);
    let mut store = open(dir.path(), 0);
    assert_eq!(store.disk_tiles(), keys.len());
    assert!(store.read(TileKey::new(-33, 5)).expect("read").is_some());
}

/// A server's store: filled to its budget, it refuses new tiles and
/// keeps every old one (across a reopen too); a kept tile still updates.
#[test]
fn a_store_that_refuses_new_tiles_keeps_the_old_ones() {
    let dir = TestDir::new("store-refuse");
    let size = encode(&tile(0, 0, 1.0)).len() as u64;
    let config = StoreConfig { disk_budget_bytes: 3 * size + size / 2, when_full: WhenFull::RefuseNew };
    let mut store = TileStore::open(dir.path(), SIDE, config).expect("open");
    for col in 0..3 {
        store.write(&tile(col, 0, 1.0)).expect("write");
    }
    assert!(store.has_room(), "half a tile of the budget is left");
    let refused = store.write(&tile(3, 0, 1.0)).expect_err("past the budget");
    assert!(matches!(&refused, StoreError::Io { source, .. } if source.kind() == io::ErrorKind::StorageFull), "{refused}");
    assert!(refused.to_string().contains("disk budget"), "{refused}");
    assert!(!store.contains(TileKey::new(3, 0)) && !store.tile_path(TileKey::new(3, 0)).exists());
    store.write(&tile(1, 0, 2.0)).expect("a kept tile is rewritten");
    assert_eq!(store.evicted(), 0);
    drop(store);
    let mut store = TileStore::open(dir.path(), SIDE, StoreConfig { disk_budget_bytes: size, when_full: WhenFull::RefuseNew }).expect("reopen");
    assert_eq!(store.disk_tiles(), 3, "a smaller budget on reopening deletes nothing");
    for col in 0..3 {
        let back = store.read(TileKey::new(col, 0)).expect("read").expect("kept");
        assert_eq!(back, tile(col, 0, if col == 1 { 2.0 } else { 1.0 }));
    }
    assert!(!store.has_room());
}

#[test]
fn the_budget_evicts_the_least_recently_touched() {
    let dir = TestDir::new("store-budget");
    let size = encode(&tile(0, 0, 1.0)).len() as u64;
    // Room for three tiles (all tiles here encode to the same size).
    let mut store = open(dir.path(), 3 * size + size / 2);
    for col in 0..3 {
        store.write(&tile(col, 0, 1.0)).expect("write");
    }
    assert_eq!((store.disk_tiles(), store.evicted()), (3, 0));
    // Reading tile 0 touches it, so tile 1 is now the oldest.
    assert!(store.read(TileKey::new(0, 0)).expect("read").is_some());
    store.write(&tile(3, 0, 1.0)).expect("write");
    assert_eq!(store.evicted(), 1);
    assert!(!store.contains(TileKey::new(1, 0)), "tile 1 was the least recently touched");
    assert!(!store.tile_path(TileKey::new(1, 0)).exists());
    assert_eq!(store.read(TileKey::new(1, 0)).expect("read"), None);
    for col in [0, 2, 3] {
        assert!(store.contains(TileKey::new(col, 0)), "tile {col}");
    }
    // Overwriting tile 2 touches it: tile 0 goes next.
    store.write(&tile(2, 0, 2.0)).expect("write");
    store.write(&tile(4, 0, 1.0)).expect("write");
    assert!(!store.contains(TileKey::new(0, 0)));
    assert!(store.disk_bytes() <= 3 * size + size / 2);
    assert_eq!(store.disk_tiles(), 3);

    // A budget smaller than one tile keeps the one just written.
    drop(store);
    let mut tiny = open(dir.path(), 1);
    assert_eq!(tiny.disk_tiles(), 0, "open evicts down to the new budget");
    tiny.write(&tile(9, 9, 1.0)).expect("write");
    tiny.write(&tile(8, 9, 1.0)).expect("write");
    assert_eq!(tiny.disk_tiles(), 1);
    assert!(tiny.contains(TileKey::new(8, 9)));
}

#[test]
fn reopening_keeps_the_index_and_removes_temp_files() {
    let dir = TestDir::new("store-reopen");
    let mut store = open(dir.path(), 0);
    for col in 0..5 {
        store.write(&tile(col, -col, col as f32)).expect("write");
    }
    store.write_state("window", b"origin").expect("state");
    let (tiles, bytes) = (store.disk_tiles(), store.disk_bytes());
    drop(store);
    // What a crash between create and rename leaves behind.
    let region = dir.path().join("tiles/r0_-1");
    let leftover = region.join("-3_3.tile.1234-0.tmp");
    fs::write(&leftover, b"half a tile").expect("leftover");
    let state_leftover = dir.path().join("window.state.1234-1.tmp");
    fs::write(&state_leftover, b"half").expect("leftover");
    let unrelated = region.join("notes.txt");
    fs::write(&unrelated, b"mine").expect("unrelated file");

    let mut store = open(dir.path(), 0);
    assert_eq!((store.disk_tiles(), store.disk_bytes()), (tiles, bytes));
    assert!(!leftover.exists() && !state_leftover.exists(), "temp files are removed on open");
    assert!(unrelated.exists(), "files the store did not write are left alone");
    for col in 0..5 {
        assert_eq!(store.read(TileKey::new(col, -col)).expect("read"), Some(tile(col, -col, col as f32)));
    }
    assert_eq!(store.read_state("window").expect("state"), Some(b"origin".to_vec()));
}

#[test]
fn a_corrupt_tile_is_quarantined() {
    let dir = TestDir::new("store-corrupt");
    let mut store = open(dir.path(), 0);
    let key = TileKey::new(-2, 3);
    store.write(&tile(key.col, key.row, 1.0)).expect("write");
    let path = store.tile_path(key);
    let mut bytes = fs::read(&path).expect("tile file");
    let at = bytes.len() / 2;
    bytes[at] ^= 0x40;
    fs::write(&path, &bytes).expect("flip a byte");
    match store.read(key) {
        Err(StoreError::Corrupt { path: p, why }) => {
            assert_eq!(p, path);
            assert!(why.contains("CRC"), "{why}");
        }
        other => panic!("expected Corrupt, got {other:?}"),
    }
    assert!(!path.exists());
    assert!(dir.path().join("tiles/r-1_0/-2_3.tile.corrupt").exists());
    assert_eq!(store.read(key).expect("second read"), None);
    assert_eq!(store.disk_tiles(), 0);
    // Fresh snow can be written there again.
    store.write(&tile(key.col, key.row, 5.0)).expect("write");
    assert_eq!(store.read(key).expect("read"), Some(tile(key.col, key.row, 5.0)));
    // A tile file under another key's name is a mismatch, also set aside.
    let other = TileKey::new(-2, 4);
    fs::copy(&path, store.tile_path(other)).expect("copy");
    drop(store);
    let mut store = open(dir.path(), 0);
    assert!(matches!(store.read(other), Err(StoreError::Mismatch { .. })));
    assert_eq!(store.read(other).expect("second read"), None);
}

#[test]
fn store_meta_must_match() {
    let dir = TestDir::new("store-meta");
    assert_eq!(TileStore::side_in(dir.path()).expect("no store yet"), None);
    drop(open(dir.path(), 0));
    assert_eq!(TileStore::side_in(dir.path()).expect("a store"), Some(SIDE));
    let meta = dir.path().join(META_FILE);
    match TileStore::open(dir.path(), 32, StoreConfig::default()).map_err(StoreError::from) {
        Err(e @ StoreError::Mismatch { .. }) => {
            assert_eq!(e.path(), Some(meta.as_path()));
            assert!(e.to_string().contains("store.meta"), "{e}");
        }
        other => panic!("expected Mismatch, got {other:?}"),
    }
    let mut bytes = fs::read(&meta).expect("meta");
    bytes[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
    let crc = crc32fast::hash(&bytes[..16]);
    bytes[16..20].copy_from_slice(&crc.to_le_bytes());
    fs::write(&meta, &bytes).expect("write meta");
    match TileStore::open(dir.path(), SIDE, StoreConfig::default()).map_err(StoreError::from) {
        Err(StoreError::Version { path, found, expected }) => {
            assert_eq!((path, found, expected), (meta.clone(), FORMAT_VERSION + 1, FORMAT_VERSION));
        }
        other => panic!("expected Version, got {other:?}"),
    }
    fs::write(&meta, b"garbage").expect("write meta");
    assert!(matches!(TileStore::side_in(dir.path()), Err(StoreError::Corrupt { .. })));
    assert!(matches!(TileStore::open(dir.path(), SIDE, StoreConfig::default()).map_err(StoreError::from), Err(StoreError::Corrupt { .. })));
    assert!(matches!(TileStore::open(dir.path(), 0, StoreConfig::default()).map_err(StoreError::from), Err(StoreError::Mismatch { .. })));
}

#[test]
fn one_store_per_directory() {
    let dir = TestDir::new("store-lock");
    let store = open(dir.path(), 0);
    match TileStore::open(dir.path(), SIDE, StoreConfig::default()).map_err(StoreError::from) {
        // Where the file system has locks, the second open is refused.
        Err(StoreError::Io { source, .. }) => {
            assert_eq!(source.kind(), io::ErrorKind::WouldBlock)
        }
        Ok(_) => assert!(store._lock.is_none(), "locked, yet a second store opened"),
        Err(e) => panic!("unexpected {e}"),
    }
    drop(store);
    drop(open(dir.path(), 0));
}

#[test]
fn state_round_trip_and_damage() {
    let dir = TestDir::new("store-state");
    let store = open(dir.path(), 0);
    assert_eq!(store.read_state("window").expect("read"), None);
    store.write_state("window", &[1, 2, 3]).expect("write");
    store.write_state("empty", &[]).expect("write");
    assert_eq!(store.read_state("window").expect("read"), Some(vec![1, 2, 3]));
    assert_eq!(store.read_state("empty").expect("read"), Some(Vec::new()));
    store.write_state("window", &[4; 1000]).expect("overwrite");
    assert_eq!(store.read_state("window").expect("read"), Some(vec![4; 1000]));
    for bad in ["", "../x", "a/b", "a.b", "x".repeat(65).as_str()] {
        assert!(matches!(store.write_state(bad, b"x"), Err(StoreError::Mismatch { .. })), "{bad:?}");
    }
    let path = dir.path().join("window.state");
    let mut bytes = fs::read(&path).expect("state file");
    bytes[500] ^= 1;
    fs::write(&path, &bytes).expect("damage");
    match store.read_state("window") {
        Err(StoreError::Corrupt { path: p, .. }) => assert_eq!(p, path),
        other => panic!("expected Corrupt, got {other:?}"),
    }
}

#[test]
fn a_vanished_directory_is_an_error() {
    let dir = TestDir::new("store-vanished");
    let mut store = open(dir.path(), 0);
    store.write(&tile(0, 0, 1.0)).expect("write");
    fs::remove_dir_all(dir.path()).expect("remove the store");
    assert!(matches!(store.write(&tile(1, 0, 1.0)), Err(StoreError::Io { .. })));
    assert!(matches!(store.write(&tile(0, 0, 2.0)), Err(StoreError::Io { .. })));
    // Gone from disk: as if never written.
    assert_eq!(store.read(TileKey::new(0, 0)).expect("read"), None);
    assert!(matches!(store.write_state("s", b"x"), Err(StoreError::Io { .. })));
    assert!(!dir.path().exists(), "the store is not recreated behind the caller's back");
}
