//! The GPU buffers and textures the deformation passes share.
//!
//! | resource | format | order | meaning |
//! |---|---|---|---|
//! | `snow` | u32 per texel ([`super::snow_word`]) | toroidal | persistent snow as a 16-bit deficit below its rest height, and the displayed height above the terrain as an f16 |
//! | `stamps` | u32 per texel | toroidal | packed footprints of the points technique (`shared/stamp.wgsl`); 4 bytes until points or combined is used |
//! | `fallen` | f32 per texel | toroidal | snowfall so far above the rest depth (m); one texel when the params have no snowfall |
//! | `packed` | u16 per texel, two a u32 ([`super::packed_snow`]) | toroidal | fresh snow (snow quanta) that presses squeezed into the column: its mass and density |
//! | `capture_shapes` | u16 per texel, two a u32 | window-local | lowest analytic shape ray cast by compute (spheres, tyres, boxes), linear in height over `[low_m, high_m]` as a 16-bit code, stored as 65535 minus it (0 for nothing); 4 bytes until a frame first ray casts |
//! | `capture` | Depth16Unorm texture | window-local | lowest drawn surface (meshes; the shapes when drawn), the same code; 1×1 until a frame first draws |
//!
//! Eight bytes a texel with the depth technique: the persistent and the
//! displayed snow share one word, the display pass fuses rims and blur in
//! workgroup memory (no scratch), and normals are computed where they are
//! used from the displayed heights. The terrain is evaluated from its
//! source, never stored per texel.

use bytemuck::{Pod, Zeroable};

use crate::gpu::layout;
use crate::height_depth::height_depth_texture;
use crate::{SnowParams, TerrainSource};

use super::terrain_bake::TerrainBakePass;
use crate::deform::technique::TechniqueExt;
use crate::pass::window_bindings::{WindowBindings, WindowBuffers};
use crate::terrain::HeightmapTerrainExt;

/// Every buffer and texture of one deformation window.
pub struct DeformResources {
    /// Texels per side.
    pub resolution: u32,
    /// Texel size (m).
    pub texel_m: f32,
    /// The snow words, toroidal (`super::snow_word`): persistent snow and displayed height.
    pub snow: wgpu::Buffer,
    /// Packed footprints (height16 << 16 | foot16) per texel, toroidal;
    /// persistent. Allocated for the points and combined techniques (at
    /// creation, or by [`Self::allocate_stamps`] on the first switch to one);
    /// until then a 4-byte stand-in that no pass reads ([`Self::has_stamps`]).
    pub stamps: wgpu::Buffer,
    /// Snowfall so far above the rest depth per texel (m), toroidal; persistent.
    pub fallen: wgpu::Buffer,
    /// Packed snow, 16 bits a texel, two a word, toroidal; persistent
    /// (`super::packed_snow`). Zero (fresh snow) where the window pass or
    /// a load writes a texel. Its last two words count the snow quanta
    /// displaced beyond the final density (a u64, low word first), written
    /// by the passes that press and read by the mass ledger.
    pub packed: wgpu::Buffer,
    /// Heightmap samples for heightmap terrain or a drawn terrain mesh;
    /// over noise hills the window's ground (one f32 a texel, toroidal like
    /// the snow, written by the window ground pass as texels are exposed:
    /// [`Self::stores_ground`]); one zero over flat ground. With
    /// [`Self::terrain_params`], the terrain's source: passes evaluate the
    /// ground at texel centres (`texel_ground` in
    /// `shared/terrain_kind.wgsl`), or read it where the window stores it
    /// (`window_ground`).
    pub heightmap: wgpu::Buffer,
    /// [`TerrainParams`] uniform.
    pub terrain_params: wgpu::Buffer,
    /// [`TerrainParams::kind`] of that terrain, which never changes: the
    /// window passes' pipelines are built for it ([`Self::terrain_constants`]).
    pub terrain_kind: u32,
    /// The capture depth target: 1×1 until [`Self::allocate_capture`] (a
    /// window whose frames draw nothing into it never holds it).
    pub capture: wgpu::Texture,
    /// View of `capture`.
    pub capture_view: wgpu::TextureView,
    /// The analytic shapes' capture, written by compute
    /// (`capture_shapes.wgsl`): two texels a word, window-local; a 4-byte
    /// stand-in until [`Self::allocate_capture`].
    pub capture_shapes: wgpu::Buffer,
    /// Changed-tile flags of shared snow (`shared/share_flags.wgsl`), one
    /// `u32` per tile slot, written by the stamp and update passes; a
    /// 4-byte stand-in that no pass writes until
    /// [`Self::allocate_share_flags`].
    pub share_flags: wgpu::Buffer,
    /// The terrain, snow, footprint and snowfall buffers as group 1 of
    /// every window pass, made again when one is replaced.
    pub bindings: WindowBindings,
    /// Whether [`Self::heightmap`] holds the window's ground ([`Self::store_ground`]).
    ground_stored: bool,
}

fn height_buffer(device: &wgpu::Device, label: &str, texels: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: texels * 4,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// The changed-tile flags: written by passes, copied out and cleared.
fn flags_buffer(device: &wgpu::Device, slots: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("changed-tile flags"),
        size: slots.max(1) * 4,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// [`TerrainParams::kind`] of noise hills.
const NOISE_KIND: u32 = 1;
/// The pipelines' `TERRAIN_KIND` over noise hills the window stores
/// (`shared/terrain_kind.wgsl`).
const TERRAIN_STORED_NOISE: u32 = 3;

impl DeformResources {
    /// Allocates everything for `params` and uploads the terrain description.
    #[must_use]
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, params: &SnowParams, terrain: &TerrainSource) -> Self {
        let res = params.resolution;
        let texels = u64::from(res) * u64::from(res);
        let heightmap = if let TerrainSource::Mesh(mesh) = terrain {
            // Any terrain mesh: drawn from above on the GPU into its grid.
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("terrain bake") });
            let buffer = TerrainBakePass::new(device).bake(device, &mut encoder, mesh);
            queue.submit([encoder.finish()]);
            buffer
        } else {
            let samples: &[f32] = match terrain {
                TerrainSource::Heightmap(h) => h.heights_m(),
                _ => &[0.0],
            };
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("heightmap"),
                size: (samples.len() as u64 * 4).max(4),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            queue.write_buffer(&buffer, 0, bytemuck::cast_slice(samples));
            buffer
        };
        let terrain_params = layout::uniform_buffer::<TerrainParams>(device, "terrain params");
        let terrain_uniform = TerrainParams::new(terrain);
        queue.write_buffer(&terrain_params, 0, bytemuck::bytes_of(&terrain_uniform));
        let capture = height_depth_texture(device, "capture depth", 1);
        let capture_view = capture.create_view(&wgpu::TextureViewDescriptor::default());
        let snow = height_buffer(device, "snow", texels);
        // Every texel is written by the window pass on first placement.
        let stamps = height_buffer(device, "stamps", if params.technique.uses_stamps() { texels } else { 1 });
        // Zeroed by wgpu; only read and written while `params.snowfall` is set.
        let fallen = height_buffer(device, "fallen", if params.keeps_lying_snow() { texels } else { 1 });
        let bindings = WindowBindings::new(
            device,
            &WindowBuffers { terrain_params: &terrain_params, heightmap: &heightmap, snow: &snow, stamps: &stamps, fallen: &fallen },
        );
        // Zeroed by wgpu: fresh snow everywhere.
        let packed = height_buffer(device, "packed snow", super::packed_snow::words(res) + super::packed_snow::COUNT_WORDS);
        Self {
            resolution: res,
            texel_m: params.texel_m(),
            snow,
            stamps,
            fallen,
            packed,
            heightmap,
            terrain_params,
            terrain_kind: terrain_uniform.kind,
            capture,
            capture_view,
            capture_shapes: height_buffer(device, "capture shapes", 1),
            share_flags: flags_buffer(device, 1),
            bindings,
            ground_stored: false,
        }
    }

    /// Makes the capture's outputs the window's size the first time a
    /// frame writes them: the shapes' codes when it ray casts (`shapes`),
    /// the depth target when it draws (`target`). Returns whether it made
    /// either (the update, bound to the stand-ins, must then be bound
    /// again).
    pub fn allocate_capture(&mut self, device: &wgpu::Device, (shapes, target): (bool, bool)) -> bool {
        let make_shapes = shapes && !self.holds_capture((true, false));
        if make_shapes {
            let texels = u64::from(self.resolution) * u64::from(self.resolution);
            self.capture_shapes = height_buffer(device, "capture shapes", texels / 2);
        }
        let make_target = target && !self.holds_capture((false, true));
        if make_target {
            self.capture = height_depth_texture(device, "capture depth", self.resolution);
            self.capture_view = self.capture.create_view(&wgpu::TextureViewDescriptor::default());
        }
        make_shapes || make_target
    }

    /// Whether the capture's outputs asked for are the window's size: the
    /// shapes' codes (`shapes`), the depth target (`target`).
    #[must_use]
    pub fn holds_capture(&self, (shapes, target): (bool, bool)) -> bool {
        let texels = u64::from(self.resolution) * u64::from(self.resolution);
        (!shapes || self.capture_shapes.size() >= texels * 2) && (!target || self.capture.width() == self.resolution)
    }

    /// Allocates the changed-tile flags for `slots` tile slots, all clear,
    /// when they do not have that many yet; returns whether it did (passes
    /// bound to the old buffer must then be bound again).
    pub fn allocate_share_flags(&mut self, device: &wgpu::Device, slots: u32) -> bool {
        if self.share_flags.size() == u64::from(slots) * 4 {
            return false;
        }
        // wgpu zeroes new buffers: every flag starts clear.
        self.share_flags = flags_buffer(device, u64::from(slots));
        true
    }

    /// The `override` constants of the passes that evaluate the ground
    /// (`shaders/shared/terrain_kind.wgsl`): this window's terrain kind, so
    /// the driver compiles only that kind's code; over noise hills
    /// `TERRAIN_STORED_NOISE`, whose `window_ground` reads the window's
    /// ground ([`Self::stores_ground`]).
    #[must_use]
    pub fn terrain_constants(&self) -> [(&'static str, f64); 1] {
        let kind = if self.stores_ground() { TERRAIN_STORED_NOISE } else { self.terrain_kind };
        [("TERRAIN_KIND", f64::from(kind))]
    }

    /// Whether the window stores the terrain under each texel in
    /// [`Self::heightmap`]: over noise hills, whose four octaves of hashes
    /// a texel were most of the arithmetic of the passes that visit every
    /// texel every frame (issue 44; `docs/deformation.md`, "The window's
    /// ground"). Flat ground costs nothing to evaluate, and a heightmap's
    /// samples are already a read.
    #[must_use]
    pub fn stores_ground(&self) -> bool {
        self.ground_stored
    }

    /// Makes the window store its ground where that pays (noise hills;
    /// [`Self::stores_ground`]) and binds the window's group to it; returns
    /// whether it does. Call before the passes are made: they are built for
    /// [`Self::terrain_constants`], and from then on every texel of the
    /// window must have gone through the window ground pass
    /// (`super::window_ground::WindowGroundPass`, the whole window on first
    /// placement) before a pass reads it. A window that does not evaluates
    /// the ground where it is needed, as before.
    pub fn store_ground(&mut self, device: &wgpu::Device) -> bool {
        if self.terrain_kind != NOISE_KIND {
            return false;
        }
        if !self.ground_stored {
            let texels = u64::from(self.resolution) * u64::from(self.resolution);
            self.heightmap = height_buffer(device, "window ground", texels);
            self.ground_stored = true;
            self.rebind_window(device);
        }
        true
    }

    /// Makes the window's groups again over its buffers (one was replaced).
    fn rebind_window(&mut self, device: &wgpu::Device) {
        let buffers =
            WindowBuffers { terrain_params: &self.terrain_params, heightmap: &self.heightmap, snow: &self.snow, stamps: &self.stamps, fallen: &self.fallen };
        self.bindings.rebind(device, &buffers);
    }

    /// Whether the footprint buffer is allocated (one `u32` per texel).
    #[must_use]
    pub fn has_stamps(&self) -> bool {
        self.stamps.size() == u64::from(self.resolution) * u64::from(self.resolution) * 4
    }

    /// Allocates the footprint buffer, every texel without a footprint, when
    /// it is not yet, and binds the window's group to it; returns whether it
    /// did.
    pub fn allocate_stamps(&mut self, device: &wgpu::Device, queue: &wgpu::Queue) -> bool {
        if self.has_stamps() {
            return false;
        }
        let texels = u64::from(self.resolution) * u64::from(self.resolution);
        self.stamps = height_buffer(device, "stamps", texels);
        let empty = vec![u32::MAX; texels as usize];
        queue.write_buffer(&self.stamps, 0, bytemuck::cast_slice(&empty));
        self.rebind_window(device);
        true
    }

    /// Bytes of GPU memory held, by resource.
    #[must_use]
    #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
    pub fn memory_bytes(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("snow", self.snow.size()),
            ("stamps", self.stamps.size()),
            ("fallen", self.fallen.size()),
            ("packed snow", self.packed.size()),
            (if self.stores_ground() { "window ground" } else { "heightmap" }, self.heightmap.size()),
            ("capture", self.capture_shapes.size()),
            ("capture target", self.mesh_capture_bytes()),
            ("changed-tile flags", self.share_flags.size()),
        ]
    }

    /// [`Self::memory_bytes`] summed, without building the list.
    #[must_use]
    pub fn memory_total(&self) -> u64 {
        self.snow.size()
            + self.stamps.size()
            + self.fallen.size()
            + self.packed.size()
            + self.heightmap.size()
            + self.capture_shapes.size()
            + self.mesh_capture_bytes()
            + self.share_flags.size()
    }

    /// Bytes of the capture depth target (16 bits a texel).
    fn mesh_capture_bytes(&self) -> u64 {
        u64::from(self.capture.width()) * u64::from(self.capture.height()) * 2
    }
}

/// Uniforms of `shared/terrain.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct TerrainParams {
    /// 0 flat, 1 noise, 2 heightmap.
    pub kind: u32,
    /// Noise seed.
    pub seed: u32,
    /// Flat height or noise base (m).
    pub base_m: f32,
    /// Noise amplitude (m).
    pub amplitude_m: f32,
    /// One over the noise wavelength (1/m): the shader multiplies by it, as
    /// the CPU does, where a division may round otherwise on a GPU.
    pub per_wavelength: f32,
    /// Heightmap pixels per row.
    pub hm_width: u32,
    /// Heightmap rows.
    pub hm_height: u32,
    /// Padding.
    pub _pad: u32,
    /// Heightmap centre (x, z) in world metres.
    pub hm_center_m: [f32; 2],
    /// One over the heightmap's size (x, z) (1/m): the shader multiplies
    /// by it, as the CPU does, where a division may round otherwise.
    pub hm_per_size_m: [f32; 2],
}

impl TerrainParams {
    /// Uniforms describing `terrain` (heightmap samples go in a separate buffer).
    #[must_use]
    pub fn new(terrain: &crate::TerrainSource) -> Self {
        use crate::TerrainSource as T;
        match terrain {
            T::Flat { height_m } => Self { kind: 0, base_m: *height_m, ..Self::default() },
            T::Noise(n) => {
                Self { kind: NOISE_KIND, seed: n.seed, base_m: n.base_m, amplitude_m: n.amplitude_m, per_wavelength: 1.0 / n.wavelength_m, ..Self::default() }
            }
            T::Heightmap(h) => Self::heightmap(h),
            // The mesh is drawn into a grid on the GPU and sampled like a heightmap.
            T::Mesh(m) => Self::heightmap(&m.grid),
        }
    }

    fn heightmap(h: &crate::HeightmapTerrain) -> Self {
        Self { kind: 2, hm_width: h.width(), hm_height: h.height(), hm_center_m: h.center_m(), hm_per_size_m: h.shared_grid().per_size_m(), ..Self::default() }
    }
}
