//! The world's tiles around the window, kept while the window is away
//! (the persistence side of the deformation): the resident slots and their
//! traffic with the tile keeper ([`streaming`]), and their passes: texels
//! between the window and the slots ([`exchange`]), tiles made resident
//! ([`restore`]), time passing on the resident tiles outside the window
//! ([`weather`]) and tiles made ready to leave ([`seal`]). The orchestrator ([`crate::snow::SnowDeformation`])
//! records them through [`crate::frame::FrameContext`]; the core
//! deformation knows nothing of them.

pub mod exchange;
pub mod restore;
pub mod seal;
pub mod streaming;
pub mod weather;

pub use streaming::{TileGrid, TileStats, TileStreaming};
