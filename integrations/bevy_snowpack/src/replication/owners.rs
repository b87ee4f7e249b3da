//! Which client controls an entity on the server ([`SnowOwnedBy`]) and the
//! snow depth the relay reads under it ([`SnowDepthUnder`]).

use bevy::prelude::*;
use bevy_replicon::prelude::*;

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
/// [`SnowReplicationSystems::Relay`](crate::SnowReplicationSystems::Relay), before `Update`: gameplay there slows a
/// player in deep snow with it. `None` until the relay runs (it starts once
/// the server knows its world).
#[derive(Component, Clone, Copy, Debug, Default, PartialEq)]
pub struct SnowDepthUnder {
    /// Snow depth (m) at the entity's x, z.
    pub depth_m: Option<f32>,
}
