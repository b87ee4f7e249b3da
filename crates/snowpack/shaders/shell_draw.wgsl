// #import shared/lighting
// #import shared/shell

// Shell mapping, drawn: the shell's tetrahedra rasterised (front faces) and
// the detail volume traced inside each along the view ray with its affine
// map, at the mip level of the pixel's footprint (sphere tracing with the
// level's distance field, then fixed steps through semi-transparent voxels,
// whose coverage is opacity). Two fragment entry points serve the depth
// peeling of `shell_resolve.wgsl` (Leshonkov & Frolov 2021, section 3.1):
// `fs_layer` finds the next layer's depth (step 1) and `fs_shade` shades it
// under a depth test `equal` (step 3), blended front to back.

struct ShellDrawParams {
    dims: vec4<f32>,      // level-0 voxels along u, v, w; w: mip levels
    count: u32,           // base vertices (offset copies follow)
    use_lod: u32,         // 0: always level 0 (the paper's basic method)
    max_steps: u32,
    _pad: u32,
    lod_bias: f32,
    min_alpha: f32,       // coverage below this is empty space
    fade_m: vec2<f32>,    // the shell fades out between these distances from the camera (square, as the patch)
}

@group(1) @binding(0) var<uniform> shell: ShellDrawParams;
@group(1) @binding(1) var<storage, read> corners: array<u32>;
@group(1) @binding(2) var<storage, read> vertices: array<ShellVertex>;
@group(1) @binding(3) var<storage, read> tetras: array<Tetra>;
@group(1) @binding(4) var volume: texture_3d<f32>;
@group(1) @binding(5) var distance: texture_3d<f32>;
@group(1) @binding(6) var volume_sampler: sampler;

@group(2) @binding(0) var cull_depth: texture_2d<f32>;
@group(2) @binding(1) var scene_depth: texture_2d<f32>;

struct TetraOut {
    @invariant @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) @interpolate(flat) tetra: u32,
}

// The same vertex shader for both steps, and `@invariant`, so a layer's
// depth found in step 1 equals the depth its fragment has in step 3.
@vertex
fn vs_tetra(@builtin(vertex_index) vi: u32) -> TetraOut {
    let index = corners[vi];
    var p: vec3<f32>;
    if index < shell.count {
        p = vertices[index].base.xyz;
    } else {
        p = vertices[index - shell.count].top.xyz;
    }
    var out: TetraOut;
    out.clip = frame.view_proj * vec4<f32>(p, 1.0);
    out.world = p;
    out.tetra = vi / 12u;
    return out;
}

struct Traced {
    albedo: vec3<f32>,    // premultiplied by opacity
    alpha: f32,
    first: vec3<f32>,     // level-0 voxel position of the first hit
    w: f32,               // its height in the shell (0 base, 1 top)
}

// Barycentric coordinates of `p` in tetrahedron `t`, and their rate along `d`.
fn barycentric(t: Tetra, p: vec3<f32>) -> vec4<f32> {
    let r = p - t.origin.xyz;
    let l = vec3<f32>(dot(t.bary[0].xyz, r), dot(t.bary[1].xyz, r), dot(t.bary[2].xyz, r));
    return vec4<f32>(1.0 - l.x - l.y - l.z, l);
}

fn bary_rate(t: Tetra, d: vec3<f32>) -> vec4<f32> {
    let l = vec3<f32>(dot(t.bary[0].xyz, d), dot(t.bary[1].xyz, d), dot(t.bary[2].xyz, d));
    return vec4<f32>(-l.x - l.y - l.z, l);
}

fn texture_at(t: Tetra, b: vec4<f32>) -> vec3<f32> {
    return b.x * t.tex[0].xyz + b.y * t.tex[1].xyz + b.z * t.tex[2].xyz + b.w * t.tex[3].xyz;
}

// Level of the detail volume for this pixel: log2 of the pixel's footprint
// in level-0 voxels, from the pixel's cone (the derivatives of the ray
// direction, which do not depend on the face being rasterised) at the entry
// distance, mapped through the tetrahedron's affine map. Derivatives of the
// entry point itself would blow up on faces seen edge-on, inside the shell.
// Call in uniform control flow, before any discard.
fn footprint_lod(t: Tetra, dir: vec3<f32>, dist: f32) -> f32 {
    let fx = dpdx(dir) * dist;
    let fy = dpdy(dir) * dist;
    let dims = shell.dims.xyz;
    // Across the texture (u, v) only: where the shell is pressed flat, w is
    // squeezed and would pick levels far too coarse for the flattened detail.
    let vx = length((texture_at(t, bary_rate(t, fx)) * dims).xy);
    let vy = length((texture_at(t, bary_rate(t, fy)) * dims).xy);
    // The footprint's area (geometric mean of its axes): the longer axis of
    // a grazing view alone would blur and thin the detail.
    let lod = 0.5 * log2(max(vx * vy, 1e-12)) + shell.lod_bias;
    return select(0.0, clamp(lod, 0.0, shell.dims.w - 1.0), shell.use_lod != 0u);
}

// Distance along the ray from `entry` to the opaque scene at this pixel.
fn scene_limit(pixel: vec2<f32>, entry: vec3<f32>, dir: vec3<f32>) -> f32 {
    let z = textureLoad(scene_depth, vec2<i32>(pixel), 0).r;
    if z <= 0.0 {
        return 1e30;  // reverse-Z: nothing drawn (sky)
    }
    let size = vec2<f32>(textureDimensions(scene_depth));
    let ndc = vec2<f32>(pixel.x / size.x * 2.0 - 1.0, 1.0 - pixel.y / size.y * 2.0);
    let h = frame.inv_view_proj * vec4<f32>(ndc, z, 1.0);
    return dot(h.xyz / h.w - entry, dir);
}

// Traces tetrahedron `id` from `entry` along `dir` (unit) up to `limit`, at
// level `lod`; with `first_only`, stops at the first covered sample.
fn trace(id: u32, entry: vec3<f32>, dir: vec3<f32>, limit: f32, lod: f32, first_only: bool) -> Traced {
    let t = tetras[id];
    var out = Traced(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0);
    let b0 = max(barycentric(t, entry), vec4<f32>(0.0));
    let db = bary_rate(t, dir);
    var t_exit = limit;
    for (var i = 0u; i < 4u; i++) {
        if db[i] < 0.0 {
            t_exit = min(t_exit, -b0[i] / db[i]);
        }
    }
    let dims = shell.dims.xyz;
    let v0 = texture_at(t, b0) * dims;
    let dv = texture_at(t, db) * dims;   // voxels per metre along the ray (rate of an affine map)
    let speed = length(dv);
    if speed <= 0.0 || t_exit <= 0.0 {
        return out;
    }
    let step_dir = dv / speed;
    let s_exit = t_exit * speed;
    let scale = exp2(floor(lod + 0.5));  // voxel size of the level, in level-0 voxels
    let fine = 0.5 * scale;
    var s = 0.0;
    for (var i = 0u; i < shell.max_steps; i++) {
        if s > s_exit || out.alpha > 0.98 {
            break;
        }
        let v = v0 + step_dir * s;
        let uvw = v / dims;
        let d = textureSampleLevel(distance, volume_sampler, uvw, lod).r;
        if d > 1.5 * scale {
            // Sphere tracing: nothing of this level within d - one voxel.
            s += d - scale;
            continue;
        }
        let c = textureSampleLevel(volume, volume_sampler, uvw, lod);
        if c.a > shell.min_alpha {
            if out.alpha == 0.0 {
                out.first = v;
                out.w = uvw.z;
            }
            if first_only {
                out.alpha = c.a;
                return out;
            }
            // Coverage is opacity per level-0 voxel of path (Beer-Lambert with
            // the level's mean density, as prefiltered volumes do): over a
            // step of `fine` level-0 voxels, 1 - (1 - a)^fine. The volume
            // stores premultiplied colour, so filtering next to empty voxels
            // does not darken edges.
            let a = 1.0 - pow(max(1.0 - c.a, 0.0), fine);
            out.albedo += (1.0 - out.alpha) * a * (c.rgb / c.a);
            out.alpha += (1.0 - out.alpha) * a;
        }
        s += fine;
    }
    return out;
}

struct Fragment {
    dir: vec3<f32>,
    lod: f32,
    fade: f32,
}

fn fragment_ray(in: TetraOut) -> Fragment {
    let t = tetras[in.tetra];
    let ray = in.world - frame.camera.xyz;
    let dir = normalize(ray);
    let square = max(abs(ray.x), abs(ray.z));
    let fade = 1.0 - smoothstep(shell.fade_m.x, shell.fade_m.y, square);
    return Fragment(dir, footprint_lod(t, dir, length(ray)), fade);
}

// Step 1: the nearest layer behind the last one (`cull_depth`, 0 where the
// pixel is done) that holds something; depth test `greater` (reverse-Z)
// keeps the nearest.
@fragment
fn fs_layer(in: TetraOut) {
    let f = fragment_ray(in);
    let cull = textureLoad(cull_depth, vec2<i32>(in.clip.xy), 0).r;
    if in.clip.z >= cull || f.fade <= 0.0 {
        discard;
    }
    let limit = scene_limit(in.clip.xy, in.world, f.dir);
    if trace(in.tetra, in.world, f.dir, limit, f.lod, true).alpha <= 0.0 {
        discard;
    }
}

// World-space normal of the volume's coverage at level-0 voxel `v`, from its
// gradient mapped back through the tetrahedron's affine map.
fn volume_normal(id: u32, v: vec3<f32>, lod: f32, fallback: vec3<f32>) -> vec3<f32> {
    let t = tetras[id];
    let dims = shell.dims.xyz;
    let h = exp2(floor(lod + 0.5));
    let g = vec3<f32>(
        textureSampleLevel(volume, volume_sampler, (v + vec3<f32>(h, 0.0, 0.0)) / dims, lod).a - textureSampleLevel(volume, volume_sampler, (v - vec3<f32>(h, 0.0, 0.0)) / dims, lod).a,
        textureSampleLevel(volume, volume_sampler, (v + vec3<f32>(0.0, h, 0.0)) / dims, lod).a - textureSampleLevel(volume, volume_sampler, (v - vec3<f32>(0.0, h, 0.0)) / dims, lod).a,
        textureSampleLevel(volume, volume_sampler, (v + vec3<f32>(0.0, 0.0, h)) / dims, lod).a - textureSampleLevel(volume, volume_sampler, (v - vec3<f32>(0.0, 0.0, h)) / dims, lod).a,
    );
    // Chain rule: d(coverage)/d(world) = J^T g, J = d(voxel)/d(world).
    let grad0 = -(t.bary[0].xyz + t.bary[1].xyz + t.bary[2].xyz);
    let j0 = t.tex[0].xyz * dims;
    let j1 = t.tex[1].xyz * dims;
    let j2 = t.tex[2].xyz * dims;
    let j3 = t.tex[3].xyz * dims;
    let world = grad0 * dot(j0, g) + t.bary[0].xyz * dot(j1, g) + t.bary[1].xyz * dot(j2, g) + t.bary[2].xyz * dot(j3, g);
    let len = length(world);
    if len < 1e-6 {
        return fallback;
    }
    return -world / len;
}

// Direction of increasing w (the shell's up) in tetrahedron `t`.
fn shell_up(t: Tetra) -> vec3<f32> {
    let grad0 = -(t.bary[0].xyz + t.bary[1].xyz + t.bary[2].xyz);
    let up = grad0 * t.tex[0].z + t.bary[0].xyz * t.tex[1].z + t.bary[1].xyz * t.tex[2].z + t.bary[2].xyz * t.tex[3].z;
    return normalize(up);
}

// Step 3: shade the layer found in step 1 (depth test `equal`), front to back
// under what earlier passes drew (premultiplied; blend one-minus-dst-alpha, one).
@fragment
fn fs_shade(in: TetraOut) -> @location(0) vec4<f32> {
    let f = fragment_ray(in);
    let limit = scene_limit(in.clip.xy, in.world, f.dir);
    let traced = trace(in.tetra, in.world, f.dir, limit, f.lod, false);
    if traced.alpha <= 0.0 {
        return vec4<f32>(0.0);
    }
    let t = tetras[in.tetra];
    let up = shell_up(t);
    // Blend toward the shell's up: thin blades lit as if rounded.
    let n = normalize(mix(volume_normal(in.tetra, traced.first, f.lod, up), up, 0.35));
    let albedo = traced.albedo / traced.alpha;
    let l = frame.sun.xyz;
    let wrap = 0.4;
    let diffuse = max((dot(n, l) + wrap) / (1.0 + wrap), 0.0);
    let sun = frame.sun_color.rgb * frame.sun.w * sun_visibility(in.world, up) * diffuse;
    // Deep in a tuft the sky is hidden: a simple occlusion by height.
    let ao = mix(0.35, 1.0, clamp(traced.w, 0.0, 1.0));
    let radiance = albedo * (sun + env_irradiance(n) * ao);
    let alpha = traced.alpha * f.fade;
    return vec4<f32>(radiance * alpha, alpha);
}
