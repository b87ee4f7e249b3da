// #import shared/lighting

// Actors (spheres and boxes): instanced meshes lit like the snow, casting
// and receiving the sun's shadow.

struct Vertex {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
}

struct Instance {
    @location(2) m0: vec4<f32>,
    @location(3) m1: vec4<f32>,
    @location(4) m2: vec4<f32>,
    @location(5) m3: vec4<f32>,
    @location(6) n0: vec4<f32>,   // inverse-transpose columns, for normals
    @location(7) n1: vec4<f32>,
    @location(8) n2: vec4<f32>,
    @location(9) colour: vec4<f32>, // albedo rgb, roughness
}

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) colour: vec4<f32>,
}

fn model(i: Instance) -> mat4x4<f32> {
    return mat4x4<f32>(i.m0, i.m1, i.m2, i.m3);
}

@vertex
fn vs_main(v: Vertex, i: Instance) -> VsOut {
    let world = (model(i) * vec4<f32>(v.position, 1.0)).xyz;
    var out: VsOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.world = world;
    out.normal = mat3x3<f32>(i.n0.xyz, i.n1.xyz, i.n2.xyz) * v.normal;
    out.colour = i.colour;
    return out;
}

@vertex
fn vs_shadow(v: Vertex, i: Instance) -> @builtin(position) vec4<f32> {
    let world = (model(i) * vec4<f32>(v.position, 1.0)).xyz;
    return frame.light_view_proj * vec4<f32>(world, 1.0);
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    let n = normalize(in.normal);
    let s = Surface(in.world, n, in.colour.rgb, in.colour.a, 1.0, vec3<f32>(1.0), 0.0, 0.0);
    return vec4<f32>(actor_debug_colour(shade(s), n), 1.0);
}
