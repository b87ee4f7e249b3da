//! What server and clients share: the game's replicated types and messages,
//! in the order both register them, and the snow world they agree on.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use bevy::prelude::*;
use bevy_replicon::prelude::*;
use bevy_snowpack::prelude::*;
use bevy_snowpack::snowpack_share::replicate::{WorldIdentity, WorldSnow, WorldTerrain};
use serde::{Deserialize, Serialize};

/// Netcode's protocol id: this example's, so nothing else connects by mistake.
pub const PROTOCOL_ID: u64 = 0x736e_6f77_6d70_0002;
/// Snow depth (m) on flat ground.
pub const DEPTH_M: f32 = 0.5;
/// The snow window's side (m) around the origin: the whole walk, and a margin of open snow.
pub const EXTENT_M: f32 = 12.0;
/// The snow window's texels a side (4.7 cm texels).
pub const RESOLUTION: u32 = 256;
/// The fox wades: its soles this high (m) over the ground, its legs and belly ploughing the snow.
pub const FOX_SOLE_M: f32 = 0.02;
/// The fastest the server moves a player (m/s); a client asks for no more a frame.
pub const MAX_SPEED_M_PER_S: f32 = 1.5;
/// Where a player spawns and a walk starts (x, m), along z = 0.
pub const WALK_FROM_M: f32 = -4.0;
/// The listen server's own player id (clients' ids are netcode's, never 0 here).
#[cfg(feature = "client")]
pub const HOST_ID: u64 = 0;

/// A player, replicated to every client: whose it is (netcode's client id,
/// [`HOST_ID`] for a listen server's own) and whether it is walking. Where
/// it is comes with its replicated `Transform`.
#[derive(Component, Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Player {
    pub id: u64,
    pub moving: bool,
}

/// A `Transform` on the wire (position and heading; players are not scaled).
#[derive(Serialize, Deserialize, Clone, Copy, Debug)]
pub struct NetTransform {
    translation: [f32; 3],
    rotation: [f32; 4],
}

impl From<Transform> for NetTransform {
    fn from(t: Transform) -> Self {
        Self { translation: t.translation.to_array(), rotation: t.rotation.to_array() }
    }
}

impl From<NetTransform> for Transform {
    fn from(t: NetTransform) -> Self {
        Self::from_translation(Vec3::from_array(t.translation)).with_rotation(Quat::from_array(t.rotation).normalize())
    }
}

/// A client's input (client → server): walk up to `distance_m` that way
/// (x, z). The server decides where that takes the player (at most
/// [`MAX_SPEED_M_PER_S`]); a client never says where its player is.
#[derive(Message, Serialize, Deserialize, Clone, Copy, Debug)]
pub struct MoveRequest {
    pub direction: [f32; 2],
    pub distance_m: f32,
}

/// What server and clients register, in the same order (replicon checks it).
pub struct GameProtocol(pub SnowReplicationSettings);

impl Plugin for GameProtocol {
    fn build(&self, app: &mut App) {
        app.add_plugins(SnowReplicationPlugin::new(self.0.clone()))
            .replicate::<Player>()
            .replicate_as::<Transform, NetTransform>()
            .add_client_message::<MoveRequest>(Channel::Ordered);
    }
}

/// Seconds since the Unix epoch (netcode's clock).
pub fn unix_now() -> Duration {
    SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default()
}

/// The world the server serves and every client's snow is (its snow,
/// `client::snow_settings`, is checked against it): 0.5 m of snow on flat
/// ground, 4.7 cm texels, shared in the default tiles. Found without a GPU.
pub fn world() -> WorldIdentity {
    let snow = WorldSnow { texel_m: EXTENT_M / RESOLUTION as f32, depth_m: DEPTH_M, refill_m_per_s: 0.0, snowfall: None, displace: false };
    WorldIdentity::new(&snow, &WorldTerrain::flat(0.0), SnowReplicationSettings::default().tile_side)
}
