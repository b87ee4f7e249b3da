//! The bundled fox (`assets/Fox.glb`) read as a skinned, animated character.

use std::path::Path;

use glam::{Mat4, Vec3};
use snowpack_scene::gltf_file::GltfFile;

fn fox_path() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/Fox.glb")
}

#[test]
fn the_fox_has_a_skin_and_three_clips() {
    let model = GltfFile::open(&fox_path()).expect("open").skinned_model().expect("skinned model");
    assert_eq!(model.mesh.positions.len(), 1728);
    assert_eq!(model.mesh.indices.len(), 1728);
    assert_eq!(model.skeleton.joints.len(), 24);
    let names: Vec<&str> = model.clips.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["Survey", "Walk", "Run"]);
    assert!(model.clips.iter().all(|c| c.duration > 0.5 && c.duration < 10.0), "{:?}", model.clips.iter().map(|c| c.duration).collect::<Vec<_>>());
    // The bind pose is the rest pose: skinning at rest gives the mesh back.
    let s = &model.skeleton;
    let joints = s.joint_matrices(&s.globals(&s.rest_pose()));
    let skinned = snowpack_testkit::cpu::skinning::skin(&model.mesh, &joints, Mat4::IDENTITY);
    let worst = skinned.iter().zip(&model.mesh.positions).map(|(a, b)| (*a - *b).length()).fold(0.0f32, f32::max);
    assert!(worst < 0.05, "rest pose moves vertices by {worst} units (of a 79-unit fox)");
}

#[test]
fn walking_lifts_and_plants_each_foot() {
    let model = GltfFile::open(&fox_path()).expect("open").skinned_model().expect("skinned model");
    let s = &model.skeleton;
    let walk = &model.clips[model.clip("Walk").expect("Walk")];
    for foot in ["b_LeftFoot02", "b_RightFoot02", "b_LeftHand", "b_RightHand"] {
        let node = s.find(foot).unwrap_or_else(|| panic!("no {foot}"));
        // Foot heights over one cycle, in metres at the fox's 0.01 scale.
        let heights: Vec<f32> = (0..60)
            .map(|k| {
                let locals = walk.sample(s, walk.duration * k as f32 / 60.0, true);
                s.globals(&locals)[node].transform_point3(Vec3::ZERO).y * 0.01
            })
            .collect();
        let (lo, hi) = heights.iter().fold((f32::MAX, f32::MIN), |(a, b), &h| (a.min(h), b.max(h)));
        assert!(hi - lo > 0.02, "{foot} barely lifts over a walk cycle: {lo:.3}..{hi:.3} m");
        assert!(lo > -0.05 && lo < 0.15, "{foot} is not near the ground at its lowest: {lo:.3} m");
    }
}

#[test]
fn a_truncated_file_is_an_error_not_a_panic() {
    let bytes = std::fs::read(fox_path()).expect("read");
    let dir = std::env::temp_dir().join(format!("snowpack-fox-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    for cut in [10, 1000, bytes.len() / 2, bytes.len() - 7] {
        let path = dir.join("cut.glb");
        std::fs::write(&path, &bytes[..cut]).expect("write");
        let err = GltfFile::open(&path).and_then(|f| f.skinned_model()).expect_err("truncated");
        assert!(err.contains("cut.glb") || err.contains("buffer"), "cut at {cut}: {err}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn walk_and_run_have_the_strides_of_a_fox() {
    let model = GltfFile::open(&fox_path()).expect("open").skinned_model().expect("skinned model");
    let s = &model.skeleton;
    let feet = snowpack::low_level::skin::feet::find_feet(s, &model.clips, &snowpack::low_level::skin::feet::DEFAULT_FOOT_PATTERNS);
    let speed = |name: &str| snowpack::low_level::skin::feet::stride_speed(s, &model.clips[model.clip(name).expect(name)], &feet) * 0.01;
    let (walk, run) = (speed("Walk"), speed("Run"));
    eprintln!("walk {walk} m/s, run {run} m/s, durations {:?}", model.clips.iter().map(|c| c.duration).collect::<Vec<_>>());
    assert!(walk > 0.5 && walk < 2.0, "walk {walk} m/s");
    assert!(run > 1.5 * walk && run < 8.0, "run {run} m/s vs walk {walk}");
    // Paws down on average: a walk has two or three, a run fewer, standing all four.
    let down = |name: &str| snowpack::low_level::skin::feet::mean_feet_down(s, &model.clips[model.clip(name).expect(name)], &feet);
    let (walk, run, stand) = (down("Walk"), down("Run"), down("Survey"));
    eprintln!("paws down: walk {walk}, run {run}, survey {stand}");
    assert!((2.0..3.2).contains(&walk), "walk: {walk} paws down");
    assert!(run < walk && run > 1.0, "run: {run} paws down, walk {walk}");
}

fn fox_scene(extra: &str, path: &str) -> snowpack_scene::Scene {
    let text = format!(
        "[snow]\nextent_m = 12.0\nresolution = 256\ndepth_m = 0.2\n{extra}\n[[actor]]\nkind = \"gltf\"\nfile = \"Fox.glb\"\nanimation = \"Survey\"\n\
         gaits = [\"Walk\", \"Run\"]\nscale = 0.01\nplacement = \"snow\"\npath = {path}\n"
    );
    snowpack_scene::Scene::parse(&text, &fox_path()).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn the_fox_walks_then_runs_with_a_cross_fade_and_matched_playback_speed() {
    // 0.9 m/s for 4 s, then 2.4 m/s (past the 8 s simulated).
    let scene = fox_scene("", "[[0.0, 0.0, 0.0, 0.0], [3.6, 0.0, 0.0, 4.0], [15.6, 0.0, 0.0, 9.0]]");
    let snowpack_scene::ShapeSpec::Gltf(g) = &scene.actors[0].shape else { panic!("not a gltf actor") };
    let clip = |name: &str| g.model.clip(name).expect(name);
    let stride = |c: usize| g.gaits.iter().find(|x| x.clip == c).expect("gait").stride_m_per_s;
    let mut world = snowpack_scene::World::new(&scene);
    let dt = 1.0 / 60.0;
    let mut seen = Vec::new();
    for frame in 0..480 {
        world.step(dt);
        let (_, c, speed) = world.clips()[0];
        let t = (frame + 1) as f32 * dt;
        if t > 0.5 && t < 3.9 {
            assert_eq!(c, clip("Walk"), "t = {t}");
            assert!((speed - 0.9 / stride(c)).abs() < 0.02, "walk plays at {speed}");
        }
        if t > 4.1 && t < 7.95 {
            assert_eq!(c, clip("Run"), "t = {t}");
            assert!((speed - 2.4 / stride(c)).abs() < 0.02, "run plays at {speed} at t = {t}, {}", stride(c));
        }
        if seen.last() != Some(&c) {
            seen.push(c);
        }
    }
    assert_eq!(seen, [clip("Walk"), clip("Run")], "one change of gait");
    // Standing still: the standing clip.
    let still = fox_scene("", "[[0.0, 0.0, 0.0, 0.0]]");
    let mut world = snowpack_scene::World::new(&still);
    world.step(dt);
    assert_eq!(world.clips()[0].1, clip("Survey"));
}

#[test]
fn a_fox_on_soft_snow_stands_lower_than_on_hard_snow_and_never_below_the_ground() {
    let height = |hardness: f32, depth: f32| {
        let mut scene = fox_scene(&format!("hardness_kpa = {hardness}\n"), "[[0.0, 0.0, 0.0, 0.0], [3.6, 0.0, 0.0, 4.0]]");
        scene.snow.depth_m = depth;
        let mut world = snowpack_scene::World::new(&scene);
        let mut ys = Vec::new();
        for _ in 0..180 {
            world.step(1.0 / 60.0);
            ys.push(world.actor_position(0).expect("fox").y);
        }
        ys.iter().sum::<f32>() / ys.len() as f32
    };
    let (soft, hard) = (height(2.0, 0.2), height(50.0, 0.2));
    // 6 kg on two to three 35 cm² paws is 5.6 to 8.4 kPa: in 2 kPa snow the
    // paws sink 0.15 to 0.16 m of the 0.2 m, in 50 kPa snow 0.02 to 0.03 m.
    assert!(hard - soft > 0.1, "soft {soft:.3} m, hard {hard:.3} m");
    assert!(hard > 0.15 && hard < 0.2, "hard {hard:.3} m");
    assert!(soft > 0.0 && soft < 0.08, "soft {soft:.3} m");
    // Deep powder and a heavy load: never below the terrain.
    assert!(height(0.01, 0.2) > -0.01);
}

#[test]
fn a_steered_fox_walks_where_it_is_steered_and_stands_on_the_snow_after_a_teleport() {
    let scene = fox_scene("", "[[0.0, 0.0, 0.0, 0.0]]");
    let mut world = snowpack_scene::World::new(&scene);
    let dt = 1.0 / 60.0;
    for _ in 0..120 {
        assert!(world.steer(0, glam::Vec2::new(0.0, 1.0)));
        world.step(dt);
    }
    let p = world.actor_position(0).expect("fox");
    assert!((p.z - 2.0).abs() < 0.05 && p.x.abs() < 1e-4, "steered 2 s at 1 m/s along +z, at {p}");
    let before = p.y;
    world.teleport(0, glam::Vec2::new(3.0, -1.0));
    let q = world.actor_position(0).expect("fox");
    assert!((q.x - 3.0).abs() < 1e-4 && (q.z + 1.0).abs() < 1e-4, "{q}");
    // Same flat snow, same gait: the same height within the walk's bob.
    assert!((q.y - before).abs() < 0.03, "{} after the teleport, {before} before", q.y);
    assert!(!world.take_footsteps().is_empty(), "no footsteps while walking");
}
