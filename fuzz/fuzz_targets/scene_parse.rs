//! Any text as a scene file: a scene or a `SceneError` naming the key, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = snowpack_scene::Scene::parse(text, std::path::Path::new("fuzz.toml"));
    }
});
