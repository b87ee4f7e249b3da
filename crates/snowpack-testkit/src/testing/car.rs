//! A car for the shared-snow tests and the bench: four treaded wheels (the
//! shapes `scenes/vehicle.toml`'s car presses) rolling along +x, as a CPU
//! snow window ([`super::CpuSnow::press_shapes`]) presses them.

use glam::Vec3;
use snowpack_share::replicate::press::ShapeSweep;
use snowpack_share::replicate::press::wheel::{Tread, TreadPattern};

/// The car's wheels at `at` (world x, z of its centre, m) with its wheels
/// rolled `roll_m`, swept from `then` (last frame's, if any): window-local
/// to a window whose first texel is `origin`, of `texel_m` texels.
#[must_use]
pub fn car_wheels(texel_m: f32, origin: [i64; 2], (at, roll_m): ([f64; 2], f32), then: Option<([f64; 2], f32)>) -> Vec<ShapeSweep> {
    let texel = f64::from(texel_m);
    let local = |p: [f64; 2], dx: f64, dz: f64| Vec3::new((p[0] + dx - origin[0] as f64 * texel) as f32, 0.75, (p[1] + dz - origin[1] as f64 * texel) as f32);
    let tread = Tread { pattern: TreadPattern::Blocks, spacing_m: 0.1, depth_m: 0.03, lug_fraction: 0.4 };
    [(1.3, -0.78), (1.3, 0.78), (-1.3, -0.78), (-1.3, 0.78)]
        .into_iter()
        .map(|(dx, dz)| ShapeSweep::Wheel {
            then: then.map(|(p, r)| (local(p, dx, dz), Vec3::Z, r)),
            now: (local(at, dx, dz), Vec3::Z, roll_m),
            radius: 0.33,
            half_width: 0.14,
            tread,
        })
        .collect()
}

/// Where the car is at time `t` (x, z in m) and how far its wheels have
/// rolled: it rolls along +x at 3 m/s from x = −9 m, between 1 s and 7 s.
#[must_use]
pub fn drive(t: f64) -> ([f64; 2], f32) {
    let d = 3.0 * (t.clamp(1.0, 7.0) - 1.0);
    ([-9.0 + d, 0.5], -(d as f32))
}
