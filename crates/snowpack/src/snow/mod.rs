//! The snow a game drives: [`SnowDeformation`] puts the core deformation
//! ([`crate::deform`]) together with what plugs into it: accumulation on
//! objects ([`crate::accumulate`]), the tiles kept while the window is away
//! and their save ([`crate::tiles`], [`crate::persist`]) and skinned
//! characters ([`crate::skin`]), recording each frame's passes in order
//! ([`deformation`]) saving the window's own state ([`saved`]) and sharing its snow with
//! other machines ([`share`]).

mod coat;
pub mod deformation;
pub mod saved;
pub mod share;
pub mod sweep;

pub use deformation::{SkinnedId, SkinnedPose, SnowDeformation, SnowFrame};
