//! Snow on the game's own ground: a heightmap image becomes the snow's
//! terrain (`SnowTerrainAsset`), and a game mesh over the same heights drawn
//! with `SnowCoverMaterial` is raised by the snow: untouched, the displaced
//! heights are the heightmap plus the snow's depth; in a ball's trail down
//! a slope they are the heightmap plus what the trail left. A spawned
//! scene's meshes become the terrain too; bad assets are named errors. And
//! the `own_terrain` example under Xvfb: its trails show on its slopes.

mod common;

use std::process::Command;

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use bevy_snowpack::{
    SnowCoverExtension, SnowCoverMaterial, SnowDeformer, SnowQuery, SnowTerrainAsset, SnowTerrainStatus, SnowpackSettings, TerrainAssetError,
    heightmap_from_image, snow_cover_lift, triangles_from_mesh,
};
use common::xvfb::Xvfb;
use common::{example, patch_luma};
use snowpack::TerrainSource;
use snowpack::low_level::SnowInspect;

/// The test's landscape: 8 m square, 65 pixels a side, 3 m for a value of 1.
const SIZE_M: f32 = 8.0;
const PIXELS: u32 = 65;
const SCALE_M: f32 = 3.0;

/// A slope rising 0.3 m a metre along x, with a wave across it: 0.2 to 2.7 m.
fn landscape(x: f32, z: f32) -> f32 {
    1.4 + 0.3 * x + 0.1 * (z * 0.8).sin()
}

/// The landscape as a 16-bit heightmap image.
fn heightmap() -> Image {
    let mut data = Vec::new();
    for row in 0..PIXELS {
        for col in 0..PIXELS {
            // Pixel centres: the heightmap covers SIZE_M and is sampled between them.
            let px = SIZE_M / PIXELS as f32;
            let (x, z) = ((col as f32 + 0.5) * px - 0.5 * SIZE_M, (row as f32 + 0.5) * px - 0.5 * SIZE_M);
            let v = (landscape(x, z) / SCALE_M * 65535.0).round() as u16;
            data.extend_from_slice(&v.to_le_bytes());
        }
    }
    Image::new(
        Extent3d { width: PIXELS, height: PIXELS, depth_or_array_layers: 1 },
        TextureDimension::D2,
        data,
        TextureFormat::R16Unorm,
        RenderAssetUsages::MAIN_WORLD,
    )
}

/// The game's mesh over `ground`: a grid of `cells` squares a side, its vertices on the heights.
fn terrain_mesh(ground: &TerrainSource, cells: u32) -> Mesh {
    let n = cells + 1;
    let step = SIZE_M / cells as f32;
    let mut positions = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (x, z) = (j as f32 * step - 0.5 * SIZE_M, i as f32 * step - 0.5 * SIZE_M);
            positions.push([x, ground.height_at(x, z), z]);
        }
    }
    let mut indices = Vec::new();
    for i in 0..cells {
        for j in 0..cells {
            let k = i * n + j;
            indices.extend_from_slice(&[k, k + n, k + 1, k + 1, k + n, k + n + 1]);
        }
    }
    let normals = vec![[0.0, 1.0, 0.0]; positions.len()];
    Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
        .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, normals)
        .with_inserted_indices(Indices::U32(indices))
}

#[test]
fn displaced_heights_follow_the_terrain_plus_the_snow() {
    let Some(mut app) = common::headless_app(common::test_settings()) else { return };
    let image = heightmap();
    let ground = TerrainSource::Heightmap(heightmap_from_image(&image, "test", Vec2::ZERO, Vec2::splat(SIZE_M), SCALE_M, 0.0).expect("a good heightmap"));
    let world = app.world_mut();
    let handle = world.resource_mut::<Assets<Image>>().add(image);
    world.insert_resource(SnowTerrainAsset::heightmap(handle, Vec2::splat(SIZE_M), SCALE_M));
    let mesh = terrain_mesh(&ground, 64);
    let vertices: Vec<[f32; 3]> = mesh.attribute(Mesh::ATTRIBUTE_POSITION).and_then(|p| p.as_float3()).expect("positions").to_vec();
    let mesh = world.resource_mut::<Assets<Mesh>>().add(mesh);
    let material = world
        .resource_mut::<Assets<SnowCoverMaterial>>()
        .add(SnowCoverMaterial { base: StandardMaterial::default(), extension: SnowCoverExtension::default() });
    world.spawn((Mesh3d(mesh), MeshMaterial3d(material)));
    // A ball of 0.5 m rolled up the slope along z = 0.5 from x = -2.5 to 2.5, its bottom 0.15 m above the ground.
    let ball = world.spawn((SnowDeformer::Sphere { radius: 0.5 }, Transform::default())).id();
    for k in 0..=50 {
        let x = -2.5 + 0.1 * k as f32;
        app.world_mut().entity_mut(ball).insert(Transform::from_xyz(x, ground.height_at(x, 0.5) + 0.65, 0.5));
        app.update();
    }
    app.world_mut().despawn(ball);
    for _ in 0..3 {
        app.update();
    }
    assert_eq!(*app.world().resource::<SnowTerrainStatus>(), SnowTerrainStatus::Applied);
    assert_eq!(app.world().resource::<SnowpackSettings>().terrain, ground, "the snow's terrain is not the heightmap image");

    let state = common::render_state(&app);
    let snow = state.deformation();
    let (shown, _) = snow.read_surface(state.context()).expect("the displayed snow");
    let terrain = snow.read_terrain(state.context()).expect("the terrain under it");
    let (n, texel) = (snow.params().resolution, snow.params().texel_m());
    let corner = snow.origin_m().expect("the window is placed");
    let corner = Vec2::new(corner.x as f32, corner.y as f32);
    // The snow lies on the heightmap: the terrain at every texel centre is the image's.
    for (k, g) in terrain.iter().enumerate() {
        let (i, j) = (k as u32 / n, k as u32 % n);
        let (x, z) = (corner.x + (j as f32 + 0.5) * texel, corner.y + (i as f32 + 0.5) * texel);
        assert!((g - ground.height_at(x, z)).abs() < 1e-4, "terrain {g} m at ({x}, {z}), the heightmap says {} m", ground.height_at(x, z));
    }
    let above: Vec<f32> = shown.iter().zip(&terrain).map(|(s, g)| s - g).collect();
    let rest = 0.4;
    // Untouched snow is shown at Hanák's remap of full depth (docs/deformation.md, the display pass):
    // depth * (1 + elevation * (f(1) - 1)), f(1) = -3.4766 + 6.508 - 2.231 + 0.215 (6.2 mm over 0.4 m).
    let elevation = snow.params().elevation;
    let shown_rest = rest * (1.0 + elevation * ((-3.4766 + 6.508 - 2.231 + 0.215) - 1.0));
    let (mut open, mut trail) = (0, Vec::new());
    for v in &vertices {
        let (x, y, z) = (v[0], v[1], v[2]);
        // Inside the window, off its outermost texels (the display's blur is clamped at the window's edges).
        if x.abs() > 3.7 || z.abs() > 3.7 {
            continue;
        }
        let displaced = y + snow_cover_lift(&above, n, corner, texel, rest, Vec2::new(x, z));
        let expected_open = ground.height_at(x, z) + shown_rest;
        if (z - 0.5).abs() > 1.5 {
            // Far from the ball: the heightmap plus the snow's (shown) depth.
            assert!((displaced - expected_open).abs() < 1e-3, "untouched vertex ({x}, {z}) displaced to {displaced} m, want {expected_open} m");
            open += 1;
        } else if (z - 0.5).abs() < 0.1 && x.abs() < 2.0 {
            // In the trail: the heightmap plus what the ball left (its bottom 0.15 m up, the snow's shown surface there).
            let j = ((x - corner.x) / texel - 0.5).round() as usize;
            let i = ((z - corner.y) / texel - 0.5).round() as usize;
            let left = above[i * n as usize + j];
            assert!(displaced < expected_open - 0.1, "trail vertex ({x}, {z}) displaced to {displaced} m: not pressed (open snow would be {expected_open} m)");
            assert!(
                (displaced - (ground.height_at(x, z) + left)).abs() < 0.02,
                "trail vertex ({x}, {z}) at {displaced} m, the snow left {left} m over the ground"
            );
            trail.push((x, displaced));
        }
    }
    assert!(open > 500, "only {open} untouched vertices checked");
    assert!(trail.len() >= 25, "only {} trail vertices checked", trail.len());
    // The trail climbs the slope: its displaced heights rise along x as the ground does.
    let (lo, hi) = trail.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), (_, h)| (lo.min(*h), hi.max(*h)));
    assert!(hi - lo > 0.8, "the trail's displaced heights span {lo}..{hi} m: not on a slope");
}

#[test]
fn a_spawned_scenes_meshes_become_the_terrain() {
    let Some(mut app) = common::headless_app(common::test_settings()) else { return };
    let world = app.world_mut();
    // A scene's root with a plateau 1 m high and 4 m wide under a child, placed 0.5 m up.
    let plateau = world.resource_mut::<Assets<Mesh>>().add(Cuboid::new(4.0, 1.0, 4.0));
    let root = world.spawn(Transform::from_xyz(0.0, 0.5, 0.0)).with_child((Mesh3d(plateau), Transform::from_xyz(0.0, 0.0, 0.0))).id();
    world.insert_resource(SnowTerrainAsset::scene(root));
    for _ in 0..4 {
        app.update();
    }
    assert_eq!(*app.world().resource::<SnowTerrainStatus>(), SnowTerrainStatus::Applied);
    let ticket = app.world_mut().resource_mut::<SnowQuery>().ask(&[Vec2::new(0.5, 0.5), Vec2::new(3.0, 3.0)]);
    let answers = (0..8)
        .find_map(|_| {
            app.update();
            app.world_mut().resource_mut::<SnowQuery>().take(ticket)
        })
        .expect("answered within 8 frames");
    let (top, beside) = (answers.samples[0].expect("in the window"), answers.samples[1].expect("in the window"));
    // The plateau's top at 1 m; beside it the grid's floor, the mesh's lowest height (its bottom at 0).
    assert!((top.terrain_m - 1.0).abs() < 1e-3, "the terrain on the plateau is {} m, want 1 m", top.terrain_m);
    assert!(beside.terrain_m.abs() < 1e-3, "the terrain beside the plateau is {} m, want 0 m", beside.terrain_m);
    assert!((top.height_m - 1.4).abs() < 1e-3, "the snow on the plateau is at {} m, want 1.4 m", top.height_m);
}

#[test]
fn bad_terrain_assets_are_named_errors() {
    let image = |format: TextureFormat, bytes: usize| {
        Image::new(Extent3d { width: 4, height: 4, depth_or_array_layers: 1 }, TextureDimension::D2, vec![0; bytes], format, RenderAssetUsages::MAIN_WORLD)
    };
    let err = heightmap_from_image(&image(TextureFormat::Rgba8Unorm, 64), "hills.png", Vec2::ZERO, Vec2::ONE, 1.0, 0.0).expect_err("RGBA is not a heightmap");
    assert!(matches!(err, TerrainAssetError::UnsupportedFormat { .. }), "{err}");
    assert!(err.to_string().contains("hills.png") && err.to_string().contains("Rgba8Unorm"), "{err}");
    let mut short = image(TextureFormat::R16Unorm, 32);
    short.data = Some(vec![0; 30]);
    let err = heightmap_from_image(&short, "short.png", Vec2::ZERO, Vec2::ONE, 1.0, 0.0).expect_err("too few bytes");
    assert!(err.to_string().contains("short.png") && err.to_string().contains("30 bytes"), "{err}");
    let err = heightmap_from_image(&image(TextureFormat::R32Float, 64), "flat.exr", Vec2::ZERO, Vec2::ZERO, 1.0, 0.0).expect_err("no size");
    assert!(matches!(err, TerrainAssetError::Terrain { .. }) && err.to_string().contains("flat.exr"), "{err}");
    let r8 = heightmap_from_image(&image(TextureFormat::R8Unorm, 16), "r8.png", Vec2::ZERO, Vec2::ONE, 2.0, 0.5).expect("R8 is a heightmap");
    assert_eq!(TerrainSource::Heightmap(r8).height_at(0.0, 0.0), 0.5);

    let lines = Mesh::new(PrimitiveTopology::LineList, RenderAssetUsages::default()).with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3]; 2]);
    let err = triangles_from_mesh(&lines, "fence.glb#Mesh0", &GlobalTransform::IDENTITY).expect_err("lines are no terrain");
    assert!(matches!(err, TerrainAssetError::BadMesh { .. }) && err.to_string().contains("fence.glb#Mesh0"), "{err}");
    let quad = Mesh::from(Plane3d::default().mesh().size(2.0, 2.0));
    let triangles = triangles_from_mesh(&quad, "quad", &GlobalTransform::from_xyz(0.0, 3.0, 0.0)).expect("a plane is a terrain");
    assert_eq!(triangles.len(), 2);
    assert!(triangles.iter().flatten().all(|p| p[1] == 3.0), "the transform places the triangles: {triangles:?}");
}

#[test]
fn a_bad_terrain_image_in_the_app_is_reported_not_a_panic() {
    let Some(mut app) = common::headless_app(common::test_settings()) else { return };
    let world = app.world_mut();
    let rgba = Image::new(
        Extent3d { width: 2, height: 2, depth_or_array_layers: 1 },
        TextureDimension::D2,
        vec![0; 16],
        TextureFormat::Rgba8Unorm,
        RenderAssetUsages::MAIN_WORLD,
    );
    let handle = world.resource_mut::<Assets<Image>>().add(rgba);
    world.insert_resource(SnowTerrainAsset::heightmap(handle, Vec2::ONE, 1.0));
    for _ in 0..3 {
        app.update();
    }
    let status = app.world().resource::<SnowTerrainStatus>().clone();
    assert!(matches!(&status, SnowTerrainStatus::Failed(why) if why.contains("Rgba8Unorm")), "{status:?}");
    assert_eq!(app.world().resource::<SnowpackSettings>().terrain, TerrainSource::Flat { height_m: 0.0 }, "the terrain changed");
}

#[test]
fn own_terrain_example_shows_trails_on_its_slopes() {
    let Some(x) = Xvfb::start() else { return };
    let dir = std::env::temp_dir().join(format!("bevy_snowpack_own_terrain_{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    let shot = dir.join("own_terrain.png");
    let out = Command::new(example("own_terrain"))
        .args(["--exit-after-frames", "90", "--screenshot"])
        .arg(&shot)
        .env("DISPLAY", &x.display)
        .env("CARGO_MANIFEST_DIR", env!("CARGO_MANIFEST_DIR"))
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("the own_terrain example runs (cargo test builds it)");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "own_terrain exited with {}\nstdout:\n{stdout}\nstderr:\n{stderr}", out.status);
    let report = stdout.lines().find(|l| l.starts_with("own_terrain: ")).unwrap_or_else(|| panic!("no report line in\n{stdout}\n{stderr}"));
    // own_terrain: trail pixel X Y fresh pixel X Y trail_height_m H fresh_height_m H
    let words: Vec<&str> = report.split_whitespace().collect();
    assert_eq!(words.get(1..3), Some(&["trail", "pixel"][..]), "no trail on screen: {report}");
    let number = |k: usize| words[k].parse::<f32>().unwrap_or_else(|e| panic!("{report}: word {k}: {e}"));
    let (trail, fresh, heights) = ((number(3), number(4)), (number(7), number(8)), (number(10), number(12)));
    let image = image::open(&shot).unwrap_or_else(|e| panic!("{}: {e}", shot.display())).to_rgba8();
    let inside = |(x, y): (f32, f32)| x >= 4.0 && y >= 4.0 && x < image.width() as f32 - 4.0 && y < image.height() as f32 - 4.0;
    assert!(inside(trail) && inside(fresh), "{report}: off the {}x{} picture", image.width(), image.height());
    let luma = |(x, y): (f32, f32)| patch_luma(&image, x as u32, y as u32);
    let (trail_luma, fresh_luma) = (luma(trail), luma(fresh));
    println!("{report}; luma: trail {trail_luma:.1}, fresh {fresh_luma:.1}; picture {}", shot.display());
    // Not a flat ground: the trail and the open snow lie at different heights of the landscape.
    assert!((heights.0 - heights.1).abs() > 0.2, "{report}: the landscape is flat there");
    // Untouched snow is bright; the trail, pressed to the ground, shows the game's dark material.
    assert!(fresh_luma > 120.0, "untouched snow reads {fresh_luma:.1}: not snow");
    assert!(fresh_luma - trail_luma > 25.0, "the trail ({trail_luma:.1}) looks like untouched snow ({fresh_luma:.1})");
    let _ = std::fs::remove_dir_all(&dir);
}
