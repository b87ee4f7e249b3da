//! Property tests of the scene parser: any text, and the shipped scenes with
//! any one value replaced by another of any type, give a scene or a
//! `SceneError` that names the file, never a panic. (`fuzz/`'s
//! `scene_parse` target runs the parser for longer on the nightly toolchain.)

use std::path::Path;

use proptest::prelude::*;
use snowpack_scene::Scene;

/// The shipped scenes, as text.
fn scenes() -> Vec<String> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut out: Vec<String> = std::fs::read_dir(&dir)
        .expect("scenes folder")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .map(|p| std::fs::read_to_string(p).expect("scene"))
        .collect();
    out.sort();
    out
}

/// TOML values of every type, including the awkward ones (huge, negative,
/// NaN, empty, nested, wrong shapes).
fn value() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<i64>().prop_map(|v| v.to_string()),
        any::<f64>().prop_map(|v| if v.is_finite() { format!("{v:?}") } else { "nan".to_owned() }),
        Just("inf".to_owned()),
        Just("-inf".to_owned()),
        Just("-0.0".to_owned()),
        Just("0".to_owned()),
        Just("1e300".to_owned()),
        Just("true".to_owned()),
        "[a-z_:.]{0,12}".prop_map(|s| format!("{s:?}")),
        Just("[]".to_owned()),
        Just("[[]]".to_owned()),
        Just("[1.0, 2.0]".to_owned()),
        Just("[[0.0, 0.0, 0.0, 0.0], [1.0, 1.0, 1.0, -1.0]]".to_owned()),
        Just("{ x = 1 }".to_owned()),
        Just("\"builtin:fox\"".to_owned()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn any_text_parses_or_is_an_error_naming_the_file(text in "[ -~\\n\\[\\]=\"#.]{0,400}") {
        if let Err(e) = Scene::parse(&text, Path::new("prop.toml")) {
            prop_assert!(e.to_string().contains("prop.toml"), "{e}");
        }
    }

    #[test]
    fn a_shipped_scene_with_one_value_replaced_parses_or_names_the_file(
        scene in any::<prop::sample::Index>(),
        line in any::<prop::sample::Index>(),
        v in value(),
    ) {
        let scenes = scenes();
        let text = &scenes[scene.index(scenes.len())];
        let lines: Vec<&str> = text.lines().collect();
        // Replace the value of one `key = value` line.
        let assignments: Vec<usize> = (0..lines.len()).filter(|&k| lines[k].contains(" = ") && !lines[k].trim_start().starts_with('#')).collect();
        prop_assume!(!assignments.is_empty());
        let k = assignments[line.index(assignments.len())];
        let key = lines[k].split(" = ").next().unwrap_or_default();
        let mut changed: Vec<String> = lines.iter().map(|l| (*l).to_owned()).collect();
        changed[k] = format!("{key} = {v}");
        let changed = changed.join("\n");
        if let Err(e) = Scene::parse(&changed, Path::new("scenes/prop.toml")) {
            prop_assert!(e.to_string().contains("prop.toml"), "{e}");
        }
    }
}
