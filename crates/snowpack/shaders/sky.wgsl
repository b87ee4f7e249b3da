// #import shared/frame

// The sky behind everything: the full-resolution environment looked up along
// each pixel's view ray (or a solid colour, for tests).

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> env_full: array<vec4<f32>>;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) ndc: vec2<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> VsOut {
    // One triangle covering the screen.
    let xy = vec2<f32>(f32((vi << 1u) & 2u), f32(vi & 2u)) * 2.0 - 1.0;
    var out: VsOut;
    out.clip = vec4<f32>(xy, 0.0, 1.0);
    out.ndc = xy;
    return out;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    // A solid background instead of the sky, by a select: with a branch on
    // the uniform alone, Mesa 22's lavapipe compiles this shader again at
    // every draw and keeps every copy (docs/deformation.md, "Branches on
    // uniforms").
    let solid = frame.background.w > 0.5;
    // Reverse-Z: depth 1 is the near plane.
    let near = frame.inv_view_proj * vec4<f32>(in.ndc, 1.0, 1.0);
    let d = normalize(near.xyz / near.w - frame.camera.xyz);
    let b = equirect_taps(dir_equirect(d), frame.env_info.x, frame.env_info.y, 0u);
    let c = bilinear_mix(b, env_full[b.i00].rgb, env_full[b.i01].rgb, env_full[b.i10].rgb, env_full[b.i11].rgb);
    return vec4<f32>(select(c * frame.sun_color.w, frame.background.rgb, solid), 1.0);
}
