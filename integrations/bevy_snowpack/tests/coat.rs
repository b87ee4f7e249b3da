//! Snow on the characters in Bevy: a mesh deformer standing in snow deeper
//! than its feet gets the library's snow coat on the vertices under the snow
//! and none above, read back into `SnowCoat` on its mesh entity; with
//! `SnowCoatLook` its standard material becomes a `SnowCoatMaterial` and its
//! vertex colours carry the coat; and `SnowCoatSettings` reach the library.

mod common;

use bevy::mesh::VertexAttributeValues;
use bevy::prelude::*;
use bevy_snowpack::prelude::*;

/// A post 0.2 m wide and 1 m tall standing on the ground in the tests' 0.4 m
/// of snow: its bottom corners are 0.4 m under the snow, its top ones 0.6 m above.
fn spawn_post(app: &mut App, settings: Option<CoatSettings>) -> Entity {
    let world = app.world_mut();
    let mesh = world.resource_mut::<Assets<Mesh>>().add(Cuboid::new(0.2, 1.0, 0.2));
    let material = world.resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial::default());
    let mut post = world.spawn((SnowDeformer::Mesh, SnowCoatLook, Mesh3d(mesh), MeshMaterial3d(material), Transform::from_xyz(0.0, 0.5, 0.0)));
    if let Some(s) = settings {
        post.insert(SnowCoatSettings(s));
    }
    post.id()
}

/// The coat of `post`'s vertices with their mesh heights, after `frames` more frames.
fn coat_after(app: &mut App, post: Entity, frames: u32) -> Vec<(f32, f32)> {
    for _ in 0..frames {
        app.update();
    }
    let world = app.world();
    let coat = world.get::<SnowCoat>(post).expect("the post's coat arrived");
    let mesh = world.resource::<Assets<Mesh>>().get(&world.get::<Mesh3d>(post).expect("mesh").0).expect("mesh asset");
    let Some(VertexAttributeValues::Float32x3(positions)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else { panic!("positions") };
    assert_eq!(coat.thickness_m.len(), positions.len(), "one value a vertex");
    positions.iter().map(|p| p[1]).zip(coat.thickness_m.iter().copied()).collect()
}

#[test]
fn a_post_in_snow_carries_snow_below_the_surface_and_none_above_and_draws_it() {
    let Some(mut app) = common::headless_app(common::test_settings()) else { return };
    let post = spawn_post(&mut app, None);
    let rows = coat_after(&mut app, post, 90);
    let cap = CoatSettings::default().cap_m;
    for (y, c) in &rows {
        // Mesh y -0.5 is the ground, 0.4 m under the snow; +0.5 is 0.6 m above it.
        if *y < 0.0 {
            assert!(*c > 0.9 * cap, "a bottom corner 0.4 m under the snow carries {c} m (cap {cap})");
        } else {
            assert_eq!(*c, 0.0, "a top corner above the snow carries {c} m");
        }
    }
    // Drawn: the standard material became a coat material and the vertex colours carry the coat.
    let world = app.world();
    assert!(world.get::<MeshMaterial3d<SnowCoatMaterial>>(post).is_some(), "the post's material was not swapped for SnowCoatMaterial");
    assert!(world.get::<MeshMaterial3d<StandardMaterial>>(post).is_none());
    let mesh = world.resource::<Assets<Mesh>>().get(&world.get::<Mesh3d>(post).expect("mesh").0).expect("mesh asset");
    let Some(VertexAttributeValues::Float32x4(colours)) = mesh.attribute(Mesh::ATTRIBUTE_COLOR) else { panic!("no vertex colours on the post") };
    let coat = world.get::<SnowCoat>(post).expect("coat");
    assert!(coat.max_m() > 0.0 && coat.covered_fraction(0.001) == 0.5, "half the corners are under the snow: {:?}", coat.thickness_m);
    // The colours are the coat of some readback (the last one's, or the one before it).
    assert!(colours.iter().zip(&coat.thickness_m).all(|(c, t)| (c[0] > 0.0) == (*t > 0.0)), "{colours:?} against {:?}", coat.thickness_m);
}

#[test]
fn coat_settings_reach_the_library() {
    let Some(mut app) = common::headless_app(common::test_settings()) else { return };
    // A cap of 5 mm and no cling: nothing is gathered.
    let post = spawn_post(&mut app, Some(CoatSettings { cling_per_s: 0.0, ..CoatSettings::default() }));
    let rows = coat_after(&mut app, post, 60);
    assert!(rows.iter().all(|(_, c)| *c == 0.0), "no cling, yet the post carries {rows:?}");
    // Changed at run time: it takes effect.
    app.world_mut().entity_mut(post).insert(SnowCoatSettings(CoatSettings { cap_m: 0.005, ..CoatSettings::default() }));
    let rows = coat_after(&mut app, post, 60);
    for (y, c) in rows {
        if y < 0.0 {
            assert!((c - 0.005).abs() < 1e-4, "with a cap of 5 mm a bottom corner carries {c} m");
        }
    }
}
