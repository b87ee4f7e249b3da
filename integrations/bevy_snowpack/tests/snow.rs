//! The plugin's snow against the library's own: the same scripted ball pressed
//! through Bevy's render world and through a standalone `SnowDeformation`
//! gives the same heights, and point queries asked through `SnowQuery`
//! answer what the library answers.

mod common;

use bevy::prelude::*;
use bevy_snowpack::{FootKind, SnowDeformer, SnowFoot, SnowFootstep, SnowQuery, SnowpackSettings};
use snowpack::low_level::SnowInspect;
use snowpack::{AdapterRequest, Deformer, GpuContext, SnowDeformation, SnowFrame, SnowParams, TerrainSource};

const DT: f32 = 1.0 / 60.0;
const RADIUS: f32 = 0.4;
/// Frames the ball rolls, then frames it rests while the queries come back.
const ROLL: u32 = 40;

/// The ball's scripted path: across the window, its bottom 0.15 m above the ground.
fn path(k: u32) -> Vec3 {
    let t = k.min(ROLL) as f32 / ROLL as f32;
    Vec3::new(-2.5 + 5.0 * t, 0.15 + RADIUS, 0.3 * (6.0 * t).sin())
}

fn settings() -> SnowpackSettings {
    SnowpackSettings {
        // No refill: the trench stays as pressed, whatever the frame times.
        params: SnowParams { extent_m: 8.0, resolution: 128, depth_m: 0.4, refill_m_per_s: 0.0, ..SnowParams::default() },
        terrain: TerrainSource::Flat { height_m: 0.0 },
        center: Vec2::ZERO,
        fixed_dt_s: Some(DT),
        store: None,
    }
}

#[derive(Component)]
struct Ball;

/// Where the ball was each frame, as the main world placed it.
#[derive(Resource, Default)]
struct Placed(Vec<Vec3>);

fn roll(mut frame: Local<u32>, mut ball: Single<&mut Transform, With<Ball>>, mut placed: ResMut<Placed>) {
    ball.translation = path(*frame);
    placed.0.push(ball.translation);
    *frame += 1;
}

#[test]
fn plugin_snow_and_queries_equal_the_library() {
    let Some(mut app) = common::headless_app(settings()) else { return };
    app.init_resource::<Placed>().add_systems(Update, roll);
    app.world_mut().spawn((Ball, SnowDeformer::Sphere { radius: RADIUS }, Transform::from_translation(path(0))));

    for _ in 0..=ROLL {
        app.update();
    }
    // Under the path, beside it, and off the trail.
    let points = [Vec2::new(0.0, 0.0), Vec2::new(-1.2, path(16).z), Vec2::new(1.5, 2.0), Vec2::new(-3.0, -3.0)];
    let ticket = app.world_mut().resource_mut::<SnowQuery>().ask(&points);
    let mut answers = None;
    for _ in 0..8 {
        app.update();
        answers = app.world_mut().resource_mut::<SnowQuery>().take(ticket);
        if answers.is_some() {
            break;
        }
    }
    let answers = answers.expect("the query was answered within 8 frames");
    assert_eq!(answers.points, points);

    let state = common::render_state(&app);
    let plugin_snow = state.deformation().read_snow(state.context()).expect("read the plugin's snow");
    // The CPU twin of the query pass over the plugin's snow as read back (the ball has
    // rested, unchanged, since before the gather; no refill), asked the same points.
    let twin = {
        let snow = state.deformation();
        let (ctx, res, params) = (state.context(), snow.resources(), snow.params().clone());
        let origin = snow.origin_texel().expect("placed");
        let corner = snow.origin_m().expect("placed");
        let qp = snowpack::low_level::deform::query::QueryParams {
            origin: [origin[0] as i32, origin[1] as i32],
            resolution: params.resolution,
            count: points.len() as u32,
            texel_m: params.texel_m(),
            depth_m: params.depth_m,
            use_fallen: 0,
            _pad: 0,
        };
        let local: Vec<[f32; 2]> = points.iter().map(|p| [(f64::from(p.x) - corner.x) as f32, (f64::from(p.y) - corner.y) as f32]).collect();
        let words = bytemuck::pod_collect_to_vec::<u8, u32>(&snowpack::low_level::gpu::read_buffer(ctx, &res.snow).expect("snow words"));
        let fallen = bytemuck::pod_collect_to_vec::<u8, f32>(&snowpack::low_level::gpu::read_buffer(ctx, &res.fallen).expect("fallen"));
        let ground = snowpack_testkit::cpu::window::ground_plane(snow.terrain(), qp.origin, params.resolution, params.texel_m());
        let packed = bytemuck::pod_collect_to_vec::<u8, u32>(&snowpack::low_level::gpu::read_buffer(ctx, &res.packed).expect("packed snow"));
        snowpack_testkit::cpu::query::query(&qp, &local, &ground, (&words, &fallen, &packed))
    };
    let frames = state.deformation().frame() as usize;
    let placed = &app.world().resource::<Placed>().0;
    assert!(frames >= placed.len() - 2 && frames <= placed.len(), "{frames} frames encoded for {} updates", placed.len());

    // The library on its own device: the same frames, the same ball, then the same query.
    let ctx = GpuContext::new_headless(&AdapterRequest::from_env()).expect("an adapter for the standalone library");
    let s = settings();
    let mut snow = SnowDeformation::new(&ctx, s.params.clone(), s.terrain.clone(), glam::DVec2::ZERO).expect("standalone deformation");
    let last = placed.len() - frames;
    for (k, p) in placed[last..].iter().enumerate() {
        let ball = [Deformer::Sphere { center: *p, radius: RADIUS }];
        let frame = SnowFrame::new(DT, &ball);
        snow.step_frame(&ctx, &if k + 1 == frames { frame.with_queries(&points) } else { frame }).expect("standalone step");
    }
    snow.finish(&ctx).expect("standalone finish");
    let library_snow = snow.read_snow(&ctx).expect("read the library's snow");

    assert_eq!(plugin_snow.len(), library_snow.len());
    let worst = plugin_snow.iter().zip(&library_snow).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    assert!(worst < 1e-3, "plugin and library snow differ by {worst} m");
    // Not trivially equal: the ball pressed a trench down to 0.15 m.
    let lowest = plugin_snow.iter().copied().fold(f32::INFINITY, f32::min);
    assert!((lowest - 0.15).abs() < 0.02, "trench bottom {lowest} m, expected 0.15 m");

    for (k, (ours, cpu)) in answers.samples.iter().zip(twin.iter().map(|c| c.sample())).enumerate() {
        let (ours, cpu) = (ours.expect("inside the window"), cpu.expect("inside the window on the CPU too"));
        for (what, a, b) in [("height", ours.height_m, cpu.height_m), ("surface", ours.surface_m, cpu.surface_m), ("rest", ours.rest_m, cpu.rest_m)] {
            assert!((a - b).abs() < 1e-4, "point {k} {what}: through Bevy {a}, CPU twin {b}");
        }
        assert!((ours.normal - cpu.normal).length() < 1e-3, "point {k} normal: through Bevy {}, CPU twin {}", ours.normal, cpu.normal);
    }
    let library = snow.point_answers().expect("the library answered");
    for (k, (ours, theirs)) in answers.samples.iter().zip(&library.samples).enumerate() {
        let (ours, theirs) = (ours.expect("inside the window"), theirs.expect("inside the window"));
        for (what, a, b) in [
            ("height", ours.height_m, theirs.height_m),
            ("surface", ours.surface_m, theirs.surface_m),
            ("terrain", ours.terrain_m, theirs.terrain_m),
            ("rest", ours.rest_m, theirs.rest_m),
        ] {
            assert!((a - b).abs() < 1e-3, "point {k} {what}: plugin {a}, library {b}");
        }
    }
    // Under the path the ball pressed the snow to 0.15 m; off the trail it is untouched.
    let under = answers.samples[0].unwrap();
    assert!((under.depth_m() - 0.15).abs() < 0.02 && under.compaction() > 0.5, "under the path: {under:?}");
    let off = answers.samples[3].unwrap();
    assert!((off.depth_m() - 0.4).abs() < 1e-3 && off.compaction() < 1e-3, "off the trail: {off:?}");
}

#[derive(Component)]
struct Paw;

/// A paw lowered onto the snow raises one footstep, with the depth and
/// sinkage the query answered; lifting it and lowering it again raises another.
#[test]
fn a_paw_coming_down_raises_a_footstep() {
    let Some(mut app) = common::headless_app(settings()) else { return };
    // Above the snow for 10 frames, down on the surface (0.4 m) for 10, up, then down again.
    let height = |k: u32| if (10..20).contains(&k) || (30..40).contains(&k) { 0.41 } else { 1.0 };
    app.add_systems(Update, move |mut frame: Local<u32>, mut paw: Single<&mut Transform, With<Paw>>| {
        paw.translation.y = height(*frame);
        *frame += 1;
    });
    app.world_mut().spawn((Paw, SnowFoot::new(FootKind::Paw), Transform::from_xyz(1.0, 1.0, -1.0)));
    let mut steps = Vec::new();
    for _ in 0..45 {
        app.update();
        let mut messages = app.world_mut().resource_mut::<Messages<SnowFootstep>>();
        steps.extend(messages.drain());
    }
    assert_eq!(steps.len(), 2, "one step per time the paw came down: {steps:?}");
    for s in &steps {
        assert_eq!(s.kind, FootKind::Paw);
        // On the displayed surface (f16 heights, within a centimetre of the 0.4 m rest).
        assert!((s.position - Vec3::new(1.0, 0.4, -1.0)).length() < 0.01, "{s:?}");
        assert!((s.depth_m - 0.4).abs() < 1e-3 && s.sinkage_m.abs() < 1e-3, "untouched snow under the paw: {s:?}");
    }
}
