//! The layering of the library's modules, read from its sources: the core
//! deformation (`src/deform/`) uses nothing of accumulation, persistence,
//! the tiles, skinning or the orchestrator that plugs them in, and
//! accumulation (`src/accumulate/`) nothing of the deformation. What both
//! share lives in neutral modules (`frame`, `height_depth`, `snowfall`).
//!
//! Only code counts: a doc link to a plug-in is documentation, not a
//! dependency. A path through the crate root (`crate::SnowDeformation`)
//! counts as the module it comes from.

use std::path::{Path, PathBuf};

/// Module names the core deformation must not name.
const NOT_IN_DEFORM: &[&str] = &["accumulate", "persist", "skin", "snow", "tiles"];
/// Module names accumulation must not name.
const NOT_IN_ACCUMULATE: &[&str] = &["deform", "persist", "skin", "snow", "tiles"];

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// Every `.rs` file under `dir`, with its text.
fn sources(dir: &Path) -> Vec<(PathBuf, String)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap_or_else(|e| panic!("reading {}: {e}", d.display())) {
            let path = entry.expect("directory entry").path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
                out.push((path, text));
            }
        }
    }
    out
}

/// The code of a line: without a `//` comment (doc comments included).
fn code(line: &str) -> &str {
    line.find("//").map_or(line, |k| &line[..k])
}

fn is_ident(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// Whether `code` names module `module` as a path segment (`module::`, not
/// `other_module::` or a field `x.module`), or declares it (`mod module`).
fn names_module(code: &str, module: &str) -> bool {
    let segment = format!("{module}::");
    let starts_path = |k: usize| code[..k].chars().next_back().is_none_or(|c| !is_ident(c) && c != '.');
    code.match_indices(&segment).any(|(k, _)| starts_path(k))
        || code.split_whitespace().collect::<Vec<_>>().windows(2).any(|w| w[0] == "mod" && w[1].trim_end_matches(';') == module)
}

/// Whether `code` has `word` as a whole identifier.
fn names_word(code: &str, word: &str) -> bool {
    code.match_indices(word).any(|(k, _)| {
        let before = code[..k].chars().next_back().is_none_or(|c| !is_ident(c));
        let after = code[k + word.len()..].chars().next().is_none_or(|c| !is_ident(c));
        before && after
    })
}

/// Names the crate root re-exports from `modules` (`pub use module::{A, B};`
/// and `pub use module::path::C;`), which code could reach them by.
fn root_names(modules: &[&str]) -> Vec<String> {
    let lib = std::fs::read_to_string(src().join("lib.rs")).expect("lib.rs");
    let mut names = Vec::new();
    for line in lib.lines().map(code) {
        let Some(rest) = line.trim().strip_prefix("pub use ") else { continue };
        let Some((module, items)) = rest.split_once("::") else { continue };
        if !modules.contains(&module) {
            continue;
        }
        let items = items.rsplit("::").next().unwrap_or(items);
        names.extend(items.split(|c: char| !is_ident(c)).filter(|w| w.chars().next().is_some_and(|c| c.is_ascii_uppercase())).map(str::to_owned));
    }
    names
}

/// Every line of code under `src/dir` that names one of `modules` or a root
/// re-export of theirs, as `file:line: text`.
fn violations(dir: &str, modules: &[&str]) -> Vec<String> {
    let names = root_names(modules);
    let files = sources(&src().join(dir));
    assert!(files.len() >= 5, "only {} files under src/{dir}: the layout changed and this test must follow", files.len());
    let mut found = Vec::new();
    for (path, text) in files {
        for (n, line) in text.lines().enumerate() {
            let c = code(line);
            if modules.iter().any(|m| names_module(c, m)) || names.iter().any(|w| names_word(c, w)) {
                found.push(format!("{}:{}: {}", path.display(), n + 1, line.trim()));
            }
        }
    }
    found
}

#[test]
fn the_checks_see_what_they_look_for() {
    assert!(names_module("use crate::accumulate::SnowAccumulation;", "accumulate"));
    assert!(names_module("use crate::{accumulate::Snowfall, gpu};", "accumulate"));
    assert!(names_module("let t = super::tiles::planes(true, false);", "tiles"));
    assert!(names_module("pub mod tiles;", "tiles"));
    assert!(names_module("use crate::snow::SnowDeformation;", "snow"));
    assert!(!names_module("use crate::snowfall::Snowfall;", "snow"));
    assert!(!names_module("res.snow.as_entire_binding(),", "snow"));
    assert!(!names_module("use crate::render::skinned::X;", "skin"));
    assert!(names_word("fn f(d: &crate::SnowDeformation) {}", "SnowDeformation"));
    assert!(!names_word("SnowDeformations", "SnowDeformation"));
    assert_eq!(code("let a = 1; // crate::persist"), "let a = 1; ");
    assert_eq!(code("/// [`crate::persist::TileStreamer`]"), "");
    let deform_names = root_names(NOT_IN_DEFORM);
    for name in ["SnowDeformation", "SnowFrame", "TileStreamer", "SnowObject"] {
        assert!(deform_names.iter().any(|n| n == name), "{name} is not among the root names of the plug-ins: {deform_names:?}");
    }
    assert!(root_names(NOT_IN_ACCUMULATE).iter().any(|n| n == "SnowParams"));
}

#[test]
fn core_deformation_knows_nothing_of_its_plug_ins() {
    let found = violations("deform", NOT_IN_DEFORM);
    assert!(found.is_empty(), "src/deform/ names accumulation, persistence, the tiles, skinning or the orchestrator:\n{}", found.join("\n"));
}

#[test]
fn accumulation_knows_nothing_of_the_deformation() {
    let found = violations("accumulate", NOT_IN_ACCUMULATE);
    assert!(found.is_empty(), "src/accumulate/ names the deformation or what plugs into it:\n{}", found.join("\n"));
}
