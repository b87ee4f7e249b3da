//! Shared snow: one world's trails on every player's machine.
//!
//! The persistent snow is a deficit below the rest height, and every step of
//! the simulation is monotone in it, so copies of a tile brought to the same
//! world clock merge by the texel-wise maximum deficit ([`SharedTile::merge`]):
//! peers may receive tiles in any order, twice, late or after a partition,
//! and still end bit for bit equal. `docs/multiplayer.md` explains the
//! design.
//!
//! | file | what |
//! |---|---|
//! | `tile`, `world`, `message`, `relay`, `motion`, `peer` | the shared-snow crate's (`snowpack_share::replicate`, no GPU), re-exported here: [`SharedTile`] and [`ShareClock`], [`WorldIdentity`], the wire format ([`Message`], [`encode`], [`decode`]), [`SnowRelay`] (what a server runs, holding each peer's deformers to a top speed in `motion`'s grid hash), [`SnowPeer`] (what a game client runs beside its [`SharedSnow`]) |
//! | this file | [`terrain_identity`]: a terrain as a world's identity names it |
//! | `flags.rs` | [`flags::ShareGrid`]: the changed-tile flags the stamp and update passes write, and their keys |
//! | `gather.rs` | [`gather::TileGatherPass`] (`tile_gather.wgsl`): whole tiles copied out of the window |
//! | `merge.rs` | [`merge::TileMergePass`] (`tile_merge.wgsl`): tiles from elsewhere folded into the window |
//! | `sharing.rs` | `Sharing` (crate-private): a window's flags, gathers, merges and their readbacks |
//!
//! Neither side owns a socket: bytes go in through `receive` and come out
//! of `poll_transmit`, so tests run a whole network in one process.
//!
//! [`crate::SnowDeformation`] implements [`SharedSnow`] with them
//! (`snow/share.rs`); `docs/deformation.md` ("Shared snow on the GPU")
//! gives the order in the frame and the costs.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

pub mod flags;
pub mod gather;
pub mod merge;
pub(crate) mod sharing;
pub use snowpack_share::replicate::{message, peer, relay, tile, world};

use crate::TerrainSource;
pub use crate::error::ShareError;
use crate::terrain::HeightmapTerrainExt;
pub use message::{Message, decode, encode};
pub use peer::{PeerConfig, PeerStats, SnowPeer};
pub use relay::{PeerId, RelayConfig, RelayStats, SnowRelay};
pub use snowpack_share::replicate::SharedSnow;
pub use tile::{CatchUp, NO_STAMP, ShareClock, SharedTile};
pub use world::WorldIdentity;

/// A short description of `terrain` that two machines with the same
/// terrain agree on: its kind and parameters, and for sampled terrains an
/// FNV-1a digest of the heights. [`WorldIdentity`]'s terrain is this
/// (here rather than beside it: the shared-snow crate knows no terrain).
#[must_use]
pub fn terrain_identity(terrain: &TerrainSource) -> String {
    match terrain {
        TerrainSource::Flat { height_m } => format!("flat at {height_m} m"),
        TerrainSource::Noise(n) => {
            format!("noise seed {} base {} m amplitude {} m wavelength {} m", n.seed, n.base_m, n.amplitude_m, n.wavelength_m)
        }
        TerrainSource::Heightmap(h) => h.shared_grid().terrain_identity(),
        TerrainSource::Mesh(m) => format!("mesh of {} triangles {:016x}", m.triangles.len(), m.grid.digest()),
    }
}
