//! Capture pass: actors' lowest surfaces, seen from below the terrain.
//!
//! Depth is linear in world height between `low_m` (depth 0) and `high_m`
//! (depth 1), quantised to 16-bit codes, and the lowest surface per texel
//! wins. Every deformer is swept over its motion since the last frame (see
//! [`super::sweep`]): spheres as capsules, boxes, tyres and meshes in
//! sub-steps. Actors outside the window leave no mark.
//!
//! Two parts, each recorded only when it has something to capture; the
//! update reads the lower of the two ([`CapturePass::update_flags`]):
//! - the analytic shapes (spheres, tyres with their tread, boxes), exact,
//!   either ray cast by compute over the tiles they reach
//!   ([`super::capture_shapes`], [`ShapeCapture::Compute`]) or drawn as
//!   impostors and cubes into the depth target ([`ShapeCapture::Raster`]);
//! - meshes (skinned characters, caller meshes), always drawn into the
//!   capture depth target ([`super::capture_draw`]).
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

pub use super::capture_instances::{CaptureInstances, CaptureMesh, CaptureParams, SweptMesh};

use crate::frame::FrameContext;

use super::capture_draw::CaptureDrawPass;
use super::capture_shapes::{ShapeCapturePass, Shapes};
use super::resources::DeformResources;
use super::update::UpdateParams;

/// How the capture takes the analytic shapes (spheres, tyres, boxes). Both
/// give the same codes at texel centres (boxes by compute are exact where
/// the drawn cubes may miss or gain a silhouette texel); they differ in
/// cost, and which is cheaper depends on the adapter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShapeCapture {
    /// Ray cast by compute, each 16×16-texel tile against the shapes over
    /// it: no rasteriser and no depth target (`capture_shapes.wgsl`).
    Compute,
    /// Drawn into the depth target: impostor quads for spheres and tyres,
    /// cubes for boxes. A software rasteriser shades only the texels a
    /// shape covers, where compute ray casts whole tiles: several times
    /// cheaper there.
    Raster,
}

impl ShapeCapture {
    /// The choice for an adapter: `SNOWPACK_SHAPE_CAPTURE` (`compute` or
    /// `raster`) when set, else drawing on a software rasteriser
    /// (`software`) and compute on a GPU.
    #[must_use]
    pub fn for_adapter(software: bool) -> Self {
        match std::env::var("SNOWPACK_SHAPE_CAPTURE").as_deref() {
            Ok("compute") => Self::Compute,
            Ok("raster") => Self::Raster,
            _ if software => Self::Raster,
            _ => Self::Compute,
        }
    }

    /// The choice for shared snow on any adapter: `SNOWPACK_SHAPE_CAPTURE`
    /// when set, else compute, whose arithmetic the peers' and the relay's
    /// CPU presses of the same shapes repeat bit for bit
    /// (`snowpack_share::replicate::press`), so the shapes travel instead of the snow.
    #[must_use]
    pub fn for_shared_snow() -> Self {
        Self::for_adapter(false)
    }
}

/// The capture: see the module documentation.
pub struct CapturePass {
    /// The analytic shapes by compute.
    shapes: ShapeCapturePass,
    /// The depth target's draw: meshes, and the shapes when drawn.
    draw: CaptureDrawPass,
    /// How the shapes are taken.
    by: ShapeCapture,
    /// What the last record captured, as the update's flags.
    captured: u32,
}

impl CapturePass {
    /// Builds both parts' pipelines; the shapes taken `by` compute or drawn.
    #[must_use]
    pub fn new(device: &wgpu::Device, by: ShapeCapture) -> Self {
        Self { shapes: ShapeCapturePass::new(device), draw: CaptureDrawPass::new(device), by, captured: 0 }
    }

    /// How the shapes are taken.
    #[must_use]
    pub fn shape_capture(&self) -> ShapeCapture {
        self.by
    }

    /// Takes the shapes `by` compute or drawn from the next record on.
    pub fn set_shape_capture(&mut self, by: ShapeCapture) {
        self.by = by;
    }

    /// What recording `inst` and `meshes` writes: (the shapes' codes by
    /// compute, the depth target), each of which must then be the window's
    /// size ([`DeformResources::allocate_capture`]).
    #[must_use]
    pub fn writes(&self, inst: &CaptureInstances, meshes: &[SweptMesh<'_>]) -> (bool, bool) {
        let shapes = shapes_of(inst).count() > 0;
        (shapes && self.by == ShapeCapture::Compute, !meshes.is_empty() || (shapes && self.by == ShapeCapture::Raster))
    }

    /// Records this frame's capture of `inst`'s shapes and the world-space
    /// `meshes` (mesh k swept over the sub-steps
    /// [`CaptureInstances::mesh_steps`]`[k]` where it has previous
    /// positions). A part with nothing to capture is not recorded;
    /// [`Self::update_flags`] then tells the update what to read. The one
    /// form of the presses' passes: the stamp pass and the decal pass record
    /// the same way (what, where, one call).
    pub fn record(&mut self, cx: &mut FrameContext<'_>, res: &DeformResources, (params, inst): (&CaptureParams, &CaptureInstances), meshes: &[SweptMesh<'_>]) {
        self.captured = 0;
        let (computes, draws) = self.writes(inst, meshes);
        if !res.holds_capture((computes, draws)) {
            tracing::error!("a capture recorded before DeformResources::allocate_capture: skipped");
            return;
        }
        if computes && self.shapes.record(cx, res, [params.low_m, params.high_m], shapes_of(inst)) {
            self.captured |= UpdateParams::CAPTURE_SHAPES;
        }
        if draws {
            self.draw.record(cx, res, (params, inst), meshes, self.by == ShapeCapture::Raster);
            self.captured |= UpdateParams::CAPTURE_DRAWN;
        }
    }

    /// What the last [`Self::record`] captured, as
    /// [`UpdateParams::CAPTURE_SHAPES`] (the shapes by compute) and
    /// [`UpdateParams::CAPTURE_DRAWN`] (the depth target): the update reads
    /// those (with [`UpdateParams::USE_CAPTURE`]) and nothing else.
    #[must_use]
    pub fn update_flags(&self) -> u32 {
        self.captured
    }
}

/// `inst`'s analytic shapes.
fn shapes_of(inst: &CaptureInstances) -> Shapes<'_> {
    Shapes { capsules: &inst.capsules, wheels: &inst.wheels, boxes: &inst.boxes }
}
