//! The glTF fox walks out over snowy hills, turns and walks back in its own
//! trail, under a Bevy camera while balls drop out of the sky and roll: the
//! fox's skinned mesh presses its paws into the snow in pose
//! (`SnowDeformer::Mesh`), its paw bones raise footstep messages, and the
//! balls carve trenches. The snow holds the fox back (`FeelsSnow`,
//! `SnowResistance`): it wades slowly through the 0.4 m of fresh snow and
//! walks faster in the trail it packed, at the floor the snow gives it. The
//! snow ground is drawn by snowpack's `SnowGroundPass` in the camera's main
//! pass.
//!
//! ```text
//! cargo run --release --example walk [-- --exit-after-frames N] [--screenshot FILE]
//! ```
//!
//! With `--exit-after-frames` the scene advances a fixed 1/30 s a frame
//! (the same picture on any machine); at the screenshot it prints where a
//! ball's trench and untouched snow are on screen and the fox's speeds
//! measured from its positions frame to frame (in fresh snow, and back in
//! its trail), for the tests.

#[path = "common/cli.rs"]
mod cli;
#[path = "common/gltf.rs"]
mod gltf;

use bevy::animation::graph::{AnimationGraph, AnimationGraphHandle, AnimationNodeIndex};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::gltf::GltfAssetLabel;
use bevy::light::CascadeShadowConfigBuilder;
use bevy::prelude::*;
use bevy::world_serialization::{WorldAssetRoot, WorldInstanceReady};
use bevy_snowpack::prelude::*;
use snowpack::low_level::TerrainSourceExt;

/// Snow depth (m) on the hills.
const DEPTH_M: f32 = 0.4;
/// The fox's model is in centimetres.
const FOX_SCALE: f32 = 0.01;
/// How far the fox's paws sink into the snow (its model's soles are at its
/// origin) until the snow has answered (`SnowResistance::floor_m`).
const FOX_SINKAGE_M: f32 = 0.07;
/// Seconds of walking out before the fox turns back along its trail
/// (counted from when its scene is in the world).
const OUT_S: f32 = 1.5;
/// The fox's trotting speed on firm ground (m/s); the snow's speed factor scales it.
const WALK_M_PER_S: f32 = 2.0;
/// A fixed step when the run is scripted (`--exit-after-frames`).
const SCRIPTED_DT_S: f32 = 1.0 / 30.0;
const BALL_RADIUS_M: f32 = 0.3;
/// The snow's penetration hardness (kPa): fresh powder.
const POWDER_KPA: f32 = 3.0;
const GRAVITY: f32 = 9.81;

fn terrain() -> TerrainSource {
    TerrainSource::Noise(NoiseTerrain { seed: 11, base_m: 0.0, amplitude_m: 1.2, wavelength_m: 20.0 })
}

fn main() {
    let cli = cli::Cli::parse();
    let scripted = cli.exit_after_frames.is_some();
    let mut snow = SnowpackPlugin::default().with_window(24.0, 512).with_depth(DEPTH_M).with_refill(0.0).with_terrain(terrain());
    // Fresh powder (3 kPa: a 10 cm plate sinks 10 cm at 3 kPa): the fox wades 18 cm deep out, not at all back in its trail.
    snow.settings.params.hardness_kpa = POWDER_KPA;
    if scripted {
        snow = snow.with_fixed_dt(SCRIPTED_DT_S);
    }
    App::new()
        .add_plugins(
            DefaultPlugins
                .set(WindowPlugin {
                    primary_window: Some(Window { title: "bevy_snowpack walk".into(), resolution: (960, 540).into(), ..default() }),
                    ..default()
                })
                // The fox lives in the repository's assets folder (relative to this crate's manifest).
                .set(AssetPlugin { file_path: "../../assets".into(), ..default() }),
        )
        .add_plugins((snow, cli::CliPlugin(cli)))
        .add_plugins(gltf::GltfTypesPlugin)
        .insert_resource(ClearColor(Color::srgb(0.62, 0.74, 0.88)))
        .insert_resource(Clock { scripted, t: 0.0 })
        .add_systems(Startup, setup)
        .add_systems(Update, (tick, walk_fox, drop_balls, report_steps, follow_camera).chain())
        .add_systems(Last, report_screen_points)
        .run();
}

/// The scene's time: real time, or a fixed step a frame when scripted.
#[derive(Resource)]
struct Clock {
    scripted: bool,
    t: f32,
}

#[derive(Component)]
struct Fox {
    walk: AnimationNodeIndex,
    /// Seconds walked since its scene came into the world (it waits for it:
    /// without its mesh it would press nothing).
    walked_s: Option<f32>,
    /// How far along its path it is (m).
    s: f32,
    /// Speeds measured from its positions frame to frame (m/s): out in fresh
    /// snow once the snow has answered, and back in its own trail.
    fresh: Vec<f32>,
    trail: Vec<f32>,
    /// Where it was last frame (x, z), and the farthest it went out (m along its path).
    last: Option<Vec2>,
    turned_at: Option<f32>,
}

/// A ball: falls, lands in the snow, rolls to a stop.
#[derive(Component)]
struct Ball {
    velocity: Vec3,
    /// Where it has been since it landed (scene time, centre).
    rolled: Vec<(f32, Vec3)>,
}

#[derive(Resource)]
struct FoxAnimations(Handle<AnimationGraph>);

#[derive(Resource, Default)]
struct Steps(u32);

/// Where the fox is `s` metres along its path: a gentle curve, and the
/// direction of growing `s`.
fn fox_path(s: f32) -> (Vec2, Vec2) {
    let at = |s: f32| Vec2::new(-5.0 + s, 1.5 * (s * 0.25).sin());
    let p = at(s);
    (p, (at(s + 0.01) - p).normalize())
}

/// The snow's rest surface over the terrain (m).
fn snow_top(x: f32, z: f32) -> f32 {
    terrain().height_at(x, z) + DEPTH_M
}

fn setup(
    mut commands: Commands,
    assets: Res<AssetServer>,
    mut graphs: ResMut<Assets<AnimationGraph>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    // Fox.glb's clips: 0 survey, 1 walk, 2 run.
    let (graph, nodes) = AnimationGraph::from_clips([assets.load(GltfAssetLabel::Animation(1).from_asset("Fox.glb"))]);
    commands.insert_resource(FoxAnimations(graphs.add(graph)));
    let (p, _) = fox_path(0.0);
    commands
        .spawn((
            Fox { walk: nodes[0], walked_s: None, s: 0.0, fresh: Vec::new(), trail: Vec::new(), last: None, turned_at: None },
            // The snow holds it back: a 6 kg fox on 35 cm² paws.
            FeelsSnow::fox(),
            WorldAssetRoot(assets.load(GltfAssetLabel::Scene(0).from_asset("Fox.glb"))),
            // Every mesh of the fox's scene presses the snow, skinned in pose,
            // and carries the snow it wades through (drawn by SnowCoatMaterial).
            SnowDeformer::Mesh,
            SnowCoatLook,
            SnowWindowTarget,
            Transform::from_xyz(p.x, snow_top(p.x, p.y) - FOX_SINKAGE_M, p.y).with_scale(Vec3::splat(FOX_SCALE)),
        ))
        .observe(start_fox);
    commands.init_resource::<Steps>();

    // Balls in the sky ahead of the camera, each with its own sideways push.
    let ball_mesh = meshes.add(Sphere::new(BALL_RADIUS_M));
    let ball_material = materials.add(StandardMaterial { base_color: Color::srgb(0.75, 0.18, 0.12), perceptual_roughness: 0.5, ..default() });
    for k in 0..3 {
        let x = -3.5 + 2.5 * k as f32;
        let z = 3.0 + 0.5 * (k % 2) as f32;
        commands.spawn((
            Ball { velocity: Vec3::ZERO, rolled: Vec::new() },
            SnowDeformer::Sphere { radius: BALL_RADIUS_M },
            Mesh3d(ball_mesh.clone()),
            MeshMaterial3d(ball_material.clone()),
            Transform::from_xyz(x, snow_top(x, z) + 1.0 + 0.7 * k as f32, z),
        ));
    }
    commands.spawn((
        DirectionalLight { illuminance: 12_000.0, shadow_maps_enabled: true, ..default() },
        Transform::from_xyz(-3.0, 2.5, 4.0).looking_at(Vec3::ZERO, Vec3::Y),
        // One cascade: the software rasteriser draws each cascade's shadow map every frame.
        CascadeShadowConfigBuilder { num_cascades: 1, maximum_distance: 20.0, ..default() }.build(),
    ));
    commands.spawn((Camera3d::default(), SnowGroundPass, Tonemapping::AcesFitted, Transform::from_xyz(0.0, 5.0, 10.0)));
}

/// Once the fox's scene is in the world: play the walk, and mark its paws as feet.
fn start_fox(
    ready: On<WorldInstanceReady>,
    mut commands: Commands,
    mut foxes: Query<&mut Fox>,
    children: Query<&Children>,
    mut players: Query<&mut AnimationPlayer>,
    names: Query<&Name>,
    animations: Res<FoxAnimations>,
) {
    let Ok(mut fox) = foxes.get_mut(ready.entity) else { return };
    fox.walked_s = Some(0.0);
    for entity in children.iter_descendants(ready.entity) {
        if let Ok(mut player) = players.get_mut(entity) {
            player.play(fox.walk).repeat();
            commands.entity(entity).insert(AnimationGraphHandle(animations.0.clone()));
        }
        // The fox's paw bones (b_LeftHand_011, b_RightFoot02_022, ... in Fox.glb) report its steps;
        // the bone sits about 8 cm above the sole.
        if names.get(entity).is_ok_and(|n| {
            let n = n.as_str().to_lowercase();
            n.contains("hand") || n.contains("foot02")
        }) {
            commands.entity(entity).insert(SnowFoot::new(FootKind::Paw).with_contact(0.08));
        }
    }
}

fn tick(time: Res<Time>, mut clock: ResMut<Clock>) {
    clock.t += if clock.scripted { SCRIPTED_DT_S } else { time.delta_secs() };
}

/// The fox walks out along its path for `OUT_S`, then back along it, at its
/// walking speed times the snow's speed factor, its paws at the floor the
/// snow gives it; its speed is measured from its positions.
fn walk_fox(clock: Res<Clock>, time: Res<Time>, mut fox: Single<(&mut Fox, &mut Transform, &SnowResistance)>) {
    let dt = if clock.scripted { SCRIPTED_DT_S } else { time.delta_secs() };
    let (fox, transform, resistance) = &mut *fox;
    let Some(walked_s) = fox.walked_s else { return };
    fox.walked_s = Some(walked_s + dt);
    let out = walked_s < OUT_S;
    if !out && fox.turned_at.is_none() {
        fox.turned_at = Some(fox.s);
    }
    let step = WALK_M_PER_S * resistance.speed_factor * dt;
    fox.s += if out { step } else { -step };
    let (p, heading) = fox_path(fox.s);
    let floor = resistance.floor_m.unwrap_or(snow_top(p.x, p.y) - FOX_SINKAGE_M);
    transform.translation = Vec3::new(p.x, floor, p.y);
    // The model faces +z; walking back it faces the other way.
    let facing = if out { heading } else { -heading };
    transform.rotation = Quat::from_rotation_y(facing.x.atan2(facing.y));
    if let Some(last) = fox.last {
        let speed = p.distance(last) / dt;
        // Out once the snow has answered; back once well inside its trail (a few frames after the turn).
        if out && resistance.floor_m.is_some() {
            fox.fresh.push(speed);
        } else if fox.turned_at.is_some_and(|turned| fox.s < turned - 0.2 && fox.s > 0.2) {
            fox.trail.push(speed);
        }
    }
    fox.last = Some(p);
}

/// Gravity until a ball meets the snow, then it settles into it and rolls downhill to a stop.
fn drop_balls(clock: Res<Clock>, time: Res<Time>, mut balls: Query<(&mut Ball, &mut Transform)>) {
    let dt = if clock.scripted { SCRIPTED_DT_S } else { time.delta_secs() };
    for (mut ball, mut transform) in &mut balls {
        let p = transform.translation;
        // Resting, the ball presses half the snow's depth.
        let rest = snow_top(p.x, p.z) - 0.5 * DEPTH_M + BALL_RADIUS_M;
        if ball.rolled.is_empty() {
            ball.velocity.y -= GRAVITY * dt;
            transform.translation += ball.velocity * dt;
            if transform.translation.y <= rest {
                transform.translation.y = rest;
                ball.rolled.push((clock.t, transform.translation));
                // Rolling off across the camera's view.
                ball.velocity = Vec3::new(1.8, 0.0, 0.5);
            }
        } else {
            let slope = terrain().normal_at(p.x, p.z, 0.05);
            let roll = Vec3::new(slope.x, 0.0, slope.z) * GRAVITY * 0.3;
            let v = (ball.velocity + roll * dt) * (1.0 - 0.8 * dt);
            ball.velocity = if v.length() < 0.05 { Vec3::ZERO } else { v };
            let q = p + ball.velocity * dt;
            transform.translation = Vec3::new(q.x, snow_top(q.x, q.z) - 0.5 * DEPTH_M + BALL_RADIUS_M, q.z);
            ball.rolled.push((clock.t, transform.translation));
        }
    }
}

fn report_steps(mut steps: MessageReader<SnowFootstep>, mut count: ResMut<Steps>) {
    for step in steps.read() {
        count.0 += 1;
        debug!("footstep at {:.2} sinkage {:.3} m", step.position, step.sinkage_m);
    }
}

/// The camera looks down on the fox's path from the side the balls roll to,
/// following the fox along x.
fn follow_camera(fox: Single<&Transform, (With<Fox>, Without<Camera3d>)>, mut camera: Single<&mut Transform, With<Camera3d>>) {
    let p = fox.translation.xz();
    let focus = Vec3::new(p.x + 1.5, terrain().height_at(p.x + 1.5, 1.8), 1.8);
    **camera = Transform::from_translation(focus + Vec3::new(0.0, 3.2, 4.8)).looking_at(focus, Vec3::Y);
}

/// At the screenshot: where on screen a ball's trench and untouched snow
/// are (physical pixels), the footsteps so far and the fox's mean speeds
/// (fresh snow, its trail), for the tests to read.
#[allow(clippy::too_many_arguments, reason = "a Bevy system: each argument is a query or resource it reads")]
fn report_screen_points(
    cli: Res<cli::Cli>,
    clock: Res<Clock>,
    mut frames: Local<u32>,
    balls: Query<&Ball>,
    camera: Single<(&Camera, &GlobalTransform)>,
    window: Single<&Window>,
    steps: Res<Steps>,
    fox: Single<&Fox>,
) {
    *frames += 1;
    if cli.screenshot.is_none() || *frames != cli.exit_after_frames.unwrap_or(120) {
        return;
    }
    let (camera, at) = *camera;
    let scale = window.scale_factor();
    let pixel = |p: Vec3| camera.world_to_viewport(at, p).ok().map(|v| v * scale);
    // Where the first ball to land was 0.4 s after landing (it has rolled on since, off that
    // spot), at the trench's floor; and untouched snow between the fox's path and the balls'.
    let trench =
        balls.iter().filter_map(|b| b.rolled.iter().find(|(t, _)| *t >= b.rolled[0].0 + 0.4)).filter(|(t, _)| *t < clock.t - 1.0).map(|(_, p)| *p).next();
    let trench = trench.map(|t| Vec3::new(t.x, snow_top(t.x, t.z) - 0.5 * DEPTH_M, t.z));
    let fresh = Vec2::new(-1.5, -1.0);
    let fresh = Vec3::new(fresh.x, snow_top(fresh.x, fresh.y), fresh.y);
    let mean = |v: &[f32]| if v.is_empty() { f32::NAN } else { v.iter().sum::<f32>() / v.len() as f32 };
    let speeds = format!("fox m/s fresh {:.3} over {} trail {:.3} over {}", mean(&fox.fresh), fox.fresh.len(), mean(&fox.trail), fox.trail.len());
    match (trench.and_then(pixel), pixel(fresh)) {
        (Some(t), Some(f)) => println!("walk: trench pixel {:.0} {:.0} fresh pixel {:.0} {:.0} footsteps {} {speeds}", t.x, t.y, f.x, f.y, steps.0),
        _ => println!("walk: no trench on screen yet, footsteps {} {speeds}", steps.0),
    }
}
