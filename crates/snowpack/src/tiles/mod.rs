//! The world's tiles around the window, kept while the window is away
//! (the persistence side of the deformation): the resident slots and their
//! traffic with the tile keeper ([`streaming`]), a slot's layout
//! ([`planes`]), and their passes: texels
//! between the window and the slots ([`exchange`]), tiles made resident
//! ([`restore`]), time passing on the resident tiles outside the window
//! ([`weather`]) and tiles made ready to leave ([`seal`]). The orchestrator ([`crate::snow::SnowDeformation`])
//! records them through [`crate::frame::FrameContext`]; the core
//! deformation knows nothing of them.

pub mod exchange;
pub mod grid;
pub mod planes;
pub mod restore;
pub mod seal;
mod slots;
pub mod streaming;
pub mod weather;

pub use streaming::{TileStats, TileStreaming};

/// A storage buffer the CPU fills through the queue (a tile pass's entry
/// list or upload), at least 16 bytes.
pub(crate) fn input_buffer(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}
