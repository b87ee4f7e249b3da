//! The snow as a game's own shaders see it: the exported WGSL module
//! ([`SNOW_SAMPLING_WGSL`], `shaders/snow_sampling.wgsl` after its import
//! `shaders/shared/terrain.wgsl`), its bind-group layout entries and the bind
//! group built from a [`SnowDeformation`].
//!
//! | binding | type | buffer | what |
//! |---|---|---|---|
//! | 0 | uniform `SnowWindow` (48 B) | [`SnowSampling`]'s own, [`SnowWindowUniform`] | where the window is; rewritten each frame |
//! | 1 | uniform `TerrainParams` (48 B) | `DeformResources::terrain_params` | the terrain description |
//! | 2 | storage, read `array<f32>` | `DeformResources::heightmap` | heightmap samples (heightmap and mesh terrain) |
//! | 3 | storage, read `array<u32>` | `DeformResources::snow` | the snow words, toroidal: displayed height above the terrain (upper f16) and persistent deficit (lower 16 bits) |
//!
//! All four are in group [`SNOW_SAMPLING_GROUP`] (1); [`snow_sampling_wgsl`]
//! gives the module for another group. The WGSL file's header documents the
//! functions (`snow_height`, `snow_normal`, `snow_depth`, `snow_compaction`)
//! and their conventions; `cpu::snow_sampling` is their CPU twin.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use bytemuck::{Pod, Zeroable};

use super::pipeline::storage_ro;
use crate::gpu::layout;
use crate::shaders;
use crate::snow::SnowDeformation;
use crate::snow::inspect::SnowInspect;

/// WGSL a game prepends to its shader to sample the snow: declares the four
/// bindings (group `SNOW_SAMPLING_GROUP`, bindings 0..=3) and the functions
/// `snow_height`, `snow_normal`, `snow_depth`, `snow_compaction` (all taking a
/// world `vec2<f32>` (x, z)). Validated by naga at build time.
pub const SNOW_SAMPLING_WGSL: &str = shaders::SNOW_SAMPLING;

/// Bind group index the bindings of [`SNOW_SAMPLING_WGSL`] are declared in.
pub const SNOW_SAMPLING_GROUP: u32 = 1;

/// [`SNOW_SAMPLING_WGSL`] with its bindings in bind group `group` instead of
/// [`SNOW_SAMPLING_GROUP`] (binding numbers stay 0..=3). WGSL has no
/// preprocessor, so this is a textual rewrite of the module's four `@group`
/// attributes (the module has no others).
#[must_use]
pub fn snow_sampling_wgsl(group: u32) -> String {
    SNOW_SAMPLING_WGSL.replace(&format!("@group({SNOW_SAMPLING_GROUP})"), &format!("@group({group})"))
}

/// [`SNOW_SAMPLING_WGSL`] with its bindings in bind group `group` at
/// `first_binding..first_binding + 4`, for an engine whose group already
/// holds other bindings below (Bevy's material group: the standard
/// material's own come first). Offset [`sampling_layout_entries`]'s binding
/// numbers the same way. A textual rewrite of the four binding attributes,
/// like `snow_sampling_wgsl` (with `low_level`).
#[must_use]
pub fn snow_sampling_wgsl_at(group: u32, first_binding: u32) -> String {
    // Highest first, so a binding already moved up is never matched again.
    (0..4).rev().fold(SNOW_SAMPLING_WGSL.to_string(), |s, k| {
        s.replace(&format!("@group({SNOW_SAMPLING_GROUP}) @binding({k})"), &format!("@group({group}) @binding({})", first_binding + k))
    })
}

/// The deformation's buffers behind bindings 1..=3 of [`SNOW_SAMPLING_WGSL`]
/// (terrain parameters, heightmap, snow words), for an engine that builds
/// the bind group itself (binding 0 is its own [`SnowWindowUniform`]
/// buffer). They are created with the deformation and kept for its life.
#[must_use]
pub fn sampling_buffers(snow: &SnowDeformation) -> [wgpu::Buffer; 3] {
    let res = snow.resources();
    [res.terrain_params.clone(), res.heightmap.clone(), res.snow.clone()]
}

/// The `SnowWindow` uniform (binding 0): where the deformation window lies.
/// A game's material fills its buffer with [`Self::new`] (its size is
/// `size_of::<SnowWindowUniform>()`); the shader reads the fields, so a game's
/// code has no need to (the tests read them through `SnowWindowUniformExt` in `low_level`).
#[repr(C)]
#[cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, reason = "the fields are read by the shader through the uniform's bytes; on the CPU only by its twin and the tests (`low_level`)")
)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SnowWindowUniform {
    /// World (x, z) of local texel (0, 0)'s outer corner, minus the floating origin (m).
    pub(crate) corner: [f32; 2],
    /// The deformation's floating origin (m): shader positions are relative to it.
    pub(crate) floating_origin: [f32; 2],
    /// Global texel index (column, row) of local texel (0, 0).
    pub(crate) origin_texel: [i32; 2],
    /// Texel size (m).
    pub(crate) texel_m: f32,
    /// Rest depth of untouched snow (m): `depth_m` plus snowfall so far on open ground.
    pub(crate) rest_depth_m: f32,
    /// Texels per side.
    pub(crate) resolution: u32,
    /// 1 once the window has been placed (after the deformation's first frame), else 0.
    pub(crate) placed: u32,
    /// `origin_texel` wrapped into `0..resolution` (`crate::deform::window::storage_origin`):
    /// where local texel (0, 0) is stored, so the shader wraps with no division.
    pub(crate) storage_origin: [u32; 2],
}

/// What the tests read of a [`SnowWindowUniform`] (a named extension trait
/// of `low_level`: the uniform has one shape with or without the feature).
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait SnowWindowUniformExt {
    /// World (x, z) of local texel (0, 0)'s outer corner, minus the floating origin (m).
    #[must_use]
    fn corner(&self) -> [f32; 2];
    /// Global texel index (column, row) of local texel (0, 0).
    #[must_use]
    fn origin_texel(&self) -> [i32; 2];
    /// Texel size (m).
    #[must_use]
    fn texel_m(&self) -> f32;
    /// Rest depth of untouched snow (m): `depth_m` plus snowfall so far on open ground.
    #[must_use]
    fn rest_depth_m(&self) -> f32;
    /// The floating origin (world x, z) the corner is relative to (m).
    #[must_use]
    fn floating_origin(&self) -> [f32; 2];
    /// Texels per window side.
    #[must_use]
    fn resolution(&self) -> u32;
    /// Whether the window has been placed (the uniform holds a window yet).
    #[must_use]
    fn placed(&self) -> bool;
}

impl SnowWindowUniformExt for SnowWindowUniform {
    fn corner(&self) -> [f32; 2] {
        self.corner
    }

    fn origin_texel(&self) -> [i32; 2] {
        self.origin_texel
    }

    fn texel_m(&self) -> f32 {
        self.texel_m
    }

    fn rest_depth_m(&self) -> f32 {
        self.rest_depth_m
    }

    fn floating_origin(&self) -> [f32; 2] {
        self.floating_origin
    }

    fn resolution(&self) -> u32 {
        self.resolution
    }

    fn placed(&self) -> bool {
        self.placed != 0
    }
}

impl SnowWindowUniform {
    /// The window of `snow` as it is now (after its last encoded frame).
    #[must_use]
    pub fn new(snow: &SnowDeformation) -> Self {
        let p = snow.params();
        let texel = p.texel_m();
        let floating = snow.floating_origin();
        let origin = snow.origin_texel();
        // The corner relative to the floating origin in f64, so it stays exact far from the world origin.
        let corner = origin.map_or([0.0; 2], |o| {
            let c = glam::DVec2::new(o[0] as f64, o[1] as f64) * f64::from(texel) - floating;
            [c.x as f32, c.y as f32]
        });
        Self {
            corner,
            floating_origin: [floating.x as f32, floating.y as f32],
            // The passes use i32 texel indices too (about 134,000 km at 6.25 cm).
            origin_texel: origin.map_or([0; 2], |o| [o[0] as i32, o[1] as i32]),
            texel_m: texel,
            rest_depth_m: p.depth_m + snow.fallen_m(),
            resolution: p.resolution,
            placed: u32::from(origin.is_some()),
            storage_origin: origin.map_or([0; 2], |o| crate::deform::window::storage_origin([o[0] as i32, o[1] as i32], p.resolution)),
        }
    }
}

/// The bind-group layout entries of [`SNOW_SAMPLING_WGSL`]'s group, for the
/// stages that call its functions (vertex, fragment, compute or several).
#[must_use]
pub fn sampling_layout_entries(visibility: wgpu::ShaderStages) -> [wgpu::BindGroupLayoutEntry; 4] {
    [layout::uniform(0, visibility), layout::uniform(1, visibility), storage_ro(2, visibility), storage_ro(3, visibility)]
}

/// The bind group of [`SNOW_SAMPLING_WGSL`] for `snow`, with `window` (a
/// uniform buffer of at least [`SnowWindowUniform`]'s size the caller keeps
/// current) at binding 0. [`SnowSampling`] does this and the updates for you.
#[must_use]
pub fn sampling_bind_group(device: &wgpu::Device, layout: &wgpu::BindGroupLayout, snow: &SnowDeformation, window: &wgpu::Buffer) -> wgpu::BindGroup {
    let res = snow.resources();
    layout::bind_group(
        device,
        "snow sampling",
        layout,
        &[window.as_entire_binding(), res.terrain_params.as_entire_binding(), res.heightmap.as_entire_binding(), res.snow.as_entire_binding()],
    )
}

/// The bind group a game binds for [`SNOW_SAMPLING_WGSL`], with its layout
/// and window uniform. Call [`Self::update`] each frame after the
/// deformation's frame is encoded (the window may have moved).
pub struct SnowSampling {
    device: wgpu::Device,
    layout: wgpu::BindGroupLayout,
    window: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    /// The deformation's buffers the bind group holds (snow words, terrain params, heightmap).
    bound: [wgpu::Buffer; 3],
}

fn bound_buffers(snow: &SnowDeformation) -> [wgpu::Buffer; 3] {
    let res = snow.resources();
    [res.snow.clone(), res.terrain_params.clone(), res.heightmap.clone()]
}

impl SnowSampling {
    /// Layout, window uniform and bind group for `snow`, visible to `visibility`.
    #[must_use]
    pub fn new(device: &wgpu::Device, snow: &SnowDeformation, visibility: wgpu::ShaderStages) -> Self {
        let layout =
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("snow sampling"), entries: &sampling_layout_entries(visibility) });
        let window = layout::uniform_buffer::<SnowWindowUniform>(device, "snow window");
        let bind_group = sampling_bind_group(device, &layout, snow, &window);
        Self { device: device.clone(), layout, window, bind_group, bound: bound_buffers(snow) }
    }

    /// Writes where the window is now; rebuilds the bind group if the
    /// deformation's buffers are no longer the ones bound.
    pub fn update(&mut self, queue: &wgpu::Queue, snow: &SnowDeformation) {
        let current = bound_buffers(snow);
        if current != self.bound {
            self.bind_group = sampling_bind_group(&self.device, &self.layout, snow, &self.window);
            self.bound = current;
        }
        queue.write_buffer(&self.window, 0, bytemuck::bytes_of(&SnowWindowUniform::new(snow)));
    }

    /// The layout, for the caller's pipeline layout (at the group its shader uses).
    #[must_use]
    pub fn layout(&self) -> &wgpu::BindGroupLayout {
        &self.layout
    }

    /// The bind group to set at that group.
    #[must_use]
    pub fn bind_group(&self) -> &wgpu::BindGroup {
        &self.bind_group
    }
}
