// #import shared/window
// #import shared/share_flags
// #import shared/displace

// Displace pass (docs/mechanics.md, "Displacement"): after the update, each
// texel gathers the moves its 24 neighbours wrote into the upper half of
// their snow words (shared/displace.wgsl) that name it, and lays that snow
// on its rest surface as lying snow (`fallen`, with snowfall): a berm,
// real height for the display, the queries, the tiles and the store.
// A gather: each thread writes its own texel only, so the sum is the same
// on every backend and in the CPU twin (src/cpu/displace.rs), and the snow
// the update took out of the columns is what the berms gain. With shared
// snow (SHARE) a texel that gains flags its tile.

struct DisplaceParams {
    origin: vec2<i32>,
    resolution: u32,
    flags: u32,                // SHARE (the pipeline's DISPLACE_FLAGS)
    storage_origin: vec2<u32>, // origin wrapped into 0..resolution
    share_side: u32,
    share_keys: u32,
}

const SHARE: u32 = 1u;
// The flags this pipeline is built for (`DisplacePass` builds one per set).
override DISPLACE_FLAGS: u32 = 0u;

@group(0) @binding(0) var<uniform> params: DisplaceParams;
@group(0) @binding(1) var<storage, read_write> share_flags: array<atomic<u32>>;
@group(1) @binding(2) var<storage, read_write> snow: array<u32>; // shared/snow_word.wgsl
@group(1) @binding(4) var<storage, read_write> fallen: array<f32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let j = gid.x;
    let i = gid.y;
    let res = params.resolution;
    if i >= res || j >= res {
        return;
    }
    let here = vec2<i32>(i32(j), i32(i));
    let r = i32(res);
    var gained = 0u;
    for (var k = 0u; k < 24u; k++) {
        let n = here - displace_offset(k);
        if any(n < vec2<i32>(0)) || any(n >= vec2<i32>(r)) {
            continue;
        }
        let code = snow[storage_index_wrapped(params.storage_origin, res, u32(n.y), u32(n.x))] >> 16u;
        if displace_code_target(code) == k + 1u {
            gained += displace_code_quanta(code);
        }
    }
    if gained == 0u {
        return;
    }
    let s = storage_index_wrapped(params.storage_origin, res, i, j);
    fallen[s] = fallen[s] + f32(gained) * 0.0001;
    if (DISPLACE_FLAGS & SHARE) != 0u {
        atomicStore(&share_flags[share_slot(params.origin + here, params.share_side, params.share_keys)], 1u);
    }
}
