// Skinning: each vertex of a skinned mesh, moved by up to four joints
// (linear blend skinning) and placed in the world by the actor's matrix.
// The output is packed xyz (12 bytes a vertex) so it serves directly as a
// vertex buffer for the capture and the renderer. Normals are skinned by the
// same blended matrix (its linear part: exact for rotations and uniform
// scale, which skeletons use) for the snow coat's sky test (snow_coat.wgsl).
// CPU twin: src/cpu/skinning.rs.

struct SkinningParams {
    model: mat4x4<f32>,
    vertex_count: u32,
    joint_count: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> params: SkinningParams;
@group(0) @binding(1) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> joint_ids: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read> weights: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> joints: array<mat4x4<f32>>;
@group(0) @binding(5) var<storage, read_write> skinned: array<f32>;
@group(0) @binding(6) var<storage, read> rest_normals: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> normals: array<f32>;

fn joint(k: u32) -> mat4x4<f32> {
    return joints[min(k, params.joint_count - 1u)];
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let v = id.x;
    if v >= params.vertex_count {
        return;
    }
    let j = joint_ids[v];
    let w = weights[v];
    let skin = joint(j.x) * w.x + joint(j.y) * w.y + joint(j.z) * w.z + joint(j.w) * w.w;
    let p = params.model * (skin * vec4<f32>(rest[v].xyz, 1.0));
    skinned[v * 3u] = p.x;
    skinned[v * 3u + 1u] = p.y;
    skinned[v * 3u + 2u] = p.z;
    let n4 = params.model * (skin * vec4<f32>(rest_normals[v].xyz, 0.0));
    var n = n4.xyz;
    let len = length(n);
    n = select(vec3<f32>(0.0, 1.0, 0.0), n / len, len > 1e-12);
    normals[v * 3u] = n.x;
    normals[v * 3u + 1u] = n.y;
    normals[v * 3u + 2u] = n.z;
}
