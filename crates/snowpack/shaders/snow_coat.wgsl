// #import shared/window
// #import shared/terrain
// #import shared/terrain_kind
// #import shared/snow_word
// #import shared/sky_test

// Snow coat: the snow each vertex of a skinned character carries (m, one f32
// a vertex), after the frame's skinning and the ground's update. A vertex
//   - wading: below the snow it stands in gains `cling_per_s` times its depth
//     under that snow each second, up to `cap_m`. The capture has already
//     pressed the snow under the body down to it, so the snow waded through is
//     the highest persistent snow within `wade_radius_m` (the centre and eight
//     points on a circle), each read as the point queries read it (bilinear
//     between texel centres, query.wgsl). No snow is above its rest surface,
//     so a vertex higher than the rest surface under it plus the radius (a
//     45-degree rise) reads only the centre: most of a body skips the circle;
//   - snowfall: facing up and reached by the sky (the objects' occlusion map,
//     as the ground's update tests it) gains this frame's fall times the up
//     component of its normal, up to `cap_m`;
//   - losing it: melts at `melt_m_per_s`, and where it moved faster than
//     `shake_speed_m_per_s` since the last frame (a jump farther than
//     `teleport_m` is no motion) loses `1 - exp(-shake_per_s dt)` of it.
// One thread a vertex. CPU twin: src/cpu/snow_coat.rs.

struct SnowCoatParams {
    origin: vec2<i32>,
    resolution: u32,
    vertex_count: u32,
    corner_m: vec2<f32>,    // world x, z of the window's corner
    texel_m: f32,
    depth_m: f32,
    dt_s: f32,
    fall_m: f32,
    cling_per_s: f32,
    cap_m: f32,
    melt_m_per_s: f32,
    shake_speed_m_per_s: f32,
    shake_per_s: f32,
    wade_radius_m: f32,
    use_fallen: u32,
    use_sky: u32,
    has_previous: u32,
    teleport_m: f32,
    sky: SkyTest,           // the occlusion's projection and range (shared/sky_test.wgsl)
    storage_origin: vec2<u32>, // origin wrapped into 0..resolution (storage_index_wrapped)
}

@group(0) @binding(0) var<uniform> params: SnowCoatParams;
@group(0) @binding(1) var<storage, read> positions: array<f32>;
@group(0) @binding(2) var<storage, read> previous: array<f32>;
@group(0) @binding(3) var<storage, read> normals: array<f32>;
@group(0) @binding(4) var<storage, read_write> coat: array<f32>;
@group(1) @binding(1) var<storage, read> heightmap: array<f32>;
@group(1) @binding(2) var<storage, read> snow: array<u32>;
@group(1) @binding(4) var<storage, read> fallen: array<f32>;
@group(1) @binding(0) var<uniform> terrain_params: TerrainParams;
@group(0) @binding(5) var sky: texture_2d<f32>;

// The inputs this pipeline is built for, `use_fallen | use_sky << 1`
// (`SnowCoatPass` builds one per set in use, pass/compute.rs); the
// default reads them from `params`. Built in, no branch tests a uniform
// alone: Mesa 22's lavapipe compiles such a shader again at every dispatch,
// uniforms inlined, and keeps every copy (docs/deformation.md, "Branches on
// uniforms").
override COAT_INPUTS: u32 = 0xffffffffu;

fn coat_inputs() -> u32 {
    if COAT_INPUTS != 0xffffffffu {
        return COAT_INPUTS;
    }
    return min(params.use_fallen, 1u) | (min(params.use_sky, 1u) << 1u);
}

// The circle's eight directions (cos, sin of k * 45 degrees).
const RING: array<vec2<f32>, 8> = array<vec2<f32>, 8>(
    vec2<f32>(1.0, 0.0), vec2<f32>(0.70710677, 0.70710677), vec2<f32>(0.0, 1.0), vec2<f32>(-0.70710677, 0.70710677),
    vec2<f32>(-1.0, 0.0), vec2<f32>(-0.70710677, -0.70710677), vec2<f32>(0.0, -1.0), vec2<f32>(0.70710677, -0.70710677),
);

// Persistent snow height and rest height of a window texel (global g, stored at s).
fn texel_height(g: vec2<i32>, s: u32) -> vec2<f32> {
    let t = window_ground(terrain_params, s, g, params.texel_m);
    var lying = 0.0;
    if (coat_inputs() & 1u) != 0u {
        lying = fallen[s];
    }
    let column = params.depth_m + lying;
    return vec2<f32>(snow_column_height(snow[s], t, column), t + column);
}

fn lerp2v(a: vec2<f32>, b: vec2<f32>, c: vec2<f32>, d: vec2<f32>, f: vec2<f32>) -> vec2<f32> {
    let ab = a + (b - a) * f.x;
    let cd = c + (d - c) * f.x;
    return ab + (cd - ab) * f.y;
}

// Persistent snow height and rest height at window-local point q (m), or -1e30 outside.
fn height_at(q: vec2<f32>) -> vec2<f32> {
    let uv = q / params.texel_m - vec2<f32>(0.5);
    let cell = floor(uv);
    let f = uv - cell;
    let last = f32(i32(params.resolution) - 2);
    if cell.x < 0.0 || cell.y < 0.0 || cell.x > last || cell.y > last {
        return vec2<f32>(-1e30);
    }
    let j = u32(cell.x);
    let i = u32(cell.y);
    let res = params.resolution;
    let g = params.origin + vec2<i32>(i32(j), i32(i));
    // i + 1 and j + 1 are inside the window (the test above): one
    // comparison wraps each, where `storage_index` took two remainders
    // (36 texels a wading vertex).
    let o = params.storage_origin;
    return lerp2v(
        texel_height(g, storage_index_wrapped(o, res, i, j)),
        texel_height(g + vec2<i32>(1, 0), storage_index_wrapped(o, res, i, j + 1u)),
        texel_height(g + vec2<i32>(0, 1), storage_index_wrapped(o, res, i + 1u, j)),
        texel_height(g + vec2<i32>(1, 1), storage_index_wrapped(o, res, i + 1u, j + 1u)),
        f,
    );
}

// 1 where the sky reaches window-local point q at height h (update.wgsl's test).
fn sky_reaches(q0: vec2<f32>, h: f32) -> f32 {
    if (coat_inputs() & 2u) == 0u {
        return 1.0;
    }
    let pix = sky_test_pixel(params.sky, q0, h, params.texel_m, params.resolution);
    if pix.x < 0 {
        return 1.0;
    }
    return sky_test_seen(params.sky, h, textureLoad(sky, pix, 0).x);
}


@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let v = id.x;
    if v >= params.vertex_count {
        return;
    }
    let p = vec3<f32>(positions[v * 3u], positions[v * 3u + 1u], positions[v * 3u + 2u]);
    let n = vec3<f32>(normals[v * 3u], normals[v * 3u + 1u], normals[v * 3u + 2u]);
    let dt = max(params.dt_s, 0.0);
    let q = p.xz - params.corner_m;
    var c = coat[v];
    // Wading.
    let centre = height_at(q);
    var top = centre.x;
    if p.y < centre.y + params.wade_radius_m {
        for (var k = 0u; k < 8u; k++) {
            top = max(top, height_at(q + RING[k] * params.wade_radius_m).x);
        }
    }
    let under = top - p.y;
    if under > 0.0 {
        c = max(c, min(c + params.cling_per_s * under * dt, params.cap_m));
    }
    // Snowfall.
    // The vertex's test first: a branch on uniforms alone would have Mesa
    // 22's lavapipe compile this shader again at every dispatch.
    if n.y > 0.0 && params.fall_m > 0.0 {
        c = max(c, min(c + params.fall_m * n.y * sky_reaches(q, p.y), params.cap_m));
    }
    // Melting and shaking off.
    c = max(c - params.melt_m_per_s * dt, 0.0);
    // Without last frame's positions `previous` holds no positions (it is
    // read, not used); the vertex's test comes first, as above.
    let moved = length(p - vec3<f32>(previous[v * 3u], previous[v * 3u + 1u], previous[v * 3u + 2u]));
    if moved <= params.teleport_m && moved > params.shake_speed_m_per_s * dt && params.has_previous != 0u && dt > 0.0 {
        c = c * exp(-params.shake_per_s * dt);
    }
    coat[v] = c;
}
