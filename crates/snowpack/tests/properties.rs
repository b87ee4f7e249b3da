//! Property tests of what snowpack reads back from disk: the tile codec, the
//! saved window state and the tile store's directory. Any bytes give `Ok`
//! or a typed error, never a panic, and decoding what was encoded gives back
//! the same bits. (The fuzz targets under `fuzz/` run the same entry points
//! for longer on the nightly toolchain.)

use snowpack::low_level::TileStoreExt;
use std::path::{Path, PathBuf};

use glam::DVec2;
use proptest::prelude::*;
use snowpack::low_level::persist::{SnowClock, TileData, TileKey, decode, encode};
use snowpack::low_level::snow::saved::SavedWindow;
use snowpack::{StoreConfig, TileStore};

/// Bit patterns, so NaNs and signed zeros compare as stored.
fn tile_bits(t: &TileData) -> (TileKey, u32, [u64; 4], Vec<u32>, Vec<u32>, Vec<u32>) {
    let c = t.clock;
    (
        t.key,
        t.side,
        [c.time_s.to_bits(), c.refill_m.to_bits(), c.fallen_m.to_bits(), c.stamp_quanta],
        t.snow_xor_rest.clone(),
        t.stamps.clone(),
        t.fallen.iter().map(|v| v.to_bits()).collect(),
    )
}

fn clock() -> impl Strategy<Value = SnowClock> {
    (any::<f64>(), any::<f64>(), any::<f64>(), any::<u64>()).prop_map(|(time_s, refill_m, fallen_m, stamp_quanta)| SnowClock {
        time_s,
        refill_m,
        fallen_m,
        stamp_quanta,
    })
}

/// Planes that look like real tiles (mostly zero snow, runs of empty
/// footprints) as well as pure noise, so both the compressor's long runs and
/// its worst case are covered.
fn plane(texels: usize) -> impl Strategy<Value = Vec<u32>> {
    prop_oneof![
        prop::collection::vec(any::<u32>(), texels),
        prop::collection::vec(prop_oneof![4 => Just(0u32), 1 => any::<u32>()], texels),
        prop::collection::vec(prop_oneof![4 => Just(u32::MAX), 1 => any::<u32>()], texels),
    ]
}

fn tile() -> impl Strategy<Value = TileData> {
    (prop_oneof![Just(1u32), Just(3), Just(16), Just(32)], any::<i64>(), any::<i64>(), clock(), any::<bool>(), any::<bool>()).prop_flat_map(
        |(side, col, row, clock, snowfall, packed)| {
            let texels = (side * side) as usize;
            let fallen = if snowfall { prop::collection::vec(any::<u32>(), texels).boxed() } else { Just(Vec::new()).boxed() };
            let packed = if packed { prop::collection::vec(prop_oneof![4 => Just(0u16), 1 => any::<u16>()], texels).boxed() } else { Just(Vec::new()).boxed() };
            (plane(texels), plane(texels), fallen, packed).prop_map(move |(snow, stamps, fallen, packed)| TileData {
                key: TileKey { col, row },
                side,
                clock,
                snow_xor_rest: snow,
                stamps,
                fallen: fallen.into_iter().map(f32::from_bits).collect(),
                packed,
            })
        },
    )
}

fn saved() -> impl Strategy<Value = SavedWindow> {
    ((any::<u32>(), any::<u32>(), any::<[f32; 4]>(), any::<[i64; 2]>(), any::<[f64; 2]>()), (clock(), any::<f32>(), any::<f32>(), any::<u64>())).prop_map(
        |((resolution, tile_side, f, origin, center), (clock, fallen_m, stamp_carry_m, frame))| SavedWindow {
            resolution,
            tile_side,
            texel_m: f[0],
            depth_m: f[1],
            stamp_range_m: [f[2], f[3]],
            origin,
            center: DVec2::from(center),
            clock,
            fallen_m,
            stamp_carry_m,
            frame,
        },
    )
}

fn saved_bits(s: &SavedWindow) -> Vec<u8> {
    // `encode` writes every field's bits in order: equal bytes, equal state.
    s.encode()
}

/// A fresh folder under the target's temporary directory.
fn scratch(name: &str, case: u64) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("snowpack-prop-{name}-{}-{case}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch folder");
    dir
}

fn write(path: &Path, bytes: &[u8]) {
    std::fs::create_dir_all(path.parent().expect("parent")).expect("folders");
    std::fs::write(path, bytes).expect("write");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn tiles_round_trip_bit_for_bit(t in tile()) {
        let back = decode(&encode(&t)).expect("a tile's own encoding decodes");
        prop_assert_eq!(tile_bits(&back), tile_bits(&t));
    }

    #[test]
    fn damaged_tiles_are_errors_not_panics(t in tile(), flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8), cut in any::<prop::sample::Index>()) {
        let mut bytes = encode(&t);
        for (at, x) in &flips {
            let k = at.index(bytes.len());
            bytes[k] ^= x | 1;
        }
        // Ok only if the damage left a valid tile (the checksum makes that unlikely); never a panic.
        if let Ok(back) = decode(&bytes) {
            prop_assert!(back.validate().is_ok());
        }
        let whole = encode(&t);
        let truncated = &whole[..cut.index(whole.len())];
        prop_assert!(decode(truncated).is_err(), "a truncated tile decoded");
    }

    #[test]
    fn any_bytes_decode_to_a_tile_or_an_error(bytes in prop::collection::vec(any::<u8>(), 0..2048)) {
        if let Ok(t) = decode(&bytes) {
            prop_assert!(t.validate().is_ok());
        }
    }

    #[test]
    fn window_state_round_trips_and_damage_is_an_error(s in saved(), cut in any::<prop::sample::Index>(), junk in prop::collection::vec(any::<u8>(), 0..256)) {
        let path = Path::new("state");
        let bytes = s.encode();
        let back = SavedWindow::decode(&bytes, path).expect("its own encoding decodes");
        prop_assert_eq!(saved_bits(&back), bytes.clone());
        prop_assert!(SavedWindow::decode(&bytes[..cut.index(bytes.len())], path).is_err());
        let _ = SavedWindow::decode(&junk, path);
    }
}

proptest! {
    // Each case makes and scans a folder: fewer cases.
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// A store folder whose files a crash or a user damaged: opening it and
    /// reading every tile gives `Ok` or a typed error, and writing after
    /// that still works or fails cleanly.
    #[test]
    fn a_damaged_store_folder_opens_or_fails_cleanly(
        t in tile().prop_filter("the store's side", |t| t.side == 16),
        meta in prop::option::of(prop::collection::vec(any::<u8>(), 0..64)),
        junk_tiles in prop::collection::vec((-3i64..3, -3i64..3, prop::collection::vec(any::<u8>(), 0..600)), 0..6),
        state in prop::option::of(prop::collection::vec(any::<u8>(), 0..128)),
        case in any::<u64>(),
    ) {
        let dir = scratch("store", case);
        {
            let mut store = TileStore::open(&dir, 16, StoreConfig::default()).expect("a fresh store");
            store.write(&t).expect("write a tile");
            store.write_state("window", b"a state").expect("write a state");
        }
        // Damage: the meta file replaced, tile files replaced by junk, the state replaced.
        if let Some(meta) = &meta {
            write(&dir.join("store.meta"), meta);
        }
        let tile_path = {
            let store = TileStore::open(&dir, 16, StoreConfig::default());
            store.ok().map(|s| (0..junk_tiles.len()).map(|k| s.tile_path(TileKey { col: junk_tiles[k].0, row: junk_tiles[k].1 })).collect::<Vec<_>>())
        };
        if let Some(paths) = &tile_path {
            for (path, (_, _, bytes)) in paths.iter().zip(&junk_tiles) {
                write(path, bytes);
            }
        }
        if let Some(state) = &state {
            write(&dir.join("window.state"), state);
        }
        match TileStore::open(&dir, 16, StoreConfig::default()) {
            Ok(mut store) => {
                // Each damaged tile is an error naming its file (set aside), then absent.
                let mut seen = std::collections::HashSet::new();
                for &(col, row, _) in &junk_tiles {
                    let key = TileKey { col, row };
                    let read = store.read(key);
                    if seen.insert(key) && key != t.key {
                        let e = read.expect_err("junk in a tile's file reads as an error");
                        let file = store.tile_path(key);
                        prop_assert_eq!(e.path(), Some(file.as_path()), "{}", e);
                    } else {
                        prop_assert!(matches!(read, Ok(None)), "a damaged tile set aside reads as absent: {:?}", read.map(|t| t.map(|t| t.key)));
                    }
                }
                // The undamaged tile and state read back as written.
                if !seen.contains(&t.key) {
                    let back = store.read(t.key).map_err(|e| TestCaseError::fail(format!("the undamaged tile: {e}")))?;
                    prop_assert_eq!(back.map(|b| tile_bits(&b)), Some(tile_bits(&t)), "the undamaged tile reads back bit for bit");
                }
                match (&state, store.read_state("window")) {
                    (None, Ok(back)) => prop_assert_eq!(back.as_deref(), Some(&b"a state"[..])),
                    (None, Err(e)) => return Err(TestCaseError::fail(format!("the undamaged state: {e}"))),
                    (Some(_), Ok(back)) => prop_assert!(false, "a damaged state read as {:?}", back),
                    (Some(_), Err(e)) => {
                        let file = dir.join("window.state");
                        prop_assert_eq!(e.path(), Some(file.as_path()), "{}", e);
                    }
                }
                // Still usable: a fresh tile writes and reads back.
                let fresh = TileData { key: TileKey { col: 100, row: 100 }, ..t.clone() };
                if store.write(&fresh).is_ok() {
                    let back = store.read(fresh.key).expect("a tile just written reads back");
                    prop_assert_eq!(back.map(|b| tile_bits(&b)), Some(tile_bits(&fresh)));
                }
            }
            // A damaged meta file is a typed error naming it.
            Err(e) => prop_assert!(meta.is_some(), "only a damaged meta may refuse the folder: {e}"),
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// Writes the fuzz targets' seed corpus (`fuzz/corpus/`): real encodings of
/// tiles, a window state and a store's files, so the fuzzer starts past the
/// magic numbers and checksums. Run on purpose:
/// `cargo test -p snowpack --test properties -- --ignored write_fuzz_corpus`.
#[test]
#[ignore = "writes files into the checkout; run on purpose to regenerate the seeds"]
fn write_fuzz_corpus() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus");
    let tile = |side: u32, snowfall: bool, trail: bool| {
        let n = (side * side) as usize;
        let snow = (0..n).map(|k| if trail && k % side as usize == 3 { (0.3f32).to_bits() ^ (0.5f32).to_bits() } else { 0 }).collect();
        let stamps = (0..n).map(|k| if trail && k % 7 == 0 { (40_000 << 16) | 30_000 } else { u32::MAX }).collect();
        let fallen = if snowfall { vec![0.02; n] } else { Vec::new() };
        TileData {
            key: TileKey { col: -3, row: 7 },
            side,
            clock: SnowClock { time_s: 12.5, refill_m: 0.025, fallen_m: 0.02, stamp_quanta: 4 },
            snow_xor_rest: snow,
            stamps,
            fallen,
            packed: if trail { (0..n).map(|k| if k % side as usize == 3 { 2000 } else { 0 }).collect() } else { Vec::new() },
        }
    };
    let seeds = [tile(16, false, false), tile(16, true, true), tile(32, false, true), tile(1, true, false)];
    for (k, t) in seeds.iter().enumerate() {
        write(&root.join(format!("tile_decode/seed-{k}")), &encode(t));
    }
    let state = SavedWindow {
        resolution: 1024,
        tile_side: 32,
        texel_m: 0.0625,
        depth_m: 0.5,
        stamp_range_m: [-1.0, 5.0],
        origin: [-512, 300],
        center: DVec2::new(1.5, -2.0),
        clock: SnowClock { time_s: 60.0, refill_m: 0.1, fallen_m: 0.0, stamp_quanta: 1000 },
        fallen_m: 0.0,
        stamp_carry_m: 0.00002,
        frame: 3600,
    };
    write(&root.join("saved_state/seed-0"), &state.encode());
    // The store target's input: [meta length: u8][meta][tile length: u16 LE][tile file][state].
    let dir = scratch("corpus", 0);
    let (meta, tile_file) = {
        let mut store = TileStore::open(&dir, 16, StoreConfig::default()).expect("store");
        let t = TileData { key: TileKey { col: 1, row: -2 }, ..seeds[1].clone() };
        store.write(&t).expect("write");
        (std::fs::read(dir.join("store.meta")).expect("meta"), std::fs::read(store.tile_path(t.key)).expect("tile file"))
    };
    let mut seed = vec![u8::try_from(meta.len()).expect("a short meta file")];
    seed.extend_from_slice(&meta);
    seed.extend_from_slice(&u16::try_from(tile_file.len()).expect("a small tile file").to_le_bytes());
    seed.extend_from_slice(&tile_file);
    seed.extend_from_slice(b"a window state");
    write(&root.join("store_dir/seed-0"), &seed);
    let _ = std::fs::remove_dir_all(&dir);
    for scene in std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")).expect("scenes") {
        let path = scene.expect("entry").path();
        if path.extension().is_some_and(|e| e == "toml") {
            write(&root.join("scene_parse").join(path.file_name().expect("name")), &std::fs::read(&path).expect("scene"));
        }
    }
}
