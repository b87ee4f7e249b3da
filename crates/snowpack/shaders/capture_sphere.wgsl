// #import shared/capture_shapes

// Capture pass, spheres swept over the frame, rasterised (the capture's
// `ShapeCapture::Raster`; `capture_shapes.wgsl` ray casts the same shapes by
// compute): an orthographic view from below the terrain looking up. Each sphere moved from `a` (last frame) to `b` (this
// frame), so what it pressed is the capsule of radius r around the segment ab
// (a sphere that did not move, or was not swept, has a == b). Each capsule is
// a quad over its footprint (the stadium of the segment's shadow, widened by
// r) whose fragments write the capsule's analytic lower surface as depth, so
// the captured height is exact: no tessellation and no sub-steps.
// The shape is shared/capture_shapes.wgsl's; CPU twin: src/cpu/capture_shapes.rs (capsule_bottom).

struct CaptureParams {
    extent_m: f32,
    texel_m: f32,
    low_m: f32,   // world height at depth 0
    high_m: f32,  // world height at depth 1
}

@group(0) @binding(0) var<uniform> params: CaptureParams;

struct VertexOut {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) a: vec4<f32>, // window-local start xyz, radius
    @location(1) @interpolate(flat) b: vec4<f32>, // window-local end xyz
}

@vertex
fn vs_main(@builtin(vertex_index) vertex: u32, @location(0) a: vec4<f32>, @location(1) b: vec4<f32>) -> VertexOut {
    // Two triangles over the square [-1, 1]^2, stretched along the motion.
    var corners = array<vec2<f32>, 6>(
        vec2(-1.0, -1.0), vec2(1.0, -1.0), vec2(1.0, 1.0),
        vec2(-1.0, -1.0), vec2(1.0, 1.0), vec2(-1.0, 1.0),
    );
    let c = corners[vertex];
    let r = a.w;
    let travel = b.xz - a.xz;
    let len = length(travel);
    var along = vec2(1.0, 0.0);
    if len > 1e-6 {
        along = travel / len;
    }
    let across = vec2(-along.y, along.x);
    let mid = 0.5 * (a.xz + b.xz);
    // Half a texel more on every side: the quad must cover every texel
    // centre inside the footprint whatever the rasteriser's rounding.
    let pad = 0.5 * params.texel_m;
    let local = mid + along * c.x * (0.5 * len + r + pad) + across * c.y * (r + pad);
    var out: VertexOut;
    out.position = vec4(local.x / params.extent_m * 2.0 - 1.0, 1.0 - local.y / params.extent_m * 2.0, 0.0, 1.0);
    out.a = a;
    out.b = b;
    return out;
}

struct FragmentOut {
    @builtin(frag_depth) depth: f32,
}

@fragment
fn fs_main(in: VertexOut) -> FragmentOut {
    // Framebuffer pixel (j + 0.5, i + 0.5) is the centre of window texel (i, j).
    let p = in.position.xy * params.texel_m;
    let bottom = capsule_bottom(p, in.a.xyz, in.b.xyz, in.a.w);
    if bottom > 1.0e38 {
        discard;
    }
    let depth = (bottom - params.low_m) / (params.high_m - params.low_m);
    if depth > 1.0 {
        discard;
    }
    var out: FragmentOut;
    out.depth = clamp(depth, 0.0, 1.0);
    return out;
}
