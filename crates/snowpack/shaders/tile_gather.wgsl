// #import shared/window
// #import shared/stamp
// #import shared/pass_flags
// #import shared/packed_snow

// Tile gather pass (shared snow): copies whole tiles on the global grid out
// of the window's toroidal buffers into a packed buffer the CPU reads back
// (src/replicate/gather.rs). Per tile t, three planes of side*side u32,
// row-major (row = +z): the deficit (snow word & 0xffff) with the packed
// snow in the high half, the packed footprint, the snowfall lying (f32
// bits). Texels outside the window get the merge's identity (deficit 0, no
// packed snow, no footprint, no snowfall), so a tile the
// window only partly covers says nothing about the rest.
// One invocation per texel: x, y within the tile, workgroup z... flattened:
// workgroup (x, y) covers an 8x8 block, y also selects the tile.
// CPU twin: src/cpu/tile_gather.rs.

struct TileGatherParams {
    origin: vec2<i32>, // global texel of window-local (0, 0): (column, row)
    resolution: u32,
    side: u32,         // tile side (texels)
    count: u32,        // tiles in `keys`
    flags: u32,        // 1: the window has footprints, 2: it has snowfall
    blocks: u32,       // 8x8 blocks per tile side: ceil(side / 8)
    _pad: u32,
}

const GATHER_HAS_STAMPS: u32 = 1u;
const GATHER_USE_FALLEN: u32 = 2u;

@group(0) @binding(0) var<uniform> params: TileGatherParams;

@group(0) @binding(1) var<storage, read> keys: array<vec2<i32>>; // tile (column, row)
@group(1) @binding(2) var<storage, read> snow: array<u32>;
@group(1) @binding(3) var<storage, read> stamps: array<u32>;
@group(1) @binding(4) var<storage, read> fallen: array<f32>;
@group(0) @binding(2) var<storage, read_write> gathered: array<u32>;
// The window's packed snow, two texels a word (shared/packed_snow.wgsl).
@group(0) @binding(3) var<storage, read> packed: array<u32>;

@compute @workgroup_size(8, 8)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    // wg.x: block within the tile (blocks * blocks of them); wg.y: the tile.
    let t = wg.y;
    let x = (wg.x % params.blocks) * 8u + lid.x;
    let y = (wg.x / params.blocks) * 8u + lid.y;
    if t >= params.count || x >= params.side || y >= params.side {
        return;
    }
    let key = keys[t];
    let g = key * i32(params.side) + vec2<i32>(i32(x), i32(y));
    let local = g - params.origin;
    let r = i32(params.resolution);
    var deficit = 0u;
    var stamp = STAMP_EMPTY;
    var lying = 0.0;
    if local.x >= 0 && local.y >= 0 && local.x < r && local.y < r {
        let s = storage_index(params.origin, params.resolution, u32(local.y), u32(local.x));
        deficit = (snow[s] & 0xffffu) | (packed_get(packed[packed_index(s)], s) << 16u);
        if (pass_flags() & GATHER_HAS_STAMPS) != 0u {
            stamp = stamps[s];
        }
        if (pass_flags() & GATHER_USE_FALLEN) != 0u {
            lying = fallen[s];
        }
    }
    let area = params.side * params.side;
    let k = t * 3u * area + y * params.side + x;
    gathered[k] = deficit;
    gathered[k + area] = stamp;
    gathered[k + 2u * area] = bitcast<u32>(lying);
}
