//! Networks with smooth activations (sigmoid, tanh): a sound interval prover with input
//! splitting. Each box of inputs is pushed through the network in interval arithmetic
//! (each activation's interval rule from `samara_bounds::rules`: sigmoid and tanh are
//! monotone, so their images are the enclosures of the end points' images in
//! outward-rounded `samara_num::Interval` arithmetic); a box whose outputs certainly violate a region
//! constraint holds no counterexample. Boxes are bisected along their widest input until
//! a box's centre, evaluated concretely, is a counterexample (Violated), every box is
//! pruned (Proved), or the budget runs out (Unknown, never Proved).

use crate::net::{affine_bounds, down, up};
use crate::point::Point;
use samara_nn::{Layer, Network};
use samara_num::Timeout;
use samara_spec::normal::{Cmp, Constraint, Var};
use std::time::Instant;

/// Sound interval image of a box through a network (any of the IR's activations).
pub fn interval_eval(net: &Network, lo: &[f64], hi: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let (mut l, mut h) = (lo.to_vec(), hi.to_vec());
    for layer in net.raw_layer_refs() {
        match layer.as_ref() {
            Layer::Affine(a) => {
                let (nl, nh) = affine_bounds(a, &l, &h);
                l = nl;
                h = nh;
            }
            Layer::Act(act) => {
                for i in 0..l.len() {
                    (l[i], h[i]) = samara_bounds::rules::interval(*act, l[i], h[i]);
                }
            }
        }
    }
    (l, h)
}

/// Total order on f64 for the priority queue.
#[derive(PartialEq, Clone, Copy)]
struct OrdF(f64);
impl Eq for OrdF {}
impl PartialOrd for OrdF {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for OrdF {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&o.0)
    }
}

/// A box in the best-first queue: smallest key first, then the most recent.
struct Item {
    key: OrdF,
    id: u64,
    b: Vec<(f64, f64)>,
}
impl PartialEq for Item {
    fn eq(&self, o: &Self) -> bool {
        self.key == o.key && self.id == o.id
    }
}
impl Eq for Item {}
impl PartialOrd for Item {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Item {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        o.key.cmp(&self.key).then(self.id.cmp(&o.id))
    }
}

fn lower_bound(c: &Constraint, bounds: &dyn Fn(Var) -> (f64, f64)) -> f64 {
    let mut lo = c.expr.constant;
    for (v, k) in &c.expr.terms {
        let (a, b) = bounds(*v);
        lo += (k * a).min(k * b);
    }
    lo
}

fn certainly_violated(c: &Constraint, bounds: &dyn Fn(Var) -> (f64, f64)) -> bool {
    let mut lo = c.expr.constant;
    for (v, k) in &c.expr.terms {
        let (a, b) = bounds(*v);
        lo = down(lo + down((k * a).min(k * b)));
    }
    match c.cmp {
        Cmp::Le => lo > 0.0,
        Cmp::Lt => lo >= 0.0,
        Cmp::Eq => {
            let mut hi = c.expr.constant;
            for (v, k) in &c.expr.terms {
                let (a, b) = bounds(*v);
                hi = up(hi + up((k * a).max(k * b)));
            }
            lo > 0.0 || hi < 0.0
        }
    }
}

/// The point with these inputs, its outputs evaluated by the plain f64 evaluator.
fn concrete_point(nets: &[&Network], inputs: Vec<Vec<f64>>) -> Point {
    let outputs = nets
        .iter()
        .zip(&inputs)
        .map(|(net, x)| net.eval_f64(x))
        .collect();
    Point {
        inputs,
        outputs,
        free: vec![],
    }
}

/// Starts of [`attack`] that descend (the centre first).
pub const DESCENTS: usize = 4;
/// Steps of each descent of [`attack`].
pub const STEPS: i32 = 8;
/// Starts of [`attack`] in all (the ones after [`DESCENTS`] evaluate a corner only).
pub const STARTS: usize = 1024;

/// Falsification of a whole disjunction on one network by a sign-gradient descent
/// (iterated FGSM, Goodfellow et al., 2015) on the constraint nearest to holding, with
/// the straight-through gradient through `Sign` ([`samara_nn::attack::outputs_and_gradient`]):
/// for networks whose gradient is zero almost everywhere (binarised layers), where a
/// box's centre and sampling rarely meet the region. Every point is checked on the
/// network's exact f64 outputs; the first that satisfies a disjunct is returned with
/// its index. Descends from the centre and [`DESCENTS`]` - 1` pseudo-random corners
/// ([`STEPS`] steps each), then evaluates further corners, [`STARTS`] starts in all;
/// stops at `timeout` (from `t0`).
pub fn attack(
    net: &Network,
    bx: &[(f64, f64)],
    region: &[Vec<Constraint>],
    timeout: Timeout,
    t0: Instant,
) -> Option<(usize, Point)> {
    let value = |c: &Constraint, x: &[f64], y: &[f64]| {
        c.expr.eval(|v| match v {
            Var::Input { index, .. } => x[index],
            Var::Output { index, .. } => y[index],
            Var::Free(_) => f64::NAN,
        })
    };
    // How far a disjunct is from holding at (x, y): its largest constraint value (a
    // constraint holds at <= 0) and that constraint.
    let nearest = |x: &[f64], y: &[f64]| {
        let mut best: Option<(f64, usize, usize)> = None;
        for (d, conj) in region.iter().enumerate() {
            let worst = conj
                .iter()
                .enumerate()
                .map(|(k, c)| (value(c, x, y), k))
                .fold((f64::NEG_INFINITY, 0), |a, b| if b.0 > a.0 { b } else { a });
            if best.is_none_or(|b| worst.0 < b.0) {
                best = Some((worst.0, d, worst.1));
            }
        }
        best
    };
    if region
        .iter()
        .flatten()
        .any(|c| c.expr.terms.iter().any(|(v, _)| matches!(v, Var::Free(_))))
    {
        return None;
    }
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        // SplitMix64: a fixed sequence of corners, the same on every run.
        seed = seed.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = seed;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    };
    let centre: Vec<f64> = bx.iter().map(|(l, h)| 0.5 * (l + h)).collect();
    for start in 0..STARTS {
        let mut x = if start == 0 {
            centre.clone()
        } else {
            bx.iter()
                .map(|&(l, h)| if next() & 1 == 0 { l } else { h })
                .collect()
        };
        if start >= DESCENTS {
            // A corner, evaluated only (a binarised network's counterexamples are often
            // corners of the box, and a forward pass costs half a descent step).
            if timeout.expired(t0, Instant::now()) {
                return None;
            }
            let p = concrete_point(&[net], vec![x]);
            if let Some(d) = region.iter().position(|conj| p.satisfies(conj)) {
                return Some((d, p));
            }
            continue;
        }
        for k in 0..STEPS {
            if timeout.expired(t0, Instant::now()) {
                return None;
            }
            let mut target = None;
            let (y, mut g) = samara_nn::attack::outputs_and_gradient(net, &x, |y| {
                let mut c = vec![0.0; y.len()];
                if let Some((_, d, k)) = nearest(&x, y) {
                    target = Some((d, k));
                    for (v, a) in &region[d][k].expr.terms {
                        if let Var::Output { index, .. } = v {
                            c[*index] += a;
                        }
                    }
                }
                c
            });
            let (d, ci) = target?;
            // The outputs of the forward pass: the network's own f64 evaluation.
            let p = Point {
                inputs: vec![x.clone()],
                outputs: vec![y],
                free: vec![],
            };
            if p.satisfies(&region[d]) {
                return Some((d, p));
            }
            for (v, a) in &region[d][ci].expr.terms {
                if let Var::Input { index, .. } = v {
                    g[*index] += a;
                }
            }
            // Descend the constraint's value: a step of a shrinking fraction of each
            // input's range against the gradient's sign (the first to a corner).
            let frac = 0.8f64.powi(k);
            for ((xi, gi), &(l, h)) in x.iter_mut().zip(&g).zip(bx) {
                if *gi != 0.0 {
                    *xi = (*xi - frac * (h - l) * gi.signum()).clamp(l, h);
                }
            }
        }
    }
    None
}

/// Outcome of the smooth prover for one conjunction, in the one answer vocabulary:
/// `Proved` (no counterexample in the domain), `Violated` with a concrete
/// counterexample, or `Unknown` when the budget (time or box limit) is exhausted.
pub type SmoothResult = samara_num::Outcome<Point, crate::UnknownReason>;

/// Search one conjunction over the applications' boxes (single free of parameters).
pub fn search(
    nets: &[&Network],
    boxes: &[Vec<(f64, f64)>],
    cs: &[Constraint],
    timeout: Timeout,
    max_boxes: usize,
) -> SmoothResult {
    let t0 = Instant::now();
    // The search space: all applications' inputs, concatenated.
    let dims: Vec<usize> = boxes.iter().map(|b| b.len()).collect();
    // Best-first: the box whose constraints look most satisfiable (smallest worst lower
    // bound) first, so counterexamples are met early; a quick sampling pass goes first.
    let mut heap: std::collections::BinaryHeap<Item> = std::collections::BinaryHeap::new();
    let mut id = 0u64;
    heap.push(Item {
        key: OrdF(f64::NEG_INFINITY),
        id,
        b: boxes.iter().flatten().copied().collect(),
    });
    let split = |flat: &[(f64, f64)]| -> Vec<Vec<(f64, f64)>> {
        let mut out = Vec::new();
        let mut off = 0;
        for d in &dims {
            out.push(flat[off..off + d].to_vec());
            off += d;
        }
        out
    };
    {
        // Falsification by sampling (deterministic low-discrepancy points).
        let flat: Vec<(f64, f64)> = boxes.iter().flatten().copied().collect();
        for i in 0..2000u64 {
            // A wide network takes a good part of a second per evaluation.
            if timeout.expired(t0, Instant::now()) {
                return SmoothResult::Unknown(crate::UnknownReason::Timeout { nodes: 0 });
            }
            let x: Vec<f64> = flat
                .iter()
                .enumerate()
                .map(|(k, (l, h))| {
                    let u = ((i + 1) as f64
                        * (0.5 + (k as f64 + 1.0).sqrt().fract() + 0.1 * k as f64))
                        .fract();
                    l + (h - l) * u
                })
                .collect();
            let per = split(&x.iter().map(|v| (*v, *v)).collect::<Vec<_>>());
            let inputs: Vec<Vec<f64>> = per
                .iter()
                .map(|b| b.iter().map(|p| p.0).collect())
                .collect();
            let p = concrete_point(nets, inputs);
            if p.satisfies(cs) {
                return SmoothResult::Violated(p);
            }
        }
    }
    let mut n = 0usize;
    while let Some(Item { b, .. }) = heap.pop() {
        n += 1;
        if n > max_boxes || timeout.expired(t0, Instant::now()) {
            return SmoothResult::Unknown(if n > max_boxes {
                crate::UnknownReason::NodeLimit { nodes: n - 1 }
            } else {
                crate::UnknownReason::Timeout { nodes: n - 1 }
            });
        }
        let per = split(&b);
        let outs: Vec<(Vec<f64>, Vec<f64>)> = nets
            .iter()
            .zip(&per)
            .map(|(net, bx)| {
                let (l, h): (Vec<f64>, Vec<f64>) = bx.iter().copied().unzip();
                interval_eval(net, &l, &h)
            })
            .collect();
        let bounds = |v: Var| match v {
            Var::Input { app, index } => per[app][index],
            Var::Output { app, index } => (outs[app].0[index], outs[app].1[index]),
            Var::Free(_) => (f64::NEG_INFINITY, f64::INFINITY),
        };
        if cs.iter().any(|c| certainly_violated(c, &bounds)) {
            continue;
        }
        let score = cs
            .iter()
            .map(|c| lower_bound(c, &bounds))
            .fold(f64::NEG_INFINITY, f64::max);
        // Concrete check at the centre.
        let inputs: Vec<Vec<f64>> = per
            .iter()
            .map(|bx| bx.iter().map(|(l, h)| 0.5 * (l + h)).collect())
            .collect();
        let p = concrete_point(nets, inputs);
        if p.satisfies(cs) {
            return SmoothResult::Violated(p);
        }
        // Bisect the widest input (relative to nothing: inputs share units per network).
        let (k, w) = b
            .iter()
            .enumerate()
            .map(|(k, (l, h))| (k, h - l))
            .fold((0, -1.0), |a, c| if c.1 > a.1 { c } else { a });
        if w <= 0.0 {
            continue;
        }
        let mid = 0.5 * (b[k].0 + b[k].1);
        let mut left = b.clone();
        left[k].1 = mid;
        let mut right = b;
        right[k].0 = mid;
        id += 2;
        heap.push(Item {
            key: OrdF(score),
            id,
            b: left,
        });
        heap.push(Item {
            key: OrdF(score),
            id: id + 1,
            b: right,
        });
    }
    SmoothResult::Proved
}
