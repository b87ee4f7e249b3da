//! The opaque errors of the tile store and of shared snow: structs with a
//! small kind a program branches on and a message that says what and where.
//! The enums in the parent module hold the details (for snowpack's app and
//! the tests that match on them); the crate builds those, and `?` or
//! `.into()` wraps them. snowpack's front door re-exports these.

use std::fmt;

use super::{ShareError as ShareDetail, StoreError as StoreDetail};

/// Declares an opaque error around a detailed enum: `Display`, `Debug`,
/// `source`, the conversions both ways and `AsRef` of the detail (which a
/// program names through `low_level`): the opaque type has one shape with
/// or without the feature.
macro_rules! opaque_error {
    ($name:ident, $detail:ident, $what:literal) => {
        /// The detail, to match on its variants (the detailed enum is
        /// `low_level`'s; the opaque error converts into it with `From`).
        impl AsRef<$detail> for $name {
            fn as_ref(&self) -> &$detail {
                &self.0
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                fmt::Display::fmt(&self.0, f)
            }
        }

        impl fmt::Debug for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                fmt::Debug::fmt(&self.0, f)
            }
        }

        impl std::error::Error for $name {
            fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
                std::error::Error::source(&*self.0)
            }
        }

        impl From<$detail> for $name {
            fn from(detail: $detail) -> Self {
                Self(Box::new(detail))
            }
        }

        impl From<$name> for $detail {
            fn from(e: $name) -> Self {
                *e.0
            }
        }
    };
}

/// What can go wrong storing or loading tiles; the message names the file.
pub struct StoreError(Box<StoreDetail>);

/// What kind of [`StoreError`] it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum StoreErrorKind {
    /// The operating system refused (disk full, read-only, a directory gone).
    Io,
    /// A file that cannot be used: damaged, written in another format
    /// version, or of another world (tile side, key).
    Invalid,
    /// The disk did not answer in time; what was asked stays queued.
    TimedOut,
    /// The store's worker thread has stopped; tiles can no longer be loaded or saved.
    WorkerGone,
    /// Tiles are kept in memory only; saving needs a disk store.
    NoDisk,
}

impl StoreError {
    /// What kind of error it is.
    #[must_use]
    pub fn kind(&self) -> StoreErrorKind {
        match *self.0 {
            StoreDetail::Io { .. } => StoreErrorKind::Io,
            StoreDetail::Corrupt { .. } | StoreDetail::Version { .. } | StoreDetail::Mismatch { .. } => StoreErrorKind::Invalid,
            StoreDetail::TimedOut { .. } => StoreErrorKind::TimedOut,
            StoreDetail::WorkerGone => StoreErrorKind::WorkerGone,
            StoreDetail::NoDisk => StoreErrorKind::NoDisk,
        }
    }
}

opaque_error!(StoreError, StoreDetail, "store error");

impl From<super::MessageError> for ShareError {
    fn from(e: super::MessageError) -> Self {
        ShareDetail::Malformed(e).into()
    }
}

impl From<StoreDetail> for ShareError {
    fn from(e: StoreDetail) -> Self {
        ShareDetail::Store(e).into()
    }
}

/// What can go wrong sharing snow.
pub struct ShareError(Box<ShareDetail>);

/// What kind of [`ShareError`] it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ShareErrorKind {
    /// The relay's world is another (the message lists the differences).
    Refused,
    /// A message that does not decode, or that this side never receives.
    Malformed,
    /// The relay's tile store failed or holds a world that cannot be used.
    Store,
}

impl ShareError {
    /// What kind of error it is.
    #[must_use]
    pub fn kind(&self) -> ShareErrorKind {
        match *self.0 {
            ShareDetail::Refused { .. } => ShareErrorKind::Refused,
            ShareDetail::Malformed(_) => ShareErrorKind::Malformed,
            ShareDetail::Store(_) | ShareDetail::StoreWorld(_) => ShareErrorKind::Store,
        }
    }
}

opaque_error!(ShareError, ShareDetail, "sharing error");
