// #import shared/objects

// Occlusion pass: the objects seen from the sky, along the snowfall direction
// (jittered for flutter), by a sheared orthographic projection onto the
// deformation window: a point p lands where the flake through it meets the
// plane y = y0, q = p.xz + shear (p.y - y0), shear = d.xz / -d.y. Depth is
// linear in height, smallest for the highest surface, so the depth test keeps
// what the sky sees. Colour: the rectangle of atlas texels the pixel's
// footprint covers, [x0, y0, x1, y1] inclusive, clamped to the chart (at most
// MAX_SPAN a side), as 16-bit integers (a float target is not renderable on
// GL); cleared to 0xffff where no object is. No culling: the depth
// test alone picks the sky-facing surface, whatever the winding.

struct OcclusionParams {
    extent_m: f32,
    y0_m: f32,
    low_m: f32,
    high_m: f32,
    shear: vec2<f32>,
    offset_m: vec2<f32>,
}

@group(0) @binding(0) var<uniform> params: OcclusionParams;
@group(0) @binding(1) var<storage, read> objects: array<ObjectGpu>;

const MAX_SPAN: f32 = 16.0;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) object: u32,
    @location(3) chart: vec4<f32>,
}

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
    @location(1) @interpolate(flat) chart: vec4<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VsOut {
    let p = (objects[v.object].local * vec4<f32>(v.position, 1.0)).xyz;
    let q = p.xz + params.shear * (p.y - params.y0_m) + params.offset_m;
    let depth = (params.high_m - p.y) / (params.high_m - params.low_m);
    var out: VsOut;
    out.clip = vec4<f32>(q.x / params.extent_m * 2.0 - 1.0, 1.0 - q.y / params.extent_m * 2.0, depth, 1.0);
    out.uv = v.uv;
    out.chart = v.chart;
    return out;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<u32> {
    let ext = 0.5 * (abs(dpdx(in.uv)) + abs(dpdy(in.uv)));
    let last = in.chart.zw - 1.0;
    let lo = clamp(floor(in.uv - ext), in.chart.xy, last);
    let hi = clamp(floor(in.uv + ext), lo, min(last, lo + MAX_SPAN - 1.0));
    return vec4<u32>(vec2<u32>(lo), vec2<u32>(hi));
}
