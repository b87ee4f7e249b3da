//! Finds the branches of a shader whose condition reads uniforms alone (and
//! constants): an `if`, a `switch` selector or a loop's `break if`.
//!
//! Mesa 22's lavapipe (Debian 12's) inlines the values of such uniforms
//! into a fresh copy of the shader, compiles it and keeps it, at every
//! dispatch or draw, even with the same values: the process grew by up to
//! 0.7 MiB a frame (docs/deformation.md, "Branches on uniforms"). Such a
//! choice is a pipeline's (an `override` constant), or the condition also
//! reads something of the invocation's (a texel, an index).
//!
//! The analysis follows values through the IR naga built: a value is
//! constant (literals, constants, `override`s), uniform (computed from
//! uniform-buffer loads and constants only) or varying (anything else: a
//! builtin, a storage or texture read, a loop-carried variable). Function
//! calls are analysed with their arguments' kinds, as a compiler inlines
//! them. The `override` idiom of the passes built per choice,
//! `if NAME != 0xffffffffu { return NAME; } return params.x;`, is read as a
//! set constant (every pipeline is built with it), so the uniform fallback
//! after it is dead code and not reported.

use std::collections::HashMap;

use naga::{Block, Expression, Function, Handle, Module, Statement};

/// Branches on uniforms alone that are allowed, as (shader constant,
/// function, why).
pub const ALLOWED: &[(&str, &str, &str)] = &[(
    "GROUND",
    "terrain_height_of_kind",
    "the terrain kind of the snow sampling module games import (`SNOW_SAMPLING_WGSL`), which has no override constants by design; \
     a select would evaluate the noise and the heightmap at every pixel",
)];

/// What a value depends on, from least to most.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
enum Kind {
    /// Literals, constants and `override`s only.
    Constant,
    /// Uniform-buffer loads and constants only, at least one load.
    Uniform,
    /// Anything else.
    Varying,
}

fn join(a: Kind, b: Kind) -> Kind {
    a.max(b)
}

/// Each call's result expression, with the function called and its arguments.
type Calls = HashMap<Handle<Expression>, (Handle<Function>, Vec<Handle<Expression>>)>;

/// One branch on uniforms alone: where, for the build error.
pub struct Finding {
    /// The function it is in.
    pub function: String,
    /// Line of the condition in the composed source.
    pub line: u32,
    /// The condition's text.
    pub text: String,
}

/// Every branch on uniforms alone reachable from `module`'s entry points.
pub fn find(module: &Module, source: &str) -> Vec<Finding> {
    let mut analysis = Analysis { module, source, memo: HashMap::new(), reported: std::collections::HashSet::new(), quiet: false, findings: Vec::new() };
    for entry in &module.entry_points {
        let args = vec![Kind::Varying; entry.function.arguments.len()];
        analysis.function(&entry.function, &args);
    }
    let mut seen = std::collections::HashSet::new();
    analysis.findings.retain(|f| seen.insert((f.function.clone(), f.line, f.text.clone())));
    analysis.findings
}

struct Analysis<'m> {
    module: &'m Module,
    source: &'m str,
    /// Return kind of each function for its argument kinds.
    memo: HashMap<(Handle<Function>, Vec<Kind>), Kind>,
    /// The functions and argument kinds whose branches have been reported.
    reported: std::collections::HashSet<(Handle<Function>, Vec<Kind>)>,
    /// Set while a caller's local variables are still being settled: the
    /// argument kinds seen then may be below the final ones, so nothing is
    /// reported.
    quiet: bool,
    findings: Vec<Finding>,
}

/// The kinds of one function's expressions and local variables, for one
/// set of argument kinds.
struct Frame<'f> {
    function: &'f Function,
    args: &'f [Kind],
    exprs: Vec<Kind>,
    locals: Vec<Kind>,
    /// The function and arguments of each call's result expression.
    calls: Calls,
}

impl<'m> Analysis<'m> {
    /// Analyses `function` with `args`, reporting its branches on uniforms
    /// alone; returns the kind of what it returns.
    fn function(&mut self, function: &Function, args: &[Kind]) -> Kind {
        let mut frame = Frame {
            function,
            args,
            exprs: vec![Kind::Constant; function.expressions.len()],
            locals: vec![Kind::Constant; function.local_variables.len()],
            calls: HashMap::new(),
        };
        collect_calls(&function.body, &mut frame.calls);
        let quiet = std::mem::replace(&mut self.quiet, true);
        // Local variables take the kinds of what is stored in them (and a
        // variable stored inside a loop becomes a loop-carried value,
        // varying); a few rounds reach the fixed point.
        for _ in 0..8 {
            self.evaluate(&mut frame);
            let before = frame.locals.clone();
            let mut stores = Vec::new();
            self.walk_stores(&frame, &function.body, Kind::Constant, &mut stores);
            for (local, kind) in stores {
                frame.locals[local] = join(frame.locals[local], kind);
            }
            for (handle, local) in function.local_variables.iter() {
                if let Some(init) = local.init {
                    frame.locals[handle.index()] = join(frame.locals[handle.index()], frame.exprs[init.index()]);
                }
            }
            if frame.locals == before {
                break;
            }
        }
        self.quiet = quiet;
        self.evaluate(&mut frame);
        let name = function.name.clone().unwrap_or_else(|| "(entry point)".into());
        let mut returned = Kind::Constant;
        self.walk_branches(&frame, &function.body, &name, &mut returned);
        returned
    }

    /// Each expression's kind, in arena order (operands come first).
    fn evaluate(&mut self, frame: &mut Frame<'_>) {
        for (handle, expr) in frame.function.expressions.iter() {
            let k = |h: Handle<Expression>| frame.exprs[h.index()];
            let kind = match *expr {
                Expression::Literal(_) | Expression::Constant(_) | Expression::Override(_) | Expression::ZeroValue(_) => Kind::Constant,
                Expression::Compose { ref components, .. } => components.iter().map(|&c| k(c)).fold(Kind::Constant, join),
                Expression::Access { base, index } => join(k(base), k(index)),
                Expression::AccessIndex { base, .. } => k(base),
                Expression::Splat { value, .. } => k(value),
                Expression::Swizzle { vector, .. } => k(vector),
                Expression::FunctionArgument(i) => frame.args.get(i as usize).copied().unwrap_or(Kind::Varying),
                Expression::GlobalVariable(g) => {
                    if self.module.global_variables[g].space == naga::AddressSpace::Uniform {
                        Kind::Uniform
                    } else {
                        Kind::Varying
                    }
                }
                Expression::LocalVariable(l) => frame.locals[l.index()],
                Expression::Load { pointer } => k(pointer),
                Expression::Unary { expr, .. } => k(expr),
                Expression::Binary { left, right, .. } => join(k(left), k(right)),
                Expression::Select { condition, accept, reject } => join(k(condition), join(k(accept), k(reject))),
                Expression::Relational { argument, .. } => k(argument),
                Expression::Math { arg, arg1, arg2, arg3, .. } => [Some(arg), arg1, arg2, arg3].into_iter().flatten().map(k).fold(Kind::Constant, join),
                Expression::As { expr, .. } => k(expr),
                Expression::CallResult(_) => match frame.calls.get(&handle).cloned() {
                    Some((callee, arguments)) => {
                        let kinds: Vec<Kind> = arguments.iter().map(|&a| k(a)).collect();
                        self.call(callee, kinds)
                    }
                    None => Kind::Varying,
                },
                _ => Kind::Varying,
            };
            frame.exprs[handle.index()] = kind;
        }
    }

    /// The return kind of `callee` with `args` (analysed once per set).
    fn call(&mut self, callee: Handle<Function>, args: Vec<Kind>) -> Kind {
        let key = (callee, args);
        if let Some(&kind) = self.memo.get(&key)
            && (self.quiet || self.reported.contains(&key))
        {
            return kind;
        }
        let module = self.module;
        let kind = self.function(&module.functions[callee], &key.1);
        if !self.quiet {
            self.reported.insert(key.clone());
        }
        self.memo.insert(key, kind);
        kind
    }

    /// Whether `condition` is the override idiom's test, and its value: an
    /// `override` compared with its own default (the passes build every
    /// pipeline with the constant set, so it never has its default).
    fn override_test(&self, frame: &Frame<'_>, condition: Handle<Expression>) -> Option<bool> {
        let Expression::Binary { op, left, right } = frame.function.expressions[condition] else { return None };
        let (Expression::Override(o), Expression::Literal(value)) = (&frame.function.expressions[left], &frame.function.expressions[right]) else {
            return None;
        };
        let default = self.module.overrides[*o].init.map(|init| &self.module.global_expressions[init])?;
        let same = matches!(default, Expression::Literal(d) if d == value);
        match op {
            naga::BinaryOperator::NotEqual if same => Some(true),
            naga::BinaryOperator::Equal if same => Some(false),
            _ => None,
        }
    }

    /// The kinds stored into local variables in the live code of `block`,
    /// where `control` is the kind of the conditions it runs under: a value
    /// stored under a varying condition is a varying choice between it and
    /// the variable's other values (the compiler's phi or select), and one
    /// stored in a loop is carried round it (varying).
    fn walk_stores(&self, frame: &Frame<'_>, block: &Block, control: Kind, out: &mut Vec<(usize, Kind)>) {
        for statement in block.iter() {
            match *statement {
                Statement::Store { pointer, value } => {
                    if let Some(local) = local_of(frame.function, pointer) {
                        out.push((local, join(control, frame.exprs[value.index()])));
                    }
                }
                Statement::Block(ref b) => self.walk_stores(frame, b, control, out),
                Statement::If { condition, ref accept, ref reject } => match self.override_test(frame, condition) {
                    Some(true) => self.walk_stores(frame, accept, control, out),
                    Some(false) => self.walk_stores(frame, reject, control, out),
                    None => {
                        let inner = join(control, frame.exprs[condition.index()]);
                        self.walk_stores(frame, accept, inner, out);
                        self.walk_stores(frame, reject, inner, out);
                    }
                },
                Statement::Switch { selector, ref cases } => {
                    let inner = join(control, frame.exprs[selector.index()]);
                    cases.iter().for_each(|c| self.walk_stores(frame, &c.body, inner, out));
                }
                Statement::Loop { ref body, ref continuing, .. } => {
                    self.walk_stores(frame, body, Kind::Varying, out);
                    self.walk_stores(frame, continuing, Kind::Varying, out);
                }
                _ => {}
            }
        }
    }

    /// Reports the branches on uniforms alone in the live code of `block`
    /// and gathers the kinds it returns. Returns whether `block` always
    /// returns (what follows it is dead).
    fn walk_branches(&mut self, frame: &Frame<'_>, block: &Block, name: &str, returned: &mut Kind) -> bool {
        for statement in block.iter() {
            match *statement {
                Statement::Return { value } => {
                    *returned = join(*returned, value.map_or(Kind::Constant, |v| frame.exprs[v.index()]));
                    return true;
                }
                Statement::Block(ref b) if self.walk_branches(frame, b, name, returned) => return true,
                Statement::If { condition, ref accept, ref reject } => {
                    let ends = match self.override_test(frame, condition) {
                        Some(true) => self.walk_branches(frame, accept, name, returned),
                        Some(false) => self.walk_branches(frame, reject, name, returned),
                        None => {
                            self.report(frame, condition, name);
                            let a = self.walk_branches(frame, accept, name, returned);
                            let r = self.walk_branches(frame, reject, name, returned);
                            a && r
                        }
                    };
                    if ends {
                        return true;
                    }
                }
                Statement::Call { function, ref arguments, result: None } => {
                    let kinds = arguments.iter().map(|a| frame.exprs[a.index()]).collect();
                    self.call(function, kinds);
                }
                Statement::Switch { selector, ref cases } => {
                    self.report(frame, selector, name);
                    for case in cases {
                        self.walk_branches(frame, &case.body, name, returned);
                    }
                }
                Statement::Loop { ref body, ref continuing, break_if } => {
                    self.walk_branches(frame, body, name, returned);
                    self.walk_branches(frame, continuing, name, returned);
                    if let Some(condition) = break_if {
                        self.report(frame, condition, name);
                    }
                }
                _ => {}
            }
        }
        false
    }

    fn report(&mut self, frame: &Frame<'_>, condition: Handle<Expression>, name: &str) {
        if self.quiet || frame.exprs[condition.index()] != Kind::Uniform {
            return;
        }
        let span = frame.function.expressions.get_span(condition);
        let (line, text) = if span.is_defined() {
            let location = span.location(self.source);
            let text = self.source.get(location.offset as usize..(location.offset + location.length) as usize).unwrap_or("?");
            (location.line_number, text.to_owned())
        } else {
            (0, format!("{:?}", frame.function.expressions[condition]))
        };
        self.findings.push(Finding { function: name.to_owned(), line, text });
    }
}

/// The local variable a store's pointer reaches (through accesses), if any.
fn local_of(function: &Function, mut pointer: Handle<Expression>) -> Option<usize> {
    loop {
        match function.expressions[pointer] {
            Expression::LocalVariable(l) => return Some(l.index()),
            Expression::Access { base, .. } | Expression::AccessIndex { base, .. } => pointer = base,
            _ => return None,
        }
    }
}

/// Each call statement's result expression, with its function and arguments.
fn collect_calls(block: &Block, out: &mut Calls) {
    for statement in block.iter() {
        match *statement {
            Statement::Call { function, ref arguments, result: Some(result) } => {
                out.insert(result, (function, arguments.clone()));
            }
            Statement::Block(ref b) => collect_calls(b, out),
            Statement::If { ref accept, ref reject, .. } => {
                collect_calls(accept, out);
                collect_calls(reject, out);
            }
            Statement::Switch { ref cases, .. } => cases.iter().for_each(|c| collect_calls(&c.body, out)),
            Statement::Loop { ref body, ref continuing, .. } => {
                collect_calls(body, out);
                collect_calls(continuing, out);
            }
            _ => {}
        }
    }
}
