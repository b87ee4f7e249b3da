//! The server's side: a `SnowRelay` on the CPU fed by replicon's client
//! messages. Each authorized client is a relay peer (its client entity's
//! bits are the peer id), the positions of the entities it owns
//! ([`SnowOwnedBy`]) are reported as where it may write, and the relay's
//! messages go back to their client alone.

use std::sync::{Mutex, MutexGuard};
use std::time::Instant;

use bevy::prelude::*;
use bevy_replicon::prelude::*;
use snowpack_share::{PeerId, SnowRelay};

use super::{SnowDepthUnder, SnowOwnedBy, SnowReplicationSettings, SnowReplicationSystems, SnowToClient, SnowToServer};

/// The server's relay (a resource on the server app, made when the plugin is
/// built; it does nothing until clients speak). Its clock is the world's:
/// seconds since the server started.
#[derive(Resource)]
pub struct SnowServer {
    /// Behind a mutex because resources are `Sync` and the relay is only
    /// `Send` (it reads its store through a cell); the plugin's systems
    /// reach it through `get_mut`, without locking.
    relay: Mutex<SnowRelay>,
    started: Instant,
}

impl SnowServer {
    /// The relay (its stats, tiles, clock), locked while the guard lives.
    pub fn relay(&self) -> MutexGuard<'_, SnowRelay> {
        self.relay.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// The relay, to feed it more than the plugin does.
    pub fn relay_mut(&mut self) -> &mut SnowRelay {
        self.relay.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// World time now (s since the server started).
    #[must_use]
    pub fn world_s(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// Snow depth (m) at world (x, z) from the merged tiles; `None` before a
    /// client has told the relay its world.
    #[must_use]
    pub fn depth_at(&self, x_m: f32, z_m: f32) -> Option<f32> {
        self.relay().depth_at(f64::from(x_m), f64::from(z_m))
    }
}

/// The relay's peer id of a client entity.
fn peer_of(client: Entity) -> PeerId {
    client.to_bits()
}

pub(super) fn build(app: &mut App) {
    let config = app.world().resource::<SnowReplicationSettings>().relay.clone();
    app.insert_resource(SnowServer { relay: Mutex::new(SnowRelay::new(config)), started: Instant::now() })
        .add_observer(connect)
        .add_observer(disconnect)
        .configure_sets(PreUpdate, SnowReplicationSystems::Relay.after(ServerSystems::Receive).run_if(in_state(ServerState::Running)))
        .add_systems(PreUpdate, (apply_settings, receive, report_owners, update, depths).chain().in_set(SnowReplicationSystems::Relay));
}

/// A client joins the relay once replicon has authorized it (its messages
/// are accepted from then on).
fn connect(add: On<Add<AuthorizedClient>>, mut server: ResMut<SnowServer>) {
    server.relay_mut().connect(peer_of(add.entity));
}

fn disconnect(remove: On<Remove<ConnectedClient>>, mut server: ResMut<SnowServer>) {
    server.relay_mut().disconnect(peer_of(remove.entity));
}

fn apply_settings(settings: Res<SnowReplicationSettings>, mut server: ResMut<SnowServer>) {
    let relay = server.relay_mut();
    if settings.is_changed() && *relay.config() != settings.relay {
        relay.set_config(settings.relay.clone());
    }
}

fn receive(mut server: ResMut<SnowServer>, mut messages: MessageReader<FromClient<SnowToServer>>) {
    let now = server.world_s();
    let relay = server.relay_mut();
    for m in messages.read() {
        if let ClientId::Client(client) = m.client_id {
            relay.receive(peer_of(client), &m.message.0, now);
        }
    }
}

/// Every authorized client's owned entities are where it may write; a client
/// owning none may write nowhere (its own claims do not count).
fn report_owners(mut server: ResMut<SnowServer>, clients: Query<Entity, With<AuthorizedClient>>, owned: Query<(&SnowOwnedBy, &Transform)>) {
    let relay = server.relay_mut();
    for client in &clients {
        let at: Vec<[f64; 2]> = owned.iter().filter(|(o, _)| o.0 == client).map(|(_, t)| [f64::from(t.translation.x), f64::from(t.translation.z)]).collect();
        relay.report_deformers(peer_of(client), &at);
    }
}

fn update(mut server: ResMut<SnowServer>, mut out: MessageWriter<ToClients<SnowToClient>>) {
    let now = server.world_s();
    let relay = server.relay_mut();
    relay.update(now);
    while let Some((peer, bytes)) = relay.poll_transmit() {
        // Peer ids are client entities' bits; one that does not decode never came from `connect`.
        let Some(client) = Entity::try_from_bits(peer) else { continue };
        out.write(ToClients { targets: SendTargets::Single(ClientId::Client(client)), message: SnowToClient(bytes) });
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
