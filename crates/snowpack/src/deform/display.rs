//! Display pass: the displayed snow height, rims and blur fused in one
//! dispatch (`display.wgsl`), into the upper half of each `snow` word.

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape};
use crate::shaders;

use super::resources::DeformResources;
use crate::pass::window_bindings::WindowAccess;

/// Uniforms of `display.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct DisplayParams {
    /// Global texel index of local (0, 0): `[column, row]`.
    pub origin: [i32; 2],
    /// Texels per side.
    pub resolution: u32,
    /// Rest depth of snow (m).
    pub depth_m: f32,
    /// Rim strength: blend of the cubic remap (mode 0), or rim height scale (modes 1, 2).
    pub elevation: f32,
    /// 0 Hanák's remap, 1 MS16 point rims, 2 rounded point rims ([`DisplayParams::mode_for`]).
    pub mode: u32,
    /// Height of stamp code 0 (m).
    pub low_m: f32,
    /// Height of stamp code 65535 (m).
    pub high_m: f32,
    /// 1 when the rest depth includes the `fallen` buffer (snowfall so far).
    pub use_fallen: u32,
    /// Texel size (m): where the terrain is evaluated.
    pub texel_m: f32,
    /// 1: blur the rimmed height (the 5x5 Gaussian); 0: show it as it is.
    pub blur: u32,
    /// Snowfall so far on open ground (m): lying snow beyond it is a berm
    /// (displacement), shown as it is above the remapped undisturbed depth.
    pub open_fallen_m: f32,
    /// `origin` wrapped into the storage (`super::window::storage_origin`):
    /// [`DisplayPass::record`] writes it from `origin` and `resolution`, so
    /// the value given here is not used.
    pub storage_origin: [u32; 2],
}

impl DisplayParams {
    /// The rim mode of a technique: rims from points where points are stamped.
    #[must_use]
    pub fn mode_for(technique: crate::Technique, style: crate::RimStyle) -> u32 {
        use crate::{RimStyle, Technique};
        match (technique, style) {
            (Technique::Depth | Technique::Decals, _) => 0,
            (Technique::Points | Technique::Combined, RimStyle::Ms16) => 1,
            (Technique::Points | Technique::Combined, RimStyle::Rounded) => 2,
        }
    }

    /// The choices a display pipeline is built for (`DISPLAY_VARIANT` in
    /// `display.wgsl`): `mode | blur << 2 | use_fallen << 3 | bare << 4`,
    /// where bare is no snow at all (`depth_m` 0 and no snowfall).
    #[must_use]
    pub fn variant(&self) -> u32 {
        let bare = self.use_fallen == 0 && self.depth_m <= 0.0;
        (self.mode & 3) | (u32::from(self.blur != 0) << 2) | (u32::from(self.use_fallen != 0) << 3) | (u32::from(bare) << 4)
    }
}

/// How the display pass maps its work onto invocations (issue 44, item 1).
/// Both read a texel's word and ground once and give the same words, bit
/// for bit; which is faster depends on the adapter, and `snowpack bench
/// --only display` measures them side by side.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "the other kernel is chosen by the bench and the tests (`low_level`)"))]
pub enum DisplayKernel {
    /// Four blurred outputs an invocation from eight workgroup-memory reads
    /// along each axis; a quarter of the invocations write, the tile's
    /// words and ground kept in workgroup memory for them.
    Blur4,
    /// One texel an invocation: its word and ground stay in registers from
    /// the first read to the write, every invocation writes, five
    /// workgroup-memory reads an output along each axis. The default: on
    /// lavapipe as fast as blur4 over flat ground and a quarter faster over
    /// noise hills.
    #[default]
    PerTexel,
}

impl DisplayKernel {
    /// Both kernels, in the bench's order.
    #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the bench and the tests (`low_level`)"))]
    pub const ALL: [Self; 2] = [Self::Blur4, Self::PerTexel];

    /// The kernel's bit in `DISPLAY_VARIANT`.
    fn variant_bit(self) -> u32 {
        match self {
            Self::Blur4 => 0,
            Self::PerTexel => 1 << 5,
        }
    }
}

/// Writes the displayed height of every texel (upper halves of `res.snow`).
pub struct DisplayPass {
    /// One pipeline per [`DisplayParams::variant`] and kernel in use.
    pass: ComputePass<DisplayParams>,
    kernel: DisplayKernel,
}

impl DisplayPass {
    /// Compiles the shader for `res`'s terrain; the pipeline for a
    /// [`DisplayParams::variant`] is built on its first frame.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        let shape = PassShape {
            label: "display",
            source: shaders::DISPLAY,
            slots: &[],
            specialise_on: Some("DISPLAY_VARIANT"),
            constants: &res.terrain_constants(),
            window: Some(WindowAccess::Write),
        };
        let mut pass = ComputePass::new(device, &shape, Some(&res.bindings));
        pass.bind(device, &[]);
        Self { pass, kernel: DisplayKernel::default() }
    }

    /// The kernel the pass records.
    #[must_use]
    pub fn kernel(&self) -> DisplayKernel {
        self.kernel
    }

    /// Records with `kernel` from the next frame on (its pipelines built on first use).
    pub fn set_kernel(&mut self, kernel: DisplayKernel) {
        self.kernel = kernel;
    }

    /// Records this frame's display.
    pub fn record(&self, cx: &mut FrameContext<'_>, res: &DeformResources, params: &DisplayParams) {
        let params = &DisplayParams { storage_origin: super::window::storage_origin(params.origin, params.resolution), ..*params };
        let g = layout::groups(params.resolution, 16);
        self.pass.record(cx, Some(&res.bindings), params, params.variant() | self.kernel.variant_bit(), (g, g));
    }
}

/// Unit normals by central differences of window-local displayed heights
/// (clamped at the edges), as the renderer's surface pass and the point
/// queries compute them.
#[must_use]
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
pub fn normals_of(height: &[f32], resolution: u32, texel_m: f32) -> Vec<[f32; 3]> {
    let r = resolution as i32;
    let at = |i: i32, j: i32| height[(i.clamp(0, r - 1) * r + j.clamp(0, r - 1)) as usize];
    let mut out = Vec::with_capacity(height.len());
    for i in 0..r {
        for j in 0..r {
            let dx = at(i, j + 1) - at(i, j - 1);
            let dz = at(i + 1, j) - at(i - 1, j);
            out.push(glam::Vec3::new(-dx, 2.0 * texel_m, -dz).normalize().to_array());
        }
    }
    out
}
