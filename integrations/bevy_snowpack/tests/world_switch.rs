//! Snow worlds that change at run time, in one app: world A gets a trench,
//! the app switches to world B (another store, depth and terrain) and
//! presses there, then switches back to A. A's trench is there again (saved
//! to A's store when the app left it, loaded when it came back) and B's is
//! not; no restart.

mod common;

use bevy::prelude::*;
use bevy_snowpack::{SnowControl, SnowDeformer, SnowQuery, SnowStoreSettings, SnowpackSettings};
use snowpack::TerrainSource;

/// Where each world is pressed.
const A_AT: Vec2 = Vec2::new(1.0, -1.0);
const B_AT: Vec2 = Vec2::new(-1.0, 1.0);

/// Updates `app` until `done` gives something, at most `frames` times.
fn until<T>(app: &mut App, frames: u32, mut done: impl FnMut(&mut App) -> Option<T>) -> Option<T> {
    (0..frames).find_map(|_| {
        app.update();
        done(app)
    })
}

/// The snow's depth (m) at A's and B's places, asked through `SnowQuery`.
fn depths(app: &mut App) -> (f32, f32) {
    let ticket = app.world_mut().resource_mut::<SnowQuery>().ask(&[A_AT, B_AT]);
    let answers = until(app, 8, |app| app.world_mut().resource_mut::<SnowQuery>().take(ticket)).expect("answered within 8 frames");
    let depth = |k: usize| answers.samples[k].expect("inside the window").depth_m();
    (depth(0), depth(1))
}

/// A box pressed into the snow at `at`, its bottom `floor_m` above the ground at `ground_m`, then taken away.
fn press(app: &mut App, at: Vec2, ground_m: f32, floor_m: f32) {
    let pressing =
        app.world_mut().spawn((SnowDeformer::Box { half_extents: Vec3::splat(0.4) }, Transform::from_xyz(at.x, ground_m + floor_m + 0.4, at.y))).id();
    for _ in 0..5 {
        app.update();
    }
    app.world_mut().despawn(pressing);
    for _ in 0..3 {
        app.update();
    }
}

/// Replaces the app's snow settings and lets the render world build the new world.
fn switch_to(app: &mut App, settings: &SnowpackSettings) {
    *app.world_mut().resource_mut::<SnowpackSettings>() = settings.clone();
    for _ in 0..3 {
        app.update();
    }
}

#[test]
fn a_world_left_and_come_back_to_keeps_its_trench_and_not_the_other_worlds() {
    let root = std::env::temp_dir().join(format!("bevy_snowpack_worlds_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let a = SnowpackSettings { store: Some(SnowStoreSettings::new(root.join("a"))), ..common::test_settings() };
    let mut b = SnowpackSettings { store: Some(SnowStoreSettings::new(root.join("b"))), ..common::test_settings() };
    // B is another world: 0.3 m of snow on ground 0.2 m up, a 6 m window.
    b.params.depth_m = 0.3;
    b.params.extent_m = 6.0;
    b.terrain = TerrainSource::Flat { height_m: 0.2 };

    let Some(mut app) = common::headless_app(a.clone()) else { return };
    app.update();
    press(&mut app, A_AT, 0.0, 0.1);
    let (a_trench, a_open) = depths(&mut app);
    assert!((a_trench - 0.1).abs() < 0.01 && (a_open - 0.4).abs() < 1e-3, "world A: {a_trench} m in the trench, {a_open} m open");

    switch_to(&mut app, &b);
    {
        let state = common::render_state(&app);
        assert_eq!(state.generation(), 1, "the render world did not build world B");
        let snow = state.deformation();
        assert!((snow.params().depth_m - 0.3).abs() < 1e-6 && (snow.params().extent_m - 6.0).abs() < 1e-6, "world B runs with {:?}", snow.params());
    }
    assert_eq!(app.world().resource::<SnowControl>().loaded_save(), Some(false), "B's new store holds no save");
    let (a_in_b, b_before) = depths(&mut app);
    assert!((a_in_b - 0.3).abs() < 1e-3, "world B shows {a_in_b} m at A's trench: A's trench leaked into B");
    assert!((b_before - 0.3).abs() < 1e-3, "world B starts with {b_before} m at its own place");
    press(&mut app, B_AT, 0.2, 0.1);
    let (_, b_trench) = depths(&mut app);
    assert!((b_trench - 0.1).abs() < 0.01, "world B's trench holds {b_trench} m, want 0.1 m");

    switch_to(&mut app, &a);
    assert_eq!(common::render_state(&app).generation(), 2, "the render world did not build world A again");
    assert_eq!(app.world().resource::<SnowControl>().loaded_save(), Some(true), "A's save was not loaded on coming back");
    let (a_back, b_in_a) = depths(&mut app);
    assert!((a_back - 0.1).abs() < 0.01, "back in world A its trench holds {a_back} m, want 0.1 m (it was {a_trench} m)");
    assert!((b_in_a - 0.4).abs() < 1e-3, "world A shows {b_in_a} m at B's trench: B's trench leaked into A");
    drop(app);
    let _ = std::fs::remove_dir_all(&root);
}
