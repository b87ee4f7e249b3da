//! Switching technique at runtime keeps the trails, allocates a technique's
//! buffer once, on its first frame, and leaves no stale footprints behind.

use glam::{DVec2, Vec3};
use snowpack::low_level::SnowInspect;
use snowpack::{Deformer, SnowDeformation, SnowParams, Technique, TerrainSource};
use snowpack_testkit::testing;

#[test]
fn switching_keeps_trails_and_allocates_once() {
    let Some(ctx) = testing::gpu() else { return };
    let params = SnowParams { extent_m: 8.0, resolution: 128, depth_m: 0.5, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    // The window's resources; the resident tiles of the default trail keeper apart.
    let total = |s: &SnowDeformation| s.memory_bytes().iter().filter(|(n, _)| *n != "resident tiles").map(|(_, b)| b).sum::<u64>();
    let tiles = |s: &SnowDeformation| s.memory_bytes().iter().find(|(n, _)| *n == "resident tiles").map_or(0, |(_, b)| *b);
    let depth_tiles = tiles(&snow);
    let mut depth_memory = 0;
    let at = |x: f32| Deformer::Sphere { center: Vec3::new(x, 0.6, 0.0), radius: 0.4 };
    // Depth presses a print at x = -2, points one at x = 0, combined one at x = 2.
    for (technique, x) in [(Technique::Depth, -2.0), (Technique::Points, 0.0), (Technique::Combined, 2.0)] {
        snow.set_technique(technique);
        for _ in 0..3 {
            snow.step(ctx, &[at(x)], 1.0 / 60.0).expect("frame");
        }
        assert_eq!(snow.technique(), technique);
        if technique == Technique::Depth {
            // After its frames: the capture makes its output on the first frame that writes it.
            depth_memory = total(&snow);
        }
    }
    // Points allocated the footprint buffer (4 bytes a texel, less its 4-byte stand-in).
    let texels = 128 * 128;
    assert_eq!(total(&snow), depth_memory + 4 * texels - 4, "points allocated more than the footprints");
    // And the resident slots a footprint plane: two planes where there was one (snow).
    assert!(depth_tiles > 0, "trails are kept by default");
    assert!(tiles(&snow) > depth_tiles && tiles(&snow) < depth_tiles * 2 + 64 * 1024, "resident tiles {} after {depth_tiles}", tiles(&snow));
    // Decals: the sphere moves on and the height field must not change.
    snow.set_technique(Technique::Decals);
    let before = snow.read_snow(ctx).expect("read");
    for k in 0..10 {
        snow.step(ctx, &[at(-3.0 + k as f32 * 0.3)], 1.0 / 60.0).expect("frame");
    }
    let after = snow.read_snow(ctx).expect("read");
    assert_eq!(before, after, "decals changed the snow");
    assert!(!snow.decals().is_empty(), "the moving sphere left no decal");
    let layer = snow.read_decals(ctx).expect("decal layer");
    assert!(layer.iter().filter(|p| p[3] > 0).count() > 50, "decals not drawn into the layer");
    // All three prints are still there: 0.2 m deep at their centres.
    let r = 128;
    let texel = 8.0 / 128.0;
    let origin = snow.origin_m().expect("placed");
    for x in [-2.0, 0.0, 2.0] {
        let j = ((x - origin.x) / texel) as usize;
        let i = ((0.0 - origin.y) / texel) as usize;
        let h = after[i * r + j];
        assert!((h - 0.2).abs() < 0.01, "print at x = {x} is {h} m, want 0.2 m");
    }
    // Back to depth: nothing stale from the points (their stored footprints do
    // not lower the snow under the depth technique); decals allocated their
    // layer, and switching back frees and allocates nothing.
    let memory = snow.memory_bytes();
    assert_eq!(total(&snow), depth_memory + 8 * texels - 8);
    snow.set_technique(Technique::Depth);
    snow.step(ctx, &[], 1.0 / 60.0).expect("frame");
    assert_eq!(snow.read_snow(ctx).expect("read"), after);
    assert_eq!(snow.memory_bytes(), memory, "a switch back changed GPU memory");
}

/// A footprint's rim ends inside its range: beyond the rim's reach the
/// displayed surface is rest snow, with no ridge where the stamp square ends.
/// (Footprints whose height was clipped at the top of the quantisation range
/// once kept a rim out to the square's edge.)
#[test]
fn point_rims_end_before_the_footprint_range() {
    let Some(ctx) = testing::gpu() else { return };
    let (extent, res, depth) = (16.0f32, 256u32, 0.6f32);
    let params = SnowParams {
        extent_m: extent,
        resolution: res,
        depth_m: depth,
        technique: Technique::Points,
        range_texels: 128,
        elevation: 1.5,
        ..SnowParams::default()
    };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    let radius = 0.45;
    // Dragged along x at z = 0, its lowest point 0.1 m above the ground.
    for k in 0..=80 {
        let x = -5.0 + 10.0 * k as f32 / 80.0;
        snow.step(ctx, &[Deformer::Sphere { center: Vec3::new(x, 0.1 + radius, 0.0), radius }], 1.0 / 60.0).expect("frame");
    }
    let (shown, _) = snow.read_surface(ctx).expect("surface");
    let texel = extent / res as f32;
    let origin = snow.origin_m().expect("placed");
    // The rounded rim ends where h - foot = 4 (rest - foot): d = sqrt(8 r (rest - foot)) = 1.34 m.
    let reach = (8.0 * radius * (depth - 0.1)).sqrt();
    let j = ((0.0 - origin.x as f32) / texel) as usize;
    let mut peak = 0.0f32;
    for i in 0..res as usize {
        let z = origin.y as f32 + (i as f32 + 0.5) * texel;
        let h = shown[i * res as usize + j];
        if z.abs() > reach + 3.0 * texel {
            assert!((h - depth).abs() < 2e-3, "z = {z:.2}: displayed {h:.4} m beyond the rim's reach ({reach:.2} m), want rest {depth}");
        } else {
            peak = peak.max(h - depth);
        }
    }
    assert!(peak > 0.05, "no rim beside the trail (peak {peak:.3} m above rest)");
}
