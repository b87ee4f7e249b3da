//! The snow characters carry (`snow_coat.wgsl`): the pass equals its CPU
//! twin on random poses and snow, and through `SnowDeformation` a character
//! wading in snow gets snow on what is under the surface and none above,
//! snowfall covers what faces up and not what faces down nor what is under a
//! roof, and melting and running lose it at the set rates.

use glam::{DVec2, Mat4, Quat, Vec3};
use snowpack::SkinnedMesh;
use snowpack::low_level::SkinnedMeshExt;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::frame::FrameContext;
use snowpack::low_level::gpu::{GpuTimer, read_buffer};
use snowpack::low_level::skin::coat::{CoatGround, SnowCoatParams, SnowCoatPass};
use snowpack::low_level::skin::skinning::SkinningPass;
use snowpack::{CoatSettings, Deformer, GpuContext, NoiseTerrain, SkinnedId, SkinnedPose, SnowDeformation, SnowFrame, SnowParams, TerrainSource};
use snowpack::{ObjectShape, SnowObject, Snowfall};
use snowpack_testkit::cpu;
use snowpack_testkit::cpu::snow_coat::CoatGroundData;
use snowpack_testkit::testing::{self, Rng};

fn floats(bytes: &[u8]) -> Vec<f32> {
    bytemuck::pod_collect_to_vec(bytes)
}

fn vec3s(bytes: &[u8]) -> Vec<Vec3> {
    floats(bytes).chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect()
}

fn random_settings(rng: &mut Rng) -> CoatSettings {
    CoatSettings {
        cling_per_s: rng.range(0.5, 5.0),
        cap_m: rng.range(0.01, 0.05),
        melt_m_per_s: rng.range(0.0, 0.01),
        shake_speed_m_per_s: rng.range(0.5, 3.0),
        shake_per_s: rng.range(0.5, 4.0),
        wade_radius_m: rng.range(0.0, 0.5),
    }
}

#[test]
fn gpu_coat_matches_its_cpu_twin_on_random_poses_and_snow() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("coat twin");
    let mut rng = Rng::new(seed);
    let params = SnowParams {
        extent_m: 16.0,
        resolution: 128,
        depth_m: rng.range(0.2, 0.6),
        snowfall: Some(Snowfall { rate_m_per_s: 0.05, max_m: 0.5, ..Snowfall::default() }),
        // The wading reads the window's stored ground, or evaluates it (a coin per seed).
        store_ground: rng.next_u64().is_multiple_of(2),
        ..SnowParams::default()
    };
    eprintln!("coat twin: the ground {}", if params.store_ground { "stored" } else { "evaluated" });
    let terrain = TerrainSource::Noise(NoiseTerrain { seed: rng.next_u64() as u32, amplitude_m: 0.5, wavelength_m: 8.0, base_m: 0.0 });
    let center = DVec2::new(f64::from(rng.range(-50.0, 50.0)), f64::from(rng.range(-50.0, 50.0)));
    let mut snow = SnowDeformation::new(ctx, params.clone(), terrain.clone(), center).expect("window");
    // Pressed snow with trails, so the wading reads varied heights.
    let spheres: Vec<Deformer> = (0..30)
        .map(|_| {
            let (x, z) = (center.x as f32 + rng.range(-3.0, 3.0), center.y as f32 + rng.range(-3.0, 3.0));
            Deformer::Sphere { center: Vec3::new(x, terrain.height_at(x, z) + rng.range(0.1, 0.5), z), radius: rng.range(0.1, 0.5) }
        })
        .collect();
    for _ in 0..4 {
        snow.step(ctx, &spheres, 1.0 / 60.0).expect("frame");
    }
    snow.finish(ctx).expect("finish");
    let res = snow.resources();
    let origin = snow.origin_texel().expect("placed");
    let corner = snow.origin_m().expect("placed");
    let origin = [origin[0] as i32, origin[1] as i32];
    let terrain_plane = cpu::window::ground_plane(&terrain, origin, params.resolution, params.texel_m());
    let snow_words: Vec<u32> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &res.snow).expect("snow"));
    let fallen = floats(&read_buffer(ctx, &res.fallen).expect("fallen"));
    let ground_data = CoatGroundData { terrain: &terrain_plane, snow: &snow_words, fallen: &fallen, sky: None };
    let no_sky = snowpack::low_level::height_depth::sky_depth_texture(&ctx.device, 1).create_view(&wgpu::TextureViewDescriptor::default());
    let ground = CoatGround { window: &res.bindings, sky: &no_sky };

    let skinning = SkinningPass::new(&ctx.device);
    let mut coat_pass = SnowCoatPass::new(&ctx.device, &res.bindings, &res.terrain_constants());
    coat_pass.reserve(&ctx.device, 1);
    let joint_count = 6;
    let n = 1500;
    let mut mesh = SkinnedMesh::default();
    for _ in 0..n {
        mesh.positions.push(Vec3::new(rng.range(-1.0, 1.0), rng.range(-0.5, 1.0), rng.range(-1.0, 1.0)));
        mesh.joints.push([0; 4].map(|_| (rng.next_u64() % joint_count as u64) as u16));
        let w = [0; 4].map(|_| rng.range(0.0, 1.0));
        let sum: f32 = w.iter().sum();
        mesh.weights.push(w.map(|x| x / sum));
    }
    mesh.indices = (0..(n / 3 * 3) as u32).collect();
    let instance = skinning.instance(&ctx.device, &ctx.queue, &mesh, joint_count).expect("valid mesh");
    let start: Vec<f32> = (0..n).map(|_| if rng.range(0.0, 1.0) < 0.3 { 0.0 } else { rng.range(0.0, 0.04) }).collect();
    ctx.queue.write_buffer(&instance.coat, 0, bytemuck::cast_slice(&start));
    let mut coat = start;
    let mut previous: Vec<Vec3> = Vec::new();
    let (cx, cz) = (center.x as f32, center.y as f32);
    for round in 0..3 {
        let joints: Vec<Mat4> = (0..joint_count)
            .map(|_| Mat4::from_rotation_translation(Quat::from_rotation_y(rng.range(-0.5, 0.5)), Vec3::new(0.0, rng.range(-0.1, 0.1), rng.range(-0.2, 0.2))))
            .collect();
        let model = Mat4::from_translation(Vec3::new(cx + rng.range(-2.0, 2.0), terrain.height_at(cx, cz) + rng.range(0.0, 0.5), cz + rng.range(-2.0, 2.0)));
        let settings = random_settings(&mut rng);
        let p = SnowCoatParams {
            origin,
            resolution: params.resolution,
            vertex_count: n as u32,
            corner_m: [corner.x as f32, corner.y as f32],
            texel_m: params.texel_m(),
            depth_m: params.depth_m,
            dt_s: rng.range(0.005, 0.05),
            fall_m: if round == 1 { 0.0 } else { rng.range(0.0, 0.01) },
            use_fallen: 1,
            has_previous: u32::from(round > 0),
            teleport_m: rng.range(0.5, 3.0),
            ..SnowCoatParams::default()
        }
        .with_settings(&settings);
        let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        let mut cx = FrameContext::new(ctx, &mut encoder, &mut timer);
        skinning.record(&mut cx, &instance, &joints, model);
        coat_pass.record(&mut cx, 0, &instance, ground, &p);
        ctx.queue.submit([encoder.finish()]);
        let gpu_positions = vec3s(&read_buffer(ctx, &instance.skinned).expect("positions"));
        let gpu_normals = vec3s(&read_buffer(ctx, &instance.normals).expect("normals"));
        let gpu_coat = floats(&read_buffer(ctx, &instance.coat).expect("coat"));
        // The normals are the skinning twin's.
        let cpu_normals = cpu::skinning::skin_normals(&mesh, &mesh.vertex_normals(), &joints, model);
        let worst_normal = cpu_normals.iter().zip(&gpu_normals).map(|(a, b)| (*a - *b).length()).fold(0.0f32, f32::max);
        assert!(worst_normal < 1e-4, "seed {seed}, round {round}: skinned normals differ by {worst_normal}");
        if previous.is_empty() {
            previous.clone_from(&gpu_positions);
        }
        let cpu_coat = cpu::snow_coat::snow_coat(&p, &ground_data, &gpu_positions, &previous, &gpu_normals, &coat);
        let mut changed = 0;
        for (v, (g, c)) in gpu_coat.iter().zip(&cpu_coat).enumerate() {
            assert!((g - c).abs() < 1e-5, "seed {seed}, round {round}, vertex {v}: GPU {g} vs CPU {c} (before {})", coat[v]);
            assert!(*g >= 0.0 && g.is_finite());
            changed += usize::from((g - coat[v]).abs() > 1e-6);
        }
        assert!(changed > n / 10, "seed {seed}, round {round}: only {changed} vertices changed; the test would not see the pass");
        previous = gpu_positions;
        coat = gpu_coat;
    }
}

/// A test character: one joint, three parts a few centimetres wide, each
/// two triangles: a leg (a vertical strip from `0` to `leg_top` m), a belly
/// facing down at `belly` m and a back facing up at `back` m. The returned
/// ranges are the vertex indices of each part.
struct Figure {
    mesh: SkinnedMesh,
    leg: std::ops::Range<usize>,
    belly: std::ops::Range<usize>,
    back: std::ops::Range<usize>,
}

fn figure(leg_top: f32, belly: f32, back: f32) -> Figure {
    let mut mesh = SkinnedMesh::default();
    let mut quad = |corners: [Vec3; 4]| {
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(corners);
        mesh.joints.extend([[0u16; 4]; 4]);
        mesh.weights.extend([[1.0, 0.0, 0.0, 0.0]; 4]);
        mesh.indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        base as usize..base as usize + 4
    };
    // A leg: a strip in the x-y plane, subdivided in height so vertices lie below and above the snow.
    let steps = 8;
    let mut leg_end = 0;
    for k in 0..steps {
        let (y0, y1) = (leg_top * k as f32 / steps as f32, leg_top * (k + 1) as f32 / steps as f32);
        leg_end = quad([Vec3::new(-0.03, y0, 0.0), Vec3::new(0.03, y0, 0.0), Vec3::new(0.03, y1, 0.0), Vec3::new(-0.03, y1, 0.0)]).end;
    }
    let leg = 0..leg_end;
    // (b - a) x (c - a) points down for the belly ((x, 0, 0) x (x, 0, z) = -y) and up for the back.
    let belly = quad([Vec3::new(-0.2, belly, -0.1), Vec3::new(0.2, belly, -0.1), Vec3::new(0.2, belly, 0.1), Vec3::new(-0.2, belly, 0.1)]);
    let back = quad([Vec3::new(-0.2, back, -0.1), Vec3::new(-0.2, back, 0.1), Vec3::new(0.2, back, 0.1), Vec3::new(0.2, back, -0.1)]);
    let normals = mesh.vertex_normals();
    assert!(belly.clone().all(|v| normals[v].y < -0.99) && back.clone().all(|v| normals[v].y > 0.99), "the figure's normals");
    Figure { mesh, leg, belly, back }
}

struct Stage {
    snow: SnowDeformation,
    id: SkinnedId,
    figure: Figure,
}

fn stage(ctx: &GpuContext, depth_m: f32, snowfall: Option<Snowfall>, figure: Figure, settings: CoatSettings) -> Stage {
    let params = SnowParams { extent_m: 16.0, resolution: 128, depth_m, snowfall, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    let id = snow.add_skinned_mesh(ctx, &figure.mesh, 1).expect("mesh");
    snow.set_coat(id, settings).expect("settings");
    Stage { snow, id, figure }
}

impl Stage {
    /// `frames` frames of 1/60 s with the figure at `at(frame)`.
    fn run(&mut self, ctx: &GpuContext, frames: u32, at: impl Fn(u32) -> Vec3) {
        let joints = [Mat4::IDENTITY];
        for f in 0..frames {
            let poses = [SkinnedPose { mesh: self.id, joints: &joints, model: Mat4::from_translation(at(f)) }];
            self.snow.step_frame(ctx, &SnowFrame::new(1.0 / 60.0, &[]).with_poses(&poses)).expect("frame");
        }
        self.snow.finish(ctx).expect("finish");
    }

    fn coat(&self, ctx: &GpuContext) -> Vec<f32> {
        self.snow.read_coat(ctx, self.id).expect("coat")
    }
}

fn quiet() -> CoatSettings {
    CoatSettings { melt_m_per_s: 0.0, shake_per_s: 0.0, ..CoatSettings::default() }
}

#[test]
fn a_character_standing_in_snow_gets_snow_below_the_surface_and_none_above() {
    let Some(ctx) = testing::gpu() else { return };
    let depth = 0.4;
    let mut s = stage(ctx, depth, None, figure(0.7, 0.75, 0.8), quiet());
    s.run(ctx, 60, |_| Vec3::ZERO);
    let coat = s.coat(ctx);
    let cap = quiet().cap_m;
    let mut below = 0;
    for v in s.figure.leg.clone() {
        let y = s.figure.mesh.positions[v].y;
        if y < depth - 0.05 {
            // 5 cm or more under the snow, gaining at least 2 cm a second: capped within the second.
            assert!(coat[v] > 0.9 * cap, "leg vertex at {y} m (snow at {depth} m) carries {} m", coat[v]);
            below += 1;
        } else if y > depth + 0.01 {
            assert_eq!(coat[v], 0.0, "leg vertex at {y} m, above the snow at {depth} m, carries {} m", coat[v]);
        }
    }
    assert!(below >= 6, "{below} leg vertices under the snow");
    for v in s.figure.belly.clone().chain(s.figure.back.clone()) {
        assert_eq!(coat[v], 0.0, "body vertex {v} above the snow and with no snowfall carries {} m", coat[v]);
    }
}

#[test]
fn snowfall_covers_what_faces_up_and_not_what_faces_down_nor_what_a_roof_covers() {
    let Some(ctx) = testing::gpu() else { return };
    let rate = 0.01;
    let fall = Snowfall { rate_m_per_s: rate, flutter_deg: 0.0, noise: 0.0, ..Snowfall::default() };
    let settings = CoatSettings { cap_m: 1.0, ..quiet() };
    // A still character in the open, 1 m above snow 10 cm deep: nothing to wade in.
    let lift = Vec3::new(-3.0, 1.0, 0.0);
    let mut open = stage(ctx, 0.1, Some(fall.clone()), figure(0.2, 0.3, 0.4), settings);
    open.run(ctx, 120, |_| lift);
    let coat = open.coat(ctx);
    let expected = rate * 2.0;
    for v in open.figure.back.clone() {
        assert!((coat[v] - expected).abs() < 0.1 * expected, "the back gained {} m in 2 s of {rate} m/s snowfall (expected {expected})", coat[v]);
    }
    for v in open.figure.belly.clone() {
        assert_eq!(coat[v], 0.0, "the belly faces down and gained {} m", coat[v]);
    }
    // The same under a roof: a box 1 m above the back.
    let mut covered = stage(ctx, 0.1, Some(fall), figure(0.2, 0.3, 0.4), settings);
    let roof = SnowObject {
        name: "roof".into(),
        shape: ObjectShape::Box { size_m: Vec3::new(2.0, 0.1, 2.0) },
        position: lift + Vec3::new(0.0, 1.4, 0.0),
        rotation: Quat::IDENTITY,
        dilate: true,
    };
    covered.snow.set_objects(ctx, &[roof]).expect("roof");
    covered.run(ctx, 120, |_| lift);
    let coat = covered.coat(ctx);
    for v in covered.figure.back.clone() {
        assert!(coat[v] < 0.05 * expected, "the back under a roof gained {} m (in the open: {expected})", coat[v]);
    }
}

#[test]
fn the_coat_melts_and_shakes_off_at_the_set_rates() {
    let Some(ctx) = testing::gpu() else { return };
    let (melt, shake) = (0.004, 2.0);
    let settings = CoatSettings { cap_m: 0.05, melt_m_per_s: melt, shake_speed_m_per_s: 3.0, shake_per_s: shake, ..CoatSettings::default() };
    let high = Vec3::new(0.0, 2.0, 0.0);
    let start = 0.04f32;
    // Standing still, above the snow: only melting.
    let mut still = stage(ctx, 0.1, None, figure(0.2, 0.3, 0.4), settings);
    let n = still.figure.mesh.positions.len();
    still.run(ctx, 1, |_| high);
    ctx.queue.write_buffer(still.snow.coat_buffer(still.id).expect("buffer"), 0, bytemuck::cast_slice(&vec![start; n]));
    still.run(ctx, 60, |_| high);
    for c in still.coat(ctx) {
        assert!((c - (start - melt)).abs() < 2e-4, "after 1 s of melting at {melt} m/s: {c} m (from {start})");
    }
    // Running at 6 m/s, above the shaking speed: the coat also falls by exp(-rate t).
    let mut running = stage(ctx, 0.1, None, figure(0.2, 0.3, 0.4), CoatSettings { melt_m_per_s: 0.0, ..settings });
    running.run(ctx, 1, |_| high);
    ctx.queue.write_buffer(running.snow.coat_buffer(running.id).expect("buffer"), 0, bytemuck::cast_slice(&vec![start; n]));
    running.run(ctx, 60, |f| high + Vec3::X * (6.0 * (f + 1) as f32 / 60.0));
    let expected = start * (-shake).exp();
    for c in running.coat(ctx) {
        assert!((c - expected).abs() < 0.03 * expected, "after 1 s at 6 m/s shaking at {shake}/s: {c} m (expected {expected})");
    }
    // Walking at 1 m/s, below the shaking speed: nothing lost.
    let mut walking = stage(ctx, 0.1, None, figure(0.2, 0.3, 0.4), CoatSettings { melt_m_per_s: 0.0, ..settings });
    walking.run(ctx, 1, |_| high);
    ctx.queue.write_buffer(walking.snow.coat_buffer(walking.id).expect("buffer"), 0, bytemuck::cast_slice(&vec![start; n]));
    walking.run(ctx, 60, |f| high + Vec3::X * ((f + 1) as f32 / 60.0));
    for c in walking.coat(ctx) {
        assert_eq!(c, start, "walking below the shaking speed lost snow");
    }
}
