//! Displace pass: snow a press squeezes beyond the final density moves to
//! the texels beside it as lying snow, the berms (`displace.wgsl`, CPU twin
//! `cpu/displace.rs`; `docs/mechanics.md`, "Displacement"). The update
//! chooses each move and writes it into the upper half of the snow word;
//! this pass gathers the moves at their targets. Runs only for a window
//! that displaces ([`crate::SnowParams::displace`]).
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, reason = "the move's table and codes are the CPU twin's and the tests' (`snowpack_testkit::cpu`); the shader has its own")
)]

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::pass::window_bindings::WindowAccess;
use crate::shaders;

use super::resources::DeformResources;

/// The most snow quanta a texel sends in one frame (`DISPLACE_MOST_Q`): 11
/// bits of 16-quantum steps, 3.3 m (less than 1.6 mm stays packed).
pub const MOST_QUANTA: u32 = 32752;

/// The 5x5 around a texel without its centre, `[column, row]` offsets, rows
/// first (`displace_offset`; the order breaks ties).
pub const OFFSETS: [[i32; 2]; 24] = {
    let mut out = [[0; 2]; 24];
    let mut k = 0;
    let mut n = 0;
    while n < 25 {
        if n != 12 {
            out[k] = [n % 5 - 2, n / 5 - 2];
            k += 1;
        }
        n += 1;
    }
    out
};

/// The upper-half code of a texel the actors press that sends nothing
/// (`DISPLACE_PRESSED`): the erosion leaves it be.
pub const PRESSED: u32 = 31 << 11;

/// The upper-half code of a move of `quanta` (a multiple of 16, at most
/// [`MOST_QUANTA`]) to offset index `target` (`displace_code`).
#[must_use]
pub const fn code(target: usize, quanta: u32) -> u32 {
    ((target as u32 + 1) << 11) | (quanta >> 4)
}

/// The offset index + 1 a move's `code` names (0: none).
#[must_use]
pub const fn code_target(code: u32) -> u32 {
    code >> 11
}

/// The quanta a move's `code` carries.
#[must_use]
pub const fn code_quanta(code: u32) -> u32 {
    (code & 0x7ff) << 4
}

/// Uniforms of `displace.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct DisplaceParams {
    /// Global texel index of local (0, 0): `[column, row]`.
    pub origin: [i32; 2],
    /// Texels per side.
    pub resolution: u32,
    /// [`Self::SHARE`] or 0.
    pub flags: u32,
    /// `origin` wrapped into the storage; [`DisplacePass::record`] sets it.
    pub storage_origin: [u32; 2],
    /// Tile side of the changed-tile flags (texels; with [`Self::SHARE`]).
    pub share_side: u32,
    /// Slots per side of the flags.
    pub share_keys: u32,
}

impl DisplaceParams {
    /// Shared snow: a texel that gains snow flags its tile.
    pub const SHARE: u32 = 1;
}

/// Gathers the update's moves into the berms.
pub struct DisplacePass {
    pass: ComputePass<DisplaceParams>,
}

impl DisplacePass {
    /// Builds the pipeline over `res`'s window.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        let shape = PassShape {
            label: "displace",
            source: shaders::DISPLACE,
            // the changed-tile flags
            slots: &[Slot::ReadWrite],
            specialise_on: Some("DISPLACE_FLAGS"),
            constants: &[],
            window: Some(WindowAccess::Write),
        };
        let mut pass = ComputePass::new(device, &shape, Some(&res.bindings));
        pass.bind(device, &[res.share_flags.as_entire_binding()]);
        Self { pass }
    }

    /// Binds the window's changed-tile flags again (after sharing allocated them).
    pub fn bind_flags(&mut self, device: &wgpu::Device, res: &DeformResources) {
        self.pass.bind(device, &[res.share_flags.as_entire_binding()]);
    }

    /// Records the gather for this frame.
    pub fn record(&self, cx: &mut FrameContext<'_>, res: &DeformResources, params: &DisplaceParams) {
        let p = DisplaceParams { storage_origin: super::window::storage_origin(params.origin, params.resolution), ..*params };
        let g = layout::groups(params.resolution, 16);
        self.pass.record(cx, Some(&res.bindings), &p, p.flags, (g, g));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_are_the_5x5_without_its_centre_rows_first() {
        assert_eq!(OFFSETS[0], [-2, -2]);
        assert_eq!(OFFSETS[11], [-1, 0]);
        assert_eq!(OFFSETS[12], [1, 0]);
        assert_eq!(OFFSETS[23], [2, 2]);
        assert!(!OFFSETS.contains(&[0, 0]));
        let moved = code(23, MOST_QUANTA);
        assert_eq!((code_target(moved), code_quanta(moved)), (24, MOST_QUANTA));
        assert!(moved <= 0xffff);
    }
}
