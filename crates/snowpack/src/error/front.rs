//! The front door's errors: opaque structs with a small kind a program
//! branches on and a message that says what and where. The enums in
//! the parent module hold the details (`snowpack::low_level::error`, for the app and
//! the tests that match on them); the library builds those, and `?` or
//! `.into()` wraps them at the front door. The store's and sharing's
//! opaque errors are the shared-snow crate's (`snowpack_share::error::front`),
//! re-exported here.

use std::fmt;

pub use snowpack_share::error::front::{ShareError, StoreError};
// The kinds a program branches on, with the features whose calls return the errors.
#[cfg(feature = "share")]
pub use snowpack_share::error::front::ShareErrorKind;
#[cfg(feature = "store")]
pub use snowpack_share::error::front::StoreErrorKind;

use super::{SnowError as SnowDetail, StoreError as StoreDetail};

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

/// Everything that can go wrong in snowpack's library calls. [`Self::kind`]
/// says what a program can do about it; the message (`Display`) says what
/// and where (the parameter, the file, wgpu's words).
pub struct SnowError(Box<SnowDetail>);

/// What kind of [`SnowError`] it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum SnowErrorKind {
    /// Bad input: a parameter out of range, a backend name that names
    /// none, an environment image that does not decode. The message names it.
    InvalidInput,
    /// No GPU to run on: no adapter matched, the adapter refused the device
    /// or lacks what snowpack needs, or OpenGL's context could not be locked.
    NoAdapter,
    /// The device was lost (driver reset, GPU removed); make a new context.
    DeviceLost,
    /// wgpu reported a validation or out-of-memory error, or a readback failed.
    Gpu,
    /// Saving or loading tiles failed (the message names the file).
    Store,
    /// Sharing snow failed (refused, malformed, the relay's store).
    Share,
}

impl SnowError {
    /// What kind of error it is.
    #[must_use]
    pub fn kind(&self) -> SnowErrorKind {
        match *self.0 {
            SnowDetail::InvalidParameter { .. } | SnowDetail::UnknownBackend(_) | SnowDetail::Environment(_) => SnowErrorKind::InvalidInput,
            SnowDetail::NoAdapter { .. } | SnowDetail::RequestDevice { .. } | SnowDetail::GlContextLocked(_) | SnowDetail::Unsupported(_) => {
                SnowErrorKind::NoAdapter
            }
            SnowDetail::DeviceLost(_) => SnowErrorKind::DeviceLost,
            SnowDetail::Gpu { .. } | SnowDetail::Readback(_) => SnowErrorKind::Gpu,
            SnowDetail::Store(_) => SnowErrorKind::Store,
            SnowDetail::Share(_) => SnowErrorKind::Share,
        }
    }
}

opaque_error!(SnowError, SnowDetail, "error");

impl From<StoreDetail> for SnowError {
    fn from(e: StoreDetail) -> Self {
        SnowDetail::Store(e).into()
    }
}

impl From<StoreError> for SnowError {
    fn from(e: StoreError) -> Self {
        SnowDetail::Store(e.into()).into()
    }
}

impl From<ShareError> for SnowError {
    fn from(e: ShareError) -> Self {
        SnowDetail::Share(e.into()).into()
    }
}
