//! Window ground pass (`window_ground.wgsl`): over noise hills, the terrain
//! under each texel a move exposed, stored in the window's ground so the
//! passes that visit every texel every frame read it instead of evaluating
//! the noise (`DeformResources::stores_ground`, `docs/deformation.md`,
//! "The window's ground").

use crate::frame::FrameContext;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::shaders;

use super::resources::DeformResources;
use super::window::{TexelRect, WindowParams, rect_dispatch};

/// Stores the terrain under the texels a move exposed (noise hills only).
pub struct WindowGroundPass {
    /// `None` where the window stores no ground (flat, heightmap, mesh).
    pass: Option<ComputePass<WindowParams>>,
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

    /// Records the ground of `rects` (nothing when empty or not stored),
    /// with the window pass's uniforms (it reads `origin`, `resolution` and
    /// `texel_m`; the rectangles are set here).
    pub fn record(&self, cx: &mut FrameContext<'_>, mut params: WindowParams, rects: &[TexelRect]) {
        let Some(pass) = &self.pass else { return };
        let Some((count, fixed, grid)) = rect_dispatch(rects) else { return };
        params.rect_count = count;
        params.rects = fixed;
        pass.record(cx, None, &params, 0, grid);
    }
}
