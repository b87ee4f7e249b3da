// #import shared/window
// #import shared/terrain
// #import shared/terrain_kind
// #import shared/snow_word
// #import shared/packed_snow

// Surface unpack pass (the renderer's): the displayed height of every texel
// (terrain + the upper half of its `snow` word, shared/snow_word.wgsl), and
// its normal by central differences from a 18x18 workgroup-memory tile
// (16x16 plus a one-texel apron, clamped at the window's edges), packed
// window-local for the passes that march or draw the height field:
//   surface[t] = (bitcast<u32>(height), pack2x16snorm(normal.x, normal.z))
// with normal.y = sqrt(1 - x^2 - z^2), and what the surface shows of the
// packed snow (`packing`: the packed snow in metres and the column's
// density as a fraction from fresh to final, tent-filtered over 3x3, for
// the compacted look: docs/rendering.md). The
// deformation does not need them: games sample the snow words directly
// (snow_sampling.wgsl).
// CPU twin: src/cpu/surface_unpack.rs.

struct UnpackParams {
    origin: vec2<i32>,
    resolution: u32,
    texel_m: f32,
    storage_origin: vec2<u32>, // origin wrapped into 0..resolution (storage_index_wrapped)
    pack_ratio: f32,           // rho_max / rho_fresh - 1: the most packed snow per metre of column
    depth_m: f32,              // rest depth: the snow words are deficits below terrain + depth + lying snow
    use_fallen: u32,           // 1: `fallen` holds the lying snow (else it is a 4-byte stand-in)
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: UnpackParams;
@group(0) @binding(1) var<storage, read> snow: array<u32>;
@group(0) @binding(2) var<storage, read> heightmap: array<f32>;
@group(0) @binding(3) var<uniform> terrain_params: TerrainParams;
@group(0) @binding(4) var<storage, read_write> surface: array<vec2<u32>>;
// The window's packed snow, two texels a word (shared/packed_snow.wgsl).
@group(0) @binding(5) var<storage, read> packed: array<u32>;
@group(0) @binding(6) var<storage, read_write> packing: array<vec2<f32>>;
// The lying snow (snowfall, berms), with `use_fallen`.
@group(0) @binding(7) var<storage, read> fallen: array<f32>;

const TILE: u32 = 16u;
const SPAN: u32 = 18u;

var<workgroup> tile: array<f32, 324>;
var<workgroup> tile_packing: array<vec2<f32>, 324>;

// What the surface of a texel with snow word `word`, packed snow `q`
// (quanta) and `column_m` of snow above the terrain shows of its packing:
// (the packed snow in m, the density as a fraction from fresh, 0, to
// final, 1: q / column / pack_ratio, and 1 where a press left no column:
// the limit of a column pressed thinner and thinner), unless refill has
// laid fresh snow over it. A press packs as much as it lowers the snow, so
// the fresh snow over the packed layer is about `q - deficit`; from 3 cm
// of it the surface is fresh. Twin: `cpu::surface_unpack::surface_packing`.
fn surface_packing(word: u32, q: u32, column_m: f32) -> vec2<f32> {
    let cover = f32(q - min(q, word & 0xffffu)) * SNOW_QUANTUM_M;
    let q_m = f32(q) * SNOW_QUANTUM_M;
    let cap_m = column_m * params.pack_ratio;
    let density = select(clamp(q_m / max(cap_m, 1e-6), 0.0, 1.0), 1.0, cap_m < 1e-4 && (word & 0xffffu) > 0u);
    return vec2<f32>(q_m, density) * (1.0 - smoothstep(0.005, 0.03, cover));
}

// Window-local texel (i, j), clamped to the window: its displayed height
// into `tile` and what it shows of its packing into `tile_packing`, at `k`.
fn load(k: u32, i: i32, j: i32) {
    let r = i32(params.resolution) - 1;
    let ci = u32(clamp(i, 0, r));
    let cj = u32(clamp(j, 0, r));
    let s = storage_index_wrapped(params.storage_origin, params.resolution, ci, cj);
    let ground = window_ground(terrain_params, s, params.origin + vec2<i32>(i32(cj), i32(ci)), params.texel_m);
    let word = snow[s];
    tile[k] = snow_word_shown(word, ground);
    // The persistent column (the displayed one has rims and blur): a select,
    // so that no branch tests a uniform alone.
    let lying = select(0.0, fallen[min(s, arrayLength(&fallen) - 1u)], params.use_fallen != 0u);
    let column = snow_column_height(word, ground, params.depth_m + lying) - ground;
    tile_packing[k] = surface_packing(word, packed_get(packed[packed_index(s)], s), column);
}

@compute @workgroup_size(16, 16)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>, @builtin(local_invocation_index) flat: u32) {
    let i0 = i32(wg.y * TILE) - 1;
    let j0 = i32(wg.x * TILE) - 1;
    for (var k = flat; k < SPAN * SPAN; k += TILE * TILE) {
        load(k, i0 + i32(k / SPAN), j0 + i32(k % SPAN));
    }
    workgroupBarrier();

    let i = wg.y * TILE + lid.y;
    let j = wg.x * TILE + lid.x;
    if i >= params.resolution || j >= params.resolution {
        return;
    }
    let t = (lid.y + 1u) * SPAN + lid.x + 1u;
    let dx = tile[t + 1u] - tile[t - 1u];
    let dz = tile[t + SPAN] - tile[t - SPAN];
    let n = normalize(vec3(-dx, 2.0 * params.texel_m, -dz));
    surface[i * params.resolution + j] = vec2<u32>(bitcast<u32>(tile[t]), pack2x16snorm(vec2(n.x, n.z)));
    // A 3x3 tent (1 2 1) over the packing, as the display blurs the heights:
    // a press's edge on the texel grid would otherwise show its staircase.
    let edges = tile_packing[t - 1u] + tile_packing[t + 1u] + tile_packing[t - SPAN] + tile_packing[t + SPAN];
    let corners = tile_packing[t - SPAN - 1u] + tile_packing[t - SPAN + 1u] + tile_packing[t + SPAN - 1u] + tile_packing[t + SPAN + 1u];
    packing[i * params.resolution + j] = (4.0 * tile_packing[t] + 2.0 * edges + corners) / 16.0;
}
