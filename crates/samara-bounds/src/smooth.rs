//! Input-domain branch and bound for networks with any of the IR's activations (sigmoid,
//! tanh and the step `Sign` as well as ReLU and clamp), on box-shaped queries ([`Case`]s)
//! whose inputs are partly fixed: VNN-COMP 2023's `dist_shift` fixes 784 of its 792
//! inputs (the image) and leaves 8 free (a generator's latent code).
//!
//! - **Several networks** ([`Apps`]): the applications of a relational query side by
//!   side, as one chain of block-diagonal affine maps with an activation per neuron
//!   (identity rows carry a shorter network's outputs and the inputs listed in
//!   [`Apps::through`], whose lines are exact), so that a constraint over inputs and
//!   outputs of several networks is a [`Case`] over this chain's outputs.
//!
//! - **Folding** ([`Folded`]): the inputs fixed to the same value in every case
//!   (`lo = hi`) are folded into the first affine map's bias, `b' = b + W_fixed x_fixed`,
//!   which leaves a network of the free inputs only, so that bounds cost and splitting
//!   work on those few dimensions. The rewrite is exact in real arithmetic; the f64
//!   rounding of `b'` is bounded per row (Higham's `gamma_k` times the sum of the
//!   magnitudes of the terms, [`samara_num::round::gamma`]) and carried as a radius of
//!   the bias that every bound adds, so the folded bounds hold for the original network
//!   over the original box. Points are re-expanded to every input ([`Folded::expand`])
//!   and evaluated on the original network.
//! - **Bounds**: CROWN (Zhang et al., "Efficient Neural Network Robustness Certification
//!   with General Activation Functions", NeurIPS 2018) by back-substitution over the
//!   folded chain, every intermediate neuron bounded by its own back-substitution and
//!   intersected with interval propagation and with the parent piece's bounds (all
//!   sound), each activation's lines from [`crate::rules`] (sigmoid and tanh:
//!   [`crate::rules::sigmoid_tanh`]). After a layer of steps the intermediate bounds
//!   are the interval rule's alone ([`crate::rules::sign`]: its lines are constants
//!   where it is stable and no tighter than its interval across the jump). Rounding is that of [`crate::linset`]: every f64
//!   dot product's error is bounded by `gamma_k` times the sum of the magnitudes of its
//!   terms times a bound of the variable it multiplies, so a bound holds in exact
//!   arithmetic over the stored weights.
//! - **Search**: an attack first (`attack`: signed-gradient descent from the
//!   centre and random starts, on the conjunction nearest to holding; through `Sign`
//!   the straight-through estimator's gradient), then depth-first splitting of the
//!   free inputs (the input with the largest smear `|coef_t| (hi_t - lo_t)` in the open
//!   constraints' linear bounds, as ReluVal, Wang et al., USENIX Security 2018), each
//!   piece closed when a constraint's lower bound is positive or a non-negative
//!   combination of the conjunction's bounds is (the `query` module's), its candidate
//!   points (the linear bound's minimising corner, the centre) checked on the original
//!   network ([`holds`]: beyond rounding, or an exact tie).

use crate::query::{combination_certifies, satisfies, Case};
use crate::rules::{self, Relax};
use crate::search::{CasePoint, Outcome, Settings, Stats, StopReason};
use crate::symbolic::Linear;
use rayon::prelude::*;
use samara_nn::{Activation, Affine, Layer, Network};
use samara_num::round::{gamma, inflate};
use samara_num::Interval;
use std::time::Instant;

/// One operation of the folded chain.
enum Op {
    Aff(Affine),
    Act(Acts),
}

/// The activations of one layer of the chain: one for every neuron (a network's own
/// layer), or one per neuron (several networks side by side, [`Apps`]), `None` for a
/// neuron passed on unchanged (an input carried to the outputs, a network shorter than
/// another).
enum Acts {
    All(Activation),
    Each(Vec<Option<Activation>>),
}

impl Acts {
    /// The activation of neuron `i` (`None`: the identity).
    fn at(&self, i: usize) -> Option<Activation> {
        match self {
            Acts::All(a) => Some(*a),
            Acts::Each(v) => v[i],
        }
    }

    /// Whether every neuron is the step `Sign` (see [`Folded::bounds`]).
    fn all_steps(&self) -> bool {
        match self {
            Acts::All(a) => *a == Activation::Sign,
            Acts::Each(v) => v.iter().all(|a| *a == Some(Activation::Sign)),
        }
    }

    /// The interval rule of neuron `i` over `[l, u]` ([`rules::interval`]).
    fn interval(&self, i: usize, l: f64, u: f64) -> (f64, f64) {
        match self.at(i) {
            Some(a) => rules::interval(a, l, u),
            None => (l, u),
        }
    }

    /// The lines of neuron `i` over `[l, u]` ([`rules::relax`]; the identity's are
    /// itself, exactly).
    fn relax(&self, i: usize, l: f64, u: f64) -> Relax {
        match self.at(i) {
            Some(a) => rules::relax(a, l, u),
            None => Relax::IDENTITY,
        }
    }
}

/// Networks side by side: the applications of a query that is not box-shaped over one
/// network (a relational property compares two of them), as one network whose inputs
/// are theirs concatenated and whose outputs are theirs concatenated, followed by the
/// inputs listed in `through` (so that a constraint over inputs and outputs is one over
/// the outputs of this network, and the search's [`Case`]s state it).
pub struct Apps<'a> {
    /// The networks, in the order of their inputs and outputs.
    pub nets: Vec<&'a Network>,
    /// Inputs (indices into the concatenated inputs) carried to the outputs, after the
    /// networks' own, in this order.
    pub through: Vec<usize>,
}

impl Apps<'_> {
    /// One network, no input carried.
    pub fn one(net: &Network) -> Apps<'_> {
        Apps {
            nets: vec![net],
            through: vec![],
        }
    }

    /// Number of inputs (all networks').
    pub fn n_inputs(&self) -> usize {
        self.nets.iter().map(|n| n.n_inputs()).sum()
    }

    /// The outputs at `x` (every network's f64 evaluation, then the carried inputs).
    pub fn eval(&self, x: &[f64]) -> Vec<f64> {
        let mut y = Vec::new();
        let mut off = 0;
        for n in &self.nets {
            y.extend(n.eval_f64(&x[off..off + n.n_inputs()]));
            off += n.n_inputs();
        }
        y.extend(self.through.iter().map(|&i| x[i]));
        y
    }

    /// The chain of layers: the network's own for one network with no input carried;
    /// otherwise each network as pairs of an affine map and an activation (an identity
    /// map before an activation that does not follow one, identity pairs after the
    /// shorter ones), the pairs of one depth side by side in one block-diagonal map
    /// with the carried inputs' identity rows below.
    fn layers(&self) -> Vec<Op> {
        let widths: Vec<usize> = self.nets.iter().map(|n| n.n_inputs()).collect();
        if let ([net], true) = (&self.nets[..], self.through.is_empty()) {
            // The network's own layers (a first map added when it starts otherwise).
            let mut ops: Vec<Op> = net
                .raw_layers()
                .into_iter()
                .map(|l| match l {
                    Layer::Affine(a) => Op::Aff(a),
                    Layer::Act(act) => Op::Act(Acts::All(act)),
                })
                .collect();
            if !matches!(ops.first(), Some(Op::Aff(_))) {
                ops.insert(0, Op::Aff(crate::pwl::identity(widths[0])));
            }
            return ops;
        }
        let pairs: Vec<Vec<(Affine, Option<Activation>)>> = self
            .nets
            .iter()
            .zip(&widths)
            .map(|(n, &w)| {
                let mut v: Vec<(Affine, Option<Activation>)> = Vec::new();
                for l in n.raw_layers() {
                    match l {
                        Layer::Affine(a) => v.push((a, None)),
                        Layer::Act(act) => match v.last_mut() {
                            Some((_, slot @ None)) => *slot = Some(act),
                            _ => {
                                let w = v.last().map_or(w, |p| p.0.out);
                                v.push((crate::pwl::identity(w), Some(act)));
                            }
                        },
                    }
                }
                v
            })
            .collect();
        let depth = pairs.iter().map(Vec::len).max().unwrap_or(0).max(1);
        let mut out = Vec::with_capacity(2 * depth);
        // Width of each network's current layer (its inputs first).
        let mut cur = widths.clone();
        for k in 0..depth {
            let inp: usize =
                cur.iter().sum::<usize>() + if k == 0 { 0 } else { self.through.len() };
            let mut rows: Vec<Vec<(usize, f64)>> = Vec::new();
            let mut b = Vec::new();
            let mut acts = Vec::new();
            let mut off = 0;
            for (p, c) in pairs.iter().zip(cur.iter_mut()) {
                match p.get(k) {
                    Some((a, act)) => {
                        for i in 0..a.out {
                            let mut r = Vec::new();
                            a.row(i).for_each_nonzero(|j, w| r.push((off + j, w)));
                            rows.push(r);
                        }
                        b.extend_from_slice(&a.b);
                        acts.extend(std::iter::repeat_n(*act, a.out));
                        off += *c;
                        *c = a.out;
                    }
                    None => {
                        rows.extend((0..*c).map(|j| vec![(off + j, 1.0)]));
                        b.extend(std::iter::repeat_n(0.0, *c));
                        acts.extend(std::iter::repeat_n(None, *c));
                        off += *c;
                    }
                }
            }
            for (j, &i) in self.through.iter().enumerate() {
                rows.push(vec![(if k == 0 { i } else { off + j }, 1.0)]);
                b.push(0.0);
                acts.push(None);
            }
            out.push(Op::Aff(Affine::from_rows(inp, rows, b)));
            if acts.iter().any(Option::is_some) {
                out.push(Op::Act(Acts::Each(acts)));
            }
        }
        out
    }
}

/// A network with the inputs fixed in every case folded into its first affine map (see
/// the module documentation).
pub struct Folded {
    /// Indices of the free inputs in the original network.
    pub free: Vec<usize>,
    /// The original input with the fixed values (free entries are overwritten).
    base: Vec<f64>,
    ops: Vec<Op>,
    /// Radius of the first map's bias: the bound of the fold's rounding, per row.
    rad: Vec<f64>,
}

/// Neurons whose two pulls share one pass over the weights ([`Folded::pull_block`]).
const PULL_BLOCK: usize = 8;

/// Intermediate bounds of one piece: per op but the last, the bounds of its output.
type Bounds = Vec<Vec<(f64, f64)>>;

impl Folded {
    /// Fold the inputs that every case fixes to one value (`lo = hi`, the same in every
    /// case). A network whose first raw layer is not affine gets an identity map first.
    pub fn new(apps: &Apps, cases: &[Case]) -> Folded {
        let n = apps.n_inputs();
        let fixed: Vec<bool> = (0..n)
            .map(|i| {
                let v = cases.first().map(|c| c.lo[i]);
                cases
                    .iter()
                    .all(|c| c.lo[i] == c.hi[i] && Some(c.lo[i]) == v && c.lo[i].is_finite())
            })
            .collect();
        let base: Vec<f64> = (0..n)
            .map(|i| if fixed[i] { cases[0].lo[i] } else { 0.0 })
            .collect();
        let free: Vec<usize> = (0..n).filter(|i| !fixed[*i]).collect();
        let layers = apps.layers();
        let mut ops = Vec::with_capacity(layers.len());
        let mut rad = Vec::new();
        for (k, l) in layers.into_iter().enumerate() {
            match l {
                Op::Aff(a) if k == 0 => {
                    let p = free.len();
                    let mut w = vec![0.0; a.out * p];
                    let mut b = Vec::with_capacity(a.out);
                    rad = Vec::with_capacity(a.out);
                    for i in 0..a.out {
                        let row = a.dense_row(i);
                        let mut s = a.b[i];
                        let mut mag = s.abs();
                        let mut terms = 1;
                        for (j, &wij) in row.iter().enumerate() {
                            if fixed[j] {
                                let t = wij * base[j];
                                if t != 0.0 {
                                    s += t;
                                    mag += t.abs();
                                    terms += 1;
                                }
                            }
                        }
                        for (t, &j) in free.iter().enumerate() {
                            w[i * p + t] = row[j];
                        }
                        b.push(s);
                        // The exact b + W_fixed x_fixed is within gamma_k * mag of s
                        // (products and sums rounded: k + 1 roundings per term at most).
                        rad.push(if terms > 1 {
                            inflate(gamma(2 * terms) * mag)
                        } else {
                            0.0
                        });
                    }
                    ops.push(Op::Aff(Affine::new(p, a.out, w, b)));
                }
                op => ops.push(op),
            }
        }
        Folded {
            free,
            base,
            ops,
            rad,
        }
    }

    /// Number of free inputs.
    pub fn n_free(&self) -> usize {
        self.free.len()
    }

    /// The original input of the free values `xf`.
    pub fn expand(&self, xf: &[f64]) -> Vec<f64> {
        let mut x = self.base.clone();
        for (t, &i) in self.free.iter().enumerate() {
            x[i] = xf[t];
        }
        x
    }

    /// The free part of an original input.
    pub fn restrict(&self, x: &[f64]) -> Vec<f64> {
        self.free.iter().map(|&i| x[i]).collect()
    }

    /// CROWN's intermediate bounds over the box of the free inputs, intersected with
    /// `parent` (bounds over a box containing this one) when given. `None` when a bound
    /// is not finite (overflow).
    fn bounds(&self, lo: &[f64], hi: &[f64], parent: Option<&Bounds>) -> Option<Pass> {
        let last = self.ops.len() - 1;
        let mut pass = Pass {
            inmag: Vec::with_capacity(self.ops.len()),
            rowmag: Vec::with_capacity(self.ops.len()),
            rel: Vec::with_capacity(self.ops.len()),
            bounds: Vec::with_capacity(last),
        };
        for k in 0..self.ops.len() {
            let inmag: Vec<f64> = if k == 0 {
                crate::symbolic::magnitudes(lo, hi)
            } else {
                pass.bounds[k - 1]
                    .iter()
                    .map(|&(l, u)| l.abs().max(u.abs()))
                    .collect()
            };
            // Per row of an affine op, sum_t |w_it| |input_t| (the pulls' rounding).
            pass.rowmag.push(match &self.ops[k] {
                Op::Aff(a) => (0..a.out)
                    .into_par_iter()
                    .map(|i| a.row(i).abs_dot(&inmag))
                    .collect(),
                Op::Act(_) => Vec::new(),
            });
            pass.inmag.push(inmag);
            let rel = match &self.ops[k] {
                Op::Act(acts) => pass.bounds[k - 1]
                    .par_iter()
                    .enumerate()
                    .map(|(i, &(l, u))| acts.relax(i, l, u))
                    .collect(),
                Op::Aff(_) => Vec::new(),
            };
            pass.rel.push(rel);
            if k == last {
                break;
            }
            let mut b: Vec<(f64, f64)> = match &self.ops[k] {
                Op::Act(acts) => pass.bounds[k - 1]
                    .iter()
                    .enumerate()
                    .map(|(i, &(l, u))| acts.interval(i, l, u))
                    .collect(),
                Op::Aff(a) => {
                    // A neuron followed by a ReLU that the parent's bounds show stable
                    // keeps them (sound here, the piece lying in the parent's box): its
                    // relaxation is exact either way.
                    let next = match self.ops.get(k + 1) {
                        Some(Op::Act(acts)) => Some(acts),
                        _ => None,
                    };
                    let keep = |i: usize| {
                        next.is_some_and(|n| n.at(i) == Some(Activation::Relu))
                            && parent.is_some_and(|p| p[k][i].0 >= 0.0 || p[k][i].1 <= 0.0)
                    };
                    // After a layer of steps (`Sign`) the interval rule alone: a step's
                    // lines are constants where it is stable, which back-substitution
                    // cannot improve on, and across its jump they are no tighter than its
                    // interval (the interval prover decides more on binarised networks,
                    // at a fraction of the cost).
                    let after_steps =
                        k > 0 && matches!(&self.ops[k - 1], Op::Act(acts) if acts.all_steps());
                    let todo: Vec<usize> = if after_steps {
                        Vec::new()
                    } else {
                        (0..a.out).filter(|i| !keep(*i)).collect()
                    };
                    let chunks: Vec<&[usize]> = todo.chunks(PULL_BLOCK).collect();
                    let pass = &pass;
                    let mr = k.checked_sub(1).map(|q| mid_rad(&pass.bounds[q]));
                    let mut b: Vec<(f64, f64)> = match parent {
                        Some(p) => p[k].clone(),
                        None => vec![(f64::NEG_INFINITY, f64::INFINITY); a.out],
                    };
                    let got: Vec<(usize, (f64, f64))> = chunks
                        .into_par_iter()
                        .flat_map_iter(|idx| {
                            let lams: Vec<Vec<f64>> = idx
                                .iter()
                                .flat_map(|&i| {
                                    [1.0, -1.0].map(|s| {
                                        let mut e = vec![0.0; a.out];
                                        e[i] = s;
                                        e
                                    })
                                })
                                .collect();
                            let fs = self.pull_block(pass, k, lams);
                            idx.iter()
                                .enumerate()
                                .map(|(r, &i)| {
                                    let l = fs[2 * r].min_over(lo, hi);
                                    let u = -fs[2 * r + 1].min_over(lo, hi);
                                    let lu = match &mr {
                                        Some((m, r)) => {
                                            let f = forward_interval(a, i, m, r);
                                            (l.max(f.0), u.min(f.1))
                                        }
                                        None => (l, u),
                                    };
                                    (i, lu)
                                })
                                .collect::<Vec<_>>()
                        })
                        .collect();
                    for (i, lu) in got {
                        b[i] = lu;
                    }
                    if let (true, Some((m, r))) = (after_steps, &mr) {
                        for (i, bi) in b.iter_mut().enumerate() {
                            *bi = forward_interval(a, i, m, r);
                        }
                    }
                    b
                }
            };
            if let Some(p) = parent {
                for (x, y) in b.iter_mut().zip(&p[k]) {
                    *x = (x.0.max(y.0), x.1.min(y.1));
                }
            }
            if b.iter().any(|&(l, u)| !l.is_finite() || !u.is_finite()) {
                return None;
            }
            pass.bounds.push(b);
        }
        Some(pass)
    }

    /// A lower bound of `lam . (output of op top)` linear in the free inputs, its slack
    /// covering every rounding (the discipline of [`crate::linset`]) and the fold's
    /// bias radius.
    fn pull(&self, pass: &Pass, top: usize, lam: Vec<f64>) -> Linear {
        self.pull_block(pass, top, vec![lam]).remove(0)
    }

    /// [`Folded::pull`] of several `lam`s at once: each affine row is read once for the
    /// whole block (the pulls of a layer's neurons stream its weights block by block
    /// instead of once per neuron). Every pull's arithmetic is the one of a lone pull.
    fn pull_block(&self, pass: &Pass, top: usize, mut lams: Vec<Vec<f64>>) -> Vec<Linear> {
        let nb = lams.len();
        let mut cst = vec![0.0f64; nb];
        let mut err = vec![0.0f64; nb];
        for j in (0..=top).rev() {
            let inmag = &pass.inmag[j];
            match &self.ops[j] {
                Op::Aff(a) => {
                    let mut nus = vec![vec![0.0; a.inp]; nb];
                    let mut cmag: Vec<f64> = cst.iter().map(|c| c.abs()).collect();
                    // sum_t |input_t| sum_i |lam_i w_it| = sum_i |lam_i| rowmag_i.
                    let mut tmag = vec![0.0; nb];
                    let rowmag = &pass.rowmag[j];
                    for i in 0..a.out {
                        let row = a.row(i);
                        for r in 0..nb {
                            let li = lams[r][i];
                            if li == 0.0 {
                                continue;
                            }
                            let p = li * a.b[i];
                            cst[r] += p;
                            cmag[r] += p.abs();
                            tmag[r] += li.abs() * rowmag[i];
                            if j == 0 && self.rad[i] > 0.0 {
                                err[r] += li.abs() * self.rad[i];
                            }
                            let nu = &mut nus[r];
                            match row {
                                samara_nn::ir::Row::Dense(w) => {
                                    for (n, w) in nu.iter_mut().zip(w) {
                                        *n += li * w;
                                    }
                                }
                                row => row.for_each_nonzero(|t, w| nu[t] += li * w),
                            }
                        }
                    }
                    let g = gamma(a.out + 1);
                    for r in 0..nb {
                        err[r] += g * (cmag[r] + tmag[r]);
                    }
                    lams = nus;
                }
                Op::Act(_) => {
                    let rel = &pass.rel[j];
                    for r in 0..nb {
                        let lam = &mut lams[r];
                        let mut cmag = cst[r].abs();
                        for ((lt, rl), im) in lam.iter_mut().zip(rel).zip(inmag) {
                            let l = *lt;
                            if l == 0.0 {
                                continue;
                            }
                            let (a, b) = if l > 0.0 {
                                (rl.al, rl.bl)
                            } else {
                                (rl.au, rl.bu)
                            };
                            let nl = l * a;
                            if nl != 0.0 {
                                err[r] += f64::EPSILON * nl.abs() * im;
                            }
                            if b != 0.0 {
                                let p = l * b;
                                cst[r] += p;
                                cmag += p.abs();
                            }
                            *lt = nl;
                        }
                        err[r] += gamma(lam.len() + 1) * cmag;
                    }
                }
            }
        }
        lams.into_iter()
            .zip(cst)
            .zip(err)
            .map(|((coef, cst), err)| Linear {
                coef,
                cst,
                slack: inflate(err),
            })
            .collect()
    }

    /// A lower bound of `c . f(x) + d` from interval bounds of the outputs (the last
    /// op's interval rule over the bounds before it: a sigmoid output is at most 1
    /// exactly, which the linear bounds only reach up to their slack), in outward-rounded
    /// interval arithmetic.
    fn interval_lower(&self, pass: &Pass, k: &crate::query::OutputConstraint) -> f64 {
        let last = self.ops.len() - 1;
        let Some(before) = last.checked_sub(1).map(|q| &pass.bounds[q]) else {
            return f64::NEG_INFINITY;
        };
        let out: Vec<(f64, f64)> = match &self.ops[last] {
            Op::Act(acts) => before
                .iter()
                .enumerate()
                .map(|(i, &(l, u))| acts.interval(i, l, u))
                .collect(),
            Op::Aff(a) => {
                let (m, r) = mid_rad(before);
                (0..a.out).map(|i| forward_interval(a, i, &m, &r)).collect()
            }
        };
        let mut acc = Interval::point(k.obj.d);
        for (c, &(l, u)) in k.obj.c.iter().zip(&out) {
            if *c != 0.0 {
                acc += Interval::point(*c) * Interval::new(l, u);
            }
        }
        acc.lo
    }

    /// Lower bounds `L_k(x) <= c_k . f(x) + d_k` of a conjunction's constraints over
    /// the piece, linear in the free inputs.
    fn constraint_bounds(&self, pass: &Pass, cs: &[crate::query::OutputConstraint]) -> Vec<Linear> {
        let top = self.ops.len() - 1;
        cs.iter()
            .map(|k| {
                let mut f = self.pull(pass, top, k.obj.c.clone());
                let c = f.cst + k.obj.d;
                f.slack = inflate(f.slack + gamma(1) * (f.cst.abs() + k.obj.d.abs()));
                f.cst = c;
                f
            })
            .collect()
    }
}

/// The per-piece state of a CROWN pass.
struct Pass {
    /// Per op, bounds of `|input|`.
    inmag: Vec<Vec<f64>>,
    /// Per affine op, per row, `sum_t |w_it|` times the bound of `|input_t|`.
    rowmag: Vec<Vec<f64>>,
    /// Per op, the activation's lines (empty for affine ops).
    rel: Vec<Vec<Relax>>,
    /// Per op but the last, bounds of its output.
    bounds: Bounds,
}

/// A sound range of row `i` of `a` over the box `b` of its input, in midpoint-radius
/// form: the box is enclosed by `m +- r` (`m` the rounded midpoint, `r` rounded up to
/// cover both ends), the row's value is `w . m + b_i +- |w| . r`, and the f64 rounding of
/// both sums is bounded by `gamma_(n+1)` times the sums of the magnitudes of their terms
/// (Higham), inflated and rounded outward. Plain f64 arithmetic, about a tenth of the
/// cost of interval products.
fn forward_interval(a: &Affine, i: usize, mid: &[f64], rad: &[f64]) -> (f64, f64) {
    let mut s = a.b[i];
    let mut mag = s.abs();
    let mut r = 0.0;
    match a.row(i) {
        samara_nn::ir::Row::Dense(w) => {
            for ((w, m), q) in w.iter().zip(mid).zip(rad) {
                let p = w * m;
                s += p;
                mag += p.abs();
                r += w.abs() * q;
            }
        }
        row => row.for_each_nonzero(|j, w| {
            let p = w * mid[j];
            s += p;
            mag += p.abs();
            r += w.abs() * rad[j];
        }),
    }
    let g = gamma(a.inp + 2);
    let e = inflate(g * (mag + r) + r);
    ((s - e).next_down(), (s + e).next_up())
}

/// Midpoints and covering radii of a box ([`forward_interval`]'s form).
fn mid_rad(b: &[(f64, f64)]) -> (Vec<f64>, Vec<f64>) {
    b.iter()
        .map(|&(l, u)| {
            let m = 0.5 * l + 0.5 * u;
            (m, (u - m).next_up().max((m - l).next_up()))
        })
        .unzip()
}

/// Sound lower bounds of every case's constraints over the box `[lo, hi]` of all the
/// network's inputs, from one CROWN pass of the folded network (for tests and callers
/// that check the folding): per case, per constraint, the bound of `c . f(x) + d`.
pub fn constraint_lower_bounds(apps: &Apps, cases: &[Case]) -> Option<Vec<Vec<f64>>> {
    let f = Folded::new(apps, cases);
    cases
        .iter()
        .map(|c| {
            let (lo, hi) = (f.restrict(&c.lo), f.restrict(&c.hi));
            let pass = f.bounds(&lo, &hi, None)?;
            Some(
                f.constraint_bounds(&pass, &c.constraints)
                    .iter()
                    .map(|l| l.min_over(&lo, &hi))
                    .collect(),
            )
        })
        .collect()
}

/// Whether outputs `y` satisfy a conjunction for this engine: beyond rounding
/// ([`satisfies`]), or with every constraint that does not clear its rounding a
/// non-strict one whose value is exactly 0 whatever the rounding: no constant, and its
/// terms cancel in pairs of equal outputs with opposite coefficients (two logits that
/// tie, as a binarised network's integer logits do; `y_l - y_j <= 0` holds there). The
/// caller re-checks every point by its own rules.
pub fn holds(cs: &[crate::query::OutputConstraint], y: &[f64]) -> bool {
    let tie = |k: &crate::query::OutputConstraint| {
        if k.strict || k.obj.d != 0.0 {
            return false;
        }
        let mut ts: Vec<(f64, f64)> = k
            .obj
            .c
            .iter()
            .zip(y)
            .filter(|(c, v)| **c != 0.0 && **v != 0.0)
            .map(|(c, v)| (*v, *c))
            .collect();
        ts.sort_by(|p, q| p.0.total_cmp(&q.0));
        ts.chunk_by(|p, q| p.0 == q.0)
            .all(|g| g.iter().map(|t| t.1).sum::<f64>() == 0.0)
    };
    cs.iter()
        .all(|k| satisfies(std::slice::from_ref(k), y) || tie(k))
}

/// A piece: a box of the free inputs, the cases still open on it, the bounds of its
/// parent.
struct Work {
    lo: Vec<f64>,
    hi: Vec<f64>,
    open: Vec<usize>,
    parent: Option<std::sync::Arc<Bounds>>,
    /// The most negative constraint bound of the parent (smaller: examined first).
    key: f64,
    depth: u32,
}

crate::work::deepest_then_least_key!(Work);

/// What examining a piece gave.
enum Piece {
    Closed,
    Found(usize, Vec<f64>),
    Split(Vec<Work>),
    Stuck,
}

/// Bound, check and split one piece.
fn examine(apps: &Apps, f: &Folded, cases: &[Case], w: Work) -> Piece {
    let Some(pass) = f.bounds(&w.lo, &w.hi, w.parent.as_deref()) else {
        return Piece::Stuck;
    };
    let mut open = Vec::new();
    let mut smear = vec![0.0f64; w.lo.len()];
    let mut worst = f64::INFINITY;
    for &ci in &w.open {
        let cs = &cases[ci].constraints;
        if cs.is_empty() {
            // Holds everywhere: the centre is a point.
            let xf: Vec<f64> = w.lo.iter().zip(&w.hi).map(|(a, b)| 0.5 * (a + b)).collect();
            return Piece::Found(ci, f.expand(&xf));
        }
        let fs = f.constraint_bounds(&pass, cs);
        let mins: Vec<f64> = fs
            .iter()
            .zip(cs)
            .map(|(l, k)| l.min_over(&w.lo, &w.hi).max(f.interval_lower(&pass, k)))
            .collect();
        if cs
            .iter()
            .zip(&mins)
            .any(|(k, m)| *m > 0.0 || (k.strict && *m >= 0.0))
        {
            continue;
        }
        if fs.len() > 1 && combination_certifies(&fs, &w.lo, &w.hi).0 {
            continue;
        }
        // Candidate points: the minimising corner of the weakest bound, the centre.
        let (kw, _) = mins
            .iter()
            .enumerate()
            .fold(
                (0, f64::NEG_INFINITY),
                |a, (k, m)| if *m > a.1 { (k, *m) } else { a },
            );
        let centre: Vec<f64> = w.lo.iter().zip(&w.hi).map(|(a, b)| 0.5 * (a + b)).collect();
        for xf in [fs[kw].argmin_corner(&w.lo, &w.hi), centre] {
            let x = f.expand(&xf);
            let y = apps.eval(&x);
            if holds(cs, &y) {
                return Piece::Found(ci, x);
            }
        }
        worst = worst.min(mins.iter().fold(f64::NEG_INFINITY, |a, b| a.max(*b)));
        for (l, mn) in fs.iter().zip(&mins) {
            if *mn <= 0.0 {
                for (t, s) in smear.iter_mut().enumerate() {
                    *s += l.coef[t].abs() * (w.hi[t] - w.lo[t]);
                }
            }
        }
        open.push(ci);
    }
    if open.is_empty() {
        return Piece::Closed;
    }
    // Split the input of the largest smear that can still be halved.
    let mut best: Option<(usize, f64)> = None;
    for (t, s) in smear.iter().enumerate() {
        let mid = 0.5 * w.lo[t] + 0.5 * w.hi[t];
        if !(mid > w.lo[t] && mid < w.hi[t]) {
            continue;
        }
        let s = if *s > 0.0 {
            *s
        } else {
            1e-300 * (w.hi[t] - w.lo[t])
        };
        if best.is_none_or(|b| s > b.1) {
            best = Some((t, s));
        }
    }
    let Some((t, _)) = best else {
        return Piece::Stuck;
    };
    let mid = 0.5 * w.lo[t] + 0.5 * w.hi[t];
    let parent = Some(std::sync::Arc::new(pass.bounds));
    let mut a = Work {
        lo: w.lo.clone(),
        hi: w.hi.clone(),
        open: open.clone(),
        parent: parent.clone(),
        key: worst,
        depth: w.depth + 1,
    };
    a.hi[t] = mid;
    let mut b = Work {
        lo: w.lo,
        hi: w.hi,
        open,
        parent,
        key: worst,
        depth: w.depth + 1,
    };
    b.lo[t] = mid;
    Piece::Split(vec![a, b])
}

/// The attack on the cases `group` sharing the box `[lo, hi]` of the free inputs
/// ([`crate::attack`]): on every thread, sign-gradient descents ([`crate::attack::Step`],
/// half the box's width at most) from the centre (first round, first worker) and seeded
/// random starts, for `seconds` each; the case and the (original) point when one holds.
#[allow(clippy::too_many_arguments)]
fn attack(
    apps: &Apps,
    f: &Folded,
    cases: &[Case],
    group: &[usize],
    lo: &[f64],
    hi: &[f64],
    s: &Settings,
    round: u64,
    seconds: f64,
    deadline: Option<Instant>,
) -> Option<(usize, Vec<f64>)> {
    use crate::attack::{descend, restarts, start, starts, Step};
    let workers = rayon::current_num_threads().max(1) as u64;
    let conj: Vec<&[crate::query::OutputConstraint]> =
        group.iter().map(|ci| &cases[*ci].constraints[..]).collect();
    let stop = std::sync::atomic::AtomicBool::new(false);
    (0..workers).into_par_iter().find_map_any(|wk| {
        let salt = round * workers + wk;
        let mut rng = starts(s.seed, salt);
        let mut model = Partial {
            apps,
            base: f.base.clone(),
            free: &f.free,
        };
        restarts(usize::MAX, seconds, &stop, deadline, |r| {
            let xf = start(&mut rng, lo, hi, r == 0 && salt == 0);
            let steps = s.steps.min(30);
            descend(
                &mut model,
                &conj,
                lo,
                hi,
                xf,
                steps,
                Step::Sign(0.5),
                deadline,
                holds,
            )
            .map(|(k, xf)| (group[k], f.expand(&xf)))
        })
    })
}

/// Decide the query on `net` (any activations): is there a case with a point? The
/// inputs fixed in every case are folded first ([`Folded`]). `Proved` only when every
/// piece of every case is closed by the sound bounds; a point is returned with the
/// network's f64 outputs there (the caller re-checks it).
pub fn solve(net: &Network, cases: &[Case], s: &Settings) -> (Outcome, Stats) {
    solve_apps(&Apps::one(net), cases, s)
}

/// [`solve`] over several networks side by side ([`Apps`]): the cases' boxes are over
/// all their inputs, their constraints over all their outputs and the carried inputs.
/// A point's `y` is [`Apps::eval`]'s.
pub fn solve_apps(apps: &Apps, cases: &[Case], s: &Settings) -> (Outcome, Stats) {
    let t0 = Instant::now();
    let mut stats = Stats::default();
    let deadline = s.timeout.deadline_from(t0);
    let out_of_time = || s.timeout.expired(t0, Instant::now());
    let found = |ci: usize, x: Vec<f64>| {
        let y = apps.eval(&x);
        Outcome::Violated(CasePoint { case: ci, x, y })
    };
    if cases.is_empty() {
        return (Outcome::Proved, stats);
    }
    let f = Folded::new(apps, cases);
    // Cases over the same box (after folding) share their pieces.
    let groups = crate::search::box_groups(cases);
    let boxes: Vec<(Vec<f64>, Vec<f64>)> = groups
        .iter()
        .map(|g| (f.restrict(&cases[g[0]].lo), f.restrict(&cases[g[0]].hi)))
        .collect();
    for (g, (lo, hi)) in groups.iter().zip(&boxes) {
        if let Some((ci, x)) = attack(apps, &f, cases, g, lo, hi, s, 0, s.attack_seconds, deadline)
        {
            return (found(ci, x), stats);
        }
    }
    let mut heap: std::collections::BinaryHeap<Work> = groups
        .iter()
        .zip(&boxes)
        .map(|(g, (lo, hi))| Work {
            lo: lo.clone(),
            hi: hi.clone(),
            open: g.clone(),
            parent: None,
            key: f64::NEG_INFINITY,
            depth: 0,
        })
        .collect();
    let mut stuck = false;
    let mut last_burst = Instant::now();
    let mut round = 0u64;
    let batch = (2 * rayon::current_num_threads()).max(2);
    while !heap.is_empty() {
        if out_of_time() {
            return (Outcome::Unknown(StopReason::Timeout), stats);
        }
        if s.max_pieces > 0 && stats.pieces >= s.max_pieces {
            return (Outcome::Unknown(StopReason::PieceLimit), stats);
        }
        // Attack bursts, about 10% of the time.
        let interval = (0.25 * t0.elapsed().as_secs_f64()).max(1.0);
        if last_burst.elapsed().as_secs_f64() > interval {
            round += 1;
            for (g, (lo, hi)) in groups.iter().zip(&boxes) {
                let secs = 0.1 * interval / groups.len() as f64;
                if let Some((ci, x)) = attack(apps, &f, cases, g, lo, hi, s, round, secs, deadline)
                {
                    return (found(ci, x), stats);
                }
            }
            last_burst = Instant::now();
        }
        let take = batch.min(heap.len());
        let ws: Vec<Work> = (0..take).filter_map(|_| heap.pop()).collect();
        stats.pieces += ws.len() as u64;
        let res: Vec<Piece> = ws
            .into_par_iter()
            .map(|w| examine(apps, &f, cases, w))
            .collect();
        for r in res {
            match r {
                Piece::Closed => {}
                Piece::Found(ci, x) => return (found(ci, x), stats),
                Piece::Split(ws) => heap.extend(ws),
                Piece::Stuck => stuck = true,
            }
        }
    }
    if std::env::var_os("SAMARA_SEARCH_PROFILE").is_some() {
        eprintln!(
            "smooth search: {} free inputs, {} pieces, {:.2} s",
            f.n_free(),
            stats.pieces,
            t0.elapsed().as_secs_f64()
        );
    }
    if stuck {
        (Outcome::Unknown(StopReason::Unsplittable), stats)
    } else {
        (Outcome::Proved, stats)
    }
}

/// Networks side by side ([`Apps`], one network in most queries) whose inputs `free`
/// vary and the others stay at `base`'s values (the folded inputs of
/// this module): the descent moves the free inputs only. The gradient is
/// [`samara_nn::attack::outputs_and_gradient`]'s (a `Sign` passes the straight-through
/// estimator's 1), per network, plus the weights of the carried inputs.
pub(crate) struct Partial<'a> {
    /// The networks.
    pub apps: &'a Apps<'a>,
    /// Every input, the free ones overwritten at each evaluation.
    pub base: Vec<f64>,
    /// Indices of the free inputs.
    pub free: &'a [usize],
}

impl crate::attack::Model for Partial<'_> {
    fn outputs_and_gradient(
        &mut self,
        xf: &[f64],
        pick: impl FnOnce(&[f64]) -> Option<Vec<f64>>,
    ) -> (Vec<f64>, Option<Vec<f64>>) {
        for (t, &i) in self.free.iter().enumerate() {
            self.base[i] = xf[t];
        }
        if let ([net], true) = (&self.apps.nets[..], self.apps.through.is_empty()) {
            // One pass: the forward's layers serve the backward.
            let mut picked = None;
            let (y, g) = samara_nn::attack::outputs_and_gradient(net, &self.base, |y| {
                picked = pick(y);
                picked.clone().unwrap_or_else(|| vec![0.0; y.len()])
            });
            let g = picked.map(|_| self.free.iter().map(|&i| g[i]).collect());
            return (y, g);
        }
        let y = self.apps.eval(&self.base);
        let Some(c) = pick(&y) else {
            return (y, None);
        };
        let mut g = vec![0.0; self.base.len()];
        let (mut at_in, mut at_out) = (0, 0);
        for net in &self.apps.nets {
            let (ni, no) = (net.n_inputs(), net.n_outputs());
            let cn = &c[at_out..at_out + no];
            if cn.iter().any(|v| *v != 0.0) {
                let x = &self.base[at_in..at_in + ni];
                let (_, gn) = samara_nn::attack::outputs_and_gradient(net, x, |_| cn.to_vec());
                for (a, b) in g[at_in..at_in + ni].iter_mut().zip(gn) {
                    *a += b;
                }
            }
            at_in += ni;
            at_out += no;
        }
        for (j, &i) in self.apps.through.iter().enumerate() {
            g[i] += c[at_out + j];
        }
        (y, Some(self.free.iter().map(|&i| g[i]).collect()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The folded bias with its radius contains the exact `b + W_fixed x_fixed`,
    /// enclosed independently by outward-rounded interval arithmetic, on rows built to
    /// round (cancelling large terms, thirds).
    #[test]
    fn fold_radius_covers_the_exact_bias() {
        let w = vec![
            1e17,
            -1e17,
            3.0,
            0.1, // row 0: cancellation
            1.0 / 3.0,
            2.0 / 3.0,
            1e-3,
            -7.25, // row 1: inexact products
            0.0,
            0.0,
            0.0,
            1.0, // row 2: only the free input
        ];
        let b = vec![1.0, 0.1, -2.0];
        let net = Network {
            input_names: (0..4).map(|i| format!("x{i}")).collect(),
            output_names: (0..3).map(|i| format!("y{i}")).collect(),
            input_norm: None,
            layers: vec![
                Layer::Affine(Affine::new(4, 3, w.clone(), b.clone())),
                Layer::Act(Activation::Sigmoid),
            ],
            output_denorm: None,
        };
        let fixed = [1.0, 1.0 + f64::EPSILON, 0.1];
        let mut lo = fixed.to_vec();
        let mut hi = fixed.to_vec();
        lo.push(-1.0);
        hi.push(1.0);
        let case = Case {
            lo,
            hi,
            constraints: vec![],
        };
        let f = Folded::new(&Apps::one(&net), &[case]);
        assert_eq!(f.free, vec![3]);
        let Op::Aff(a) = &f.ops[0] else {
            panic!("the first op is the folded map")
        };
        assert_eq!((a.inp, a.out), (1, 3));
        // Row 2 has no fixed term: its bias is kept exactly, with no radius.
        assert!(a.b[2] == -2.0 && f.rad[2] == 0.0);
        for i in 0..2 {
            let mut exact = Interval::point(b[i]);
            for (j, x) in fixed.iter().enumerate() {
                exact += Interval::point(w[i * 4 + j]) * Interval::point(*x);
            }
            let (l, u) = (a.b[i] - f.rad[i], a.b[i] + f.rad[i]);
            assert!(
                l <= exact.lo && exact.hi <= u,
                "row {i}: [{l}, {u}] misses [{}, {}]",
                exact.lo,
                exact.hi
            );
            assert_eq!(a.weight(i, 0), w[i * 4 + 3]);
        }
        assert_eq!(f.expand(&[0.5]), vec![1.0, 1.0 + f64::EPSILON, 0.1, 0.5]);
    }
}
