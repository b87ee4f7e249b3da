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
//! | `settings.rs` | [`SnowReplicationSettings`] and the relay's store |
//! | `messages.rs` | the two replicon messages |
//! | `owners.rs` | [`SnowOwnedBy`] and [`SnowDepthUnder`] |
//! | `systems.rs` | [`SnowReplicationSystems`] |
//!
//! `mod.rs` holds the plugin and re-exports the rest; the files below it
//! never name it (`crates/snowpack/tests/layering.rs`: no file circles).
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
mod messages;
mod owners;
mod server;
mod settings;
mod systems;

use bevy::prelude::*;
use bevy_replicon::prelude::*;

#[cfg(feature = "multiplayer")]
pub use client::SnowSharing;
pub use messages::{SnowToClient, SnowToServer};
pub use owners::{SnowDepthUnder, SnowOwnedBy};
pub use server::SnowServer;
pub use settings::{SnowRelayStore, SnowReplicationSettings};
pub use systems::SnowReplicationSystems;

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
