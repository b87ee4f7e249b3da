//! Rendered frames against reference images, compared with SSIM (a
//! perceptual metric) and a per-test threshold. On failure the test writes
//! `NAME-actual.png` and `NAME-difference.png` next to `NAME.png` in
//! `tests/reference/`. `SNOWPACK_BLESS=1` rewrites the references from the
//! current renderer (look at them before committing).
//!
//! The inputs are fixed (no random seeds): a reference image pins one scene.
//! Thresholds leave room for what differs between adapters (rasterisation
//! rules, texture filtering, transcendental precision) and nothing more: each
//! test also checks that an image *without* the feature it is about (the
//! trail, the spheres, the rim shadows) scores below its threshold, so the
//! threshold cannot pass a frame that lost what the test looks for.

use std::path::PathBuf;

use glam::{DVec2, Vec3};
use snowpack::low_level::SnowInspect;
use snowpack::low_level::render::params::sun_from_angles;
use snowpack::{Camera, Deformer, EnvironmentMap, GpuContext, NoiseTerrain, RenderParams, Renderer, SnowDeformation, SnowParams, Technique, TerrainSource};
use snowpack::{IMAGE_FORMAT, LightParams};
use snowpack_testkit::testing::{self, Rng};

/// Frame size of every reference (small: the suite runs on a software rasteriser).
const SIZE: (u32, u32) = (320, 192);

const SKY_HDR: &[u8] = include_bytes!("../../../assets/spiaggia_di_mondello_1k.hdr");

fn reference_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests").join("reference")
}

fn save_png(path: &std::path::Path, rgba: &[u8]) {
    image::save_buffer(path, rgba, SIZE.0, SIZE.1, image::ExtendedColorType::Rgba8).unwrap_or_else(|e| panic!("writing {}: {e}", path.display()));
}

/// Compares `image` with the reference `name` at `min_ssim`; returns the score.
fn check_reference(name: &str, image: &[u8], min_ssim: f64) -> f64 {
    let dir = reference_dir();
    let path = dir.join(format!("{name}.png"));
    if std::env::var("SNOWPACK_BLESS").is_ok_and(|v| v == "1") {
        std::fs::create_dir_all(&dir).expect("reference folder");
        save_png(&path, image);
        eprintln!("blessed {}", path.display());
        return 1.0;
    }
    let reference =
        image::open(&path).unwrap_or_else(|e| panic!("reference {} cannot be read ({e}); run with SNOWPACK_BLESS=1 to make it", path.display())).to_rgba8();
    assert_eq!(reference.dimensions(), SIZE, "reference {} has another size", path.display());
    let score = testing::ssim(reference.as_raw(), image, SIZE.0, SIZE.1);
    eprintln!("{name}: SSIM {score:.4} (threshold {min_ssim})");
    if score < min_ssim {
        let actual = dir.join(format!("{name}-actual.png"));
        let difference = dir.join(format!("{name}-difference.png"));
        save_png(&actual, image);
        save_png(&difference, &testing::difference_image(reference.as_raw(), image));
        panic!("{name}: SSIM {score:.4} is below {min_ssim}; see {} and {}", actual.display(), difference.display());
    }
    score
}

fn sky() -> EnvironmentMap {
    EnvironmentMap::from_hdr(SKY_HDR).expect("the bundled sky decodes")
}

fn render(ctx: &GpuContext, snow: &SnowDeformation, actors: &[Deformer], params: RenderParams, camera: &Camera) -> Vec<u8> {
    let mut renderer = Renderer::new(ctx, snow, &sky(), RenderParams { shadow_map_size: 1024, ..params }, IMAGE_FORMAT).expect("renderer");
    renderer.render_image(ctx, snow, actors, camera, SIZE).expect("frame")
}

fn window(ctx: &GpuContext, terrain: TerrainSource, technique: Technique) -> SnowDeformation {
    let params = SnowParams { extent_m: 16.0, resolution: 256, depth_m: 0.4, elevation: 1.5, technique, ..SnowParams::default() };
    SnowDeformation::new(ctx, params, terrain, DVec2::ZERO).expect("window")
}

/// A sphere dragged along a curve across flat snow, 25 cm into its 40 cm.
fn drag_trail(ctx: &GpuContext, snow: &mut SnowDeformation) -> Vec<Deformer> {
    let mut actors = Vec::new();
    for k in 0..=60 {
        let t = k as f32 / 60.0;
        let x = -6.0 + 12.0 * t;
        let z = 1.5 * (t * std::f32::consts::PI * 1.5).sin();
        actors = vec![Deformer::Sphere { center: Vec3::new(x, 0.55, z), radius: 0.4 }];
        snow.step(ctx, &actors, 1.0 / 30.0).expect("frame");
    }
    snow.finish(ctx).expect("finish");
    actors
}

#[test]
fn flat_snow_with_a_trail() {
    let Some(ctx) = testing::gpu() else { return };
    // Sun from the side of the trail: one wall lit, the other in shade.
    let light = LightParams { sun_direction: Some(sun_from_angles(30.0, 290.0)), ..LightParams::default() };
    let params = RenderParams { light, ..RenderParams::default() };
    let camera = Camera { position: Vec3::new(-1.0, 3.5, -6.5), target: Vec3::new(0.5, 0.0, 0.5), fov_deg: 55.0 };
    let threshold = 0.97;

    let mut snow = window(ctx, TerrainSource::Flat { height_m: 0.0 }, Technique::Depth);
    let untouched = render(ctx, &snow, &[], params, &camera);
    let actors = drag_trail(ctx, &mut snow);
    let image = render(ctx, &snow, &actors, params, &camera);
    check_reference("flat-trail", &image, threshold);
    // Without the trail and the sphere the frame must fail the same test.
    let blank = testing::ssim(&image, &untouched, SIZE.0, SIZE.1);
    eprintln!("flat-trail without the trail: SSIM {blank:.4}");
    assert!(blank < threshold, "a frame without the trail scores {blank:.4}: the threshold proves nothing");
}

#[test]
fn noise_terrain_with_many_spheres() {
    let Some(ctx) = testing::gpu() else { return };
    let noise = NoiseTerrain { seed: 11, base_m: 0.0, amplitude_m: 1.5, wavelength_m: 10.0 };
    let terrain = TerrainSource::Noise(noise);
    let mut snow = window(ctx, terrain.clone(), Technique::Depth);
    // 40 spheres from a fixed seed, each resting a third of its radius into the snow.
    let mut rng = Rng::new(40);
    let actors: Vec<Deformer> = (0..40)
        .map(|_| {
            let (x, z, r) = (rng.range(-7.0, 7.0), rng.range(-7.0, 7.0), rng.range(0.2, 0.5));
            Deformer::Sphere { center: Vec3::new(x, terrain.height_at(x, z) + 0.4 + r * 0.4, z), radius: r }
        })
        .collect();
    for _ in 0..4 {
        snow.step(ctx, &actors, 1.0 / 30.0).expect("frame");
    }
    snow.finish(ctx).expect("finish");
    let params = RenderParams { light: LightParams { sun_direction: Some(sun_from_angles(40.0, 120.0)), ..LightParams::default() }, ..RenderParams::default() };
    let camera = Camera { position: Vec3::new(0.0, 9.0, -13.0), target: Vec3::new(0.0, 0.0, 1.0), fov_deg: 60.0 };
    let threshold = 0.95;
    let image = render(ctx, &snow, &actors, params, &camera);
    check_reference("noise-spheres", &image, threshold);
    let bare = render(ctx, &window(ctx, terrain, Technique::Depth), &[], params, &camera);
    let score = testing::ssim(&image, &bare, SIZE.0, SIZE.1);
    eprintln!("noise-spheres without the spheres: SSIM {score:.4}");
    assert!(score < threshold, "a frame without the spheres scores {score:.4}: the threshold proves nothing");
}

#[test]
fn low_sun_shows_rim_shadows() {
    let Some(ctx) = testing::gpu() else { return };
    // Sun 7 degrees up, across the trail: rims throw long shadows over the snow beside them.
    let low = RenderParams { light: LightParams { sun_direction: Some(sun_from_angles(7.0, 0.0)), ..LightParams::default() }, ..RenderParams::default() };
    let camera = Camera { position: Vec3::new(1.0, 3.0, -5.0), target: Vec3::new(0.0, 0.0, 0.5), fov_deg: 55.0 };
    let threshold = 0.93;
    // Combined: the points raise real rims from their stored foot heights.
    let mut snow = window(ctx, TerrainSource::Flat { height_m: 0.0 }, Technique::Combined);
    drag_trail(ctx, &mut snow);
    // The sphere has left; only its trail and rims remain in view.
    let image = render(ctx, &snow, &[], low, &camera);
    check_reference("low-sun-rims", &image, threshold);
    // The same trail under a high sun loses the long shadows and must score lower.
    let high = RenderParams { light: LightParams { sun_direction: Some(sun_from_angles(70.0, 0.0)), ..LightParams::default() }, ..low };
    let score = testing::ssim(&image, &render(ctx, &snow, &[], high, &camera), SIZE.0, SIZE.1);
    eprintln!("low-sun-rims under a high sun: SSIM {score:.4}");
    assert!(score < threshold, "the trail under a high sun scores {score:.4}: the threshold proves nothing");
}
