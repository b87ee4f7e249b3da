//! The capture's analytic shapes by compute (`capture_shapes.wgsl`): every
//! sphere swept over the frame (a capsule), tyre pose and box, ray cast
//! from below at each window texel's centre, without a rasteriser or a
//! depth target.
//!
//! The CPU bins the shapes into the window's 16×16-texel tiles by their
//! bounds (half a texel wider than the shape) with a counting sort
//! ([`ShapeBins`]); the capture buffer is cleared to "nothing" (a fill, 2
//! bytes a texel: the pass's floor), and one workgroup runs per tile that
//! holds a shape, each invocation ray casting its two texels against that
//! tile's list only. A window with a few actors touches a few tiles: the
//! cost beyond the fill is the texels of those tiles times the shapes over
//! them. (A first version that ray cast every texel of the window, empty
//! tiles included, took lavapipe 93 ms for 256 spheres; this one 8 ms:
//! `docs/PERFORMANCE.md`.) The result is the capture depth's 16-bit code,
//! two texels a word
//! (`res.capture_shapes`), the same code the depth target holds for the
//! meshes; the update reads the lower of both.
//!
//! A box is ray cast against its inverse model matrix, inverted here on the
//! CPU (as the twin does), so a box is exact too.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec4};

use crate::frame::FrameContext;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::shaders;

use super::resources::DeformResources;

/// Uniforms of `capture_shapes.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ShapeParams {
    /// Texel size (m).
    pub texel_m: f32,
    /// World height at depth 0 (m).
    pub low_m: f32,
    /// World height at depth 1 (m).
    pub high_m: f32,
    /// Texels per window side (a multiple of 16).
    pub resolution: u32,
    /// Capsules first in the list.
    pub capsules: u32,
    /// Tyre poses after them; boxes last.
    pub wheels: u32,
    /// Workgroups per row of the dispatch.
    pub row: u32,
    /// Padding to 16 bytes.
    pub _pad: u32,
}

/// A frame's analytic shapes, window-local, as
/// [`super::capture::CaptureInstances`] lists them.
#[derive(Clone, Copy, Debug)]
pub struct Shapes<'a> {
    /// Per sphere swept over the frame: `[ax, ay, az, radius, bx, by, bz, 0]`.
    pub capsules: &'a [[f32; 8]],
    /// Per tyre pose: [`super::wheel::instance`].
    pub wheels: &'a [[f32; 16]],
    /// Per box pose: its column-major model matrix (of the unit cube).
    pub boxes: &'a [[f32; 16]],
}

impl Shapes<'_> {
    /// How many shapes there are.
    #[must_use]
    pub fn count(&self) -> usize {
        self.capsules.len() + self.wheels.len() + self.boxes.len()
    }
}

/// Texels per side of the tile a workgroup ray casts.
const TILE: u32 = 16;

/// The shapes as `capture_shapes.wgsl` reads them, and where they reach.
#[derive(Clone, Debug, Default)]
pub struct ShapeList {
    /// Per shape its bounds (as [`Self::bounds`]), then a capsule's two
    /// ends (start xyz and radius, end xyz: three `vec4` in all), a tyre's
    /// instance or a box's inverse model matrix (five); capsules, then
    /// tyres, then boxes.
    pub data: Vec<[f32; 4]>,
    /// Per shape the window-local rectangle (x0, z0, x1, z1, m) outside
    /// which it captures nothing: its footprint, half a texel wider.
    pub bounds: Vec<[f32; 4]>,
}

/// Fills `out` with `inst`'s shapes (cleared first, its memory kept).
pub fn shape_list(inst: Shapes<'_>, texel_m: f32, out: &mut ShapeList) {
    out.data.clear();
    out.bounds.clear();
    out.data.reserve(3 * inst.capsules.len() + 5 * (inst.wheels.len() + inst.boxes.len()));
    out.bounds.reserve(inst.count());
    let pad = 0.5 * texel_m;
    let mut shape = |[x0, z0, x1, z1]: [f32; 4], data: &[[f32; 4]]| {
        let bounds = [x0 - pad, z0 - pad, x1 + pad, z1 + pad];
        out.bounds.push(bounds);
        out.data.push(bounds);
        out.data.extend_from_slice(data);
    };
    for c in inst.capsules {
        let r = c[3];
        let bounds = [c[0].min(c[4]) - r, c[2].min(c[6]) - r, c[0].max(c[4]) + r, c[2].max(c[6]) + r];
        shape(bounds, &[[c[0], c[1], c[2], c[3]], [c[4], c[5], c[6], c[7]]]);
    }
    for w in inst.wheels {
        let reach = w[3].hypot(w[7]);
        let data = [[w[0], w[1], w[2], w[3]], [w[4], w[5], w[6], w[7]], [w[8], w[9], w[10], w[11]], [w[12], w[13], w[14], w[15]]];
        shape([w[0] - reach, w[2] - reach, w[0] + reach, w[2] + reach], &data);
    }
    for m in inst.boxes {
        let model = Mat4::from_cols_array(m);
        // The unit cube's shadow: the centre plus each axis's reach.
        let (c, [a, b, d]) = (model.w_axis, [model.x_axis, model.y_axis, model.z_axis]);
        let reach = |k: usize| a[k].abs() + b[k].abs() + d[k].abs();
        let inv = model.inverse();
        shape([c.x - reach(0), c.z - reach(2), c.x + reach(0), c.z + reach(2)], &[inv.x_axis, inv.y_axis, inv.z_axis, inv.w_axis].map(|v: Vec4| v.to_array()));
    }
}

/// Workgroups per row of the dispatch (one a tile holding a shape).
const DISPATCH_ROW: u32 = 256;

/// The shapes binned into a window's 16×16-texel tiles, as
/// `capture_shapes.wgsl` reads them: per tile holding a shape (row-major),
/// four words: its column and row (in tiles), the index of its first entry
/// and its count; then the entries (shape indices, in shape order per tile).
#[derive(Clone, Debug, Default)]
pub struct ShapeBins {
    /// The records, then the entries.
    pub words: Vec<u32>,
    /// Tiles holding a shape (records at the start of `words`).
    pub tiles: u32,
    /// Shapes per tile of the window, then each tile's next entry; reused.
    counts: Vec<u32>,
    /// Where each shape reaches (tile columns, tile rows); reused.
    spans: Vec<Option<([u32; 2], [u32; 2])>>,
}

impl ShapeBins {
    /// Bins `bounds` ([`ShapeList::bounds`]) into the tiles of a window of
    /// `resolution` texels of `texel_m` (a counting sort: counts, offsets,
    /// entries). A tile lists a shape when the shape's bounds reach a texel
    /// centre of the tile.
    pub fn fill(&mut self, bounds: &[[f32; 4]], resolution: u32, texel_m: f32) {
        let side = resolution / TILE;
        self.counts.clear();
        self.counts.resize((side * side) as usize, 0);
        // The texel centres ((j + 0.5) t) a span reaches, as tiles.
        let last = (resolution - 1) as f32;
        let span = |lo: f32, hi: f32| -> Option<[u32; 2]> {
            let (a, b) = ((lo / texel_m - 0.5).ceil(), (hi / texel_m - 0.5).floor());
            (a <= b && b >= 0.0 && a <= last).then(|| [a.clamp(0.0, last) as u32 / TILE, b.clamp(0.0, last) as u32 / TILE])
        };
        self.spans.clear();
        self.spans.extend(bounds.iter().map(|b| span(b[0], b[2]).zip(span(b[1], b[3]))));
        let each_tile = |s: &([u32; 2], [u32; 2]), f: &mut dyn FnMut(usize)| {
            for z in s.1[0]..=s.1[1] {
                for x in s.0[0]..=s.0[1] {
                    f((z * side + x) as usize);
                }
            }
        };
        let counts = &mut self.counts;
        for s in self.spans.iter().flatten() {
            each_tile(s, &mut |k| counts[k] += 1);
        }
        let tiles = counts.iter().filter(|&&c| c > 0).count();
        self.tiles = tiles as u32;
        self.words.clear();
        self.words.reserve(4 * tiles);
        // Records; each tile's count becomes its next entry.
        let mut next = 4 * tiles as u32;
        for (k, count) in counts.iter_mut().enumerate() {
            if *count > 0 {
                let k = k as u32;
                self.words.extend([k % side, k / side, next, *count]);
                (next, *count) = (next + *count, next);
            }
        }
        self.words.resize(next as usize, 0);
        let words = &mut self.words;
        for (index, s) in self.spans.iter().enumerate() {
            let Some(s) = s else { continue };
            each_tile(s, &mut |k| {
                words[counts[k] as usize] = index as u32;
                counts[k] += 1;
            });
        }
    }
}

/// Ray casts the capture's analytic shapes into `res.capture_shapes` by
/// compute: see the module documentation.
pub struct ShapeCapturePass {
    pass: ComputePass<ShapeParams>,
    /// The shapes' data, then the tiles' lists: one upload a frame; grown
    /// to the largest frame's.
    buffer: wgpu::Buffer,
    /// This frame's shapes, lists and upload, kept for their memory.
    list: ShapeList,
    binned: ShapeBins,
    words: Vec<u32>,
    /// The capture buffer the pass is bound to (a window's resources).
    bound: Option<wgpu::Buffer>,
}

impl ShapeCapturePass {
    /// Compiles the shader; binds on the first record.
    #[must_use]
    pub fn new(device: &wgpu::Device) -> Self {
        let shape = PassShape {
            label: "capture",
            source: shaders::CAPTURE_SHAPES,
            // the shapes and the tiles' lists, as words and as vec4s; the capture
            slots: &[Slot::Read, Slot::Read, Slot::ReadWrite],
            specialise_on: None,
            constants: &[],
            window: None,
        };
        Self {
            pass: ComputePass::new(device, &shape, None),
            buffer: storage_buffer(device, 64 * 64),
            list: ShapeList::default(),
            binned: ShapeBins::default(),
            words: Vec::new(),
            bound: None,
        }
    }

    /// Records the ray cast of `inst` over the window of `res`, its depth
    /// linear in height from `low_m` (0) to `high_m` (1); returns whether it
    /// did (`false`: no shapes, nothing written or to read).
    pub fn record(&mut self, cx: &mut FrameContext<'_>, res: &DeformResources, [low_m, high_m]: [f32; 2], inst: Shapes<'_>) -> bool {
        if inst.count() == 0 {
            return false;
        }
        let texel_m = res.texel_m;
        shape_list(inst, texel_m, &mut self.list);
        self.binned.fill(&self.list.bounds, res.resolution, texel_m);
        // A header (the tiles holding a shape, where the bins start), the
        // shapes, the bins: what changes every frame is uploaded, the
        // uniforms only when the window or the shapes' count do.
        let tiles = self.binned.tiles;
        self.words.clear();
        self.words.extend_from_slice(&[tiles, 0, 0, 0]);
        self.words.extend_from_slice(bytemuck::cast_slice(&self.list.data));
        self.words[1] = self.words.len() as u32;
        self.words.extend_from_slice(&self.binned.words);
        let bytes: &[u8] = bytemuck::cast_slice(&self.words);
        let grown = bytes.len() as u64 > self.buffer.size();
        if grown {
            // Twice what this frame needs: a list that hovers about a size
            // does not make a buffer (and a bind group) again and again.
            self.buffer = storage_buffer(cx.device(), (2 * bytes.len() as u64).next_power_of_two());
        }
        cx.queue().write_buffer(&self.buffer, 0, bytes);
        if grown || self.bound.as_ref() != Some(&res.capture_shapes) {
            self.pass.bind(cx.device(), &[self.buffer.as_entire_binding(), self.buffer.as_entire_binding(), res.capture_shapes.as_entire_binding()]);
            self.bound = Some(res.capture_shapes.clone());
        }
        let u = ShapeParams {
            texel_m,
            low_m,
            high_m,
            resolution: res.resolution,
            capsules: inst.capsules.len() as u32,
            wheels: inst.wheels.len() as u32,
            row: DISPATCH_ROW,
            _pad: 0,
        };
        // "Nothing" everywhere, then the tiles that hold a shape (every
        // shape may lie outside the window's texel centres: then none).
        cx.encoder.clear_buffer(&res.capture_shapes, 0, None);
        if tiles > 0 {
            self.pass.record(cx, None, &u, 0, (tiles.min(DISPATCH_ROW), tiles.div_ceil(DISPATCH_ROW)));
        }
        true
    }
}

/// The shapes and bins' buffer, `bytes` long.
fn storage_buffer(device: &wgpu::Device, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("capture shapes"),
        size: bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}
