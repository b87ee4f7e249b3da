//! The pressure–sinkage arithmetic of snow the game can feel: how far a
//! load sinks into the snow and what the snow costs a walker or a wheel
//! ([`crate::resistance`] has the sources). Plain functions below the
//! components that use them: the wheels ([`crate::deformers`]) and the
//! resistance.

/// Standard gravity (m/s²).
pub(crate) const GRAVITY: f32 = 9.81;

/// Sinkage (m) of `pressure_pa` into `depth_m` of untouched snow of
/// `hardness_kpa`: the library's `D p / (p + H)`.
#[must_use]
pub(crate) fn sinkage_m(pressure_pa: f32, depth_m: f32, hardness_kpa: f32) -> f32 {
    let (p, h) = (pressure_pa.max(0.0), hardness_kpa.max(1e-6) * 1000.0);
    depth_m.max(0.0) * p / (p + h)
}

/// Sinkage (m) of a rigid wheel (the library's `WheelLoad::sinkage_m`): its
/// load over the contact chord `2 √(2 r z − z²)` times its width is the
/// pressure, and the sinkage is where the snow holds it (bisection).
#[must_use]
pub(crate) fn wheel_sinkage_m(load_kg: f32, radius_m: f32, width_m: f32, depth_m: f32, hardness_kpa: f32) -> f32 {
    let depth = depth_m.max(0.0);
    if depth == 0.0 || load_kg <= 0.0 {
        return 0.0;
    }
    let r = radius_m.max(1e-6);
    let pressure = |z: f32| {
        let chord = if z >= r { 2.0 * r } else { 2.0 * (2.0 * r * z - z * z).max(0.0).sqrt() };
        load_kg * GRAVITY / (chord * width_m.max(1e-6)).max(1e-9)
    };
    let (mut lo, mut hi) = (0.0_f32, depth);
    for _ in 0..48 {
        let mid = 0.5 * (lo + hi);
        if mid < sinkage_m(pressure(mid), depth, hardness_kpa) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Richmond, Potter and Santee's terrain coefficient of snow at a sinkage
/// of `sinkage_m`, ramped from firm ground's 1 over the first 2 cm of snow
/// depth (their fit starts at packed snow's 1.26).
#[must_use]
pub(crate) fn terrain_coefficient(sinkage_m: f32, depth_m: f32) -> f32 {
    let z = 100.0 * sinkage_m.max(0.0);
    let snow = 0.0005 * z * z * z + 0.0001 * z * z + 0.1072 * z + 1.2604;
    1.0 + (snow - 1.0) * (depth_m / 0.02).clamp(0.0, 1.0)
}

/// Bekker's compaction resistance (N) of a wheel `width_m` wide sinking to
/// `sinkage_m` below the untouched snow of `depth_m`, where the snow is
/// already pressed `pressed_m`, with the library's `p(z) = H z / (D − z)`.
#[must_use]
pub(crate) fn compaction_resistance_n(width_m: f32, sinkage_m: f32, pressed_m: f32, depth_m: f32, hardness_kpa: f32) -> f32 {
    let (d, s) = (depth_m.max(0.0), pressed_m.max(0.0));
    let z = sinkage_m.min(d - 1e-6);
    if z <= s || d <= 0.0 {
        return 0.0;
    }
    let h = hardness_kpa.max(0.0) * 1000.0;
    width_m.max(0.0) * h * ((s - z) + d * ((d - s) / (d - z)).ln())
}
