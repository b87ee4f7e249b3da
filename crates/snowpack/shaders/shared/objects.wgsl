// Accumulation objects as the GPU sees them (`ObjectGpu` in src/accumulate/state.rs).

struct ObjectGpu {
    local: mat4x4<f32>,    // object space to window-local space (x and z from the window's corner)
    world: mat4x4<f32>,    // object space to world space
    rotation: mat4x4<f32>, // rotation only, for normals
    colour: vec4<f32>,     // albedo rgb, roughness
    flags: vec4<u32>,      // x: 1 when dilated
}

const NO_OWNER: u32 = 0xffffffffu;
const DILATE: u32 = 1u;
// Fixed-point unit of the scatter's hit counts: one whole pixel of snow.
const HIT_UNIT: f32 = 65536.0;
