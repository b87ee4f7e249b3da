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
//! | `tile.rs` | [`SharedTile`], [`ShareClock`]: a tile's state and clock, catching up and merging |
//! | `world.rs` | [`WorldIdentity`]: the settings a world's machines share |

pub mod tile;
pub mod world;

pub use tile::{CatchUp, NO_STAMP, ShareClock, SharedTile};
pub use world::{WorldIdentity, terrain_identity};
