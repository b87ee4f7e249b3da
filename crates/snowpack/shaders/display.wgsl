// #import shared/window
// #import shared/terrain
// #import shared/terrain_kind
// #import shared/stamp
// #import shared/snow_word

// Display pass: the displayed snow height, written into the upper half of
// each `snow` word (shared/snow_word.wgsl) as its height above the terrain.
// It is the rim, then (with `blur`) the separable 5x5 Gaussian (1 4 6 4 1)/16
// of the rimmed height, clamped at the window's edges, fused in one dispatch:
// a workgroup computes the rim of its 16x16 texels and a 2-texel apron into
// workgroup memory, blurs along x there, then along z (four outputs per
// invocation, blur4), and writes only its own texels' words, so no scratch
// buffer is needed.
// The rim, mode 0 (depth, decals): Hanák's cubic remap (eq. 4.1),
//   f(x) = -3.4766x^3 + 6.508x^2 - 2.231x + 0.215,
// applied to the normalised snow depth x and blended in by `elevation`:
//   shown = terrain + depth * (x + elevation * (f(x) - x)),
// depth being the rest depth plus the snowfall so far where it snows; where
// lying snow passes the snowfall so far (a berm), the remap takes the
// depth without it and the berm shows as it is.
// Modes 1 (MS16) and 2 (Wasmut's rounded variant), for points and combined:
// the persistent snow as it is, plus a rim where a stored footprint rises
// above the rest height over undisturbed snow, from its foot height:
//   e = sqrt(h - foot) - sqrt(rest - foot), M = sqrt(rest - foot), r = e / M,
//   MS16: 1 - (0.5 - 2r)^2, rounded: 1 - (2r - 1)^2, clamped at 0,
// times elevation * RIM_PEAK * (rest - foot).
// Two kernels, the same arithmetic (`DisplayKernel`, issue 44 item 1), each
// reading a texel's word and ground once (the ground is four octaves of
// hashed noise over hills, unless the window stores it): blur4 (bit 5
// clear) blurs four outputs per invocation from eight workgroup-memory
// reads, and a quarter of the invocations write, the tile's words and
// ground kept in workgroup memory for them; per-texel (bit 5 set) gives
// every invocation its own texel, whose word and ground it keeps in
// registers, every invocation writing, at five reads per output along each
// axis. Which is faster depends on the adapter; the bench measures both
// side by side (`snowpack bench --only display`).
// `snow` is atomic here only because other workgroups read the lower half of
// words whose upper half this one writes: each word has one writer, which
// keeps the lower half it read. CPU twin: snowpack-testkit's cpu/display.rs.

struct DisplayParams {
    origin: vec2<i32>,
    resolution: u32,
    depth_m: f32,
    elevation: f32,
    mode: u32,
    low_m: f32,
    high_m: f32,
    use_fallen: u32,  // 1: the rest depth includes `fallen` (snowfall so far)
    texel_m: f32,
    blur: u32,        // 1: blur the rimmed height
    open_fallen_m: f32, // snowfall so far on open ground: lying snow beyond it is a berm
    storage_origin: vec2<u32>, // origin wrapped into 0..resolution (storage_index_wrapped)
}

@group(0) @binding(0) var<uniform> params: DisplayParams;
// The terrain's source (shared/terrain.wgsl), evaluated at texel centres.
@group(1) @binding(1) var<storage, read> heightmap: array<f32>;
@group(1) @binding(2) var<storage, read_write> snow: array<atomic<u32>>;
@group(1) @binding(3) var<storage, read_write> stamps: array<u32>;
@group(1) @binding(4) var<storage, read_write> fallen: array<f32>;
@group(1) @binding(0) var<uniform> terrain_params: TerrainParams;

// The choices this pipeline is built for, packed as in
// `DisplayParams::variant` (mode | blur << 2 | use_fallen << 3 | bare << 4),
// and the kernel (per_texel << 5, `DisplayKernel`):
// `DisplayPass` builds one pipeline per set in use (pass/compute.rs); the
// default reads them from `params`. No branch here tests uniforms alone:
// Mesa 22's lavapipe compiles such a shader again, with the uniforms'
// values inlined, at every dispatch, and keeps each copy (docs/deformation.md).
override DISPLAY_VARIANT: u32 = 0xffffffffu;

fn display_variant() -> u32 {
    if DISPLAY_VARIANT != 0xffffffffu {
        return DISPLAY_VARIANT;
    }
    let bare = params.use_fallen == 0u && params.depth_m <= 0.0;
    return params.mode | (min(params.blur, 1u) << 2u) | (min(params.use_fallen, 1u) << 3u) | (u32(bare) << 4u);
}

fn display_mode() -> u32 {
    return display_variant() & 3u;
}

fn display_blurs() -> bool {
    return (display_variant() & 4u) != 0u;
}

fn display_uses_fallen() -> bool {
    return (display_variant() & 8u) != 0u;
}

// No snow without snowfall (depth_m 0): the rest height is the ground.
fn display_bare() -> bool {
    return (display_variant() & 16u) != 0u;
}

// The per-texel kernel (else blur4).
fn display_per_texel() -> bool {
    return (display_variant() & 32u) != 0u;
}

const RIM_PEAK: f32 = 0.25;
// Snow within this of the rest height counts as undisturbed (grows rims).
const UNDISTURBED_M: f32 = 0.001;
const TILE: u32 = 16u;
const SPAN: u32 = 20u; // TILE + 2 * 2 (the blur's radius on both sides)

// Rimmed heights of the tile and its apron, [row * SPAN + column].
var<workgroup> rimmed: array<f32, 400>;
// Blurred along x: the tile's 16 columns over the apron's 20 rows, [row * TILE + column].
var<workgroup> along_x: array<f32, 320>;
// blur4: the tile's own words and ground as first read, [row * TILE + column],
// so that its writes neither read a word again nor evaluate the ground again.
var<workgroup> tile_word: array<u32, 256>;
var<workgroup> tile_ground: array<f32, 256>;

fn hanak_cubic(x: f32) -> f32 {
    return ((-3.4766 * x + 6.508) * x - 2.231) * x + 0.215;
}

fn point_rim(st: u32, rest: f32) -> f32 {
    if st == STAMP_EMPTY {
        return 0.0;
    }
    let h = stamp_height(st >> 16u, params.low_m, params.high_m);
    let foot = stamp_height(st & 0xffffu, params.low_m, params.high_m);
    if foot >= rest || h <= rest {
        return 0.0;
    }
    let m = sqrt(rest - foot);
    let r = (sqrt(h - foot) - m) / m;
    var t: f32;
    if display_mode() == 1u {
        t = 0.5 - 2.0 * r;
    } else {
        t = 2.0 * r - 1.0;
    }
    return max(1.0 - t * t, 0.0) * params.elevation * RIM_PEAK * (rest - foot);
}

// The terrain under window-local texel (i, j), stored at `s`.
fn ground_at(s: u32, i: u32, j: u32) -> f32 {
    return window_ground(terrain_params, s, params.origin + vec2<i32>(i32(j), i32(i)), params.texel_m);
}

// The rimmed (not yet blurred) height of window-local texel (i, j).
fn rimmed_height(i: u32, j: u32) -> f32 {
    let s = storage_index_wrapped(params.storage_origin, params.resolution, i, j);
    return rimmed_of(s, atomicLoad(&snow[s]), ground_at(s, i, j));
}

// The rimmed height of the texel at storage index `s`, of snow word `word`
// over terrain height `ground`.
fn rimmed_of(s: u32, word: u32, ground: f32) -> f32 {
    var lying = 0.0;
    if display_uses_fallen() {
        lying = fallen[s];
    }
    let depth = params.depth_m + lying;
    let snow_h = snow_column_height(word, ground, depth);
    if display_bare() || (display_uses_fallen() && depth <= 0.0) {
        // Bare ground (depth_m 0, no snowfall yet): no snow to remap or to
        // push into rims. Without snowfall that is the pipeline's choice;
        // with it, this texel's.
        return snow_h;
    }
    if display_mode() == 0u {
        // Remapped over the undisturbed depth (rest depth and snowfall so
        // far); lying snow beyond the snowfall is a berm (displacement),
        // and what rises above that depth is shown as it is.
        let base = params.depth_m + min(lying, params.open_fallen_m);
        // No undisturbed depth (bare ground under a berm): nothing to remap.
        let x = select(0.0, clamp((snow_h - ground) / base, 0.0, 1.0), base > 0.0);
        let remapped = x + params.elevation * (hanak_cubic(x) - x);
        let above = select(0.0, max(snow_h - ground - base, 0.0), lying > params.open_fallen_m);
        return ground + base * max(remapped, 0.0) + above;
    }
    let rest = ground + depth;
    var out = snow_h;
    if out >= rest - UNDISTURBED_M {
        out += point_rim(stamps[s], rest);
    }
    return out;
}

// The 5-tap Gaussian (1 4 6 4 1)/16 of a[0..8] at taps 0..3 (four outputs
// from eight inputs: each workgroup-memory value is read about twice, not five
// times; those reads were most of this pass's time on a SIMD software
// rasteriser, which gathers them lane by lane).
fn blur4(a: vec4<f32>, b: vec4<f32>) -> vec4<f32> {
    return (a + 4.0 * vec4(a.yzw, b.x) + 6.0 * vec4(a.zw, b.xy) + 4.0 * vec4(a.w, b.xyz) + b) * (1.0 / 16.0);
}


// The 5-tap Gaussian of one output, summed in blur4's order (bit for bit the same).
fn blur1(a: f32, b: f32, c: f32, d: f32, e: f32) -> f32 {
    return (a + 4.0 * b + 6.0 * c + 4.0 * d + e) * (1.0 / 16.0);
}

// Where the apron's k-th texel of the 144 around the tile lies in the
// SPAN x SPAN block: rows 0, 1, 18 and 19 whole, then columns 0, 1, 18 and
// 19 of rows 2 to 17.
fn ring_index(k: u32) -> u32 {
    let edge = array<u32, 4>(0u, 1u, SPAN - 2u, SPAN - 1u);
    if k < 4u * SPAN {
        return edge[k / SPAN] * SPAN + k % SPAN;
    }
    let t = k - 4u * SPAN;
    return (2u + t / 4u) * SPAN + edge[t % 4u];
}

// The per-texel kernel: this invocation's texel (i, j) keeps its word and
// ground from the first read to the write.
fn display_per_texel_main(wg: vec2<u32>, lid: vec2<u32>, flat: u32) {
    let last = params.resolution - 1u;
    let i = wg.y * TILE + lid.y;
    let j = wg.x * TILE + lid.x;
    // A texel past the window's edge reads the edge (the clamp) and writes nothing.
    let ci = min(i, last);
    let cj = min(j, last);
    let s = storage_index_wrapped(params.storage_origin, params.resolution, ci, cj);
    let word = atomicLoad(&snow[s]);
    let ground = ground_at(s, ci, cj);
    let own = rimmed_of(s, word, ground);
    if !display_blurs() {
        if i == ci && j == cj {
            atomicStore(&snow[s], snow_word_with_shown(word, own - ground));
        }
        return;
    }
    rimmed[(lid.y + 2u) * SPAN + lid.x + 2u] = own;
    if flat < SPAN * SPAN - TILE * TILE {
        let k = ring_index(flat);
        let ri = clamp(i32(wg.y * TILE) - 2 + i32(k / SPAN), 0, i32(last));
        let rj = clamp(i32(wg.x * TILE) - 2 + i32(k % SPAN), 0, i32(last));
        rimmed[k] = rimmed_height(u32(ri), u32(rj));
    }
    workgroupBarrier();
    // Along x: the 20 rows' 16 columns, 320 outputs over 256 invocations.
    for (var o = flat; o < SPAN * TILE; o += TILE * TILE) {
        let r = (o / TILE) * SPAN + o % TILE;
        along_x[o] = blur1(rimmed[r], rimmed[r + 1u], rimmed[r + 2u], rimmed[r + 3u], rimmed[r + 4u]);
    }
    workgroupBarrier();
    // Along z: this invocation's own output.
    let t = lid.y * TILE + lid.x;
    let shown = blur1(along_x[t], along_x[t + TILE], along_x[t + 2u * TILE], along_x[t + 3u * TILE], along_x[t + 4u * TILE]);
    if i == ci && j == cj {
        atomicStore(&snow[s], snow_word_with_shown(word, shown - ground));
    }
}

@compute @workgroup_size(16, 16)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>, @builtin(local_invocation_index) flat: u32) {
    if display_per_texel() {
        display_per_texel_main(wg.xy, lid.xy, flat);
        return;
    }
    if !display_blurs() {
        let i = wg.y * TILE + lid.y;
        let j = wg.x * TILE + lid.x;
        if i < params.resolution && j < params.resolution {
            let s = storage_index_wrapped(params.storage_origin, params.resolution, i, j);
            let word = atomicLoad(&snow[s]);
            let ground = ground_at(s, i, j);
            atomicStore(&snow[s], snow_word_with_shown(word, rimmed_of(s, word, ground) - ground));
        }
        return;
    }
    let last = i32(params.resolution) - 1;
    let i0 = i32(wg.y * TILE) - 2;
    let j0 = i32(wg.x * TILE) - 2;
    for (var k = flat; k < SPAN * SPAN; k += TILE * TILE) {
        let row = k / SPAN;
        let col = k % SPAN;
        let i = u32(clamp(i0 + i32(row), 0, last));
        let j = u32(clamp(j0 + i32(col), 0, last));
        let s = storage_index_wrapped(params.storage_origin, params.resolution, i, j);
        let word = atomicLoad(&snow[s]);
        let ground = ground_at(s, i, j);
        rimmed[k] = rimmed_of(s, word, ground);
        if row >= 2u && row < TILE + 2u && col >= 2u && col < TILE + 2u {
            let t = (row - 2u) * TILE + col - 2u;
            tile_word[t] = word;
            tile_ground[t] = ground;
        }
    }
    workgroupBarrier();
    // Along x: 80 invocations, each four outputs of one row.
    if flat < SPAN * TILE / 4u {
        let row = flat / 4u;
        let c0 = (flat % 4u) * 4u;
        let r = row * SPAN + c0;
        let x = blur4(vec4(rimmed[r], rimmed[r + 1u], rimmed[r + 2u], rimmed[r + 3u]), vec4(rimmed[r + 4u], rimmed[r + 5u], rimmed[r + 6u], rimmed[r + 7u]));
        let o = row * TILE + c0;
        along_x[o] = x.x;
        along_x[o + 1u] = x.y;
        along_x[o + 2u] = x.z;
        along_x[o + 3u] = x.w;
    }
    workgroupBarrier();
    // Along z: 64 invocations, each four rows of one column, written out.
    if flat < TILE * TILE / 4u {
        let c = flat % TILE;
        let r0 = (flat / TILE) * 4u;
        let t = r0 * TILE + c;
        let z = blur4(
            vec4(along_x[t], along_x[t + TILE], along_x[t + 2u * TILE], along_x[t + 3u * TILE]),
            vec4(along_x[t + 4u * TILE], along_x[t + 5u * TILE], along_x[t + 6u * TILE], along_x[t + 7u * TILE]),
        );
        let i = wg.y * TILE + r0;
        let j = wg.x * TILE + c;
        for (var n = 0u; n < 4u; n++) {
            if i + n < params.resolution && j < params.resolution {
                let s = storage_index_wrapped(params.storage_origin, params.resolution, i + n, j);
                let k = t + n * TILE;
                atomicStore(&snow[s], snow_word_with_shown(tile_word[k], z[n] - tile_ground[k]));
            }
        }
    }
}
