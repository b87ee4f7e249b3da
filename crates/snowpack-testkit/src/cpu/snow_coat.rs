//! CPU twin of `snow_coat.wgsl`.

use glam::{Vec2, Vec3};

use snowpack::low_level::deform::snow_word;
use snowpack::low_level::skin::coat::SnowCoatParams;

use super::window::storage_index;

fn lerp2(a: Vec2, b: Vec2, c: Vec2, d: Vec2, f: Vec2) -> Vec2 {
    let ab = a + (b - a) * f.x;
    let cd = c + (d - c) * f.x;
    ab + (cd - ab) * f.y
}

/// The window's data the coat reads: per storage texel the terrain (as the
/// CPU twins take it), the snow words and the fallen snow; the occlusion map
/// (row-major depths of the window's resolution) when objects are set.
pub struct CoatGroundData<'a> {
    /// Terrain height per storage texel.
    pub terrain: &'a [f32],
    /// Snow words per storage texel.
    pub snow: &'a [u32],
    /// Fallen snow per storage texel.
    pub fallen: &'a [f32],
    /// Occlusion depths, row-major, or `None` (the sky reaches everything).
    pub sky: Option<&'a [f32]>,
}

/// Persistent snow height and rest height at window-local `q`, or -1e30 outside.
fn height_at(p: &SnowCoatParams, g: &CoatGroundData<'_>, q: Vec2) -> Vec2 {
    let uv = q / p.texel_m - Vec2::splat(0.5);
    let cell = uv.floor();
    let f = uv - cell;
    let last = (p.resolution as i32 - 2) as f32;
    if cell.x < 0.0 || cell.y < 0.0 || cell.x > last || cell.y > last {
        return Vec2::splat(-1e30);
    }
    let (j, i) = (cell.x as u32, cell.y as u32);
    let h = |di: u32, dj: u32| {
        let s = storage_index(p.origin, p.resolution, i + di, j + dj);
        let t = g.terrain[s];
        let lying = if p.use_fallen != 0 { g.fallen[s] } else { 0.0 };
        let column = p.depth_m + lying;
        Vec2::new(snow_word::column_height(g.snow[s], t, column), t + column)
    };
    lerp2(h(0, 0), h(0, 1), h(1, 0), h(1, 1), f)
}

fn sky_reaches(p: &SnowCoatParams, g: &CoatGroundData<'_>, q0: Vec2, h: f32) -> f32 {
    let Some(sky) = g.sky.filter(|_| p.use_sky != 0) else { return 1.0 };
    p.sky.reaches(q0.to_array(), h, p.texel_m, p.resolution, sky)
}

/// The coat `snow_coat.wgsl` leaves on each vertex, from `coat` before the
/// frame, this frame's `positions` and `normals`, and last frame's `previous`.
#[must_use]
pub fn snow_coat(p: &SnowCoatParams, g: &CoatGroundData<'_>, positions: &[Vec3], previous: &[Vec3], normals: &[Vec3], coat: &[f32]) -> Vec<f32> {
    let ring = [
        Vec2::new(1.0, 0.0),
        Vec2::new(0.707_106_77, 0.707_106_77),
        Vec2::new(0.0, 1.0),
        Vec2::new(-0.707_106_77, 0.707_106_77),
        Vec2::new(-1.0, 0.0),
        Vec2::new(-0.707_106_77, -0.707_106_77),
        Vec2::new(0.0, -1.0),
        Vec2::new(0.707_106_77, -0.707_106_77),
    ];
    let dt = p.dt_s.max(0.0);
    positions
        .iter()
        .enumerate()
        .map(|(v, &pos)| {
            let n = normals[v];
            let q = Vec2::new(pos.x, pos.z) - Vec2::from(p.corner_m);
            let mut c = coat[v];
            let centre = height_at(p, g, q);
            let top = if pos.y < centre.y + p.wade_radius_m {
                ring.iter().fold(centre.x, |top, d| top.max(height_at(p, g, q + *d * p.wade_radius_m).x))
            } else {
                centre.x
            };
            let under = top - pos.y;
            if under > 0.0 {
                c = c.max((c + p.cling_per_s * under * dt).min(p.cap_m));
            }
            if p.fall_m > 0.0 && n.y > 0.0 {
                c = c.max((c + p.fall_m * n.y * sky_reaches(p, g, q, pos.y)).min(p.cap_m));
            }
            c = (c - p.melt_m_per_s * dt).max(0.0);
            if p.has_previous != 0 && dt > 0.0 {
                let moved = (pos - previous[v]).length();
                if moved <= p.teleport_m && moved > p.shake_speed_m_per_s * dt {
                    c *= (-p.shake_per_s * dt).exp();
                }
            }
            c
        })
        .collect()
}
