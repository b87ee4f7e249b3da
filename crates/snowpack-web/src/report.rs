//! What the page's test run reports about its own frame: where world points
//! land on it, how bright a patch around them is, and whether the frame is
//! blank. The page computes these on the frame it read back; `web/test.sh`
//! checks them again on the pixels it saved.

use glam::{Mat4, Vec2, Vec3};

/// The pixel (x right, y down) at which `world` appears in a `size` image
/// drawn with `view_proj`; `None` behind the camera or off the image.
#[must_use]
pub fn pixel_of(view_proj: Mat4, world: Vec3, size: (u32, u32)) -> Option<Vec2> {
    let clip = view_proj * world.extend(1.0);
    if clip.w <= 1e-6 {
        return None;
    }
    let ndc = clip.truncate() / clip.w;
    if ndc.x.abs() > 1.0 || ndc.y.abs() > 1.0 {
        return None;
    }
    Some(Vec2::new((ndc.x * 0.5 + 0.5) * size.0 as f32, (0.5 - ndc.y * 0.5) * size.1 as f32))
}

/// Rec. 709 luma of an 8-bit RGBA texel.
fn luma(p: &[u8]) -> f32 {
    0.2126 * f32::from(p[0]) + 0.7152 * f32::from(p[1]) + 0.0722 * f32::from(p[2])
}

/// Mean luma of the `(2 radius + 1)²` patch around `at` in a row-major RGBA
/// image of `size`; `None` when the patch leaves the image.
#[must_use]
pub fn patch_luma(rgba: &[u8], size: (u32, u32), at: Vec2, radius: u32) -> Option<f32> {
    let (cx, cy) = (at.x.floor() as i64, at.y.floor() as i64);
    let r = i64::from(radius);
    let (w, h) = (i64::from(size.0), i64::from(size.1));
    if cx - r < 0 || cy - r < 0 || cx + r >= w || cy + r >= h || rgba.len() < (w * h * 4) as usize {
        return None;
    }
    let mut sum = 0.0;
    for y in cy - r..=cy + r {
        for x in cx - r..=cx + r {
            let k = ((y * w + x) * 4) as usize;
            sum += luma(&rgba[k..k + 4]);
        }
    }
    Some(sum / ((2 * r + 1) * (2 * r + 1)) as f32)
}

/// Standard deviation of the luma over the whole image: a blank (cleared,
/// never drawn) frame has almost none.
#[must_use]
pub fn luma_spread(rgba: &[u8]) -> f32 {
    let n = (rgba.len() / 4).max(1) as f64;
    let (sum, sq) = rgba.chunks_exact(4).map(|p| f64::from(luma(p))).fold((0.0, 0.0), |(s, q), l| (s + l, q + l * l));
    let mean = sum / n;
    ((sq / n - mean * mean).max(0.0)).sqrt() as f32
}

/// Below this luma spread a frame counts as blank.
pub const BLANK_SPREAD: f32 = 2.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_centre_of_the_view_lands_in_the_middle_of_the_image() {
        // As snowpack's camera projects: reverse-Z with an infinite far plane.
        let camera = glam::camera::rh::proj::directx::perspective_infinite_reverse(60f32.to_radians(), 2.0, 0.1)
            * glam::camera::rh::view::look_at_mat4(Vec3::new(0.0, 5.0, -10.0), Vec3::ZERO, Vec3::Y);
        let p = pixel_of(camera, Vec3::ZERO, (200, 100)).expect("in view");
        assert!((p - Vec2::new(100.0, 50.0)).length() < 1e-3, "{p}");
        // Above the target is higher up the image (smaller y); behind the camera is nowhere.
        assert!(pixel_of(camera, Vec3::new(0.0, 1.0, 0.0), (200, 100)).expect("in view").y < 50.0);
        assert_eq!(pixel_of(camera, Vec3::new(0.0, 5.0, -20.0), (200, 100)), None);
    }

    #[test]
    fn patches_and_spread_tell_a_trail_from_snow_and_a_blank_frame_from_a_picture() {
        let (w, h) = (32u32, 16u32);
        let mut rgba = vec![230u8; (w * h * 4) as usize];
        for y in 4..9 {
            for x in 20..25 {
                let k = ((y * w + x) * 4) as usize;
                rgba[k..k + 3].copy_from_slice(&[120, 125, 140]);
            }
        }
        let snow = patch_luma(&rgba, (w, h), Vec2::new(5.5, 6.5), 2).expect("inside");
        let trail = patch_luma(&rgba, (w, h), Vec2::new(22.5, 6.5), 2).expect("inside");
        assert!((snow - 230.0).abs() < 1e-3 && trail < 130.0, "{snow} {trail}");
        assert_eq!(patch_luma(&rgba, (w, h), Vec2::new(0.5, 0.5), 2), None);
        assert!(luma_spread(&rgba) > BLANK_SPREAD);
        assert!(luma_spread(&vec![17u8; (w * h * 4) as usize]) < BLANK_SPREAD);
    }
}
