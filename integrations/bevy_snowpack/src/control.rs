//! Requests the main world makes of the render world's deformation that need
//! a blocking wait there: a save into the disk store, and the snow that has
//! settled on each [`crate::SnowCatcher`]. Asked in one frame, taken by the
//! render world at that frame's extraction, answered after its submit and
//! received at the start of a later main-world frame
//! ([`crate::SnowSystems::Receive`]); nothing in the main world waits.

use bevy::prelude::*;
use snowpack::ObjectStats;

/// Saves and object readbacks (a main-world resource).
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_snowpack::prelude::*;
/// fn save_on_key(keys: Res<ButtonInput<KeyCode>>, mut control: ResMut<SnowControl>) {
///     if keys.just_pressed(KeyCode::F5) {
///         control.request_save();
///     }
///     if let Some(result) = control.take_save_result() {
///         info!("snow saved: {result:?}");
///     }
/// }
/// ```
#[derive(Resource, Default, Debug)]
pub struct SnowControl {
    pub(crate) save_requested: bool,
    pub(crate) save_result: Option<Result<u64, String>>,
    pub(crate) loaded_save: Option<bool>,
    pub(crate) stats_requested: bool,
    pub(crate) stats: Option<Vec<(Entity, ObjectStats)>>,
}

impl SnowControl {
    /// Asks for the whole snow state to be saved into the disk store
    /// ([`crate::SnowStoreSettings`]) after this frame; the result comes
    /// through [`Self::take_save_result`].
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

    /// Asks for the snow on every [`crate::SnowCatcher`] (read back after this frame).
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
}
