//! The two replicon messages the library's wire bytes travel in:
//! [`SnowToServer`] and [`SnowToClient`].

use bevy::prelude::*;
use serde::{Deserialize, Serialize};

/// A shared-snow message from a client to the server (its peer's `Hello`,
/// `Presence`, `Tiles` deltas, `Digest`): the library's wire bytes.
#[derive(Message, Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
pub struct SnowToServer(pub Vec<u8>);

/// A shared-snow message from the server to one client (`Welcome`, `Ack`,
/// merged `Tiles`, `Want`, `Clock`, `InSync`): the library's wire bytes.
#[derive(Message, Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
pub struct SnowToClient(pub Vec<u8>);
