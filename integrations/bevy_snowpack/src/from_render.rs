//! The way back from the render world: what it read from the GPU (query
//! answers, object stats, save results, coats) goes through a channel, and
//! the main world receives it at the start of its frame
//! ([`crate::SnowSystems::Receive`], `receive.rs`).

use std::sync::mpsc::{Receiver, Sender};

use bevy::platform::cell::SyncCell;
use bevy::prelude::*;
use snowpack::ObjectStats;

use crate::query::SnowAnswers;

/// What the render world sends the main world.
pub(crate) enum FromRender {
    /// Answers to the questions asked through [`crate::SnowQuery`].
    Answers(Vec<SnowAnswers>),
    /// Whether a save was loaded when the deformation was created.
    LoadedSave(bool),
    /// A save's result: the frame saved, or the error as text.
    Saved(Result<u64, String>),
    /// The snow on each [`crate::SnowCatcher`].
    ObjectStats(Vec<(Entity, ObjectStats)>),
    /// The snow coat of a mesh deformer's mesh (its entity), one value a vertex.
    Coat(Entity, Vec<f32>),
}

/// The render world's end of the channel to the main world.
#[derive(Resource)]
pub(crate) struct ToMainWorld(pub Sender<FromRender>);

impl ToMainWorld {
    /// Sends to the main world; a main world that has gone (the app is closing) is not an error.
    pub(crate) fn send(&self, message: FromRender) {
        let _ = self.0.send(message);
    }
}

/// The main world's end of the channel from the render world.
#[derive(Resource)]
pub(crate) struct FromRenderWorld(SyncCell<Receiver<FromRender>>);

impl FromRenderWorld {
    pub(crate) fn new(receiver: Receiver<FromRender>) -> Self {
        Self(SyncCell::new(receiver))
    }

    /// What has arrived so far (taken).
    pub(crate) fn drain(&mut self) -> Vec<FromRender> {
        self.0.get().try_iter().collect()
    }
}
