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
    let skinned = snowpack::cpu::skinning::skin(&model.mesh, &joints, Mat4::IDENTITY);
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
