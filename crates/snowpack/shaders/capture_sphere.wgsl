// Capture pass, spheres: an orthographic view from below the terrain looking
// up. Each sphere is a screen-aligned quad over its footprint whose fragments
// write the analytic lower surface of the sphere as depth, so the captured
// height is exact (no tessellation error). CPU twin: src/cpu/capture.rs.

struct CaptureParams {
    extent_m: f32,
    texel_m: f32,
    low_m: f32,   // world height at depth 0
    high_m: f32,  // world height at depth 1
}

@group(0) @binding(0) var<uniform> params: CaptureParams;

struct VertexOut {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) sphere: vec4<f32>, // window-local centre xyz, radius
}

@vertex
fn vs_main(@builtin(vertex_index) vertex: u32, @location(0) sphere: vec4<f32>) -> VertexOut {
    // Two triangles over the square [-1, 1]^2.
    var corners = array<vec2<f32>, 6>(
        vec2(-1.0, -1.0), vec2(1.0, -1.0), vec2(1.0, 1.0),
        vec2(-1.0, -1.0), vec2(1.0, 1.0), vec2(-1.0, 1.0),
    );
    let c = corners[vertex];
    let local = sphere.xz + c * sphere.w;
    var out: VertexOut;
    out.position = vec4(local.x / params.extent_m * 2.0 - 1.0, 1.0 - local.y / params.extent_m * 2.0, 0.0, 1.0);
    out.sphere = sphere;
    return out;
}

struct FragmentOut {
    @builtin(frag_depth) depth: f32,
}

@fragment
fn fs_main(in: VertexOut) -> FragmentOut {
    // Framebuffer pixel (j + 0.5, i + 0.5) is the centre of window texel (i, j).
    let p = in.position.xy * params.texel_m;
    let d = p - in.sphere.xz;
    let r2 = in.sphere.w * in.sphere.w;
    let d2 = dot(d, d);
    if d2 > r2 {
        discard;
    }
    let bottom = in.sphere.y - sqrt(r2 - d2);
    let depth = (bottom - params.low_m) / (params.high_m - params.low_m);
    if depth > 1.0 {
        discard;
    }
    var out: FragmentOut;
    out.depth = clamp(depth, 0.0, 1.0);
    return out;
}
