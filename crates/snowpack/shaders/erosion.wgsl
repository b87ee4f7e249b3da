// #import shared/window
// #import shared/terrain
// #import shared/terrain_kind
// #import shared/snow_word
// #import shared/packed_snow
// #import shared/pack_press

// Erosion pass (docs/mechanics.md, "Erosion"): where a press left a wall
// steeper than the snow's angle of repose, snow slides from its top into
// the trench (Sumner, O'Brien and Hodgins 1999, *Animating Sand, Mud, and
// Snow*: material moves from a cell to a lower neighbour while the slope
// between them exceeds the angle of repose). The slope is taken between the
// levels above or below the rest surface (lying snow, the berms, less the
// deficit), not the heights: untouched snow on steep terrain stays where
// it fell, and only what presses and displacement disturbed moves.
// Pairwise and in place: one thread owns two neighbouring texels (along x
// or z, even or odd pairs: four dispatches an iteration), reads and writes
// only them, so no texel is touched twice in a dispatch and the snow moved
// out of one is exactly what the other gains, in whole quanta:
//   level = lying (quanta) - deficit
//   diff  = level_a - level_b                (b the lower snow)
//   move  = (diff - threshold) / 2           when diff > threshold
//           at most what a holds above the terrain
//   a: deficit += move, packed -= move * packed_a / column_a
//   b: deficit -= move, at most its deficit; the rest lies on b (fallen);
//      packed += that much
// so the window's snow (sum of column + packed) does not change. The moved
// snow keeps a's density, which never takes b past the final density.
// CPU twin: src/cpu/erosion.rs.

struct ErosionParams {
    origin: vec2<i32>,
    resolution: u32,
    texel_m: f32,
    storage_origin: vec2<u32>, // origin wrapped into 0..resolution
    depth_m: f32,
    threshold_q: u32,  // tan(repose) * texel, in snow quanta
    axis: u32,         // 0: pairs along x (columns j, j + 1), 1: along z (rows)
    offset: u32,       // 0: pairs start at even indices, 1: at odd
    use_fallen: u32,   // the rest height includes the snowfall so far
    marks: u32,        // 1: the update marked the texels the actors press (displacement)
}

@group(0) @binding(0) var<uniform> params: ErosionParams;
// Packed snow, two texels a word (shared/packed_snow.wgsl); atomics, as the
// two texels of a word may belong to two threads.
@group(0) @binding(1) var<storage, read_write> packed: array<atomic<u32>>;
@group(1) @binding(0) var<uniform> terrain_params: TerrainParams;
@group(1) @binding(1) var<storage, read> heightmap: array<f32>;
@group(1) @binding(2) var<storage, read_write> snow: array<u32>; // shared/snow_word.wgsl
@group(1) @binding(4) var<storage, read_write> fallen: array<f32>;

// Quanta from texel `s` (window-local i, j) down to the terrain.
fn column_quanta(s: u32, i: u32, j: u32) -> u32 {
    let ground = window_ground(terrain_params, s, params.origin + vec2<i32>(i32(j), i32(i)), params.texel_m);
    // A select, not a branch on the uniform (docs/deformation.md); `fallen`
    // is one texel long without snowfall.
    let lying = fallen[min(s, arrayLength(&fallen) - 1u)];
    let column = params.depth_m + select(0.0, lying, params.use_fallen != 0u);
    return snow_column_press(ground, column, ground);
}

// Texel `s`'s lying snow (snowfall so far, berms) in whole quanta, rounded:
// a product then a rounding, which no backend fuses, so the twin agrees.
fn lying_quanta(s: u32) -> i32 {
    let lying = fallen[min(s, arrayLength(&fallen) - 1u)];
    return i32(round(select(0.0, lying, params.use_fallen != 0u) * 10000.0));
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let res = params.resolution;
    // Pair k along the axis: indices 2k + offset and 2k + offset + 1.
    let along = 2u * gid.x + params.offset;
    let across = gid.y;
    let z = params.axis == 1u;
    let i0 = select(across, along, z);
    let j0 = select(along, across, z);
    let i1 = i0 + select(0u, 1u, z);
    let j1 = j0 + select(1u, 0u, z);
    if max(i1, j1) >= res || max(i0, j0) >= res {
        return;
    }
    let s0 = storage_index_wrapped(params.storage_origin, res, i0, j0);
    let s1 = storage_index_wrapped(params.storage_origin, res, i1, j1);
    let w0 = snow[s0];
    let w1 = snow[s1];
    // Snow does not slide into or out of a texel an actor presses (Sumner et
    // al. move material only between columns out of contact): the update's
    // marks (shared/displace.wgsl) while displacing.
    let marked = select(0u, (w0 >> 27u) | (w1 >> 27u), params.marks != 0u);
    if marked != 0u {
        return;
    }
    let d0 = w0 & 0xffffu;
    let d1 = w1 & 0xffffu;
    // The level of each above (berms) or below (trails) the rest surface.
    let l0 = lying_quanta(s0) - i32(d0);
    let l1 = lying_quanta(s1) - i32(d1);
    // a: the higher snow, b: the lower.
    var sa = s0;
    var sb = s1;
    var da = d0;
    var db = d1;
    var ga = column_quanta(s0, i0, j0);
    if l1 > l0 {
        sa = s1;
        sb = s0;
        da = d1;
        db = d0;
        ga = column_quanta(s1, i1, j1);
    }
    let diff = u32(abs(l1 - l0));
    if diff <= params.threshold_q {
        return;
    }
    let column_a = ga - min(da, ga);
    let moved = min((diff - params.threshold_q) / 2u, column_a);
    if moved == 0u {
        return;
    }
    let qa = packed_get(atomicLoad(&packed[packed_index(sa)]), sa);
    let qb = packed_get(atomicLoad(&packed[packed_index(sb)]), sb);
    let carried = moved * qa / column_a;
    // a gives from its column; b fills its trail, then lies on its surface.
    let filled = min(moved, db);
    snow[sa] = (snow[sa] & 0xffff0000u) | (da + moved);
    snow[sb] = (snow[sb] & 0xffff0000u) | (db - filled);
    if moved > filled {
        fallen[sb] = fallen[sb] + f32(moved - filled) * 0.0001;
    }
    packed_set(sa, qa, qa - carried);
    packed_set(sb, qb, min(qb + carried, 65535u));
}
