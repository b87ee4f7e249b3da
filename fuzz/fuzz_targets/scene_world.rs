//! Any text as a scene file in `scenes/` (so the shipped scenes' relative
//! assets resolve: the mound's glTF, the fox, `builtin:` assets), loaded as
//! the program loads one and, when it loads, turned into what the program
//! builds before the GPU (`common::build_world`): the saved scene parses back
//! the same, the `World` is built and stepped with finite deformers, the
//! capture instances and the objects' atlas are made. Errors name the scene.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use snowpack_scene::Scene;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/fuzz.toml");
    match Scene::parse(text, &path) {
        Ok(scene) => common::build_world(&scene, true),
        Err(err) => assert!(err.to_string().contains("fuzz.toml"), "the error does not name the scene: {err}"),
    }
});
