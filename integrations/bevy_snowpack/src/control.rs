//! Requests the main world makes of the render world's deformation that need
//! a blocking wait there: a save into the disk store, and the snow that has
//! settled on each [`crate::SnowCatcher`]. Asked in one frame, taken by the
//! render world at that frame's extraction, answered after its submit and
//! received at the start of a later main-world frame
//! ([`crate::SnowSystems::Receive`]); nothing in the main world waits.
//!
//! A result is announced to observers ([`SnowSaved`], [`SnowObjectStats`])
//! when it arrives, and also kept for [`SnowControl`]'s `take_*` methods
//! (polling, for a system that prefers it): a game uses either.

use bevy::prelude::*;
use snowpack::ObjectStats;

use crate::SnowSystems;

/// Saves and object readbacks (a main-world resource).
///
/// With an observer (the result is announced once, when it arrives):
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_snowpack::prelude::*;
/// fn save_on_key(keys: Res<ButtonInput<KeyCode>>, mut control: ResMut<SnowControl>) {
///     if keys.just_pressed(KeyCode::F5) {
///         control.request_save();
///     }
/// }
/// # let mut app = App::new();
/// app.add_systems(Update, save_on_key).add_observer(|saved: On<SnowSaved>| info!("snow saved: {:?}", saved.result));
/// ```
///
/// Or polled (the result is kept until taken):
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_snowpack::prelude::*;
/// fn save_result(mut control: ResMut<SnowControl>) {
///     if let Some(result) = control.take_save_result() {
///         info!("snow saved: {result:?}");
///     }
/// }
/// ```
#[derive(Resource, Reflect, Default, Debug)]
#[reflect(Resource, Debug, Default)]
pub struct SnowControl {
    pub(crate) save_requested: bool,
    #[reflect(ignore)]
    pub(crate) save_result: Option<Result<u64, String>>,
    pub(crate) loaded_save: Option<bool>,
    pub(crate) stats_requested: bool,
    #[reflect(ignore)]
    pub(crate) stats: Option<Vec<(Entity, ObjectStats)>>,
    /// Results arrived and not yet announced to observers.
    #[reflect(ignore)]
    announce: Vec<Announce>,
}

/// A result waiting for its announcement.
#[derive(Debug)]
enum Announce {
    Saved(Result<u64, String>),
    Stats(Vec<(Entity, ObjectStats)>),
}

/// A save asked for with [`SnowControl::request_save`] has finished: an
/// event for observers (`app.add_observer(|saved: On<SnowSaved>| ...)`),
/// triggered in [`SnowSystems::Receive`] of the frame it arrives in.
#[derive(Event, Clone, Debug, PartialEq)]
pub struct SnowSaved {
    /// The deformation frame saved, or the library's error as text (no disk
    /// store, a full or read-only disk).
    pub result: Result<u64, String>,
}

/// The snow on every [`crate::SnowCatcher`], asked for with
/// [`SnowControl::request_object_stats`]: an event for observers, triggered
/// in [`SnowSystems::Receive`] of the frame it arrives in.
#[derive(Event, Clone, Debug, PartialEq)]
pub struct SnowObjectStats {
    /// Depth over each object's upward-facing surfaces, by entity.
    pub stats: Vec<(Entity, ObjectStats)>,
}

impl SnowControl {
    /// Asks for the whole snow state to be saved into the disk store
    /// ([`crate::SnowStoreSettings`]) after this frame; the result comes as
    /// a [`SnowSaved`] event and through [`Self::take_save_result`].
    pub fn request_save(&mut self) {
        self.save_requested = true;
    }

    /// The last save's result once it has arrived (taken): the deformation
    /// frame it saved, or the library's error as text (no disk store, a full
    /// or read-only disk).
    pub fn take_save_result(&mut self) -> Option<Result<u64, String>> {
        self.save_result.take()
    }

    /// Whether the store held a save that the snow was loaded from at
    /// start; `None` until the deformation's creation has been received,
    /// `Some(false)` without a store or a save.
    #[must_use]
    pub fn loaded_save(&self) -> Option<bool> {
        self.loaded_save
    }

    /// Asks for the snow on every [`crate::SnowCatcher`] (read back after
    /// this frame); it comes as a [`SnowObjectStats`] event and through
    /// [`Self::take_object_stats`].
    pub fn request_object_stats(&mut self) {
        self.stats_requested = true;
    }

    /// The snow on each object once read back (taken): depth over its
    /// upward-facing surfaces, by entity.
    pub fn take_object_stats(&mut self) -> Option<Vec<(Entity, ObjectStats)>> {
        self.stats.take()
    }

    /// The requests made since the last extraction (taken): (save, object stats).
    pub(crate) fn take_requests(&mut self) -> (bool, bool) {
        (std::mem::take(&mut self.save_requested), std::mem::take(&mut self.stats_requested))
    }

    /// A save's result arrived from the render world.
    pub(crate) fn arrive_save(&mut self, result: Result<u64, String>) {
        self.announce.push(Announce::Saved(result.clone()));
        self.save_result = Some(result);
    }

    /// The objects' snow arrived from the render world.
    pub(crate) fn arrive_stats(&mut self, stats: Vec<(Entity, ObjectStats)>) {
        self.announce.push(Announce::Stats(stats.clone()));
        self.stats = Some(stats);
    }
}

pub(crate) fn build(app: &mut App) {
    app.add_systems(PreUpdate, announce_results.in_set(SnowSystems::Receive).after(crate::systems::Delivered));
}

/// Triggers the events of the results that arrived since the last frame.
fn announce_results(mut commands: Commands, mut control: ResMut<SnowControl>) {
    if control.announce.is_empty() {
        return;
    }
    for arrived in std::mem::take(&mut control.announce) {
        match arrived {
            Announce::Saved(result) => commands.trigger(SnowSaved { result }),
            Announce::Stats(stats) => commands.trigger(SnowObjectStats { stats }),
        }
    }
}
