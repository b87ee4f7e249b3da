//! The library's error type, and the error types it wraps: of the tile
//! store ([`StoreError`], re-exported by [`crate::persist`]) and of shared
//! snow ([`ShareError`] and [`MessageError`], re-exported by
//! [`crate::replicate`]), which the shared-snow crate (`snowpack_share::error`)
//! defines and this module re-exports. They are at the bottom of the
//! layers, so that every module can return a [`SnowError`].
//!
//! These enums are the errors in detail, as the library builds them; the
//! front door's errors ([`front`]: `snowpack::SnowError` and its kind) wrap
//! them.

pub mod front;

#[cfg_attr(not(feature = "low_level"), allow(unused_imports, reason = "`low_level::error::MessageError`; the library names it through `replicate`"))]
pub use snowpack_share::error::MessageError;
pub use snowpack_share::error::{ShareError, StoreError};

/// Everything that can go wrong in snowpack's library calls.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SnowError {
    /// No adapter matched; the message says what to install or set.
    #[error("no GPU adapter found{filter}: {hint}")]
    NoAdapter {
        /// The filter that was applied, for example ` with SNOWPACK_BACKEND=vulkan`.
        filter: String,
        /// What a person can do about it.
        hint: String,
    },
    /// A backend list (`--backend`, `SNOWPACK_BACKEND`) named no known backend.
    #[error("{0:?} names no backend; use vulkan, gl, metal, dx12 or webgpu (comma-separated)")]
    UnknownBackend(String),
    /// The adapter refused the device.
    #[error("the adapter {adapter:?} refused to create a device: {source}")]
    RequestDevice {
        /// The adapter's name.
        adapter: String,
        /// wgpu's reason.
        source: wgpu::RequestDeviceError,
    },
    /// The device was lost (driver reset, GPU removed); it cannot be used again.
    #[error("the GPU device was lost: {0}")]
    DeviceLost(String),
    /// wgpu's OpenGL backend could not lock the adapter's context (another
    /// thread held the EGL/WGL context for seconds: a driver or thread
    /// deadlock); wgpu panics there, and snowpack turns that panic into this
    /// error where it can ([`crate::GpuContext::new_headless`] and adapter
    /// selection).
    #[error("the OpenGL context could not be locked ({0}); another thread holds it; try again, or choose another backend (--backend vulkan)")]
    GlContextLocked(String),
    /// wgpu reported a validation or out-of-memory error.
    #[error("GPU error in {context}: {message}")]
    Gpu {
        /// What snowpack was doing.
        context: &'static str,
        /// wgpu's message.
        message: String,
    },
    /// Mapping a buffer for reading failed.
    #[error("reading back from the GPU failed: {0}")]
    Readback(String),
    /// A parameter is out of range.
    #[error("invalid snow parameter `{field}`: {why}")]
    InvalidParameter {
        /// The field's name as in the `[snow]` table.
        field: &'static str,
        /// Why it is rejected.
        why: String,
    },
    /// An environment image could not be decoded.
    #[error("cannot read the environment image: {0}")]
    Environment(String),
    /// The adapter lacks something the renderer needs.
    #[error("the adapter cannot run the renderer: {0}")]
    Unsupported(String),
    /// Saving or loading snow tiles failed (the error names the file).
    #[error("tile store: {0}")]
    Store(#[from] StoreError),
    /// Sharing snow with a relay failed (refused, malformed, its store).
    #[error("shared snow: {0}")]
    Share(#[from] ShareError),
}
