//! The smallest bevy_snowpack app: a cube pushed around on the snow, a sun,
//! a camera that draws snowpack's snow ground in its main pass (`SnowGroundPass`).
//!
//! ```text
//! cargo run --example minimal [-- --exit-after-frames N] [--screenshot FILE]
//! ```

#[path = "common/cli.rs"]
mod cli;

use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::light::CascadeShadowConfigBuilder;
use bevy::prelude::*;
use bevy_snowpack::prelude::*;

#[derive(Component)]
struct Pushed;

fn main() {
    let cli = cli::Cli::parse();
    App::new()
        .add_plugins(DefaultPlugins.set(WindowPlugin {
            primary_window: Some(Window { title: "bevy_snowpack minimal".into(), resolution: (960, 540).into(), ..default() }),
            ..default()
        }))
        .add_plugins((SnowpackPlugin::default(), cli::CliPlugin(cli)))
        .add_systems(Startup, setup)
        .add_systems(Update, push)
        .run();
}

fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>, mut materials: ResMut<Assets<StandardMaterial>>) {
    // The cube: 0.6 m wide, its bottom 0.1 m above the ground in 0.4 m of snow.
    commands.spawn((
        Pushed,
        SnowDeformer::Box { half_extents: Vec3::splat(0.3) },
        Mesh3d(meshes.add(Cuboid::new(0.6, 0.6, 0.6))),
        MeshMaterial3d(materials.add(Color::srgb(0.7, 0.2, 0.15))),
        Transform::from_xyz(0.0, 0.4, 0.0),
    ));
    commands.spawn((
        DirectionalLight { illuminance: 12_000.0, shadow_maps_enabled: true, ..default() },
        Transform::from_xyz(-4.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
        CascadeShadowConfigBuilder { maximum_distance: 30.0, ..default() }.build(),
    ));
    // The camera draws snowpack's own snow ground in its main pass.
    commands.spawn((
        Camera3d::default(),
        SnowGroundPass,
        Tonemapping::AcesFitted,
        Transform::from_xyz(0.0, 6.0, 9.0).looking_at(Vec3::new(0.0, 0.0, 1.0), Vec3::Y),
    ));
}

/// The cube slides along a figure eight, turning with its path.
fn push(time: Res<Time>, mut cube: Single<&mut Transform, With<Pushed>>) {
    let t = time.elapsed_secs() * 0.5;
    let p = Vec3::new(4.0 * t.sin(), 0.4, 2.5 * (2.0 * t).sin());
    let v = Vec3::new(4.0 * t.cos(), 0.0, 5.0 * (2.0 * t).cos());
    cube.translation = p;
    cube.rotation = Quat::from_rotation_y(v.x.atan2(v.z));
}
