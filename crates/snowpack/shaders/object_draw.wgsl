// #import shared/lighting
// #import shared/objects

// Accumulation objects drawn with their snow: each vertex is pushed out along
// its normal by the accumulated depth (bilinear in the atlas, clamped to its
// chart; zero on box-face borders so the snow meets the edges), and the
// fragment blends the object's material into fresh snow with a normal bent by
// the accumulation's Scharr slopes. wgpu has no tessellation; the meshes are
// dense instead (about 4 cm quads).

struct AtlasInfo {
    resolution: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(1) @binding(0) var<storage, read> objects: array<ObjectGpu>;
@group(1) @binding(1) var<storage, read> atlas: array<vec4<f32>>;
@group(1) @binding(2) var<uniform> atlas_info: AtlasInfo;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) tangent: vec3<f32>,
    @location(3) bitangent: vec3<f32>,
    @location(4) uv: vec2<f32>,
    @location(5) taper: f32,
    @location(6) object: u32,
    @location(7) chart: vec4<f32>,
}

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) tangent: vec3<f32>,
    @location(3) bitangent: vec3<f32>,
    @location(4) uv: vec2<f32>,
    @location(5) @interpolate(flat) chart: vec4<f32>,
    @location(6) @interpolate(flat) object: u32,
}

fn atlas_at(c: vec2<f32>, chart: vec4<f32>) -> vec4<f32> {
    let t = clamp(c, chart.xy, chart.zw - 1.0);
    return atlas[u32(t.y) * atlas_info.resolution + u32(t.x)];
}

// Bilinear over texel centres, clamped to the chart.
fn sample_atlas(uv: vec2<f32>, chart: vec4<f32>) -> vec4<f32> {
    let t = uv - 0.5;
    let b = floor(t);
    let f = t - b;
    let a = mix(atlas_at(b, chart), atlas_at(b + vec2<f32>(1.0, 0.0), chart), f.x);
    let c = mix(atlas_at(b + vec2<f32>(0.0, 1.0), chart), atlas_at(b + vec2<f32>(1.0, 1.0), chart), f.x);
    return mix(a, c, f.y);
}

fn displaced(v: VertexIn) -> vec3<f32> {
    let depth = sample_atlas(v.uv, v.chart).x * v.taper;
    let p = v.position + v.normal * depth;
    return (objects[v.object].world * vec4<f32>(p, 1.0)).xyz;
}

@vertex
fn vs_main(v: VertexIn) -> VsOut {
    let o = objects[v.object];
    let world = displaced(v);
    var out: VsOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.world = world;
    out.normal = (o.rotation * vec4<f32>(v.normal, 0.0)).xyz;
    out.tangent = (o.rotation * vec4<f32>(v.tangent, 0.0)).xyz;
    out.bitangent = (o.rotation * vec4<f32>(v.bitangent, 0.0)).xyz;
    out.uv = v.uv;
    out.chart = v.chart;
    out.object = v.object;
    return out;
}

@vertex
fn vs_shadow(v: VertexIn) -> @builtin(position) vec4<f32> {
    return frame.light_view_proj * vec4<f32>(displaced(v), 1.0);
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    let o = objects[in.object];
    let s = sample_atlas(in.uv, in.chart);
    let n0 = normalize(in.normal);
    // The snow height's gradient on the surface from its derivatives along the
    // atlas axes (s.y, s.z per texel): grad = [T B] G^-1 (s.y, s.z), G the
    // Gram matrix of T and B (not orthogonal on the octahedral chart).
    let t = in.tangent;
    let b = in.bitangent;
    let g11 = dot(t, t);
    let g12 = dot(t, b);
    let g22 = dot(b, b);
    let det = max(g11 * g22 - g12 * g12, 1e-12);
    let grad = t * ((g22 * s.y - g12 * s.z) / det) + b * ((g11 * s.z - g12 * s.y) / det);
    let bent = normalize(n0 - grad);
    let cover = smoothstep(0.0005, 0.02, s.x);
    let n = normalize(mix(n0, bent, cover));
    let albedo = mix(o.colour.rgb, frame.fresh.rgb, cover);
    let roughness = mix(o.colour.a, frame.fresh.a, cover);
    let surface = Surface(in.world, n, albedo, roughness, 1.0, mix(vec3<f32>(1.0), frame.scatter.rgb, cover), frame.scatter.a * cover, frame.detail.x * cover);
    return vec4<f32>(actor_debug_colour(shade(surface), n), 1.0);
}
