//! The ground material draws the trench, and its prepass (which Bevy's shadow
//! maps are drawn with) is displaced too: a low sun across a pressed trench
//! puts its bottom in the shadow of its near wall. Undisplaced shadow
//! geometry would lie flat below the snow and shadow nothing; the trench's
//! flat bottom faces the sun like untouched snow, so only the displaced
//! shadow pass darkens it. Its fragment shader gives the pressed floor the
//! compacted look. And snowpack's own ground through `SnowGroundPass`.

mod common;

use std::sync::{Arc, Mutex};

use bevy::camera::RenderTarget;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::light::CascadeShadowConfigBuilder;
use bevy::prelude::*;
use bevy::render::render_resource::{TextureFormat, TextureUsages};
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy_snowpack::{SnowDeformer, SnowGroundExtension, SnowGroundMaterial, SnowGroundPass, SnowpackSettings};
use snowpack::{SnowParams, TerrainSource};

const SIZE: u32 = 256;

#[derive(Resource, Clone, Default)]
struct Captured(Arc<Mutex<Option<Image>>>);

/// Why the material's tests are ignored by a plain `cargo test`.
const LAVAPIPE_22: &str = "Mesa 22.3's lavapipe (Debian 12's) kills its queue thread (SIGSEGV) on any draw whose vertex position \
                           depends on the sampled snow; .ci/run runs these on lavapipe from Mesa 25.0.7 (bookworm-backports), \
                           run them with --ignored on any other adapter";

/// The ground material over a box's trench along x (1 m wide at the bottom,
/// pressed from 0.4 m of snow to `floor_m`), seen straight down from 6 m
/// with -z up the picture, lit by a sun at `sun_elevation_deg` shining along
/// +z (across the trench). Returns the luma of the trench's floor (the
/// middle rows) and of untouched snow 2.5 m away, and the picture as RGBA8.
/// (The depth technique shows a press with Hanák's remap: a floor at 0.1 m
/// is drawn at 4 mm, at 0.3 m at 0.29 m.)
fn render_trench(extension: SnowGroundExtension, floor_m: f32, sun_elevation_deg: f32) -> Option<(f32, f32, Vec<u8>)> {
    let mut app = common::headless_app(common::test_settings())?;
    let captured = Captured::default();
    app.insert_resource(captured.clone());

    let world = app.world_mut();
    let mut image = Image::new_target_texture(SIZE, SIZE, TextureFormat::Rgba8UnormSrgb, None);
    image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
    let target = world.resource_mut::<Assets<Image>>().add(image);
    let grid = Plane3d::default().mesh().size(8.0, 8.0).subdivisions(127);
    let mesh = world.resource_mut::<Assets<Mesh>>().add(grid);
    let snow = StandardMaterial { base_color: Color::WHITE, perceptual_roughness: 1.0, ..default() };
    let material = world.resource_mut::<Assets<SnowGroundMaterial>>().add(SnowGroundMaterial { base: snow, extension });
    world.spawn((Mesh3d(mesh), MeshMaterial3d(material)));
    world.spawn((SnowDeformer::Box { half_extents: Vec3::new(3.0, 0.5, 0.5) }, Transform::from_xyz(0.0, floor_m + 0.5, 0.0)));
    world.spawn((
        DirectionalLight { illuminance: 1_500.0, shadow_maps_enabled: true, ..default() },
        Transform::from_xyz(0.0, sun_elevation_deg.to_radians().tan(), -1.0).looking_at(Vec3::ZERO, Vec3::Y),
        CascadeShadowConfigBuilder { num_cascades: 1, maximum_distance: 20.0, ..default() }.build(),
    ));
    world.insert_resource(GlobalAmbientLight { brightness: 0.0, ..default() });
    world.spawn((
        Camera3d::default(),
        RenderTarget::Image(target.clone().into()),
        Tonemapping::None,
        Transform::from_xyz(0.0, 6.0, 0.0).looking_at(Vec3::ZERO, Vec3::NEG_Z),
    ));

    for _ in 0..10 {
        app.update();
    }
    let slot = captured.0.clone();
    app.world_mut().spawn(Screenshot::image(target)).observe(move |shot: On<ScreenshotCaptured>| {
        *slot.lock().unwrap() = Some(shot.image.clone());
    });
    for _ in 0..6 {
        app.update();
        if captured.0.lock().unwrap().is_some() {
            break;
        }
    }
    let image = captured.0.lock().unwrap().take().expect("screenshot captured");
    let rgba = image.data.expect("pixels");
    let width = image.texture_descriptor.size.width as usize;
    // Luma of a row band at image row `y`, columns across the middle half.
    let band = |y: usize| {
        let mut sum = 0.0;
        for row in y - 2..=y + 2 {
            for x in width / 4..3 * width / 4 {
                let p = &rgba[(row * width + x) * 4..][..3];
                sum += 0.3 * f32::from(p[0]) + 0.6 * f32::from(p[1]) + 0.1 * f32::from(p[2]);
            }
        }
        sum / (5.0 * (width / 2) as f32)
    };
    // z = 0 (the trench) is the middle row, z = +2.5 m (untouched, far from the trench) in the lower part.
    let (trench, untouched) = (band(SIZE as usize / 2), band(SIZE as usize * 7 / 8));
    Some((trench, untouched, rgba))
}

/// Saves a test's picture where `BEVY_SNOWPACK_DUMP` (a folder) says, to look at.
fn dump(name: &str, rgba: &[u8]) {
    if let Some(dir) = std::env::var_os("BEVY_SNOWPACK_DUMP") {
        let path = std::path::Path::new(&dir).join(name);
        image::RgbaImage::from_raw(SIZE, SIZE, rgba.to_vec()).expect("a full picture").save(&path).expect("saved");
    }
}

/// The material without its compacted look: trails shade only by their shape and shadows.
fn shape_only() -> SnowGroundExtension {
    let fresh = SnowGroundExtension::default();
    SnowGroundExtension { packed_albedo: Vec3::ONE, packed_roughness: 1.0, ground_show_through: 0.0, ..fresh }
}

/// A low sun (15 degrees) across a trench pressed to 0.1 m (drawn at 4 mm):
/// its near wall shades 1.5 m, more than its 1 m floor. The compacted look
/// is off, so only shadows darken the floor.
#[test]
#[ignore = "needs lavapipe from Mesa >= 23 or a hardware adapter (see LAVAPIPE_22)"]
fn ground_is_displaced_in_main_and_shadow_passes() {
    let _ = LAVAPIPE_22;
    let Some((trench, untouched, rgba)) = render_trench(shape_only(), 0.1, 15.0) else { return };
    dump("material_shadow.png", &rgba);
    assert!(untouched > 60.0, "untouched snow is lit (luma {untouched})");
    assert!(trench < 0.5 * untouched, "the trench bottom is in its wall's shadow: luma {trench} vs {untouched}");
}

/// The sun high (70 degrees) over a trench pressed to 0.3 m (a quarter of the
/// depth, drawn a quarter down), so its floor is lit like open snow: with
/// snowpack's material the pressed floor is darker (packed albedo) than with
/// the look off, and untouched snow is the same either way.
#[test]
#[ignore = "needs lavapipe from Mesa >= 23 or a hardware adapter (see LAVAPIPE_22)"]
fn the_material_gives_trails_the_compacted_look() {
    let Some((plain_trench, plain_open, plain)) = render_trench(shape_only(), 0.3, 70.0) else { return };
    dump("material_look_off.png", &plain);
    let Some((trench, open, rgba)) = render_trench(SnowGroundExtension::default(), 0.3, 70.0) else { return };
    dump("material_look.png", &rgba);
    println!("trench floor luma: look {trench:.1}, shape only {plain_trench:.1}; untouched: {open:.1}, {plain_open:.1}");
    assert!((open - plain_open).abs() < 1.0, "untouched snow changed with the look: {open} vs {plain_open}");
    assert!((plain_trench - plain_open).abs() < 0.1 * plain_open, "a lit floor without the look reads like open snow: {plain_trench} vs {plain_open}");
    assert!(trench < 0.93 * plain_trench, "the pressed floor is darker with the look: {trench} vs {plain_trench}");
}

/// snowpack's own ground drawn in the camera's main pass: the trench is there,
/// its compacted floor shaded apart from the untouched snow around it.
#[test]
fn snow_ground_pass_draws_the_trench() {
    let settings = SnowpackSettings {
        params: SnowParams { extent_m: 8.0, resolution: 128, depth_m: 0.4, refill_m_per_s: 0.0, ..SnowParams::default() },
        terrain: TerrainSource::Flat { height_m: 0.0 },
        center: Vec2::ZERO,
        fixed_dt_s: Some(1.0 / 60.0),
        store: None,
    };
    let Some(mut app) = common::headless_app(settings) else { return };
    let captured = Captured::default();
    let world = app.world_mut();
    let mut image = Image::new_target_texture(SIZE, SIZE, TextureFormat::Rgba8UnormSrgb, None);
    image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
    let target = world.resource_mut::<Assets<Image>>().add(image);
    world.spawn((SnowDeformer::Box { half_extents: Vec3::new(3.0, 0.5, 0.5) }, Transform::from_xyz(0.0, 0.6, 0.0)));
    world.spawn((
        Camera3d::default(),
        SnowGroundPass,
        RenderTarget::Image(target.clone().into()),
        Tonemapping::None,
        Transform::from_xyz(0.0, 4.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    for _ in 0..10 {
        app.update();
    }
    let slot = captured.0.clone();
    app.world_mut().spawn(Screenshot::image(target)).observe(move |shot: On<ScreenshotCaptured>| {
        *slot.lock().unwrap() = Some(shot.image.clone());
    });
    for _ in 0..6 {
        app.update();
        if captured.0.lock().unwrap().is_some() {
            break;
        }
    }
    let image = captured.0.lock().unwrap().take().expect("screenshot captured");
    let rgba = image.data.expect("pixels");
    dump("ground_pass.png", &rgba);
    let width = image.texture_descriptor.size.width as usize;
    // Mean luma of image row y over the middle half of the columns.
    let row = |y: usize| {
        let sum: f32 = (width / 4..3 * width / 4)
            .map(|x| {
                let p = &rgba[(y * width + x) * 4..][..3];
                0.3 * f32::from(p[0]) + 0.6 * f32::from(p[1]) + 0.1 * f32::from(p[2])
            })
            .sum();
        sum / (width / 2) as f32
    };
    // The camera looks at the trench (z = 0) from 4 m up and 4 m back: the
    // trench crosses the middle of the picture, untouched snow is nearer (below).
    let size = SIZE as usize;
    let untouched = row(size * 7 / 8);
    let (darkest_row, darkest) = (size / 4..3 * size / 4).map(|y| (y, row(y))).min_by(|a, b| a.1.total_cmp(&b.1)).expect("rows");
    assert!(untouched > 150.0, "untouched snow is bright: luma {untouched}");
    assert!(darkest < 0.7 * untouched, "the trench floor (row {darkest_row}) is shaded apart: luma {darkest} vs {untouched}");
    assert!((size * 3 / 8..size * 5 / 8).contains(&darkest_row), "the trench crosses the middle of the picture: row {darkest_row}");
}
