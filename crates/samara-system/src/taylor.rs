//! Taylor coefficients in time over a [`Graph`] by incremental Taylor-mode AD, and
//! [`record`]: any generic [`Scalar`] function (the built-in glider's `Plant::rhs`)
//! recorded into a graph, so that it gets the same.
//!
//! The solution of `x' = g(x, u)` (`u` held) has coefficients `x_{k+1} = g_k / (k + 1)`,
//! where `g_k` is the `k`-th coefficient of `g` along the solution. Running `g` on
//! truncated series ([`Series`]) once per order recomputes every lower coefficient of
//! every intermediate each time: `O(K^3)` products per instruction for `K` orders. Here
//! every instruction keeps its coefficients, and order `k` computes only coefficient `k`
//! of each, from the lower ones, by the classical recurrences (Moore, *Interval
//! Analysis*, 1966; Griewank & Walther, *Evaluating Derivatives*, 2nd ed., ch. 13):
//! `O(K^2)`. The recurrences and their evaluation order are those of [`Series`], so the
//! coefficients are the same numbers (in interval arithmetic: the same enclosures), and
//! branches are decided the same way, on the constant coefficient, strictly; an
//! undecided one marks the result `bad` as there. Instructions without a recurrence here
//! (`tan`, `min`, `max`, `sgn`, `powi`) are accepted on constants (the held inputs and
//! what depends only on them); elsewhere they give `None`, and callers run the series.

use crate::graph::{Bin2, Cond, Graph, Op, Un};
use samara_num::{conv, dconv, Scalar, Series, Sign};
use std::cell::RefCell;
use std::collections::HashMap;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// The Taylor series in time, coefficients `0..=upto`, of the solution of
/// `x' = g(x, u)` from `x0` under the held inputs `u`, as [`Series`] with `n = upto + 1`
/// (`bad` where a branch was undecided); `None` if an instruction without a recurrence
/// here reads the states, or `upto + 1 > K`.
pub fn solution_series<S: Scalar, const K: usize>(
    g: &Graph,
    x0: &[S],
    u: &[S],
    upto: usize,
) -> Option<Vec<Series<S, K>>> {
    solution_series_trimmed::<S, K>(g, x0, u, upto, &|_, v| v)
}

/// The order at which `acc - sum_{j in js} p_j q_{i-j}` ends (the smallest
/// [`Scalar::trunc_order`] of its terms): what [`Scalar::mul_capped`] truncates the products of a quotient's or
/// root's recurrence at, as `samara_num::conv` does.
fn quot_cap<S: Scalar>(acc: &S, p: &[S], q: &[S], i: usize, js: std::ops::Range<usize>) -> u32 {
    js.map(|j| p[j].trunc_order().min(q[i - j].trunc_order()))
        .fold(acc.trunc_order(), u32::min)
}

/// [`solution_series`] with each state's time coefficient `k >= 1` passed through
/// `trim(k, x_k)` before the later orders read it. `trim` must return an enclosure of
/// its argument (for Taylor models: the same function with terms past a lower order
/// bounded into the remainder), so that the coefficients stay sound; what it saves is
/// the arithmetic of the higher time orders, whose contribution `x_k h^k` is small.
pub fn solution_series_trimmed<S: Scalar, const K: usize>(
    g: &Graph,
    x0: &[S],
    u: &[S],
    upto: usize,
    trim: &dyn Fn(usize, S) -> S,
) -> Option<Vec<Series<S, K>>> {
    solution_series_trimmed_in::<S, K>(g, x0, u, upto, trim, &mut SeriesScratch::default())
}

/// The working storage of [`solution_series_trimmed_in`]: every instruction's
/// coefficients and the per-instruction flags. A caller that expands many series (one
/// validated step of the zonotope flow expands three) keeps one and passes it to every
/// expansion, so that the tables are allocated once, not per expansion; the contents
/// never carry over (each expansion writes every coefficient before reading it, and
/// resets the constants' zeros).
#[derive(Debug)]
pub struct SeriesScratch<S> {
    c: Vec<S>,
    aux: Vec<S>,
    aux2: Vec<S>,
    slot: Vec<usize>,
    twin: Vec<usize>,
    trig: Vec<usize>,
    konst: Vec<bool>,
    bad: Vec<bool>,
    pick: Vec<i8>,
}

impl<S> Default for SeriesScratch<S> {
    fn default() -> Self {
        SeriesScratch {
            c: Vec::new(),
            aux: Vec::new(),
            aux2: Vec::new(),
            slot: Vec::new(),
            twin: Vec::new(),
            trig: Vec::new(),
            konst: Vec::new(),
            bad: Vec::new(),
            pick: Vec::new(),
        }
    }
}

/// `v` with `n` entries, reusing its allocation: the first ones as they were, new ones
/// `x`.
fn resize<T: Clone>(v: &mut Vec<T>, n: usize, x: &T) {
    if v.len() > n {
        v.truncate(n);
    } else {
        v.resize(n, x.clone());
    }
}

/// `v` holding `n` copies of `x`, reusing its allocation.
fn refill<T: Clone>(v: &mut Vec<T>, n: usize, x: T) {
    v.clear();
    v.resize(n, x);
}

/// [`solution_series_trimmed`] in the storage `scratch` (the same numbers: the tables
/// are reset to what a fresh expansion allocates).
pub fn solution_series_trimmed_in<S: Scalar, const K: usize>(
    g: &Graph,
    x0: &[S],
    u: &[S],
    upto: usize,
    trim: &dyn Fn(usize, S) -> S,
    scratch: &mut SeriesScratch<S>,
) -> Option<Vec<Series<S, K>>> {
    let m = upto + 1;
    if m > K || g.outputs.len() != x0.len() || !prepare(g, m, scratch) {
        return None;
    }
    let mut x = start(x0, m);
    for i in 0..upto {
        advance(g, i, m, &mut x, u, trim, scratch);
    }
    Some(collect(g, x, m, &scratch.bad))
}

/// The states' series of [`solution_series_pair_in`]: on `S` to one order, on `T` to a
/// higher one.
pub type SeriesPair<S, T, const KS: usize, const KT: usize> =
    (Vec<Series<S, KS>>, Vec<Series<T, KT>>);

/// The expansion of [`solution_series_trimmed_in`] on `S` to order `upto_s`, continued on
/// `T` to order `upto_t` from the coefficients so far mapped by `proj` (both without
/// trimming): the coefficients `0..=upto_s` of the first and `0..=upto_t` of the second.
///
/// The lower orders are computed once, on `S`. Where `proj` maps each coefficient to
/// an enclosure of the same number in `T` (the value part of an interval dual), the
/// continuation encloses the higher coefficients: every recurrence of order `i` reads
/// coefficients below `i` only, and is inclusion-monotone. Where `proj` commutes with
/// every operation (the value part of an [`samara_num::IDual`] is computed by the very
/// interval operations on the value parts), the second series are, bit for bit, those of
/// [`solution_series_trimmed_in`] on `T` from `proj(x0)` (the Lohner step's Jacobian and
/// its higher orders over one box: the lower orders' values not computed twice). The
/// branches are decided once, on `S`. `None` where [`solution_series_trimmed_in`] gives
/// `None`, or `upto_s > upto_t`.
#[allow(clippy::too_many_arguments)]
pub fn solution_series_pair_in<S: Scalar, T: Scalar, const KS: usize, const KT: usize>(
    g: &Graph,
    x0: &[S],
    u: &[S],
    upto_s: usize,
    upto_t: usize,
    proj: &dyn Fn(&S) -> T,
    scratch_s: &mut SeriesScratch<S>,
    scratch_t: &mut SeriesScratch<T>,
) -> Option<SeriesPair<S, T, KS, KT>> {
    let (ms, mt) = (upto_s + 1, upto_t + 1);
    if ms > KS || mt > KT || upto_s > upto_t || g.outputs.len() != x0.len() {
        return None;
    }
    if !prepare(g, ms, scratch_s) || !prepare(g, mt, scratch_t) {
        return None;
    }
    let keep: &dyn Fn(usize, S) -> S = &|_, v| v;
    let mut xs = start(x0, ms);
    for i in 0..upto_s {
        advance(g, i, ms, &mut xs, u, keep, scratch_s);
    }
    // The same graph: the same rows and companion slots in both tables.
    let rows = |from: &[S], to: &mut [T]| {
        for (f, t) in from.chunks(ms).zip(to.chunks_mut(mt)) {
            for (a, b) in f.iter().zip(t.iter_mut()) {
                *b = proj(a);
            }
        }
    };
    rows(&scratch_s.c, &mut scratch_t.c);
    rows(&scratch_s.aux, &mut scratch_t.aux);
    rows(&scratch_s.aux2, &mut scratch_t.aux2);
    scratch_t.bad.clone_from(&scratch_s.bad);
    scratch_t.pick.clone_from(&scratch_s.pick);
    let mut xt: Vec<Vec<T>> = xs
        .iter()
        .map(|r| {
            let mut v = vec![T::cst(0.0); mt];
            for (a, b) in r.iter().zip(v.iter_mut()) {
                *b = proj(a);
            }
            v
        })
        .collect();
    let ut: Vec<T> = u.iter().map(proj).collect();
    let keep_t: &dyn Fn(usize, T) -> T = &|_, v| v;
    for i in upto_s..upto_t {
        advance(g, i, mt, &mut xt, &ut, keep_t, scratch_t);
    }
    Some((
        collect(g, xs, ms, &scratch_s.bad),
        collect(g, xt, mt, &scratch_t.bad),
    ))
}

/// The states' coefficient table: row `j` holds `x0[j]` and `m - 1` zeros.
fn start<S: Scalar>(x0: &[S], m: usize) -> Vec<Vec<S>> {
    x0.iter()
        .map(|v| {
            let mut r = vec![S::cst(0.0); m];
            r[0] = v.clone();
            r
        })
        .collect()
}

/// Reset the tables of `scratch` for an expansion of `g` with `m` coefficients per row;
/// `false` if an instruction without a recurrence here reads the states.
fn prepare<S: Scalar>(g: &Graph, m: usize, scratch: &mut SeriesScratch<S>) -> bool {
    let SeriesScratch {
        c,
        aux,
        aux2,
        slot,
        twin,
        trig,
        konst,
        bad,
        pick,
    } = scratch;
    let nops = g.ops.len();
    let zero = S::cst(0.0);
    // Coefficients per instruction: row `k` is `c[k * m..(k + 1) * m]`. Only the
    // constants' higher coefficients (zero) are reset, below: every other coefficient
    // a recurrence reads is written first (order `i` of an instruction reads the orders
    // up to `i` of earlier instructions and below `i` of its own row and companion
    // rows, all computed before it), so what an earlier expansion left is never read.
    resize(c, nops * m, &zero);
    // Companion series only for the instructions that need them: `slot[k]` is the row
    // of instruction `k` in `aux` (sin, cos, tanh, atan) and `aux2` (atan).
    // A sine and a cosine of the same operand are one pair of recurrences: the later
    // of the two (`twin[k]`, the earlier's index) reads its coefficients from the
    // earlier's companion row, which holds the very numbers it would compute (the same
    // recurrences on the same operands, in the same order).
    refill(slot, nops, usize::MAX);
    refill(twin, nops, usize::MAX);
    let mut slots = 0;
    // The sines and cosines met so far that have their own rows.
    trig.clear();
    for (k, op) in g.ops.iter().enumerate() {
        if let Op::Un(f @ (Un::Sin | Un::Cos), a) = *op {
            let other = if f == Un::Sin { Un::Cos } else { Un::Sin };
            if let Some(&j) = trig.iter().find(|&&j| g.ops[j] == Op::Un(other, a)) {
                twin[k] = j;
                continue;
            }
            trig.push(k);
        }
        if matches!(op, Op::Un(Un::Sin | Un::Cos | Un::Tanh | Un::Atan, _)) {
            slot[k] = slots;
            slots += 1;
        }
    }
    resize(aux, slots * m, &zero);
    resize(aux2, slots * m, &zero);
    refill(konst, nops, false);
    refill(bad, nops, false);
    // Decided branches, per instruction (0: undecided): for `abs` the sign -1 / 1, for
    // `select` 1 the first branch, -1 the second.
    refill(pick, nops, 0i8);
    // Instructions without a recurrence here (tan, sgn, min, max, powi) are taken
    // only on constants, by their own arithmetic on the constant coefficient (as a
    // series of constants computes them).
    for (k, op) in g.ops.iter().enumerate() {
        let generic = match *op {
            Op::Const(_) | Op::Input(_) => {
                konst[k] = true;
                false
            }
            Op::State(_) => false,
            Op::Un(f, a) => {
                konst[k] = konst[a];
                matches!(f, Un::Tan | Un::Sgn)
            }
            Op::Bin(f, a, b) => {
                konst[k] = konst[a] && konst[b];
                matches!(f, Bin2::Min | Bin2::Max)
            }
            Op::AddC(a, _)
            | Op::SubC(a, _)
            | Op::CSub(_, a)
            | Op::MulC(a, _)
            | Op::DivC(a, _)
            | Op::CDiv(_, a) => {
                konst[k] = konst[a];
                false
            }
            Op::Powi(a, _) => {
                konst[k] = konst[a];
                true
            }
            Op::Select(_, _, a, b) => {
                konst[k] = konst[a] && konst[b];
                false
            }
        };
        if generic && !konst[k] {
            return false;
        }
    }
    for (row, _) in c.chunks_mut(m).zip(konst.iter()).filter(|(_, &k)| k) {
        row[1..].fill(zero.clone());
    }
    true
}

/// Order `i` of every instruction (from the orders below it), then coefficient `i + 1`
/// of every state, through `trim`.
fn advance<S: Scalar>(
    g: &Graph,
    i: usize,
    m: usize,
    x: &mut [Vec<S>],
    u: &[S],
    trim: &dyn Fn(usize, S) -> S,
    scratch: &mut SeriesScratch<S>,
) {
    let nops = g.ops.len();
    let zero = S::cst(0.0);
    let SeriesScratch {
        c,
        aux,
        aux2,
        slot,
        twin,
        trig: _,
        konst,
        bad,
        pick,
    } = scratch;
    for k in 0..nops {
        // Constants have only their constant coefficient.
        if konst[k] && i > 0 {
            continue;
        }
        let v = {
            let r = |a: usize| &c[a * m..(a + 1) * m];
            match g.ops[k] {
                Op::Const(v) => S::cst(v),
                Op::State(s) => x[s][i].clone(),
                Op::Input(s) => u[s].clone(),
                Op::AddC(a, v) => {
                    if i == 0 {
                        r(a)[0].clone() + v
                    } else {
                        r(a)[i].clone()
                    }
                }
                Op::SubC(a, v) => {
                    if i == 0 {
                        r(a)[0].clone() - v
                    } else {
                        r(a)[i].clone()
                    }
                }
                Op::CSub(v, a) => {
                    if i == 0 {
                        -r(a)[0].clone() + v
                    } else {
                        -r(a)[i].clone()
                    }
                }
                Op::MulC(a, v) => r(a)[i].clone() * v,
                Op::DivC(a, v) => r(a)[i].clone() / v,
                // `S::cst(v) / a`: a constant numerator.
                Op::CDiv(v, a) => {
                    if konst[a] {
                        S::cst(v).div_by_ref(&r(a)[0])
                    } else {
                        let num = if i == 0 { S::cst(v) } else { zero.clone() };
                        let cap = quot_cap(&num, r(a), &c[k * m..(k + 1) * m], i, 1..i + 1);
                        let mut acc = num;
                        for j in 1..=i {
                            acc -= r(a)[j].mul_capped(&c[k * m + i - j], cap);
                        }
                        acc.div_by_ref(&r(a)[0])
                    }
                }
                Op::Bin(f, a, b) => match f {
                    Bin2::Add => r(a)[i].add_by_ref(&r(b)[i]),
                    Bin2::Sub => r(a)[i].sub_by_ref(&r(b)[i]),
                    Bin2::Mul => {
                        if konst[a] {
                            r(b)[i].mul_by_ref(&r(a)[0])
                        } else if konst[b] {
                            r(a)[i].mul_by_ref(&r(b)[0])
                        } else {
                            conv(r(a), r(b), i)
                        }
                    }
                    Bin2::Div => {
                        if konst[b] {
                            r(a)[i].clone().div_by_ref(&r(b)[0])
                        } else {
                            let mut acc = r(a)[i].clone();
                            let cap = quot_cap(&acc, r(b), &c[k * m..(k + 1) * m], i, 1..i + 1);
                            for j in 1..=i {
                                acc -= r(b)[j].mul_capped(&c[k * m + i - j], cap);
                            }
                            acc.div_by_ref(&r(b)[0])
                        }
                    }
                    // Constants only (refused above otherwise): i = 0.
                    Bin2::Min | Bin2::Max => crate::graph::bin(f, &r(a)[0], &r(b)[0]),
                },
                Op::Un(f, a) => match f {
                    Un::Neg => -r(a)[i].clone(),
                    Un::Sqr => {
                        if i == 0 {
                            r(a)[0].sqr()
                        } else {
                            conv(r(a), r(a), i)
                        }
                    }
                    Un::Sqrt => {
                        if i == 0 {
                            r(a)[0].sqrt()
                        } else {
                            let mut acc = r(a)[i].clone();
                            let row = &c[k * m..(k + 1) * m];
                            let cap = quot_cap(&acc, row, row, i, 1..i);
                            for j in 1..i {
                                acc -= c[k * m + j].mul_capped(&c[k * m + i - j], cap);
                            }
                            acc / (c[k * m].clone() * 2.0)
                        }
                    }
                    Un::Exp => {
                        if i == 0 {
                            r(a)[0].exp()
                        } else {
                            dconv(r(a), &c[k * m..(k + 1) * m], i)
                        }
                    }
                    Un::Ln => {
                        if i == 0 {
                            r(a)[0].ln()
                        } else {
                            let mut acc = r(a)[i].clone();
                            for j in 1..i {
                                acc -= c[k * m + j].clone()
                                    * r(a)[i - j].clone()
                                    * (j as f64 / i as f64);
                            }
                            acc.div_by_ref(&r(a)[0])
                        }
                    }
                    Un::Sin | Un::Cos if twin[k] != usize::MAX => {
                        aux[slot[twin[k]] * m + i].clone()
                    }
                    Un::Sin | Un::Cos => {
                        // Row `k` of `c` is this function, its `aux` row the companion.
                        let sin = f == Un::Sin;
                        if i == 0 {
                            let (s0, c0) = r(a)[0].sin_cos();
                            let (own, other) = if sin { (s0, c0) } else { (c0, s0) };
                            aux[slot[k] * m] = other;
                            own
                        } else {
                            let (own, other) = if sin {
                                let s = dconv(r(a), &aux[slot[k] * m..(slot[k] + 1) * m], i);
                                let co = -dconv(r(a), &c[k * m..(k + 1) * m], i);
                                (s, co)
                            } else {
                                let s = dconv(r(a), &c[k * m..(k + 1) * m], i);
                                let co = -dconv(r(a), &aux[slot[k] * m..(slot[k] + 1) * m], i);
                                (co, s)
                            };
                            aux[slot[k] * m + i] = other;
                            own
                        }
                    }
                    Un::Atan => {
                        // q = a^2 + 1 (aux), d_{i-1} = (i a_i - sum q_j d_{i-1-j}) / q_0
                        // (aux2), u_i = d_{i-1} / i.
                        if i == 0 {
                            aux[slot[k] * m] = r(a)[0].sqr() + 1.0;
                            r(a)[0].atan()
                        } else {
                            aux[slot[k] * m + i] = conv(r(a), r(a), i);
                            let q = i - 1;
                            let mut acc = r(a)[q + 1].clone() * (q as f64 + 1.0);
                            for j in 1..=q {
                                acc -= aux[slot[k] * m + j].clone()
                                    * aux2[slot[k] * m + q - j].clone();
                            }
                            let d = acc / aux[slot[k] * m].clone();
                            aux2[slot[k] * m + q] = d.clone();
                            d / i as f64
                        }
                    }
                    Un::Abs => {
                        if i == 0 {
                            pick[k] = match r(a)[0].sign().strict() {
                                Sign::Positive => 1,
                                Sign::Negative => -1,
                                _ => 0,
                            };
                        }
                        match pick[k] {
                            1 => r(a)[i].clone(),
                            -1 => -r(a)[i].clone(),
                            _ => r(a)[i].abs(),
                        }
                    }
                    Un::Tanh => {
                        // w = 1 - t^2 (aux): t_i = dconv(a, w, i) needs w up to
                        // i - 1, and w_{i-1} = -(t^2)_{i-1} the t stored so far.
                        if i == 0 {
                            let t0 = r(a)[0].tanh();
                            aux[slot[k] * m] = -t0.sqr() + 1.0;
                            t0
                        } else {
                            if i > 1 {
                                aux[slot[k] * m + i - 1] = -conv(r(k), r(k), i - 1);
                            }
                            dconv(r(a), &aux[slot[k] * m..(slot[k] + 1) * m], i)
                        }
                    }
                    // Constants only (refused above otherwise): i = 0.
                    Un::Tan | Un::Sgn => crate::graph::un(f, &r(a)[0]),
                },
                // Constants only (refused above otherwise): i = 0.
                Op::Powi(a, n) => r(a)[0].powi(n),
                Op::Select(cond, q, a, b) => {
                    if i == 0 {
                        let s = r(q)[0].sign().strict();
                        pick[k] = match (cond, s) {
                            (Cond::Neg | Cond::NonPos, Sign::Negative) => 1,
                            (Cond::Neg | Cond::NonPos, Sign::Positive) => -1,
                            _ => 0,
                        };
                    }
                    match pick[k] {
                        1 => r(a)[i].clone(),
                        -1 => r(b)[i].clone(),
                        _ => r(a)[i].hull(&r(b)[i]),
                    }
                }
            }
        };
        c[k * m + i] = v;
        if i == 0 {
            // Unusable if an operand is, or the branch was undecided; a decided
            // select takes its branch's flag, as a series would.
            bad[k] = match g.ops[k] {
                Op::Select(_, _, a, b) => match pick[k] {
                    1 => bad[a],
                    -1 => bad[b],
                    _ => true,
                },
                Op::Un(Un::Abs, a) => bad[a] || pick[k] == 0,
                op => {
                    let (ops, n) = op.operands();
                    ops[..n].iter().any(|&a| bad[a])
                }
            };
        }
    }
    for (j, &o) in g.outputs.iter().enumerate() {
        x[j][i + 1] = trim(i + 1, c[o * m + i].clone() / (i as f64 + 1.0));
    }
}

/// The states' series from their coefficient table (`bad` all of them where an output
/// is).
fn collect<S: Scalar, const K: usize>(
    g: &Graph,
    x: Vec<Vec<S>>,
    m: usize,
    bad: &[bool],
) -> Vec<Series<S, K>> {
    // A state whose series is bad makes every later coefficient of everything reading
    // it unusable: as with series, one bad output spoils them all.
    let all_bad = g.outputs.iter().any(|&o| bad[o]);
    x.into_iter()
        .map(|co| {
            let mut s = Series::var(co[0].clone());
            for (t, v) in co.into_iter().enumerate() {
                s.c[t] = v;
            }
            s.n = m;
            s.bad = all_bad;
            s
        })
        .collect()
}

/// What a recording has gathered so far: the instructions, whether an operation without
/// an instruction (a hull) was met, and whether the recorded function asked for a value
/// or a sign of its arguments (a branch that the values decide).
struct Tape {
    ops: Vec<Op>,
    refused: bool,
    asked: bool,
}

thread_local! {
    /// The recording in progress on this thread (`None`: not recording).
    static TAPE: RefCell<Option<Tape>> = const { RefCell::new(None) };
}

fn push(op: Op) -> usize {
    TAPE.with(|t| {
        let mut t = t.borrow_mut();
        let tape = t
            .as_mut()
            .expect("Rec used outside samara_system::taylor::record");
        tape.ops.push(op);
        tape.ops.len() - 1
    })
}

/// Note that the recorded function looked at a value (its instructions may depend on it).
fn asked() {
    TAPE.with(|t| {
        if let Some(tape) = t.borrow_mut().as_mut() {
            tape.asked = true;
        }
    });
}

/// A value being recorded: its instruction and its value in `S` (which decides the
/// branches the recorded function takes, as [`Series`] would decide them on its
/// constant coefficient).
#[derive(Clone, Debug)]
pub struct Rec<S: Scalar> {
    id: usize,
    val: S,
}

impl<S: Scalar> Rec<S> {
    fn un(&self, f: Un, val: S) -> Self {
        Rec {
            id: push(Op::Un(f, self.id)),
            val,
        }
    }
    fn bin(&self, f: Bin2, o: &Self, val: S) -> Self {
        Rec {
            id: push(Op::Bin(f, self.id, o.id)),
            val,
        }
    }
}

macro_rules! rec_ops {
    ($tr:ident, $m:ident, $f:expr, $trc:ident, $opc:ident) => {
        impl<S: Scalar> $tr for Rec<S> {
            type Output = Self;
            fn $m(self, o: Self) -> Self {
                let v = self.val.clone().$m(o.val.clone());
                self.bin($f, &o, v)
            }
        }
        impl<S: Scalar> $tr<f64> for Rec<S> {
            type Output = Self;
            fn $m(self, o: f64) -> Self {
                Rec {
                    id: push(Op::$opc(self.id, o)),
                    val: self.val.$m(o),
                }
            }
        }
    };
}
rec_ops!(Add, add, Bin2::Add, AddC, AddC);
rec_ops!(Sub, sub, Bin2::Sub, SubC, SubC);
rec_ops!(Mul, mul, Bin2::Mul, MulC, MulC);
rec_ops!(Div, div, Bin2::Div, DivC, DivC);

impl<S: Scalar> Neg for Rec<S> {
    type Output = Self;
    fn neg(self) -> Self {
        let v = -self.val.clone();
        self.un(Un::Neg, v)
    }
}
impl<S: Scalar> AddAssign for Rec<S> {
    fn add_assign(&mut self, o: Self) {
        *self = self.clone() + o;
    }
}
impl<S: Scalar> SubAssign for Rec<S> {
    fn sub_assign(&mut self, o: Self) {
        *self = self.clone() - o;
    }
}
impl<S: Scalar> MulAssign for Rec<S> {
    fn mul_assign(&mut self, o: Self) {
        *self = self.clone() * o;
    }
}

impl<S: Scalar> Scalar for Rec<S> {
    fn cst(c: f64) -> Self {
        Rec {
            id: push(Op::Const(c)),
            val: S::cst(c),
        }
    }
    fn value(&self) -> f64 {
        asked();
        self.val.value()
    }
    fn sin(&self) -> Self {
        self.un(Un::Sin, self.val.sin())
    }
    fn cos(&self) -> Self {
        self.un(Un::Cos, self.val.cos())
    }
    fn tanh(&self) -> Self {
        self.un(Un::Tanh, self.val.tanh())
    }
    fn atan(&self) -> Self {
        self.un(Un::Atan, self.val.atan())
    }
    fn sqrt(&self) -> Self {
        self.un(Un::Sqrt, self.val.sqrt())
    }
    fn exp(&self) -> Self {
        self.un(Un::Exp, self.val.exp())
    }
    fn abs(&self) -> Self {
        self.un(Un::Abs, self.val.abs())
    }
    fn ln(&self) -> Self {
        self.un(Un::Ln, self.val.ln())
    }
    fn sqr(&self) -> Self {
        self.un(Un::Sqr, self.val.sqr())
    }
    /// As [`Series`]: only a strict sign of the constant coefficient decides.
    fn sign(&self) -> Sign {
        asked();
        self.val.sign().strict()
    }
    /// A hull has no instruction: the recording is refused (a series would be `bad`).
    fn hull(&self, o: &Self) -> Self {
        TAPE.with(|t| {
            if let Some(tape) = t.borrow_mut().as_mut() {
                tape.refused = true;
            }
        });
        Rec {
            id: self.id,
            val: self.val.hull(&o.val),
        }
    }
}

/// Record `f(state, input, out)` (a generic right-hand side, e.g. the glider's
/// `Plant::rhs`) at the values `x`, `u` as a graph with states `x` and inputs `u`; the
/// branches it takes are those `S`'s values decide (strictly, as on series). `None` if
/// `f` took a hull (an undecided branch), which has no instruction.
pub fn record<S: Scalar>(
    x: &[S],
    u: &[S],
    n_out: usize,
    f: impl FnOnce(&[Rec<S>], &[Rec<S>], &mut [Rec<S>]),
) -> Option<Graph> {
    record_checked(x, u, n_out, f).map(|(g, _)| g)
}

/// [`record`], and whether its graph holds at every argument: `true` when `f` never
/// asked for a sign or a value of what it computes ([`Scalar::sign`],
/// [`Scalar::value`], through which every branch of a generic function on a
/// [`Scalar`] goes: the trait's own branching methods, `smin`, `relu`, `clamp_to`,
/// `sgn`, ..., call `sign`, and a hull refuses the recording). Its instructions then depend on nothing the values decide, and a
/// recording at any other `x`, `u` gives the same graph: a caller may keep it and
/// expand it at every argument (the glider's reduced model: one recording per thread
/// instead of one per validated step).
pub fn record_checked<S: Scalar>(
    x: &[S],
    u: &[S],
    n_out: usize,
    f: impl FnOnce(&[Rec<S>], &[Rec<S>], &mut [Rec<S>]),
) -> Option<(Graph, bool)> {
    TAPE.with(|t| {
        *t.borrow_mut() = Some(Tape {
            ops: Vec::new(),
            refused: false,
            asked: false,
        })
    });
    let xs: Vec<Rec<S>> = x
        .iter()
        .enumerate()
        .map(|(i, v)| Rec {
            id: push(Op::State(i)),
            val: v.clone(),
        })
        .collect();
    let us: Vec<Rec<S>> = u
        .iter()
        .enumerate()
        .map(|(i, v)| Rec {
            id: push(Op::Input(i)),
            val: v.clone(),
        })
        .collect();
    let mut out: Vec<Rec<S>> = (0..n_out)
        .map(|_| Rec {
            id: push(Op::Const(0.0)),
            val: S::cst(0.0),
        })
        .collect();
    f(&xs, &us, &mut out);
    let tape = TAPE.with(|t| t.borrow_mut().take()).expect("recording");
    if tape.refused {
        return None;
    }
    Some((
        Graph {
            ops: tape.ops,
            outputs: out.iter().map(|r| r.id).collect(),
        },
        !tape.asked,
    ))
}

/// `g` with every repeated instruction (the same operation on the same operands, constants
/// compared bit for bit) computed once and instructions no output reads dropped: common
/// subexpression elimination by hash-consing, as [`crate::System`]'s graphs are built.
/// Nothing is folded or reordered, so every expansion of the result gives the same
/// numbers as of `g`, with less work (the glider's recorded right-hand side computes
/// `alpha^2` and `omega^2` twice each).
pub fn merge_common(g: &Graph) -> Graph {
    let n = g.ops.len();
    // Renumbering of the first pass: each instruction to its first equal.
    let mut to = vec![0usize; n];
    let mut seen: HashMap<(u8, u64, u64, u64), usize> = HashMap::with_capacity(n);
    let mut ops: Vec<Op> = Vec::with_capacity(n);
    for (k, op) in g.ops.iter().enumerate() {
        let op = op.remap(|a| to[a]);
        to[k] = *seen.entry(op.key()).or_insert_with(|| {
            ops.push(op);
            ops.len() - 1
        });
    }
    let outputs: Vec<usize> = g.outputs.iter().map(|&o| to[o]).collect();
    // Drop what no output reads.
    let mut live = vec![false; ops.len()];
    for &o in &outputs {
        live[o] = true;
    }
    for k in (0..ops.len()).rev() {
        if live[k] {
            let (a, m) = ops[k].operands();
            for &j in &a[..m] {
                live[j] = true;
            }
        }
    }
    let mut index = vec![usize::MAX; ops.len()];
    let mut kept = Vec::with_capacity(ops.len());
    for (k, op) in ops.into_iter().enumerate() {
        if live[k] {
            index[k] = kept.len();
            kept.push(op.remap(|a| index[a]));
        }
    }
    Graph {
        ops: kept,
        outputs: outputs.iter().map(|&o| index[o]).collect(),
    }
}
