//! The errors the streamer keeps for the game, bounded, and the one a
//! flush in progress returns.

use crate::persist::StoreError;

/// Most errors kept for `TileStreamer::take_errors`; more are logged and
/// counted but not kept, so a game that never takes them does not grow.
const MAX_ERRORS: usize = 1024;

/// The errors waiting for `TileStreamer::take_errors` (at most
/// [`MAX_ERRORS`]) and, while `flush` waits, the first write error, for it
/// to return.
#[derive(Default)]
pub(super) struct ErrorLog {
    /// Errors for the game.
    errors: Vec<StoreError>,
    /// While `flush` waits: where the first write error goes, for it to return.
    flush_error: Option<Option<StoreError>>,
}

impl ErrorLog {
    /// Keeps `error` for the game, or, from a write while a flush waits and
    /// the first such, for the flush to return.
    pub(super) fn report(&mut self, error: StoreError, from_write: bool) {
        if from_write && let Some(slot @ None) = &mut self.flush_error {
            *slot = Some(error);
        } else if self.errors.len() < MAX_ERRORS {
            self.errors.push(error);
        } else {
            tracing::warn!("tile store: {error} (not kept: {MAX_ERRORS} errors are waiting for take_errors)");
        }
    }

    /// A flush starts waiting: the next write error is its answer.
    pub(super) fn begin_flush(&mut self) {
        self.flush_error = Some(None);
    }

    /// The flush is over: the first write error while it waited.
    pub(super) fn end_flush(&mut self) -> Option<StoreError> {
        self.flush_error.take().flatten()
    }

    /// Keeps a flush's write error the flush could not return.
    pub(super) fn keep(&mut self, error: Option<StoreError>) {
        self.errors.extend(error);
    }

    /// The errors kept since the last call.
    pub(super) fn take(&mut self) -> Vec<StoreError> {
        std::mem::take(&mut self.errors)
    }
}
