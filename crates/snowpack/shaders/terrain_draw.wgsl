// #import shared/frame
// #import shared/lighting
// #import shared/terrain
// #import shared/terrain_kind

// The snow terrain: CDLOD patches (instanced grids) displaced by the displayed
// snow surface inside the deformation window and by terrain + rest depth
// outside it, geomorphed so levels blend without popping or cracks.

@group(1) @binding(0) var<storage, read> surface: array<vec2<u32>>;
@group(1) @binding(1) var<storage, read> heightmap: array<f32>;
@group(1) @binding(2) var<uniform> terrain_params: TerrainParams;
@group(1) @binding(3) var<storage, read> ao_map: array<f32>;
@group(1) @binding(4) var decal_layer: texture_2d<f32>;
// What each texel's surface shows of its packing (packed snow m, density
// from fresh 0 to final 1; window-local; surface_unpack.wgsl).
@group(1) @binding(5) var<storage, read> packing: array<vec2<f32>>;

struct Node {
    @location(0) node: vec4<f32>,   // origin x, origin z, size (m), quads per side
    @location(1) morph: vec4<f32>,  // morph start, morph end (LOD distance, m), level, unused
}

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) grid: vec2<f32>,
    @location(2) @interpolate(flat) level: u32,
    @location(3) @interpolate(flat) quads: f32,
}

// Same as `lod_bonus` in src/render/lod.rs: detail is shifted closer by up
// to `bonus` metres over the deformation window, fading out over `margin`.
// None before the window is placed. No branch in this file tests uniforms alone: Mesa 22's lavapipe compiles such a
// shader again at every draw, uniforms inlined, and keeps every copy
// (docs/deformation.md, "Branches on uniforms"); a select chooses instead.
fn lod_bonus(xz: vec2<f32>) -> f32 {
    let lo = frame.window.xy;
    let hi = lo + vec2<f32>(frame.window.z);
    let q = max(max(lo - xz, xz - hi), vec2<f32>(0.0));
    return select(frame.lod.x * clamp(1.0 - length(q) / frame.lod.y, 0.0, 1.0), 0.0, frame.window_info.y == 0u);
}

fn lod_distance(xz: vec2<f32>) -> f32 {
    let d = length(vec3<f32>(xz.x - frame.camera.x, frame.camera.w, xz.y - frame.camera.z));
    return max(d - lod_bonus(xz), 0.0);
}

// Continuous window texel coordinates (column, row) of a world (x, z).
fn window_texel(xz: vec2<f32>) -> vec2<f32> {
    return (xz - frame.window.xy) / frame.window.w - 0.5;
}

// 1 well inside the window, falling to 0 over its outermost 4 texels, so the
// displayed surface joins the undeformed snow outside without a step.
fn window_weight(t: vec2<f32>) -> f32 {
    let last = f32(frame.window_info.x - 1u);
    let edge = min(min(t.x, t.y), min(last - t.x, last - t.y));
    return select(clamp(edge / 4.0, 0.0, 1.0), 0.0, frame.window_info.y == 0u);
}

struct Taps {
    i00: u32,
    i01: u32,
    i10: u32,
    i11: u32,
    f: vec2<f32>,
}

fn window_taps(t: vec2<f32>) -> Taps {
    let last = f32(frame.window_info.x - 1u);
    let c = clamp(t, vec2<f32>(0.0), vec2<f32>(last));
    let c0 = floor(c);
    let f = c - c0;
    let r = frame.window_info.x;
    let j0 = u32(c0.x);
    let i0 = u32(c0.y);
    let j1 = min(j0 + 1u, r - 1u);
    let i1 = min(i0 + 1u, r - 1u);
    return Taps(i0 * r + j0, i0 * r + j1, i1 * r + j0, i1 * r + j1, f);
}

fn surface_height(k: Taps) -> f32 {
    let a = bitcast<f32>(surface[k.i00].x);
    let b = bitcast<f32>(surface[k.i01].x);
    let c = bitcast<f32>(surface[k.i10].x);
    let d = bitcast<f32>(surface[k.i11].x);
    return mix(mix(a, b, k.f.x), mix(c, d, k.f.x), k.f.y);
}

fn unpack_normal(bits: u32) -> vec3<f32> {
    let xz = unpack2x16snorm(bits);
    return vec3<f32>(xz.x, sqrt(max(1.0 - dot(xz, xz), 0.0)), xz.y);
}

fn surface_normal(k: Taps) -> vec3<f32> {
    let a = unpack_normal(surface[k.i00].y);
    let b = unpack_normal(surface[k.i01].y);
    let c = unpack_normal(surface[k.i10].y);
    let d = unpack_normal(surface[k.i11].y);
    return normalize(mix(mix(a, b, k.f.x), mix(c, d, k.f.x), k.f.y));
}

fn surface_packing(k: Taps) -> vec2<f32> {
    return mix(mix(packing[k.i00], packing[k.i01], k.f.x), mix(packing[k.i10], packing[k.i11], k.f.x), k.f.y);
}

fn window_ao(k: Taps) -> f32 {
    return mix(mix(ao_map[k.i00], ao_map[k.i01], k.f.x), mix(ao_map[k.i10], ao_map[k.i11], k.f.x), k.f.y);
}

fn ground_height(xz: vec2<f32>) -> f32 {
    return terrain_height_built(terrain_params, xz.x, xz.y);
}

// Undisturbed snow: terrain plus the rest depth.
fn rest_height(xz: vec2<f32>) -> f32 {
    return ground_height(xz) + frame.snow.x;
}

fn displayed_height(xz: vec2<f32>) -> f32 {
    let t = window_texel(xz);
    let w = window_weight(t);
    let rest = rest_height(xz);
    if w <= 0.0 {
        return rest;
    }
    return mix(rest, surface_height(window_taps(t)), w);
}

fn node_vertex(vi: u32, node: Node) -> VsOut {
    let quads = u32(node.node.w);
    let grid = vec2<f32>(f32(vi % (quads + 1u)), f32(vi / (quads + 1u)));
    let step = node.node.z / f32(quads);
    let xz0 = node.node.xy + grid * step;
    // Geomorph: odd vertices slide onto their even neighbour as the LOD
    // distance crosses the morph range, reaching the next level's grid exactly.
    let morph = clamp((lod_distance(xz0) - node.morph.x) / (node.morph.y - node.morph.x), 0.0, 1.0);
    let odd = fract(grid * 0.5) * 2.0;
    let morphed = grid - odd * morph;
    let xz = node.node.xy + morphed * step;
    let world = vec3<f32>(xz.x, displayed_height(xz), xz.y);
    var out: VsOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.world = world;
    out.grid = morphed;
    out.level = u32(node.morph.z);
    out.quads = node.node.w;
    return out;
}

@vertex
fn vs_main(@builtin(vertex_index) vi: u32, node: Node) -> VsOut {
    return node_vertex(vi, node);
}

@vertex
fn vs_shadow(@builtin(vertex_index) vi: u32, node: Node) -> @builtin(position) vec4<f32> {
    let v = node_vertex(vi, node);
    return frame.light_view_proj * vec4<f32>(v.world, 1.0);
}

// Unit normal of the undisturbed snow by central differences.
fn rest_normal(xz: vec2<f32>, eps: f32) -> vec3<f32> {
    let dx = rest_height(xz + vec2<f32>(eps, 0.0)) - rest_height(xz - vec2<f32>(eps, 0.0));
    let dz = rest_height(xz + vec2<f32>(0.0, eps)) - rest_height(xz - vec2<f32>(0.0, eps));
    return normalize(vec3<f32>(-dx, 2.0 * eps, -dz));
}

fn lod_colour(level: u32) -> vec3<f32> {
    var palette = array<vec3<f32>, 8>(
        vec3<f32>(0.9, 0.2, 0.2), vec3<f32>(0.95, 0.6, 0.1), vec3<f32>(0.9, 0.9, 0.2), vec3<f32>(0.3, 0.85, 0.3),
        vec3<f32>(0.2, 0.8, 0.85), vec3<f32>(0.25, 0.4, 0.95), vec3<f32>(0.6, 0.3, 0.9), vec3<f32>(0.9, 0.4, 0.8),
    );
    return palette[level % 8u];
}

fn decode_detail(c: vec4<f32>) -> vec2<f32> {
    return c.rg * 2.0 - 1.0;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    let xz = in.world.xz;
    // Texture samples and derivatives first, in uniform control flow.
    let freq = frame.detail.z;
    let d1 = decode_detail(textureSample(detail_map, detail_sampler, xz * freq));
    let rot = mat2x2<f32>(0.8, 0.6, -0.6, 0.8);
    let d2 = decode_detail(textureSample(detail_map, detail_sampler, rot * xz * (freq * 0.23) + vec2<f32>(0.37, 0.11)));
    let grid_w = fwidth(in.grid);

    let t = window_texel(xz);
    let w = window_weight(t);
    let taps = window_taps(t);
    let ground = ground_height(xz);
    let rest = ground + frame.snow.x;
    var h = rest;
    var n = rest_normal(xz, 0.25);
    var ao = 1.0;
    var packing_shown = vec2<f32>(0.0);
    if w > 0.0 {
        h = mix(rest, surface_height(taps), w);
        n = normalize(mix(n, surface_normal(taps), w));
        ao = mix(1.0, window_ao(taps), w);
        packing_shown = surface_packing(taps) * w;
    }
    // Compaction follows the snow's state, not its shape (docs/rendering.md):
    // what the surface shows of its packing (faded out under refill:
    // surface_unpack.wgsl), the larger of its hardness and its density. The
    // hardness is Bekker's curve at q + 10 cm (docs/mechanics.md), so on a
    // log scale ln(1 + q / 0.1 m), complete at the packed snow of a press of
    // `compaction_full` of the rest depth; the density, from fresh to
    // final, is what a thin column pressed to the ground has. A berm pushed
    // aside is fresh snow; a trail refilled is fresh on top.
    let pressed = clamp((rest - h) / max(frame.snow.x, 1e-4), 0.0, 1.0);
    let full_m = max(frame.compaction.x * frame.snow.x, 1e-3);
    let hardness = log(1.0 + packing_shown.x / 0.1) / log(1.0 + full_m / 0.1);
    let compaction = smoothstep(0.0, 1.0, max(hardness, packing_shown.y));
    // Snow thickness above the ground; bare ground shows where it is gone,
    // and partly at the bottom of a print pressed to the last quarter of a
    // deep layer (frame.compaction.w).
    let bare = 1.0 - smoothstep(0.005, 0.03, h - ground);
    let show_through = frame.compaction.w * smoothstep(0.75, 1.0, pressed) * (1.0 - bare);

    // Decals (the decal technique's footprints): premultiplied normal x, z, tint, coverage.
    var tint = 1.0;
    if w > 0.0 && frame.window_info.w != 0u {
        let r = i32(frame.window_info.x) - 1;
        let texel = clamp(vec2<i32>(floor(t + 0.5)), vec2<i32>(0), vec2<i32>(r));
        let decal = textureLoad(decal_layer, texel, 0);
        if decal.a > 0.0 {
            let dn = vec2<f32>(decal.r, decal.g) / decal.a * 2.0 - 1.0;
            let dn3 = vec3<f32>(dn.x, sqrt(max(1.0 - dot(dn, dn), 0.0)), dn.y);
            n = normalize(mix(n, dn3, decal.a * w));
            tint = 1.0 - decal.a * w * (0.4 - 0.4 * decal.b / decal.a);
        }
    }

    // Detail normals, UDN-blended at two scales; flattened in compacted snow.
    let detail_strength = frame.detail.y * mix(1.0, frame.compaction.y, compaction) * (1.0 - bare);
    let dxz = (d1 + d2 * 0.8) * detail_strength;
    n = normalize(vec3<f32>(n.x + dxz.x, n.y, n.z + dxz.y));

    // Macro variation: a low-frequency brightness drift so no tiling shows.
    let macro_noise = value_noise(xz.x / 9.0, xz.y / 9.0, 91u) * 0.6 + value_noise(xz.x / 31.0, xz.y / 31.0, 92u) * 0.4;
    var albedo = mix(frame.fresh.rgb, frame.packed.rgb, compaction) * (1.0 + frame.detail.w * macro_noise) * tint;
    var roughness = mix(frame.fresh.a, frame.packed.a, compaction);
    albedo = mix(albedo, frame.ground.rgb, bare + show_through);
    roughness = mix(roughness, frame.ground.a, bare + show_through);

    let sparkle = frame.detail.x * mix(1.0, frame.compaction.z, compaction) * (1.0 - bare - show_through);
    let s = Surface(in.world, n, albedo, roughness, ao, frame.scatter.rgb, frame.scatter.a, sparkle);
    var colour = shade(s);

    // The debug views, chosen by selects (see the top of `lod_bonus`): each
    // costs a few operations a pixel.
    let view = frame.window_info.z;
    // Wireframe: fade the lines where quads shrink below ~5 pixels, so
    // distant levels show their colour instead of a moire of lines; patch
    // borders stay visible at any distance (the quadtree's layout).
    let f = abs(fract(in.grid - 0.5) - 0.5) / max(grid_w, vec2<f32>(1e-5));
    let density = max(grid_w.x, grid_w.y);
    let line = (1.0 - clamp(min(f.x, f.y), 0.0, 1.0)) * clamp(1.0 - (density - 0.2) / 0.15, 0.15, 1.0);
    let in_patch = in.grid / in.quads;
    let pf = abs(fract(in_patch - 0.5) - 0.5) / max(grid_w / in.quads, vec2<f32>(1e-6));
    let border = 1.0 - clamp(min(pf.x, pf.y) - 0.5, 0.0, 1.0);
    // Deformation: red pressed below rest (fraction of the depth), blue raised (rims).
    let signed_depth = (rest - h) / max(frame.snow.x, 1e-4);
    colour = select(colour, n * 0.5 + 0.5, view == VIEW_NORMALS);
    colour = select(colour, vec3<f32>(ao), view == VIEW_AO);
    colour = select(colour, lod_colour(in.level) * (0.35 + 0.65 * max(dot(n, frame.sun.xyz), 0.0)), view == VIEW_LOD);
    colour = select(colour, mix(colour, lod_colour(in.level) * 2.0, max(line, border)), view == VIEW_WIREFRAME);
    colour = select(colour, vec3<f32>(0.12) + vec3<f32>(max(signed_depth, 0.0), 0.0, max(-signed_depth * 4.0, 0.0)), view == VIEW_DEFORMATION);
    return vec4<f32>(colour, 1.0);
}
