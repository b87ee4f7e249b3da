//! `frame.png` until the renderer lands: a top-down lit view of the displayed
//! snow surface (Lambert sun plus sky ambient), with trails shown by their
//! shading and by the darker tint of compacted snow.

use glam::Vec3;

/// Shades the window-local surface (its normals; snow and terrain heights
/// give the compaction tint; decals, when given, their normal map and tint)
/// into an sRGB image of `width` x `height`.
#[must_use]
#[expect(clippy::too_many_arguments, reason = "one plain function until the renderer replaces it")]
pub fn render(
    normals: &[[f32; 3]],
    decals: Option<&[[u8; 4]]>,
    snow: &[f32],
    terrain: &[f32],
    depth_m: f32,
    resolution: u32,
    width: u32,
    height: u32,
) -> image::RgbImage {
    let r = resolution as usize;
    let sun = Vec3::new(-0.6, 0.55, 0.45).normalize();
    let fresh = Vec3::new(0.93, 0.95, 1.0);
    let packed = Vec3::new(0.72, 0.76, 0.84);
    let ground = Vec3::new(0.35, 0.3, 0.25);
    let sky = Vec3::new(0.45, 0.55, 0.75);
    image::RgbImage::from_fn(width, height, |px, py| {
        // Image row 0 is the window's far edge (+z up on screen).
        let j = ((px as f32 + 0.5) / width as f32 * r as f32) as usize;
        let i = r - 1 - ((py as f32 + 0.5) / height as f32 * r as f32) as usize;
        let k = i.min(r - 1) * r + j.min(r - 1);
        let mut n = Vec3::from(normals[k]);
        let fraction = ((snow[k] - terrain[k]) / depth_m).clamp(0.0, 1.0);
        let mut albedo = if fraction < 0.02 { ground } else { packed.lerp(fresh, fraction.powf(0.7)) };
        if let Some(layer) = decals {
            // Premultiplied normal x, z and tint over coverage.
            let [nx, nz, tint, a] = layer[k].map(|c| f32::from(c) / 255.0);
            if a > 0.0 {
                let dn = Vec3::new(nx / a * 2.0 - 1.0, 0.0, nz / a * 2.0 - 1.0);
                let dn = Vec3::new(dn.x, (1.0 - dn.x * dn.x - dn.z * dn.z).max(0.0).sqrt(), dn.z);
                n = n.lerp(dn, a).normalize();
                albedo *= 1.0 - a + a * (0.6 + 0.4 * tint / a);
            }
        }
        let lit = albedo * (n.dot(sun).max(0.0) * 0.85) + albedo * sky * (0.35 + 0.25 * n.y);
        // Simple filmic-ish curve, then sRGB.
        let mapped = lit / (lit + Vec3::splat(0.6)) * 1.35;
        let to8 = |c: f32| (c.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0 + 0.5) as u8;
        image::Rgb([to8(mapped.x), to8(mapped.y), to8(mapped.z)])
    })
}
