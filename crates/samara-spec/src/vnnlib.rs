//! VNN-LIB 1.0 (the SMT-LIB-based property format of VNN-COMP) export and import.
//!
//! Export writes a query with one network application: `X_i` inputs and `Y_j` outputs
//! of the ONNX file (its own units), the input box as top-level bounds, and the
//! counterexample region as `(assert (or (and ...) ...))`. A VNN-LIB file states what
//! a counterexample satisfies, exactly samara's normal form. Strict comparisons are
//! written `<` (SMT-LIB semantics; many VNN-COMP tools read them as `<=`). Relational
//! queries (two or more network calls) and free parameters cannot be expressed.
//!
//! Import reads declarations, `assert`s of `<=`, `>=`, `<`, `>`, `=` over linear terms
//! (`+`, `-`, `*` by a constant, numbers), `and`/`or`: single-variable bounds on `X_i`
//! at the top level become the input box; everything else becomes the region. See
//! [`read`] for exactly what is accepted and the limits.

use crate::normal::{Application, Cmp, Constraint, Goal, LinExpr, Query, Var};
use std::collections::HashMap;
use std::fmt::Write as _;

/// Why a query cannot be exported or a file not imported.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum VnnlibError {
    /// The query does not fit VNN-LIB.
    #[error("query `{0}` cannot be written as VNN-LIB: {1}")]
    Unsupported(String, String),
    /// A syntax or semantic error in a file, at a 1-based line and column.
    #[error("{file}:{line}:{col}: {message}")]
    Parse {
        /// File.
        file: String,
        /// Line.
        line: usize,
        /// Column.
        col: usize,
        /// What is wrong (and how to fix it).
        message: String,
    },
}

fn num(v: f64) -> String {
    if v < 0.0 {
        format!("(- {:?})", -v)
    } else {
        format!("{v:?}")
    }
}

fn term(e: &LinExpr) -> String {
    let mut parts: Vec<String> = e
        .terms
        .iter()
        .map(|(v, c)| {
            let name = match v {
                Var::Input { index, .. } => format!("X_{index}"),
                Var::Output { index, .. } => format!("Y_{index}"),
                Var::Free(k) => format!("P_{k}"),
            };
            if *c == 1.0 {
                name
            } else {
                format!("(* {} {name})", num(*c))
            }
        })
        .collect();
    if e.constant != 0.0 || parts.is_empty() {
        parts.push(num(e.constant));
    }
    if parts.len() == 1 {
        parts.pop().expect("one")
    } else {
        format!("(+ {})", parts.join(" "))
    }
}

fn atom(c: &Constraint) -> String {
    let op = match c.cmp {
        Cmp::Le => "<=",
        Cmp::Lt => "<",
        Cmp::Eq => "=",
    };
    format!("({op} {} 0.0)", term(&c.expr))
}

/// A relational query (several calls of one network) as a single-call query over the
/// `k`-fold stacked network (`samara_nn::Network::stacked`): application `a`'s input `i`
/// becomes input `a * n + i`, and likewise for outputs. Returns the rewritten query and
/// `k`; `None` if the applications use different networks.
pub fn stack_applications(q: &Query) -> Option<(Query, usize)> {
    let k = q.applications.len();
    let first = q.applications.first()?;
    if q.applications.iter().any(|a| {
        a.network != first.network || a.n_inputs != first.n_inputs || a.n_outputs != first.n_outputs
    }) {
        return None;
    }
    let (n, m) = (first.n_inputs, first.n_outputs);
    let map = |v: Var| match v {
        Var::Input { app, index } => Var::Input {
            app: 0,
            index: app * n + index,
        },
        Var::Output { app, index } => Var::Output {
            app: 0,
            index: app * m + index,
        },
        f => f,
    };
    let mut out = q.clone();
    out.applications = vec![Application {
        network: format!("{}x{k}", first.network),
        n_inputs: n * k,
        n_outputs: m * k,
        input_box: q
            .applications
            .iter()
            .flat_map(|a| a.input_box.iter().copied())
            .collect(),
    }];
    for conj in &mut out.region {
        for c in conj.iter_mut() {
            for t in c.expr.terms.iter_mut() {
                t.0 = map(t.0);
            }
        }
    }
    Some((out, k))
}

/// One query per disjunct, for verifiers that do not read `or`.
pub fn split_disjuncts(q: &Query) -> Vec<Query> {
    q.region
        .iter()
        .enumerate()
        .map(|(d, conj)| Query {
            name: format!("{}_{d}", q.name),
            region: vec![conj.clone()],
            ..q.clone()
        })
        .collect()
}

/// Write a query as VNN-LIB text.
pub fn export(q: &Query) -> Result<String, VnnlibError> {
    if q.applications.len() != 1 {
        return Err(VnnlibError::Unsupported(
            q.name.clone(),
            format!(
                "it calls networks {} times; VNN-LIB has one network",
                q.applications.len()
            ),
        ));
    }
    if !q.free_vars.is_empty() || q.goal != Goal::Prove {
        return Err(VnnlibError::Unsupported(
            q.name.clone(),
            "critical-value queries have a free parameter; bind it with --param".into(),
        ));
    }
    let a = &q.applications[0];
    let mut s = format!(
        "; samara property `{}` (network `{}`): a counterexample satisfies every assertion\n",
        q.name, a.network
    );
    for i in 0..a.n_inputs {
        let _ = writeln!(s, "(declare-const X_{i} Real)");
    }
    for j in 0..a.n_outputs {
        let _ = writeln!(s, "(declare-const Y_{j} Real)");
    }
    for (i, (lo, hi)) in a.input_box.iter().enumerate() {
        if lo.is_finite() {
            let _ = writeln!(s, "(assert (>= X_{i} {}))", num(*lo));
        }
        if hi.is_finite() {
            let _ = writeln!(s, "(assert (<= X_{i} {}))", num(*hi));
        }
    }
    let disj: Vec<String> = q
        .region
        .iter()
        .map(|conj| {
            format!(
                "(and {})",
                conj.iter().map(atom).collect::<Vec<_>>().join(" ")
            )
        })
        .collect();
    let _ = writeln!(s, "(assert (or {}))", disj.join("\n    "));
    Ok(s)
}

/// The deepest parenthesis nesting an imported file may have (VNN-COMP files nest 4
/// deep); deeper input is refused with its line:column.
pub const MAX_DEPTH: usize = 256;

/// The most inputs, and the most outputs, a file may declare.
pub const MAX_VARS: usize = 1 << 24;

/// The most cases (conjunctions) an imported counterexample region may expand to; a
/// file that would expand to more is refused before anything is expanded.
pub const MAX_CASES: u64 = 1 << 16;

/// The most constraints in all (cases times constraints per case, counted before
/// expanding) an imported region may hold.
pub const MAX_CONSTRAINTS: u64 = 1 << 24;

/// A VNN-LIB file as read: the variables it declares and the query it states.
#[derive(Clone, Debug, PartialEq)]
pub struct Property {
    /// Declared inputs: the file declares exactly `X_0 .. X_{n_inputs - 1}`.
    pub n_inputs: usize,
    /// Declared outputs: the file declares exactly `Y_0 .. Y_{n_outputs - 1}`.
    pub n_outputs: usize,
    /// The `Prove` query (one application with `n_inputs` inputs and `n_outputs`
    /// outputs).
    pub query: Query,
}

impl Property {
    /// `(inputs, outputs)` the file declares, to compare with the network's.
    pub fn declared(&self) -> (usize, usize) {
        (self.n_inputs, self.n_outputs)
    }
}

type Pos = crate::syntax::Pos;

#[derive(Debug)]
enum Sx {
    Atom(String, Pos),
    List(Vec<Sx>, Pos),
}

impl Sx {
    fn pos(&self) -> Pos {
        match self {
            Sx::Atom(_, p) | Sx::List(_, p) => *p,
        }
    }
}

struct Reader<'a> {
    file: &'a str,
}

impl Reader<'_> {
    fn err(&self, pos: Pos, message: impl Into<String>) -> VnnlibError {
        VnnlibError::Parse {
            file: self.file.into(),
            line: pos.line,
            col: pos.col,
            message: message.into(),
        }
    }

    /// The s-expressions of the text, read without recursion.
    fn sexprs(&self, text: &str) -> Result<Vec<Sx>, VnnlibError> {
        let mut stack: Vec<(Vec<Sx>, Pos)> = vec![(vec![], Pos { line: 1, col: 1 })];
        let mut chars = text.chars().peekable();
        let (mut line, mut col) = (1usize, 1usize);
        let mut tok = String::new();
        let mut tok_pos = Pos { line, col };
        let flush = |tok: &mut String, at: Pos, stack: &mut Vec<(Vec<Sx>, Pos)>| {
            if !tok.is_empty() {
                if let Some(top) = stack.last_mut() {
                    top.0.push(Sx::Atom(std::mem::take(tok), at));
                }
            }
        };
        while let Some(c) = chars.next() {
            let here = Pos { line, col };
            if c == '\n' {
                line += 1;
                col = 1;
            } else {
                col += 1;
            }
            match c {
                ';' => {
                    flush(&mut tok, tok_pos, &mut stack);
                    while let Some(&d) = chars.peek() {
                        if d == '\n' {
                            break;
                        }
                        chars.next();
                        col += 1;
                    }
                }
                '(' => {
                    flush(&mut tok, tok_pos, &mut stack);
                    if stack.len() > MAX_DEPTH {
                        return Err(self.err(
                            here,
                            format!(
                                "parentheses nested deeper than {MAX_DEPTH} levels; split the formula"
                            ),
                        ));
                    }
                    stack.push((vec![], here));
                }
                ')' => {
                    flush(&mut tok, tok_pos, &mut stack);
                    if stack.len() == 1 {
                        return Err(self.err(here, "unbalanced `)`: nothing to close"));
                    }
                    let (l, at) = stack.pop().expect("more than one");
                    stack
                        .last_mut()
                        .expect("at least one")
                        .0
                        .push(Sx::List(l, at));
                }
                '"' | '|' => {
                    return Err(self.err(
                        here,
                        format!(
                            "`{c}`: strings and quoted symbols are not part of VNN-LIB properties"
                        ),
                    ))
                }
                c if c.is_whitespace() => flush(&mut tok, tok_pos, &mut stack),
                c => {
                    if tok.is_empty() {
                        tok_pos = here;
                    }
                    tok.push(c);
                }
            }
        }
        flush(&mut tok, tok_pos, &mut stack);
        if stack.len() != 1 {
            let at = stack.last().map_or(Pos { line: 1, col: 1 }, |s| s.1);
            return Err(self.err(at, "unbalanced parentheses: this `(` is not closed"));
        }
        Ok(stack.pop().expect("one").0)
    }

    /// `X_i` / `Y_j` as (is_output, index); `None` if the name is neither.
    fn var_name(&self, a: &str, pos: Pos) -> Result<Option<(bool, usize)>, VnnlibError> {
        let (out, digits) = if let Some(d) = a.strip_prefix("X_") {
            (false, d)
        } else if let Some(d) = a.strip_prefix("Y_") {
            (true, d)
        } else {
            return Ok(None);
        };
        if digits.is_empty()
            || !digits.bytes().all(|b| b.is_ascii_digit())
            || (digits.len() > 1 && digits.starts_with('0'))
        {
            return Err(self.err(
                pos,
                format!("bad variable `{a}`: write X_i or Y_j with i, j = 0, 1, 2, ..."),
            ));
        }
        match digits.parse::<usize>() {
            Ok(i) if i < MAX_VARS => Ok(Some((out, i))),
            _ => Err(self.err(
                pos,
                format!("variable `{a}`: index beyond the cap of {MAX_VARS} variables"),
            )),
        }
    }
}

/// A formula of an assertion, atoms already linear constraints.
enum F {
    Atom(Constraint),
    And(Vec<F>),
    Or(Vec<F>),
}

/// (cases, constraints per case) of a formula's disjunctive normal form, saturating;
/// cases counted at least 1 where they multiply, so that the bound holds for every
/// intermediate product too.
fn size(f: &F) -> (u64, u64) {
    match f {
        F::Atom(_) => (1, 1),
        F::Or(v) => v
            .iter()
            .map(size)
            .fold((0, 0), |(n, l), (m, k)| (n.saturating_add(m), l.max(k))),
        F::And(v) => v.iter().map(size).fold((1, 0), |(n, l), (m, k)| {
            (n.saturating_mul(m.max(1)), l.saturating_add(k))
        }),
    }
}

/// The disjunctive normal form (call after checking [`size`]).
fn dnf(f: F) -> Vec<Vec<Constraint>> {
    match f {
        F::Atom(c) => vec![vec![c]],
        F::Or(v) => v.into_iter().flat_map(dnf).collect(),
        F::And(v) => {
            let mut acc = vec![vec![]];
            for g in v {
                acc = and(&acc, &dnf(g));
            }
            acc
        }
    }
}

fn and(a: &[Vec<Constraint>], b: &[Vec<Constraint>]) -> Vec<Vec<Constraint>> {
    let mut out = Vec::with_capacity(a.len() * b.len());
    for x in a {
        for y in b {
            out.push(x.iter().chain(y).cloned().collect());
        }
    }
    out
}

struct Decls {
    nx: usize,
    ny: usize,
}

impl Reader<'_> {
    fn lin(&self, s: &Sx, d: &Decls) -> Result<LinExpr, VnnlibError> {
        match s {
            Sx::Atom(a, pos) => {
                if let Ok(v) = a.parse::<f64>() {
                    if !v.is_finite() {
                        return Err(self.err(*pos, format!("`{a}` is not a finite number")));
                    }
                    return Ok(LinExpr {
                        terms: vec![],
                        constant: v,
                    });
                }
                let Some((out, i)) = self.var_name(a, *pos)? else {
                    return Err(self.err(
                        *pos,
                        format!("unknown symbol `{a}` (expected X_i, Y_j or a number)"),
                    ));
                };
                let (n, letter) = if out { (d.ny, 'Y') } else { (d.nx, 'X') };
                if i >= n {
                    let declared = match n {
                        0 => format!("no {letter} variable"),
                        1 => format!("only {letter}_0"),
                        _ => format!("{letter}_0 .. {letter}_{}", n - 1),
                    };
                    return Err(self.err(
                        *pos,
                        format!(
                            "`{a}` is not declared (the file declares {declared}); declare it with (declare-const {a} Real) or fix the index"
                        ),
                    ));
                }
                let var = if out {
                    Var::Output { app: 0, index: i }
                } else {
                    Var::Input { app: 0, index: i }
                };
                Ok(LinExpr {
                    terms: vec![(var, 1.0)],
                    constant: 0.0,
                })
            }
            Sx::List(l, pos) => {
                let op = match l.first() {
                    Some(Sx::Atom(o, _)) => o.as_str(),
                    _ => return Err(self.err(*pos, "expected an operator after `(`")),
                };
                let args: Vec<LinExpr> = l[1..]
                    .iter()
                    .map(|x| self.lin(x, d))
                    .collect::<Result<_, _>>()?;
                let add = |mut a: LinExpr, b: &LinExpr, k: f64| {
                    a.terms.extend(b.terms.iter().map(|(v, c)| (*v, k * c)));
                    a.constant += k * b.constant;
                    a
                };
                match (op, args.as_slice()) {
                    ("+", _) => Ok(args
                        .iter()
                        .fold(LinExpr::default(), |acc, x| add(acc, x, 1.0))),
                    ("-", []) => Err(self.err(*pos, "`-` needs at least one argument")),
                    ("-", [a]) => Ok(add(LinExpr::default(), a, -1.0)),
                    ("-", [a, rest @ ..]) => {
                        Ok(rest.iter().fold(a.clone(), |acc, x| add(acc, x, -1.0)))
                    }
                    ("*", [_, _, ..]) => {
                        let mut k = 1.0;
                        let mut var: Option<&LinExpr> = None;
                        for a in &args {
                            if a.terms.is_empty() {
                                k *= a.constant;
                            } else if var.is_none() {
                                var = Some(a);
                            } else {
                                return Err(self.err(
                                    *pos,
                                    "nonlinear product: at most one factor may contain variables",
                                ));
                            }
                        }
                        Ok(match var {
                            Some(e) => add(LinExpr::default(), e, k),
                            None => LinExpr {
                                terms: vec![],
                                constant: k,
                            },
                        })
                    }
                    _ => Err(self.err(
                        *pos,
                        format!(
                            "unsupported term `({op} ...)`: terms are numbers, X_i, Y_j, +, - and * by constants"
                        ),
                    )),
                }
            }
        }
    }

    fn formula(&self, s: &Sx, d: &Decls) -> Result<F, VnnlibError> {
        let Sx::List(l, pos) = s else {
            return Err(self.err(s.pos(), "expected a formula `(op ...)`"));
        };
        let op = match l.first() {
            Some(Sx::Atom(o, _)) => o.as_str(),
            _ => return Err(self.err(*pos, "expected an operator after `(`")),
        };
        match op {
            "and" | "or" => {
                let v = l[1..]
                    .iter()
                    .map(|x| self.formula(x, d))
                    .collect::<Result<Vec<_>, _>>()?;
                Ok(if op == "and" { F::And(v) } else { F::Or(v) })
            }
            "<=" | ">=" | "<" | ">" | "=" => {
                if l.len() != 3 {
                    return Err(self.err(
                        *pos,
                        format!("`{op}` takes two arguments, found {}", l.len() - 1),
                    ));
                }
                let (a, b) = (self.lin(&l[1], d)?, self.lin(&l[2], d)?);
                let diff = |x: LinExpr, y: LinExpr| LinExpr {
                    terms: x
                        .terms
                        .into_iter()
                        .chain(y.terms.into_iter().map(|(v, c)| (v, -c)))
                        .collect(),
                    constant: x.constant - y.constant,
                };
                let (expr, cmp) = match op {
                    "<=" => (diff(a, b), Cmp::Le),
                    "<" => (diff(a, b), Cmp::Lt),
                    ">=" => (diff(b, a), Cmp::Le),
                    ">" => (diff(b, a), Cmp::Lt),
                    _ => (diff(a, b), Cmp::Eq),
                };
                let expr = expr.normalised();
                if !expr.constant.is_finite() || expr.terms.iter().any(|t| !t.1.is_finite()) {
                    return Err(self.err(
                        *pos,
                        "a coefficient overflows (is not a finite number); use smaller constants",
                    ));
                }
                Ok(F::Atom(Constraint { expr, cmp }))
            }
            _ => Err(self.err(
                *pos,
                format!("unsupported connective `{op}`: formulas use and, or, <=, >=, <, >, ="),
            )),
        }
    }
}

/// A single-input bound `k X_i + c (<=|<) 0` as (i, is_upper, bound, exact): the
/// closed bound, rounded outward when `-c / k` is not exact (|k| != 1); `exact` is
/// false for a rounded or a strict bound, which must also stay in the region.
fn input_bound(c: &Constraint) -> Option<(usize, bool, f64, bool)> {
    match c.expr.terms.as_slice() {
        [(Var::Input { index, .. }, k)] if c.cmp != Cmp::Eq && *k != 0.0 => {
            let upper = *k > 0.0;
            let t = -c.expr.constant / k;
            let unit = k.abs() == 1.0;
            let t = match (unit, upper) {
                (true, _) => t,
                (false, true) => t.next_up(),
                (false, false) => t.next_down(),
            };
            Some((*index, upper, t, unit && c.cmp == Cmp::Le))
        }
        _ => None,
    }
}

/// Read VNN-LIB text as a `Prove` query on network `network`. See [`read`].
pub fn import(text: &str, file: &str, network: &str, name: &str) -> Result<Query, VnnlibError> {
    read(text, file, network, name).map(|p| p.query)
}

/// [`read`] from bytes: bytes that are not UTF-8 are an error with their line:column.
pub fn read_bytes(
    bytes: &[u8],
    file: &str,
    network: &str,
    name: &str,
) -> Result<Property, VnnlibError> {
    let text = crate::syntax::decode(bytes, file).map_err(|e| VnnlibError::Parse {
        file: file.into(),
        line: e.pos.line,
        col: e.pos.col,
        message: e.message,
    })?;
    read(text, file, network, name)
}

/// Read VNN-LIB text as a `Prove` query on network `network`, with the declared
/// variable counts.
///
/// What is accepted: `(declare-const X_i Real)` / `(declare-const Y_j Real)` (or
/// `declare-fun` with `()`), declaring exactly `X_0 .. X_{n-1}` and `Y_0 .. Y_{m-1}`
/// (any order, no gaps, no repeats, at least one of each, at most [`MAX_VARS`]);
/// `(assert F)` where `F` is built from `and`, `or` and `<=`, `>=`, `<`, `>`, `=` over
/// linear terms (finite numbers, declared `X_i` / `Y_j`, `+`, `-`, `*` by constants);
/// `set-logic`, `set-info`, `check-sat`, `get-model` and `exit` are ignored. Anything
/// else is an error naming `file:line:col`. Single-input bounds on `X_i` that hold in
/// every case (top-level assertions, or bounds present in every disjunct) give the
/// input box (closed, rounded outward); top-level bounds `X_i <= c` / `X_i >= c` live
/// in the box only, strict ones and ones with a coefficient other than ±1 stay in the
/// region too, as does every bound inside a disjunction. The assertions' cases are
/// counted before expanding: at most [`MAX_CASES`] cases and [`MAX_CONSTRAINTS`]
/// constraints.
pub fn read(text: &str, file: &str, network: &str, name: &str) -> Result<Property, VnnlibError> {
    let r = Reader { file };
    let cmds = r.sexprs(text)?;
    // Declarations.
    let mut xs: HashMap<usize, Pos> = HashMap::new();
    let mut ys: HashMap<usize, Pos> = HashMap::new();
    let mut asserts: Vec<&Sx> = Vec::new();
    for s in &cmds {
        let Sx::List(l, pos) = s else {
            return Err(r.err(
                s.pos(),
                "expected a command `(declare-const ...)` or `(assert ...)`",
            ));
        };
        let head = match l.first() {
            Some(Sx::Atom(c, _)) => c.as_str(),
            _ => {
                return Err(r.err(
                    *pos,
                    "expected a command `(declare-const ...)` or `(assert ...)`",
                ))
            }
        };
        match head {
            "declare-const" | "declare-fun" => {
                let typed = match (head, l.as_slice()) {
                    ("declare-const", [_, Sx::Atom(v, vp), Sx::Atom(t, _)]) => Some((v, *vp, t)),
                    ("declare-fun", [_, Sx::Atom(v, vp), Sx::List(args, _), Sx::Atom(t, _)])
                        if args.is_empty() =>
                    {
                        Some((v, *vp, t))
                    }
                    _ => None,
                };
                let Some((v, vp, t)) = typed else {
                    return Err(r.err(
                        *pos,
                        "expected (declare-const X_i Real) or (declare-const Y_j Real)",
                    ));
                };
                if t != "Real" {
                    return Err(r.err(
                        *pos,
                        format!("`{v}` has sort `{t}`; only Real is supported"),
                    ));
                }
                let Some((out, i)) = r.var_name(v, vp)? else {
                    return Err(r.err(
                        vp,
                        format!("`{v}`: only inputs X_0, X_1, ... and outputs Y_0, Y_1, ... can be declared"),
                    ));
                };
                let map = if out { &mut ys } else { &mut xs };
                if let Some(first) = map.insert(i, vp) {
                    return Err(r.err(
                        vp,
                        format!(
                            "`{v}` is declared twice (first at {}:{})",
                            first.line, first.col
                        ),
                    ));
                }
            }
            "assert" => match l.as_slice() {
                [_, f] => asserts.push(f),
                _ => {
                    return Err(r.err(
                        *pos,
                        format!("`assert` takes one formula, found {}", l.len() - 1),
                    ))
                }
            },
            "set-logic" | "set-info" | "check-sat" | "get-model" | "exit" => {}
            _ => {
                return Err(r.err(
                    *pos,
                    format!("unsupported command `{head}`: expected declare-const or assert"),
                ))
            }
        }
    }
    let mut counts = [0usize; 2];
    for (k, (map, letter)) in [(&xs, 'X'), (&ys, 'Y')].into_iter().enumerate() {
        let n = map.len();
        if n == 0 {
            return Err(r.err(
                Pos { line: 1, col: 1 },
                format!("the file declares no {letter} variable; declare {letter}_0, {letter}_1, ... with (declare-const {letter}_0 Real)"),
            ));
        }
        // Indices are distinct: all below n means exactly 0 .. n-1.
        if let Some((&i, &p)) = map
            .iter()
            .filter(|(i, _)| **i >= n)
            .max_by_key(|(i, _)| **i)
        {
            let missing = (0..n).find(|j| !map.contains_key(j)).unwrap_or(0);
            return Err(r.err(
                p,
                format!(
                    "`{letter}_{i}` is declared but `{letter}_{missing}` is not: declare {letter}_0 .. {letter}_{} without gaps ({n} declared)",
                    n - 1
                ),
            ));
        }
        counts[k] = n;
    }
    let d = Decls {
        nx: counts[0],
        ny: counts[1],
    };
    // Assertions: top-level conjuncts, flattened.
    let mut input_box = vec![(f64::NEG_INFINITY, f64::INFINITY); d.nx];
    let mut common: Vec<Constraint> = Vec::new();
    let mut factors: Vec<F> = Vec::new();
    let mut todo: Vec<F> = Vec::new();
    for a in asserts.iter().rev() {
        todo.push(r.formula(a, &d)?);
    }
    while let Some(f) = todo.pop() {
        match f {
            F::And(v) => todo.extend(v.into_iter().rev()),
            F::Atom(c) => match input_bound(&c) {
                Some((i, upper, t, exact)) => {
                    let b = &mut input_box[i];
                    if upper {
                        b.1 = b.1.min(t);
                    } else {
                        b.0 = b.0.max(t);
                    }
                    if !exact {
                        common.push(c);
                    }
                }
                None => common.push(c),
            },
            f @ F::Or(_) => factors.push(f),
        }
    }
    // Count before expanding.
    let all = F::And(factors);
    let (cases, per_case) = size(&all);
    let per_case = per_case.saturating_add(common.len() as u64);
    let at = asserts.first().map_or(Pos { line: 1, col: 1 }, |a| a.pos());
    if cases > MAX_CASES {
        return Err(r.err(
            at,
            format!(
                "the assertions expand to {} cases, more than the cap of {MAX_CASES}; split the file into several",
                if cases == u64::MAX { "more than 10^19".to_string() } else { cases.to_string() }
            ),
        ));
    }
    if cases.saturating_mul(per_case) > MAX_CONSTRAINTS {
        return Err(r.err(
            at,
            format!(
                "the assertions expand to {cases} cases of up to {per_case} constraints, more than the cap of {MAX_CONSTRAINTS} constraints; split the file into several"
            ),
        ));
    }
    let mut region = dnf(all);
    for conj in &mut region {
        conj.extend(common.iter().cloned());
    }
    // Bounds on an input present in every case bound the input box by their hull
    // (sparse: time linear in the constraints, whatever the number of inputs).
    if !region.is_empty() {
        let mut hull = vec![(f64::INFINITY, f64::NEG_INFINITY); d.nx];
        let mut seen = vec![(0usize, 0usize); d.nx];
        for conj in &region {
            let mut b: HashMap<usize, (f64, f64)> = HashMap::new();
            for c in conj {
                if let Some((i, upper, t, _)) = input_bound(c) {
                    let e = b.entry(i).or_insert((f64::NEG_INFINITY, f64::INFINITY));
                    if upper {
                        e.1 = e.1.min(t);
                    } else {
                        e.0 = e.0.max(t);
                    }
                }
            }
            for (i, (lo, hi)) in b {
                if lo > f64::NEG_INFINITY {
                    seen[i].0 += 1;
                    hull[i].0 = hull[i].0.min(lo);
                }
                if hi < f64::INFINITY {
                    seen[i].1 += 1;
                    hull[i].1 = hull[i].1.max(hi);
                }
            }
        }
        for i in 0..d.nx {
            if seen[i].0 == region.len() {
                input_box[i].0 = input_box[i].0.max(hull[i].0);
            }
            if seen[i].1 == region.len() {
                input_box[i].1 = input_box[i].1.min(hull[i].1);
            }
        }
    }
    Ok(Property {
        n_inputs: d.nx,
        n_outputs: d.ny,
        query: Query {
            name: name.into(),
            applications: vec![Application {
                network: network.into(),
                n_inputs: d.nx,
                n_outputs: d.ny,
                input_box,
            }],
            free_vars: vec![],
            region,
            goal: Goal::Prove,
        },
    })
}
