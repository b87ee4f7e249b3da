//! Snow on the game's own ground: a hilly landscape from a heightmap image
//! (made in code here, as a game would load a 16-bit PNG), drawn with the
//! game's own `StandardMaterial` extended by `SnowCoverExtension`; the snow's
//! terrain comes from the same image (`SnowTerrainAsset`). Three balls roll
//! along the slopes and leave trails down to the ground, where the game's
//! material shows through.
//!
//! ```text
//! cargo run --example own_terrain [-- --exit-after-frames N] [--screenshot FILE]
//! ```
//!
//! At the screenshot it prints where a trail and untouched snow are on
//! screen and the terrain's heights there (`own_terrain: trail pixel X Y
//! fresh pixel X Y trail_height_m H fresh_height_m H`).

#[path = "common/cli.rs"]
mod cli;

use bevy::asset::RenderAssetUsages;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::light::CascadeShadowConfigBuilder;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use bevy_snowpack::prelude::*;

/// The landscape's side (m) and its heightmap's pixels a side.
const SIZE_M: f32 = 24.0;
const PIXELS: u32 = 129;
/// Height of a heightmap value of 1 (m).
const HEIGHT_SCALE_M: f32 = 3.0;
/// The balls' radius (m); they sink to 5 cm below the ground, so their trails reach it.
const BALL_M: f32 = 0.45;

/// The terrain's heights, for placing the balls and the report.
#[derive(Resource)]
struct Ground(TerrainSource);

/// A ball rolling around a loop on the slopes: centre, radii, speed and phase.
#[derive(Component)]
struct Roller {
    center: Vec2,
    radii: Vec2,
    speed: f32,
    phase: f32,
}

impl Roller {
    /// Where it is (x, z) at time `t`.
    fn at(&self, t: f32) -> Vec2 {
        let a = self.phase + self.speed * t;
        self.center + self.radii * Vec2::new(a.cos(), a.sin())
    }
}

fn main() {
    let cli = cli::Cli::parse();
    let scripted = cli.exit_after_frames.is_some();
    let settings = SnowpackSettings {
        // No rim remap (`elevation` 0): a trail pressed to the ground shows the ground, the game's own material.
        params: SnowParams { extent_m: SIZE_M, resolution: 256, depth_m: 0.25, refill_m_per_s: 0.0, elevation: 0.0, ..SnowParams::default() },
        fixed_dt_s: scripted.then_some(SCRIPTED_DT_S),
        ..SnowpackSettings::default()
    };
    App::new()
        .add_plugins(DefaultPlugins.set(WindowPlugin {
            primary_window: Some(Window { title: "bevy_snowpack own terrain".into(), resolution: (960, 540).into(), ..default() }),
            ..default()
        }))
        .add_plugins((SnowpackPlugin::new(settings), cli::CliPlugin(cli)))
        .insert_resource(ClearColor(Color::srgb(0.62, 0.74, 0.88)))
        .insert_resource(Clock { scripted, t: 0.0, frames: 0 })
        .add_systems(Startup, setup)
        .add_systems(Update, (roll, report).chain())
        .run();
}

/// A fixed step when the run is scripted (`--exit-after-frames`): the same picture on any machine.
const SCRIPTED_DT_S: f32 = 1.0 / 30.0;

/// The scene's time: real time, or a fixed step a frame when scripted.
#[derive(Resource)]
struct Clock {
    scripted: bool,
    t: f32,
    frames: u32,
}

/// A 16-bit heightmap of rolling hills: a ridge across the middle, a dip
/// and a knoll, as a game's terrain image would be.
fn heightmap() -> Image {
    let mut data = Vec::with_capacity((PIXELS * PIXELS * 2) as usize);
    for row in 0..PIXELS {
        for col in 0..PIXELS {
            let (x, z) = ((col as f32 / (PIXELS - 1) as f32 - 0.5) * SIZE_M, (row as f32 / (PIXELS - 1) as f32 - 0.5) * SIZE_M);
            let hills = 0.5 + 0.25 * (x * 0.32).sin() * (z * 0.27).cos() + 0.2 * (-(x * x + (z - 3.0).powi(2)) / 30.0).exp() - 0.1 * (z / 12.0);
            let v = (hills.clamp(0.0, 1.0) * 65535.0).round() as u16;
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

/// The game's own terrain mesh: a grid of `cells` squares a side over the heights, with normals.
fn terrain_mesh(ground: &TerrainSource, cells: u32) -> Mesh {
    let n = cells + 1;
    let step = SIZE_M / cells as f32;
    let mut positions = Vec::with_capacity((n * n) as usize);
    let mut normals = Vec::with_capacity((n * n) as usize);
    let mut uvs = Vec::with_capacity((n * n) as usize);
    for i in 0..n {
        for j in 0..n {
            let (x, z) = (j as f32 * step - 0.5 * SIZE_M, i as f32 * step - 0.5 * SIZE_M);
            positions.push([x, ground.height_at(x, z), z]);
            let dx = ground.height_at(x + step, z) - ground.height_at(x - step, z);
            let dz = ground.height_at(x, z + step) - ground.height_at(x, z - step);
            normals.push(Vec3::new(-dx, 2.0 * step, -dz).normalize().to_array());
            uvs.push([j as f32 / cells as f32, i as f32 / cells as f32]);
        }
    }
    let mut indices = Vec::with_capacity((cells * cells * 6) as usize);
    for i in 0..cells {
        for j in 0..cells {
            let k = i * n + j;
            indices.extend_from_slice(&[k, k + n, k + 1, k + 1, k + n, k + n + 1]);
        }
    }
    Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
        .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, normals)
        .with_inserted_attribute(Mesh::ATTRIBUTE_UV_0, uvs)
        .with_inserted_indices(Indices::U32(indices))
}

fn setup(
    mut commands: Commands,
    mut images: ResMut<Assets<Image>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut covers: ResMut<Assets<SnowCoverMaterial>>,
) {
    let image = heightmap();
    let ground = match bevy_snowpack::heightmap_from_image(&image, "own_terrain heightmap", Vec2::ZERO, Vec2::splat(SIZE_M), HEIGHT_SCALE_M, 0.0) {
        Ok(h) => TerrainSource::Heightmap(h),
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    // The snow's terrain: the same image, as the game's asset.
    commands.insert_resource(SnowTerrainAsset::heightmap(images.add(image), Vec2::splat(SIZE_M), HEIGHT_SCALE_M));

    // The game's landscape in its own material (a dark, grassy brown), with the snow laid on it.
    let grass = StandardMaterial { base_color: Color::srgb(0.22, 0.26, 0.12), perceptual_roughness: 0.95, ..default() };
    let landscape = covers.add(SnowCoverMaterial { base: grass, extension: SnowCoverExtension::default() });
    commands.spawn((Mesh3d(meshes.add(terrain_mesh(&ground, 192))), MeshMaterial3d(landscape)));

    let ball = meshes.add(Sphere::new(BALL_M).mesh().uv(24, 16));
    let rollers = [
        (Color::srgb(0.8, 0.15, 0.1), Roller { center: Vec2::new(-2.0, 1.0), radii: Vec2::new(6.0, 4.0), speed: 0.45, phase: 0.0 }),
        (Color::srgb(0.15, 0.3, 0.8), Roller { center: Vec2::new(3.0, -1.0), radii: Vec2::new(4.0, 6.5), speed: -0.4, phase: 1.0 }),
        (Color::srgb(0.9, 0.7, 0.1), Roller { center: Vec2::new(0.0, 4.0), radii: Vec2::new(7.5, 2.5), speed: 0.35, phase: 2.5 }),
    ];
    for (color, roller) in rollers {
        let start = roller.at(0.0);
        commands.spawn((
            SnowDeformer::Sphere { radius: BALL_M },
            Mesh3d(ball.clone()),
            MeshMaterial3d(materials.add(StandardMaterial { base_color: color, perceptual_roughness: 0.5, ..default() })),
            Transform::from_xyz(start.x, ground.height_at(start.x, start.y) + BALL_M - 0.05, start.y),
            roller,
        ));
    }
    commands.insert_resource(Ground(ground));
    commands.spawn((
        DirectionalLight { illuminance: 9_000.0, shadow_maps_enabled: true, ..default() },
        Transform::from_xyz(-6.0, 5.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
        CascadeShadowConfigBuilder { maximum_distance: 50.0, ..default() }.build(),
    ));
    commands.spawn((Camera3d::default(), Tonemapping::AcesFitted, Transform::from_xyz(0.0, 14.0, 19.0).looking_at(Vec3::new(0.0, 1.0, 1.0), Vec3::Y)));
}

/// The balls roll along their loops, their bottoms 5 cm into the ground under the snow.
fn roll(time: Res<Time>, mut clock: ResMut<Clock>, ground: Res<Ground>, mut balls: Query<(&Roller, &mut Transform)>) {
    clock.frames += 1;
    clock.t += if clock.scripted { SCRIPTED_DT_S } else { time.delta_secs() };
    for (roller, mut transform) in &mut balls {
        let p = roller.at(clock.t);
        transform.translation = Vec3::new(p.x, ground.0.height_at(p.x, p.y) + BALL_M - 0.05, p.y);
    }
}

/// At the screenshot frame: where on screen a trail (the first ball's path,
/// an eighth of a loop behind it) and untouched snow (off every path) are,
/// with the terrain's heights there.
fn report(cli: Res<cli::Cli>, clock: Res<Clock>, ground: Res<Ground>, balls: Query<&Roller>, camera: Single<(&Camera, &GlobalTransform)>) {
    if cli.screenshot.is_none() || Some(clock.frames) != cli.exit_after_frames {
        return;
    }
    let Some(first) = balls.iter().find(|r| r.phase == 0.0) else { return };
    let trail = first.at(clock.t - std::f32::consts::FRAC_PI_4 / first.speed.abs());
    let fresh = Vec2::new(-8.0, -7.0);
    let (camera, at) = *camera;
    let pixel = |p: Vec2| camera.world_to_viewport(at, Vec3::new(p.x, ground.0.height_at(p.x, p.y), p.y)).ok();
    match (pixel(trail), pixel(fresh)) {
        (Some(a), Some(b)) => println!(
            "own_terrain: trail pixel {:.0} {:.0} fresh pixel {:.0} {:.0} trail_height_m {:.3} fresh_height_m {:.3}",
            a.x,
            a.y,
            b.x,
            b.y,
            ground.0.height_at(trail.x, trail.y),
            ground.0.height_at(fresh.x, fresh.y)
        ),
        _ => println!("own_terrain: off screen"),
    }
}
