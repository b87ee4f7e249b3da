//! What one frame's recording hands to every pass and to the parts that
//! plug into the core deformation (accumulation on objects, the tiles kept
//! for the world, skinning, shared snow): the GPU handles to record with
//! ([`FrameContext`], the first argument of every pass's `record`) and where
//! the window is this frame ([`WindowFrame`]). The orchestrator
//! ([`crate::snow::SnowDeformation`]) makes both; the plug-ins need nothing
//! else of the deformation, so neither side imports the other.

use glam::DVec2;

use crate::gpu::{GpuContext, GpuTimer};

/// The handles a pass records its part of a frame with: the device and
/// queue, the frame's encoder and its timer (each pass reserves a timing
/// slot). Every pass's `record` takes it first, as `&mut FrameContext`, so
/// one context is made per frame (or per submit, for work recorded outside
/// a frame) and handed down through the plug-ins to their passes.
pub struct FrameContext<'a> {
    /// Device and queue (uploads, buffers made on demand).
    pub gpu: &'a GpuContext,
    /// The frame's command encoder.
    pub encoder: &'a mut wgpu::CommandEncoder,
    /// The frame's per-pass timer.
    pub timer: &'a mut GpuTimer,
}

impl<'a> FrameContext<'a> {
    /// The handles for recording into `encoder`, timed by `timer`.
    pub fn new(gpu: &'a GpuContext, encoder: &'a mut wgpu::CommandEncoder, timer: &'a mut GpuTimer) -> Self {
        Self { gpu, encoder, timer }
    }

    /// The same device and encoder timed by `timer` instead (for example
    /// [`GpuTimer::disabled`] for passes that should not take a timing slot).
    pub fn with_timer<'b>(&'b mut self, timer: &'b mut GpuTimer) -> FrameContext<'b> {
        FrameContext { gpu: self.gpu, encoder: &mut *self.encoder, timer }
    }

    /// The device's queue (the passes' uniform uploads).
    #[must_use]
    pub fn queue(&self) -> &'a wgpu::Queue {
        &self.gpu.queue
    }

    /// The device (buffers and bind groups made on demand).
    #[must_use]
    pub fn device(&self) -> &'a wgpu::Device {
        &self.gpu.device
    }
}

/// Where the deformation window is this frame and what the snow in it is
/// like: what a plug-in needs to place its work against the window's
/// texels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WindowFrame {
    /// Global texel index `[column, row]` of the window's local texel (0, 0).
    pub origin: [i64; 2],
    /// World (x, z) of the window's corner (local texel (0, 0)'s outer
    /// corner), relative to the floating origin like deformer and object
    /// positions (m).
    pub corner: DVec2,
    /// Texels per side of the window.
    pub resolution: u32,
    /// Side of the window (m).
    pub extent_m: f32,
    /// Texel size (m).
    pub texel_m: f32,
    /// Rest depth of fresh snow above the terrain (m).
    pub depth_m: f32,
    /// Snowfall so far on open ground at the start of this frame (m): what
    /// freshly exposed texels and fresh tiles get.
    pub fallen_m: f32,
    /// Most snowfall a texel keeps above the rest depth (m); 0 without snowfall.
    pub max_fallen_m: f32,
    /// Whether the world has snowfall (the window a snowfall buffer).
    pub use_fallen: bool,
    /// Bottom of the capture and footprint height range (m).
    pub low_m: f32,
    /// Top of the capture and footprint height range (m).
    pub high_m: f32,
    /// Lowest and highest terrain height anywhere (m).
    pub terrain_m: (f32, f32),
}

impl WindowFrame {
    /// From the lowest terrain to the highest rest surface of the snow (m):
    /// the heights the sky's view of the ground must cover.
    #[must_use]
    pub fn ground_range_m(&self) -> (f32, f32) {
        (self.terrain_m.0, self.terrain_m.1 + self.depth_m + self.fallen_m)
    }
}
