//! Window ground pass (`window_ground.wgsl`): over noise hills, the terrain
//! under each texel a move exposed, stored in the window's ground so the
//! passes that visit every texel every frame read it instead of evaluating
//! the noise (`DeformResources::stores_ground`, `docs/deformation.md`,
//! "The window's ground").

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::shaders;

use super::resources::DeformResources;
use super::window::{TexelRect, rect_dispatch};

/// Uniforms of `window_ground.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct WindowGroundParams {
    /// Global texel index of local (0, 0): `[column, row]`.
    pub origin: [i32; 2],
    /// Texels per side.
    pub resolution: u32,
    /// Texel size (m).
    pub texel_m: f32,
    /// How many of `rects` are used ([`WindowGroundPass::record`] sets it).
    pub rect_count: u32,
    /// Padding to the rectangles' 16-byte alignment.
    pub _pad: [u32; 3],
    /// Exposed local rectangles `[row0, col0, rows, cols]` ([`WindowGroundPass::record`] sets them).
    pub rects: [TexelRect; 2],
}

/// Stores the terrain under the texels a move exposed (noise hills only).
pub struct WindowGroundPass {
    /// `None` where the window stores no ground (flat, heightmap, mesh).
    pass: Option<ComputePass<WindowGroundParams>>,
}

impl WindowGroundPass {
    /// Builds the pipeline where `res` stores its ground.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        if !res.stores_ground() {
            return Self { pass: None };
        }
        let shape = PassShape {
            label: "window ground",
            source: shaders::WINDOW_GROUND,
            slots: &[Slot::Uniform, Slot::ReadWrite],
            specialise_on: None,
            constants: &res.terrain_constants(),
            window: None,
        };
        let mut pass = ComputePass::new(device, &shape, None);
        pass.bind(device, &[res.terrain_params.as_entire_binding(), res.heightmap.as_entire_binding()]);
        Self { pass: Some(pass) }
    }

    /// Records the ground of `rects` (nothing when empty or not stored).
    pub fn record(&self, cx: &mut FrameContext<'_>, mut params: WindowGroundParams, rects: &[TexelRect]) {
        let Some(pass) = &self.pass else { return };
        let Some((count, fixed, grid)) = rect_dispatch(rects) else { return };
        params.rect_count = count;
        params.rects = fixed;
        pass.record(cx, None, &params, 0, grid);
    }
}
