//! The compiled expression graph: a flat list of instructions in evaluation order, each
//! operand an earlier instruction. Built by hash-consing (a common subexpression is one
//! instruction), constant subexpressions folded in f64, unused instructions dropped.

use samara_num::{Scalar, Sign};
use std::collections::HashMap;

/// One-argument operations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Un {
    /// `-x`.
    Neg,
    /// `x^2` ([`Scalar::sqr`]).
    Sqr,
    /// Square root.
    Sqrt,
    /// Exponential.
    Exp,
    /// Natural logarithm.
    Ln,
    /// Sine.
    Sin,
    /// Cosine.
    Cos,
    /// Tangent.
    Tan,
    /// Hyperbolic tangent.
    Tanh,
    /// Arc tangent.
    Atan,
    /// Absolute value.
    Abs,
    /// Three-way sign (-1, 0, 1).
    Sgn,
}

/// Two-argument operations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Bin2 {
    /// `a + b`.
    Add,
    /// `a - b`.
    Sub,
    /// `a * b`.
    Mul,
    /// `a / b`.
    Div,
    /// `min(a, b)`.
    Min,
    /// `max(a, b)`.
    Max,
}

/// Branch conditions of [`Op::Select`], on the sign of the condition operand `c`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Cond {
    /// `c < 0`.
    Neg,
    /// `c <= 0`.
    NonPos,
}

/// One instruction. Operands are indices of earlier instructions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Op {
    /// A constant.
    Const(f64),
    /// State component `i`.
    State(usize),
    /// Input `i` (for the actuation map: network output `i`).
    Input(usize),
    /// `f(a)`.
    Un(Un, usize),
    /// `a op b`.
    Bin(Bin2, usize, usize),
    /// `a + c`.
    AddC(usize, f64),
    /// `a - c`.
    SubC(usize, f64),
    /// `c - a`, evaluated as `-a + c`.
    CSub(f64, usize),
    /// `a * c`.
    MulC(usize, f64),
    /// `a / c`.
    DivC(usize, f64),
    /// `c / a`.
    CDiv(f64, usize),
    /// `a^n` for an integer `n >= 3` ([`Scalar::powi`]).
    Powi(usize, u32),
    /// `if cond(c) then a else b`; undecided for a set: the hull of `a` and `b`.
    Select(Cond, usize, usize, usize),
}

impl Op {
    /// The instruction as a hashable key (constants by their bits).
    pub(crate) fn key(&self) -> (u8, u64, u64, u64) {
        let b = |x: f64| x.to_bits();
        let u = |x: usize| x as u64;
        match *self {
            Op::Const(c) => (0, b(c), 0, 0),
            Op::State(i) => (1, u(i), 0, 0),
            Op::Input(i) => (2, u(i), 0, 0),
            Op::Un(f, a) => (3, f as u64, u(a), 0),
            Op::Bin(f, a, c) => (4, f as u64, u(a), u(c)),
            Op::AddC(a, c) => (5, u(a), b(c), 0),
            Op::SubC(a, c) => (6, u(a), b(c), 0),
            Op::CSub(c, a) => (7, u(a), b(c), 0),
            Op::MulC(a, c) => (8, u(a), b(c), 0),
            Op::DivC(a, c) => (9, u(a), b(c), 0),
            Op::CDiv(c, a) => (10, u(a), b(c), 0),
            Op::Powi(a, n) => (11, u(a), n as u64, 0),
            Op::Select(k, c, a, d) => (12 + k as u8, u(c), u(a), u(d)),
        }
    }

    pub(crate) fn operands(&self) -> ([usize; 3], usize) {
        match *self {
            Op::Const(_) | Op::State(_) | Op::Input(_) => ([0; 3], 0),
            Op::Un(_, a)
            | Op::AddC(a, _)
            | Op::SubC(a, _)
            | Op::CSub(_, a)
            | Op::MulC(a, _)
            | Op::DivC(a, _)
            | Op::CDiv(_, a)
            | Op::Powi(a, _) => ([a, 0, 0], 1),
            Op::Bin(_, a, b) => ([a, b, 0], 2),
            Op::Select(_, c, a, b) => ([c, a, b], 3),
        }
    }

    /// The same operation on operands renumbered by `m`.
    pub(crate) fn remap(self, m: impl Fn(usize) -> usize) -> Op {
        match self {
            Op::Un(f, a) => Op::Un(f, m(a)),
            Op::Bin(f, a, b) => Op::Bin(f, m(a), m(b)),
            Op::AddC(a, c) => Op::AddC(m(a), c),
            Op::SubC(a, c) => Op::SubC(m(a), c),
            Op::CSub(c, a) => Op::CSub(c, m(a)),
            Op::MulC(a, c) => Op::MulC(m(a), c),
            Op::DivC(a, c) => Op::DivC(m(a), c),
            Op::CDiv(c, a) => Op::CDiv(c, m(a)),
            Op::Powi(a, n) => Op::Powi(m(a), n),
            Op::Select(k, c, a, b) => Op::Select(k, m(c), m(a), m(b)),
            other => other,
        }
    }
}

pub(crate) fn un<S: Scalar>(f: Un, x: &S) -> S {
    match f {
        Un::Neg => -x.clone(),
        Un::Sqr => x.sqr(),
        Un::Sqrt => x.sqrt(),
        Un::Exp => x.exp(),
        Un::Ln => x.ln(),
        Un::Sin => x.sin(),
        Un::Cos => x.cos(),
        Un::Tan => x.tan(),
        Un::Tanh => x.tanh(),
        Un::Atan => x.atan(),
        Un::Abs => x.abs(),
        Un::Sgn => x.sgn(),
    }
}

pub(crate) fn bin<S: Scalar>(f: Bin2, a: &S, b: &S) -> S {
    match f {
        Bin2::Add => a.clone() + b.clone(),
        Bin2::Sub => a.clone() - b.clone(),
        Bin2::Mul => a.clone() * b.clone(),
        Bin2::Div => a.clone() / b.clone(),
        Bin2::Min => a.smin(b),
        Bin2::Max => a.smax(b),
    }
}

fn select<S: Scalar>(k: Cond, c: &S, a: &S, b: &S) -> S {
    let s = c.sign();
    let decided = match (k, s) {
        (Cond::Neg, Sign::Negative) => Some(true),
        (Cond::Neg, Sign::Positive | Sign::Zero | Sign::NonNegative) => Some(false),
        (Cond::NonPos, Sign::Negative | Sign::Zero | Sign::NonPositive) => Some(true),
        (Cond::NonPos, Sign::Positive) => Some(false),
        _ => None,
    };
    match decided {
        Some(true) => a.clone(),
        Some(false) => b.clone(),
        None => a.hull(b),
    }
}

/// The graph: instructions and the indices of its outputs.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Graph {
    /// Instructions in evaluation order.
    pub ops: Vec<Op>,
    /// Output instruction of each output.
    pub outputs: Vec<usize>,
}

/// An affine map `out = A_state x + A_input u + b` (rows: outputs).
#[derive(Clone, Debug, PartialEq)]
pub struct Affine {
    /// Coefficients of the states, one row per output.
    pub state: Vec<Vec<f64>>,
    /// Coefficients of the inputs (network outputs for the actuation map), one row per output.
    pub input: Vec<Vec<f64>>,
    /// Constant terms.
    pub offset: Vec<f64>,
}

impl Graph {
    /// Evaluate every output, with `scratch` as the value buffer (reused between calls).
    pub fn eval_with<S: Scalar>(
        &self,
        scratch: &mut Vec<S>,
        state: &[S],
        input: &[S],
        out: &mut [S],
    ) {
        scratch.clear();
        scratch.reserve(self.ops.len());
        for op in &self.ops {
            let v = {
                let r = &*scratch;
                match *op {
                    Op::Const(c) => S::cst(c),
                    Op::State(i) => state[i].clone(),
                    Op::Input(i) => input[i].clone(),
                    Op::Un(f, a) => un(f, &r[a]),
                    Op::Bin(f, a, b) => bin(f, &r[a], &r[b]),
                    Op::AddC(a, c) => r[a].clone() + c,
                    Op::SubC(a, c) => r[a].clone() - c,
                    Op::CSub(c, a) => -r[a].clone() + c,
                    Op::MulC(a, c) => r[a].clone() * c,
                    Op::DivC(a, c) => r[a].clone() / c,
                    Op::CDiv(c, a) => S::cst(c) / r[a].clone(),
                    Op::Powi(a, n) => r[a].powi(n),
                    Op::Select(k, c, a, b) => select(k, &r[c], &r[a], &r[b]),
                }
            };
            scratch.push(v);
        }
        for (o, &k) in out.iter_mut().zip(&self.outputs) {
            *o = scratch[k].clone();
        }
    }

    /// Evaluate every output (allocates a value buffer; see [`Graph::eval_with`]).
    pub fn eval<S: Scalar>(&self, state: &[S], input: &[S], out: &mut [S]) {
        let mut scratch = Vec::new();
        self.eval_with(&mut scratch, state, input, out);
    }

    /// Whether any instruction reads an input.
    pub fn reads_inputs(&self) -> bool {
        self.ops.iter().any(|o| matches!(o, Op::Input(_)))
    }

    /// The affine form of the outputs, or `None` if some output is not affine (a product
    /// of two non-constants, a division by a non-constant, a nonlinear function).
    pub fn affine(&self, n_state: usize, n_input: usize) -> Option<Affine> {
        let mut rows: Vec<(Vec<f64>, Vec<f64>, f64)> = Vec::with_capacity(self.ops.len());
        let lin = |r: &(Vec<f64>, Vec<f64>, f64), s: f64, c: f64| -> (Vec<f64>, Vec<f64>, f64) {
            (
                r.0.iter().map(|v| v * s).collect(),
                r.1.iter().map(|v| v * s).collect(),
                r.2 * s + c,
            )
        };
        let zero = (vec![0.0; n_state], vec![0.0; n_input], 0.0);
        for op in &self.ops {
            let row = match *op {
                Op::Const(c) => (zero.0.clone(), zero.1.clone(), c),
                Op::State(i) => {
                    let mut r = zero.clone();
                    *r.0.get_mut(i)? = 1.0;
                    r
                }
                Op::Input(i) => {
                    let mut r = zero.clone();
                    *r.1.get_mut(i)? = 1.0;
                    r
                }
                Op::Un(Un::Neg, a) => lin(&rows[a], -1.0, 0.0),
                Op::Bin(f @ (Bin2::Add | Bin2::Sub), a, b) => {
                    let s = if f == Bin2::Add { 1.0 } else { -1.0 };
                    let (x, y) = (&rows[a], &rows[b]);
                    (
                        x.0.iter().zip(&y.0).map(|(p, q)| p + s * q).collect(),
                        x.1.iter().zip(&y.1).map(|(p, q)| p + s * q).collect(),
                        x.2 + s * y.2,
                    )
                }
                Op::AddC(a, c) => lin(&rows[a], 1.0, c),
                Op::SubC(a, c) => lin(&rows[a], 1.0, -c),
                Op::CSub(c, a) => lin(&rows[a], -1.0, c),
                Op::MulC(a, c) => lin(&rows[a], c, 0.0),
                Op::DivC(a, c) => lin(&rows[a], 1.0 / c, 0.0),
                _ => return None,
            };
            rows.push(row);
        }
        let mut a = Affine {
            state: vec![],
            input: vec![],
            offset: vec![],
        };
        for &o in &self.outputs {
            let r = &rows[o];
            a.state.push(r.0.clone());
            a.input.push(r.1.clone());
            a.offset.push(r.2);
        }
        Some(a)
    }
}

/// A stand-in for one instruction: the polynomial `sum_k coef[k] (z - centre)^k` of its
/// operand `z`, plus an input that carries the difference (see [`Graph::with_stand_ins`]).
#[derive(Clone, Debug, PartialEq)]
pub struct StandIn {
    /// The instruction replaced (a one-argument [`Op::Un`]).
    pub node: usize,
    /// Expansion point of the polynomial.
    pub centre: f64,
    /// Coefficients, constant first.
    pub coef: Vec<f64>,
    /// The input index that carries `f(z) - p(z)`.
    pub input: usize,
}

impl Graph {
    /// The graph with each stand-in's instruction `f(z)` replaced by `p(z) + input`: with
    /// the input set to `f(z) - p(z)` it computes the same function, and with the input
    /// held in an interval it encloses it. This is how a non-analytic or stiff term (an
    /// `abs` across 0, a `sqrt` near 0) is flown as a polynomial plus a bounded
    /// disturbance (`samara_reach::tmflow`). Stand-ins on instructions that are not
    /// one-argument operations are ignored.
    pub fn with_stand_ins(&self, subs: &[StandIn]) -> Graph {
        let mut ops: Vec<Op> = Vec::with_capacity(self.ops.len() + 8 * subs.len());
        let mut map = vec![0usize; self.ops.len()];
        for (i, op) in self.ops.iter().enumerate() {
            let sub = subs.iter().find(|s| s.node == i);
            match (sub, *op) {
                (Some(s), Op::Un(_, a)) if !s.coef.is_empty() => {
                    let z = map[a];
                    let d = if s.centre == 0.0 {
                        z
                    } else {
                        ops.push(Op::SubC(z, s.centre));
                        ops.len() - 1
                    };
                    let n = s.coef.len() - 1;
                    ops.push(Op::Const(s.coef[n]));
                    let mut acc = ops.len() - 1;
                    for k in (0..n).rev() {
                        ops.push(Op::Bin(Bin2::Mul, acc, d));
                        ops.push(Op::AddC(ops.len() - 1, s.coef[k]));
                        acc = ops.len() - 1;
                    }
                    ops.push(Op::Input(s.input));
                    ops.push(Op::Bin(Bin2::Add, acc, ops.len() - 1));
                    map[i] = ops.len() - 1;
                }
                _ => {
                    ops.push(op.remap(|k| map[k]));
                    map[i] = ops.len() - 1;
                }
            }
        }
        Graph {
            ops,
            outputs: self.outputs.iter().map(|&o| map[o]).collect(),
        }
    }
}

/// Hash-consing graph builder with constant folding.
#[derive(Default)]
pub(crate) struct Builder {
    pub ops: Vec<Op>,
    memo: HashMap<(u8, u64, u64, u64), usize>,
}

impl Builder {
    pub fn konst(&self, i: usize) -> Option<f64> {
        match self.ops[i] {
            Op::Const(c) => Some(c),
            _ => None,
        }
    }

    /// Add an instruction, folding constants; `None` if a folded constant is not finite.
    pub fn push(&mut self, op: Op) -> Option<usize> {
        let folded = match op {
            Op::Un(f, a) => self.konst(a).map(|x| un(f, &x)),
            Op::Bin(f, a, b) => match (self.konst(a), self.konst(b)) {
                (Some(x), Some(y)) => Some(bin(f, &x, &y)),
                _ => None,
            },
            Op::AddC(a, c) => self.konst(a).map(|x| x + c),
            Op::SubC(a, c) => self.konst(a).map(|x| x - c),
            Op::CSub(c, a) => self.konst(a).map(|x| -x + c),
            Op::MulC(a, c) => self.konst(a).map(|x| x * c),
            Op::DivC(a, c) => self.konst(a).map(|x| x / c),
            Op::CDiv(c, a) => self.konst(a).map(|x| c / x),
            Op::Powi(a, n) => self.konst(a).map(|x| Scalar::powi(&x, n)),
            Op::Select(k, c, a, b) => {
                if let Some(x) = self.konst(c) {
                    let yes = match k {
                        Cond::Neg => x < 0.0,
                        Cond::NonPos => x <= 0.0,
                    };
                    return Some(if yes { a } else { b });
                }
                if a == b {
                    return Some(a);
                }
                None
            }
            _ => None,
        };
        let op = match folded {
            Some(v) if !v.is_finite() => return None,
            Some(v) => Op::Const(v),
            None => match op {
                // Exact identities only (no reassociation: bits are kept).
                Op::MulC(a, c) | Op::DivC(a, c) if c == 1.0 => return Some(a),
                Op::Un(Un::Neg, a) => match self.ops[a] {
                    Op::Un(Un::Neg, b) => return Some(b),
                    _ => op,
                },
                _ => op,
            },
        };
        if let Op::Const(c) = op {
            if !c.is_finite() {
                return None;
            }
        }
        let key = op.key();
        if let Some(&i) = self.memo.get(&key) {
            return Some(i);
        }
        self.ops.push(op);
        self.memo.insert(key, self.ops.len() - 1);
        Some(self.ops.len() - 1)
    }

    /// The graph with the given outputs, unused instructions removed.
    pub fn finish(&self, outputs: &[usize]) -> Graph {
        let mut live = vec![false; self.ops.len()];
        for &o in outputs {
            live[o] = true;
        }
        for i in (0..self.ops.len()).rev() {
            if live[i] {
                let (a, n) = self.ops[i].operands();
                for &k in &a[..n] {
                    live[k] = true;
                }
            }
        }
        let mut new_index = vec![usize::MAX; self.ops.len()];
        let mut ops = Vec::new();
        for (i, op) in self.ops.iter().enumerate() {
            if !live[i] {
                continue;
            }
            let op = op.remap(|k| new_index[k]);
            new_index[i] = ops.len();
            ops.push(op);
        }
        Graph {
            ops,
            outputs: outputs.iter().map(|&o| new_index[o]).collect(),
        }
    }
}
