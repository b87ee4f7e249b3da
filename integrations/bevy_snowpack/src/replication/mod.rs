//! Shared snow over a game's own bevy_replicon connection
//! ([`SnowReplicationPlugin`]): on the server app a `snowpack::SnowRelay`
//! on the CPU (no render plugins, no GPU), on each client a
//! `snowpack::SnowPeer` beside [`crate::SnowpackPlugin`]'s deformation in the
//! render world. The library's messages (deltas, digests, acknowledgements,
//! late-join tiles: `docs/multiplayer.md`) travel as two replicon messages,
//! [`SnowToServer`] and [`SnowToClient`], on a reliable unordered channel.
//!
//! | file | what |
//! |---|---|
//! | `server.rs` | the relay: its world and store, messages in and out, owned entities' positions reported, depth under each owned entity |
//! | `client.rs` | the peer: messages between the main world and the render world's deformation, its status |
//!
//! The world is the server's: the relay serves the world its settings name
//! ([`SnowReplicationSettings::world`], or a listen server's own snow), and
//! refuses a client of another, the first one too. Which client may change
//! the snow where follows which entities it owns on the server:
//! [`SnowOwnedBy`] names the client (replicon's `ClientId`: a connected
//! client's entity, or the listen server itself) that controls an entity,
//! and the relay lets a client write only near the server's positions of its
//! own entities (its peer's own claims are then not used).

#[cfg(feature = "multiplayer")]
mod client;
mod server;

use std::path::PathBuf;

use bevy::prelude::*;
use bevy_replicon::prelude::*;
use serde::{Deserialize, Serialize};
use snowpack_share::{PeerConfig, RelayConfig, StoreConfig, WorldIdentity};

#[cfg(feature = "multiplayer")]
pub use client::SnowSharing;
pub use server::SnowServer;

/// Shared snow over bevy_replicon: add it after `RepliconPlugins` (and, on a
/// client, after [`crate::SnowpackPlugin`]) in every app of the game, server
/// and clients alike, before the transport's channels are made (replicon
/// derives them from the registered messages).
///
/// - While replicon's `ServerState` is `Running` the app is the server: it
///   runs the relay ([`SnowServer`]) of the world its settings name
///   ([`SnowReplicationSettings::world`]), in its store if they name one,
///   and updates each [`SnowOwnedBy`] entity's [`SnowDepthUnder`]. Bevy's
///   render plugins are not needed: a server of `MinimalPlugins` and
///   `StatesPlugin` works, and creates no GPU device.
/// - While `ClientState` is `Connected` the app is a client: its snow is
///   shared (tiles of [`SnowReplicationSettings::tile_side`] texels) and
///   [`SnowSharing`] says how far it is.
/// - A server app that also has [`crate::SnowpackPlugin`] is a listen
///   server (one app hosting and playing, replicon's `ClientId::Server`):
///   its own snow is a client of its own relay, through replicon's local
///   messages, and its player's entities are `SnowOwnedBy(ClientId::Server)`.
///
/// ```no_run
/// use bevy::prelude::*;
/// use bevy::state::app::StatesPlugin;
/// use bevy_replicon::prelude::*;
/// use bevy_snowpack::prelude::*;
/// use bevy_snowpack::snowpack::SnowDeformation;
///
/// // The world every client must have: the server's own configuration.
/// let snow = SnowParams { extent_m: 12.0, resolution: 256, depth_m: 0.5, ..SnowParams::default() };
/// let world = SnowDeformation::world_identity_for(&snow, &TerrainSource::Flat { height_m: 0.0 }, SnowReplicationSettings::default().tile_side);
/// // A dedicated server: no window, no renderer; its trails kept on disk.
/// App::new()
///     .add_plugins((MinimalPlugins, StatesPlugin, RepliconPlugins))
///     .add_plugins(SnowReplicationPlugin::new(SnowReplicationSettings {
///         world: Some(world),
///         store: Some(SnowRelayStore::new("world/")),
///         ..default()
///     }))
///     // ... the transport (bevy_replicon_renet2's plugins and its server resources)
///     .run();
/// ```
#[derive(Default)]
pub struct SnowReplicationPlugin {
    /// The settings it starts with (a resource: change it at run time).
    pub settings: SnowReplicationSettings,
}

impl SnowReplicationPlugin {
    /// The plugin with these settings.
    #[must_use]
    pub fn new(settings: SnowReplicationSettings) -> Self {
        Self { settings }
    }
}

impl Plugin for SnowReplicationPlugin {
    fn build(&self, app: &mut App) {
        app.insert_resource(self.settings.clone())
            // Reliable, unordered: tiles merge in any order, so nothing waits behind a lost packet.
            .add_client_message::<SnowToServer>(Channel::Unordered)
            .add_server_message::<SnowToClient>(Channel::Unordered)
            // They name no entity, so they need not wait for the replication of one.
            .make_message_independent::<SnowToClient>();
        server::build(app);
        #[cfg(feature = "multiplayer")]
        client::build(app);
    }
}

/// What the shared snow is made of (a resource, the same on the server and
/// the clients). Applied when changed: `peer` (clients) and `relay` (the
/// server). Fixed when a client first joins: `tile_side`, `gather_interval_s`
/// and `peer_name` (a change warns and is ignored until the app restarts).
/// Read when the server starts its relay (`ServerState` becomes `Running`):
/// `world` and `store` (a change while it runs warns and waits for the next
/// start).
#[derive(Resource, Clone, Debug, PartialEq)]
pub struct SnowReplicationSettings {
    /// Side of a shared tile (texels, 8..=256). Every client of a world must
    /// use the same side (the relay refuses another, naming it).
    pub tile_side: u32,
    /// A changed tile is gathered at most this often (s of the snow's time).
    pub gather_interval_s: f64,
    /// How a client's peer paces itself (presence, digests, deltas, resends).
    pub peer: PeerConfig,
    /// How the server's relay paces and polices its clients (the radius
    /// around their entities they may write in, byte and tile rates).
    pub relay: RelayConfig,
    /// The client's name in the relay's logs.
    pub peer_name: String,
    /// On the server: the world it serves, from its own configuration
    /// (`SnowDeformation::world_identity_for` of the snow its clients run, with
    /// `tile_side`). A client of another world is refused naming what
    /// differs, the first one too; a client never chooses the world. `None`:
    /// a listen server serves its own snow's world; a dedicated server
    /// serves nobody until it is set (it warns).
    pub world: Option<WorldIdentity>,
    /// On the server: where the relay keeps its tiles (and the world and its
    /// clock), so a restarted server, or a player joining an empty one,
    /// still sees every trail. `None`: in memory, for the server's life.
    pub store: Option<SnowRelayStore>,
}

impl Default for SnowReplicationSettings {
    fn default() -> Self {
        Self {
            tile_side: 32,
            gather_interval_s: 0.25,
            peer: PeerConfig::default(),
            relay: RelayConfig::default(),
            peer_name: "bevy_snowpack".into(),
            world: None,
            store: None,
        }
    }
}

/// The server relay's tile store (`snowpack::TileStore`, the format
/// `snowpack server --store` keeps: either can serve the other's folder).
#[derive(Clone, Debug, PartialEq)]
pub struct SnowRelayStore {
    /// The store's folder (created when missing; one server at a time, and
    /// not a folder the snow's own [`crate::SnowStoreSettings`] uses: the
    /// relay's tiles hold deficits, not heights).
    pub dir: PathBuf,
    /// Its disk budget.
    pub config: StoreConfig,
}

impl SnowRelayStore {
    /// A store in `dir` with the library's default budget.
    #[must_use]
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self { dir: dir.into(), config: StoreConfig::default() }
    }
}

/// A shared-snow message from a client to the server (its peer's `Hello`,
/// `Presence`, `Tiles` deltas, `Digest`): the library's wire bytes.
#[derive(Message, Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
pub struct SnowToServer(pub Vec<u8>);

/// A shared-snow message from the server to one client (`Welcome`, `Ack`,
/// merged `Tiles`, `Want`, `Clock`, `InSync`): the library's wire bytes.
#[derive(Message, Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
pub struct SnowToClient(pub Vec<u8>);

/// On the server: the client that controls this entity (replicon's
/// `ClientId`: `ClientId::Client` of a connected client's entity, the one
/// with `ConnectedClient`, or `ClientId::Server` for a listen server's own
/// player). The relay lets that client change the snow only near its
/// entities, placed by their `Transform` (root entities: a server without
/// `TransformPlugin` has no `GlobalTransform`), and [`SnowDepthUnder`] is
/// kept up to date on them.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
#[require(SnowDepthUnder)]
pub struct SnowOwnedBy(pub ClientId);

/// On the server: the snow depth (m) under an entity with [`SnowOwnedBy`],
/// from the relay's merged tiles on the CPU (the answer a client's
/// [`crate::SnowQuery`] gives there once it holds the same tiles). Updated in
/// [`SnowReplicationSystems::Relay`], before `Update`: gameplay there slows a
/// player in deep snow with it. `None` until the relay runs (it starts once
/// the server knows its world).
#[derive(Component, Clone, Copy, Debug, Default, PartialEq)]
pub struct SnowDepthUnder {
    /// Snow depth (m) at the entity's x, z.
    pub depth_m: Option<f32>,
}

/// The shared snow's systems; order a game's own around them.
///
/// Server (while `ServerState` is `Running`):
/// - [`Self::Relay`] (`PreUpdate`, after replicon's `ServerSystems::Receive`):
///   the relay started (once the world is known), messages received, the
///   owners' positions reported, the relay updated (and its changed tiles
///   written to its store before anything is sent), its messages written,
///   [`SnowDepthUnder`] updated.
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
