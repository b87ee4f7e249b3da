//! The build's check for branches on uniforms alone (`build/uniform_branches.rs`,
//! docs/deformation.md "Branches on uniforms"): Mesa 22's lavapipe compiles
//! a shader with such a branch again at every dispatch or draw and keeps
//! every copy, so the build refuses one. Here the check is tried on small
//! shaders that have one, in each form it takes, and on ones that choose
//! the ways the passes do (an `override` constant, a select, the
//! invocation's test first), and it is run over every shipped shader.

#[path = "../build/uniform_branches.rs"]
mod uniform_branches;

/// The findings in `body` (a compute entry point's statements) after the
/// shared declarations, as (function, condition text).
fn findings(functions: &str, body: &str) -> Vec<(String, String)> {
    let source = format!(
        "struct P {{ flag: u32, count: u32, depth: f32, kind: u32 }}
@group(0) @binding(0) var<uniform> params: P;
@group(0) @binding(1) var<storage, read_write> out: array<f32>;
override CHOICE: u32 = 0xffffffffu;
{functions}
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {{
    let i = id.x;
    var v = f32(i);
{body}
    out[i] = v;
}}"
    );
    let module = naga::front::wgsl::parse_str(&source).unwrap_or_else(|e| panic!("{}", e.emit_to_string(&source)));
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
        .validate(&module)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&source)));
    uniform_branches::find(&module, &source).into_iter().map(|f| (f.function, f.text)).collect()
}

fn found(functions: &str, body: &str) -> bool {
    !findings(functions, body).is_empty()
}

#[test]
fn a_branch_on_uniforms_alone_is_found_in_each_form() {
    // An `if`, a `switch`, a loop's exit, a condition made of several uniforms.
    assert_eq!(findings("", "    if params.flag != 0u { v = 1.0; }"), vec![("main".to_owned(), "params.flag != 0u".to_owned())]);
    assert!(found("", "    switch params.kind { case 1u: { v = 2.0; } default: {} }"));
    assert!(found("", "    loop { v += 1.0; continuing { break if params.depth > 0.0; } }"));
    assert!(found("", "    if params.depth <= 0.0 && params.count > 2u { v = 0.0; }"));
    // Through a local variable, and through a helper's argument.
    assert!(found("", "    let d = params.depth * 2.0;\n    var e = d;\n    if e > 1.0 { v = 0.0; }"));
    assert!(found("fn helper(x: u32) -> f32 { if x > 2u { return 1.0; } return 0.0; }", "    v += helper(params.count);"));
    // The uniform first in a `&&` is a branch of its own.
    assert!(found("", "    if params.flag != 0u && i > 3u { v = 0.0; }"));
}

#[test]
fn choices_made_as_the_passes_make_them_are_not_reported() {
    // The pass's constant, in the idiom of the passes built per choice.
    let idiom = "fn choice() -> u32 { if CHOICE != 0xffffffffu { return CHOICE; } return params.flag; }";
    assert!(!found(idiom, "    if (choice() & 1u) != 0u { v = 1.0; }"));
    // A select, the invocation's test first, a condition that reads a texel.
    assert!(!found("", "    v = select(v, 0.0, params.flag != 0u);"));
    assert!(!found("", "    if i > 3u && params.flag != 0u { v = 0.0; }"));
    assert!(!found("", "    if params.depth + out[i] <= 0.0 { v = 0.0; }"));
    // A helper whose argument is the invocation's, and a variable set under
    // the invocation's test.
    assert!(!found("fn helper(x: u32) -> f32 { if x > 2u { return 1.0; } return 0.0; }", "    v += helper(i);"));
    assert!(!found("", "    var e = 0.0;\n    if i > 3u { e = params.depth; }\n    if e > 1.0 { v = 0.0; }"));
    // A loop counter is carried round the loop, whatever bounds it.
    assert!(!found("", "    for (var k = 0u; k < params.count; k++) { v += 1.0; }"));
}

#[test]
fn the_shipped_shaders_branch_on_uniforms_only_where_allowed() {
    let mut checked = 0;
    for (name, source) in snowpack::low_level::shaders::ALL {
        let module = naga::front::wgsl::parse_str(source).expect("the build validated it");
        for f in uniform_branches::find(&module, source) {
            assert!(
                uniform_branches::ALLOWED.iter().any(|(shader, function, _)| shader == name && *function == f.function),
                "{name}: fn {} branches on uniforms alone: {}",
                f.function,
                f.text
            );
        }
        checked += 1;
    }
    assert!(checked > 30, "only {checked} shaders");
}
