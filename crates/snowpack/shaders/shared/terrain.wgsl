// Terrain height at a world position; the CPU twin is `src/terrain.rs`.
// Same operations in the same order as the Rust code, so both agree to rounding.
// The including shader declares `heightmap: array<f32>` (storage pointers
// cannot be passed to functions without an extension).

struct TerrainParams {
    kind: u32,          // 0 flat, 1 noise, 2 heightmap
    seed: u32,
    base_m: f32,        // flat height, or noise base
    amplitude_m: f32,
    per_wavelength: f32, // 1 / wavelength (1/m): a multiply rounds alike everywhere
    hm_width: u32,
    hm_height: u32,
    _pad: u32,
    hm_center_m: vec2<f32>,
    hm_per_size_m: vec2<f32>, // 1 / the covered size (1/m): multiplied, as on the CPU
}

const NOISE_OCTAVES: u32 = 4u;
// 1 / (1 + 1/2 + 1/4 + 1/8): the fractal sum is normalised by a multiply.
const NOISE_NORM: f32 = 0.53333336;

// The same operations in the same order as the Rust twin
// (`snowpack_share::replicate::press::ground`), with no division: a relay
// that presses over these hills finds the ground from the world's identity.
// An explicit `fma` is not one everywhere (lavapipe splits it into a
// multiply and an add), so there is none.

fn lattice_hash(ix: i32, iz: i32, seed: u32) -> u32 {
    var h = (bitcast<u32>(ix) * 0x8da6b343u) ^ (bitcast<u32>(iz) * 0xd8163841u) ^ (seed * 0xcb1ab31fu);
    h = (h ^ (h >> 16u)) * 0x7feb352du;
    h = (h ^ (h >> 15u)) * 0x846ca68bu;
    return h ^ (h >> 16u);
}

fn lattice_value(ix: i32, iz: i32, seed: u32) -> f32 {
    return f32(lattice_hash(ix, iz, seed) >> 8u) * (2.0 / 16777216.0) - 1.0;
}

fn noise_fade(t: f32) -> f32 {
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
}

fn value_noise(x: f32, z: f32, seed: u32) -> f32 {
    let fx = floor(x);
    let fz = floor(z);
    let ix = i32(fx);
    let iz = i32(fz);
    let tx = noise_fade(x - fx);
    let tz = noise_fade(z - fz);
    let a = lattice_value(ix, iz, seed);
    let b = lattice_value(ix + 1, iz, seed);
    let c = lattice_value(ix, iz + 1, seed);
    let d = lattice_value(ix + 1, iz + 1, seed);
    let ab = a + (b - a) * tx;
    let cd = c + (d - c) * tx;
    return ab + (cd - ab) * tz;
}

fn fbm(x: f32, z: f32, seed: u32) -> f32 {
    var sum = 0.0;
    var amp = 1.0;
    var freq = 1.0;
    for (var octave = 0u; octave < NOISE_OCTAVES; octave++) {
        sum += amp * value_noise(x * freq, z * freq, seed + octave);
        amp *= 0.5;
        freq *= 2.0;
    }
    return sum * NOISE_NORM;
}

// The twin is `HeightGrid::height_at` (snowpack_share::replicate::press::ground),
// with no division, so a relay that holds the heightmap presses over the
// same ground.
fn heightmap_at(t: TerrainParams, x: f32, z: f32) -> f32 {
    let w = i32(t.hm_width);
    let h = i32(t.hm_height);
    var u = ((x - t.hm_center_m.x) * t.hm_per_size_m.x + 0.5) * f32(t.hm_width) - 0.5;
    var v = ((z - t.hm_center_m.y) * t.hm_per_size_m.y + 0.5) * f32(t.hm_height) - 0.5;
    u = clamp(u, 0.0, f32(w - 1));
    v = clamp(v, 0.0, f32(h - 1));
    let u0 = floor(u);
    let v0 = floor(v);
    let fu = u - u0;
    let fv = v - v0;
    let i0 = i32(v0);
    let j0 = i32(u0);
    let i1 = min(i0 + 1, h - 1);
    let j1 = min(j0 + 1, w - 1);
    let a = heightmap[i0 * w + j0];
    let b = heightmap[i0 * w + j1];
    let c = heightmap[i1 * w + j0];
    let d = heightmap[i1 * w + j1];
    let ab = a + (b - a) * fu;
    let cd = c + (d - c) * fu;
    return ab + (cd - ab) * fv;
}

fn terrain_height(t: TerrainParams, x: f32, z: f32) -> f32 {
    return terrain_height_of_kind(t.kind, t, x, z);
}

// `terrain_height` for a kind given apart from `t` (a pipeline's constant:
// shared/terrain_kind.wgsl).
fn terrain_height_of_kind(kind: u32, t: TerrainParams, x: f32, z: f32) -> f32 {
    switch kind {
        // 3: noise whose value at each window texel the window also stores
        // (shared/terrain_kind.wgsl, `window_ground`); elsewhere evaluated.
        case 1u, 3u: {
            return t.base_m + t.amplitude_m * fbm(x * t.per_wavelength, z * t.per_wavelength, t.seed);
        }
        case 2u: {
            return heightmap_at(t, x, z);
        }
        default: {
            return t.base_m;
        }
    }
}
