//! The readback ring answers CPU queries of snow height and depth, a few
//! frames late, and agrees with a blocking read of the same frame.

use glam::{DVec2, Vec3};
use snowpack::testing;
use snowpack::{Deformer, SnowDeformation, SnowParams, TerrainSource};

#[test]
fn snapshot_queries_match_the_pressed_snow() {
    let Some(ctx) = testing::gpu() else { return };
    let params = SnowParams { extent_m: 8.0, resolution: 128, depth_m: 0.5, ..SnowParams::default() };
    let terrain = TerrainSource::Flat { height_m: 2.0 };
    let mut snow = SnowDeformation::new(ctx, params, terrain, DVec2::new(100.0, -40.0)).expect("window");
    // A sphere whose bottom is 0.25 m below the 2.5 m snow surface.
    let sphere = Deformer::Sphere { center: Vec3::new(101.0, 2.75, -39.5), radius: 0.5 };
    for _ in 0..6 {
        snow.step(ctx, &[sphere], 1.0 / 60.0).expect("frame");
    }
    snow.finish(ctx).expect("finish");
    let snap = snow.snapshot().expect("a snapshot has arrived");
    assert!(snap.frame >= 3, "snapshot of frame {} after 6 frames and a finish", snap.frame);
    let t = snow.terrain();
    // Under the sphere's centre: 0.25 m of snow left (bilinear between texel centres
    // near the bottom of the sphere, so within a few mm).
    let depth = snap.depth_at(t, 101.0, -39.5).expect("inside the window");
    assert!((depth - 0.25).abs() < 0.005, "depth under the sphere {depth}");
    let height = snap.height_at(101.0, -39.5).expect("inside");
    assert!((height - 2.25).abs() < 0.005, "height under the sphere {height}");
    // Away from it: untouched.
    assert!((snap.depth_at(t, 98.0, -42.0).expect("inside") - 0.5).abs() < 1e-6);
    // Outside the window there is no answer rather than a wrong one.
    assert!(snap.height_at(0.0, 0.0).is_none());

    // The snapshot holds exactly what a blocking read returns.
    let local = snow.read_snow(ctx).expect("read");
    let origin = snow.origin_texel().expect("placed");
    for (k, h) in local.iter().enumerate() {
        let (i, j) = ((k / 128) as i64, (k % 128) as i64);
        assert_eq!(snap.texel(origin[0] + j, origin[1] + i), Some(*h));
    }
}

#[test]
fn window_moves_keep_trails_in_world_space() {
    let Some(ctx) = testing::gpu() else { return };
    let params = SnowParams { extent_m: 16.0, resolution: 128, depth_m: 0.5, elevation: 0.0, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    let print = Deformer::Sphere { center: Vec3::new(1.0, 0.6, 1.0), radius: 0.4 };
    snow.step(ctx, &[print], 0.016).expect("frame");
    let full = snow.exposed_texels();
    assert_eq!(full, 128 * 128);
    // Slide 3 m in x and 1 m in z: only the new strips are rewritten.
    snow.set_center(DVec2::new(3.0, 1.0));
    snow.step(ctx, &[], 0.016).expect("frame");
    let texel = 16.0 / 128.0;
    let (dx, dz) = ((3.0 / texel) as u64, (1.0 / texel) as u64);
    assert_eq!(snow.exposed_texels() - full, 128 * 128 - (128 - dx) * (128 - dz));
    snow.finish(ctx).expect("finish");
    let snap = snow.snapshot().expect("snapshot");
    // The print is still at world (1, 1): 0.2 m deep at its centre.
    let h = snap.height_at(1.0, 1.0).expect("still inside the window");
    assert!((h - 0.2).abs() < 0.01, "print moved or vanished: {h}");
    assert!((snap.height_at(4.0, 4.0).expect("inside") - 0.5).abs() < 1e-6);
}
