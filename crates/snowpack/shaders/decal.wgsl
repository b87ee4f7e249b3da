// Decal pass: the last contacts of each actor drawn as quads oriented to the
// terrain normal, seen from above into a window-local layer the renderer
// (and frame.png) composite over the snow. The footprint texture (generated
// at start-up, rotation invariant for spheres) holds a normal map (rg), the
// tint of compacted snow (b) and coverage (a). Decals never touch the height
// field. Written rgba: world normal x, z (as 0.5 + n / 2), tint, coverage.

struct DecalParams {
    corner_m: vec2<f32>,  // world (x, z) of the window's corner, relative to `anchor`
    extent_m: f32,
    _pad: f32,
}

struct DecalIn {
    // centre (x, z relative to the anchor), radius, yaw
    @location(0) place: vec4<f32>,
    // terrain normal at the centre (xyz), age fade
    @location(1) normal: vec4<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
    @location(1) t: vec3<f32>,
    @location(2) b: vec3<f32>,
    @location(3) n: vec3<f32>,
    @location(4) fade: f32,
}

@group(0) @binding(0) var<uniform> params: DecalParams;
@group(0) @binding(1) var footprint: texture_2d<f32>;
@group(0) @binding(2) var footprint_sampler: sampler;

@vertex
fn vs_main(@builtin(vertex_index) v: u32, d: DecalIn) -> VertexOut {
    let corner = vec2(f32(v & 1u), f32((v >> 1u) & 1u)) * 2.0 - 1.0;
    let n = normalize(d.normal.xyz);
    // Tangent frame on the terrain, turned by the decal's yaw.
    let yaw = vec3(cos(d.place.w), 0.0, sin(d.place.w));
    let t = normalize(yaw - n * dot(yaw, n));
    let b = cross(n, t);
    let offset = (t * corner.x + b * corner.y) * d.place.z;
    let x = d.place.x + offset.x - params.corner_m.x;
    let z = d.place.y + offset.z - params.corner_m.y;
    var out: VertexOut;
    out.clip = vec4(x / params.extent_m * 2.0 - 1.0, 1.0 - z / params.extent_m * 2.0, 0.5, 1.0);
    out.uv = corner * 0.5 + 0.5;
    out.t = t;
    out.b = b;
    out.n = n;
    out.fade = d.normal.w;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let texel = textureSample(footprint, footprint_sampler, in.uv);
    let local = vec2(texel.r, texel.g) * 2.0 - 1.0;
    let up = sqrt(max(1.0 - dot(local, local), 0.0));
    let world_n = normalize(in.t * local.x + in.b * local.y + in.n * up);
    return vec4(world_n.x * 0.5 + 0.5, world_n.z * 0.5 + 0.5, texel.b, texel.a * in.fade);
}
