//! ReLU splitting with beta-CROWN bounds, the search's branch and bound for boxes with
//! many inputs (images), where halving one of hundreds of inputs hardly changes a bound.
//!
//! A node is the search's box with a phase fixed for some unstable ReLUs (`z_t <= 0`,
//! inactive, or `z_t >= 0`, active); it stands for the set `S` of inputs of the box where
//! every fixed phase holds. Its pre-activation bounds are its parent's (the root's valid
//! on the box, so on `S`) with the fixed neurons clamped (`[l, min(u, 0)]` or
//! `[max(l, 0), u]`), so a fixed neuron is passed exactly, and the layers after the
//! newest phase re-bounded by CROWN over them (intersected with the parent's). Each constraint `g(y) <= 0` of an open case is bounded
//! below on `S` by beta-CROWN (Wang et al., NeurIPS 2021): the backward bound with
//! optimised lower-relaxation slopes (alpha-CROWN, Xu et al., ICLR 2021) and a Lagrange
//! multiplier per fixed phase, the term `beta_t * z_t(x)` with the sign that makes it
//! `<= 0` on `S` ([`symbolic::backward_lower_beta`] checks the sign against the clamped
//! bounds, so a wrong multiplier can only be ignored, never unsound). Slopes and
//! multipliers are chosen by projected Adam steps on the bound's f64 value, warm-started
//! from the parent; the bound itself is always the rigorous pull-back with outward
//! rounding. A case is closed on a node when one of its constraints' bounds is positive
//! (non-negative for a strict one); the minimising box corner of each bound is evaluated
//! concretely, and a point is reported only when it satisfies every constraint of its
//! case with a margin ([`crate::search::satisfies`]).
//!
//! The branching neuron is chosen by filtered smart branching (De Palma et al., ICLR
//! 2021) for the case closest to holding: of the [`FSB_CANDIDATES`] unstable neurons with
//! the largest relaxation gap weighted by the bound's sensitivity, `|nu_t| * u (-l) /
//! (u - l)` (BaBSR's intercept score, Bunel et al., JMLR 2020), the one whose worse
//! child has the highest f64 bound with the node's slopes and multipliers and the new
//! phase's multiplier a child starts from (the choice only steers the search; every
//! child is bounded rigorously). On convolutional networks only the neurons the bound
//! passes by their chord (a negative coefficient) are candidates, the best
//! [`FSB_INTERCEPT_CANDIDATES`] of them ([`Tree::intercept`]: on oval21 the others'
//! splits hardly moved a bound). On deep dense networks the first nodes branch in the
//! early layers instead, whose splits tighten the later layers' re-bounds ([`Deep`]).
//! A child's new multiplier starts where its parent's lower relaxation of the neuron
//! was, so its bound starts at its parent's. Nodes go depth first (the frontier stays
//! small), in parallel batches, every pull-back over the sparse rows of the lowered
//! convolutions ([`symbolic::Sparse`], built once per batch). A node with every
//! unstable neuron fixed that is still open cannot be split: the network is affine on
//! its set, and the exact LP of [`crate::exact`] decides it (closed, or a point); only
//! when that LP does not (deadline, rounding) the search reports it as unknown.
//!
//! On boxes with few inputs ([`Tree::lp_bounds`]: networks with one hidden layer, where
//! the root's pre-activation bounds are exact over the box and only the output layer's
//! relaxation is left), each phase is also a linear constraint on the inputs, and the
//! last ReLU layer's neurons that a constraint passes by their chord (a negative
//! pull-back coefficient) are bounded over the node's set by an LP with those
//! constraints ([`crate::phases::tighten_last`], each bound certified by weak duality
//! with outward rounding): the chords tighten, and neurons the set decides become
//! stable (the bound tightening of MILP solvers, here per node). Branching then takes
//! only those chord neurons: a neuron passed by its lower relaxation `max(0, z)` leaves,
//! at the optimal slopes and multipliers (which equal the LP's, Salman et al., NeurIPS
//! 2019), one child's bound at its parent's. On VNN-COMP 2024 safenlp, branching on
//! every neuron left 6 of the 9 hard instances open at 20 s that this closes in 0.4-7
//! CPU seconds each.

use crate::adam::Adam;
use crate::query::{forward, satisfies, Case};
use crate::rules::relu;
use crate::symbolic::{self, Linear, Objective, Sparse};
use rayon::prelude::*;
use samara_nn::Affine;
use std::sync::Arc;
use std::time::Instant;

/// Concrete pre-activation bounds of every map but the last.
type Bounds = Vec<Vec<(f64, f64)>>;

/// The case closest to holding on a node: its bound, the pull-back's ReLU-output
/// coefficients, the case and constraint, and the constraint's slopes and multipliers.
type Driver = (f64, Vec<Vec<f64>>, usize, usize, Arc<Warm>);

/// Slopes and split multipliers of one constraint's bound, the warm start of a child.
#[derive(Clone, Debug)]
pub(crate) struct Warm {
    alpha: Vec<Vec<f64>>,
    beta: Vec<Vec<f64>>,
}

/// One node: the phases fixed, the cases still open, warm starts per (case, constraint).
pub(crate) struct Node {
    splits: Vec<(usize, usize, bool)>,
    open: Vec<usize>,
    warm: Vec<(usize, usize, Arc<Warm>)>,
    /// Pre-activation bounds valid on the parent's set (so on this one).
    pre: Option<Arc<Bounds>>,
    /// The lowest constraint bound of the parent (lower goes first among equal depths).
    key: f64,
    depth: u32,
}

impl Node {
    /// Phases fixed.
    pub(crate) fn depth(&self) -> u32 {
        self.depth
    }
}

// The max-heap pops the deepest node, and of those the lowest key.
crate::work::deepest_then_least_key!(Node);

/// What one node came to.
pub(crate) enum NodeOut {
    /// Every open case is closed on the node (or its set is empty).
    Closed,
    /// A point of the given case.
    Found(usize, Vec<f64>),
    /// The two children left to examine.
    Split(Vec<Node>),
    /// Open with every unstable neuron fixed.
    Stuck,
    /// Past the deadline.
    Late,
}

/// The fixed data of one box's ReLU splitting.
pub(crate) struct Tree<'a> {
    pub(crate) maps: &'a [(Affine, bool)],
    pub(crate) cases: &'a [Case],
    /// Pre-activation bounds of every map but the last, valid on the whole box.
    pub(crate) pre: &'a [Vec<(f64, f64)>],
    pub(crate) lo: &'a [f64],
    pub(crate) hi: &'a [f64],
    /// Optimisation steps of the root node's bounds and of every later node's.
    pub(crate) root_iters: usize,
    pub(crate) iters: usize,
    /// Bound the earliest layer with unstable neurons over each node's set by LP with
    /// the node's phases as constraints ([`crate::phases::tighten`]; in the last ReLU
    /// layer only the neurons passed by their chord, [`crate::phases::tighten_last`]),
    /// and branch only on neurons of the last ReLU layer whose pull-back coefficient is
    /// negative (see [`examine`]). For boxes with few inputs, where the LP is small
    /// (networks with one hidden layer, VNN-COMP 2024 safenlp: 30 inputs).
    pub(crate) lp_bounds: bool,
    /// Branch only on neurons some bound passes by its chord (a negative pull-back
    /// coefficient, BaBSR's intercept score proper, as alpha-beta-CROWN's branching
    /// scores them), comparing [`FSB_INTERCEPT_CANDIDATES`] of them; on every unstable
    /// neuron when there are none. For convolutional networks (those with
    /// [`symbolic::Sparse`] rows). A neuron passed by its lower line `alpha z` scores
    /// exactly its parent's bound under filtered smart branching (see [`split_beta`]),
    /// and on oval21 those splits hardly moved the bound after the node's Adam steps
    /// either: on VNN-COMP 2021 oval21 `cifar_wide_kw` img19 (one thread, 60 s, about
    /// 19 CPU-s each), the first path's bound was -0.025 at depth 20 and nothing below
    /// the first quarter of the tree closed (leaves at depth 49); scoring only chords,
    /// -0.007 to -0.013 at depth 20, leaves at depth 27, and 1.5e-3 of the tree closed in the same
    /// CPU time; at the full 720 s (2 threads, load 6-9) img19 was proved in 5,289 nodes,
    /// 115.7 CPU-s (a timeout before, 429 CPU-s; VeriNet 38 s).
    pub(crate) intercept: bool,
    /// Branch in the early layers first, for deep dense networks ([`Deep`]).
    pub(crate) deep: Option<Deep>,
    /// The slopes of the root's alpha-CROWN intermediate bounds: with them, each node
    /// re-bounds the layers after its newest phase once more, after CROWN
    /// ([`symbolic::rebound_with_slopes`]).
    pub(crate) pre_slopes: Option<&'a symbolic::PreSlopes>,
    /// Nodes with at least this many phases fixed also bound each constraint by the LP
    /// over their phases' rows, and pass its multipliers to their children (see
    /// [`examine`]; deep dense networks, whose nodes' Adam steps stall).
    pub(crate) lp_depth: Option<u32>,
    /// With `SAMARA_SEARCH_PROFILE`: the share of this search's trees closed so far (a
    /// node closed at depth `d` closes `2^-d` of its case's tree), its progress measure.
    pub(crate) closed_share: std::sync::Mutex<f64>,
}

/// Branching for deep dense networks (MNIST's 256x4 and 256x6 of VNN-COMP 2021/2022):
/// splitting a neuron of an early layer fixes a term that every later layer's bounds
/// carry, so the later layers' neurons, re-bounded on the node by CROWN (see
/// [`examine`]), tighten and many become stable (the "indirect effect" of DEEPSPLIT,
/// Henriksen & Lomuscio, IJCAI 2021), which the score from the output bound's
/// pull-back does not see: by that score the search split only the last ReLU layer,
/// the one after which nothing is re-bounded. So nodes with fewer than `depth` phases
/// fixed branch only in the earliest of maps `..layers` that has unstable neurons (by
/// the same scores and filtered smart branching, restricted to it): a split there
/// reaches the most layers (DEEPSPLIT's indirect effect grows with the layers after the
/// neuron). The bounds are unchanged (only the choice of neuron is). On VNN-COMP 2022
/// mnist_fc `256x4` prop_3_0.05, one split of map 0 left 48 of the last layer's 73
/// neurons unstable, and the query was proved in 1.2 CPU-s (it timed out at 300 s
/// before, 2,000+ nodes a minute down to depth 131 and nodes with every unstable neuron
/// fixed still open). On `256x6` prop_9_0.03 the choice among maps 0-2 by the output
/// bound's score split map 2 first, and after seven early splits the bound was still
/// -298, where it started; six splits of map 0 took it to -134..-168 (with the root's
/// slopes at the nodes, [`Tree::pre_slopes`]; 2026-11-28, branch i53-d).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Deep {
    /// Nodes with fewer phases fixed branch early.
    pub(crate) depth: u32,
    /// The early maps: `0..layers`.
    pub(crate) layers: usize,
}

/// The root node of the cases `open` (all over the tree's box).
pub(crate) fn root(open: Vec<usize>) -> Node {
    Node {
        splits: Vec::new(),
        open,
        warm: Vec::new(),
        pre: None,
        key: f64::NEG_INFINITY,
        depth: 0,
    }
}

/// beta-CROWN's bound of one objective on a node with bounds `pre` (clamped by its
/// phases `splits`): slopes and multipliers from `iters` Adam steps on the f64 value
/// (from `warm` when given), the rigorous bound at the best ones found, and the
/// pull-back's ReLU-output coefficients there (for branching).
#[allow(clippy::too_many_arguments)]
fn optimise(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    lo: &[f64],
    hi: &[f64],
    splits: &[(usize, usize, bool)],
    warm: Option<&Warm>,
    iters: usize,
    deadline: Option<Instant>,
    sp: Option<&Sparse>,
) -> (Linear, Warm, Vec<Vec<f64>>) {
    let mut alpha = match warm {
        Some(w) => w.alpha.clone(),
        None => symbolic::default_alpha(maps, pre),
    };
    let mut beta: Vec<Vec<f64>> = match warm {
        Some(w) => w.beta.clone(),
        None => alpha.iter().map(|a| vec![0.0; a.len()]).collect(),
    };
    // Only the fixed phases carry multipliers, each of the sign its phase allows
    // (non-negative for an inactive neuron, non-positive for an active one).
    let mut sign: Vec<Vec<f64>> = alpha.iter().map(|a| vec![0.0; a.len()]).collect();
    for &(j, t, on) in splits {
        sign[j][t] = if on { -1.0 } else { 1.0 };
    }
    for (b, s) in beta.iter_mut().zip(&sign) {
        for (bi, si) in b.iter_mut().zip(s) {
            if *si == 0.0 || *bi * si < 0.0 {
                *bi = 0.0;
            }
        }
    }
    let unstable = |j: usize, t: usize| {
        let (l, u) = pre[j][t];
        l < 0.0 && u > 0.0
    };
    let mut best = symbolic::value_grad(maps, pre, obj, lo, hi, &alpha, Some(&beta), sp);
    let mut best_ab = (alpha.clone(), beta.clone());
    // Step sizes: slopes live in [0, 1]; a multiplier's scale is that of the pull-back's
    // coefficients of its layer.
    let lr_a: Vec<f64> = vec![0.1; alpha.len()];
    let lr_b: Vec<f64> = (0..beta.len())
        .map(|j| {
            let nu = &best.nu[j + 1];
            0.05 * nu.iter().map(|v| v.abs()).sum::<f64>() / nu.len().max(1) as f64
        })
        .collect();
    let mut adam_a = Adam::new(&alpha);
    let mut adam_b = Adam::new(&beta);
    let mut cur = best.alpha.clone();
    let mut cur_b = best.beta.clone();
    for it in 0..iters {
        if deadline.is_some_and(|d| Instant::now() >= d) {
            break;
        }
        adam_a.step(&mut alpha, &cur, it, &lr_a, unstable, |_, _, v| {
            relu::alpha_range(v)
        });
        if !splits.is_empty() {
            adam_b.step(
                &mut beta,
                &cur_b,
                it,
                &lr_b,
                |j, t| sign[j][t] != 0.0,
                |j, t, v| {
                    if v * sign[j][t] > 0.0 {
                        v
                    } else {
                        0.0
                    }
                },
            );
        }
        let vg = symbolic::value_grad(maps, pre, obj, lo, hi, &alpha, Some(&beta), sp);
        cur = vg.alpha.clone();
        cur_b = vg.beta.clone();
        if vg.value > best.value {
            best = vg;
            best_ab = (alpha.clone(), beta.clone());
        }
    }
    let (alpha, beta) = best_ab;
    let f = symbolic::backward_lower_sp(maps, pre, obj, lo, hi, Some(&alpha), Some(&beta), sp);
    (f, Warm { alpha, beta }, best.nu)
}

/// Bound one node: close its cases, look for a point at each bound's minimising corner,
/// or split the best-scored unstable neuron.
pub(crate) fn examine(
    tree: &Tree,
    node: Node,
    deadline: Option<Instant>,
    sp: Option<&Sparse>,
) -> NodeOut {
    let Tree {
        maps,
        cases,
        lo,
        hi,
        ..
    } = *tree;
    if deadline.is_some_and(|d| Instant::now() >= d) {
        return NodeOut::Late;
    }
    let mut pre = match &node.pre {
        Some(p) => p.to_vec(),
        None => tree.pre.to_vec(),
    };
    for &(j, t, on) in &node.splits {
        let b = &mut pre[j][t];
        if on {
            b.0 = b.0.max(0.0);
        } else {
            b.1 = b.1.min(0.0);
        }
        if b.0 > b.1 {
            // The phase contradicts a bound valid on the box: the set is empty.
            return NodeOut::Closed;
        }
    }
    // The newest phase tightens the later layers' bounds: CROWN over the clamped bounds
    // (sound on the node's set), intersected with the inherited ones.
    if let Some(&(j, _, _)) = node.splits.last() {
        if j + 1 < pre.len() {
            pre = symbolic::crown_pre_from_sp(maps, lo, hi, &pre, j + 1, deadline, sp);
            if let Some(slopes) = tree.pre_slopes {
                symbolic::rebound_with_slopes(maps, &mut pre, lo, hi, j + 1, slopes, deadline);
            }
            if pre.iter().flatten().any(|&(l, u)| l > u) {
                return NodeOut::Closed;
            }
        }
    }
    // On few inputs, the phases are linear constraints on a small LP: the earliest layer
    // with unstable neurons is bounded over the node's set `S`, not the box, so its
    // chords tighten and neurons `S` decides become stable (each bound certified by weak
    // duality with outward rounding, see [`crate::phases::tighten`]).
    if tree.lp_bounds && !node.splits.is_empty() {
        let fs = phase_rows(maps, &pre, &node.splits, lo, hi);
        // Only the last ReLU layer's neurons some open constraint passes by its chord
        // (a negative coefficient) gain from tighter bounds: the others are passed by a
        // lower line whose best slope the multipliers find for any bounds.
        let only = chord_neurons(maps, cases, &node.open);
        let empty = match &only {
            Some(o) => {
                crate::phases::tighten_last(maps, &mut pre, &fs, lo, hi, o, deadline).is_none()
            }
            None => crate::phases::tighten(maps, &mut pre, &fs, lo, hi).is_none(),
        };
        if empty {
            return NodeOut::Closed;
        }
    }
    let iters = if node.splits.is_empty() {
        tree.root_iters
    } else {
        tree.iters
    };
    // Deep nodes with few unstable neurons left also bound each constraint by an LP
    // over the phases' rows ([`crate::exact::Rows::minimise_linear`] of the beta-CROWN
    // bound): the best multipliers for the rows, where the node's few Adam steps stall.
    let unstable = pre
        .iter()
        .enumerate()
        .map(|(j, l)| {
            if maps[j].1 {
                l.iter().filter(|b| relu::unstable(b.0, b.1)).count()
            } else {
                0
            }
        })
        .sum::<usize>();
    let mut rows = (tree.lp_depth.is_some_and(|d| node.depth >= d))
        .then(|| crate::exact::Rows::new(maps, &pre, &node.splits, lo, hi));
    let prof = std::env::var_os("SAMARA_SEARCH_PROFILE").is_some();
    let mut still = Vec::new();
    let mut warm = Vec::new();
    // The pull-back's ReLU-output coefficients of each entry of `warm`, for the
    // children's multipliers of the new split.
    let mut nus: Vec<Vec<Vec<f64>>> = Vec::new();
    // The case closest to holding, with its bound's coefficients, constraint and
    // slopes and multipliers.
    let mut driver: Option<Driver> = None;
    for &ci in &node.open {
        let case = &cases[ci];
        let mut closed = false;
        let mut case_lb = f64::NEG_INFINITY;
        let mut case_nu: Option<(Vec<Vec<f64>>, usize, Arc<Warm>)> = None;
        for (k, con) in case.constraints.iter().enumerate() {
            let w = node
                .warm
                .iter()
                .find(|w| w.0 == ci && w.1 == k)
                .map(|w| &*w.2);
            let (f, mut wk, nu) = optimise(
                maps,
                &pre,
                &con.obj,
                lo,
                hi,
                &node.splits,
                w,
                iters,
                deadline,
                sp,
            );
            let mut lb = f.min_over(lo, hi);
            let closes = |lb: f64| if con.strict { lb >= 0.0 } else { lb > 0.0 };
            if !closes(lb) {
                if let Some(rows) = rows.as_mut() {
                    let t0 = Instant::now();
                    let mut point = None;
                    let lb2 = rows.minimise_linear(&f, deadline, |b, x| {
                        if closes(b) {
                            return true;
                        }
                        if satisfies(&case.constraints, &forward(maps, x, None)) {
                            point = Some(x.to_vec());
                            return true;
                        }
                        false
                    });
                    if prof {
                        eprintln!(
                            "lp polish: depth {}, {unstable} unstable, {} rows, {lb:.4e} -> {lb2:.4e} in {:.3} s",
                            node.depth,
                            rows.len(),
                            t0.elapsed().as_secs_f64()
                        );
                    }
                    if let Some(x) = point {
                        return NodeOut::Found(ci, x);
                    }
                    // The LP's multipliers of the split phases join the node's (beta-CROWN
                    // is sound for any multipliers of the phases' signs): when the
                    // rigorous pull-back gains, the children start from them.
                    if let Some(duals) = rows.duals() {
                        let mut beta = wk.beta.clone();
                        for (&(j, t, on), &l) in rows.phases().iter().zip(duals) {
                            if l > 0.0 && l.is_finite() && node.splits.contains(&(j, t, on)) {
                                beta[j][t] += if on { -l } else { l };
                            }
                        }
                        let f3 = symbolic::backward_lower_sp(
                            maps,
                            &pre,
                            &con.obj,
                            lo,
                            hi,
                            Some(&wk.alpha),
                            Some(&beta),
                            sp,
                        );
                        let lb3 = f3.min_over(lo, hi);
                        if prof {
                            eprintln!("lp beta: {lb:.4e} -> {lb3:.4e}");
                        }
                        if lb3 > lb {
                            wk.beta = beta;
                            lb = lb3;
                        }
                    }
                    lb = lb.max(lb2);
                }
            }
            if closes(lb) {
                closed = true;
                break;
            }
            let x = f.argmin_corner(lo, hi);
            if satisfies(&case.constraints, &forward(maps, &x, None)) {
                return NodeOut::Found(ci, x);
            }
            let wk = Arc::new(wk);
            warm.push((ci, k, wk.clone()));
            if lb > case_lb || case_nu.is_none() {
                case_lb = lb;
                case_nu = Some((nu.clone(), k, wk));
            }
            nus.push(nu);
        }
        if closed {
            continue;
        }
        if case.constraints.is_empty() {
            let x: Vec<f64> = lo.iter().zip(hi).map(|(a, b)| 0.5 * (a + b)).collect();
            return NodeOut::Found(ci, x);
        }
        still.push(ci);
        if driver.as_ref().is_none_or(|d| case_lb < d.0) {
            driver = case_nu.map(|(nu, k, wk)| (case_lb, nu, ci, k, wk));
        }
    }
    let Some((key, nu, dci, dk, dwarm)) = driver else {
        return NodeOut::Closed;
    };
    if deadline.is_some_and(|d| Instant::now() >= d) {
        return NodeOut::Late;
    }
    // BaBSR's intercept score over the unstable neurons; the widest one when the
    // pull-back does not see any (every coefficient 0).
    let mut widest: Option<(f64, usize, usize)> = None;
    // In the last ReLU layer, a neuron with a positive coefficient is passed by its
    // lower relaxation `max(0, z)`'s best line; at the optimal slopes and multipliers
    // (the LP's, Salman et al. 2019) splitting it leaves one child's bound at its
    // parent's, so with `lp_bounds` only the negative ones (chords) are scored.
    let last = pre.len().saturating_sub(1);
    // On deep dense networks, the first nodes branch in the earliest ReLU layer of the
    // early ones that has unstable neurons (see [`Deep`]); any unstable neuron there
    // scores above 0.
    let early = tree.deep.filter(|d| node.depth < d.depth).and_then(|d| {
        pre.iter()
            .take(d.layers)
            .enumerate()
            .position(|(j, l)| maps[j].1 && l.iter().any(|b| relu::unstable(b.0, b.1)))
    });
    // With `chords_only` (see [`Tree::intercept`]) a positive coefficient scores 0.
    let signed = |j: usize, t: usize, chords_only: bool| {
        let v = nu[j + 1][t];
        if let Some(k) = early {
            match j == k {
                true => v.abs().max(f64::MIN_POSITIVE),
                false => 0.0,
            }
        } else if (chords_only || tree.lp_bounds && j == last) && v > 0.0 {
            0.0
        } else {
            v.abs()
        }
    };
    // The scored neurons, best first: with [`Tree::intercept`] those passed by their
    // chord, and all of them when there are none.
    let scored = |chords_only: bool| {
        let mut cands: Vec<(f64, usize, usize)> = Vec::new();
        for (j, layer) in pre.iter().enumerate() {
            if !maps[j].1 {
                continue;
            }
            for (t, &(l, u)) in layer.iter().enumerate() {
                if relu::unstable(l, u) {
                    let sc = signed(j, t, chords_only) * relu::gap(l, u);
                    if sc > 0.0 {
                        cands.push((sc, j, t));
                    }
                }
            }
        }
        cands.sort_by(|a, b| b.0.total_cmp(&a.0));
        cands
    };
    let mut cands = scored(tree.intercept);
    if cands.is_empty() && tree.intercept {
        cands = scored(false);
    }
    for (j, layer) in pre.iter().enumerate() {
        if !maps[j].1 {
            continue;
        }
        for (t, &(l, u)) in layer.iter().enumerate() {
            let gap = relu::gap(l, u);
            if relu::unstable(l, u) && widest.is_none_or(|p| gap > p.0) {
                widest = Some((gap, j, t));
            }
        }
    }
    let mut choice = cands.first().copied().or(widest);
    // Filtered smart branching (De Palma et al., ICLR 2021): of the best-scored
    // neurons, the one whose worse child has the highest bound, each child's bound the
    // driving constraint's pull-back with the neuron's phase fixed, from the slopes and
    // multipliers the child will start from (the parent's, and the new phase's of
    // [`split_beta`]). A neuron passed by the parent's lower line then scores exactly
    // the parent's bound (its split alone gains nothing before the multipliers move):
    // on oval21 base img5303 (x0.05) the tree closed 79 nodes instead of 179 when the
    // children's multipliers were scored as 0.
    let fsb = if tree.intercept {
        FSB_INTERCEPT_CANDIDATES
    } else {
        FSB_CANDIDATES
    };
    cands.truncate(fsb);
    if cands.len() > 1 {
        let obj = &cases[dci].constraints[dk].obj;
        let mut scratch = pre.clone();
        let mut beta = dwarm.beta.clone();
        let mut best: Option<(f64, usize, usize)> = None;
        for &(_, j, t) in &cands {
            let (l, u) = pre[j][t];
            let mut worse = f64::INFINITY;
            for on in [false, true] {
                scratch[j][t] = if on { (0.0, u) } else { (l, 0.0) };
                beta[j][t] = split_beta(&dwarm.alpha, &nu, j, t, on);
                let v = symbolic::value_only(
                    maps,
                    &scratch,
                    obj,
                    lo,
                    hi,
                    &dwarm.alpha,
                    Some(&beta),
                    sp,
                );
                worse = worse.min(v);
            }
            scratch[j][t] = (l, u);
            beta[j][t] = dwarm.beta[j][t];
            if best.is_none_or(|b| worse > b.0) {
                best = Some((worse, j, t));
            }
        }
        choice = best.or(choice);
    }
    let Some((_, j, t)) = choice else {
        return exact_node(tree, &pre, &node, &still, deadline);
    };
    let pre = Arc::new(pre);
    let children = [false, true]
        .into_iter()
        .map(|on| {
            let mut splits = node.splits.clone();
            splits.push((j, t, on));
            let warm = warm
                .iter()
                .zip(&nus)
                .filter(|(w, _)| still.contains(&w.0))
                .map(|((ci, k, w), nu)| (*ci, *k, Arc::new(split_warm(w, nu, j, t, on))))
                .collect();
            Node {
                splits,
                open: still.clone(),
                warm,
                pre: Some(pre.clone()),
                key,
                depth: node.depth + 1,
            }
        })
        .collect();
    NodeOut::Split(children)
}

/// Inputs up to which [`exact_node`] solves its LP (MNIST's 784): the dense tableau has
/// about `2 n` columns and `n` rows over `n` inputs, 12 MB at 784 inputs and 100 rows,
/// and 150 MB at a CIFAR image's 3,072, where a node stays stuck (unknown) instead.
pub(crate) const EXACT_LP_INPUTS: usize = 1024;

/// A node with no unstable neuron left and cases `still` open: each decided by the exact
/// LP of [`crate::exact`] (the network is affine on the node's set), else stuck.
fn exact_node(
    tree: &Tree,
    pre: &[Vec<(f64, f64)>],
    node: &Node,
    still: &[usize],
    deadline: Option<Instant>,
) -> NodeOut {
    debug_assert!(crate::exact::all_stable(tree.maps, pre));
    if tree.lo.len() > EXACT_LP_INPUTS {
        return NodeOut::Stuck;
    }
    let t0 = Instant::now();
    let mut open = false;
    let mut outs = Vec::new();
    for &ci in still {
        let e = crate::exact::decide(
            tree.maps,
            pre,
            &node.splits,
            &tree.cases[ci],
            tree.lo,
            tree.hi,
            deadline,
        );
        if std::env::var_os("SAMARA_SEARCH_PROFILE").is_some() {
            outs.push(match &e {
                crate::exact::Exact::Closed => "closed".to_string(),
                crate::exact::Exact::Found(_) => "found".to_string(),
                crate::exact::Exact::Open(lb) => format!("open {lb:.3e}"),
            });
        }
        match e {
            crate::exact::Exact::Closed => {}
            crate::exact::Exact::Found(x) => return NodeOut::Found(ci, x),
            crate::exact::Exact::Open(_) => open = true,
        }
    }
    if std::env::var_os("SAMARA_SEARCH_PROFILE").is_some() {
        eprintln!(
            "exact lp: depth {}, {} phases, {:.3} s: {}",
            node.depth,
            node.splits.len(),
            t0.elapsed().as_secs_f64(),
            outs.join(", ")
        );
    }
    if open {
        NodeOut::Stuck
    } else {
        NodeOut::Closed
    }
}

/// The phases `splits` as linear constraints `f_p(x) <= 0` on the node's set: a linear
/// lower bound (CROWN through the bounds `pre`, valid on the set) of `z_t` for an
/// inactive phase, of `-z_t` for an active one.
fn phase_rows(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    splits: &[(usize, usize, bool)],
    lo: &[f64],
    hi: &[f64],
) -> Vec<Linear> {
    splits
        .iter()
        .map(|&(j, t, on)| {
            let mut c = vec![0.0; maps[j].0.out];
            c[t] = if on { -1.0 } else { 1.0 };
            let obj = Objective { c, d: 0.0 };
            symbolic::backward_lower(&maps[..=j], &pre[..j], &obj, lo, hi)
        })
        .collect()
}

/// Which neurons of the last ReLU layer some constraint of the cases `open` pulls back
/// with a negative coefficient (those its bound passes by their chord); `None` when the
/// chain does not end in an affine map after a ReLU layer.
fn chord_neurons(maps: &[(Affine, bool)], cases: &[Case], open: &[usize]) -> Option<Vec<bool>> {
    let n = maps.len();
    if n < 2 || !maps[n - 2].1 || maps[n - 1].1 {
        return None;
    }
    let m = &maps[n - 1].0;
    let mut neg = vec![false; m.inp];
    for &ci in open {
        for con in &cases[ci].constraints {
            let mut nu = vec![0.0; m.inp];
            for (i, &c) in con.obj.c.iter().enumerate() {
                if c != 0.0 {
                    for (t, w) in m.row(i).nonzeros() {
                        nu[t] += c * w;
                    }
                }
            }
            for (f, v) in neg.iter_mut().zip(&nu) {
                *f |= *v < 0.0;
            }
        }
    }
    Some(neg)
}

/// The warm start of a child that fixes neuron `t` of ReLU map `j` (active when `on`)
/// from its parent's slopes and multipliers `w` and the parent's pull-back coefficients
/// `nu`: the new phase's multiplier is the one that passes the neuron exactly as the
/// parent's lower line did. With coefficient `v = nu[j + 1][t] > 0` on the neuron's
/// output, the parent's pull-back takes `v alpha_t z_t`; the child passes the fixed
/// neuron as `0` (inactive) or `v z_t` (active), and the multiplier `beta_t = v alpha_t
/// >= 0` (inactive) or `-v (1 - alpha_t) <= 0` (active) gives back `v alpha_t z_t`, so
/// the child's optimisation starts from its parent's bound (over the same intermediate
/// bounds; the child's are tighter) instead of below it, as with `beta_t = 0`
/// (beta-CROWN's bound, Wang et al. 2021, is valid for every multiplier of the phase's
/// sign; the choice only sets where the Adam steps begin). With `v <= 0` the parent's
/// chord is above the fixed neuron's pass on `[l, u]` and the multiplier stays 0.
fn split_warm(w: &Warm, nu: &[Vec<f64>], j: usize, t: usize, on: bool) -> Warm {
    let mut w = w.clone();
    if j < w.beta.len() {
        w.beta[j][t] = split_beta(&w.alpha, nu, j, t, on);
    }
    w
}

/// The multiplier of [`split_warm`] for the new phase of neuron `t` of ReLU map `j`.
fn split_beta(alpha: &[Vec<f64>], nu: &[Vec<f64>], j: usize, t: usize, on: bool) -> f64 {
    let v = nu.get(j + 1).and_then(|n| n.get(t)).copied().unwrap_or(0.0);
    let a = alpha.get(j).map_or(0.0, |a| relu::alpha_range(a[t]));
    match (v > 0.0, on) {
        (false, _) => 0.0,
        (true, false) => v * a,
        (true, true) => -v * (1.0 - a),
    }
}

/// How many of the best-scored neurons filtered smart branching compares (each costs
/// two f64 pull-backs, a few percent of a node's bounds on oval21's networks).
const FSB_CANDIDATES: usize = 8;

/// How many of the best-scored neurons filtered smart branching compares with
/// [`Tree::intercept`]. On oval21 `cifar_wide_kw` img19 (one thread, 60 s, about 19
/// CPU-s each), the share of the tree closed past its first quarter was 2.8e-4 with 1
/// (BaBSR alone), 1.5e-3 with 4, 5.8e-4 with 8 and 3.2e-4 with 16 (16, 32 and 64 chose
/// the same neurons along the first path: the extra candidates only cost). On
/// `cifar_base_kw` img4631 (90 s, about 29 CPU-s each) 2 closed 0.219 of the tree, 4
/// 0.190 and 8 0.157, but on img19 2 closed a third of what 4 did (3.8e-4 to 1.2e-3).
const FSB_INTERCEPT_CANDIDATES: usize = 4;

/// Examine a batch of nodes in parallel.
pub(crate) fn examine_batch(
    tree: &Tree,
    batch: Vec<Node>,
    deadline: Option<Instant>,
) -> Vec<NodeOut> {
    let t0 = Instant::now();
    let sp = Sparse::of(tree.maps, tree.lo.len());
    let n = batch.len();
    let depths: Vec<u32> = batch.iter().map(|b| b.depth).collect();
    let out: Vec<NodeOut> = batch
        .into_par_iter()
        .map(|n| examine(tree, n, deadline, sp.as_ref()))
        .collect();
    if std::env::var_os("SAMARA_SEARCH_PROFILE").is_some() {
        let kind = |o: &NodeOut| match o {
            NodeOut::Closed => "closed".to_string(),
            NodeOut::Found(..) => "found".to_string(),
            NodeOut::Split(ch) => format!(
                "d{}:{:.4}@{}",
                ch[0].depth,
                ch[0].key,
                ch[0].splits.last().map_or(0, |s| s.0)
            ),
            NodeOut::Stuck => "stuck".to_string(),
            NodeOut::Late => "late".to_string(),
        };
        let ks: Vec<String> = out.iter().map(kind).collect();
        let ks = ks.join(" ");
        let mut share = tree.closed_share.lock().unwrap_or_else(|e| e.into_inner());
        for (o, d) in out.iter().zip(&depths) {
            if matches!(o, NodeOut::Closed) {
                *share += 0.5f64.powi(*d as i32);
            }
        }
        eprintln!(
            "relu split batch: {n} nodes in {:.3} s: closed share {:.9e}: {ks}",
            t0.elapsed().as_secs_f64(),
            *share
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testnet::{pre_activations, random_maps};
    use rand::{Rng, SeedableRng};

    /// The LP bounds of a node on a network with one hidden layer
    /// ([`crate::phases::tighten_last`] with the phases of [`phase_rows`] as
    /// constraints): on random networks, boxes and phases, every neuron's bounds are
    /// within the box's clamped ones and hold at every one of 10,000 sampled points of
    /// the node's set (the box's points where every phase holds); the node's optimised
    /// bound over them stays below the objective at those points, and the LP tightens
    /// some chord neuron's bounds in most trials.
    #[test]
    fn lp_node_bounds_hold_on_the_nodes_set_and_are_within_the_boxs() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(48);
        let (mut checked, mut tightened, mut chords) = (0usize, 0usize, 0usize);
        for trial in 0..40 {
            let n = 2 + trial % 5;
            let maps = random_maps(&mut rng, &[n, 12, 2]);
            let lo: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..0.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|l| l + rng.gen_range(0.3..1.5)).collect();
            let mut pre = symbolic::hidden_pre(&maps, &lo, &hi, None);
            pre.truncate(1);
            let un: Vec<usize> = (0..12)
                .filter(|&t| relu::unstable(pre[0][t].0, pre[0][t].1))
                .collect();
            if un.len() < 3 {
                continue;
            }
            let k = 1 + trial % 3;
            let splits: Vec<(usize, usize, bool)> = un
                .iter()
                .take(k)
                .map(|&t| (0, t, rng.gen_bool(0.5)))
                .collect();
            let mut clamped = pre.clone();
            for &(j, t, on) in &splits {
                let b = &mut clamped[j][t];
                if on {
                    b.0 = 0.0;
                } else {
                    b.1 = 0.0;
                }
            }
            let obj = Objective {
                c: vec![1.0, -1.0],
                d: rng.gen_range(-1.0..1.0),
            };
            let case = Case {
                lo: lo.clone(),
                hi: hi.clone(),
                constraints: vec![crate::query::OutputConstraint {
                    obj: obj.clone(),
                    strict: false,
                }],
            };
            let only = chord_neurons(&maps, std::slice::from_ref(&case), &[0]).unwrap();
            chords += only.iter().filter(|o| **o).count();
            let mut nb = clamped.clone();
            let fs = phase_rows(&maps, &clamped, &splits, &lo, &hi);
            let empty =
                crate::phases::tighten_last(&maps, &mut nb, &fs, &lo, &hi, &only, None).is_none();
            let points: Vec<Vec<Vec<f64>>> = (0..10_000)
                .map(|_| {
                    let x: Vec<f64> = lo
                        .iter()
                        .zip(&hi)
                        .map(|(a, b)| rng.gen_range(*a..=*b))
                        .collect();
                    let mut z = pre_activations(&maps, &x);
                    z.insert(0, x);
                    z
                })
                .filter(|z| splits.iter().all(|&(j, t, on)| (z[j + 1][t] >= 0.0) == on))
                .collect();
            if empty {
                assert!(
                    points.is_empty(),
                    "trial {trial}: a set with points called empty"
                );
                continue;
            }
            for (t, (&(l, u), &(cl, cu))) in nb[0].iter().zip(&clamped[0]).enumerate() {
                assert!(l >= cl && u <= cu, "trial {trial}: neuron {t} loosened");
                if !only[t] {
                    assert_eq!((l, u), (cl, cu), "trial {trial}: neuron {t} not a chord's");
                }
                tightened += (l > cl || u < cu) as usize;
            }
            let (f, _, _) = optimise(&maps, &nb, &obj, &lo, &hi, &splits, None, 20, None, None);
            let lb = f.min_over(&lo, &hi);
            for z in &points {
                for (t, &(l, u)) in nb[0].iter().enumerate() {
                    assert!(l <= z[1][t] && z[1][t] <= u, "trial {trial}: z_{t} outside");
                }
                let y = &z[2];
                let v = obj.d + y[0] - y[1];
                assert!(lb <= v, "trial {trial}: bound {lb} above {v}");
                checked += 1;
            }
        }
        assert!(checked > 50_000, "{checked}");
        assert!(
            chords > 40 && tightened > 20,
            "{chords} chord neurons, {tightened} tightened"
        );
    }

    /// The children's warm start of a split ([`split_warm`]) starts where the parent
    /// ended: with the parent's slopes and multipliers, the new phase's multiplier and
    /// the parent's intermediate bounds clamped by the phase, the child's f64 value
    /// equals the parent's (within rounding), and its rigorous bound is at least the
    /// parent's rigorous bound (less the rounding slack) where the old start (multiplier
    /// 0) is below it; both bounds stay below the objective at 10,000 sampled points of
    /// the child's set (the box's points where the phase holds), on random networks.
    #[test]
    fn a_childs_warm_start_keeps_its_parents_bound_and_stays_sound() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(47);
        let (mut checked, mut better) = (0, 0);
        for trial in 0..40 {
            let n = 2 + trial % 4;
            let maps = random_maps(&mut rng, &[n, 10, 10, 8, 2]);
            let lo: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..0.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|l| l + rng.gen_range(0.2..1.5)).collect();
            let fwd = symbolic::hidden_pre(&maps, &lo, &hi, None);
            let pre = symbolic::crown_pre(&maps, &lo, &hi, Some(&fwd));
            let obj = Objective {
                c: vec![1.0, -1.0],
                d: rng.gen_range(-1.0..1.0),
            };
            let points: Vec<Vec<f64>> = (0..10_000)
                .map(|_| {
                    lo.iter()
                        .zip(&hi)
                        .map(|(a, b)| rng.gen_range(*a..=*b))
                        .collect()
                })
                .collect();
            let evals: Vec<(Vec<Vec<f64>>, f64)> = points
                .iter()
                .map(|x| {
                    let z = pre_activations(&maps, x);
                    let y = z.last().unwrap();
                    let v = obj.d + obj.c.iter().zip(y).map(|(c, v)| c * v).sum::<f64>();
                    (z, v)
                })
                .collect();
            let (pf, pw, nu) = optimise(&maps, &pre, &obj, &lo, &hi, &[], None, 8, None, None);
            let parent_lb = pf.min_over(&lo, &hi);
            let parent_v =
                symbolic::value_only(&maps, &pre, &obj, &lo, &hi, &pw.alpha, Some(&pw.beta), None);
            for (j, layer) in pre.iter().enumerate().take(maps.len() - 1) {
                for (t, &(l, u)) in layer.iter().enumerate() {
                    if !relu::unstable(l, u) || nu[j + 1][t] <= 0.0 {
                        continue;
                    }
                    for on in [false, true] {
                        let mut cpre = pre.clone();
                        cpre[j][t] = if on { (0.0, u) } else { (l, 0.0) };
                        let splits = [(j, t, on)];
                        let cw = split_warm(&pw, &nu, j, t, on);
                        let v = symbolic::value_only(
                            &maps,
                            &cpre,
                            &obj,
                            &lo,
                            &hi,
                            &cw.alpha,
                            Some(&cw.beta),
                            None,
                        );
                        assert!(
                            (v - parent_v).abs() <= 1e-9 * (1.0 + parent_v.abs()),
                            "trial {trial}: child value {v} parent {parent_v}"
                        );
                        let f = symbolic::backward_lower_sp(
                            &maps,
                            &cpre,
                            &obj,
                            &lo,
                            &hi,
                            Some(&cw.alpha),
                            Some(&cw.beta),
                            None,
                        );
                        let lb = f.min_over(&lo, &hi);
                        assert!(lb >= parent_lb - 1e-9 * (1.0 + parent_lb.abs()));
                        let mut zero = pw.clone();
                        zero.beta[j][t] = 0.0;
                        let old = symbolic::backward_lower_sp(
                            &maps,
                            &cpre,
                            &obj,
                            &lo,
                            &hi,
                            Some(&zero.alpha),
                            Some(&zero.beta),
                            None,
                        )
                        .min_over(&lo, &hi);
                        if lb > old + 1e-9 {
                            better += 1;
                        }
                        // The rigorous child bound (and the optimised one) below every
                        // sampled point of the child's set.
                        let (cf, _, _) = optimise(
                            &maps,
                            &cpre,
                            &obj,
                            &lo,
                            &hi,
                            &splits,
                            Some(&cw),
                            8,
                            None,
                            None,
                        );
                        let clb = cf.min_over(&lo, &hi);
                        for (z, val) in &evals {
                            if (z[j][t] >= 0.0) != on {
                                continue;
                            }
                            assert!(
                                lb <= *val && clb <= *val,
                                "trial {trial}: {lb} {clb} > {val}"
                            );
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert!(checked > 100_000, "{checked}");
        assert!(better > 10, "{better}");
    }

    /// The LP over a node's phase rows ([`crate::exact::Rows::minimise_linear`] of the
    /// node's beta-CROWN bound, as [`examine`] does at [`Tree::lp_depth`]) and the
    /// bound with its multipliers added to the node's (the children's warm start) stay
    /// below the objective at every one of 10,000 sampled points of the node's set, on
    /// random 3-4 input networks with 3 hidden layers and 2-6 phases fixed (those of a
    /// sampled point, so the set has points); and the LP raises the bound in some trials.
    #[test]
    fn lp_polish_and_its_multipliers_stay_below_the_nodes_points() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(52);
        let (mut checked, mut gained, mut beta_gained) = (0usize, 0, 0);
        for trial in 0..60 {
            let n = 3 + trial % 2;
            let maps = random_maps(&mut rng, &[n, 10, 9, 8, 2]);
            let lo: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..0.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|l| l + rng.gen_range(0.5..2.0)).collect();
            let fwd = symbolic::hidden_pre(&maps, &lo, &hi, None);
            let mut pre = symbolic::crown_pre(&maps, &lo, &hi, Some(&fwd));
            pre.truncate(maps.len() - 1);
            let x0: Vec<f64> = (0..n).map(|k| rng.gen_range(lo[k]..=hi[k])).collect();
            let z0 = pre_activations(&maps, &x0);
            let mut splits = Vec::new();
            let k = 2 + trial % 5;
            'fix: for (j, layer) in pre.clone().iter().enumerate() {
                for (t, &(l, u)) in layer.iter().enumerate() {
                    if splits.len() >= k {
                        break 'fix;
                    }
                    if relu::unstable(l, u) && rng.gen_bool(0.5) {
                        let on = z0[j][t] >= 0.0;
                        pre[j][t] = if on { (0.0, u) } else { (l, 0.0) };
                        splits.push((j, t, on));
                    }
                }
            }
            if splits.is_empty() {
                continue;
            }
            let obj = Objective {
                c: vec![1.0, -1.0],
                d: rng.gen_range(-1.0..1.0),
            };
            let (f, w, _) = optimise(&maps, &pre, &obj, &lo, &hi, &splits, None, 10, None, None);
            let lb = f.min_over(&lo, &hi);
            let mut rows = crate::exact::Rows::new(&maps, &pre, &splits, &lo, &hi);
            let lb2 = rows.minimise_linear(&f, None, |_, _| false);
            let mut beta = w.beta.clone();
            if let Some(duals) = rows.duals() {
                for (&(j, t, on), &l) in rows.phases().iter().zip(duals) {
                    if l > 0.0 && splits.contains(&(j, t, on)) {
                        beta[j][t] += if on { -l } else { l };
                    }
                }
            }
            let lb3 = symbolic::backward_lower_sp(
                &maps,
                &pre,
                &obj,
                &lo,
                &hi,
                Some(&w.alpha),
                Some(&beta),
                None,
            )
            .min_over(&lo, &hi);
            gained += (lb2 > lb + 1e-9) as usize;
            beta_gained += (lb3 > lb + 1e-9) as usize;
            for _ in 0..10_000 {
                let x: Vec<f64> = (0..n).map(|k| rng.gen_range(lo[k]..=hi[k])).collect();
                let z = pre_activations(&maps, &x);
                if !splits.iter().all(|&(j, t, on)| (z[j][t] >= 0.0) == on) {
                    continue;
                }
                let y = z.last().unwrap();
                let v = obj.d + y[0] - y[1];
                assert!(lb2 <= v && lb3 <= v, "trial {trial}: {lb2} {lb3} above {v}");
                checked += 1;
            }
        }
        eprintln!("{checked} points, LP gained {gained}, its multipliers {beta_gained}");
        assert!(checked > 50_000, "{checked}");
        assert!(gained > 3, "the LP never gained: {gained}");
    }

    /// The whole ReLU-splitting tree with [`Tree::intercept`] branching (chord neurons
    /// only) and without: on random 3-hidden-layer networks and boxes, a tree that closes
    /// every node has no point among 20,000 sampled ones of the box where the case
    /// holds, a point either reports is in the box and satisfies the case at the
    /// network's f64 output, and the two branchings never disagree (one closed, the
    /// other a point); the trials include both verdicts.
    #[test]
    fn intercept_branching_trees_are_sound_and_agree() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(53);
        let (mut proved, mut found) = (0, 0);
        for trial in 0..40 {
            let n = 2 + trial % 3;
            let maps = random_maps(&mut rng, &[n, 8, 8, 6, 2]);
            let lo: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..0.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|l| l + rng.gen_range(0.3..1.5)).collect();
            let fwd = symbolic::hidden_pre(&maps, &lo, &hi, None);
            let mut pre = symbolic::crown_pre(&maps, &lo, &hi, Some(&fwd));
            pre.truncate(maps.len() - 1);
            let case = two_output_case(&mut rng, &lo, &hi);
            let cases = std::slice::from_ref(&case);
            let mut verdicts = Vec::new();
            for intercept in [false, true] {
                let tree = Tree {
                    maps: &maps,
                    cases,
                    pre: &pre,
                    lo: &lo,
                    hi: &hi,
                    root_iters: 10,
                    iters: 5,
                    lp_bounds: false,
                    intercept,
                    deep: None,
                    pre_slopes: None,
                    lp_depth: None,
                    closed_share: std::sync::Mutex::new(0.0),
                };
                let verdict = walk(&tree, &case, trial, |_, _| {});
                if verdict == Some(true) {
                    no_sampled_point(
                        &mut rng,
                        &maps,
                        &case,
                        &format!("trial {trial} (intercept {intercept})"),
                    );
                }
                verdicts.push(verdict);
            }
            if let [Some(a), Some(b)] = verdicts[..] {
                assert_eq!(a, b, "trial {trial}: the branchings disagree");
            }
            proved += (verdicts[1] == Some(true)) as usize;
            found += (verdicts[1] == Some(false)) as usize;
        }
        eprintln!("{proved} proved, {found} points");
        assert!(proved >= 5 && found >= 5, "{proved} proved, {found} points");
    }

    /// The case `d + y0 - y1 <= 0` over the box `[lo, hi]`, `d` drawn in `[-1.5, 1.5)`.
    fn two_output_case(rng: &mut rand_chacha::ChaCha8Rng, lo: &[f64], hi: &[f64]) -> Case {
        Case {
            lo: lo.to_vec(),
            hi: hi.to_vec(),
            constraints: vec![crate::query::OutputConstraint {
                obj: Objective {
                    c: vec![1.0, -1.0],
                    d: rng.gen_range(-1.5..1.5),
                },
                strict: false,
            }],
        }
    }

    /// A tree of the one case from its root, deepest node first, up to 4,000 nodes:
    /// `Some(true)` when every node closed, `Some(false)` at a point (asserted in the box
    /// and satisfying the case at the network's f64 output), `None` past the node limit
    /// or stuck. `on_split` sees the count of nodes examined and each split's children.
    fn walk(
        tree: &Tree,
        case: &Case,
        trial: usize,
        mut on_split: impl FnMut(usize, &[Node]),
    ) -> Option<bool> {
        let mut heap = std::collections::BinaryHeap::from([root(vec![0])]);
        let mut nodes = 0;
        while let Some(node) = heap.pop() {
            nodes += 1;
            if nodes > 4_000 {
                return None;
            }
            match examine(tree, node, None, None) {
                NodeOut::Closed => {}
                NodeOut::Split(ch) => {
                    on_split(nodes, &ch);
                    heap.extend(ch)
                }
                NodeOut::Found(_, x) => {
                    let y = forward(tree.maps, &x, None);
                    assert!(satisfies(&case.constraints, &y), "trial {trial}");
                    assert!((0..x.len()).all(|k| case.lo[k] <= x[k] && x[k] <= case.hi[k]));
                    return Some(false);
                }
                NodeOut::Stuck | NodeOut::Late => return None,
            }
        }
        Some(true)
    }

    /// No point of 20,000 drawn uniformly in the case's box satisfies it (`d + y0 - y1 >
    /// 0` at each): the check of a closed tree against the network itself.
    fn no_sampled_point(
        rng: &mut rand_chacha::ChaCha8Rng,
        maps: &[(Affine, bool)],
        case: &Case,
        what: &str,
    ) {
        for _ in 0..20_000 {
            let x: Vec<f64> = (0..case.lo.len())
                .map(|k| rng.gen_range(case.lo[k]..=case.hi[k]))
                .collect();
            let y = forward(maps, &x, None);
            let v = case.constraints[0].obj.d + y[0] - y[1];
            assert!(v > 0.0, "{what}: {v} at {x:?}");
        }
    }

    /// Early-layer branching on deep networks ([`Deep`], the earliest early ReLU layer
    /// with unstable neurons first) with each node's later layers re-bounded by the
    /// root's alpha-CROWN slopes too ([`Tree::pre_slopes`]), against the plain tree
    /// (output-bound branching, CROWN re-bounds only): on random 4-hidden-layer networks
    /// and boxes, the root splits a neuron of the earliest ReLU layer with unstable
    /// neurons; a tree that closes every node has no point among 20,000 sampled ones of
    /// the box where the case holds, a point either reports is in the box and satisfies
    /// the case at the network's f64 output, and the two trees never disagree; the
    /// trials include both verdicts.
    #[test]
    fn deep_branching_with_the_roots_slopes_is_sound_and_agrees() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(54);
        let (mut proved, mut found, mut early) = (0, 0, 0);
        for trial in 0..40 {
            let n = 2 + trial % 3;
            let maps = random_maps(&mut rng, &[n, 8, 8, 8, 6, 2]);
            let lo: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..0.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|l| l + rng.gen_range(0.3..1.5)).collect();
            let fwd = symbolic::hidden_pre(&maps, &lo, &hi, None);
            let mut pre = symbolic::crown_pre(&maps, &lo, &hi, Some(&fwd));
            let slopes = symbolic::alpha_pre_with(
                &maps,
                &mut pre,
                &lo,
                &hi,
                8,
                symbolic::Ascent::Normalised,
                true,
                None,
            );
            let case = two_output_case(&mut rng, &lo, &hi);
            let cases = std::slice::from_ref(&case);
            let first = (0..2).find(|&j| pre[j].iter().any(|b| relu::unstable(b.0, b.1)));
            let mut verdicts = Vec::new();
            for deep in [false, true] {
                let tree = Tree {
                    maps: &maps,
                    cases,
                    pre: &pre,
                    lo: &lo,
                    hi: &hi,
                    root_iters: 10,
                    iters: 5,
                    lp_bounds: false,
                    intercept: false,
                    deep: deep.then_some(Deep {
                        depth: 6,
                        layers: 2,
                    }),
                    pre_slopes: deep.then_some(&slopes),
                    lp_depth: None,
                    closed_share: std::sync::Mutex::new(0.0),
                };
                let verdict = walk(&tree, &case, trial, |nodes, ch| {
                    if let (true, 1, Some(f)) = (deep, nodes, first) {
                        assert_eq!(ch[0].splits[0].0, f, "trial {trial}");
                        early += 1;
                    }
                });
                if verdict == Some(true) {
                    no_sampled_point(
                        &mut rng,
                        &maps,
                        &case,
                        &format!("trial {trial} (deep {deep})"),
                    );
                }
                verdicts.push(verdict);
            }
            if let [Some(a), Some(b)] = verdicts[..] {
                assert_eq!(a, b, "trial {trial}: the branchings disagree");
            }
            proved += (verdicts[1] == Some(true)) as usize;
            found += (verdicts[1] == Some(false)) as usize;
        }
        eprintln!("{proved} proved, {found} points, {early} early root splits");
        assert!(
            proved >= 5 && found >= 5 && early >= 5,
            "{proved} proved, {found} points, {early} early root splits"
        );
    }
}
