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
//! | `world.rs` | [`WorldIdentity`]: the settings a world's machines share ([`WorldSnow`] and [`WorldTerrain`] make one without a GPU) |
//! | `message.rs` | [`Message`], [`encode`], [`decode`]: the wire format, with its caps |
//! | `press/` | [`press::PressFrame`]: a frame's analytic shapes, pressed on the CPU with the GPU capture's sweep and ray casts and the update's press, so they travel instead of the snow they pressed |
//! | `presses.rs` | the frames of a `Presses` message on the wire |
//! | `relay/` | [`SnowRelay`] (`mod.rs`): what a server runs (merges, relays, polices, persists; CPU only); beside it `peers.rs` (a peer's state), `interest.rs` (the tiles it is sent), `outbox.rs` (its queue), `bucket.rs` (the rate buckets), `admission.rs` (the checks on a world and a tile), `held.rs` (the tiles in memory), `digest.rs` (a digest against the relay's copies), `stored.rs` (a tile as the store keeps it), `config.rs`, `stats.rs` |
//! | `motion.rs` | [`motion::MotionHistory`]: where a peer's deformers were, held to a top speed, in a grid hash |
//! | `peer.rs` | [`SnowPeer`]: what a game client runs beside its [`SharedSnow`] |
//!
//! Neither side owns a socket: bytes go in through `receive` and come out
//! of `poll_transmit`, so tests run a whole network in one process.
//!
//! snowpack's `SnowDeformation` implements [`SharedSnow`] on the GPU (its
//! `replicate` module adds the window's changed-tile flags, gather and
//! merge passes); `docs/deformation.md` ("Shared snow on the GPU") gives
//! the order in the frame and the costs.

pub mod message;
pub mod motion;
pub mod peer;
pub mod press;
pub mod presses;
pub mod relay;
pub mod tile;
pub mod world;

pub use crate::error::ShareError;
pub use message::{MAX_MESSAGE_BYTES, Message, MessageError, decode, encode};
pub use peer::{PeerConfig, PeerStats, SnowPeer, SnowPeerExt};
pub use relay::{PeerId, RelayConfig, RelayRejections, RelayStats, SnowRelay};
pub use tile::{CatchUp, NO_STAMP, ShareClock, SharedTile};
pub use world::{WorldIdentity, WorldIdentityExt, WorldSettings, WorldSnow, WorldSnowfall, WorldTerrain};

/// What a [`SnowPeer`] needs of the snow it shares: the
/// window's clock and place, the tiles it changed, and a way to fold in
/// tiles from elsewhere. snowpack's `SnowDeformation` implements it on the
/// GPU; snowpack's `testing::CpuSnow` on the CPU, for tests without a device.
pub trait SharedSnow {
    /// The world clock the snow is at now.
    fn share_clock(&self) -> ShareClock;
    /// Sets the clock (on joining a world: the relay's), before the first
    /// frame or between frames; the window's fresh snow follows it.
    fn join_clock(&mut self, clock: ShareClock);
    /// The window's first texel (global texel column, row) and its
    /// resolution, once it has been placed.
    fn window(&self) -> Option<([i64; 2], u32)>;
    /// Tiles the snow changed (a press or a footprint) since the last call,
    /// as their state at the frame they were read: whole tiles on the global
    /// grid, texels outside the window untouched. Never waits for the GPU.
    fn take_changed_tiles(&mut self) -> Vec<SharedTile>;
    /// The analytic presses of the frames since the last call
    /// ([`crate::replicate::press::PressFrame`]): what a peer sends instead of the
    /// snow they pressed, where presses travel. None by default (a snow
    /// that keeps no record sends its changes as tiles alone).
    fn take_press_frames(&mut self) -> Vec<crate::replicate::press::PressFrame> {
        Vec::new()
    }
    /// Folds `tiles` into the snow where they overlap the window (the
    /// deeper deficit wins; never written over). Tiles behind the snow's
    /// clock are caught up first; tiles ahead of it are held until the clock
    /// reaches them.
    fn merge_tiles(&mut self, tiles: &[SharedTile]);
}
