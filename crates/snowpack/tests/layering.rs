//! The layering of the library's modules, read from its sources against the
//! one declared order: the `## Layers` table of `docs/architecture.md`
//! (module, layer number, what it owns).
//!
//! A module may use modules of its own layer or of lower layers; it may not
//! use a module of a higher layer, and the modules of one layer may not use
//! each other in a cycle. Every module the crate root declares must be in the
//! table, and every module in the table must exist.
//!
//! What counts as a use: `use crate::…` (groups included), `crate::x::…` and
//! `super::…` paths in code (`super` resolved upwards from the file's module
//! and any inline `mod` it is in), and a path through a crate-root re-export
//! (`crate::SnowDeformation`) counts as the module it is re-exported from.
//! Comments (doc comments included, so doc links), string and character
//! literals do not count, and neither do items compiled only for this
//! crate's unit tests (`#[cfg(test)]`): they are not part of the library.
//! The crate root (`lib.rs` outside inline modules) is above every layer.
//!
//! Files are read the same way, in every crate of the repository (the Bevy
//! plugin, another workspace, read by path): each `.rs` file is a node, and
//! no two files may use each other, directly or round a circle
//! ([`file_circles`]; `docs/architecture.md`, "Layers"). A file uses
//! another when it names an item the other defines: in a `use` (groups,
//! `crate::`, `super::`, `self::`, a module it declares), in a `crate::`,
//! `super::` or `self::` path in code, or in a path in code that starts at a
//! name its `use` binds or a module it declares (`window::index()`,
//! `coat::paint()`). A path through a re-export counts as the file that
//! defines the item, so naming a module's `mod.rs` (or the crate root) is a
//! use of it only for an item defined there, and a name from another crate
//! (`use snowpack::…`) is none. A `use` of a module itself is no use (the
//! paths through it are). A parent declaring a child (`mod x;`) or
//! re-exporting a descendant's item (`pub use x::X;`) is nesting, not a use,
//! unless its own code uses that item too; a child naming an item its parent
//! defines is a use, so a parent whose code calls its children keeps what
//! they share in a file of its own.
//!
//! The same reading holds the library's functions to [`MAX_FUNCTION_LINES`]
//! lines (from `fn` to the closing brace), so that no pass or orchestrator
//! grows back into one long function; `tools/long_functions.py` lists them.
//!
//! The shared-snow crate (`crates/snowpack-share`) is read the same way
//! against its own table (`## snowpack-share's layers`), and its code must
//! name no GPU, windowing or image crate (nor snowpack): a server builds it
//! alone. Its manifest lacking them keeps it so; this names the line that
//! would need them.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The document that declares the order.
const ARCHITECTURE: &str = include_str!("../../../docs/architecture.md");
/// The heading of the declaring table.
const LAYERS_HEADING: &str = "## Layers";
/// The heading of the shared-snow crate's table.
const SHARE_LAYERS_HEADING: &str = "## snowpack-share's layers";
/// Crates the shared-snow crate's code may not name: the GPU, windowing and
/// image stacks, and snowpack (which depends on it). Not `glam`: the
/// presses that travel (`replicate::press`) repeat the capture's vector
/// arithmetic with the very functions the window calls, and glam is plain
/// arithmetic with no system dependency.
const NOT_IN_SHARE: [&str; 7] = ["wgpu", "naga", "winit", "image", "egui", "bytemuck", "snowpack"];

/// Each declared module: its layer (0 is the lowest) and the modules of its
/// own layer it may use.
type Declared = BTreeMap<String, (u32, BTreeSet<String>)>;

/// Reads the first table under `heading` in `markdown`: one row per module,
/// `` | `module` | 2 · name | what it owns | `a`, `b` | `` (the layer cell
/// starts with its number; the fourth cell, when there is one, names the
/// modules of the same layer it uses; a row may name several modules).
fn declared_layers(markdown: &str, heading: &str) -> Result<Declared, String> {
    let after = markdown.split_once(&format!("\n{heading}\n")).ok_or_else(|| format!("no `{heading}` heading"))?.1;
    let rows = after.lines().skip_while(|l| !l.trim_start().starts_with('|')).take_while(|l| l.trim_start().starts_with('|'));
    let ticked = |cell: &str| cell.split('`').skip(1).step_by(2).map(str::to_owned).collect::<Vec<_>>();
    let mut out = Declared::new();
    for row in rows.skip(2) {
        let cells: Vec<&str> = row.trim().trim_matches('|').split('|').map(str::trim).collect();
        let [modules, layer, ..] = cells[..] else { return Err(format!("a row with fewer than two cells: {row}")) };
        let digits: String = layer.chars().take_while(char::is_ascii_digit).collect();
        let layer: u32 = digits.parse().map_err(|_| format!("the layer cell does not start with a number: {row}"))?;
        let beside: BTreeSet<String> = cells.get(3).map(|c| ticked(c)).unwrap_or_default().into_iter().collect();
        let names = ticked(modules);
        if names.is_empty() {
            return Err(format!("a row names no `module`: {row}"));
        }
        for name in names {
            if out.insert(name.clone(), (layer, beside.clone())).is_some() {
                return Err(format!("`{name}` is declared twice"));
            }
        }
    }
    if out.is_empty() {
        return Err(format!("no table rows under `{heading}`"));
    }
    for (name, (layer, beside)) in &out {
        for b in beside {
            if out.get(b).map(|d| d.0) != Some(*layer) {
                return Err(format!("`{name}` lists `{b}` as beside it, which is not a module of layer {layer}"));
            }
        }
    }
    let edges: Vec<(String, String)> = out.iter().flat_map(|(a, (_, bs))| bs.iter().map(move |b| (a.clone(), b.clone()))).collect();
    if let Some((a, b)) = edges.iter().find(|(a, b)| route(&edges, b, a).is_some()) {
        return Err(format!("the uses beside form a cycle: `{a}` uses `{b}` and `{b}` reaches `{a}`"));
    }
    Ok(out)
}

/// A route from `start` to `goal` along `edges`, when there is one.
fn route(edges: &[(String, String)], start: &str, goal: &str) -> Option<Vec<String>> {
    let mut seen = BTreeSet::new();
    let mut stack = vec![vec![start.to_owned()]];
    while let Some(route) = stack.pop() {
        let last = route.last().expect("a route has a start").clone();
        if last == goal {
            return Some(route);
        }
        if !seen.insert(last.clone()) {
            continue;
        }
        for (_, b) in edges.iter().filter(|(a, _)| *a == last) {
            let mut longer = route.clone();
            longer.push(b.clone());
            stack.push(longer);
        }
    }
    None
}

/// `text` with comments and the insides of string and character literals
/// replaced by spaces, line breaks kept (so line numbers stay).
fn code_only(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut k = 0;
    while k < c.len() {
        let at = |n: usize| c.get(k + n).copied().unwrap_or('\0');
        let ident_before = k > 0 && (c[k - 1].is_alphanumeric() || c[k - 1] == '_');
        if at(0) == '/' && at(1) == '/' {
            while k < c.len() && c[k] != '\n' {
                blank(&mut out, c[k]);
                k += 1;
            }
        } else if at(0) == '/' && at(1) == '*' {
            let mut depth = 0;
            loop {
                if k >= c.len() {
                    break;
                }
                if c[k] == '/' && c.get(k + 1) == Some(&'*') {
                    depth += 1;
                    out.push_str("  ");
                    k += 2;
                } else if c[k] == '*' && c.get(k + 1) == Some(&'/') {
                    depth -= 1;
                    out.push_str("  ");
                    k += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    blank(&mut out, c[k]);
                    k += 1;
                }
            }
        } else if !ident_before && (at(0) == 'r' || (at(0) == 'b' && at(1) == 'r')) && {
            let s = if at(0) == 'b' { 2 } else { 1 };
            let hashes = c[k + s..].iter().take_while(|&&h| h == '#').count();
            c.get(k + s + hashes) == Some(&'"')
        } {
            // A raw string: r"…", r#"…"#, br#"…"#.
            let s = if at(0) == 'b' { 2 } else { 1 };
            let hashes = c[k + s..].iter().take_while(|&&h| h == '#').count();
            let open = s + hashes + 1;
            out.extend(std::iter::repeat_n(' ', open));
            k += open;
            let close: String = std::iter::once('"').chain(std::iter::repeat_n('#', hashes)).collect();
            while k < c.len() && !c[k..].iter().take(close.len()).copied().eq(close.chars()) {
                blank(&mut out, c[k]);
                k += 1;
            }
            out.extend(std::iter::repeat_n(' ', close.len().min(c.len() - k)));
            k += close.len();
        } else if at(0) == '"' {
            k = blank_quoted(&c, k, '"', &mut out);
        } else if at(0) == '\'' && (at(1) == '\\' || (at(1) != '\'' && at(2) == '\'')) {
            // A character literal ('a', '\n', '\u{..}'), not a lifetime ('a).
            k = blank_quoted(&c, k, '\'', &mut out);
        } else {
            out.push(c[k]);
            k += 1;
        }
    }
    out
}

/// Blanks one character of a comment or literal: a space, or the newline it is.
fn blank(out: &mut String, ch: char) {
    out.push(if ch == '\n' { '\n' } else { ' ' });
}

/// Blanks the literal quoted by `quote` that opens at `c[k]` (escapes
/// included, newlines kept) into `out`; returns the index after it.
fn blank_quoted(c: &[char], mut k: usize, quote: char, out: &mut String) -> usize {
    out.push(' ');
    k += 1;
    while k < c.len() && c[k] != quote {
        let n = if c[k] == '\\' { 2 } else { 1 };
        for _ in 0..n.min(c.len() - k) {
            blank(out, c[k]);
            k += 1;
        }
    }
    out.push(' ');
    k + 1
}

/// A token of code: an identifier, `::`, `=>` or one punctuation character.
#[derive(Clone, Debug, PartialEq)]
struct Token {
    text: String,
    line: usize,
}

fn tokens(code: &str) -> Vec<Token> {
    let c: Vec<char> = code.chars().collect();
    let mut out = Vec::new();
    let (mut k, mut line) = (0, 1);
    while k < c.len() {
        let ch = c[k];
        if ch == '\n' {
            line += 1;
            k += 1;
        } else if ch.is_whitespace() {
            k += 1;
        } else if ch.is_alphanumeric() || ch == '_' {
            let start = k;
            while k < c.len() && (c[k].is_alphanumeric() || c[k] == '_') {
                k += 1;
            }
            out.push(Token { text: c[start..k].iter().collect(), line });
        } else if (ch == ':' && c.get(k + 1) == Some(&':')) || (ch == '=' && c.get(k + 1) == Some(&'>')) {
            out.push(Token { text: c[k..k + 2].iter().collect(), line });
            k += 2;
        } else {
            out.push(Token { text: ch.to_string(), line });
            k += 1;
        }
    }
    out
}

/// One path a file names: the module it is in and the absolute path it names
/// (crate-relative segments; a group `crate::{a, b::C}` gives one per leaf),
/// with the name it binds when it is a `use` leaf (for the root's re-exports)
/// and whether that `use` is public (`pub use`, `pub(crate) use`: a
/// re-export). A loose path (`window::storage_index()`, `Steps::new()`:
/// starting at a name the file binds or a module it declares) keeps its
/// segments as written; [`file_edges`] resolves it through the file's
/// imports.
#[derive(Clone, Debug, PartialEq)]
struct Named {
    line: usize,
    from: Vec<String>,
    path: Vec<String>,
    binds: Option<String>,
    reexport: bool,
}

/// What [`named_paths`] reads in one file: the crate paths it names, the
/// modules it declares at the crate root, its loose paths (file scope only)
/// and the identifiers its code uses outside `use` items.
struct Reading {
    named: Vec<Named>,
    declared: Vec<String>,
    loose: Vec<Named>,
    words: BTreeSet<String>,
}

/// The module path of a file under `src/` (`render/shell/count.rs` is
/// `render::shell::count`, `render/mod.rs` is `render`, `lib.rs` the root).
fn module_of(file: &str) -> Vec<String> {
    let file = file.strip_suffix(".rs").unwrap_or(file);
    let mut parts: Vec<String> = file.split('/').map(str::to_owned).collect();
    if parts.last().is_some_and(|p| p == "mod" || p == "lib" || p == "main") {
        parts.pop();
    }
    parts
}

/// Index just past the `#[…]` or `#![…]` starting at `k`.
fn skip_attribute(t: &[Token], mut k: usize) -> usize {
    k += 1;
    if t.get(k).is_some_and(|x| x.text == "!") {
        k += 1;
    }
    skip_group(t, k)
}

/// Index just past the bracketed group opening at `k`.
fn skip_group(t: &[Token], mut k: usize) -> usize {
    let mut depth = 0i32;
    while k < t.len() {
        match t[k].text.as_str() {
            "(" | "[" | "{" => depth += 1,
            ")" | "]" | "}" => {
                depth -= 1;
                if depth == 0 {
                    return k + 1;
                }
            }
            _ => {}
        }
        k += 1;
    }
    k
}

/// Index just past the item (or field, variant, match arm or statement)
/// starting at `k`: at a `;` or `,` outside brackets, or after a `}` that
/// closes its own group (unless `=>` follows, as after a match arm's pattern);
/// never past the bracket that closes the enclosing group.
fn skip_item(t: &[Token], mut k: usize) -> usize {
    while k < t.len() && t[k].text == "#" {
        k = skip_attribute(t, k);
    }
    let mut depth = 0i32;
    while k < t.len() {
        match t[k].text.as_str() {
            "(" | "[" | "{" => depth += 1,
            ")" | "]" => {
                if depth == 0 {
                    return k;
                }
                depth -= 1;
            }
            "}" => {
                if depth == 0 {
                    return k;
                }
                depth -= 1;
                if depth == 0 && t.get(k + 1).is_none_or(|n| n.text != "=>") {
                    return k + 1;
                }
            }
            ";" | "," if depth == 0 => return k + 1,
            _ => {}
        }
        k += 1;
    }
    k
}

/// Whether the attribute at `k` is exactly `#[cfg(test)]`.
fn is_cfg_test(t: &[Token], k: usize) -> bool {
    let words: Vec<&str> = t[k..t.len().min(k + 7)].iter().map(|x| x.text.as_str()).collect();
    words == ["#", "[", "cfg", "(", "test", ")", "]"]
}

/// Parses the use tree or path whose first segment is at `k`; pushes each
/// leaf's segments (relative, as written) and bound name; returns the index
/// after it.
fn parse_tree(t: &[Token], mut k: usize, prefix: &[String], leaves: &mut Vec<(Vec<String>, Option<String>, usize)>) -> usize {
    let mut path = prefix.to_vec();
    let line = t.get(k).map_or(0, |x| x.line);
    while let Some(tok) = t.get(k) {
        if tok.text == "{" {
            k += 1;
            while k < t.len() && t[k].text != "}" {
                k = parse_tree(t, k, &path, leaves);
                if t.get(k).is_some_and(|x| x.text == ",") {
                    k += 1;
                }
            }
            return k + 1;
        }
        if tok.text == "*" {
            path.push("*".to_owned());
            leaves.push((path, None, line));
            return k + 1;
        }
        if !tok.text.starts_with(|ch: char| ch.is_alphabetic() || ch == '_') {
            break;
        }
        path.push(tok.text.clone());
        k += 1;
        if t.get(k).is_some_and(|x| x.text == "::") {
            k += 1;
        } else {
            break;
        }
    }
    let mut binds = path.last().filter(|s| *s != "self").cloned();
    if path.last().is_some_and(|s| s == "self") {
        path.pop();
        binds = path.last().cloned();
    }
    if t.get(k).is_some_and(|x| x.text == "as") {
        binds = t.get(k + 1).map(|x| x.text.clone());
        k += 2;
    }
    leaves.push((path, binds, line));
    k
}

/// The modules a file declares outside any braces (`mod x;`, `pub mod x;`,
/// `mod x { … }`), those under `#[cfg(test)]` left out.
fn file_modules(t: &[Token]) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut depth = 0usize;
    let mut k = 0;
    while k < t.len() {
        match t[k].text.as_str() {
            "#" if depth == 0 && is_cfg_test(t, k) => {
                k = skip_item(t, skip_attribute(t, k));
                continue;
            }
            "{" => depth += 1,
            "}" => depth = depth.saturating_sub(1),
            "mod" if depth == 0 => {
                if let Some(name) = t.get(k + 1).filter(|x| x.text.starts_with(|ch: char| ch.is_alphabetic() || ch == '_')) {
                    out.insert(name.text.clone());
                }
            }
            _ => {}
        }
        k += 1;
    }
    out
}

/// Whether the `use` at `k` is public: `pub use`, `pub(crate) use`,
/// `pub(in path) use`.
fn is_pub_use(t: &[Token], k: usize) -> bool {
    match k.checked_sub(1).map(|j| t[j].text.as_str()) {
        Some("pub") => true,
        Some(")") => {
            let open = (0..k - 1).rev().find(|&j| t[j].text == "(");
            open.is_some_and(|j| j > 0 && t[j - 1].text == "pub")
        }
        _ => false,
    }
}

/// The identifiers `t`'s code uses outside `use` items and `#[cfg(test)]`
/// items: what tells a parent that only re-exports a child's item from one
/// that uses it.
fn code_words(t: &[Token]) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut k = 0;
    while k < t.len() {
        if t[k].text == "#" && is_cfg_test(t, k) {
            k = skip_item(t, skip_attribute(t, k));
        } else if t[k].text == "use" {
            k = skip_item(t, k);
        } else {
            if t[k].text.starts_with(|ch: char| ch.is_alphabetic() || ch == '_') {
                out.insert(t[k].text.clone());
            }
            k += 1;
        }
    }
    out
}

/// `rel` (a path as written in module `here`) as absolute segments:
/// `crate::` from the root, `self::` and `super::` from `here`, anything
/// else (a module `here` declares, or a name at the crate root) below `here`.
fn absolute(here: &[String], rel: Vec<String>) -> Vec<String> {
    let mut base = here.to_vec();
    let mut segs = rel.into_iter().peekable();
    match segs.peek().map(String::as_str) {
        Some("crate") => {
            base.clear();
            segs.next();
        }
        Some("self") => {
            segs.next();
        }
        _ => {}
    }
    while segs.peek().is_some_and(|s| s == "super") {
        segs.next();
        base.pop();
    }
    base.extend(segs);
    base
}

/// Every crate path `file` (a path under `src/`) names in `text`, resolved
/// to absolute segments, the modules it declares at the crate root, its
/// loose paths and the words of its code ([`Reading`]). Items under
/// `#[cfg(test)]` are skipped.
fn named_paths(file: &str, text: &str) -> Reading {
    let t = tokens(&code_only(text));
    let file_module = module_of(file);
    let children = file_modules(&t);
    let mut out = Reading { named: Vec::new(), declared: Vec::new(), loose: Vec::new(), words: code_words(&t) };
    // Inline modules the walk is in: (name, brace depth outside it).
    let mut inline: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let mut pending_mod: Option<String> = None;
    let mut k = 0;
    while k < t.len() {
        let here = |inline: &[(String, usize)]| file_module.iter().cloned().chain(inline.iter().map(|(n, _)| n.clone())).collect::<Vec<_>>();
        let word = t[k].text.as_str();
        let prev = if k > 0 { t[k - 1].text.as_str() } else { "" };
        let next = t.get(k + 1).map_or("", |x| x.text.as_str());
        if word == "#" && is_cfg_test(&t, k) {
            k = skip_item(&t, skip_attribute(&t, k));
            continue;
        }
        match word {
            "{" => {
                if let Some(name) = pending_mod.take() {
                    inline.push((name, depth));
                }
                depth += 1;
            }
            "}" => {
                depth = depth.saturating_sub(1);
                if inline.last().is_some_and(|(_, d)| *d == depth) {
                    inline.pop();
                }
            }
            ";" => pending_mod = None,
            "mod" if next.starts_with(|ch: char| ch.is_alphabetic() || ch == '_') => {
                if here(&inline).is_empty() {
                    out.declared.push(next.to_owned());
                }
                pending_mod = Some(next.to_owned());
                k += 2;
                continue;
            }
            _ => {}
        }
        let starts_path = prev != "::" && next == "::" && word.starts_with(|ch: char| ch.is_alphabetic() || ch == '_');
        if !starts_path {
            k += 1;
            continue;
        }
        let is_use = prev == "use";
        let reexport = is_use && is_pub_use(&t, k - 1);
        // `use child::…` names a module the file declares; any other `use
        // x::…` a name in scope or an outside crate (a loose path).
        let relative_use = is_use && inline.is_empty() && children.contains(word);
        let anchored = matches!(word, "crate" | "super" | "self") || relative_use;
        if !anchored && !inline.is_empty() {
            k += 1;
            continue;
        }
        let mut leaves = Vec::new();
        k = parse_tree(&t, k, &[], &mut leaves);
        for (rel, binds, line) in leaves {
            let binds = binds.filter(|_| is_use);
            let from = here(&inline);
            if anchored {
                out.named.push(Named { line, path: absolute(&from, rel), from, binds, reexport });
            } else {
                out.loose.push(Named { line, path: rel, from, binds, reexport });
            }
        }
    }
    out
}

/// The layering problems of the crate whose sources are `files` (path under
/// `src/`, text), against `declared`; empty when it keeps the order. Each
/// problem names the file and line.
fn check(declared: &Declared, files: &[(String, String)]) -> Vec<String> {
    let mut problems = Vec::new();
    let mut per_file = Vec::new();
    let mut modules = BTreeSet::new();
    for (file, text) in files {
        let reading = named_paths(file, text);
        if module_of(file).is_empty() {
            modules.extend(reading.declared);
        }
        per_file.push((file, text, reading.named));
    }
    if modules.is_empty() {
        problems.push("no crate root (lib.rs) among the sources, or it declares no modules".to_owned());
    }
    for m in &modules {
        if !declared.contains_key(m) {
            problems.push(format!("src/lib.rs declares module `{m}`, which the `{LAYERS_HEADING}` table of docs/architecture.md does not place"));
        }
    }
    for m in declared.keys() {
        if !modules.contains(m) {
            problems.push(format!("docs/architecture.md places module `{m}`, which src/lib.rs does not declare"));
        }
    }
    // The root's re-exports: the name bound at the root, and the module it comes from.
    let mut root_names: BTreeMap<String, String> = BTreeMap::new();
    for (_, _, named) in &per_file {
        for n in named.iter().filter(|n| n.from.is_empty()) {
            if let (Some(name), Some(first)) = (&n.binds, n.path.first())
                && modules.contains(first)
                && n.path.len() > 1
            {
                root_names.insert(name.clone(), first.clone());
            }
        }
    }
    // Uses between different modules: (from, to) → where.
    let mut edges: BTreeMap<(String, String), Vec<String>> = BTreeMap::new();
    for (file, text, named) in &per_file {
        let lines: Vec<&str> = text.lines().collect();
        for n in named {
            let Some(from) = n.from.first() else { continue };
            let at = format!("src/{file}:{}: {}", n.line, lines.get(n.line - 1).map_or("", |l| l.trim()));
            let to = match n.path.first() {
                None => {
                    problems.push(format!("{at}\n    names the crate root itself"));
                    continue;
                }
                Some(first) if modules.contains(first) => first.clone(),
                Some(first) => match root_names.get(first) {
                    Some(m) => m.clone(),
                    None => {
                        problems.push(format!("{at}\n    `crate::{first}` is neither a module nor a re-export of the crate root"));
                        continue;
                    }
                },
            };
            if *from != to {
                let places = edges.entry((from.clone(), to)).or_default();
                if !places.contains(&at) {
                    places.push(at);
                }
            }
        }
    }
    let layer = |m: &str| declared.get(m).map(|d| d.0);
    // Uses beside (within one layer): in a cycle, or not declared.
    let same: Vec<(String, String)> = edges.keys().filter(|(a, b)| layer(a).is_some() && layer(a) == layer(b)).cloned().collect();
    for ((from, to), places) in &edges {
        let (Some(lf), Some(lt)) = (layer(from), layer(to)) else { continue };
        let why = if lt > lf {
            format!("upward: `{from}` (layer {lf}) uses `{to}` (layer {lt})")
        } else if lt < lf {
            continue;
        } else if let Some(back) = route(&same, to, from) {
            format!("cycle in layer {lf}: `{from}` uses `{to}`, and {}", back.join(" → "))
        } else if !declared[from].1.contains(to) {
            format!("beside: `{from}` uses `{to}` of its own layer ({lf}), which its row in docs/architecture.md does not list")
        } else {
            continue;
        };
        for at in places {
            problems.push(format!("{at}\n    {why}"));
        }
    }
    problems
}

/// The most lines a function of the library may span (`fn` to its closing brace).
const MAX_FUNCTION_LINES: usize = 80;

/// Each function with a body in `code` (comments and literals blanked):
/// its name, the line of `fn` and the line of its closing brace.
fn functions(code: &str) -> Vec<(String, usize, usize)> {
    let t = tokens(code);
    let mut out = Vec::new();
    for k in 0..t.len().saturating_sub(1) {
        if t[k].text != "fn" || !t[k + 1].text.starts_with(|c: char| c.is_alphabetic() || c == '_') {
            continue;
        }
        // The body opens at the first `{` outside the signature's brackets;
        // a `;` first is a declaration without a body. `->` is not a bracket.
        let mut depth = 0i32;
        let mut open = None;
        for j in k + 2..t.len() {
            match t[j].text.as_str() {
                "(" | "[" | "<" => depth += 1,
                ">" if t[j - 1].text == "-" => {}
                ")" | "]" | ">" => depth -= 1,
                ";" if depth <= 0 => break,
                "{" if depth <= 0 => {
                    open = Some(j);
                    break;
                }
                _ => {}
            }
        }
        let Some(open) = open else { continue };
        let mut braces = 0;
        for token in &t[open..] {
            match token.text.as_str() {
                "{" => braces += 1,
                "}" => braces -= 1,
                _ => continue,
            }
            if braces == 0 {
                out.push((t[k + 1].text.clone(), t[k].line, token.line));
                break;
            }
        }
    }
    out
}

/// `file:line name (N lines)` for each function of `files` longer than `limit` lines.
fn long_functions(files: &[(String, String)], limit: usize) -> Vec<String> {
    let mut out = Vec::new();
    for (file, text) in files {
        for (name, first, last) in functions(&code_only(text)) {
            if last - first + 1 > limit {
                out.push(format!("{file}:{first} {name} ({} lines)", last - first + 1));
            }
        }
    }
    out
}

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// The shared-snow crate's directory.
fn share_crate() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../snowpack-share")
}

/// Every `.rs` file under `src/`: its path under `src/` (with `/`) and its text.
fn sources() -> Vec<(String, String)> {
    sources_in(&src())
}

/// Every `.rs` file under `root`: its path under `root` (with `/`) and its text.
fn sources_in(root: &Path) -> Vec<(String, String)> {
    let root = root.to_path_buf();
    let mut out = Vec::new();
    let mut stack = vec![root.clone()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap_or_else(|e| panic!("reading {}: {e}", d.display())) {
            let path = entry.expect("directory entry").path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
                let rel = path.strip_prefix(&root).expect("under src").components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>().join("/");
                out.push((rel, text));
            }
        }
    }
    out.sort();
    out
}

fn declared() -> Declared {
    declared_layers(ARCHITECTURE, LAYERS_HEADING).unwrap_or_else(|e| panic!("docs/architecture.md: {e}"))
}

/// Each place in `files` (path under `src/`, text) whose code names one of
/// [`NOT_IN_SHARE`] (`wgpu::…`, `use image::…`, `extern crate winit`):
/// `src/file:line: the line`, and the crate.
fn gpu_names(files: &[(String, String)]) -> Vec<String> {
    let mut out = Vec::new();
    for (file, text) in files {
        let t = tokens(&code_only(text));
        let lines: Vec<&str> = text.lines().collect();
        for k in 0..t.len() {
            let word = t[k].text.as_str();
            let prev = if k > 0 { t[k - 1].text.as_str() } else { "" };
            let next = t.get(k + 1).map_or("", |x| x.text.as_str());
            if NOT_IN_SHARE.contains(&word) && ((prev != "::" && next == "::") || prev == "crate") {
                let line = t[k].line;
                out.push(format!("src/{file}:{line}: {}\n    names `{word}`", lines.get(line - 1).map_or("", |l| l.trim())));
            }
        }
    }
    out
}

/// The crates a manifest's `[dependencies]` tables (target-specific ones
/// included) list, by their names as written.
fn manifest_dependencies(manifest: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut in_deps = false;
    for line in manifest.lines().map(str::trim) {
        if line.starts_with('[') {
            in_deps = line.trim_end_matches(']').ends_with("dependencies") && !line.contains("dev-dependencies") && !line.contains("build-dependencies");
        } else if in_deps && let Some((name, _)) = line.split_once('=') {
            let name = name.trim();
            out.push(name.split('.').next().unwrap_or(name).to_owned());
        }
    }
    out
}

#[test]
fn the_share_crate_keeps_its_declared_order() {
    let files = sources_in(&share_crate().join("src"));
    assert!(files.len() >= 10, "only {} source files in snowpack-share: the layout changed and this test must follow", files.len());
    let declared = declared_layers(ARCHITECTURE, SHARE_LAYERS_HEADING).unwrap_or_else(|e| panic!("docs/architecture.md: {e}"));
    let problems = check(&declared, &files);
    assert!(problems.is_empty(), "snowpack-share breaks the order declared in docs/architecture.md ({SHARE_LAYERS_HEADING}):\n{}", problems.join("\n"));
}

#[test]
fn the_share_crate_names_no_gpu_code() {
    let names = gpu_names(&sources_in(&share_crate().join("src")));
    assert!(names.is_empty(), "snowpack-share names the GPU, windowing or image stack (a server builds it alone):\n{}", names.join("\n"));
    let manifest = std::fs::read_to_string(share_crate().join("Cargo.toml")).expect("snowpack-share's Cargo.toml");
    let deps = manifest_dependencies(&manifest);
    assert!(deps.contains(&"thiserror".to_owned()), "the manifest's dependencies were not read: {deps:?}");
    let gpu: Vec<&String> = deps.iter().filter(|d| NOT_IN_SHARE.contains(&d.as_str())).collect();
    assert!(gpu.is_empty(), "snowpack-share's Cargo.toml depends on {gpu:?}");
}

#[test]
fn a_planted_gpu_name_in_the_share_crate_is_reported() {
    let files = [
        (
            "replicate/relay/mod.rs".to_owned(),
            "//! wgpu::Device in a comment\nuse std::io;\nuse wgpu::Device;\nfn f() { let _ = \"image::open\"; }\n".to_owned(),
        ),
        (
            "persist/codec.rs".to_owned(),
            "fn g() -> bytemuck::Pod { bytemuck::Pod::ZERO }\nfn h() { let wgpu = 1; let _ = wgpu; let _ = glam::Vec2::ZERO; }\n".to_owned(),
        ),
    ];
    let names = gpu_names(&files);
    assert_eq!(names.len(), 3, "{names:#?}");
    assert!(names[0].starts_with("src/replicate/relay/mod.rs:3: use wgpu::Device;") && names[0].ends_with("names `wgpu`"), "{}", names[0]);
    assert!(names[1].starts_with("src/persist/codec.rs:1:") && names[2].starts_with("src/persist/codec.rs:1:"), "{names:#?}");
    let deps = manifest_dependencies(
        "[package]\nname = \"x\"\n[dependencies]\nthiserror.workspace = true\nwgpu = \"30\"\n[dev-dependencies]\nimage = \"1\"\n[target.'cfg(unix)'.dependencies]\nwinit = { version = \"0.30\" }\n",
    );
    assert_eq!(deps, ["thiserror", "wgpu", "winit"]);
}

#[test]
fn every_module_keeps_the_declared_order() {
    let files = sources();
    assert!(files.len() > 100, "only {} source files: the layout changed and this test must follow", files.len());
    let problems = check(&declared(), &files);
    assert!(problems.is_empty(), "the modules break the order declared in docs/architecture.md ({LAYERS_HEADING}):\n{}", problems.join("\n"));
}

/// The layers and a crate of `files` in a test's own words.
/// (Each layer entry: module, layer, the modules beside it it may use.)
fn planted(layers: &[(&str, u32, &[&str])], files: &[(&str, &str)]) -> Vec<String> {
    let declared = layers.iter().map(|&(m, l, b)| (m.to_owned(), (l, b.iter().map(|&s| s.to_owned()).collect()))).collect();
    check(&declared, &files.iter().map(|&(f, t)| (f.to_owned(), t.to_owned())).collect::<Vec<_>>())
}

#[test]
fn a_planted_upward_import_is_reported() {
    let lib = "pub mod gpu;\npub mod render;\npub use render::Renderer;\n";
    let clean =
        planted(&[("gpu", 0, &[]), ("render", 1, &[])], &[("lib.rs", lib), ("gpu/mod.rs", "pub struct Ctx;\n"), ("render/mod.rs", "use crate::gpu::Ctx;\n")]);
    assert!(clean.is_empty(), "{clean:?}");
    for gpu in [
        "pub struct Ctx;\nuse crate::render::Renderer;\n",
        "pub struct Ctx;\nuse crate::{render::Renderer};\n",
        "pub struct Ctx;\nfn f(_: &crate::Renderer) {}\n",
        "pub struct Ctx;\nfn f() { let _ = crate::render::Renderer::new(); }\n",
    ] {
        let found = planted(&[("gpu", 0, &[]), ("render", 1, &[])], &[("lib.rs", lib), ("gpu/mod.rs", gpu), ("render/mod.rs", "use crate::gpu::Ctx;\n")]);
        assert_eq!(found.len(), 1, "{gpu}: {found:?}");
        assert!(found[0].starts_with("src/gpu/mod.rs:2:") && found[0].contains("upward: `gpu` (layer 0) uses `render` (layer 1)"), "{found:?}");
    }
    // `super` from a submodule resolves upwards, out of its module.
    let found =
        planted(&[("gpu", 0, &[]), ("render", 1, &[])], &[("lib.rs", lib), ("gpu/readback.rs", "\n\nuse super::super::render::X;\n"), ("render/mod.rs", "")]);
    assert!(found.len() == 1 && found[0].starts_with("src/gpu/readback.rs:3:") && found[0].contains("upward"), "{found:?}");
}

#[test]
fn a_planted_cycle_is_reported() {
    let lib = "pub mod persist;\npub mod tiles;\n";
    let layers: [(&str, u32, &[&str]); 2] = [("persist", 4, &[]), ("tiles", 4, &["persist"])];
    let tiles = "use crate::persist::TileStore;\n";
    assert!(planted(&layers, &[("lib.rs", lib), ("tiles/mod.rs", tiles), ("persist/mod.rs", "pub struct TileStore;\n")]).is_empty());
    let persist = "pub struct TileStore;\nfn f() {\n    super::tiles::planes();\n}\n";
    let found = planted(&layers, &[("lib.rs", lib), ("tiles/mod.rs", tiles), ("persist/mod.rs", persist)]);
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(found.iter().any(|p| p.starts_with("src/persist/mod.rs:3:") && p.contains("cycle in layer 4: `persist` uses `tiles`")), "{found:?}");
    assert!(found.iter().any(|p| p.starts_with("src/tiles/mod.rs:1:") && p.contains("cycle in layer 4: `tiles` uses `persist`")), "{found:?}");
}

#[test]
fn the_real_tree_with_a_planted_import_fails() {
    let mut files = sources();
    let gpu = files.iter_mut().find(|(f, _)| f == "gpu/mod.rs").expect("src/gpu/mod.rs");
    gpu.1.push_str("\nuse crate::SnowDeformation;\n");
    let found = check(&declared(), &files);
    assert!(found.iter().any(|p| p.starts_with("src/gpu/mod.rs:") && p.contains("upward: `gpu`") && p.contains("uses `snow`")), "{found:?}");
    let mut files = sources();
    let persist = files.iter_mut().find(|(f, _)| f == "persist/mod.rs").expect("src/persist/mod.rs");
    persist.1.push_str("\nfn planted() { let _ = crate::tiles::streaming::PLANE_SNOW; }\n");
    let found = check(&declared(), &files);
    assert!(found.iter().any(|p| p.starts_with("src/persist/mod.rs:") && p.contains("cycle") && p.contains("`persist` uses `tiles`")), "{found:?}");
}

#[test]
fn what_is_not_code_does_not_count() {
    let lib = "pub mod gpu;\npub mod render;\n";
    let layers: [(&str, u32, &[&str]); 2] = [("gpu", 0, &[]), ("render", 1, &[])];
    let gpu = r##"
//! See [`crate::render::Renderer`].
/// Links to [`crate::render`] and [`super::render::X`].
/* crate::render::Y /* nested crate::render */ */
const A: &str = "crate::render::Z";
const B: &str = r#"use crate::render::W;"#;
const C: char = '"';
fn f<'a>(x: &'a str) -> &'a str { x } // crate::render
#[cfg(test)]
mod tests {
    use crate::render::Renderer;
    fn g() { super::super::render::h(); }
}
#[cfg(test)]
use crate::render::T;
enum E {
    #[cfg(test)]
    Pause { a: crate::render::A },
    Run,
}
"##;
    let found = planted(&layers, &[("lib.rs", lib), ("gpu/mod.rs", gpu), ("render/mod.rs", "")]);
    assert!(found.is_empty(), "{found:?}");
    // ...but code after them does.
    let found = planted(&layers, &[("lib.rs", lib), ("gpu/mod.rs", &format!("{gpu}fn late() {{ crate::render::x(); }}\n")), ("render/mod.rs", "")]);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].starts_with("src/gpu/mod.rs:21:"), "{found:?}");
}

#[test]
fn modules_and_the_table_must_agree() {
    let found = planted(&[("gpu", 0, &[])], &[("lib.rs", "pub mod gpu;\n#[cfg(any(test, feature = \"low_level\"))]\npub mod extra;\n"), ("gpu/mod.rs", "")]);
    assert!(found.iter().any(|p| p.contains("declares module `extra`")), "{found:?}");
    let found = planted(&[("gpu", 0, &[]), ("gone", 1, &[])], &[("lib.rs", "pub mod gpu;\n"), ("gpu/mod.rs", "")]);
    assert!(found.iter().any(|p| p.contains("places module `gone`")), "{found:?}");
    let found = planted(&[("gpu", 0, &[])], &[("lib.rs", "pub mod gpu;\n"), ("gpu/mod.rs", "fn f() { crate::Unknown::new(); }\n")]);
    assert!(found.iter().any(|p| p.contains("`crate::Unknown` is neither")), "{found:?}");
}

#[test]
fn the_table_is_read() {
    let md = "# A\n\n## Layers\n\nText.\n\n| module | layer | owns | beside |\n|---|---|---|---|\n| `error`, `shaders` | 0 · base | x | — |\n| `gpu` | 1 · gpu | y | |\n| `pool` | 1 · gpu | z | `gpu` |\n\n## Next\n| `no` | 9 | z |\n";
    let layers = declared_layers(md, LAYERS_HEADING).expect("a table");
    let none = BTreeSet::new;
    let expected: Declared = [("error", 0, none()), ("shaders", 0, none()), ("gpu", 1, none()), ("pool", 1, ["gpu".to_owned()].into())]
        .into_iter()
        .map(|(m, l, b)| (m.to_owned(), (l, b)))
        .collect();
    assert_eq!(layers, expected);
    assert!(declared_layers("## Layers\n| `a` | x |\n|-|-|\n| `a` | one |\n", LAYERS_HEADING).is_err(), "a layer that is not a number");
    assert!(declared_layers("## Layers\n|m|l|\n|-|-|\n| `a` | 1 |\n| `a` | 2 |\n", LAYERS_HEADING).is_err(), "a module twice");
    assert!(declared_layers("## Layers\n|m|l|o|b|\n|-|-|-|-|\n| `a` | 1 | | `b` |\n| `b` | 2 | | |\n", LAYERS_HEADING).is_err(), "beside across layers");
    assert!(declared_layers("## Layers\n|m|l|o|b|\n|-|-|-|-|\n| `a` | 1 | | `b` |\n| `b` | 1 | | `a` |\n", LAYERS_HEADING).is_err(), "a declared cycle");
    let real = declared();
    assert!(real.len() >= 16, "{real:?}");
}

#[test]
fn an_undeclared_use_beside_is_reported() {
    let lib = "pub mod deform;\npub mod accumulate;\n";
    let files = [("lib.rs", lib), ("deform/mod.rs", ""), ("accumulate/occlusion.rs", "\nuse crate::deform::X;\n")];
    let found = planted(&[("deform", 3, &[]), ("accumulate", 3, &[])], &files);
    assert!(found.len() == 1 && found[0].starts_with("src/accumulate/occlusion.rs:2:") && found[0].contains("beside: `accumulate` uses `deform`"), "{found:?}");
    assert!(planted(&[("deform", 3, &[]), ("accumulate", 3, &["deform"])], &files).is_empty());
}

/// The files of the crate whose root is `root` (`lib.rs` or `main.rs`) among
/// `files` (path under the crate's `src/`, text): the root, every file a
/// `mod` declaration reaches from it, and every file in the folder of a
/// module it reaches (`render/mod.rs` declares its renderer's modules
/// through a macro). A folder with both roots holds two crates, each with
/// its own modules: at the top level only `mod` declarations count.
fn crate_files<'a>(root: &str, files: &'a [(String, String)]) -> Vec<&'a (String, String)> {
    let by_module: BTreeMap<Vec<String>, &(String, String)> =
        files.iter().filter(|(f, _)| f != "lib.rs" && f != "main.rs").map(|entry| (module_of(&entry.0), entry)).collect();
    let mut out: Vec<&(String, String)> = files.iter().filter(|(f, _)| f == root).collect();
    let mut k = 0;
    while k < out.len() {
        let (file, text) = out[k];
        let here = module_of(file);
        let declared = file_modules(&tokens(&code_only(text))).into_iter().map(|child| here.iter().cloned().chain([child]).collect::<Vec<_>>());
        let in_folder = by_module.keys().filter(|m| !here.is_empty() && m.len() == here.len() + 1 && m.starts_with(&here)).cloned();
        for path in declared.chain(in_folder).collect::<Vec<_>>() {
            if let Some(entry) = by_module.get(&path)
                && !out.iter().any(|e| e.0 == entry.0)
            {
                out.push(entry);
            }
        }
        k += 1;
    }
    out
}

/// Each file's `use` bindings: name → the absolute path it binds, or `None`
/// for a name from outside the crate (`use std::…`, `use snowpack::…`).
type Imports = BTreeMap<String, BTreeMap<String, Option<Vec<String>>>>;

/// The file that defines what the absolute `path` names among `modules`
/// (module path → file): the file of its longest module prefix, followed
/// through that file's `use` of the next segment (a re-export, or an import
/// a child module reaches with `super::`), up to 8 times; `None` when that
/// `use` brings the name from outside the crate.
fn defining_file(path: &[String], modules: &BTreeMap<Vec<String>, String>, imports: &Imports, hops: u32) -> Option<String> {
    let n = (0..=path.len()).rev().find(|&n| modules.contains_key(&path[..n]))?;
    let file = &modules[&path[..n]];
    if let Some(next) = path.get(n)
        && hops < 8
        && let Some(bound) = imports.get(file).and_then(|m| m.get(next))
    {
        return defining_file(bound.as_ref()?, modules, imports, hops + 1);
    }
    Some(file.clone())
}

/// The `use` bindings of every file of `read` ([`Imports`]): the anchored
/// ones (`crate::`, `super::`, `self::`, a declared module) first, then the
/// loose ones, through them.
fn file_imports(read: &[(&String, &String, Reading)], modules: &BTreeMap<Vec<String>, String>) -> Imports {
    let mut imports = Imports::new();
    for (file, _, reading) in read {
        let here = module_of(file);
        for n in reading.named.iter().filter(|n| n.from == here) {
            if let Some(name) = &n.binds {
                imports.entry((*file).clone()).or_default().insert(name.clone(), Some(n.path.clone()));
            }
        }
    }
    for (file, _, reading) in read {
        let here = module_of(file);
        for n in reading.loose.iter().filter(|n| n.from == here) {
            let Some(name) = &n.binds else { continue };
            let resolved = resolve_loose(n, &here, modules, imports.get(*file)).map(|r| r.path);
            imports.entry((*file).clone()).or_default().entry(name.clone()).or_insert(resolved);
        }
    }
    imports
}

/// The absolute path a loose path of the file of module `here` names: its
/// first segment a name the file's `use` binds (`imports`) or a module the
/// file declares; `None` for anything else (`std::…`, `Self::…`, a local
/// type's associated item, a name from outside the crate).
fn resolve_loose(
    n: &Named,
    here: &[String],
    modules: &BTreeMap<Vec<String>, String>,
    imports: Option<&BTreeMap<String, Option<Vec<String>>>>,
) -> Option<Named> {
    let (first, rest) = n.path.split_first()?;
    let mut path = match imports.and_then(|m| m.get(first)) {
        Some(bound) => bound.clone()?,
        None => {
            let child: Vec<String> = here.iter().chain([first]).cloned().collect();
            modules.contains_key(&child).then_some(child)?
        }
    };
    path.extend(rest.iter().cloned());
    Some(Named { path, ..n.clone() })
}

/// The file `n` (named in the file of module `here`, whose code uses
/// `words`) is an edge to, if any: the file that defines the item. `None`
/// for a `use` of a module itself (the paths through it count where they
/// name an item) and for a re-export of a descendant's item (`pub use
/// steps::Steps` in `snow/mod.rs`) that the re-exporting file's own code
/// does not use: that is how modules nest, not an import.
fn used_file(n: &Named, here: &[String], modules: &BTreeMap<Vec<String>, String>, imports: &Imports, words: &BTreeSet<String>) -> Option<String> {
    if n.binds.is_some() && modules.contains_key(&n.path) {
        return None;
    }
    let to = defining_file(&n.path, modules, imports, 0)?;
    let there = module_of(&to);
    let nests = there.len() > here.len() && there.starts_with(here);
    let only_reexported = n.reexport && nests && n.binds.as_ref().is_none_or(|b| !words.contains(b));
    (!only_reexported).then_some(to)
}

/// The uses between files of one crate (`files`: path under `src/`, text,
/// every file of the crate): from → to → the first place, `src/file:line:
/// the line`. A path through a re-export counts as the file that defines
/// the item, so naming a module's `mod.rs` counts only for an item defined
/// in it; the rest of the rule is [`used_file`]'s.
fn file_edges(files: &[&(String, String)]) -> BTreeMap<String, BTreeMap<String, String>> {
    let modules: BTreeMap<Vec<String>, String> = files.iter().map(|(f, _)| (module_of(f), f.clone())).collect();
    let read: Vec<(&String, &String, Reading)> = files.iter().map(|(f, text)| (f, text, named_paths(f, text))).collect();
    let imports = file_imports(&read, &modules);
    let mut edges: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    for (file, text, reading) in &read {
        let lines: Vec<&str> = text.lines().collect();
        let here = module_of(file);
        let loose = reading.loose.iter().filter_map(|n| resolve_loose(n, &here, &modules, imports.get(*file)));
        for n in reading.named.iter().cloned().chain(loose) {
            let Some(to) = used_file(&n, &here, &modules, &imports, &reading.words) else { continue };
            if to == **file {
                continue;
            }
            let at = format!("src/{file}:{}: {}", n.line, lines.get(n.line - 1).map_or("", |l| l.trim()));
            edges.entry((*file).clone()).or_default().entry(to).or_insert(at);
        }
    }
    edges
}

/// The file circles of a crate folder (`files`: path under `src/`, text;
/// the library's and the binary's crates each read on its own): for each
/// circle once, where each of its files uses the next.
fn file_circles(files: &[(String, String)]) -> Vec<String> {
    let mut problems = Vec::new();
    let mut seen: BTreeSet<Vec<String>> = BTreeSet::new();
    for root in ["lib.rs", "main.rs"] {
        let crate_files = crate_files(root, files);
        if crate_files.is_empty() {
            continue;
        }
        let edges = file_edges(&crate_files);
        let pairs: Vec<(String, String)> = edges.iter().flat_map(|(a, tos)| tos.keys().map(move |b| (a.clone(), b.clone()))).collect();
        for (a, b) in &pairs {
            let Some(back) = route(&pairs, b, a) else { continue };
            let mut members: Vec<String> = back.clone();
            members.sort();
            members.dedup();
            if !seen.insert(members) {
                continue;
            }
            let mut circle = vec![a.clone()];
            circle.extend(back);
            let steps: Vec<String> = circle.windows(2).map(|w| format!("  {}", edges[&w[0]][&w[1]])).collect();
            problems.push(format!("file circle {}:\n{}", circle.join(" → "), steps.join("\n")));
        }
    }
    problems
}

/// Every crate folder of the repository with sources: the root workspace's
/// crates, the Bevy plugin and its multiplayer example.
fn crate_source_folders() -> Vec<PathBuf> {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut out: Vec<PathBuf> = std::fs::read_dir(repo.join("crates")).expect("crates/").map(|e| e.expect("entry").path().join("src")).collect();
    out.push(repo.join("integrations/bevy_snowpack/src"));
    out.push(repo.join("integrations/bevy_snowpack/examples/multiplayer/src"));
    out.retain(|d| d.is_dir());
    out.sort();
    out
}

#[test]
fn no_crate_has_a_file_circle() {
    let folders = crate_source_folders();
    assert!(folders.len() >= 7, "only {} crate folders: the layout changed and this test must follow", folders.len());
    // The graph was read: every file of the library is in it (those a macro
    // declares too), with its uses.
    let library = sources();
    let reached = crate_files("lib.rs", &library);
    assert_eq!(reached.len(), library.len(), "files of src/ the crate root does not reach");
    let uses: usize = file_edges(&reached).values().map(BTreeMap::len).sum();
    assert!(uses > 2 * library.len(), "only {uses} uses between {} files", library.len());
    let mut problems = Vec::new();
    for folder in &folders {
        let files = sources_in(folder);
        problems.extend(file_circles(&files).into_iter().map(|p| format!("{}: {p}", folder.display())));
    }
    assert!(problems.is_empty(), "files that use each other in a circle (move what both need below them):\n{}", problems.join("\n"));
}

/// `files` in a test's own words, as a crate folder.
fn folder(files: &[(&str, &str)]) -> Vec<(String, String)> {
    files.iter().map(|&(f, t)| (f.to_owned(), t.to_owned())).collect()
}

#[test]
fn a_planted_file_circle_is_reported() {
    let lib = "mod snow;\n";
    let snow = "mod coat;\nmod steps;\npub use steps::Steps;\npub struct Shared;\n";
    // A child naming its parent's own item, and the parent re-exporting a child: nesting, not a circle.
    let fine = folder(&[("lib.rs", lib), ("snow/mod.rs", snow), ("snow/coat.rs", "fn f(_: super::Shared) {}\n"), ("snow/steps.rs", "pub struct Steps;\n")]);
    assert!(file_circles(&fine).is_empty(), "{:#?}", file_circles(&fine));
    // Two files of one module using each other, one way through the parent's re-export.
    let coat = "pub struct Coat;\nfn f(_: super::Steps) {}\n";
    let steps = "use super::coat::Coat;\npub struct Steps(Coat);\n";
    let circle = folder(&[("lib.rs", lib), ("snow/mod.rs", snow), ("snow/coat.rs", coat), ("snow/steps.rs", steps)]);
    let found = file_circles(&circle);
    assert_eq!(found.len(), 1, "{found:#?}");
    assert!(
        found[0].contains("snow/coat.rs → snow/steps.rs → snow/coat.rs") || found[0].contains("snow/steps.rs → snow/coat.rs → snow/steps.rs"),
        "{}",
        found[0]
    );
    assert!(
        found[0].contains("src/snow/steps.rs:1: use super::coat::Coat;") && found[0].contains("src/snow/coat.rs:2: fn f(_: super::Steps) {}"),
        "{}",
        found[0]
    );
    // A parent whose own code calls its child (a loose path through the
    // module it declares), while the child names an item the parent defines.
    let parent = "mod coat;\npub struct Shared;\nfn run() { coat::paint(); }\n";
    let found = file_circles(&folder(&[("lib.rs", lib), ("snow/mod.rs", parent), ("snow/coat.rs", "pub fn paint() {}\nfn f(_: super::Shared) {}\n")]));
    assert_eq!(found.len(), 1, "{found:#?}");
    assert!(found[0].contains("src/snow/mod.rs:3: fn run() { coat::paint(); }") && found[0].contains("src/snow/coat.rs:2:"), "{}", found[0]);
    // The same child with a parent that only declares it: no circle.
    let found = file_circles(&folder(&[("lib.rs", lib), ("snow/mod.rs", "mod coat;\npub struct Shared;\n"), ("snow/coat.rs", "fn f(_: super::Shared) {}\n")]));
    assert!(found.is_empty(), "{found:#?}");
    // A parent that re-exports a child's item and uses it in its own code.
    let parent = "mod coat;\npub use coat::Coat;\npub struct Shared(Coat);\n";
    let found = file_circles(&folder(&[("lib.rs", lib), ("snow/mod.rs", parent), ("snow/coat.rs", "pub struct Coat;\nfn f(_: super::Shared) {}\n")]));
    assert_eq!(found.len(), 1, "{found:#?}");
    // Siblings through a module one imports (`use super::window;`, then `window::…` in code).
    let window = "use super::stamp::EMPTY;\npub fn index() -> u32 { EMPTY }\n";
    let stamp = "use super::window;\npub const EMPTY: u32 = 0;\nfn f() -> u32 { window::index() }\n";
    let cpu = "mod stamp;\nmod window;\n";
    let found = file_circles(&folder(&[("lib.rs", "mod cpu;\n"), ("cpu/mod.rs", cpu), ("cpu/stamp.rs", stamp), ("cpu/window.rs", window)]));
    assert_eq!(found.len(), 1, "{found:#?}");
    assert!(found[0].contains("src/cpu/stamp.rs:3: fn f() -> u32 { window::index() }"), "{}", found[0]);
    // A name the crate root brings from another crate is not the root's own.
    let outside = folder(&[
        ("main.rs", "mod bench;\nuse app_lib::BadInput;\nfn main() { bench::run(); }\n"),
        ("bench.rs", "pub fn run() -> Result<(), crate::BadInput> { Ok(()) }\n"),
    ]);
    assert!(file_circles(&outside).is_empty(), "{:#?}", file_circles(&outside));
    // A binary's modules are its own crate: main.rs's files never meet lib.rs's.
    let two = folder(&[
        ("lib.rs", "pub mod a;\n"),
        ("a.rs", "pub struct A;\n"),
        ("main.rs", "mod b;\nmod c;\n"),
        ("b.rs", "use crate::c::C;\npub struct B;\n"),
        ("c.rs", "pub struct C;\n"),
    ]);
    assert!(file_circles(&two).is_empty());
}

#[test]
fn the_real_tree_with_a_planted_file_circle_fails() {
    let mut files = sources();
    assert!(file_circles(&files).is_empty(), "the real tree must be clean before planting");
    // The shader sources come to name the tile streamer, which names them: a circle through two files.
    let shaders = files.iter_mut().find(|(f, _)| f == "shaders.rs").expect("src/shaders.rs");
    shaders.1.push_str("\nfn planted() { let _ = crate::persist::TileStreamer::new; }\n");
    let streamer = files.iter_mut().find(|(f, _)| f == "persist/streamer/mod.rs").expect("src/persist/streamer/mod.rs");
    streamer.1.push_str("\nfn planted_back() { let _ = crate::shaders::UPDATE; }\n");
    let found = file_circles(&files);
    assert!(found.iter().any(|p| p.contains("src/shaders.rs") && p.contains("planted")), "{found:#?}");
}

#[test]
fn the_real_tree_with_a_planted_circle_in_one_module_fails() {
    let mut files = sources();
    // The slot layout comes to name the streaming's copy-out (through the
    // re-export in `streaming/mod.rs`), which names it: two files of `tiles`.
    let planes = files.iter_mut().find(|(f, _)| f == "tiles/planes.rs").expect("src/tiles/planes.rs");
    planes.1.push_str("\nfn planted() { let _ = super::streaming::tile_from_planes; }\n");
    let found = file_circles(&files);
    let circle = found.iter().find(|p| {
        p.contains("tiles/planes.rs → tiles/streaming/copy_out.rs → tiles/planes.rs")
            || p.contains("tiles/streaming/copy_out.rs → tiles/planes.rs → tiles/streaming/copy_out.rs")
    });
    assert!(circle.is_some_and(|p| p.contains("src/tiles/planes.rs:") && p.contains("planted")), "{found:#?}");
}

/// Every `.rs` file of the repository's crates that is not a test: each root
/// crate's `src/` and `examples/`, and the Bevy plugin's (its own workspace,
/// read from here as files), by path from the repository's root.
fn repository_sources() -> Vec<(String, String)> {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut crates: Vec<PathBuf> = std::fs::read_dir(repo.join("crates")).expect("crates/").map(|e| e.expect("entry").path()).collect();
    crates.push(repo.join("integrations/bevy_snowpack"));
    crates.sort();
    let mut out = Vec::new();
    for dir in crates.iter().flat_map(|c| [c.join("src"), c.join("examples")]).filter(|d| d.is_dir()) {
        let mut stack = vec![dir];
        while let Some(d) = stack.pop() {
            for entry in std::fs::read_dir(&d).unwrap_or_else(|e| panic!("reading {}: {e}", d.display())) {
                let path = entry.expect("directory entry").path();
                if path.is_dir() {
                    stack.push(path);
                } else if path.extension().is_some_and(|e| e == "rs") {
                    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
                    let rel = path.strip_prefix(&repo).expect("in the repository").components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>();
                    out.push((rel.join("/"), text));
                }
            }
        }
    }
    assert!(out.iter().any(|(f, _)| f.starts_with("integrations/bevy_snowpack/src/")), "the Bevy plugin's sources were not found");
    out.sort();
    out
}

#[test]
fn no_function_is_longer_than_the_limit() {
    let long = long_functions(&repository_sources(), MAX_FUNCTION_LINES);
    assert!(long.is_empty(), "functions over {MAX_FUNCTION_LINES} lines (split them into steps; tools/long_functions.py lists them):\n{}", long.join("\n"));
}

#[test]
fn a_planted_long_function_is_reported() {
    let body: String = (0..80).map(|k| format!("    let x{k} = {k};\n")).collect();
    let long = format!("fn long() -> u32 {{\n{body}    0\n}}\n");
    let files = vec![("src/planted.rs".to_owned(), format!("fn short() {{}}\n{long}"))];
    assert_eq!(long_functions(&files, MAX_FUNCTION_LINES), ["src/planted.rs:2 long (83 lines)"]);
    // Braces in comments and literals, a declaration without a body and
    // `->` in a signature do not count.
    let tricky = "trait T { fn f(&self) -> u8; }\nfn g<A: Fn() -> u8>(a: A) -> u8 {\n    // }\n    let s = \"}\";\n    a()\n}\n";
    assert_eq!(functions(&code_only(tricky)), [("g".to_owned(), 2, 6)]);
}

/// The crate root's re-exports by the feature that gates them (`""` for
/// none): `pub use` lines of `lib.rs` outside any module, a
/// `#[cfg(feature = "…")]` line before one naming its feature.
fn root_exports(lib: &str) -> BTreeMap<String, BTreeSet<String>> {
    let mut out: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut feature = String::new();
    let code = lib.to_owned();
    let mut lines = code.lines().map(str::trim);
    while let Some(first) = lines.next() {
        // A statement rustfmt wrapped over several lines, joined.
        let mut line = first.to_owned();
        while line.starts_with("pub use ") && !line.ends_with(';') {
            let Some(more) = lines.next() else { break };
            line.push(' ');
            line.push_str(more);
        }
        let line = line.as_str();
        if let Some(rest) = line.strip_prefix("#[cfg(feature = \"") {
            feature = rest.split('"').next().unwrap_or_default().to_owned();
            continue;
        }
        if let Some(tree) = line.strip_prefix("pub use ") {
            let tree = tree.trim_end_matches(';');
            let names = match tree.split_once('{') {
                Some((_, group)) => group.trim_end_matches('}').split(',').map(|s| s.trim().to_owned()).collect::<Vec<_>>(),
                None => vec![tree.rsplit("::").next().unwrap_or(tree).to_owned()],
            };
            out.entry(feature.clone()).or_default().extend(names.into_iter().filter(|n| !n.is_empty()).map(|n| n.rsplit("::").next().unwrap_or(&n).to_owned()));
        }
        if !line.starts_with('#') {
            feature.clear();
        }
    }
    out
}

/// The identifiers in backticks in `text` (a table cell): `SnowPeer`, not
/// `kind()`, `low_level::error` or a feature's name.
fn backticked_items(text: &str) -> BTreeSet<String> {
    text.split('`')
        .skip(1)
        .step_by(2)
        .filter(|w| !w.is_empty() && w.chars().all(|c| c.is_alphanumeric() || c == '_') && !w.starts_with(|c: char| c.is_ascii_digit()))
        .filter(|w| !["low_level", "relay", "renderer", "store", "share"].contains(w))
        .map(str::to_owned)
        .collect()
}

/// The rows of the first table under `heading` in `markdown`: each row's cells.
fn table_rows(markdown: &str, heading: &str) -> Vec<Vec<String>> {
    let after = markdown.split_once(&format!("\n{heading}\n")).map_or("", |(_, rest)| rest);
    after
        .lines()
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'))
        .skip(2)
        .map(|l| l.trim().trim_matches('|').split(" | ").map(|c| c.trim().to_owned()).collect())
        .collect()
}

/// `docs/architecture.md`'s front door says what the root exports: its
/// table is the root's re-exports without features, and the rows of its
/// features table name what `renderer`, `relay`, `store` and `share` add
/// and every root item that only `low_level` adds.
#[test]
fn the_front_door_table_is_the_roots_exports() {
    let lib = std::fs::read_to_string(src().join("lib.rs")).expect("src/lib.rs");
    let exports = root_exports(&lib);
    assert!(exports.get("").is_some_and(|e| e.contains("SnowDeformation")), "the root's re-exports were not read: {exports:?}");
    let table: BTreeSet<String> =
        table_rows(ARCHITECTURE, "## The front door").iter().filter_map(|row| row.get(1)).flat_map(|cell| backticked_items(cell)).collect();
    let root = &exports[""];
    let missing: Vec<&String> = root.difference(&table).collect();
    let extra: Vec<&String> = table.difference(root).collect();
    assert!(
        missing.is_empty() && extra.is_empty(),
        "docs/architecture.md's front-door table: exported at the root but not listed {missing:?}; listed but not exported without features {extra:?}"
    );
    let rows = feature_rows();
    for feature in ["renderer", "relay", "store", "share"] {
        let listed = backticked_items(rows.get(feature).unwrap_or_else(|| panic!("no `{feature}` row in the features table")));
        let exported = exports.get(feature).cloned().unwrap_or_default();
        assert_eq!(listed, exported, "docs/architecture.md's `{feature}` row against the root's `#[cfg(feature = \"{feature}\")]` re-exports");
    }
    // The root is the same with or without `low_level`: what tools need
    // beyond it lives in `snowpack::low_level`, under names of its own.
    let switched: Vec<&String> = exports.get("low_level").into_iter().flatten().collect();
    assert!(switched.is_empty(), "root items that only `low_level` exports (move them into `low_level`): {switched:?}");
    assert!(rows.contains_key("low_level"), "no `low_level` row in the features table");
}

/// The visibility-switching macros issue 42 removed (`low_level_pub!`,
/// `low_level_fields!`, `low_level_some_fields!`: fields and methods that
/// turned public with a feature) are gone from every crate, and none like
/// them is defined again: a type has one shape with or without a feature.
#[test]
fn no_type_changes_shape_with_a_feature() {
    let uses: Vec<String> = repository_sources()
        .iter()
        .flat_map(|(path, text)| {
            let code = code_only(text);
            ["low_level_pub!", "low_level_fields!", "low_level_some_fields!", "macro_rules! low_level"]
                .into_iter()
                .filter(move |m| code.contains(m))
                .map(move |m| format!("{path}: {m}"))
                .collect::<Vec<_>>()
        })
        .collect();
    assert!(uses.is_empty(), "visibility-switching macros: {uses:?}");
}

/// The features table under the front door: feature name → what it adds.
fn feature_rows() -> BTreeMap<String, String> {
    let section = ARCHITECTURE.split_once("\n## The front door\n").map_or("", |(_, rest)| rest);
    let features = section.split_once("\nFeatures:\n").map_or("", |(_, rest)| rest);
    features
        .lines()
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'))
        .skip(2)
        .filter_map(|l| {
            let cells: Vec<&str> = l.trim().trim_matches('|').split(" | ").map(str::trim).collect();
            Some((cells.first()?.trim_matches('`').to_owned(), (*cells.get(1)?).to_owned()))
        })
        .collect()
}

/// What `src/low_level.rs` re-exports, by module path (`low_level`,
/// `low_level::deform::capture`, ...): the last name of each item of each
/// `pub use`. An error names a `pub use` that ends in `*` (a whole module).
fn low_level_items(code: &str) -> Result<BTreeMap<String, BTreeSet<String>>, String> {
    let code = code_only(code);
    let mut out: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut path = vec!["low_level".to_owned()];
    let mut rest = code.as_str();
    while let Some(at) = ["pub mod ", "pub use ", "}"].iter().filter_map(|w| rest.find(w).map(|k| (k, *w))).min() {
        let (k, word) = at;
        rest = &rest[k + word.len()..];
        match word {
            "pub mod " => {
                let (name, after) = rest.split_once('{').ok_or("a `pub mod` without a body")?;
                path.push(name.trim().to_owned());
                rest = after;
            }
            "pub use " => {
                let (tree, after) = rest.split_once(';').ok_or("a `pub use` without `;`")?;
                let tree: String = tree.split_whitespace().collect();
                if tree.ends_with('*') || tree.contains("*,") || tree.contains("*}") {
                    return Err(format!("`pub use {tree}` in `{}` re-exports a whole module", path.join("::")));
                }
                let names = tree.split_once('{').map_or(tree.as_str(), |(_, group)| group.trim_end_matches('}'));
                let entry = out.entry(path.join("::")).or_default();
                entry.extend(names.split(',').filter(|n| !n.is_empty()).map(|n| n.rsplit("::").next().unwrap_or(n).to_owned()));
                rest = after;
            }
            _ => {
                path.pop();
            }
        }
    }
    Ok(out)
}

/// `low_level` is a list of named items, never a whole module nor a root
/// item again, and `docs/architecture.md` ("`low_level`, item by item")
/// lists exactly them.
#[test]
fn the_low_level_list_is_low_levels_named_items() {
    let code = std::fs::read_to_string(src().join("low_level.rs")).expect("src/low_level.rs");
    let items = low_level_items(&code).unwrap_or_else(|e| panic!("src/low_level.rs: {e}"));
    assert!(items.get("low_level::deform::capture").is_some_and(|c| c.contains("CapturePass")), "src/low_level.rs was not read: {items:?}");
    let listed: BTreeMap<String, BTreeSet<String>> = table_rows(ARCHITECTURE, "### `low_level`, item by item")
        .iter()
        .filter_map(|row| Some((row.first()?.trim_matches('`').to_owned(), backticked_items(row.get(1)?))))
        .collect();
    let mut problems = Vec::new();
    for (module, names) in &items {
        let doc = listed.get(module).cloned().unwrap_or_default();
        let missing: Vec<&String> = names.difference(&doc).collect();
        let extra: Vec<&String> = doc.difference(names).collect();
        if !missing.is_empty() || !extra.is_empty() {
            problems.push(format!("`{module}`: re-exported but not listed {missing:?}; listed but not re-exported {extra:?}"));
        }
    }
    problems.extend(listed.keys().filter(|m| !items.contains_key(*m)).map(|m| format!("`{m}` is listed but src/low_level.rs has no such module")));
    // Beyond the front door only: nothing the root exports (with any
    // feature) again, but for the errors' detailed enums, which carry the
    // opaque root errors' names.
    let lib = std::fs::read_to_string(src().join("lib.rs")).expect("src/lib.rs");
    let root: BTreeSet<String> = root_exports(&lib).into_values().flatten().collect();
    let details = ["SnowError", "StoreError", "ShareError"];
    for (module, names) in &items {
        let again: Vec<&String> = names.iter().filter(|n| root.contains(*n) && !details.contains(&n.as_str())).collect();
        if !again.is_empty() {
            problems.push(format!("`{module}` re-exports what the root already exports: {again:?}"));
        }
    }
    assert!(problems.is_empty(), "docs/architecture.md's `low_level` list against src/low_level.rs:\n{}", problems.join("\n"));
}

/// A glob re-export planted in `low_level` is reported, at any depth.
#[test]
fn a_planted_glob_in_low_level_is_reported() {
    let named =
        "pub use crate::a::Ext;\npub mod deform {\n    pub mod capture {\n        pub use crate::deform::capture::{CapturePass, CaptureParams};\n    }\n}\n";
    let items = low_level_items(named).expect("named items only");
    assert_eq!(items["low_level"], BTreeSet::from(["Ext".to_owned()]));
    assert_eq!(items["low_level::deform::capture"], BTreeSet::from(["CaptureParams".to_owned(), "CapturePass".to_owned()]));
    for planted in ["pub mod tiles {\n    pub use crate::tiles::*;\n}\n", "pub mod a {\n    pub use crate::a::{B, c::*};\n}\n"] {
        let err = low_level_items(&format!("{named}{planted}")).expect_err("a glob must be reported");
        assert!(err.contains("whole module"), "{err}");
    }
}

/// The crate a repository path belongs to: `crates/snowpack`, `integrations/bevy_snowpack`.
fn crate_of(path: &str) -> String {
    path.split('/').take(2).collect::<Vec<_>>().join("/")
}

/// Per crate and type name: the inherent `impl` blocks (`path:line`) and
/// how many types of that name the crate defines (`struct`, `enum`,
/// `union`; two modules may each have their own `Reader`).
fn impl_blocks(files: &[(String, String)]) -> BTreeMap<(String, String), (Vec<String>, usize)> {
    let ident = |s: &str| s.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect::<String>();
    let mut out: BTreeMap<(String, String), (Vec<String>, usize)> = BTreeMap::new();
    for (path, text) in files {
        let code = code_only(text);
        let krate = crate_of(path);
        for line in code.lines() {
            let words: Vec<&str> = line.split_whitespace().collect();
            if let Some(k) = words.iter().position(|w| ["struct", "enum", "union"].contains(w))
                && words[..k].iter().all(|w| w.starts_with("pub") || w.starts_with("#["))
                && let Some(name) = words.get(k + 1).map(|w| ident(w)).filter(|w| !w.is_empty())
            {
                out.entry((krate.clone(), name)).or_default().1 += 1;
            }
        }
        let mut rest = code.as_str();
        let mut offset = 0;
        while let Some(k) = rest.find("impl") {
            let at = offset + k;
            let before = code[..at].chars().next_back();
            rest = &rest[k + 4..];
            offset = at + 4;
            // `impl` as a word at the start of an item (a line), not `impl Trait` in a signature.
            let line_start = code[..at].rfind('\n').map_or(0, |p| p + 1);
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_') || !code[line_start..at].trim().is_empty() {
                continue;
            }
            let Some(head) = rest.split('{').next() else { continue };
            if !rest.starts_with([' ', '<']) || head.contains(" for ") || head.contains(';') {
                continue;
            }
            // Skip the impl's own generics, then take the type's last path segment.
            let mut ty = head.trim_start();
            if ty.starts_with('<') {
                let mut depth = 0;
                let end = ty.char_indices().find(|&(_, c)| {
                    depth += i32::from(c == '<') - i32::from(c == '>');
                    depth == 0
                });
                ty = end.map_or("", |(e, _)| &ty[e + 1..]).trim_start();
            }
            let path_part: String = ty.chars().take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':').collect();
            let name = path_part.rsplit("::").next().unwrap_or_default().to_owned();
            if !name.is_empty() {
                let line = code[..at].matches('\n').count() + 1;
                out.entry((krate.clone(), name)).or_default().0.push(format!("{path}:{line}"));
            }
        }
    }
    out
}

/// Types whose inherent `impl` blocks outnumber the types of that name.
fn split_impls(files: &[(String, String)]) -> Vec<String> {
    impl_blocks(files)
        .into_iter()
        .filter(|(_, (blocks, defined))| *defined > 0 && blocks.len() > *defined)
        .map(|((krate, name), (blocks, _))| format!("{krate}: `{name}` has {} inherent impl blocks: {}", blocks.len(), blocks.join(", ")))
        .collect()
}

/// Every type has one inherent `impl` block, in every crate of the
/// repository (issue 42, item 2): its methods are in one place, and a
/// type's behaviour spread over files (each adding an `impl`) is reported.
#[test]
fn every_type_has_one_inherent_impl_block() {
    let files = repository_sources();
    let blocks = impl_blocks(&files);
    assert!(blocks.get(&("crates/snowpack".to_owned(), "SnowDeformation".to_owned())).is_some_and(|(b, d)| b.len() == 1 && *d == 1), "impl blocks not read");
    let split = split_impls(&files);
    assert!(split.is_empty(), "types with more than one inherent impl block (join them, or hand the work to a part that owns it):\n{}", split.join("\n"));
}

/// A second `impl` block planted in another file is reported; trait impls,
/// `impl Trait` in signatures and two types of one name are not.
#[test]
fn a_planted_second_impl_block_is_reported() {
    let files = |second: &str| {
        vec![
            ("crates/x/src/a.rs".to_owned(), "pub struct Wheel;\nimpl Wheel {\n    fn a(&self) -> impl Iterator<Item = u8> { None.into_iter() }\n}\nimpl Default for Wheel { fn default() -> Self { Wheel } }\nmod m {\n    pub struct Reader;\n    impl Reader {}\n}\n".to_owned()),
            ("crates/x/src/b.rs".to_owned(), format!("pub struct Reader;\nimpl Reader {{}}\nimpl<'a> std::fmt::Debug for Reader {{}}\n{second}")),
        ]
    };
    assert!(split_impls(&files("")).is_empty(), "{:?}", split_impls(&files("")));
    let found = split_impls(&files("impl<T> crate::a::Wheel<T> {\n    fn b(&self) {}\n}\n"));
    assert_eq!(found, ["crates/x: `Wheel` has 2 inherent impl blocks: crates/x/src/a.rs:2, crates/x/src/b.rs:4"]);
}
