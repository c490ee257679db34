//! The checker and compiler: names resolved, arities and definitions checked, every
//! expression lowered into a [`Graph`].

use crate::error::{closest, Pos, SystemError};
use crate::graph::{Bin2, Builder, Cond, Graph, Op, Un};
use crate::lex::err;
use crate::parse::{function_arity, Bin, Cmp, Expr, GoalAst, Stmt, WhenAst, FUNCTIONS};
use crate::{Discrete, Goal, GoalKind, InputTable, ModeVar, Switch, System, When};
use std::collections::HashMap;
use std::f64::consts::PI;

/// Largest integer exponent evaluated by repeated squaring.
const MAX_POWI: f64 = 65536.0;

/// What an expression may read.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Mode {
    /// Constants: numbers, `pi`, parameters defined above.
    Const,
    /// Right-hand sides and `let`s: states, inputs, parameters, `let`s.
    Rhs,
    /// Observations and goal bands: states, parameters, `let`s (that read no input).
    States,
    /// Actuation: network outputs `net[i]` and parameters.
    Actuate,
}

struct Ctx<'a> {
    file: &'a str,
    src: &'a str,
    states: HashMap<String, usize>,
    inputs: HashMap<String, usize>,
    params: HashMap<String, f64>,
    /// Every parameter name with its line (also those not yet evaluated).
    param_lines: HashMap<String, usize>,
    lets: HashMap<String, (usize, Pos)>,
}

struct Lower<'a, 'c> {
    cx: &'c Ctx<'a>,
    b: Builder,
    mode: Mode,
    let_nodes: Vec<usize>,
    net_max: usize,
    /// The condition operand (`a - b` of `if a < b`) and place of every `if` lowered.
    switches: Vec<(usize, Pos)>,
}

type R<T> = Result<T, SystemError>;

/// A `mode` line: name, place, values with their places.
type ModeDecl = (String, Pos, Vec<(String, Pos)>);

/// An input's table: the first `when` line's place and, per mode value, its values.
type TableRows = (Pos, Vec<Option<Vec<f64>>>);

/// One input's actuation: its graph, clip, and number of network outputs read.
type Actuation = (Graph, Option<(f64, f64)>, usize);

impl Ctx<'_> {
    fn fail<T>(&self, pos: Pos, message: String, hint: &str) -> R<T> {
        Err(err(self.file, self.src, pos, message, hint))
    }
    fn all_names(&self) -> impl Iterator<Item = &str> {
        self.states
            .keys()
            .chain(self.inputs.keys())
            .chain(self.param_lines.keys())
            .chain(self.lets.keys())
            .map(|s| s.as_str())
            .chain(std::iter::once("pi"))
    }
}

impl<'a, 'c> Lower<'a, 'c> {
    fn new(cx: &'c Ctx<'a>, mode: Mode, lets: &[(String, Pos, Expr)]) -> R<Self> {
        let mut l = Lower {
            cx,
            b: Builder::default(),
            mode: Mode::Rhs,
            let_nodes: Vec::new(),
            net_max: 0,
            switches: Vec::new(),
        };
        if matches!(mode, Mode::Rhs | Mode::States) {
            for (_, _, e) in lets {
                let n = l.expr(e)?;
                l.let_nodes.push(n);
            }
        }
        l.mode = mode;
        Ok(l)
    }

    fn push(&mut self, op: Op, pos: Pos) -> R<usize> {
        match self.b.push(op) {
            Some(i) => Ok(i),
            None => self.cx.fail(
                pos,
                "this constant expression does not evaluate to a finite number".into(),
                "check the operands (e.g. log or sqrt of a negative constant, an overflow)",
            ),
        }
    }

    fn name(&mut self, n: &str, pos: Pos) -> R<usize> {
        let cx = self.cx;
        if n == "pi" {
            return self.push(Op::Const(PI), pos);
        }
        let what = match self.mode {
            Mode::Const => "a constant expression (numbers, pi, parameters defined above)",
            Mode::Rhs => "an equation",
            Mode::States => "an observation or a goal (states, parameters, lets without inputs)",
            Mode::Actuate => "an actuation (net[i], numbers, parameters)",
        };
        if let Some(&v) = cx.params.get(n) {
            return self.push(Op::Const(v), pos);
        }
        if let Some(&line) = cx.param_lines.get(n) {
            return cx.fail(
                pos,
                format!("parameter `{n}` is defined later, at line {line}"),
                "move its `param` line above this one",
            );
        }
        if let Some(&i) = cx.states.get(n) {
            if matches!(self.mode, Mode::Rhs | Mode::States) {
                return self.push(Op::State(i), pos);
            }
            return cx.fail(
                pos,
                format!("`{n}` is a state and cannot appear in {what}"),
                "parameters, periods, bounds and actuations are constants or depend on net[i] only",
            );
        }
        if let Some(&i) = cx.inputs.get(n) {
            if self.mode == Mode::Rhs {
                return self.push(Op::Input(i), pos);
            }
            return cx.fail(
                pos,
                format!("`{n}` is an input and cannot appear in {what}"),
                "inputs are set by `actuate`; observations and goals read states only",
            );
        }
        if let Some(&(k, lpos)) = cx.lets.get(n) {
            if self.mode == Mode::Const || self.mode == Mode::Actuate {
                return cx.fail(
                    pos,
                    format!("`{n}` is a `let` definition and cannot appear in {what}"),
                    "use a `param` for a constant",
                );
            }
            if k < self.let_nodes.len() {
                return Ok(self.let_nodes[k]);
            }
            return cx.fail(
                pos,
                format!("`{n}` is defined later, at line {}", lpos.line),
                "a `let` may use only the `let`s above it: move its definition up",
            );
        }
        let hint = match closest(n, cx.all_names()) {
            Some(s) => format!("did you mean `{s}`?"),
            None => "declare it with `state`, `input`, `param` or `let`".into(),
        };
        cx.fail(pos, format!("unknown name `{n}`"), &hint)
    }

    fn expr(&mut self, e: &Expr) -> R<usize> {
        match e {
            Expr::Num(v, p) => self.push(Op::Const(*v), *p),
            Expr::Name(n, p) => self.name(n, *p),
            Expr::Net(k, p) => {
                if self.mode != Mode::Actuate {
                    return self.cx.fail(
                        *p,
                        "`net[i]` (a network output) may appear only in `actuate`".into(),
                        "map network outputs to inputs with `actuate u = net[0]`",
                    );
                }
                self.net_max = self.net_max.max(k + 1);
                self.push(Op::Input(*k), *p)
            }
            Expr::Neg(a, p) => {
                let a = self.expr(a)?;
                self.push(Op::Un(Un::Neg, a), *p)
            }
            Expr::Chain(first, rest) => {
                let mut acc = self.expr(first)?;
                for (op, p, e) in rest {
                    let r = self.expr(e)?;
                    acc = self.bin(*op, acc, r, *p)?;
                }
                Ok(acc)
            }
            Expr::Pow(a, n, p) => {
                let a = self.expr(a)?;
                let n = self.expr(n)?;
                self.pow(a, n, *p)
            }
            Expr::Call(f, args, p) => self.call(f, args, *p),
            Expr::If(cmp, parts, p) => {
                let [l, r, a, b] = &**parts;
                let (l, r) = (self.expr(l)?, self.expr(r)?);
                let (c, k) = match cmp {
                    Cmp::Lt => (self.bin(Bin::Sub, l, r, *p)?, Cond::Neg),
                    Cmp::Le => (self.bin(Bin::Sub, l, r, *p)?, Cond::NonPos),
                    Cmp::Gt => (self.bin(Bin::Sub, r, l, *p)?, Cond::Neg),
                    Cmp::Ge => (self.bin(Bin::Sub, r, l, *p)?, Cond::NonPos),
                };
                self.switches.push((c, *p));
                let (a, b) = (self.expr(a)?, self.expr(b)?);
                self.push(Op::Select(k, c, a, b), *p)
            }
        }
    }

    fn bin(&mut self, op: Bin, a: usize, b: usize, p: Pos) -> R<usize> {
        let (ka, kb) = (self.b.konst(a), self.b.konst(b));
        let o = match op {
            Bin::Add => match (ka, kb) {
                (_, Some(c)) => Op::AddC(a, c),
                (Some(c), None) => Op::AddC(b, c),
                _ => Op::Bin(Bin2::Add, a, b),
            },
            Bin::Sub => match (ka, kb) {
                (_, Some(c)) => Op::SubC(a, c),
                (Some(c), None) => Op::CSub(c, b),
                _ => Op::Bin(Bin2::Sub, a, b),
            },
            Bin::Mul => match (ka, kb) {
                (_, Some(c)) => Op::MulC(a, c),
                (Some(c), None) => Op::MulC(b, c),
                _ => Op::Bin(Bin2::Mul, a, b),
            },
            Bin::Div if kb == Some(0.0) => {
                return self.cx.fail(
                    p,
                    "division by zero: the divisor is the constant 0".into(),
                    "divide by a nonzero constant or by an expression that varies",
                )
            }
            Bin::Div => match (ka, kb) {
                (_, Some(c)) => Op::DivC(a, c),
                (Some(c), None) => Op::CDiv(c, b),
                _ => Op::Bin(Bin2::Div, a, b),
            },
        };
        self.push(o, p)
    }

    fn pow(&mut self, a: usize, n: usize, p: Pos) -> R<usize> {
        if let Some(e) = self.b.konst(n) {
            if e.fract() == 0.0 && e.abs() <= MAX_POWI {
                let k = e.abs() as u32;
                let r = match k {
                    0 => self.push(Op::Const(1.0), p)?,
                    1 => a,
                    2 => self.push(Op::Un(Un::Sqr, a), p)?,
                    _ => self.push(Op::Powi(a, k), p)?,
                };
                if e < 0.0 {
                    if self.b.konst(r) == Some(0.0) {
                        return self.cx.fail(
                            p,
                            "division by zero: a negative power of the constant 0".into(),
                            "use a nonzero base",
                        );
                    }
                    return self.push(Op::CDiv(1.0, r), p);
                }
                return Ok(r);
            }
            if e == 0.5 {
                return self.push(Op::Un(Un::Sqrt, a), p);
            }
        }
        // a^b = exp(b ln a), defined for a > 0.
        let l = self.push(Op::Un(Un::Ln, a), p)?;
        let m = self.bin(Bin::Mul, n, l, p)?;
        self.push(Op::Un(Un::Exp, m), p)
    }

    fn call(&mut self, f: &str, args: &[Expr], p: Pos) -> R<usize> {
        let cx = self.cx;
        let Some((lo, hi)) = function_arity(f) else {
            if cx.all_names().any(|n| n == f) {
                return cx.fail(
                    p,
                    format!("`{f}` is not a function"),
                    "write a product with `*`, e.g. `2 * (x + 1)`",
                );
            }
            let hint = match closest(f, FUNCTIONS.iter().copied()) {
                Some(s) => format!("did you mean `{s}`?"),
                None => format!("the functions are {}", FUNCTIONS.join(", ")),
            };
            return cx.fail(p, format!("unknown function `{f}`"), &hint);
        };
        if args.len() < lo || args.len() > hi {
            let want = if lo == hi {
                format!("{lo} argument{}", if lo == 1 { "" } else { "s" })
            } else {
                format!("{lo} to {hi} arguments")
            };
            return cx.fail(
                p,
                format!("`{f}` takes {want}, got {}", args.len()),
                &format!(
                    "write `{f}(x)`{}",
                    if lo == 2 { " or `f(x, y)`" } else { "" }
                ),
            );
        }
        let mut v = Vec::with_capacity(args.len());
        for a in args {
            v.push(self.expr(a)?);
        }
        let u = match f {
            "sqrt" => Un::Sqrt,
            "exp" => Un::Exp,
            "log" | "ln" => Un::Ln,
            "sin" => Un::Sin,
            "cos" => Un::Cos,
            "tan" => Un::Tan,
            "tanh" => Un::Tanh,
            "atan" => Un::Atan,
            "abs" => Un::Abs,
            "sign" => Un::Sgn,
            _ => {
                let k = if f == "min" { Bin2::Min } else { Bin2::Max };
                let mut acc = v[0];
                for &x in &v[1..] {
                    acc = self.push(Op::Bin(k, acc, x), p)?;
                }
                return Ok(acc);
            }
        };
        self.push(Op::Un(u, v[0]), p)
    }

    /// A constant expression's value.
    fn constant(&mut self, e: &Expr) -> R<f64> {
        let i = self.expr(e)?;
        match self.b.konst(i) {
            Some(v) => Ok(v),
            None => self.cx.fail(
                e.pos(),
                "expected a constant".into(),
                "use numbers, pi and parameters only",
            ),
        }
    }
}

fn constant(cx: &Ctx, e: &Expr) -> R<f64> {
    Lower::new(cx, Mode::Const, &[])?.constant(e)
}

fn range(cx: &Ctx, lo: &Expr, hi: &Expr, what: &str) -> R<(f64, f64)> {
    let (a, b) = (constant(cx, lo)?, constant(cx, hi)?);
    if a > b {
        return cx.fail(
            lo.pos(),
            format!("empty {what}: the lower end {a} is above the upper end {b}"),
            "write the interval as `[lo, hi]` with lo <= hi",
        );
    }
    Ok((a, b))
}

/// Check and compile a parsed file.
pub(crate) fn compile(
    stmts: &[Stmt],
    file: &str,
    src: &str,
    overrides: &[(&str, f64)],
) -> R<System> {
    let mut cx = Ctx {
        file,
        src,
        states: HashMap::new(),
        inputs: HashMap::new(),
        params: HashMap::new(),
        param_lines: HashMap::new(),
        lets: HashMap::new(),
    };
    let mut name = String::new();
    let mut states: Vec<(String, Pos)> = Vec::new();
    let mut inputs: Vec<(String, Pos)> = Vec::new();
    let mut lets: Vec<(String, Pos, Expr)> = Vec::new();
    let mut declared: HashMap<String, Pos> = HashMap::new();
    let mut mode_decl: Option<ModeDecl> = None;
    let mut declare = |n: &str, p: Pos, what: &str| -> R<()> {
        if let Some(q) = declared.get(n) {
            return Err(err(
                file,
                src,
                p,
                format!("`{n}` is already declared at line {}", q.line),
                &format!("rename this {what}"),
            ));
        }
        declared.insert(n.to_string(), p);
        Ok(())
    };
    // Pass 1: declarations.
    for s in stmts {
        match s {
            Stmt::System(n, _) => name = n.clone(),
            Stmt::State(v) => {
                for (n, p) in v {
                    declare(n, *p, "state")?;
                    cx.states.insert(n.clone(), states.len());
                    states.push((n.clone(), *p));
                }
            }
            Stmt::Input(v) => {
                for (n, p) in v {
                    declare(n, *p, "input")?;
                    cx.inputs.insert(n.clone(), inputs.len());
                    inputs.push((n.clone(), *p));
                }
            }
            Stmt::Param(n, p, _) => {
                declare(n, *p, "parameter")?;
                cx.param_lines.insert(n.clone(), p.line);
            }
            Stmt::Mode(n, p, vals) => {
                declare(n, *p, "mode")?;
                if let Some((m, q, _)) = &mode_decl {
                    return Err(err(
                        file,
                        src,
                        *p,
                        format!(
                            "a second mode `{n}`: the file already has the mode `{m}` (line {})",
                            q.line
                        ),
                        "a system has at most one `mode`; list all its values in one line",
                    ));
                }
                for (k, (v, vp)) in vals.iter().enumerate() {
                    if let Some((_, q)) = vals[..k].iter().find(|(w, _)| w == v) {
                        return Err(err(
                            file,
                            src,
                            *vp,
                            format!(
                                "the value `{v}` is listed twice (first at column {})",
                                q.col
                            ),
                            "list each value of the mode once",
                        ));
                    }
                }
                mode_decl = Some((n.clone(), *p, vals.clone()));
            }
            Stmt::Let(n, p, e) => {
                declare(n, *p, "definition")?;
                cx.lets.insert(n.clone(), (lets.len(), *p));
                lets.push((n.clone(), *p, e.clone()));
            }
            _ => {}
        }
    }
    if states.is_empty() {
        return cx.fail(
            Pos::default(),
            "the system declares no state".into(),
            "declare the states with e.g. `state x, v`",
        );
    }
    for (o, _) in overrides {
        if !cx.param_lines.contains_key(*o) {
            let hint = match closest(o, cx.param_lines.keys().map(|s| s.as_str())) {
                Some(s) => format!("did you mean `{s}`?"),
                None => "the file's parameters are its `param` lines".into(),
            };
            return cx.fail(
                Pos::default(),
                format!("no parameter `{o}` to override"),
                &hint,
            );
        }
    }
    // Pass 2: parameters, in order.
    let mut params = Vec::new();
    for s in stmts {
        if let Stmt::Param(n, _, e) = s {
            let v = match overrides.iter().rev().find(|(o, _)| o == n) {
                Some(&(_, v)) if v.is_finite() => v,
                Some(&(_, v)) => {
                    return cx.fail(
                        Pos::default(),
                        format!("the override of `{n}` is {v}, not a finite number"),
                        "give a finite value",
                    )
                }
                None => constant(&cx, e)?,
            };
            cx.params.insert(n.clone(), v);
            params.push((n.clone(), v));
        }
    }
    // Pass 3: right-hand side (`x' = ...`) or discrete update (`next x = ...`).
    let discrete = stmts
        .iter()
        .any(|s| matches!(s, Stmt::Next(..) | Stmt::NextArgmax(..)));
    let mut rhs_b = Lower::new(&cx, Mode::Rhs, &lets)?;
    let mut eq: Vec<Option<usize>> = vec![None; states.len()];
    let mut eq_pos: Vec<Pos> = vec![Pos::default(); states.len()];
    for s in stmts {
        let (n, p, e, is_next) = match s {
            Stmt::Eq(n, p, e) => (n, p, e, false),
            Stmt::Next(n, p, e) => (n, p, e, true),
            _ => continue,
        };
        if discrete && !is_next {
            return cx.fail(
                *p,
                format!("`{n}'` is a derivative, but the system is discrete-time (it has `next` updates)"),
                &format!("write the update `next {n} = ...`, or use derivatives only"),
            );
        }
        let Some(&i) = cx.states.get(n) else {
            if mode_decl.as_ref().is_some_and(|m| &m.0 == n) {
                return cx.fail(
                    *p,
                    format!("the mode `{n}` changes only by `next {n} = argmax(net)`"),
                    "a mode's new value is the index of the network's largest output",
                );
            }
            let hint = match closest(n, states.iter().map(|s| s.0.as_str())) {
                Some(s) if is_next => {
                    format!("did you mean `next {s}`? Otherwise declare it with `state {n}`")
                }
                Some(s) => format!("did you mean `{s}'`? Otherwise declare it with `state {n}`"),
                None => format!("declare it with `state {n}`"),
            };
            let what = if is_next {
                format!("`next {n}` updates an undefined state `{n}`")
            } else {
                format!("`{n}'` is the derivative of an undefined state `{n}`")
            };
            return cx.fail(*p, what, &hint);
        };
        if eq[i].is_some() {
            let what = if is_next { "an update" } else { "an equation" };
            return cx.fail(
                *p,
                format!("`{n}` already has {what} at line {}", eq_pos[i].line),
                &format!("give each state exactly one {}", &what[3..]),
            );
        }
        eq[i] = Some(rhs_b.expr(e)?);
        eq_pos[i] = *p;
    }
    let mut outs = Vec::new();
    for (i, o) in eq.iter().enumerate() {
        match o {
            Some(k) => outs.push(*k),
            None => {
                let (n, p) = &states[i];
                if discrete {
                    return cx.fail(
                        *p,
                        format!("state `{n}` has no update"),
                        &format!("add `next {n} = ...` (write `next {n} = {n}` for a constant)"),
                    );
                }
                return cx.fail(
                    *p,
                    format!("state `{n}` has no equation"),
                    &format!("add `{n}' = ...` (write `{n}' = 0` for a constant)"),
                );
            }
        }
    }
    let (rhs, next_graph) = if discrete {
        let mut z = Builder::default();
        let k = z.push(Op::Const(0.0)).expect("finite");
        (
            z.finish(&vec![k; states.len()]),
            Some(rhs_b.b.finish(&outs)),
        )
    } else {
        (rhs_b.b.finish(&outs), None)
    };
    // Every `if` of the equations whose condition varies, its condition an output of
    // one graph (for the simulator's diagnosis of a collapsed step: which switch flips
    // at the state); one pass over the instructions however many `if`s there are.
    let mut switches: Vec<Switch> = Vec::new();
    let mut conds: Vec<usize> = Vec::new();
    let mut seen: std::collections::HashSet<(usize, usize)> = Default::default();
    let lines: Vec<&str> = src.lines().collect();
    for &(c, p) in &rhs_b.switches {
        if rhs_b.b.konst(c).is_some() || !seen.insert((p.line, p.col)) {
            continue;
        }
        let line = lines.get(p.line.saturating_sub(1)).copied().unwrap_or("");
        switches.push(Switch {
            pos: p,
            text: switch_excerpt(line, p.col),
        });
        conds.push(c);
    }
    let switch_conditions = rhs_b.b.finish(&conds);
    // Pass 4: the rest.
    let mut period = None;
    let mut horizon = None;
    let mut observe: Option<Graph> = None;
    let mut act: Vec<Option<Actuation>> = vec![None; inputs.len()];
    let mut resets = Vec::new();
    let mut init: Vec<Option<(f64, f64)>> = vec![None; states.len()];
    let mut goal_asts = Vec::new();
    let mut mode_init: Option<usize> = None;
    let mut argmax_pos: Option<Pos> = None;
    let mut networks_by = false;
    // Per input: the first table line's place and, per mode value, the listed values.
    let mut tables: Vec<Option<TableRows>> = vec![None; inputs.len()];
    let mode_values = |n: &str, p: Pos, what: &str| -> R<&Vec<(String, Pos)>> {
        match &mode_decl {
            Some((m, _, v)) if m == n => Ok(v),
            Some((m, _, _)) => cx.fail(
                p,
                format!("`{n}` is not the mode of this system ({what})"),
                &format!("the mode is `{m}`"),
            ),
            None => cx.fail(
                p,
                format!("`{n}` is not a mode ({what})"),
                &format!("declare it with `mode {n} in [A, B, ...]`"),
            ),
        }
    };
    let value_index = |vals: &Vec<(String, Pos)>, m: &str, v: &str, p: Pos| -> R<usize> {
        match vals.iter().position(|(w, _)| w == v) {
            Some(k) => Ok(k),
            None => {
                let hint = match closest(v, vals.iter().map(|w| w.0.as_str())) {
                    Some(w) => format!("did you mean `{w}`?"),
                    None => format!(
                        "the values of `{m}` are {}",
                        vals.iter()
                            .map(|w| w.0.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                };
                cx.fail(p, format!("`{v}` is not a value of the mode `{m}`"), &hint)
            }
        }
    };
    let state_index = |n: &str, p: Pos| -> R<usize> {
        match cx.states.get(n) {
            Some(&i) => Ok(i),
            None => {
                let hint = match closest(n, states.iter().map(|s| s.0.as_str())) {
                    Some(s) => format!("did you mean `{s}`?"),
                    None => format!(
                        "the states are {}",
                        states
                            .iter()
                            .map(|s| s.0.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                };
                cx.fail(p, format!("`{n}` is not a state"), &hint)
            }
        }
    };
    for s in stmts {
        match s {
            Stmt::Period(e, p) | Stmt::Horizon(e, p) => {
                let v = constant(&cx, e)?;
                let is_p = matches!(s, Stmt::Period(..));
                if v.is_nan() || v <= 0.0 {
                    return cx.fail(
                        e.pos(),
                        format!(
                            "the {} must be a positive number, got {v}",
                            if is_p { "period" } else { "horizon" }
                        ),
                        if is_p {
                            "write e.g. `period 0.1`"
                        } else {
                            "write e.g. `horizon 5`"
                        },
                    );
                }
                let slot = if is_p { &mut period } else { &mut horizon };
                if slot.is_some() {
                    return cx.fail(*p, "this is given twice".into(), "keep one line");
                }
                *slot = Some((v, *p));
            }
            Stmt::Observe(v, p) => {
                if observe.is_some() {
                    return cx.fail(
                        *p,
                        "`observe` is given twice".into(),
                        "list every network input in one `observe` line",
                    );
                }
                let mut l = Lower::new(&cx, Mode::States, &lets)?;
                let mut o = Vec::new();
                for e in v {
                    o.push(l.expr(e)?);
                }
                let g = l.b.finish(&o);
                if g.reads_inputs() {
                    return cx.fail(
                        *p,
                        "an observation depends on an input (through a `let`)".into(),
                        "observe states only",
                    );
                }
                observe = Some(g);
            }
            Stmt::Actuate {
                name: n,
                pos,
                expr,
                clip,
            } => {
                let Some(&i) = cx.inputs.get(n) else {
                    let hint = match closest(n, inputs.iter().map(|s| s.0.as_str())) {
                        Some(s) => format!("did you mean `{s}`?"),
                        None => format!("declare it with `input {n}`"),
                    };
                    return cx.fail(*pos, format!("`{n}` is not an input"), &hint);
                };
                if act[i].is_some() {
                    return cx.fail(
                        *pos,
                        format!("input `{n}` is actuated twice"),
                        "keep one `actuate` line per input",
                    );
                }
                let mut l = Lower::new(&cx, Mode::Actuate, &[])?;
                let o = l.expr(expr)?;
                let net_max = l.net_max;
                let g = l.b.finish(&[o]);
                let c = match clip {
                    Some((lo, hi)) => Some(range(&cx, lo, hi, "clip interval")?),
                    None => None,
                };
                act[i] = Some((g, c, net_max));
            }
            Stmt::Reset(_, p, _) if discrete => {
                return cx.fail(
                    *p,
                    "`reset` applies to continuous-time systems".into(),
                    "in a discrete-time system write the value in the state's `next` update",
                );
            }
            Stmt::Init(n, p, lo, _) if mode_decl.as_ref().is_some_and(|m| &m.0 == n) => {
                let vals = mode_values(n, *p, "init")?;
                let Expr::Name(v, vp) = lo else {
                    return cx.fail(
                        lo.pos(),
                        format!("the mode `{n}` starts at one of its values"),
                        &format!("write `init {n} = {}`", vals[0].0),
                    );
                };
                if mode_init.is_some() {
                    return cx.fail(
                        *p,
                        format!("the mode `{n}` is initialised twice"),
                        "keep one `init` line per mode",
                    );
                }
                mode_init = Some(value_index(vals, n, v, *vp)?);
            }
            Stmt::NextArgmax(n, p) => {
                mode_values(n, *p, "`argmax` sets a mode")?;
                if argmax_pos.is_some() {
                    return cx.fail(
                        *p,
                        format!("the mode `{n}` has two updates"),
                        "keep one `next` line per mode",
                    );
                }
                argmax_pos = Some(*p);
            }
            Stmt::NetworksBy(n, p) => {
                mode_values(n, *p, "networks are chosen by a mode")?;
                if networks_by {
                    return cx.fail(*p, "`networks by` is given twice".into(), "keep one line");
                }
                networks_by = true;
            }
            Stmt::ActuateTable {
                name: n,
                pos,
                values,
                mode: (m, mp),
                value: (v, vp),
            } => {
                let Some(&i) = cx.inputs.get(n) else {
                    let hint = match closest(n, inputs.iter().map(|s| s.0.as_str())) {
                        Some(s) => format!("did you mean `{s}`?"),
                        None => format!("declare it with `input {n}`"),
                    };
                    return cx.fail(*pos, format!("`{n}` is not an input"), &hint);
                };
                let vals = mode_values(m, *mp, "`when` names a mode")?;
                let k = value_index(vals, m, v, *vp)?;
                let nv = vals.len();
                let t = tables[i].get_or_insert_with(|| (*pos, vec![None; nv]));
                if t.1[k].is_some() {
                    return cx.fail(
                        *pos,
                        format!("`{n}` already has values for `{m} = {v}`"),
                        "give one line per mode value",
                    );
                }
                let mut row = Vec::with_capacity(values.len());
                for e in values {
                    row.push(constant(&cx, e)?);
                }
                t.1[k] = Some(row);
            }
            Stmt::Reset(n, p, e) => {
                let i = state_index(n, *p)?;
                resets.push((i, constant(&cx, e)?));
            }
            Stmt::Init(n, p, lo, hi) => {
                let i = state_index(n, *p)?;
                if init[i].is_some() {
                    return cx.fail(
                        *p,
                        format!("state `{n}` is initialised twice"),
                        "keep one `init` line per state",
                    );
                }
                init[i] = Some(range(&cx, lo, hi, "initial interval")?);
            }
            Stmt::Goal(g, w, p) => goal_asts.push((g, w, *p)),
            _ => {}
        }
    }
    let Some((period, _)) = period else {
        return cx.fail(
            Pos::default(),
            "the control period is missing".into(),
            "add e.g. `period 0.1`",
        );
    };
    let Some((horizon, hpos)) = horizon else {
        return cx.fail(
            Pos::default(),
            "the horizon is missing".into(),
            "add e.g. `horizon 5`",
        );
    };
    let k = (horizon / period).round();
    if k < 1.0 || (k * period - horizon).abs() > 1e-9 * horizon {
        return cx.fail(
            hpos,
            format!("the horizon {horizon} is not a multiple of the period {period}"),
            "make the horizon a whole number of control periods",
        );
    }
    if k > 1e7 {
        return cx.fail(
            hpos,
            format!("the horizon is {k} control periods, more than 10^7"),
            "shorten the horizon or lengthen the period",
        );
    }
    let mut init_box = Vec::new();
    for (i, v) in init.iter().enumerate() {
        match v {
            Some(r) => init_box.push(*r),
            None => {
                let (n, p) = &states[i];
                return cx.fail(
                    *p,
                    format!("state `{n}` has no initial value"),
                    &format!("add `init {n} = 0` or `init {n} in [lo, hi]`"),
                );
            }
        }
    }
    let mut mode = None;
    if let Some((m, mp, vals)) = &mode_decl {
        if argmax_pos.is_none() {
            return cx.fail(
                *mp,
                format!("the mode `{m}` has no update"),
                &format!("add `next {m} = argmax(net)`"),
            );
        }
        let Some(init) = mode_init else {
            return cx.fail(
                *mp,
                format!("the mode `{m}` has no initial value"),
                &format!("add `init {m} = {}`", vals[0].0),
            );
        };
        let mut out_tables = Vec::new();
        for (i, t) in tables.iter().enumerate() {
            let Some((tp, rows)) = t else { continue };
            let n = &inputs[i].0;
            if act[i].is_some() {
                return cx.fail(
                    *tp,
                    format!("input `{n}` is actuated twice: by `actuate {n} = ...` and by a table"),
                    "keep either the `actuate` line or the table's `when` lines",
                );
            }
            let mut full = Vec::with_capacity(rows.len());
            for (k, r) in rows.iter().enumerate() {
                match r {
                    Some(r) => full.push(r.clone()),
                    None => {
                        return cx.fail(
                            *tp,
                            format!("`{n}` has no values for `{m} = {}`", vals[k].0),
                            &format!("add `actuate {n} = ... when {m} = {}`", vals[k].0),
                        )
                    }
                }
            }
            let mut z = Builder::default();
            let c = z.push(Op::Const(0.0)).expect("finite");
            act[i] = Some((z.finish(&[c]), None, 0));
            out_tables.push(InputTable {
                input: i,
                values: full,
            });
        }
        mode = Some(ModeVar {
            name: m.clone(),
            values: vals.iter().map(|v| v.0.clone()).collect(),
            init,
            networks_by,
            tables: out_tables,
        });
    }
    let mut actuate_ops = Vec::new();
    let mut clips = Vec::new();
    let mut n_net = 0;
    for (i, a) in act.into_iter().enumerate() {
        match a {
            Some((g, c, m)) => {
                actuate_ops.push(g);
                clips.push(c);
                n_net = n_net.max(m);
            }
            None => {
                let (n, p) = &inputs[i];
                return cx.fail(
                    *p,
                    format!("input `{n}` is never actuated"),
                    &format!("add e.g. `actuate {n} = net[{i}]`"),
                );
            }
        }
    }
    // One actuation graph with one output per input.
    let mut ab = Builder::default();
    let mut aouts = Vec::new();
    for g in &actuate_ops {
        let mut map = Vec::with_capacity(g.ops.len());
        for op in &g.ops {
            let o = op.remap(|k| map[k]);
            match ab.push(o) {
                Some(k) => map.push(k),
                None => {
                    return cx.fail(
                        Pos::default(),
                        "an actuation does not evaluate to a finite number".into(),
                        "check the constants of the `actuate` lines",
                    )
                }
            }
        }
        aouts.push(map[g.outputs[0]]);
    }
    let actuate = ab.finish(&aouts);
    if let Some(m) = &mode {
        n_net = n_net.max(m.values.len());
    }
    let observe = match observe {
        Some(g) => g,
        None => {
            let mut b = Builder::default();
            let o: Vec<usize> = (0..states.len())
                .map(|i| b.push(Op::State(i)).expect("state"))
                .collect();
            b.finish(&o)
        }
    };
    let mut goals = Vec::new();
    for (g, w, p) in goal_asts {
        let window = |win: &Option<(Expr, Expr)>| -> R<(f64, f64)> {
            match win {
                None => Ok((0.0, horizon)),
                Some((a, b)) => {
                    let (t1, t2) = range(&cx, a, b, "time window")?;
                    if t1 < 0.0 || t2 > horizon * (1.0 + 1e-12) {
                        return cx.fail(
                            a.pos(),
                            format!("the window [{t1}, {t2}] is not inside [0, {horizon}]"),
                            "keep goal windows within the horizon",
                        );
                    }
                    Ok((t1, t2))
                }
            }
        };
        let when = match w {
            WhenAst::End => When::End,
            WhenAst::Always(win) => {
                let (a, b) = window(win)?;
                When::Always(a, b)
            }
            WhenAst::Eventually(win) => {
                let (a, b) = window(win)?;
                When::Eventually(a, b)
            }
        };
        let bx = |v: &Vec<(String, Pos, Expr, Expr)>| -> R<Vec<(f64, f64)>> {
            let mut b = vec![(f64::NEG_INFINITY, f64::INFINITY); states.len()];
            for (n, q, lo, hi) in v {
                let i = state_index(n, *q)?;
                b[i] = range(&cx, lo, hi, "goal interval")?;
            }
            Ok(b)
        };
        let kind = match g {
            GoalAst::Reach(v) => GoalKind::Reach(bx(v)?),
            GoalAst::Avoid(v) => GoalKind::Avoid(bx(v)?),
            GoalAst::Band { expr, lo, hi, abs } => {
                let mut l = Lower::new(&cx, Mode::States, &lets)?;
                let o = l.expr(expr)?;
                let graph = l.b.finish(&[o]);
                if graph.reads_inputs() {
                    return cx.fail(
                        expr.pos(),
                        "a goal band depends on an input (through a `let`)".into(),
                        "write goals over states only",
                    );
                }
                let hi = match hi {
                    Some(e) => constant(&cx, e)?,
                    None => f64::INFINITY,
                };
                let lo = match (lo, abs) {
                    (Some(e), _) => constant(&cx, e)?,
                    (None, true) => -hi,
                    (None, false) => f64::NEG_INFINITY,
                };
                if lo > hi {
                    return cx.fail(
                        expr.pos(),
                        format!("the band [{lo}, {hi}] is empty"),
                        "check the bounds",
                    );
                }
                let linear = graph
                    .affine(states.len(), 0)
                    .map(|a| (a.state[0].clone(), a.offset[0]));
                GoalKind::Band {
                    graph,
                    lo,
                    hi,
                    linear,
                }
            }
        };
        let text = src
            .lines()
            .nth(p.line.saturating_sub(1))
            .unwrap_or("")
            .trim()
            .to_string();
        goals.push(Goal {
            kind,
            when,
            text,
            pos: p,
        });
    }
    Ok(System {
        name,
        file: file.to_string(),
        states: states.into_iter().map(|s| s.0).collect(),
        inputs: inputs.into_iter().map(|s| s.0).collect(),
        params,
        period,
        horizon,
        init: init_box,
        observe,
        actuate,
        clips,
        n_net_outputs: n_net,
        resets,
        goals,
        switches,
        switch_conditions,
        discrete: next_graph.map(|next| Discrete { next, mode }),
        rhs,
        src: src.to_string(),
    })
}

/// The source of an `if` for messages: its whole line (trimmed) when short, else 100
/// characters from the `if` on (a long line of many `if`s is not copied for each).
fn switch_excerpt(line: &str, col: usize) -> String {
    let line = line.trim_end();
    if line.len() <= 160 {
        return line.trim_start().to_string();
    }
    // The column as a byte offset (exact for ASCII; elsewhere the nearest character
    // boundary after it): constant work per `if`, however long the line.
    let mut at = col.saturating_sub(1).min(line.len());
    while !line.is_char_boundary(at) {
        at += 1;
    }
    let from: String = line[at..].chars().take(100).collect();
    format!("... {from} ...")
}
