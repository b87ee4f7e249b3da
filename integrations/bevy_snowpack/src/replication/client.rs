//! The client's side: a `SnowPeer` in the render world beside the plugin's
//! deformation (it reads the frame's changed tiles and queues merges there).
//! It shares while the app is a connected client, or a listen server (its
//! messages then reach its own relay through replicon's local messages).
//! What the server sent is taken from the main world at extraction; what the
//! peer makes comes back through a channel and is written as replicon
//! messages in the main world's `PostUpdate`.

use std::collections::VecDeque;
use std::sync::mpsc::{Receiver, Sender};
use std::time::Instant;

use bevy::platform::cell::SyncCell;
use bevy::prelude::*;
use bevy::render::renderer::RenderGraph;
use bevy::render::{Extract, ExtractSchedule, MainWorld, RenderApp};
use bevy_replicon::prelude::*;
use snowpack::{PeerStats, ShareErrorKind, SharedWindow as _, SnowPeer, WorldIdentity};

use super::{SnowReplicationSettings, SnowReplicationSystems, SnowToClient, SnowToServer};
use crate::render_state::SnowRenderState;
use crate::{SnowDeformer, SnowSystems};

/// Messages kept for the server while the connection is down; beyond it the
/// oldest go (the peer resends deltas and its digests repair the rest).
const MAX_OUTBOX: usize = 1024;

/// A client's shared snow as its peer last reported it (a main-world
/// resource, updated each frame in [`SnowReplicationSystems::Receive`]).
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_snowpack::prelude::*;
/// // Before quitting: everything pressed here is at the server, everything it has is here.
/// fn leave_when_settled(mut sharing: ResMut<SnowSharing>, mut exit: MessageWriter<AppExit>) {
///     sharing.request_sync();
///     if sharing.is_settled() {
///         exit.write(AppExit::Success);
///     }
/// }
/// ```
#[derive(Resource, Default, Debug)]
pub struct SnowSharing {
    status: PeerStatus,
    /// From the server, for the render world's next extraction.
    inbox: Vec<Vec<u8>>,
    /// From the peer, for the server.
    outbox: VecDeque<Vec<u8>>,
    sync_requested: bool,
    bytes_sent: u64,
    bytes_received: u64,
    messages_sent: u64,
    messages_received: u64,
    /// The app has a render world with a peer (a client, or a listen server).
    pub(super) local_snow: bool,
}

/// What the render world's peer reports each frame.
#[derive(Clone, Debug, Default)]
struct PeerStatus {
    welcomed: bool,
    unacknowledged: usize,
    synced: bool,
    waiting_tiles: usize,
    dirty_tiles: usize,
    stats: PeerStats,
    refused: Option<String>,
    world: Option<WorldIdentity>,
}

impl SnowSharing {
    /// The server has welcomed this client into its world (its clock is the snow's).
    #[must_use]
    pub fn is_welcomed(&self) -> bool {
        self.status.welcomed
    }

    /// Changes not yet acknowledged by the server (deltas in flight and tiles waiting to go).
    #[must_use]
    pub fn unacknowledged(&self) -> usize {
        self.status.unacknowledged
    }

    /// The server answered the last digest with "in sync", nothing changed since, and nothing waits to go.
    #[must_use]
    pub fn is_synced(&self) -> bool {
        self.status.synced
    }

    /// Tiles received and not yet merged into the window (ahead of its clock, or beyond a frame's upload).
    #[must_use]
    pub fn waiting_tiles(&self) -> usize {
        self.status.waiting_tiles
    }

    /// Everything this client changed is gathered and acknowledged, and everything the
    /// server holds over its window is merged in: what a client about to
    /// quit (or about to read the snow for a test) waits for, after
    /// [`Self::request_sync`] for a few frames.
    #[must_use]
    pub fn is_settled(&self) -> bool {
        let s = &self.status;
        s.welcomed && s.synced && s.unacknowledged == 0 && s.waiting_tiles == 0 && s.dirty_tiles == 0
    }

    /// Tiles the snow changed that are not gathered for the peer yet.
    #[must_use]
    pub fn dirty_tiles(&self) -> usize {
        self.status.dirty_tiles
    }

    /// The peer's counters (bytes and tiles each way, resends, drops).
    #[must_use]
    pub fn stats(&self) -> PeerStats {
        self.status.stats
    }

    /// This app's snow's world (once it shares): what the server must serve
    /// for it to join, and what a listen server serves when its settings
    /// name no world.
    #[must_use]
    pub fn world(&self) -> Option<&WorldIdentity> {
        self.status.world.as_ref()
    }

    /// Why the server refused this client (its world differs: depth, tile side, terrain...), if it did.
    #[must_use]
    pub fn refused(&self) -> Option<&str> {
        self.status.refused.as_deref()
    }

    /// Shared-snow payload bytes written to the connection ([`SnowToServer`]).
    #[must_use]
    pub fn bytes_sent(&self) -> u64 {
        self.bytes_sent
    }

    /// Shared-snow payload bytes received from the connection ([`SnowToClient`]).
    #[must_use]
    pub fn bytes_received(&self) -> u64 {
        self.bytes_received
    }

    /// Messages written ([`SnowToServer`]) and received ([`SnowToClient`]).
    #[must_use]
    pub fn messages(&self) -> (u64, u64) {
        (self.messages_sent, self.messages_received)
    }

    /// For the next frame: the changed tiles are gathered whatever the
    /// interval, and a digest goes out as soon as it may, so
    /// [`Self::is_settled`] comes soon (ask each frame while waiting for it).
    pub fn request_sync(&mut self) {
        self.sync_requested = true;
    }
}

/// The render world's end of the channel to the main world.
#[derive(Resource)]
struct ToMain(Sender<(Vec<Vec<u8>>, PeerStatus)>);

/// The main world's end.
#[derive(Resource)]
struct FromPeer(SyncCell<Receiver<(Vec<Vec<u8>>, PeerStatus)>>);

/// The peer beside the render world's deformation.
#[derive(Resource, Default)]
struct PeerState {
    peer: Option<SnowPeer>,
    started: Option<Instant>,
    /// The connection was up at the last frame (a reconnection says `Hello` again).
    connected: bool,
    /// The settings the peer was made with.
    applied: Option<SnowReplicationSettings>,
    /// Sharing could not be switched on (the settings are wrong): not tried again.
    failed: bool,
    /// Why the server refused this client, once it has.
    refused: Option<String>,
    /// The peer's world (the snow's, with the sharing tile side).
    world: Option<WorldIdentity>,
}

/// What the peer takes from the main world each frame.
#[derive(Resource, Default)]
struct ExtractedPeerFrame {
    inbox: Vec<Vec<u8>>,
    deformers: Vec<[f64; 2]>,
    connected: bool,
    sync: bool,
    settings: Option<SnowReplicationSettings>,
}

pub(super) fn build(app: &mut App) {
    let (to_main, from_peer) = std::sync::mpsc::channel();
    app.init_resource::<SnowSharing>()
        .insert_resource(FromPeer(SyncCell::new(from_peer)))
        .configure_sets(PreUpdate, SnowReplicationSystems::Receive.after(ClientSystems::Receive))
        .configure_sets(PostUpdate, SnowReplicationSystems::Send.before(ClientSystems::Send))
        .add_systems(PreUpdate, receive.in_set(SnowReplicationSystems::Receive))
        .add_systems(PostUpdate, send.in_set(SnowReplicationSystems::Send).run_if(in_state(ClientState::Connected).or_else(in_state(ServerState::Running))));
    // A server without Bevy's renderer has no render world, and no peer.
    if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
        render_app
            .insert_resource(ToMain(to_main))
            .init_resource::<PeerState>()
            .init_resource::<ExtractedPeerFrame>()
            .add_systems(ExtractSchedule, (extract_deformers, take_inbox).chain().in_set(SnowSystems::Extract))
            .add_systems(RenderGraph, step_peer.after(SnowSystems::Encode).in_set(SnowReplicationSystems::Peer));
    }
    // The plugin's snow (added before this plugin) in a render world: a client, or a listen server.
    let local_snow = app.get_sub_app(RenderApp).is_some() && app.world().contains_resource::<crate::SnowpackSettings>();
    app.world_mut().resource_mut::<SnowSharing>().local_snow = local_snow;
}

/// What the server sent, for the render world; what the peer made, for the server.
fn receive(mut sharing: ResMut<SnowSharing>, mut from_server: MessageReader<SnowToClient>, mut from_peer: ResMut<FromPeer>) {
    for m in from_server.read() {
        sharing.bytes_received += m.0.len() as u64;
        sharing.messages_received += 1;
        sharing.inbox.push(m.0.clone());
    }
    for (messages, status) in from_peer.0.get().try_iter() {
        for bytes in messages {
            if sharing.outbox.len() >= MAX_OUTBOX {
                sharing.outbox.pop_front();
            }
            sharing.outbox.push_back(bytes);
        }
        sharing.status = status;
    }
}

fn send(mut sharing: ResMut<SnowSharing>, mut out: MessageWriter<SnowToServer>) {
    let sharing = &mut *sharing;
    for bytes in sharing.outbox.drain(..) {
        sharing.bytes_sent += bytes.len() as u64;
        sharing.messages_sent += 1;
        out.write(SnowToServer(bytes));
    }
}

/// Where this client's deformers are (the peer's `Presence`; a server that
/// knows its owned entities overrides it).
fn extract_deformers(mut frame: ResMut<ExtractedPeerFrame>, deformers: Extract<Query<&GlobalTransform, With<SnowDeformer>>>) {
    frame.deformers.clear();
    frame.deformers.extend(deformers.iter().map(|t| {
        let p = t.translation();
        [f64::from(p.x), f64::from(p.z)]
    }));
}

/// Takes what the server sent (the main world's inbox is emptied), the
/// connection's state (a listen server is connected to itself), a sync
/// request and the settings.
fn take_inbox(mut main_world: ResMut<MainWorld>, mut frame: ResMut<ExtractedPeerFrame>) {
    let client = main_world.get_resource::<State<ClientState>>().is_some_and(|s| *s.get() == ClientState::Connected);
    let listen_server = main_world.get_resource::<State<ServerState>>().is_some_and(|s| *s.get() == ServerState::Running);
    frame.connected = client || listen_server;
    frame.settings = main_world.get_resource::<SnowReplicationSettings>().cloned();
    if let Some(mut sharing) = main_world.get_resource_mut::<SnowSharing>() {
        // Appended: messages a frame without a deformation never took wait for the next one.
        let inbox = std::mem::take(&mut sharing.inbox);
        frame.inbox.extend(inbox);
        frame.sync |= std::mem::take(&mut sharing.sync_requested);
    }
}

/// One step of the peer after the frame's submit: sharing switched on at the
/// first connected frame, messages in, changed tiles out, merges queued,
/// messages and status to the main world.
fn step_peer(state: Option<ResMut<SnowRenderState>>, mut peer: ResMut<PeerState>, mut frame: ResMut<ExtractedPeerFrame>, to_main: Res<ToMain>) {
    let Some(mut state) = state else { return };
    let Some(settings) = frame.settings.clone() else { return };
    let (ctx, snow) = state.context_and_deformation();
    let peer = &mut *peer;
    if !frame.connected {
        peer.connected = false;
        return;
    }
    if peer.failed {
        return;
    }
    if peer.peer.is_none() {
        if let Err(e) = snow.enable_sharing(ctx, settings.tile_side, settings.gather_interval_s) {
            tracing::error!("bevy_snowpack: the snow cannot be shared: {e}");
            peer.failed = true;
            return;
        }
        let world = snow.world_identity();
        peer.peer = Some(SnowPeer::new(world.clone(), &settings.peer_name, settings.peer.clone()));
        peer.world = Some(world);
        peer.started = Some(Instant::now());
        peer.applied = Some(settings.clone());
        peer.connected = true;
    }
    let Some(p) = peer.peer.as_mut() else { return };
    if !peer.connected {
        // The transport came back: `Hello` again, deltas in flight resent.
        p.reconnect();
        peer.connected = true;
    }
    if let Some(applied) = peer.applied.as_mut() {
        apply_settings(applied, &settings, p);
    }
    for bytes in frame.inbox.drain(..) {
        match p.receive(&bytes) {
            Ok(()) => {}
            Err(e) if e.kind() == ShareErrorKind::Refused => {
                // The message lists what differs (depth, tile side, terrain...).
                let why = e.to_string();
                tracing::error!("bevy_snowpack: the server refused this client's snow: {why}");
                peer.refused = Some(why);
            }
            Err(e) => tracing::warn!("bevy_snowpack: shared snow: {e}"),
        }
    }
    if std::mem::take(&mut frame.sync) {
        snow.flush_changed_tiles();
        p.request_digest();
    }
    p.set_deformers(&frame.deformers);
    let now_s = peer.started.map_or(0.0, |t| t.elapsed().as_secs_f64());
    p.update(snow, now_s);
    let messages: Vec<Vec<u8>> = std::iter::from_fn(|| p.poll_transmit()).collect();
    let status = PeerStatus {
        welcomed: p.is_welcomed(),
        unacknowledged: p.unacknowledged(),
        synced: p.is_synced(),
        waiting_tiles: snow.waiting_tiles(),
        dirty_tiles: snow.dirty_tiles(),
        stats: p.stats(),
        refused: peer.refused.clone(),
        world: peer.world.clone(),
    };
    // A main world that has gone (the app is closing) is not an error.
    let _ = to_main.0.send((messages, status));
}

/// What changed in the settings since the peer applied them: its pacing is
/// applied, the settings fixed once joined warn, the server's own are
/// nothing to the peer.
fn apply_settings(applied: &mut SnowReplicationSettings, settings: &SnowReplicationSettings, p: &mut SnowPeer) {
    if *applied == *settings {
        return;
    }
    if applied.peer != settings.peer {
        p.set_config(settings.peer.clone());
    }
    for (name, changed) in [
        ("tile_side", applied.tile_side != settings.tile_side),
        ("gather_interval_s", applied.gather_interval_s != settings.gather_interval_s),
        ("peer_name", applied.peer_name != settings.peer_name),
    ] {
        if changed {
            tracing::warn!("bevy_snowpack: SnowReplicationSettings::{name} is fixed once the client has joined; the change is ignored");
        }
    }
    *applied = SnowReplicationSettings {
        tile_side: applied.tile_side,
        gather_interval_s: applied.gather_interval_s,
        peer_name: applied.peer_name.clone(),
        ..settings.clone()
    };
}
