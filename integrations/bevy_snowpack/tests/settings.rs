//! Settings changed after startup reach the snow: a trench that stays as
//! pressed while the refill is off fills in once the main world turns the
//! refill on; the technique switches (settings that size the snow make a
//! new world instead: tests/world_switch.rs).

mod common;

use bevy::prelude::*;
use bevy_snowpack::prelude::*;
use snowpack::low_level::SnowInspect;

#[test]
fn changed_settings_reach_the_snow() {
    let Some(mut app) = common::headless_app(common::test_settings()) else { return };
    // A box pressed into the snow at (1, -1), its bottom 0.1 m above the ground, then taken away.
    let pressing = app.world_mut().spawn((SnowDeformer::Box { half_extents: Vec3::splat(0.4) }, Transform::from_xyz(1.0, 0.5, -1.0))).id();
    for _ in 0..5 {
        app.update();
    }
    app.world_mut().despawn(pressing);
    for _ in 0..3 {
        app.update();
    }
    let pressed = common::snow_heights(&app)(1.0, -1.0);
    assert!((pressed - 0.1).abs() < 0.01, "the box pressed the snow to {pressed} m, want 0.1 m");

    // No refill (the settings at start): the trench stays.
    for _ in 0..30 {
        app.update();
    }
    let kept = common::snow_heights(&app)(1.0, -1.0);
    assert!((kept - pressed).abs() < 1e-3, "without refill the trench went from {pressed} m to {kept} m");

    // The game turns the refill on and switches the technique.
    {
        let mut settings = app.world_mut().resource_mut::<SnowpackSettings>();
        settings.params.refill_m_per_s = 0.2;
        settings.params.technique = Technique::Combined;
    }
    for _ in 0..30 {
        app.update();
    }
    let refilled = common::snow_heights(&app)(1.0, -1.0);
    // 0.2 m/s over about half a second: about 0.1 m back in the trench (frames in flight make it a little less).
    assert!(refilled > kept + 0.05 && refilled < 0.4 + 1e-3, "with refill the trench went from {kept} m to {refilled} m, want about 0.1 m more");
    let state = common::render_state(&app);
    let snow = state.deformation();
    assert_eq!(snow.technique(), Technique::Combined, "the technique was not switched");
    assert!((snow.params().refill_m_per_s - 0.2).abs() < 1e-6);
    // Live changes keep the world: no new one was made.
    assert_eq!(state.generation(), 0);
}
