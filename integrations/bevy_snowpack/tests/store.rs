//! The disk store and the objects: a trench saved through `SnowControl`
//! comes back in a new app started on the same store, and snow falling on a
//! `SnowCatcher` settles on its top at the snowfall's rate.

mod common;

use bevy::prelude::*;
use bevy_snowpack::{SnowCatcher, SnowControl, SnowDeformer, SnowQuery, SnowStoreSettings};
use snowpack::Snowfall;

/// Updates `app` until `done` gives something, at most `frames` times.
fn until<T>(app: &mut App, frames: u32, mut done: impl FnMut(&mut App) -> Option<T>) -> Option<T> {
    (0..frames).find_map(|_| {
        app.update();
        done(app)
    })
}

#[test]
fn a_saved_trench_comes_back_in_a_new_app_on_the_same_store() {
    let dir = std::env::temp_dir().join(format!("bevy_snowpack_store_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let settings = bevy_snowpack::SnowpackSettings { store: Some(SnowStoreSettings::new(&dir)), ..common::test_settings() };
    {
        let Some(mut app) = common::headless_app(settings.clone()) else { return };
        // A box pressed into the snow at (1, -1), its bottom 0.1 m above the ground.
        app.world_mut().spawn((SnowDeformer::Box { half_extents: Vec3::splat(0.4) }, Transform::from_xyz(1.0, 0.5, -1.0)));
        for _ in 0..5 {
            app.update();
        }
        assert_eq!(app.world().resource::<SnowControl>().loaded_save(), Some(false), "a new store holds no save");
        app.world_mut().resource_mut::<SnowControl>().request_save();
        let saved = until(&mut app, 5, |app| app.world_mut().resource_mut::<SnowControl>().take_save_result()).expect("the save ran within 5 frames");
        assert!(saved.is_ok(), "saving failed: {saved:?}");
    }
    // A new app on the same store: nothing presses, the trench is loaded.
    let Some(mut app) = common::headless_app(settings) else { return };
    app.update();
    assert_eq!(app.world().resource::<SnowControl>().loaded_save(), Some(true), "the save was not loaded");
    let ticket = app.world_mut().resource_mut::<SnowQuery>().ask(&[Vec2::new(1.0, -1.0), Vec2::new(-2.0, 2.0)]);
    let answers = until(&mut app, 8, |app| app.world_mut().resource_mut::<SnowQuery>().take(ticket)).expect("answered within 8 frames");
    let (trench, open) = (answers.samples[0].expect("in the window"), answers.samples[1].expect("in the window"));
    assert!((trench.depth_m() - 0.1).abs() < 0.01, "the saved trench holds {} m of snow, want 0.1 m", trench.depth_m());
    assert!((open.depth_m() - 0.4).abs() < 1e-3, "open snow holds {} m, want 0.4 m", open.depth_m());
    drop(app);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn falling_snow_settles_on_an_object_at_the_snowfall_rate() {
    const RATE: f32 = 0.01;
    let fall = Snowfall { rate_m_per_s: RATE, flutter_deg: 0.0, noise: 0.0, atlas_resolution: 256, ..Snowfall::default() };
    let mut settings = common::test_settings();
    settings.params.snowfall = Some(fall);
    let Some(mut app) = common::headless_app(settings) else { return };
    // A crate standing on the ground, its top 0.8 m up, well above the snow.
    let crate_ = app.world_mut().spawn((SnowCatcher::cuboid(Vec3::new(1.0, 0.8, 1.0)), Transform::from_xyz(0.0, 0.4, 0.0))).id();
    let frames = 120;
    for _ in 0..frames {
        app.update();
    }
    app.world_mut().resource_mut::<SnowControl>().request_object_stats();
    let stats = until(&mut app, 5, |app| app.world_mut().resource_mut::<SnowControl>().take_object_stats()).expect("the stats within 5 frames");
    assert_eq!(stats.len(), 1);
    assert_eq!(stats[0].0, crate_);
    let top = stats[0].1;
    // Every frame that ran fell on it (the first frames' objects are laid out before their snow).
    let fallen = RATE * (frames + 5) as f32 / 60.0;
    assert!(top.mean_m > 0.8 * RATE * frames as f32 / 60.0 && top.mean_m < 1.1 * fallen, "the crate's top holds {} m, about {fallen} m fell", top.mean_m);
    assert!(top.covered_fraction > 0.95, "the crate's top is {} covered", top.covered_fraction);
}
