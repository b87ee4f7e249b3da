//! The server's side: a `SnowRelay` on the CPU fed by replicon's client
//! messages. It serves the world the server's settings name (or a listen
//! server's own snow), keeps its tiles in a store when the settings name
//! one, and starts once that world is known. Each authorized client is a
//! relay peer (its client entity's bits are the peer id; a listen server's
//! own snow is [`LOCAL_PEER`]), the positions of the entities it owns
//! ([`SnowOwnedBy`]) are reported as where it may write, and the relay's
//! messages go back to their client alone.
//!
//! Only the relay, its store and its messages are used here, and Bevy's
//! non-render crates: a dedicated server compiles no renderer for it.

use std::collections::HashMap;
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use bevy::prelude::*;
use bevy_replicon::prelude::*;
use snowpack_share::{PeerId, ShareError, SnowRelay, TileStore, WorldIdentity};

#[cfg(feature = "multiplayer")]
use super::SnowSharing;
use super::{SnowDepthUnder, SnowOwnedBy, SnowReplicationSettings, SnowReplicationSystems, SnowToClient, SnowToServer};

/// The relay's peer id of a listen server's own snow (`ClientId::Server`).
/// No client entity has these bits: an entity's index is never `u32::MAX`.
const LOCAL_PEER: PeerId = u64::MAX;

/// How often a failing store is said again.
const STORE_ERROR_EVERY: Duration = Duration::from_secs(10);

/// The server's relay (a resource on the server app while it serves: made
/// when `ServerState` is `Running` and the world is known, dropped when it
/// stops). Its clock is the world's: seconds since the world began, kept in
/// its store across restarts. An app may insert its own
/// ([`SnowServer::open`]) to handle a bad store itself; the plugin then
/// uses that one.
#[derive(Resource)]
pub struct SnowServer {
    /// Behind a mutex because resources are `Sync` and the relay is only
    /// `Send` (it reads its store through a cell); the plugin's systems
    /// reach it through `get_mut`, without locking.
    relay: Mutex<SnowRelay>,
    /// When the world began (Unix seconds).
    epoch_unix_s: f64,
    /// Whether the relay keeps a store (then it is flushed before each send).
    stored: bool,
    /// When a store failure was last said.
    store_error_said: Option<Instant>,
}

impl SnowServer {
    /// A relay of `world` with `settings.relay`, keeping its tiles in
    /// `settings.store` when set (opened or created; a store of another
    /// world or tile side is an error naming what differs, as is one another
    /// server holds). Its clock goes on from the store's epoch.
    pub fn open(world: WorldIdentity, settings: &SnowReplicationSettings) -> Result<Self, ShareError> {
        let mut relay = match &settings.store {
            Some(store) => {
                let tiles =
                    TileStore::open(&store.dir, settings.tile_side, store.config).map_err(|e| ShareError::from(snowpack_share::error::StoreError::from(e)))?;
                SnowRelay::with_store(tiles, settings.relay.clone())?
            }
            None => SnowRelay::new(settings.relay.clone()),
        };
        relay.pin_world(world)?;
        let epoch_unix_s = relay.world_epoch(unix_now_s())?;
        Ok(Self { relay: Mutex::new(relay), epoch_unix_s, stored: settings.store.is_some(), store_error_said: None })
    }

    /// The relay (its stats, tiles, clock), locked while the guard lives.
    pub fn relay(&self) -> MutexGuard<'_, SnowRelay> {
        self.relay.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// The relay, to feed it more than the plugin does.
    pub fn relay_mut(&mut self) -> &mut SnowRelay {
        self.relay.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// World time now (s since the world began).
    #[must_use]
    pub fn world_s(&self) -> f64 {
        unix_now_s() - self.epoch_unix_s
    }

    /// The world it serves.
    #[must_use]
    pub fn world(&self) -> Option<WorldIdentity> {
        self.relay().world().cloned()
    }

    /// Snow depth (m) at world (x, z) from the merged tiles (and the store).
    #[must_use]
    pub fn depth_at(&self, x_m: f32, z_m: f32) -> Option<f32> {
        self.relay().depth_at(f64::from(x_m), f64::from(z_m))
    }
}

fn unix_now_s() -> f64 {
    SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default().as_secs_f64()
}

/// The relay's peer id of a client.
fn peer_of(client: ClientId) -> PeerId {
    match client {
        ClientId::Client(entity) => entity.to_bits(),
        ClientId::Server => LOCAL_PEER,
    }
}

/// The client of a relay peer id; `None` for one no client has.
fn client_of(peer: PeerId) -> Option<ClientId> {
    if peer == LOCAL_PEER { Some(ClientId::Server) } else { Entity::try_from_bits(peer).map(ClientId::Client) }
}

pub(super) fn build(app: &mut App) {
    app.add_observer(connect)
        .add_observer(disconnect)
        .add_systems(OnExit(ServerState::Running), stop)
        .configure_sets(PreUpdate, SnowReplicationSystems::Relay.after(ServerSystems::Receive).run_if(in_state(ServerState::Running)))
        .add_systems(
            PreUpdate,
            (
                start.run_if(not(resource_exists::<SnowServer>)),
                (apply_settings, receive, report_owners, update, depths).chain().run_if(resource_exists::<SnowServer>),
            )
                .chain()
                .in_set(SnowReplicationSystems::Relay),
        );
}

/// What [`start`] said last, so a waiting or failing server says it once.
#[derive(Default)]
struct StartState {
    said: Option<String>,
}

/// Makes the relay once the world is known: the settings' world, or on a
/// listen server its own snow's. Authorized clients join it.
fn start(
    mut commands: Commands,
    settings: Res<SnowReplicationSettings>,
    #[cfg(feature = "multiplayer")] sharing: Option<Res<SnowSharing>>,
    clients: Query<Entity, With<AuthorizedClient>>,
    mut state: Local<StartState>,
) {
    // A listen server's own snow (a build with the client half) says its world.
    #[cfg(feature = "multiplayer")]
    let (local, local_snow) = (sharing.as_deref().and_then(SnowSharing::world).cloned(), sharing.as_ref().is_some_and(|s| s.local_snow));
    #[cfg(not(feature = "multiplayer"))]
    let (local, local_snow): (Option<WorldIdentity>, bool) = (None, false);
    let Some(world) = settings.world.clone().or(local) else {
        if local_snow {
            // A listen server: its snow says its world within a frame or two.
            return;
        }
        let why = "bevy_snowpack: the server serves no snow yet: set SnowReplicationSettings::world (a listen server takes its own snow's)".to_owned();
        if state.said.as_ref() != Some(&why) {
            tracing::warn!("{why}");
            state.said = Some(why);
        }
        return;
    };
    match SnowServer::open(world, &settings) {
        Ok(mut server) => {
            let relay = server.relay_mut();
            for client in &clients {
                relay.connect(peer_of(ClientId::Client(client)));
            }
            tracing::info!(
                "bevy_snowpack: the relay serves its world{}",
                settings.store.as_ref().map_or(String::new(), |s| format!(", tiles in {}", s.dir.display()))
            );
            commands.insert_resource(server);
            state.said = None;
        }
        Err(e) => {
            let why = format!("bevy_snowpack: the relay cannot start: {e}");
            if state.said.as_ref() != Some(&why) {
                tracing::error!("{why}");
                state.said = Some(why);
            }
        }
    }
}

/// The relay stops with the server; what it changed is written first.
fn stop(mut commands: Commands, server: Option<ResMut<SnowServer>>) {
    if let Some(mut server) = server {
        if let Err(e) = server.relay_mut().flush() {
            tracing::error!("bevy_snowpack: the relay's store failed as the server stopped: {e}");
        }
        commands.remove_resource::<SnowServer>();
    }
}

/// A client joins the relay once replicon has authorized it (its messages
/// are accepted from then on).
fn connect(add: On<Add<AuthorizedClient>>, server: Option<ResMut<SnowServer>>) {
    if let Some(mut server) = server {
        server.relay_mut().connect(peer_of(ClientId::Client(add.entity)));
    }
}

fn disconnect(remove: On<Remove<ConnectedClient>>, server: Option<ResMut<SnowServer>>) {
    if let Some(mut server) = server {
        server.relay_mut().disconnect(peer_of(ClientId::Client(remove.entity)));
    }
}

fn apply_settings(settings: Res<SnowReplicationSettings>, mut server: ResMut<SnowServer>) {
    if !settings.is_changed() {
        return;
    }
    let stored = server.stored;
    let serving = server.world();
    let relay = server.relay_mut();
    if *relay.config() != settings.relay {
        relay.set_config(settings.relay.clone());
    }
    if settings.world.is_some() && settings.world != serving {
        tracing::warn!("bevy_snowpack: SnowReplicationSettings::world changed while the relay runs; it serves its world until the server restarts");
    }
    if settings.store.is_some() != stored {
        tracing::warn!("bevy_snowpack: SnowReplicationSettings::store changed while the relay runs; the change waits for the server to restart");
    }
}

fn receive(mut server: ResMut<SnowServer>, mut messages: MessageReader<FromClient<SnowToServer>>) {
    let now = server.world_s();
    let relay = server.relay_mut();
    for m in messages.read() {
        if m.client_id == ClientId::Server {
            // A listen server's own snow: a peer from its first message (connecting twice changes nothing).
            relay.connect(LOCAL_PEER);
        }
        relay.receive(peer_of(m.client_id), &m.message.0, now);
    }
}

/// Every authorized client's owned entities (and a listen server's own) are
/// where it may write; a client owning none may write nowhere (its own
/// claims do not count).
fn report_owners(mut server: ResMut<SnowServer>, clients: Query<Entity, With<AuthorizedClient>>, owned: Query<(&SnowOwnedBy, &Transform)>) {
    let mut at: HashMap<ClientId, Vec<[f64; 2]>> = clients.iter().map(|c| (ClientId::Client(c), Vec::new())).collect();
    at.entry(ClientId::Server).or_default();
    for (owner, t) in &owned {
        // An owner the relay does not know is reported to nobody (the relay ignores it).
        at.entry(owner.0).or_default().push([f64::from(t.translation.x), f64::from(t.translation.z)]);
    }
    let relay = server.relay_mut();
    for (client, positions) in &at {
        relay.report_deformers(peer_of(*client), positions);
    }
}

/// The relay's step; with a store, every changed tile is written before
/// anything (acknowledgements included) goes out, so what a client was
/// told is kept survives the server being killed.
fn update(mut server: ResMut<SnowServer>, mut out: MessageWriter<ToClients<SnowToClient>>) {
    let now = server.world_s();
    let stored = server.stored;
    let relay = server.relay_mut();
    relay.update(now);
    let flushed = if stored { relay.flush() } else { Ok(()) };
    while let Some((peer, bytes)) = relay.poll_transmit() {
        let Some(client) = client_of(peer) else { continue };
        out.write(ToClients { targets: SendTargets::Single(client), message: SnowToClient(bytes) });
    }
    if let Err(e) = flushed
        && server.store_error_said.is_none_or(|t| t.elapsed() >= STORE_ERROR_EVERY)
    {
        server.store_error_said = Some(Instant::now());
        tracing::error!("bevy_snowpack: the relay's store failed; tiles are kept in memory until it works again: {e}");
    }
}

fn depths(mut server: ResMut<SnowServer>, mut owned: Query<(&Transform, &mut SnowDepthUnder), With<SnowOwnedBy>>) {
    let relay = server.relay_mut();
    for (t, mut under) in &mut owned {
        let depth_m = relay.depth_at(f64::from(t.translation.x), f64::from(t.translation.z));
        // Written only when it changes, so `Changed<SnowDepthUnder>` means a change.
        under.set_if_neq(SnowDepthUnder { depth_m });
    }
}
