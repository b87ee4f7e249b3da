//! The sliding window: where the deformation region is, snapped to whole
//! texels, and which texels a move exposes.
//!
//! Texel (i, j) of the window is the global texel (origin_row + i,
//! origin_col + j), covering world x in `(origin_col + j) * texel ..` and z in
//! `(origin_row + i) * texel ..`. Storage is toroidal: the global texel g lives
//! at `g mod resolution`, so a move rewrites only the texels it exposes.

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::shaders;

use super::resources::DeformResources;
use crate::pass::window_bindings::WindowAccess;

/// A rectangle of window-local texels: `[row0, col0, rows, cols]`.
pub type TexelRect = [u32; 4];

/// The window's position on the global texel grid.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SlidingWindow {
    resolution: u32,
    origin: Option<[i64; 2]>,
}

impl SlidingWindow {
    /// A window that has not been placed yet (the first placement exposes everything).
    #[must_use]
    pub fn new(resolution: u32) -> Self {
        Self { resolution, origin: None }
    }

    /// Global texel index `[column, row]` of local texel (0, 0), once placed.
    #[must_use]
    pub fn origin(&self) -> Option<[i64; 2]> {
        self.origin
    }

    /// The origin a window centred on world (x, z) snaps to.
    #[must_use]
    pub fn snapped_origin(&self, center_x: f64, center_z: f64, texel_m: f64) -> [i64; 2] {
        let half = i64::from(self.resolution / 2);
        [(center_x / texel_m).floor() as i64 - half, (center_z / texel_m).floor() as i64 - half]
    }

    /// Moves the window to `origin` and returns the local rectangles that are
    /// newly exposed there (empty when it did not move; at most two).
    pub fn move_to(&mut self, origin: [i64; 2]) -> Vec<TexelRect> {
        let res = self.resolution;
        let full = || vec![[0, 0, res, res]];
        let Some(old) = self.origin.replace(origin) else { return full() };
        let (dx, dz) = (origin[0] - old[0], origin[1] - old[1]);
        let r = i64::from(res);
        if dx.abs() >= r || dz.abs() >= r {
            return full();
        }
        let mut rects = Vec::new();
        // New columns, all rows.
        let (col0, cols) = if dx > 0 { ((r - dx) as u32, dx as u32) } else { (0, (-dx) as u32) };
        if cols > 0 {
            rects.push([0, col0, res, cols]);
        }
        // New rows, in the columns not already covered.
        let (rest0, rest) = if dx > 0 { (0, res - cols) } else { (cols, res - cols) };
        let (row0, rows) = if dz > 0 { ((r - dz) as u32, dz as u32) } else { (0, (-dz) as u32) };
        if rows > 0 && rest > 0 {
            rects.push([row0, rest0, rows, rest]);
        }
        rects
    }
}

// Where local (0, 0) lies in the toroidal storage: the window's layout, kept
// with its bindings below the passes that read it (the coat's too).
pub use crate::pass::window_bindings::storage_origin;

/// The exposed rectangles as a pass's uniforms take them (count, fixed
/// array) and the 2D workgroup grid of 256 that covers their texels (under
/// the 65535 per-dimension limit); `None` when there are none.
#[must_use]
pub fn rect_dispatch(rects: &[TexelRect]) -> Option<(u32, [TexelRect; 2], (u32, u32))> {
    if rects.is_empty() {
        return None;
    }
    let mut fixed = [[0; 4]; 2];
    for (slot, rect) in fixed.iter_mut().zip(rects) {
        *slot = *rect;
    }
    let texels: u32 = rects.iter().take(2).map(|r| r[2] * r[3]).sum();
    let groups = layout::groups(texels, 256);
    let grid = if groups <= 65535 { (groups, 1) } else { (65535, groups.div_ceil(65535)) };
    Some((rects.len().min(2) as u32, fixed, grid))
}

/// Uniforms of `window.wgsl` and `window_ground.wgsl` (`shared/window_params.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct WindowParams {
    /// Global texel index of local (0, 0): `[column, row]`.
    pub origin: [i32; 2],
    /// Texels per side.
    pub resolution: u32,
    /// Texel size (m).
    pub texel_m: f32,
    /// Rest depth of fresh snow (m).
    pub depth_m: f32,
    /// How many of `rects` are used.
    pub rect_count: u32,
    /// Snowfall so far on open ground (m), given to new texels.
    pub fallen_m: f32,
    /// [`WindowParams::WRITE_FALLEN`] when the `fallen` buffer is in use.
    pub flags: u32,
    /// Exposed local rectangles `[row0, col0, rows, cols]`.
    pub rects: [TexelRect; 2],
}

impl WindowParams {
    /// Write the snowfall so far into `fallen` of new texels.
    pub const WRITE_FALLEN: u32 = 1;
    /// `flags`: clear the footprints of new texels (the window has a footprint buffer).
    pub const WRITE_STAMPS: u32 = 2;
    /// `flags`: count the snow the overwritten texels held as left the
    /// window (every move but the first fill, `shared/mass_ledger.wgsl`).
    pub const COUNT_LEFT: u32 = 4;
}

/// Writes fresh, untouched snow into newly exposed texels (`window.wgsl`).
pub struct WindowPass {
    /// One pipeline per set of [`WindowParams::flags`] in use.
    pass: ComputePass<WindowParams>,
}

impl WindowPass {
    /// Builds the pipeline for `res`'s window.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        let shape = PassShape {
            label: "window",
            source: shaders::WINDOW,
            // the packed snow
            slots: &[Slot::ReadWrite],
            specialise_on: Some("PASS_FLAGS"),
            constants: &[],
            window: Some(WindowAccess::Write),
        };
        let mut pass = ComputePass::new(device, &shape, Some(&res.bindings));
        pass.bind(device, &[res.packed.as_entire_binding()]);
        Self { pass }
    }

    /// Records the exposure of `rects` (nothing when empty).
    pub fn record(&self, cx: &mut FrameContext<'_>, res: &DeformResources, mut params: WindowParams, rects: &[TexelRect]) {
        let Some((count, fixed, grid)) = rect_dispatch(rects) else { return };
        params.rect_count = count;
        params.rects = fixed;
        self.pass.record(cx, Some(&res.bindings), &params, params.flags, grid);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn count(rects: &[TexelRect]) -> u32 {
        rects.iter().map(|r| r[2] * r[3]).sum()
    }

    #[test]
    fn first_placement_and_long_jumps_expose_everything() {
        let mut w = SlidingWindow::new(64);
        assert_eq!(w.move_to([10, 20]), vec![[0, 0, 64, 64]]);
        assert_eq!(w.move_to([10 + 64, 20]), vec![[0, 0, 64, 64]]);
    }

    #[test]
    fn moves_expose_exactly_the_new_texels() {
        for (dx, dz) in [(3i64, 0i64), (-3, 0), (0, 5), (0, -5), (2, 7), (-9, 4), (5, -1), (-2, -2), (0, 0)] {
            let mut w = SlidingWindow::new(32);
            w.move_to([100, -50]);
            let rects = w.move_to([100 + dx, -50 + dz]);
            let expected = 32 * 32 - (32 - dx.unsigned_abs() as u32) * (32 - dz.unsigned_abs() as u32);
            assert_eq!(count(&rects), expected, "move ({dx}, {dz}): {rects:?}");
            // Every exposed texel is outside the old window; none is counted twice.
            let mut seen = std::collections::HashSet::new();
            for r in &rects {
                for i in r[0]..r[0] + r[2] {
                    for j in r[1]..r[1] + r[3] {
                        let (gc, gr) = (100 + dx + i64::from(j), -50 + dz + i64::from(i));
                        let inside_old = (100..132).contains(&gc) && (-50..-18).contains(&gr);
                        assert!(!inside_old, "({i}, {j}) was already in the window");
                        assert!(seen.insert((i, j)));
                    }
                }
            }
        }
    }

    #[test]
    fn snapping_is_to_whole_texels() {
        let w = SlidingWindow::new(16);
        assert_eq!(w.snapped_origin(0.0, 0.0, 0.5), [-8, -8]);
        assert_eq!(w.snapped_origin(0.49, -0.01, 0.5), [-8, -9]);
        assert_eq!(w.snapped_origin(1.0, 0.0, 0.5), [-6, -8]);
    }

    /// The wrapped origin plus a local texel, wrapped by one comparison (as
    /// `storage_index_wrapped` does), is the CPU twin's storage index.
    #[test]
    fn the_wrapped_origin_gives_every_texel_its_storage_index() {
        for res in [1u32, 7, 96, 512] {
            for origin in [[0, 0], [-1, 5], [i32::MIN, i32::MAX], [-300, 299], [1023, -1024]] {
                let [wx, wy] = storage_origin(origin, res);
                assert!(wx < res && wy < res);
                for (i, j) in [(0, 0), (res - 1, 0), (0, res - 1), (res / 2, res - 1)] {
                    let wrap = |o: u32, k: u32| if o + k >= res { o + k - res } else { o + k };
                    let index = wrap(wy, i) as usize * res as usize + wrap(wx, j) as usize;
                    let r = i64::from(res);
                    let si = (i64::from(origin[1]) + i64::from(i)).rem_euclid(r) as usize;
                    let sj = (i64::from(origin[0]) + i64::from(j)).rem_euclid(r) as usize;
                    assert_eq!(index, si * res as usize + sj, "res {res}, origin {origin:?}, texel ({i}, {j})");
                }
            }
        }
    }
}
