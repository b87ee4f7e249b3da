//! Requests the main world makes of the render world's deformation that need
//! a blocking wait there: a save into the disk store, and the snow that has
//! settled on each [`crate::SnowObject`]. Asked in one frame, answered after
//! that frame's submit; nothing in the main world waits.

use std::sync::{Arc, Mutex, MutexGuard};

use bevy::prelude::*;
use snowpack::ObjectStats;

#[derive(Default)]
struct Shared {
    save_requested: bool,
    save_result: Option<Result<u64, String>>,
    loaded_save: Option<bool>,
    stats_requested: bool,
    stats: Option<Vec<(Entity, ObjectStats)>>,
}

/// Saves and object readbacks (a resource shared by the main and the render world).
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_snowpack::SnowControl;
/// fn save_on_key(keys: Res<ButtonInput<KeyCode>>, control: Res<SnowControl>) {
///     if keys.just_pressed(KeyCode::F5) {
///         control.request_save();
///     }
///     if let Some(result) = control.take_save_result() {
///         info!("snow saved: {result:?}");
///     }
/// }
/// ```
#[derive(Resource, Clone, Default)]
pub struct SnowControl(Arc<Mutex<Shared>>);

impl SnowControl {
    fn lock(&self) -> MutexGuard<'_, Shared> {
        // A panic elsewhere while holding the lock leaves plain data behind: keep using it.
        self.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Asks for the whole snow state to be saved into the disk store
    /// ([`crate::SnowStoreSettings`]) after this frame; the result comes
    /// through [`Self::take_save_result`].
    pub fn request_save(&self) {
        self.lock().save_requested = true;
    }

    /// The last save's result once it has run (taken): the deformation
    /// frame it saved, or the library's error as text (no disk store, a full
    /// or read-only disk).
    pub fn take_save_result(&self) -> Option<Result<u64, String>> {
        self.lock().save_result.take()
    }

    /// Whether the store held a save that the snow was loaded from at
    /// start; `None` until the deformation exists, `Some(false)` without a
    /// store or a save.
    #[must_use]
    pub fn loaded_save(&self) -> Option<bool> {
        self.lock().loaded_save
    }

    /// Asks for the snow on every [`crate::SnowObject`] (read back after this frame).
    pub fn request_object_stats(&self) {
        self.lock().stats_requested = true;
    }

    /// The snow on each object once read back (taken): depth over its
    /// upward-facing surfaces, by entity.
    pub fn take_object_stats(&self) -> Option<Vec<(Entity, ObjectStats)>> {
        self.lock().stats.take()
    }

    pub(crate) fn take_save_request(&self) -> bool {
        std::mem::take(&mut self.lock().save_requested)
    }

    pub(crate) fn take_stats_request(&self) -> bool {
        std::mem::take(&mut self.lock().stats_requested)
    }

    pub(crate) fn set_save_result(&self, result: Result<u64, String>) {
        self.lock().save_result = Some(result);
    }

    pub(crate) fn set_loaded_save(&self, loaded: bool) {
        self.lock().loaded_save = Some(loaded);
    }

    pub(crate) fn set_object_stats(&self, stats: Vec<(Entity, ObjectStats)>) {
        self.lock().stats = Some(stats);
    }
}
