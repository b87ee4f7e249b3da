//! Erosion pass: walls steeper than the snow's angle of repose slide into
//! the trench beside them (`erosion.wgsl`, CPU twin `cpu/erosion.rs`;
//! `docs/mechanics.md`, "Erosion"). One iteration a frame (four while the
//! window displaces snow: a plough's windrow arrives faster than one
//! settles it), four dispatches of neighbouring pairs each; off unless the
//! snow has an angle of repose
//! ([`crate::SnowParams::repose_deg`]).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::pass::window_bindings::WindowAccess;
use crate::shaders;

use super::resources::DeformResources;
use super::snow_word::SNOW_QUANTA_PER_M;

/// Uniforms of `erosion.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ErosionParams {
    /// Global texel index of local (0, 0): `[column, row]`.
    pub origin: [i32; 2],
    /// Texels per side.
    pub resolution: u32,
    /// Texel size (m).
    pub texel_m: f32,
    /// `origin` wrapped into the storage; [`ErosionPass::record`] sets it.
    pub storage_origin: [u32; 2],
    /// Rest depth of snow (m).
    pub depth_m: f32,
    /// The steepest step between neighbouring deficits that holds (snow
    /// quanta): `tan(repose) × texel` ([`Self::threshold_quanta`]).
    pub threshold_q: u32,
    /// 0: pairs along x, 1: along z.
    pub axis: u32,
    /// 0: pairs from even indices, 1: from odd.
    pub offset: u32,
    /// 1 when the rest height includes the snowfall so far.
    pub use_fallen: u32,
    /// 1 when the update marked the texels the actors press (a window that
    /// displaces, [`super::displace::PRESSED`]): no snow slides into or
    /// out of them.
    pub marks: u32,
}

impl ErosionParams {
    /// One iteration's half-sweeps, in order: `(axis, offset)`.
    pub const SWEEPS: [(u32, u32); 4] = [(0, 0), (0, 1), (1, 0), (1, 1)];

    /// The step (snow quanta) between neighbouring texels `texel_m` apart
    /// that a slope of `repose_deg` allows.
    #[must_use]
    pub fn threshold_quanta(repose_deg: f32, texel_m: f32) -> u32 {
        (repose_deg.to_radians().tan() * texel_m * SNOW_QUANTA_PER_M).floor().clamp(0.0, 65_535.0) as u32
    }
}

/// The four half-sweeps of an iteration, each with its own uniform.
pub struct ErosionPass {
    sweeps: [ComputePass<ErosionParams>; 4],
}

impl ErosionPass {
    /// Builds the pipeline over `res`'s window.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        let shape = PassShape {
            label: "erosion",
            source: shaders::EROSION,
            // the packed snow
            slots: &[Slot::ReadWrite],
            specialise_on: None,
            constants: &res.terrain_constants(),
            window: Some(WindowAccess::Write),
        };
        let first = ComputePass::new(device, &shape, Some(&res.bindings));
        let mut sweeps = [first.sibling(device), first.sibling(device), first.sibling(device), first];
        for pass in &mut sweeps {
            pass.bind(device, &[res.packed.as_entire_binding()]);
        }
        Self { sweeps }
    }

    /// Records `iterations` iterations (the four half-sweeps each) of `params`.
    pub fn record(&self, cx: &mut FrameContext<'_>, res: &DeformResources, params: &ErosionParams, iterations: u32) {
        let storage_origin = super::window::storage_origin(params.origin, params.resolution);
        let pairs = layout::groups(params.resolution.div_ceil(2), 16);
        let rows = layout::groups(params.resolution, 16);
        for _ in 0..iterations {
            for (pass, (axis, offset)) in self.sweeps.iter().zip(ErosionParams::SWEEPS) {
                let p = ErosionParams { storage_origin, axis, offset, ..*params };
                pass.record(cx, Some(&res.bindings), &p, 0, (pairs, rows));
            }
        }
    }
}
