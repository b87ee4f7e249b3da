//! The `// #import` directive of snowpack's WGSL files, resolved: which files
//! a shader is composed of, in which order. Used by `build.rs` (which writes
//! the composed constants) and by the crate's tests (which recompose every
//! constant from the files and compare). Plain `std`, no dependencies.
//!
//! A WGSL file names each file it uses on a line of its own, at its top
//! (before its first line of code):
//!
//! ```wgsl
//! // #import shared/window
//! // #import shared/terrain
//! ```
//!
//! The name is the file's path under `shaders/` without `.wgsl`. The line is
//! a WGSL comment, so an editor or naga still reads each file alone. Imports
//! are transitive: a shader is its imports' compositions, depth first in the
//! order written, each file once (where first reached), then the file itself.
//! A missing file, a malformed directive, a directive below the code and an
//! import cycle are errors.

/// The directive's prefix, after optional leading whitespace.
pub const DIRECTIVE: &str = "// #import";

/// The names `file`'s text imports, in the order written.
///
/// # Errors
/// A directive without exactly one well-formed name after it, or one below
/// the file's first line of code.
pub fn imports_of(file: &str, text: &str) -> Result<Vec<String>, String> {
    let mut names = Vec::new();
    let mut code_seen = false;
    for (index, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        let line_no = index + 1;
        if let Some(rest) = trimmed.strip_prefix(DIRECTIVE) {
            if code_seen {
                return Err(format!("{file}.wgsl:{line_no}: `{DIRECTIVE}` below the first line of code; imports go at the top of the file"));
            }
            let mut words = rest.split_whitespace();
            let (Some(name), None) = (words.next(), words.next()) else {
                return Err(format!("{file}.wgsl:{line_no}: expected `{DIRECTIVE} NAME` (one name per line), found `{}`", line.trim()));
            };
            if !rest.starts_with(char::is_whitespace) || !valid_name(name) {
                return Err(format!(
                    "{file}.wgsl:{line_no}: bad import `{}`: a name is a path under shaders/ without `.wgsl`, \
                     of lower-case letters, digits and `_` separated by `/` (e.g. `shared/window`)",
                    line.trim()
                ));
            }
            if name == file {
                return Err(format!("{file}.wgsl:{line_no}: `{file}` imports itself"));
            }
            names.push(name.to_string());
        } else if !trimmed.is_empty() && !trimmed.starts_with("//") {
            code_seen = true;
        }
    }
    Ok(names)
}

/// Whether `name` is a file name the directive accepts (`shared/window`).
#[must_use]
pub fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.split('/').all(|part| {
            !part.is_empty()
                && part.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_')
                && !part.starts_with(|c: char| c.is_ascii_digit())
        })
}

/// The files `entry` is composed of, in dependency order, each once, `entry`
/// last. `read(name)` gives the text of `shaders/{name}.wgsl`, `None` where
/// there is no such file.
///
/// # Errors
/// `entry` or a file it imports (transitively) missing or with a malformed
/// directive, or an import cycle (the message shows the cycle).
pub fn compose_order(entry: &str, read: &mut dyn FnMut(&str) -> Option<String>) -> Result<Vec<String>, String> {
    let mut order = Vec::new();
    let mut stack = Vec::new();
    visit(entry, None, read, &mut stack, &mut order)?;
    Ok(order)
}

fn visit(
    name: &str,
    importer: Option<&str>,
    read: &mut dyn FnMut(&str) -> Option<String>,
    stack: &mut Vec<String>,
    order: &mut Vec<String>,
) -> Result<(), String> {
    if order.iter().any(|done| done == name) {
        return Ok(());
    }
    if let Some(at) = stack.iter().position(|open| open == name) {
        let mut cycle: Vec<&str> = stack[at..].iter().map(String::as_str).collect();
        cycle.push(name);
        return Err(format!("import cycle: {}", cycle.join(" -> ")));
    }
    let Some(text) = read(name) else {
        return Err(match importer {
            Some(by) => format!("{by}.wgsl imports `{name}`, but there is no shaders/{name}.wgsl"),
            None => format!("there is no shaders/{name}.wgsl"),
        });
    };
    stack.push(name.to_string());
    for import in imports_of(name, &text)? {
        visit(&import, Some(name), read, stack, order)?;
    }
    stack.pop();
    order.push(name.to_string());
    Ok(())
}
