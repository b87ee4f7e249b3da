// #import shared/objects

// Increment pass: the frame's hits to a depth increment per atlas texel,
// fresh = hits / HIT_UNIT * volume / area, where volume is what one occlusion
// pixel receives this frame (rate * dt * pixel area on the ground plane), so
// the snow that falls is conserved whatever the atlas density. Clears the hits.
// CPU twin: src/cpu/increment.rs.

struct IncrementParams {
    atlas_resolution: u32,
    volume_m3: f32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> params: IncrementParams;
@group(0) @binding(1) var<storage, read> normal_area: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> hits: array<u32>;
@group(0) @binding(3) var<storage, read_write> fresh: array<f32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.atlas_resolution;
    if gid.x >= n || gid.y >= n {
        return;
    }
    let k = gid.y * n + gid.x;
    let area = normal_area[k].w;
    var add = 0.0;
    if area > 0.0 {
        add = f32(hits[k]) / HIT_UNIT * params.volume_m3 / area;
    }
    fresh[k] = add;
    hits[k] = 0u;
}
