// The snow over a game's own mesh (SnowCoverMaterial): how far the snow
// lifts a vertex above the mesh, the slope that adds to the mesh's normal,
// and how pressed the snow is. Plain WGSL placed after each shader's imports
// (its group number is filled in from Rust).
//
// The snow words come as a texture (R32Uint, the deformation's toroidal
// order: stored texel (col, row) is global texel (col, row) mod resolution;
// the upper 16 bits are the displayed height above the terrain as an f16),
// copied from the deformation's buffer each frame: Debian 12's lavapipe
// crashes on Bevy mesh draws whose position depends on a storage-buffer read,
// and a texture read is what Bevy's own morph targets do in the vertex stage.

struct SnowCoverWindow {
    corner: vec2<f32>,          // world (x, z) of local texel (0, 0)'s outer corner, minus the floating origin
    floating_origin: vec2<f32>,
    origin_texel: vec2<i32>,
    texel_m: f32,
    rest_depth_m: f32,
    resolution: u32,
    placed: u32,                // 0 until the deformation has run a frame
    storage_origin: vec2<u32>,  // where local texel (0, 0) is stored
}

// Fresh snow (albedo, roughness), pressed snow (albedo, roughness), and
// (compaction_full, ground_show_through, cover_from_m, cover_full_m).
struct SnowCoverLook {
    fresh: vec4<f32>,
    packed: vec4<f32>,
    params: vec4<f32>,
}

@group(MATERIAL_GROUP) @binding(100) var<uniform> snow_cover_window: SnowCoverWindow;
@group(MATERIAL_GROUP) @binding(101) var snow_cover_words: texture_2d<u32>;
@group(MATERIAL_GROUP) @binding(102) var<uniform> snow_cover_look: SnowCoverLook;

fn snow_cover_inside(world_xz: vec2<f32>) -> bool {
    let extent = f32(snow_cover_window.resolution) * snow_cover_window.texel_m;
    let q = world_xz - snow_cover_window.corner;
    // The point's tests first: a branch on the uniform alone has Mesa 22's
    // lavapipe compile the shader again at every draw.
    return all(q >= vec2<f32>(0.0)) && all(q <= vec2<f32>(extent)) && snow_cover_window.placed != 0u;
}

// Displayed height above the terrain of local texel (i, j), clamped into the window.
fn snow_cover_above(i: i32, j: i32) -> f32 {
    let r = snow_cover_window.resolution;
    let si = snow_cover_window.storage_origin.y + u32(clamp(i, 0, i32(r) - 1));
    let sj = snow_cover_window.storage_origin.x + u32(clamp(j, 0, i32(r) - 1));
    let texel = vec2<u32>(select(sj, sj - r, sj >= r), select(si, si - r, si >= r));
    let h = textureLoad(snow_cover_words, texel, 0).r >> 16u;
    // The f16 decoded with integer operations, as the library's sampling module does.
    let e = (h >> 10u) & 0x1fu;
    let sign = (h & 0x8000u) << 16u;
    return select(bitcast<f32>(sign | ((e + 112u) << 23u) | ((h & 0x3ffu) << 13u)), bitcast<f32>(sign), e == 0u);
}

// Position of a point among the texel centres: the lower-left centre's (column, row) and the bilinear weights.
fn snow_cover_taps(world_xz: vec2<f32>) -> vec4<f32> {
    let last = f32(snow_cover_window.resolution - 1u);
    let t = clamp((world_xz - snow_cover_window.corner) / snow_cover_window.texel_m - 0.5, vec2<f32>(0.0), vec2<f32>(last));
    let c = floor(t);
    return vec4<f32>(c, t - c);
}

fn snow_cover_bilinear(f: vec2<f32>, a: f32, b: f32, c: f32, d: f32) -> f32 {
    return mix(mix(a, b, f.x), mix(c, d, f.x), f.y);
}

// How far the snow lifts a point of the mesh: the snow's displayed height
// above the terrain there (bilinear between texel centres), the rest depth
// outside the window.
fn snow_cover_lift(world_xz: vec2<f32>) -> f32 {
    let k = snow_cover_taps(world_xz);
    let j = i32(k.x);
    let i = i32(k.y);
    let inside = snow_cover_bilinear(
        k.zw, snow_cover_above(i, j), snow_cover_above(i, j + 1), snow_cover_above(i + 1, j), snow_cover_above(i + 1, j + 1));
    return select(snow_cover_window.rest_depth_m, inside, snow_cover_inside(world_xz));
}

// The slope (d/dx, d/dz) of the lift: central differences over one texel at the four texels, bilinear.
fn snow_cover_slope(world_xz: vec2<f32>) -> vec2<f32> {
    let k = snow_cover_taps(world_xz);
    let j = i32(k.x);
    let i = i32(k.y);
    let dx = snow_cover_bilinear(
        k.zw,
        snow_cover_above(i, j + 1) - snow_cover_above(i, j - 1),
        snow_cover_above(i, j + 2) - snow_cover_above(i, j),
        snow_cover_above(i + 1, j + 1) - snow_cover_above(i + 1, j - 1),
        snow_cover_above(i + 1, j + 2) - snow_cover_above(i + 1, j),
    );
    let dz = snow_cover_bilinear(
        k.zw,
        snow_cover_above(i + 1, j) - snow_cover_above(i - 1, j),
        snow_cover_above(i + 1, j + 1) - snow_cover_above(i - 1, j + 1),
        snow_cover_above(i + 2, j) - snow_cover_above(i, j),
        snow_cover_above(i + 2, j + 1) - snow_cover_above(i, j + 1),
    );
    let slope = vec2<f32>(dx, dz) / (2.0 * snow_cover_window.texel_m);
    return select(vec2<f32>(0.0), slope, snow_cover_inside(world_xz));
}

// The mesh's normal with the snow's slope added (a heightfield's normal is
// (-dh/dx, 1, -dh/dz) and the mesh's gives the terrain's part); steep
// faces (walls) keep their own.
fn snow_cover_normal(mesh_normal: vec3<f32>, world_xz: vec2<f32>) -> vec3<f32> {
    let up = max(mesh_normal.y, 1e-3);
    let s = snow_cover_slope(world_xz);
    let covered = normalize(vec3<f32>(mesh_normal.x / up - s.x, 1.0, mesh_normal.z / up - s.y));
    return select(mesh_normal, covered, mesh_normal.y > 0.2);
}

// 0 untouched .. 1 pressed to the ground: (rest depth - lift) / rest depth; 0 outside the window.
fn snow_cover_compaction(world_xz: vec2<f32>) -> f32 {
    let depth = snow_cover_window.rest_depth_m;
    return clamp((depth - snow_cover_lift(world_xz)) / max(depth, 1e-4), 0.0, 1.0);
}
