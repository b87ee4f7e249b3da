//! The plugin's system sets, and the way back from the render world: the
//! render world sends what it read from the GPU (query answers, object
//! stats, save results) through a channel, and the main world receives it at
//! the start of its frame ([`SnowSystems::Receive`]).

use std::sync::mpsc::{Receiver, Sender};

use bevy::platform::cell::SyncCell;
use bevy::prelude::*;
use bevy::transform::TransformSystems;
use snowpack::ObjectStats;

use crate::control::SnowControl;
use crate::query::{SnowAnswers, SnowQuery};

/// The plugin's systems, in the order a frame runs them; order a game's own
/// around them with `.before(SnowSystems::…)` / `.after(SnowSystems::…)`.
///
/// Main world:
/// - [`Self::Receive`] (`PreUpdate`): what the render world read back arrives
///   ([`SnowQuery`] answers, [`SnowControl`] results; what arrives during a
///   frame's extraction is handed over there). A system after it in the
///   same frame sees them.
/// - [`Self::Gather`] (`PostUpdate`, after transform propagation): the mesh
///   deformers' poses are gathered for this frame's extraction. A system that
///   moves a [`crate::SnowDeformer`] runs before `PostUpdate` (or before this set).
/// - [`Self::Footsteps`] (`PostUpdate`, after [`Self::Gather`]): the
///   [`crate::SnowFoot`] answers are read, [`crate::SnowFootstep`] messages
///   written, and the next questions asked. Read the messages after this set
///   (or in the next frame's `Update`).
/// - [`Self::Bounds`] (`PostUpdate`, after Bevy's bounds): the snow ground
///   meshes' bounds span the snow's heights.
///
/// Render world:
/// - [`Self::Extract`] (`ExtractSchedule`): the settings, deformers, objects,
///   meshes' poses, questions and requests are taken from the main world.
/// - [`Self::Encode`] (`RenderGraph`, before the cameras): changed settings are
///   applied and the snow's frame recorded; after the submit, the readbacks
///   are started and finished ones sent to the main world.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SnowSystems {
    /// Answers and results from the render world arrive (main world, `PreUpdate`).
    Receive,
    /// The mesh deformers' poses are gathered (main world, `PostUpdate`).
    Gather,
    /// Footsteps are detected and their questions asked (main world, `PostUpdate`).
    Footsteps,
    /// The snow ground meshes' bounds are grown (main world, `PostUpdate`).
    Bounds,
    /// The frame's snow is taken from the main world (render world, `ExtractSchedule`).
    Extract,
    /// Settings applied, the frame recorded, readbacks sent (render world, `RenderGraph`).
    Encode,
}

/// What the render world sends the main world.
pub(crate) enum FromRender {
    /// Answers to the questions asked through [`SnowQuery`].
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

pub(crate) fn build(app: &mut App) {
    app.configure_sets(PostUpdate, (SnowSystems::Gather.after(TransformSystems::Propagate), SnowSystems::Footsteps.after(SnowSystems::Gather)))
        .add_systems(PreUpdate, receive_from_render.in_set(SnowSystems::Receive));
}

/// Moves what arrived from the render world into [`SnowQuery`] and [`SnowControl`].
pub(crate) fn receive_from_render(
    mut from: ResMut<FromRenderWorld>,
    mut query: ResMut<SnowQuery>,
    mut control: ResMut<SnowControl>,
    mut coats: ResMut<crate::coat::ArrivedCoats>,
) {
    deliver(from.drain(), &mut query, &mut control, &mut coats);
}

/// Receives in the main world during extraction (the render world's
/// `take_requests`), too: what the render world's startup reported (a
/// loaded save) runs in the first update's extraction, before its
/// `ExtractSchedule`, so it is there once that update returns, as it is for
/// a game's first `Update`.
pub(crate) fn receive_in(main_world: &mut World) {
    let Some(arrived) = main_world.get_resource_mut::<FromRenderWorld>().map(|mut f| f.drain()) else { return };
    if arrived.is_empty() {
        return;
    }
    main_world.resource_scope(|world, mut query: Mut<SnowQuery>| {
        world.resource_scope(|world, mut coats: Mut<crate::coat::ArrivedCoats>| {
            if let Some(mut control) = world.get_resource_mut::<SnowControl>() {
                deliver(arrived, &mut query, &mut control, &mut coats);
            }
        });
    });
}

/// Puts what arrived where the main world reads it.
fn deliver(arrived: Vec<FromRender>, query: &mut SnowQuery, control: &mut SnowControl, coats: &mut crate::coat::ArrivedCoats) {
    for message in arrived {
        match message {
            FromRender::Answers(answers) => query.deliver(answers),
            FromRender::LoadedSave(loaded) => control.loaded_save = Some(loaded),
            FromRender::Saved(result) => control.arrive_save(result),
            FromRender::ObjectStats(stats) => control.arrive_stats(stats),
            FromRender::Coat(entity, thickness_m) => {
                coats.0.insert(entity, thickness_m);
            }
        }
    }
}
