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
//! The neurons left unstable then have their bounds tightened the same way ([`tighten`]):
//! a tree asks whether `z_i < c` has a point for a `c` halfway between the bound and what an
//! attack reaches, and a closed tree moves the bound to `c` (the bound tightening of MILP
//! solvers), so that the later layers, bounded over the narrower ones, become stable.
//!
//! Soundness: each tree is `relusplit`'s (beta-CROWN bounds, rigorous
//! rounding) over bounds of the earlier layers valid on the box, so a closed tree is a
//! proof, and a bound only ever moves to `0` (or `c`) from the side the tree closed. An open tree
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
        let (unstable, sub) = chain_to(maps, pre, k);
        let sub = &sub[..];
        let before = &pre[..k];
        // (neuron, try to prove z > 0 = no point with z < 0)
        let tries: Vec<(usize, Option<bool>)> = unstable
            .par_iter()
            .map(|&i| {
                if deadline.is_some_and(|d| Instant::now() >= d) {
                    return (i, None);
                }
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
        // Most promising first: the bound to move to 0 nearest to it relative to the
        // width; a layer whose last two chunks proved nothing is left (on mnist_fc
        // `256x6` prop_9_0.03 the fourth layer's 256 trees all stayed open).
        let mut todo: Vec<(usize, bool, f64)> = tries
            .iter()
            .filter_map(|&(i, side)| {
                let (l, u) = pre[k][i];
                side.map(|a| (i, a, if a { -l } else { u } / (u - l)))
            })
            .collect();
        todo.sort_by(|a, b| a.2.total_cmp(&b.2));
        let chunk = (4 * rayon::current_num_threads()).max(4);
        let mut results: Vec<(usize, bool, bool, u64)> = Vec::new();
        let mut dry = 0;
        for part in todo.chunks(chunk) {
            let got: Vec<(usize, bool, bool, u64)> = part
                .par_iter()
                .map(|&(i, active, _)| {
                    let (closed, nodes) =
                        prove_sign(sub, before, i, active, lo, hi, node_limit, deadline);
                    (i, active, closed, nodes)
                })
                .collect();
            dry = if got.iter().any(|g| g.2) { 0 } else { dry + 1 };
            results.extend(got);
            if dry >= 2 || deadline.is_some_and(|d| Instant::now() >= d) {
                break;
            }
        }
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

/// The unstable neurons of map `k` in `pre`, and the chain of maps up to `k` with the
/// last one's ReLU dropped, whose outputs are map `k`'s pre-activations `z`.
fn chain_to(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    k: usize,
) -> (Vec<usize>, Vec<(Affine, bool)>) {
    let unstable = (0..pre[k].len())
        .filter(|&i| pre[k][i].0 < 0.0 && pre[k][i].1 > 0.0)
        .collect();
    let mut sub: Vec<(Affine, bool)> = maps[..=k].to_vec();
    sub[k].1 = false;
    (unstable, sub)
}

/// What [`tighten`] did on one ReLU layer: neurons unstable, bounds tried, bounds moved,
/// tree nodes examined.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Tightened {
    /// `(layer, unstable, tried, moved, nodes)`.
    pub layer: (usize, usize, usize, usize, u64),
}

/// Move the bounds of the unstable neurons of ReLU map `k` of `pre` (valid on the box
/// `[lo, hi]`) halfway towards what a projected-gradient attack reaches, each by a tree of
/// at most `node_limit` nodes that proves the new bound (`z >= c` or `z <= c`), the bound
/// tightening of MILP solvers with our own branch and bound: a neuron whose sign the
/// attack sees change (or whose sign [`stabilise`] could not prove) keeps its ReLU
/// unstable, but a narrower `[l, u]` narrows its relaxation (the chord's intercept
/// `-l u / (u - l)`) and every later layer's bounds. The largest gaps first, in parallel
/// chunks; a layer whose last two chunks moved nothing is left, as is everything past
/// `deadline`. A bound only moves to a value a closed tree proved.
pub fn tighten(
    maps: &[(Affine, bool)],
    pre: &mut [Vec<(f64, f64)>],
    lo: &[f64],
    hi: &[f64],
    k: usize,
    node_limit: u64,
    deadline: Option<Instant>,
) -> Tightened {
    if k == 0 || k >= pre.len() || !maps[k].1 || deadline.is_some_and(|d| Instant::now() >= d) {
        return Tightened::default();
    }
    let (unstable, sub) = chain_to(maps, pre, k);
    let sub = &sub[..];
    let before = &pre[..k];
    // (neuron, above, target, gap): each side's target halfway between its bound and
    // the attack's extreme (0 when the attack never crossed it).
    let mut todo: Vec<(usize, bool, f64, f64)> = unstable
        .par_iter()
        .flat_map_iter(|&i| {
            let (l, u) = pre[k][i];
            let min = descend(sub, i, 1.0, lo, hi).min(0.0);
            let max = (-descend(sub, i, -1.0, lo, hi)).max(0.0);
            let gap = u * -l / (u - l);
            [
                (i, true, 0.5 * (l + min), gap),
                (i, false, 0.5 * (u + max), gap),
            ]
        })
        .collect();
    todo.sort_by(|a, b| b.3.total_cmp(&a.3));
    let chunk = (4 * rayon::current_num_threads()).max(4);
    let mut moved: Vec<(usize, bool, f64)> = Vec::new();
    let (mut tried, mut nodes, mut dry) = (0usize, 0u64, 0);
    for part in todo.chunks(chunk) {
        let got: Vec<(usize, bool, f64, bool, u64)> = part
            .par_iter()
            .map(|&(i, above, at, _)| {
                let (closed, n) =
                    prove_bound(sub, before, i, above, at, lo, hi, node_limit, deadline);
                (i, above, at, closed, n)
            })
            .collect();
        tried += got.len();
        dry = if got.iter().any(|g| g.3) { 0 } else { dry + 1 };
        for &(i, above, at, closed, n) in &got {
            nodes += n;
            if closed {
                moved.push((i, above, at));
            }
        }
        if dry >= 2 || deadline.is_some_and(|d| Instant::now() >= d) {
            break;
        }
    }
    for &(i, above, at) in &moved {
        let b = &mut pre[k][i];
        if above {
            b.0 = b.0.max(at);
        } else {
            b.1 = b.1.min(at);
        }
    }
    Tightened {
        layer: (k, unstable.len(), tried, moved.len(), nodes),
    }
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
    prove_bound(sub, before, i, active, 0.0, lo, hi, node_limit, deadline)
}

/// Whether a ReLU-splitting tree over `sub` (whose last map's output `i` is `z`) closes
/// the case `z < at` (`above`: proves `z >= at` on the box) or `z > at` (not `above`:
/// proves `z <= at`) within `node_limit` nodes and `deadline`; with the nodes examined.
#[allow(clippy::too_many_arguments)]
fn prove_bound(
    sub: &[(Affine, bool)],
    before: &[Vec<(f64, f64)>],
    i: usize,
    above: bool,
    at: f64,
    lo: &[f64],
    hi: &[f64],
    node_limit: u64,
    deadline: Option<Instant>,
) -> (bool, u64) {
    let out = sub[sub.len() - 1].0.out;
    let mut c = vec![0.0; out];
    // above: the case z - at < 0 (strictly); closed when z >= at on the box.
    // below: the case at - z < 0; closed when z <= at on the box.
    c[i] = if above { 1.0 } else { -1.0 };
    let d = if above { -at } else { at };
    let cases = [Case {
        lo: lo.to_vec(),
        hi: hi.to_vec(),
        constraints: vec![OutputConstraint {
            obj: Objective { c, d },
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
        // Dense networks only (see [`crate::relusplit::Tree::intercept`]).
        intercept: false,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::symbolic;
    use crate::testnet::{affine_of_2d, pre_activations, random_maps, region_vertices};
    use rand::{Rng, SeedableRng};

    /// The exact minimum and maximum of every pre-activation of maps `1..` over the box
    /// of a 2-input chain, independently of any bound: every activation pattern of the
    /// ReLU maps before the neuron's is enumerated; along a pattern each pre-activation
    /// is an affine function of `x` (composed here in f64), its region the polygon of the
    /// box's points where every earlier neuron has the pattern's sign, and an affine
    /// function's extremes over a polygon are at its vertices, among the pairwise
    /// intersections of the box's edges and the earlier neurons' zero lines. Patterns
    /// whose polygon is empty contribute nothing.
    fn exact_ranges(maps: &[(Affine, bool)], lo: &[f64], hi: &[f64]) -> Vec<Vec<(f64, f64)>> {
        let hidden: Vec<usize> = maps.iter().filter(|m| m.1).map(|m| m.0.out).collect();
        let total: usize = hidden.iter().sum();
        let mut out: Vec<Vec<(f64, f64)>> = maps
            .iter()
            .map(|m| vec![(f64::INFINITY, f64::NEG_INFINITY); m.0.out])
            .collect();
        for pattern in 0u64..(1u64 << total) {
            let bit = |j: usize, t: usize| {
                let off: usize = hidden[..j].iter().sum::<usize>() + t;
                pattern >> off & 1 == 1
            };
            // Affine functions (a0, a1, b) of x along the pattern, and the sign lines.
            let mut cur: Vec<[f64; 3]> = vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
            let mut lines: Vec<([f64; 3], bool)> = Vec::new();
            let mut zs: Vec<Vec<[f64; 3]>> = Vec::new();
            for (j, (m, r)) in maps.iter().enumerate() {
                let mut z = affine_of_2d(m, &cur);
                zs.push(z.clone());
                if *r {
                    for (t, zt) in z.iter_mut().enumerate() {
                        let on = bit(j, t);
                        lines.push((*zt, on));
                        if !on {
                            *zt = [0.0; 3];
                        }
                    }
                }
                cur = z;
            }
            let verts = region_vertices(lo, hi, &lines, 1e-12, 1e-10);
            // A neuron of map k depends only on the pattern of maps before k: the
            // pattern's later bits only cut the region, so every region of the earlier
            // maps' pattern is covered by the union over the later bits.
            for (j, z) in zs.iter().enumerate() {
                for (i, f) in z.iter().enumerate() {
                    for x in &verts {
                        let v = f[0] * x[0] + f[1] * x[1] + f[2];
                        let b = &mut out[j][i];
                        *b = (b.0.min(v), b.1.max(v));
                    }
                }
            }
        }
        out
    }

    /// A random 2-input chain with three ReLU layers (its widths by `trial`), its box, and
    /// CROWN's pre-activation bounds of every map but the last.
    #[allow(clippy::type_complexity)]
    fn draw(
        rng: &mut rand_chacha::ChaCha8Rng,
        trial: usize,
    ) -> (
        Vec<(Affine, bool)>,
        Vec<f64>,
        Vec<f64>,
        Vec<Vec<(f64, f64)>>,
    ) {
        let widths: &[usize] = match trial % 3 {
            0 => &[2, 5, 5, 4, 2],
            1 => &[2, 4, 6, 3, 2],
            _ => &[2, 6, 4, 4, 2],
        };
        let maps = random_maps(rng, widths);
        let lo: Vec<f64> = (0..2).map(|_| rng.gen_range(-1.0..0.0)).collect();
        let hi: Vec<f64> = lo.iter().map(|l| l + rng.gen_range(0.5..2.5)).collect();
        let fwd = symbolic::hidden_pre(&maps, &lo, &hi, None);
        let mut pre = symbolic::crown_pre(&maps, &lo, &hi, Some(&fwd));
        pre.truncate(maps.len() - 1);
        (maps, lo, hi, pre)
    }

    /// Every bound of `pre` contains its neuron's exact range `exact` and the
    /// pre-activations of 10,000 points drawn from the box (which also check the
    /// enumeration: no sample beyond its extremes).
    fn assert_contains(
        rng: &mut rand_chacha::ChaCha8Rng,
        trial: usize,
        maps: &[(Affine, bool)],
        (lo, hi): (&[f64], &[f64]),
        pre: &[Vec<(f64, f64)>],
        exact: &[Vec<(f64, f64)>],
    ) {
        for (k, layer) in pre.iter().enumerate() {
            for (i, &(l, u)) in layer.iter().enumerate() {
                let (emin, emax) = exact[k][i];
                assert!(
                    l <= emin + 1e-9 && emax <= u + 1e-9,
                    "trial {trial}: map {k} neuron {i}: bounds ({l}, {u}), exact ({emin}, {emax})"
                );
            }
        }
        for _ in 0..10_000 {
            let x: Vec<f64> = (0..2).map(|t| rng.gen_range(lo[t]..=hi[t])).collect();
            let z = pre_activations(maps, &x);
            for (k, layer) in pre.iter().enumerate() {
                for (i, &(l, u)) in layer.iter().enumerate() {
                    assert!(
                        l <= z[k][i] && z[k][i] <= u,
                        "trial {trial}: map {k} neuron {i}: {} outside ({l}, {u})",
                        z[k][i]
                    );
                    let (emin, emax) = exact[k][i];
                    assert!(
                        emin - 1e-9 <= z[k][i] && z[k][i] <= emax + 1e-9,
                        "trial {trial}: map {k} neuron {i}: exact range missed {}",
                        z[k][i]
                    );
                }
            }
        }
    }

    /// On random 2-input chains with three ReLU layers, from CROWN's bounds: every
    /// neuron [`stabilise`] proves active has an exact minimum (by [`exact_ranges`]'s
    /// enumeration of the activation patterns) of at least 0, every one it proves
    /// inactive an exact maximum of at most 0, and the refined bounds hold at 10,000
    /// sampled points of the box (as do the exact extremes, a check of the enumeration);
    /// enough neurons are proved to make the check bite (140 of 672 on 2026-11-28).
    #[test]
    fn stabilised_neurons_are_stable_by_exact_enumeration() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(52);
        let (mut proved, mut tried) = (0usize, 0usize);
        for trial in 0..60 {
            let (maps, lo, hi, mut pre) = draw(&mut rng, trial);
            let before = pre.clone();
            let last = pre.len() - 1;
            let r = stabilise(&maps, &mut pre, &lo, &hi, 1..=last, 200, None);
            let exact = exact_ranges(&maps, &lo, &hi);
            for (k, layer) in pre.iter().enumerate() {
                for (i, &(l, u)) in layer.iter().enumerate() {
                    let (l0, u0) = before[k][i];
                    if l0 < 0.0 && u0 > 0.0 {
                        tried += 1;
                        if l >= 0.0 || u <= 0.0 {
                            proved += 1;
                        }
                    }
                }
            }
            assert_contains(&mut rng, trial, &maps, (&lo, &hi), &pre, &exact);
            let counted: usize = r.layers.iter().map(|l| l.3).sum();
            assert!(counted <= tried);
        }
        eprintln!("proved stable {proved} of {tried} unstable neurons");
        assert!(proved >= 10, "only {proved} of {tried} proved stable");
    }

    /// On random 2-input chains with three ReLU layers, from CROWN's bounds: every bound
    /// [`tighten`] moves still contains the neuron's exact range (by [`exact_ranges`]'s
    /// enumeration) and 10,000 sampled points, and enough bounds move to make the check
    /// bite (689 of the 772 tried on 2026-11-28).
    #[test]
    fn tightened_bounds_contain_the_exact_ranges() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(54);
        let (mut moved, mut tried) = (0usize, 0usize);
        for trial in 0..60 {
            let (maps, lo, hi, mut pre) = draw(&mut rng, trial);
            for k in 1..pre.len() {
                let t = tighten(&maps, &mut pre, &lo, &hi, k, 50, None);
                tried += t.layer.2;
                moved += t.layer.3;
            }
            let exact = exact_ranges(&maps, &lo, &hi);
            assert_contains(&mut rng, trial, &maps, (&lo, &hi), &pre, &exact);
        }
        eprintln!("tightened {moved} of {tried} bounds tried");
        assert!(
            moved * 5 >= tried && moved > 20,
            "{moved} of {tried} bounds moved"
        );
    }
}
