//! Any bytes as a glTF file (`.glb`), in every use a scene makes of one: a
//! mesh terrain, an accumulation `[[object]]` and a character `[[actor]]`.
//! Each is refused with an error naming the scene, the file and the key, or
//! loads and its world is built and stepped (`common::build_world`); never a
//! panic, a hang or a runaway allocation.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use snowpack_scene::gltf_file::GltfFile;

fuzz_target!(|data: &[u8]| {
    let dir = common::scratch("gltf_model");
    let file = dir.join("model.glb");
    // The bytes alone: refused naming the file, or every use tried.
    match GltfFile::from_bytes(data, &file) {
        Err(why) => assert!(why.contains("model.glb"), "the error does not name the file: {why}"),
        Ok(gltf) => {
            let _ = gltf.world_triangles(1.0);
            let _ = gltf.object_mesh(1.0);
            let _ = gltf.skinned_model();
        }
    }
    // As a scene uses it, through to the built world.
    std::fs::write(&file, data).expect("write model.glb");
    for (body, table) in [
        ("[terrain]\nkind = \"mesh\"\npath = \"model.glb\"\n", "[terrain]"),
        ("[[object]]\nname = \"o\"\nkind = \"gltf\"\nfile = \"model.glb\"\n", "[[object]][0]"),
        ("[[actor]]\nkind = \"gltf\"\nfile = \"model.glb\"\npath = [[0.0, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 2.0]]\n", "[[actor]][0]"),
    ] {
        match common::load(&dir, body) {
            // The save's round trip is scene_world's: here it would load the model twice more.
            Ok(scene) => common::build_world(&scene, false),
            Err(err) => common::assert_names(&err, "model.glb", table),
        }
    }
});
