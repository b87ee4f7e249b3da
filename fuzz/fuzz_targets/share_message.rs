//! Any bytes as a sharing message: a message (which encodes back to a
//! decodable message of the same kind) or a typed error, and fed to a relay
//! (with a welcomed peer, so every kind's handling is reached) and to a
//! peer, neither of which may panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use snowpack::low_level::replicate::{Message, decode, encode};
use snowpack::low_level::{WorldIdentityExt, WorldSettings};
use snowpack::{PeerConfig, RelayConfig, SnowPeer, SnowRelay, WorldIdentity};

fn world() -> WorldIdentity {
    WorldIdentity::from_settings(WorldSettings {
        texel_m: 0.125,
        tile_side: 16,
        terrain: "flat at 0 m".to_owned(),
        depth_m: 0.5,
        refill_m_per_s: 0.0005,
        snowfall_m_per_s: 0.0,
        max_fallen_m: 0.0,
        has_snowfall: false,
        stamp_range_m: [-1.0, 1.0],
    })
}

fuzz_target!(|data: &[u8]| {
    if let Ok(message) = decode(data) {
        let again = decode(&encode(&message)).expect("a decoded message encodes to a decodable one");
        assert_eq!(again.kind(), message.kind());
    }
    let mut relay = SnowRelay::new(RelayConfig::default());
    relay.connect(1);
    relay.receive(1, &encode(&Message::Hello { world: world(), name: "fuzz".to_owned(), presses: true }), 0.0);
    relay.receive(1, &encode(&Message::Presence { window: [-64, -64], resolution: 128, deformers: vec![[0.0, 0.0]] }), 0.0);
    relay.receive(1, data, 1.0);
    relay.update(1.5);
    while relay.poll_transmit().is_some() {}
    let _ = relay.depth_at(0.0, 0.0);
    let mut peer = SnowPeer::new(world(), "fuzz", PeerConfig::default());
    let _ = peer.receive(data);
});
