//! The WGSL source of every pass, composed from `shaders/` and validated by
//! naga at build time (see `build.rs`): one constant per `.wgsl` file directly
//! in `shaders/`, its stem upper-cased, each the files its `// #import` lines
//! reach (transitively, each once, dependencies first) and then the file
//! itself (`docs/rendering.md`, "Shader files and imports").

include!(concat!(env!("OUT_DIR"), "/shaders.rs"));

#[cfg(test)]
#[path = "../build/imports.rs"]
mod imports;

#[cfg(test)]
mod tests {
    use std::collections::{BTreeMap, BTreeSet};
    use std::path::{Path, PathBuf};

    use super::imports::{compose_order, imports_of};

    fn shaders_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders")
    }

    fn read_shader(name: &str) -> Option<String> {
        std::fs::read_to_string(shaders_dir().join(format!("{name}.wgsl"))).ok()
    }

    /// Stems of the `.wgsl` files directly in `dir`, sorted.
    fn stems(dir: &Path, extension: &str) -> Vec<String> {
        let mut out: Vec<String> = std::fs::read_dir(dir)
            .unwrap_or_else(|e| panic!("reading {}: {e}", dir.display()))
            .map(|entry| entry.expect("directory entry").path())
            .filter(|path| path.is_file() && path.extension().is_some_and(|x| x == extension))
            .map(|path| path.file_stem().and_then(|s| s.to_str()).expect("UTF-8 file name").to_string())
            .collect();
        out.sort();
        out
    }

    #[test]
    fn one_constant_per_top_level_file_named_after_it() {
        let names: Vec<String> = stems(&shaders_dir(), "wgsl").iter().map(|s| s.to_uppercase()).collect();
        let constants: Vec<&str> = super::ALL.iter().map(|(name, _)| *name).collect();
        assert_eq!(constants, names);
        // The exported module keeps its name and content: the terrain, then the sampling functions.
        assert_eq!(super::SNOW_SAMPLING, format!("{}\n{}\n", read_shader("shared/terrain").unwrap(), read_shader("snow_sampling").unwrap()));
    }

    #[test]
    fn every_constant_is_its_file_after_its_imports() {
        for (name, source) in super::ALL {
            let pass = name.to_lowercase();
            // What build.rs's resolver composes, read back from the files.
            let parts = compose_order(&pass, &mut read_shader).unwrap_or_else(|e| panic!("{name}: {e}"));
            let expected: String = parts.iter().map(|p| read_shader(p).unwrap() + "\n").collect();
            assert_eq!(*source, expected, "{name} is not {parts:?}");

            // And independently of the resolver: the files the imports reach,
            // each once, every file after the files it imports, nothing else.
            let mut reached = BTreeSet::new();
            let mut todo = vec![pass.clone()];
            while let Some(file) = todo.pop() {
                if reached.insert(file.clone()) {
                    todo.extend(imports_of(&file, &read_shader(&file).unwrap()).unwrap());
                }
            }
            assert_eq!(parts.iter().cloned().collect::<BTreeSet<_>>(), reached, "{name}");
            assert_eq!(parts.len(), reached.len(), "{name}: a file twice");
            assert_eq!(parts.last(), Some(&pass), "{name}: its own file last");
            let at: BTreeMap<&str, usize> = parts.iter().enumerate().map(|(i, p)| (p.as_str(), i)).collect();
            for file in &parts {
                for import in imports_of(file, &read_shader(file).unwrap()).unwrap() {
                    assert!(at[import.as_str()] < at[file.as_str()], "{name}: {import} after {file}, which imports it");
                }
            }
        }
    }

    /// A resolver over an in-memory set of files.
    fn resolve(files: &[(&str, &str)], entry: &str) -> Result<Vec<String>, String> {
        let map: BTreeMap<&str, &str> = files.iter().copied().collect();
        compose_order(entry, &mut |name| map.get(name).map(|t| (*t).to_string()))
    }

    #[test]
    fn imports_resolve_transitively_each_once_in_dependency_order() {
        let files = [
            ("pass", "// #import shared/b\n// #import shared/c\n\n// A pass.\nfn main() {}\n"),
            ("shared/b", "// B needs A.\n// #import shared/a\nfn b() {}\n"),
            ("shared/c", "  // #import shared/a\n// #import shared/b\nfn c() {}\n"),
            ("shared/a", "fn a() {}\n"),
        ];
        assert_eq!(resolve(&files, "pass").unwrap(), ["shared/a", "shared/b", "shared/c", "pass"]);
        assert_eq!(resolve(&files, "shared/a").unwrap(), ["shared/a"]);
    }

    #[test]
    fn a_missing_file_names_its_importer() {
        let files = [("pass", "// #import shared/gone\nfn main() {}\n")];
        let e = resolve(&files, "pass").unwrap_err();
        assert_eq!(e, "pass.wgsl imports `shared/gone`, but there is no shaders/shared/gone.wgsl");
        assert_eq!(resolve(&files, "other").unwrap_err(), "there is no shaders/other.wgsl");
    }

    #[test]
    fn a_cycle_is_reported_with_its_path() {
        let files = [
            ("pass", "// #import shared/a\n"),
            ("shared/a", "// #import shared/b\n"),
            ("shared/b", "// #import shared/c\n"),
            ("shared/c", "// #import shared/a\n"),
        ];
        assert_eq!(resolve(&files, "pass").unwrap_err(), "import cycle: shared/a -> shared/b -> shared/c -> shared/a");
        let itself = [("pass", "// #import pass\n")];
        assert!(resolve(&itself, "pass").unwrap_err().contains("imports itself"));
    }

    #[test]
    fn malformed_or_late_directives_are_errors() {
        for bad in ["// #import", "// #import a b", "// #import shared/a.wgsl", "// #import ../a", "// #import Shared/A", "// #importshared/a"] {
            let e = imports_of("pass", &format!("{bad}\nfn main() {{}}\n")).unwrap_err();
            assert!(e.starts_with("pass.wgsl:1: "), "{bad}: {e}");
        }
        let late = imports_of("pass", "// header\n\nfn main() {}\n// #import shared/a\n").unwrap_err();
        assert!(late.starts_with("pass.wgsl:4: ") && late.contains("below the first line of code"), "{late}");
        // Other comments, `#import` not at a comment's start, and text after a directive's line are not directives.
        assert_eq!(imports_of("pass", "// see #import below\n/// #import x\nfn f() {}\n").unwrap(), Vec::<String>::new());
    }

    /// CPU twins not named after a shader, with the reason (none today).
    const TWINS_WITHOUT_A_SHADER: &[(&str, &str)] = &[];

    #[test]
    fn every_cpu_twin_is_named_after_its_shader() {
        // The twins live in the test kit (crates/snowpack-testkit/src/cpu).
        let cpu = Path::new(env!("CARGO_MANIFEST_DIR")).join("../snowpack-testkit/src/cpu");
        let shaders: BTreeSet<String> = stems(&shaders_dir(), "wgsl").into_iter().collect();
        for twin in stems(&cpu, "rs") {
            if twin == "mod" || TWINS_WITHOUT_A_SHADER.iter().any(|(file, _)| *file == twin) {
                continue;
            }
            assert!(
                shaders.contains(&twin),
                "snowpack-testkit/src/cpu/{twin}.rs twins no shaders/{twin}.wgsl: rename it after its shader (or list it, with why)"
            );
            let text = std::fs::read_to_string(cpu.join(format!("{twin}.rs"))).expect("twin source");
            let doc: String = text.lines().take_while(|l| l.starts_with("//!")).collect();
            assert!(doc.contains(&format!("{twin}.wgsl")), "snowpack-testkit/src/cpu/{twin}.rs: its module doc names `{twin}.wgsl`");
        }
    }
}
