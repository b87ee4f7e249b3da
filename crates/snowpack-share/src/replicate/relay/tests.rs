//! The relay's tests: stored tiles, threads, a pinned world and the epoch.

use super::*;
use crate::persist::{StoreError, TileData};
use crate::replicate::world::WorldSettings;

#[test]
fn stored_tiles_come_back_bit_for_bit() {
    let key = TileKey::new(-2, 5);
    let clock = ShareClock { time_s: 3.5, refill_quanta: 123_456, stamp_quanta: 77, fallen_m: 0.015_625 };
    for (stamps, fallen) in [(false, false), (true, false), (false, true), (true, true)] {
        let mut t = SharedTile::untouched(key, 8, clock, stamps, fallen);
        t.deficit[3] = 65_535;
        t.deficit[9] = 17;
        if stamps {
            t.stamps[4] = 0x0102_0304;
        }
        if fallen {
            t.fallen[5] = 0.25;
            t.packed = vec![0; t.texels()];
            t.packed[9] = 40_000;
        }
        let back = tile_from_data(tile_to_data(&t)).expect("round trip");
        assert_eq!(back, t);
        assert_eq!(back.digest(), t.digest());
    }
}

/// A server moves its relay to a thread of its own.
#[test]
fn a_relay_and_a_peer_can_move_between_threads() {
    fn send<T: Send>() {}
    send::<SnowRelay>();
    send::<super::super::SnowPeer>();
}

#[test]
fn data_no_relay_wrote_is_corrupt() {
    let t = SharedTile::untouched(TileKey::new(0, 0), 8, ShareClock::default(), false, false);
    let why = |d: TileData| match tile_from_data(d) {
        Err(StoreError::Corrupt { why, .. }) => why,
        other => panic!("expected Corrupt, got {other:?}"),
    };
    let mut half = tile_to_data(&t);
    half.clock.refill_m = 0.5;
    assert!(why(half).contains("whole number"));
    let mut mixed = tile_to_data(&t);
    mixed.snow_xor_rest[3] = 7;
    assert!(why(mixed).contains("differ"));
    let mut flags = tile_to_data(&t);
    flags.snow_xor_rest[0] |= 1 << 20;
    assert!(why(flags).contains("flags"));
}

fn pinned_world() -> WorldIdentity {
    WorldIdentity::from_settings(WorldSettings {
        texel_m: 0.0625,
        tile_side: 32,
        terrain: "flat at 0 m".to_owned(),
        depth_m: 0.5,
        refill_m_per_s: 0.0,
        snowfall_m_per_s: 0.0,
        max_fallen_m: 0.0,
        has_snowfall: false,
        stamp_range_m: [-1.0, 3.0],
    })
}

/// A pinned world: the first peer of another is refused, and the world stays.
#[test]
fn a_pinned_world_is_never_a_peers() {
    let w = pinned_world();
    let mut relay = SnowRelay::new(RelayConfig::default());
    relay.pin_world(w.clone()).expect("pinned");
    relay.connect(1);
    let other = WorldIdentity::from_settings(WorldSettings { depth_m: 0.8, ..w.settings.clone() });
    relay.receive(1, &encode(&Message::Hello { world: other, name: "first".to_owned(), presses: true }), 0.0);
    let (_, answer) = relay.poll_transmit().expect("an answer");
    match decode(&answer) {
        Ok(Message::Refused { differences }) => assert_eq!(differences, ["snow depth (m): 0.8 here, 0.5 there"]),
        other => panic!("not refused: {other:?}"),
    }
    assert_eq!(relay.world(), Some(&w));
    assert_eq!(relay.stats().rejected.refused, 1);
}

/// A store keeps its world: pinning another is an error naming each difference.
#[test]
fn pinning_another_world_than_the_stores_fails() {
    let dir = std::env::temp_dir().join(format!("snowpack-relay-pin-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let w = pinned_world();
    {
        let store = TileStore::open(&dir, 32, crate::persist::StoreConfig::default()).expect("store");
        let mut relay = SnowRelay::with_store(store, RelayConfig::default()).expect("relay");
        relay.pin_world(w.clone()).expect("a fresh store takes the world");
    }
    let store = TileStore::open(&dir, 32, crate::persist::StoreConfig::default()).expect("store");
    let mut relay = SnowRelay::with_store(store, RelayConfig::default()).expect("relay");
    assert_eq!(relay.world(), Some(&w));
    match relay.pin_world(WorldIdentity::from_settings(WorldSettings { depth_m: 0.8, ..w.settings.clone() })).map_err(crate::error::ShareError::from) {
        Err(ShareError::StoreWorld(why)) => assert_eq!(why, "snow depth (m): 0.5 here, 0.8 there"),
        other => panic!("not refused: {other:?}"),
    }
    relay.pin_world(w).expect("the same world");
    drop(relay);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The world's epoch is written once and read back after a restart.
#[test]
fn the_world_epoch_is_kept_in_the_store() {
    let dir = std::env::temp_dir().join(format!("snowpack-relay-epoch-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let open =
        || SnowRelay::with_store(TileStore::open(&dir, 32, crate::persist::StoreConfig::default()).expect("store"), RelayConfig::default()).expect("relay");
    assert_eq!(SnowRelay::new(RelayConfig::default()).world_epoch(7.0).expect("no store"), 7.0);
    assert_eq!(open().world_epoch(100.0).expect("epoch"), 100.0);
    assert_eq!(open().world_epoch(250.0).expect("epoch"), 100.0, "the epoch was not kept");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A world pinned holding its heightmap keeps it in the store: a relay
/// opened on the store (a server without the scene's file) presses there,
/// and says so in its `Welcome`; a damaged or foreign saved heightmap is
/// an error naming it.
#[test]
fn a_pinned_heightmap_is_kept_in_the_store_and_pressed_over_after_a_restart() {
    use crate::replicate::press::ground::HeightGrid;
    use crate::replicate::world::{WorldSnow, WorldTerrain};
    use std::sync::Arc;
    let dir = std::env::temp_dir().join(format!("snowpack-relay-ground-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let heights: Vec<f32> = (0..12).map(|k| k as f32 * 0.01).collect();
    let grid = Arc::new(HeightGrid::new(4, 3, heights, [0.5, -1.0], [8.0, 6.0]).expect("a grid"));
    assert_eq!(HeightGrid::from_bytes(&grid.to_bytes()).as_ref(), Ok(&*grid));
    let snow = WorldSnow { texel_m: 0.0625, depth_m: 0.5, refill_m_per_s: 0.0, snowfall: None, displace: false };
    let w = WorldIdentity::new(&snow, &WorldTerrain::heightmap(Arc::clone(&grid)), 32);
    let open = || TileStore::open(&dir, 32, crate::persist::StoreConfig::default()).expect("store");
    SnowRelay::with_store(open(), RelayConfig::default()).expect("relay").pin_world(w.clone()).expect("a fresh store takes the world");
    let mut relay = SnowRelay::with_store(open(), RelayConfig::default()).expect("the store's world and heightmap");
    assert!(crate::replicate::press::press_ground(relay.world().expect("the saved world")).is_some(), "the relay holds the heightmap");
    relay.connect(1);
    relay.receive(1, &encode(&Message::Hello { world: WorldIdentity::from_settings(w.settings.clone()), name: "p".to_owned(), presses: false }), 0.0);
    let (_, answer) = relay.poll_transmit().expect("an answer");
    assert!(matches!(decode(&answer), Ok(Message::Welcome { presses: true, .. })), "{:?}", decode(&answer));
    drop(relay);
    // Damaged, or another heightmap than the world's.
    let mut cut = grid.to_bytes();
    cut.pop();
    let other = HeightGrid::new(1, 1, vec![0.0], [0.0; 2], [1.0; 2]).expect("a grid");
    for (bytes, says) in [(cut, "does not decode"), (other.to_bytes(), "the saved world's terrain")] {
        open().write_state(GROUND_STATE, &bytes).expect("write");
        match SnowRelay::with_store(open(), RelayConfig::default()).map_err(crate::error::ShareError::from) {
            Err(ShareError::StoreWorld(why)) => assert!(why.contains(says), "{why}"),
            other => panic!("not refused: {:?}", other.map(|r| r.world().cloned())),
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
