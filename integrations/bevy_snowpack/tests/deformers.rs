//! Meshes press the snow in pose: a plain mesh with `SnowDeformer::Mesh`
//! presses what the same box as `SnowDeformer::Box` presses, and a skinned
//! mesh presses where its joints put it, not where its entity stands.

mod common;

use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use bevy_snowpack::SnowDeformer;

/// The boxes' half size: 0.3 m across, 0.25 m tall.
const HALF: Vec3 = Vec3::new(0.3, 0.25, 0.3);

/// Both boxes' path: 4 m along x in 40 frames (6 texels a frame: swept), bottoms 0.15 m above the ground.
fn along(k: u32, z: f32) -> Vec3 {
    Vec3::new(-2.0 + 0.1 * k.min(40) as f32, 0.15 + HALF.y, z)
}

#[derive(Component)]
struct Lane(f32);

#[test]
fn a_mesh_presses_what_the_same_box_presses() {
    let Some(mut app) = common::headless_app(common::test_settings()) else { return };
    app.add_systems(Update, |mut frame: Local<u32>, mut boxes: Query<(&mut Transform, &Lane)>| {
        for (mut t, lane) in &mut boxes {
            t.translation = along(*frame, lane.0);
            t.rotation = Quat::from_rotation_y(0.3);
        }
        *frame += 1;
    });
    let world = app.world_mut();
    let cuboid = world.resource_mut::<Assets<Mesh>>().add(Cuboid::from_size(2.0 * HALF));
    world.spawn((Lane(-2.0), SnowDeformer::Box { half_extents: HALF }, Transform::from_translation(along(0, -2.0))));
    world.spawn((Lane(2.0), SnowDeformer::Mesh, Mesh3d(cuboid), Transform::from_translation(along(0, 2.0))));
    for _ in 0..50 {
        app.update();
    }
    let height = common::snow_heights(&app);
    // The two lanes are 4 m (64 texels) apart: compare them texel for texel. The two
    // rasterise the same triangles by different sweeps (the box's sub-steps, the skin's),
    // so a texel whose centre lies on the trench's edge may fall either way (and a mesh's
    // vertices are also drawn as points, which covers the texel a swept corner runs
    // through): each texel must match the other lane at itself or at a neighbour, and the
    // volumes may differ by at most the box trench's edge texels pressed to full depth.
    let texel = 0.0625;
    let at = |lane: f32, i: i32, j: i32| height(j as f32 * texel + 0.03, lane + i as f32 * texel + 0.03);
    let near = |a: f32, other: f32, i: i32, j: i32| (-1..=1).any(|di| (-1..=1).any(|dj| (at(other, i + di, j + dj) - a).abs() < 0.005));
    let (mut box_volume, mut mesh_volume, mut deepest, mut mismatched, mut edge) = (0.0f32, 0.0f32, 0.0f32, Vec::new(), 0.0f32);
    for i in -12..=12 {
        for j in -40..=40 {
            let (a, b) = (at(-2.0, i, j), at(2.0, i, j));
            box_volume += 0.4 - a;
            mesh_volume += 0.4 - b;
            deepest = deepest.max(0.4 - b);
            let pressed = |h: f32| h < 0.4 - 0.005;
            if pressed(a) && [(0, 1), (0, -1), (1, 0), (-1, 0)].iter().any(|&(di, dj)| !pressed(at(-2.0, i + di, j + dj))) {
                edge += 1.0;
            }
            if !near(a, 2.0, i, j) || !near(b, -2.0, i, j) {
                mismatched.push((i, j, a, b));
            }
        }
    }
    assert!((deepest - 0.25).abs() < 0.01, "the mesh pressed {deepest} m of the 0.4 m, want 0.25");
    assert!(mismatched.is_empty(), "mesh and box trenches differ beyond a texel's shift at (row, column, box, mesh) {mismatched:?}");
    let bound = edge * 0.25;
    println!("pressed volume (texel-metres): box {box_volume}, mesh {mesh_volume}; edge bound {bound}");
    assert!((mesh_volume - box_volume).abs() <= bound, "pressed volume: mesh {mesh_volume}, box {box_volume} (texel-metres), more than the edge's {bound}");
}

#[derive(Component)]
struct Moved;

#[test]
fn a_skinned_mesh_presses_where_its_joints_put_it() {
    let Some(mut app) = common::headless_app(common::test_settings()) else { return };
    let world = app.world_mut();
    // A box whose every vertex is bound to joint 1.
    let mut mesh = Cuboid::from_size(2.0 * HALF).mesh().build();
    let n = mesh.count_vertices();
    mesh.insert_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, VertexAttributeValues::Uint16x4(vec![[1, 0, 0, 0]; n]));
    mesh.insert_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, vec![[1.0f32, 0.0, 0.0, 0.0]; n]);
    let mesh = world.resource_mut::<Assets<Mesh>>().add(mesh);
    let bind = world.resource_mut::<Assets<SkinnedMeshInverseBindposes>>().add(SkinnedMeshInverseBindposes::from(vec![Mat4::IDENTITY; 2]));
    let still = world.spawn(Transform::from_xyz(0.0, 3.0, 0.0)).id();
    let moved = world.spawn((Moved, Transform::from_translation(along(0, -1.0)))).id();
    // The mesh entity itself stands 2 m to the side in the snow: skinned, its own transform does not place it.
    world.spawn((SnowDeformer::Mesh, Mesh3d(mesh), SkinnedMesh { inverse_bindposes: bind, joints: vec![still, moved] }, Transform::from_xyz(0.0, 0.2, 2.0)));
    app.add_systems(Update, |mut frame: Local<u32>, mut joint: Single<&mut Transform, With<Moved>>| {
        joint.translation = along(*frame, -1.0);
        *frame += 1;
    });
    for _ in 0..50 {
        app.update();
    }
    let height = common::snow_heights(&app);
    for x in [-1.8, -1.0, 0.0, 1.0, 1.8] {
        let h = height(x, -1.0);
        assert!((h - 0.15).abs() < 0.01, "under joint 1's path at x = {x}: {h} m, want the box's bottom at 0.15 m");
        let beside = height(x, 2.0);
        assert!((beside - 0.4).abs() < 1e-3, "where the mesh entity stands, x = {x}: {beside} m, want untouched 0.4 m");
    }
}

#[derive(Component)]
struct Plough;

/// `SnowDeformer::Blade` with `params.displace`: a blade 1.5 m wide, turned
/// 30° from its travel, scrapes 0.4 m of snow to the ground along x; the
/// cut is bare, the windrow beside it rises above the snow, and the snow
/// above the rest surface is what the cut lost.
#[test]
fn a_blade_pushes_its_cut_into_a_windrow() {
    let mut settings = common::test_settings();
    settings.params.displace = true;
    settings.params.repose_deg = Some(38.0);
    let Some(mut app) = common::headless_app(settings) else { return };
    // Forward (-z) turned to +x; 3 m along x in 60 frames.
    let at = |k: u32| Vec3::new(-1.5 + 0.05 * k.min(60) as f32, -0.02, 0.0);
    app.add_systems(Update, move |mut frame: Local<u32>, mut blades: Query<&mut Transform, With<Plough>>| {
        for mut t in &mut blades {
            t.translation = at(*frame);
        }
        *frame += 1;
    });
    app.world_mut().spawn((
        Plough,
        SnowDeformer::Blade { width: 1.5, height: 0.8, angle_deg: 30.0 },
        Transform::from_translation(at(0)).with_rotation(Quat::from_rotation_y(-std::f32::consts::FRAC_PI_2)),
    ));
    for _ in 0..80 {
        app.update();
    }
    let height = common::snow_heights(&app);
    // The cut's middle along the way (the blade spans z ±0.65 turned 30°).
    for x in [-0.5f32, 0.0, 0.5] {
        let h = height(x, 0.0);
        assert!(h < 0.05, "the cut at x = {x} holds {h} m of snow");
    }
    let (mut top, mut above, mut below) = (0.0f32, 0.0f32, 0.0f32);
    for i in -60..=60 {
        for j in -60..=60 {
            let h = height(j as f32 * 0.0625 + 0.03, i as f32 * 0.0625 + 0.03);
            top = top.max(h);
            above += (h - 0.4).max(0.0);
            below += (0.4 - h).max(0.0);
        }
    }
    println!("blade: windrow top {top} m; above the snow {above}, below it {below} (texel-metres)");
    assert!(top > 0.55, "the windrow tops at {top} m over 0.4 m of snow");
    assert!(below > 100.0 && (above / below - 1.0).abs() < 0.05, "berms {above} against the cut's {below} texel-metres");
}
