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
//! at the top level become the input box; everything else becomes the region.

use crate::normal::{Application, Cmp, Constraint, Goal, LinExpr, Query, Var};
use std::fmt::Write as _;

/// Why a query cannot be exported or a file not imported.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum VnnlibError {
    /// The query does not fit VNN-LIB.
    #[error("query `{0}` cannot be written as VNN-LIB: {1}")]
    Unsupported(String, String),
    /// A syntax or semantic error in a file.
    #[error("{file}: {message}")]
    Parse {
        /// File.
        file: String,
        /// What is wrong.
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

#[derive(Clone, Debug, PartialEq)]
enum Sx {
    Atom(String),
    List(Vec<Sx>),
}

fn sexprs(text: &str, file: &str) -> Result<Vec<Sx>, VnnlibError> {
    let perr = |m: String| VnnlibError::Parse {
        file: file.into(),
        message: m,
    };
    let mut stack: Vec<Vec<Sx>> = vec![vec![]];
    let mut tok = String::new();
    let flush = |tok: &mut String, stack: &mut Vec<Vec<Sx>>| {
        if !tok.is_empty() {
            stack
                .last_mut()
                .expect("stack")
                .push(Sx::Atom(std::mem::take(tok)));
        }
    };
    for line in text.lines() {
        let line = line.split(';').next().unwrap_or("");
        for c in line.chars() {
            match c {
                '(' => {
                    flush(&mut tok, &mut stack);
                    stack.push(vec![]);
                }
                ')' => {
                    flush(&mut tok, &mut stack);
                    let l = stack.pop().ok_or_else(|| perr("unbalanced `)`".into()))?;
                    stack
                        .last_mut()
                        .ok_or_else(|| perr("unbalanced `)`".into()))?
                        .push(Sx::List(l));
                }
                c if c.is_whitespace() => flush(&mut tok, &mut stack),
                c => tok.push(c),
            }
        }
        flush(&mut tok, &mut stack);
    }
    if stack.len() != 1 {
        return Err(perr("unbalanced parentheses: a `(` is not closed".into()));
    }
    Ok(stack.pop().expect("one"))
}

fn lin(s: &Sx, file: &str) -> Result<LinExpr, VnnlibError> {
    let perr = |m: String| VnnlibError::Parse {
        file: file.into(),
        message: m,
    };
    match s {
        Sx::Atom(a) => {
            if let Ok(v) = a.parse::<f64>() {
                return Ok(LinExpr {
                    terms: vec![],
                    constant: v,
                });
            }
            let var = if let Some(i) = a.strip_prefix("X_") {
                Var::Input {
                    app: 0,
                    index: i.parse().map_err(|_| perr(format!("bad variable `{a}`")))?,
                }
            } else if let Some(j) = a.strip_prefix("Y_") {
                Var::Output {
                    app: 0,
                    index: j.parse().map_err(|_| perr(format!("bad variable `{a}`")))?,
                }
            } else {
                return Err(perr(format!(
                    "unknown symbol `{a}` (expected X_i, Y_j or a number)"
                )));
            };
            Ok(LinExpr {
                terms: vec![(var, 1.0)],
                constant: 0.0,
            })
        }
        Sx::List(l) => {
            let op = match l.first() {
                Some(Sx::Atom(o)) => o.as_str(),
                _ => return Err(perr("expected an operator".into())),
            };
            let args: Vec<LinExpr> = l[1..]
                .iter()
                .map(|x| lin(x, file))
                .collect::<Result<_, _>>()?;
            let add = |a: LinExpr, b: &LinExpr, k: f64| LinExpr {
                terms: a
                    .terms
                    .into_iter()
                    .chain(b.terms.iter().map(|(v, c)| (*v, k * c)))
                    .collect(),
                constant: a.constant + k * b.constant,
            };
            match (op, args.len()) {
                ("+", _) => Ok(args
                    .iter()
                    .fold(LinExpr::default(), |acc, x| add(acc, x, 1.0))),
                ("-", 1) => Ok(add(LinExpr::default(), &args[0], -1.0)),
                ("-", _) => Ok(args[1..]
                    .iter()
                    .fold(args[0].clone(), |acc, x| add(acc, x, -1.0))),
                ("*", 2) => {
                    let (a, b) = (&args[0], &args[1]);
                    let (k, e) = if a.terms.is_empty() {
                        (a.constant, b)
                    } else if b.terms.is_empty() {
                        (b.constant, a)
                    } else {
                        return Err(perr("nonlinear product".into()));
                    };
                    Ok(add(LinExpr::default(), e, k))
                }
                _ => Err(perr(format!("unsupported term `({op} ...)`"))),
            }
        }
    }
}

fn formula(s: &Sx, file: &str) -> Result<Vec<Vec<Constraint>>, VnnlibError> {
    let perr = |m: String| VnnlibError::Parse {
        file: file.into(),
        message: m,
    };
    let Sx::List(l) = s else {
        return Err(perr("expected a formula".into()));
    };
    let op = match l.first() {
        Some(Sx::Atom(o)) => o.as_str(),
        _ => return Err(perr("expected an operator".into())),
    };
    match op {
        "and" => {
            let mut acc = vec![vec![]];
            for x in &l[1..] {
                let d = formula(x, file)?;
                let mut next = Vec::new();
                for a in &acc {
                    for b in &d {
                        next.push(a.iter().chain(b).cloned().collect::<Vec<_>>());
                    }
                }
                acc = next;
            }
            Ok(acc)
        }
        "or" => {
            let mut out = Vec::new();
            for x in &l[1..] {
                out.extend(formula(x, file)?);
            }
            Ok(out)
        }
        "<=" | ">=" | "<" | ">" | "=" => {
            if l.len() != 3 {
                return Err(perr(format!("`{op}` takes two arguments")));
            }
            let (a, b) = (lin(&l[1], file)?, lin(&l[2], file)?);
            let d = |x: LinExpr, y: LinExpr| LinExpr {
                terms: x
                    .terms
                    .into_iter()
                    .chain(y.terms.into_iter().map(|(v, c)| (v, -c)))
                    .collect(),
                constant: x.constant - y.constant,
            };
            let (expr, cmp) = match op {
                "<=" => (d(a, b), Cmp::Le),
                "<" => (d(a, b), Cmp::Lt),
                ">=" => (d(b, a), Cmp::Le),
                ">" => (d(b, a), Cmp::Lt),
                _ => (d(a, b), Cmp::Eq),
            };
            Ok(vec![vec![Constraint {
                expr: expr.normalised(),
                cmp,
            }]])
        }
        _ => Err(perr(format!("unsupported connective `{op}`"))),
    }
}

/// Read VNN-LIB text as a `Prove` query on network `network`.
pub fn import(text: &str, file: &str, network: &str, name: &str) -> Result<Query, VnnlibError> {
    let perr = |m: String| VnnlibError::Parse {
        file: file.into(),
        message: m,
    };
    let (mut nx, mut ny) = (0usize, 0usize);
    let mut asserts = Vec::new();
    for s in sexprs(text, file)? {
        let Sx::List(l) = &s else {
            return Err(perr("expected a command".into()));
        };
        match l.first() {
            Some(Sx::Atom(c)) if c == "declare-const" => match l.get(1) {
                Some(Sx::Atom(v)) if v.starts_with("X_") => nx += 1,
                Some(Sx::Atom(v)) if v.starts_with("Y_") => ny += 1,
                _ => {
                    return Err(perr(
                        "declare-const of something other than X_i or Y_j".into(),
                    ))
                }
            },
            Some(Sx::Atom(c)) if c == "assert" => asserts.push(
                l.get(1)
                    .cloned()
                    .ok_or_else(|| perr("empty assert".into()))?,
            ),
            _ => return Err(perr("expected declare-const or assert".into())),
        }
    }
    let mut input_box = vec![(f64::NEG_INFINITY, f64::INFINITY); nx];
    let mut common: Vec<Constraint> = Vec::new();
    let mut region: Vec<Vec<Constraint>> = vec![vec![]];
    for a in &asserts {
        let d = formula(a, file)?;
        if d.len() == 1 && d[0].len() == 1 {
            let c = &d[0][0];
            if let [(Var::Input { index, .. }, k)] = c.expr.terms.as_slice() {
                if c.cmp != Cmp::Eq && *index < nx {
                    let t = -c.expr.constant / k;
                    let r = &mut input_box[*index];
                    if *k > 0.0 {
                        r.1 = r.1.min(t);
                    } else {
                        r.0 = r.0.max(t);
                    }
                    continue;
                }
            }
            common.push(c.clone());
            continue;
        }
        let mut next = Vec::new();
        for a in &region {
            for b in &d {
                next.push(a.iter().chain(b).cloned().collect::<Vec<_>>());
            }
        }
        region = next;
    }
    for conj in &mut region {
        conj.extend(common.iter().cloned());
    }
    Ok(Query {
        name: name.into(),
        applications: vec![Application {
            network: network.into(),
            n_inputs: nx,
            n_outputs: ny,
            input_box,
        }],
        free_vars: vec![],
        region,
        goal: Goal::Prove,
    })
}
