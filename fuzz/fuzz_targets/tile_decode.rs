//! Any bytes as a tile file: a valid tile (which encodes back to a tile
//! with the same bits) or a typed error, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use snowpack::low_level::persist::{decode, encode};

fuzz_target!(|data: &[u8]| {
    if let Ok(tile) = decode(data) {
        assert!(tile.validate().is_ok(), "decode accepted an inconsistent tile");
        let again = decode(&encode(&tile)).expect("a decoded tile encodes to a decodable one");
        assert_eq!(encode(&again), encode(&tile));
    }
});
