//! The snow a game drives: [`SnowDeformation`] is a small orchestrator over
//! the core window ([`core_window`]: the deformation's resources and passes) and
//! the plug-ins, each owning its state in its own file: skinned characters
//! ([`characters`], over [`crate::skin`]), objects snow settles on
//! ([`objects`], over [`crate::accumulate`]), the tiles kept while the
//! window is away and their save ([`store`], over [`crate::tiles`] and
//! [`crate::persist`]), and shared snow ([`share`], over
//! [`crate::replicate`]). One frame is [`steps`]: the passes in order. The
//! snow's time is [`clock`], the window's own saved state [`saved`], and
//! the whole-window readbacks for tools [`reads`].

pub mod characters;
pub mod clock;
mod coat;
pub mod core_window;
pub mod deformation;
mod ground_after;
pub mod inspect;
pub mod objects;
pub mod reads;
pub mod saved;
pub mod share;
#[cfg(feature = "share")]
pub mod shared_window;
pub mod skinned;
pub mod snow_frame;
pub mod steps;
#[cfg_attr(not(feature = "store"), expect(dead_code, reason = "for `StoredWindow`'s calls (feature `store`)"))]
pub mod store;
#[cfg(feature = "store")]
pub mod stored_window;
pub mod sweep;

pub use deformation::SnowDeformation;
pub use skinned::{SkinnedId, SkinnedPose};
pub use snow_frame::SnowFrame;
