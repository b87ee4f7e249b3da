// #import shared/capture_shapes

// Capture pass, wheels, rasterised (the capture's `ShapeCapture::Raster`;
// `capture_shapes.wgsl` ray casts the same tyres by compute): an
// orthographic view from below the terrain looking up. Each instance is one pose of a tyre (a wheel swept over the frame is
// drawn once per sub-step): a cylinder of outer radius r and half width w
// around its axle, with a tread of raised lugs (surface at r) and grooves
// between them (at r - depth). A quad over the tyre's footprint writes the
// lowest surface along each texel centre's vertical line as depth, exactly:
// no tessellation. The tyre is shared/capture_shapes.wgsl's; CPU twin:
// src/cpu/capture_shapes.rs (wheel_bottom); the tread
// coordinates are documented in src/deform/wheel.rs.

struct CaptureParams {
    extent_m: f32,
    texel_m: f32,
    low_m: f32,   // world height at depth 0
    high_m: f32,  // world height at depth 1
}

@group(0) @binding(0) var<uniform> params: CaptureParams;

struct VertexOut {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) center: vec4<f32>, // window-local centre, outer radius
    @location(1) @interpolate(flat) axle: vec4<f32>,   // unit axle, half width
    @location(2) @interpolate(flat) tread: vec4<f32>,  // roll (m), spacing (m), lug depth (m), pattern
    @location(3) @interpolate(flat) extra: vec4<f32>,  // lug fraction
}

@vertex
fn vs_main(@builtin(vertex_index) vertex: u32, @location(0) center: vec4<f32>, @location(1) axle: vec4<f32>, @location(2) tread: vec4<f32>, @location(3) extra: vec4<f32>) -> VertexOut {
    var corners = array<vec2<f32>, 6>(
        vec2(-1.0, -1.0), vec2(1.0, -1.0), vec2(1.0, 1.0),
        vec2(-1.0, -1.0), vec2(1.0, 1.0), vec2(-1.0, 1.0),
    );
    // A square around the centre that holds the tyre in any orientation,
    // half a texel wider so every texel centre under it is covered.
    let half = sqrt(center.w * center.w + axle.w * axle.w) + 0.5 * params.texel_m;
    let local = center.xz + corners[vertex] * half;
    var out: VertexOut;
    out.position = vec4(local.x / params.extent_m * 2.0 - 1.0, 1.0 - local.y / params.extent_m * 2.0, 0.0, 1.0);
    out.center = center;
    out.axle = axle;
    out.tread = tread;
    out.extra = extra;
    return out;
}

struct FragmentOut {
    @builtin(frag_depth) depth: f32,
}

@fragment
fn fs_main(in: VertexOut) -> FragmentOut {
    // Framebuffer pixel (j + 0.5, i + 0.5) is the centre of window texel (i, j).
    let p = in.position.xy * params.texel_m;
    let w = vec3(p.x - in.center.x, 0.0, p.y - in.center.z);
    let y = wheel_bottom(w, in.axle.xyz, in.center.w, in.axle.w, in.tread, in.extra.x);
    if y >= MISS {
        discard;
    }
    let depth = (in.center.y + y - params.low_m) / (params.high_m - params.low_m);
    if depth > 1.0 {
        discard;
    }
    var out: FragmentOut;
    out.depth = clamp(depth, 0.0, 1.0);
    return out;
}
