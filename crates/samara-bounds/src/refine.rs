//! Refinement of the intermediate bounds of ReLU splitting's root by an exact search per
//! neuron: an unstable neuron `z_i` of an early ReLU layer `k` whose sign a local attack
//! never sees change is handed to a small ReLU-splitting tree of its own, over the chain
//! up to map `k` with `z_i` as the output, asked whether `z_i < 0` (or `z_i > 0`) has a
//! point in the box. A closed tree proves the neuron stable on the whole box, and its
//! bound becomes `0`. This is the intermediate-bound refinement of alpha-beta-CROWN's
//! `bab-refine` (Wang et al., NeurIPS 2021; its mnistfc configuration refines the first
//! layers' bounds by MILP before the branch and bound), with our own branch and bound
//! in place of the MILP solver: the neuron's bound is an optimisation over the earlier
//! layers' phases, decided by splitting them.
//!
//! Soundness: each tree is [`crate::relusplit`]'s (beta-CROWN bounds, rigorous
//! rounding) over bounds of the earlier layers valid on the box, so a closed tree is a
//! proof, and a bound only ever moves to `0` from the side the tree closed. An open tree
//! (node limit, deadline, or a point found) changes nothing. The attack only chooses
//! which neurons are tried.
//!
//! On VNN-COMP 2022 mnist_fc `256x6` prop_3_0.05, alpha-CROWN's root bounds left 79
//! neurons of the second ReLU layer and 51 of the third unstable, of which a
//! projected-gradient attack saw only 52 and 10 take both signs (2026-11-28, i52-m).

use crate::query::{Case, OutputConstraint};
use crate::relusplit::{self, NodeOut};
use crate::symbolic::{Objective, Sparse};
use rayon::prelude::*;
use samara_nn::Affine;
use std::time::Instant;

/// What [`stabilise`] did, per ReLU layer tried: neurons unstable before, those the
/// attack saw take both signs, proved stable, and left open by their trees.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Refined {
    /// `(layer, unstable, both_signs, proved, open)` per layer tried.
    pub layers: Vec<(usize, usize, usize, usize, usize)>,
    /// Tree nodes examined in all.
    pub nodes: u64,
}

/// Try to prove stable, by a tree of at most `node_limit` nodes each, the unstable
/// neurons of ReLU maps `layers` of `pre` (from map 1) (valid on the box `[lo, hi]`) whose sign a
/// projected-gradient attack does not see change (see the module doc); layer by layer,
/// so each layer's trees use the bounds the earlier ones refined. Neurons are tried in
/// parallel; past `deadline` the rest stay. Every change sets a bound to `0`.
pub fn stabilise(
    maps: &[(Affine, bool)],
    pre: &mut [Vec<(f64, f64)>],
    lo: &[f64],
    hi: &[f64],
    layers: std::ops::RangeInclusive<usize>,
    node_limit: u64,
    deadline: Option<Instant>,
) -> Refined {
    let mut out = Refined::default();
    let first = (*layers.start()).max(1);
    let last = (*layers.end()).min(pre.len().saturating_sub(1));
    for k in first..=last {
        if !maps[k].1 || deadline.is_some_and(|d| Instant::now() >= d) {
            continue;
        }
        let unstable: Vec<usize> = (0..pre[k].len())
            .filter(|&i| pre[k][i].0 < 0.0 && pre[k][i].1 > 0.0)
            .collect();
        // The chain up to map k, its last map without its ReLU: z_k is the output.
        let mut sub: Vec<(Affine, bool)> = maps[..=k].to_vec();
        sub[k].1 = false;
        let sub = &sub[..];
        let before = &pre[..k];
        // (neuron, try to prove z > 0 = no point with z < 0)
        let tries: Vec<(usize, Option<bool>)> = unstable
            .par_iter()
            .map(|&i| {
                let min = descend(sub, i, 1.0, lo, hi);
                let max = -descend(sub, i, -1.0, lo, hi);
                let side = match (min < 0.0, max > 0.0) {
                    (true, true) => None,
                    (false, _) => Some(true),
                    (true, false) => Some(false),
                };
                (i, side)
            })
            .collect();
        let both = tries.iter().filter(|t| t.1.is_none()).count();
        let results: Vec<(usize, bool, bool, u64)> = tries
            .par_iter()
            .filter_map(|&(i, side)| side.map(|s| (i, s)))
            .map(|(i, active)| {
                let (closed, nodes) =
                    prove_sign(sub, before, i, active, lo, hi, node_limit, deadline);
                (i, active, closed, nodes)
            })
            .collect();
        let mut proved = 0;
        for &(i, active, closed, nodes) in &results {
            out.nodes += nodes;
            if closed {
                proved += 1;
                let b = &mut pre[k][i];
                if active {
                    b.0 = b.0.max(0.0);
                } else {
                    b.1 = b.1.min(0.0);
                }
            }
        }
        out.layers
            .push((k, unstable.len(), both, proved, results.len() - proved));
    }
    out
}

/// Whether a ReLU-splitting tree over `sub` (whose last map's output `i` is `z`) closes
/// the case `z < 0` (`active`) or `z > 0` (not `active`) within `node_limit` nodes and
/// `deadline`, examined one node at a time; with the nodes examined.
#[allow(clippy::too_many_arguments)]
fn prove_sign(
    sub: &[(Affine, bool)],
    before: &[Vec<(f64, f64)>],
    i: usize,
    active: bool,
    lo: &[f64],
    hi: &[f64],
    node_limit: u64,
    deadline: Option<Instant>,
) -> (bool, u64) {
    let out = sub[sub.len() - 1].0.out;
    let mut c = vec![0.0; out];
    // active: the case z < 0, i.e. z < 0 strictly; closed when z >= 0 on the box.
    // inactive: the case -z < 0; closed when z <= 0 on the box.
    c[i] = if active { 1.0 } else { -1.0 };
    let cases = [Case {
        lo: lo.to_vec(),
        hi: hi.to_vec(),
        constraints: vec![OutputConstraint {
            obj: Objective { c, d: 0.0 },
            strict: true,
        }],
    }];
    let tree = relusplit::Tree {
        maps: sub,
        cases: &cases,
        pre: before,
        lo,
        hi,
        root_iters: 20,
        iters: 10,
        lp_bounds: false,
        deep: None,
        pre_slopes: None,
        lp_depth: None,
        closed_share: std::sync::Mutex::new(0.0),
    };
    let sp = Sparse::of(sub, lo.len());
    let mut heap = std::collections::BinaryHeap::new();
    heap.push(relusplit::root(vec![0]));
    let mut nodes = 0u64;
    while let Some(node) = heap.pop() {
        if nodes >= node_limit {
            return (false, nodes);
        }
        nodes += 1;
        match relusplit::examine(&tree, node, deadline, sp.as_ref()) {
            NodeOut::Closed => {}
            NodeOut::Split(ch) => heap.extend(ch),
            NodeOut::Found(..) | NodeOut::Stuck | NodeOut::Late => return (false, nodes),
        }
    }
    (true, nodes)
}

/// The least `sign * z_i` a sign-gradient descent from the box's centre meets (25
/// steps; `sub`'s last map gives `z`): an attack, only to choose which neurons to try.
fn descend(sub: &[(Affine, bool)], i: usize, sign: f64, lo: &[f64], hi: &[f64]) -> f64 {
    let mut best = f64::INFINITY;
    let mut x: Vec<f64> = lo.iter().zip(hi).map(|(a, b)| 0.5 * (a + b)).collect();
    for it in 0..25 {
        let (v, g) = value_grad(sub, i, &x);
        best = best.min(sign * v);
        let step = 0.5 / (1.0 + it as f64 * 0.2);
        for t in 0..x.len() {
            let w = hi[t] - lo[t];
            x[t] = (x[t] - sign * step * w * g[t].signum()).clamp(lo[t], hi[t]);
        }
    }
    best
}

/// Output `i` of the chain `sub` at `x`, and its gradient in `x` (f64).
fn value_grad(sub: &[(Affine, bool)], i: usize, x: &[f64]) -> (f64, Vec<f64>) {
    let mut a = x.to_vec();
    let mut zs = Vec::with_capacity(sub.len());
    for (m, r) in sub {
        let mut z = vec![0.0; m.out];
        m.apply_f64(&a, &mut z);
        zs.push(z.clone());
        if *r {
            z.iter_mut().for_each(|v| *v = v.max(0.0));
        }
        a = z;
    }
    let k = sub.len() - 1;
    let val = zs[k][i];
    let mut g = vec![0.0; sub[k].0.out];
    g[i] = 1.0;
    for j in (0..=k).rev() {
        let m = &sub[j].0;
        if j < k && sub[j].1 {
            for (gv, z) in g.iter_mut().zip(&zs[j]) {
                if *z <= 0.0 {
                    *gv = 0.0;
                }
            }
        }
        let mut gi = vec![0.0; m.inp];
        for (o, &go) in g.iter().enumerate() {
            if go != 0.0 {
                for (p, v) in gi.iter_mut().enumerate() {
                    *v += go * m.weight(o, p);
                }
            }
        }
        g = gi;
    }
    (val, g)
}
