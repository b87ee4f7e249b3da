//! Bytes as the files of a tile store's folder (its meta file, a tile file
//! and a state): opening the folder and reading give `Ok` or a typed error,
//! never a panic, and an opened store still writes and reads a tile.
#![no_main]

use libfuzzer_sys::fuzz_target;
use snowpack::low_level::TileStoreExt;
use snowpack::low_level::persist::{SnowClock, TileData, TileKey};
use snowpack::{StoreConfig, TileStore};

fuzz_target!(|data: &[u8]| {
    let dir = std::env::temp_dir().join(format!("snowpack-fuzz-store-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    // A real store first, so the damaged files sit where the store looks for them.
    let tile_path = match TileStore::open(&dir, 16, StoreConfig::default()) {
        Ok(store) => store.tile_path(TileKey { col: 1, row: -2 }),
        Err(_) => return,
    };
    // The input: [meta length: u8][meta][tile length: u16 LE][tile file][state], cut short where it ends.
    let (meta_len, rest) = data.split_first().map_or((0, &[][..]), |(&n, rest)| (usize::from(n), rest));
    let (a, rest) = rest.split_at(meta_len.min(rest.len()));
    let (tile_len, rest) = if rest.len() >= 2 { (usize::from(u16::from_le_bytes([rest[0], rest[1]])), &rest[2..]) } else { (0, rest) };
    let (b, c) = rest.split_at(tile_len.min(rest.len()));
    let _ = std::fs::write(dir.join("store.meta"), a);
    let _ = std::fs::create_dir_all(tile_path.parent().expect("region folder"));
    let _ = std::fs::write(&tile_path, b);
    let _ = std::fs::write(dir.join("window.state"), c);
    if let Ok(mut store) = TileStore::open(&dir, 16, StoreConfig::default()) {
        let _ = store.read(TileKey { col: 1, row: -2 });
        let _ = store.read_state("window");
        let tile = TileData {
            key: TileKey { col: 5, row: 5 },
            side: 16,
            clock: SnowClock::default(),
            snow_xor_rest: vec![0; 256],
            stamps: vec![u32::MAX; 256],
            fallen: Vec::new(),
            packed: Vec::new(),
        };
        if store.write(&tile).is_ok() {
            assert_eq!(store.read(tile.key).expect("read back"), Some(tile));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
});
