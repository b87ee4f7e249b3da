//! The tile store through a power cut at every point of a save: on a disk in
//! memory that keeps only what was synced (`testing::PowerLossDisk`, strict
//! POSIX: a file's name is durable only once its folder is synced), every
//! tile and state blob reads back bit for bit as its old or its new version,
//! and every write that returned before the cut is there. CPU only.

use snowpack::low_level::TileStoreExt;
use std::path::Path;
use std::sync::Arc;

use snowpack::low_level::persist::{SnowClock, TileData, TileKey};
use snowpack::{StoreConfig, TileStore};
use snowpack_testkit::testing::{self, PowerLossDisk, Rng, Unsynced};

const SIDE: u32 = 16;
/// Inside a folder the store must create, so that its creation is tested too.
const DIR: &str = "/games/snow/save-1";
const STATE: &str = "window";

/// Tiles written as version A, then overwritten as B: two regions, negative
/// coordinates included.
fn old_keys() -> Vec<TileKey> {
    vec![TileKey::new(0, 0), TileKey::new(1, 0), TileKey::new(31, 31), TileKey::new(-1, 0), TileKey::new(-33, 2), TileKey::new(-1, -1)]
}

/// A tile first written in the B phase, the first of its region folder.
const NEW: TileKey = TileKey::new(200, -300);

/// Version `v` of a tile: noise from the seed, so versions and tiles differ everywhere.
fn tile(seed: u64, key: TileKey, v: u64) -> TileData {
    let mut rng = Rng::new(seed ^ (key.col as u64).wrapping_mul(0x9e37_79b9) ^ (key.row as u64).wrapping_mul(0x85eb_ca6b) ^ v.wrapping_mul(0xc2b2_ae35));
    let n = (SIDE * SIDE) as usize;
    TileData {
        key,
        side: SIDE,
        clock: SnowClock { time_s: v as f64, refill_m: rng.range(0.0, 1.0).into(), fallen_m: 0.5, stamp_quanta: v },
        snow_xor_rest: (0..n).map(|k| if k % 3 == 0 { 0 } else { rng.next_u64() as u32 }).collect(),
        stamps: (0..n).map(|_| rng.next_u64() as u32).collect(),
        fallen: (0..n).map(|_| rng.range(0.0, 0.3)).collect(),
        packed: (0..n).map(|k| if k % 5 == 0 { rng.next_u64() as u16 } else { 0 }).collect(),
    }
}

/// The tile's bits, for an exact comparison (f32 `==` would equate 0 and -0).
fn bits(t: &TileData) -> Vec<u64> {
    let c = t.clock;
    let head = [t.key.col as u64, t.key.row as u64, u64::from(t.side), c.time_s.to_bits(), c.refill_m.to_bits(), c.fallen_m.to_bits(), c.stamp_quanta];
    let planes = t.snow_xor_rest.iter().chain(&t.stamps).copied().chain(t.fallen.iter().map(|f| f.to_bits())).map(u64::from);
    head.into_iter().chain([t.snow_xor_rest.len() as u64, t.stamps.len() as u64, t.fallen.len() as u64]).chain(planes).collect()
}

fn state(v: u8) -> Vec<u8> {
    vec![v; 300]
}

fn open(disk: &PowerLossDisk) -> Result<TileStore, snowpack::low_level::persist::StoreError> {
    TileStore::open_on(Arc::new(disk.clone()), Path::new(DIR), SIDE, StoreConfig::default())
}

/// What the B phase got done before the power went: the writes that returned `Ok`.
#[derive(Debug, Default)]
struct Acked {
    opened: bool,
    tiles: Vec<TileKey>,
    state: bool,
}

/// Opens the store and writes version B of every tile, the state blob, and
/// the new region's tile, carrying on past errors (after a power cut every
/// call fails, and must fail cleanly).
fn phase_b(disk: &PowerLossDisk, seed: u64) -> Acked {
    let mut acked = Acked::default();
    let Ok(mut store) = open(disk) else {
        return acked;
    };
    acked.opened = true;
    let keys = old_keys();
    for (k, &key) in keys.iter().enumerate() {
        if store.write(&tile(seed, key, 2)).is_ok() {
            acked.tiles.push(key);
        }
        if k == keys.len() / 2 {
            acked.state = store.write_state(STATE, &state(2)).is_ok();
        }
    }
    if store.write(&tile(seed, NEW, 2)).is_ok() {
        acked.tiles.push(NEW);
    }
    acked
}

/// Opens the disk after the cut and checks every tile and the state blob.
fn check(after: &PowerLossDisk, seed: u64, acked: &Acked, what: &str) {
    let mut store = open(after).unwrap_or_else(|e| panic!("{what}: the store does not open after the power cut: {e}"));
    let mut present = 0;
    for key in old_keys().into_iter().chain([NEW]) {
        let got = store.read(key).unwrap_or_else(|e| panic!("{what}: {key:?} does not read back: {e}"));
        present += usize::from(got.is_some());
        let (old, new) = (tile(seed, key, 1), tile(seed, key, 2));
        match got {
            Some(t) if bits(&t) == bits(&new) => {}
            Some(t) if bits(&t) == bits(&old) && key != NEW => {
                assert!(!acked.tiles.contains(&key), "{what}: {key:?} is its old version, yet its new one's write had returned");
            }
            Some(_) => panic!("{what}: {key:?} is neither its old nor its new version"),
            None if key == NEW => assert!(!acked.tiles.contains(&key), "{what}: {key:?} is missing, yet its write had returned"),
            None => panic!("{what}: {key:?} is missing (its old version was durable)"),
        }
    }
    assert_eq!(store.disk_tiles(), present, "{what}: the index counts what reads back");
    match store.read_state(STATE) {
        Ok(Some(s)) if s == state(2) => {}
        Ok(Some(s)) if s == state(1) => assert!(!acked.state, "{what}: the state is old, yet its new write had returned"),
        other => panic!("{what}: the state is neither old nor new: {other:?}"),
    }
    let files = after.files();
    assert!(!files.iter().any(|p| p.to_string_lossy().ends_with(".corrupt")), "{what}: a tile was quarantined: {files:?}");
    assert!(!files.iter().any(|p| p.to_string_lossy().ends_with(".tmp")), "{what}: temporary files survive open: {files:?}");
    // The store works on after the cut: a tile written now reads back.
    let more = tile(seed, TileKey::new(5, 5), 3);
    store.write(&more).unwrap_or_else(|e| panic!("{what}: writing after the cut: {e}"));
    assert!(store.read(more.key).expect("read").is_some_and(|t| bits(&t) == bits(&more)), "{what}");
}

#[test]
fn a_power_cut_at_any_point_leaves_every_tile_old_or_new() {
    let seed = testing::seed("a_power_cut_at_any_point_leaves_every_tile_old_or_new");
    let mut rng = Rng::new(seed);

    // Version A, in a store whose folders do not exist yet. Every write has
    // returned, so after a cut that loses everything unsynced it is all there.
    let disk = PowerLossDisk::new();
    {
        let mut store = open(&disk).expect("open a new store");
        for key in old_keys() {
            store.write(&tile(seed, key, 1)).expect("write A");
        }
        store.write_state(STATE, &state(1)).expect("write state A");
    }
    let a = disk.crash(Unsynced::Lost);
    {
        let mut store = open(&a).expect("the store opens after a cut");
        for key in old_keys() {
            let t = store.read(key).expect("read").unwrap_or_else(|| panic!("{key:?}: version A was lost to a power cut after its write returned"));
            assert!(bits(&t) == bits(&tile(seed, key, 1)), "{key:?}");
        }
        assert_eq!(store.read_state(STATE).expect("state"), Some(state(1)));
    }

    // How many operations the B phase takes, uncut.
    let whole = a.fork();
    let start = whole.ops();
    let acked = phase_b(&whole, seed);
    let total = whole.ops() - start;
    assert!(acked.opened && acked.state && acked.tiles.len() == old_keys().len() + 1, "the B phase fails without a cut: {acked:?}");
    eprintln!("the B phase takes {total} disk operations");

    // The power goes after each of them in turn (and after all of them);
    // each cut is recovered three ways: losing every unsynced change,
    // keeping them all, and keeping a random part of them.
    let mut cuts = 0;
    for k in 0..=total {
        let disk = a.fork();
        disk.cut_power_after(k);
        let acked = phase_b(&disk, seed);
        assert_eq!(acked.tiles.len() == old_keys().len() + 1 && acked.state, k == total, "cut after {k}: {acked:?}");
        for unsynced in [Unsynced::Lost, Unsynced::Kept, Unsynced::Random(rng.next_u64()), Unsynced::Random(rng.next_u64())] {
            check(&disk.crash(unsynced), seed, &acked, &format!("seed {seed}, cut after {k} of {total} operations, {unsynced:?}"));
            cuts += 1;
        }
    }
    eprintln!("{cuts} power cuts recovered");
}

/// A region folder's first tile: after a cut it is absent (and nothing is
/// left half made) or whole, and a write that returned is durable.
#[test]
fn a_new_region_folder_survives_with_its_first_tile_or_not_at_all() {
    let seed = testing::seed("a_new_region_folder_survives_with_its_first_tile_or_not_at_all");
    let base = PowerLossDisk::new();
    drop(open(&base).expect("open a new store"));
    let base = base.crash(Unsynced::Lost);
    let start = base.ops();
    let probe = base.fork();
    {
        let mut store = open(&probe).expect("open");
        store.write(&tile(seed, NEW, 1)).expect("write");
    }
    let total = probe.ops() - start;
    for k in 0..=total {
        let disk = base.fork();
        disk.cut_power_after(k);
        let returned = open(&disk).is_ok_and(|mut store| store.write(&tile(seed, NEW, 1)).is_ok());
        for unsynced in [Unsynced::Lost, Unsynced::Kept, Unsynced::Random(seed ^ k)] {
            let after = disk.crash(unsynced);
            let what = format!("seed {seed}, cut after {k} of {total}, {unsynced:?}");
            let mut store = open(&after).unwrap_or_else(|e| panic!("{what}: {e}"));
            match store.read(NEW).unwrap_or_else(|e| panic!("{what}: {e}")) {
                Some(t) => assert!(bits(&t) == bits(&tile(seed, NEW, 1)), "{what}: the tile is not whole"),
                None => {
                    assert!(!returned, "{what}: the write returned, yet the tile is gone");
                    assert_eq!(store.disk_tiles(), 0, "{what}");
                }
            }
            assert!(!after.files().iter().any(|p| p.to_string_lossy().ends_with(".tmp")), "{what}: temporary files survive open");
        }
    }
}
