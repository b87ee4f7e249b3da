//! The shared snow's system sets, [`SnowReplicationSystems`].

use bevy::prelude::*;

/// The shared snow's systems; order a game's own around them.
///
/// Server (while `ServerState` is `Running`):
/// - [`Self::Relay`] (`PreUpdate`, after replicon's `ServerSystems::Receive`):
///   the relay started (once the world is known), messages received, the
///   owners' positions reported, the relay updated (and its changed tiles
///   written to its store before anything is sent), its messages written,
///   [`SnowDepthUnder`](crate::SnowDepthUnder) updated.
///
/// Client (while `ClientState` is `Connected`, or on a listen server while
/// `ServerState` is `Running`):
/// - [`Self::Receive`] (`PreUpdate`, after replicon's `ClientSystems::Receive`):
///   messages from the server queued for the render world, the peer's last
///   status and messages received from it.
/// - [`Self::Send`] (`PostUpdate`, before replicon's `ClientSystems::Send`):
///   the peer's messages written.
/// - [`Self::Peer`] (render world, `RenderGraph`, after
///   [`crate::SnowSystems::Encode`]): the peer takes the frame's changed
///   tiles, merges what arrived and makes its messages.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SnowReplicationSystems {
    /// The server's relay (main world, `PreUpdate`).
    Relay,
    /// What arrived reaches the client's peer and back (main world, `PreUpdate`).
    Receive,
    /// The client's messages go out (main world, `PostUpdate`).
    Send,
    /// The client's peer steps beside the deformation (render world, `RenderGraph`).
    Peer,
}
