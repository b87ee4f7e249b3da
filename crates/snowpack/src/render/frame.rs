//! The per-frame uniform block every render pass reads (`Frame` in `shaders/shared/frame.wgsl`).

/// Per-frame values: matrices, light, window placement, material, debug view.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FrameUniforms {
    /// World to clip.
    pub view_proj: [[f32; 4]; 4],
    /// Clip to world.
    pub inv_view_proj: [[f32; 4]; 4],
    /// World to the shadow map's clip space.
    pub light_view_proj: [[f32; 4]; 4],
    /// Eye position; w: vertical term of the LOD distance (m).
    pub camera: [f32; 4],
    /// Unit vector toward the sun; w: sun intensity.
    pub sun: [f32; 4],
    /// Sun colour; w: sky intensity.
    pub sun_color: [f32; 4],
    /// Window corner x, z, extent, texel (m).
    pub window: [f32; 4],
    /// Resolution, placed, debug view, decals on.
    pub window_info: [u32; 4],
    /// Detail bonus (m), its fade margin (m), unused, view distance (m).
    pub lod: [f32; 4],
    /// Rest depth (m), shadow distance (m), shadow texel (m), exposure multiplier.
    pub snow: [f32; 4],
    /// Fresh albedo, fresh roughness.
    pub fresh: [f32; 4],
    /// Compacted albedo, compacted roughness.
    pub packed: [f32; 4],
    /// Bare ground albedo, roughness.
    pub ground: [f32; 4],
    /// Scatter tint, wrap.
    pub scatter: [f32; 4],
    /// Sparkle, detail strength, detail frequency, macro variation.
    pub detail: [f32; 4],
    /// Solid background colour; w: 1 to draw it instead of the sky.
    pub background: [f32; 4],
    /// Environment width and height (texels), unused, unused.
    pub env_info: [u32; 4],
    /// Compacted snow: full-look pressed fraction, detail kept, sparkle kept, ground show-through.
    pub compaction: [f32; 4],
}
