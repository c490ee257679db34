//! ReLU-phase splitting inside one input piece, for the pieces of the input search
//! ([`crate::search`]) that only a few ReLUs cross.
//!
//! A node is the piece's box together with a phase for some of its unstable ReLUs
//! (`z_i >= 0`, active, or `z_i <= 0`, inactive); it stands for the set `S` of inputs of
//! the box where every fixed phase holds. Its pre-activation bounds are full CROWN
//! (Zhang et al., NeurIPS 2018) with the fixed neurons clamped (`[max(l, 0), u]` or
//! `[l, min(u, 0)]`): valid on `S`, and the later layers tighten since a fixed neuron
//! is passed exactly. Each fixed phase is itself a linear constraint on the inputs: its
//! CROWN lower bound (of `z_i` for an inactive one, of `-z_i` for an active one, through
//! the earlier layers' bounds) must be `<= 0` on `S`. A case of the query is closed on
//! the node when no input satisfies, at once, its output constraints' linear lower
//! bounds and the phases' ones: one of them is positive over the box, or a non-negative
//! combination is (the min-max LP of [`crate::lp`], its weights certified with outward
//! rounding by [`crate::symbolic::Linear::combine`]). The argument only evaluates the
//! bounds at a hypothetical point of `S`, where all of them are valid, so bounds that
//! were computed under the node's own phases are sound for it. The weights on the
//! phase constraints play the role of beta-CROWN's split multipliers (Wang et al.,
//! NeurIPS 2021), chosen here by an LP over the final linear bounds instead of by
//! gradient ascent through the pull-back.
//!
//! With every unstable ReLU fixed, the network is affine on `S` and the bounds are exact
//! up to their rounding slack: the LP is then the exact feasibility check of the linear
//! region (the star-set step of nnenum, Bak et al., CAV 2020), so the splitting decides
//! the piece unless a point sits within rounding distance of a constraint. Before that,
//! the earliest layer with unstable neurons is already affine on `S`: its neurons are
//! bounded over `S` (not the box) by an LP with the phases as constraints
//! ([`crate::lp::min_linear_duals`]), the bound certified by weak duality with outward
//! rounding, so neurons that `S` decides become stable. Nodes are split in the earliest
//! layer with unstable neurons (layer order, as nnenum does), at its most balanced
//! neuron (largest `min(-l, u)`), depth first, within a node budget; a node that can
//! neither be closed nor split (or an exhausted budget) hands the piece back to input
//! splitting. Candidate points (each node's LP
//! minimiser) are only reported after a concrete f64 evaluation with a margin
//! ([`crate::search::satisfies`]).
//!
//! Cost per node: on `S` the layers before the earliest unstable one are affine, so
//! every pull-back of a node runs on a shorter chain whose first map is their
//! composition (`Chain`; its f64 rounding error is bounded and carried in the
//! pull-backs' slack), extended from the parent's; the cases are checked once before the
//! later layers are re-bounded, which a node they close skips; the two children of a node
//! run in parallel (`rayon::join`).

use crate::query::{combination_certifies, forward, satisfies, Case};
use crate::symbolic::{self, Linear, Objective};
use samara_nn::Affine;
use samara_num::round::{gamma, inflate};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// What the phase splitting of one piece came to.
pub(crate) enum PhaseResult {
    /// Every open case is closed on the piece.
    Closed,
    /// A point of the given case.
    Found(usize, Vec<f64>),
    /// Undecided (budget spent, or a fully split node neither closed nor refuted).
    GaveUp,
    /// No point found and no case left open except on fully split nodes whose region is
    /// thin: the network is affine there and the exact min-max LP of the case's
    /// constraints (and the phases) is within rounding of 0, so any point of it satisfies
    /// the constraints only at the rounding level (Y_0 = relu(s), Y_1 = relu(-s) with
    /// `Y_0 > 0` and `Y_1 > 0`: the region's closure is the set `s = 0`). Splitting the
    /// inputs further cannot decide it; the search reports `thin_region` at once.
    Thin,
}

/// Whether the min-max LP value `value` of the linear functions `fs` over `[lo, hi]` is
/// within rounding of 0 from below (or above it): below `1e-9` times the size of the
/// terms summed in them.
fn thin_value(value: f64, fs: &[Linear], lo: &[f64], hi: &[f64]) -> bool {
    let scale = fs
        .iter()
        .map(|f| {
            f.cst.abs()
                + f.slack.abs()
                + f.coef
                    .iter()
                    .zip(lo.iter().zip(hi))
                    .map(|(c, (a, b))| c.abs() * a.abs().max(b.abs()))
                    .sum::<f64>()
        })
        .fold(0.0, f64::max);
    value >= -1e-9 * scale
}

/// The unstable ReLUs of a piece (`l < 0 < u`), as `(map, neuron)`, in layer order.
pub(crate) fn unstable(maps: &[(Affine, bool)], pre: &[Vec<(f64, f64)>]) -> Vec<(usize, usize)> {
    let mut v = Vec::new();
    for (j, b) in pre.iter().enumerate() {
        if !maps[j].1 {
            continue;
        }
        for (i, &(l, u)) in b.iter().enumerate() {
            if l < 0.0 && u > 0.0 {
                v.push((j, i));
            }
        }
    }
    v
}

/// One fixed phase: map, neuron, active.
type Fix = (usize, usize, bool);

/// What the nodes of one piece's phase tree share while they run in parallel.
struct Tree<'a> {
    maps: &'a [(Affine, bool)],
    cases: &'a [Case],
    lo: &'a [f64],
    hi: &'a [f64],
    /// Row magnitudes ([`symbolic::row_magnitudes`]) of the piece's bounds, for the
    /// rounding bounds of every node's pull-backs: a node's bounds lie inside the
    /// piece's, so magnitudes from the piece's bound its inputs from above (sound, and
    /// computed once instead of once per node).
    rows: Vec<Vec<f64>>,
    budget: usize,
    deadline: Option<Instant>,
    /// Nodes examined so far.
    seen: AtomicU64,
    /// Set once a point is found or the tree gives up: the other nodes return at once.
    stop: AtomicBool,
    gave_up: AtomicBool,
    /// Some fully split node was left open with a thin region.
    thin: AtomicBool,
    found: Mutex<Option<(usize, Vec<f64>)>>,
}

impl<'a> Tree<'a> {
    fn new(
        maps: &'a [(Affine, bool)],
        cases: &'a [Case],
        pre: &[Vec<(f64, f64)>],
        lo: &'a [f64],
        hi: &'a [f64],
        budget: usize,
        deadline: Option<Instant>,
    ) -> Self {
        Tree {
            maps,
            cases,
            lo,
            hi,
            rows: symbolic::row_magnitudes(maps, pre, lo, hi),
            budget,
            deadline,
            seen: AtomicU64::new(0),
            stop: AtomicBool::new(false),
            gave_up: AtomicBool::new(false),
            thin: AtomicBool::new(false),
            found: Mutex::new(None),
        }
    }

    /// The chain of the piece itself, from map 0 (every node's starts there or later).
    fn root_chain(&self) -> Arc<Chain> {
        Arc::new(Chain {
            maps: self.maps.to_vec(),
            rows: self.rows.clone(),
            at: 0,
            prefix: Prefix::root(self.maps),
        })
    }

    fn give_up(&self) {
        self.gave_up.store(true, Ordering::Relaxed);
        self.stop.store(true, Ordering::Relaxed);
    }

    fn found(&self, ci: usize, x: Vec<f64>) {
        let mut f = self.found.lock().unwrap_or_else(|e| e.into_inner());
        f.get_or_insert((ci, x));
        self.stop.store(true, Ordering::Relaxed);
    }

    /// Case `ci`'s bounds on a node's set `S` (its chain `ch`, bounds `nb` and phase constraints
    /// `phase_fs`, all valid on `S`): `None` when they show that the case has no point
    /// on `S` (one constraint's lower bound is positive, or a certified non-negative
    /// combination with the phases is), else the linear lower bounds (the phases'
    /// first) and the min-max LP's answer, if it ran.
    fn case_open(
        &self,
        ch: &Chain,
        nb: &[Vec<(f64, f64)>],
        phase_fs: &[Linear],
        ci: usize,
    ) -> Option<(Vec<Linear>, Option<crate::lp::MinMax>)> {
        let (lo, hi) = (self.lo, self.hi);
        let mut fs = phase_fs.to_vec();
        for k in &self.cases[ci].constraints {
            let f = symbolic::backward_lower_rows(&ch.maps, &nb[ch.at..], &k.obj, &ch.rows);
            let lb = f.min_over(lo, hi);
            if if k.strict { lb >= 0.0 } else { lb > 0.0 } {
                return None;
            }
            fs.push(f);
        }
        let (ok, mm) = if fs.len() >= 2 {
            combination_certifies(&fs, lo, hi)
        } else {
            (false, None)
        };
        (!ok).then_some((fs, mm))
    }
}

/// A node's network on its set `S` from hidden layer `at` on, as a shorter chain: maps
/// `0..=at` composed into one affine map of the inputs (exact on `S`, where every
/// neuron of the layers before `at` is stable or fixed), then maps `at + 1..`; with the
/// row magnitudes of its pull-backs: the composed map's raised by its rounding error
/// ([`symbolic::rows_with_error`]), the later maps' the tree's. Bounds of the chain are
/// the node's from layer `at` on. A pull-back through it crosses one map of the inputs'
/// width instead of `at + 1` layers.
struct Chain {
    maps: Vec<(Affine, bool)>,
    rows: Vec<Vec<f64>>,
    at: usize,
    /// The composition behind the first map, for the children to extend.
    prefix: Prefix,
}

/// Maps `0..=at` composed into one affine map of the inputs, `z_at = A x + c` up to an
/// absolute error `e` per output, on a set where every neuron of the layers before `at`
/// is stable or fixed (see [`Chain`]): `cols[t]` is column `t` of `A`, `cols[n]` is `c`.
/// A node's children extend their parent's (their stable neurons are the parent's and
/// more), so each layer is composed once per path.
#[derive(Clone)]
struct Prefix {
    cols: Vec<Vec<f64>>,
    e: Vec<f64>,
    at: usize,
}

impl Prefix {
    /// Map 0 alone (exact).
    fn root(maps: &[(Affine, bool)]) -> Prefix {
        let m = &maps[0].0;
        let mut cols: Vec<Vec<f64>> = (0..m.inp)
            .map(|t| (0..m.out).map(|i| m.weight(i, t)).collect())
            .collect();
        cols.push(m.b.clone());
        Prefix {
            cols,
            e: vec![0.0; m.out],
            at: 0,
        }
    }

    /// The prefix composed on to map `to` through the phases of bounds `nb` (layers
    /// `self.at..to` stable or fixed in `nb`): per layer `A' = W D A`, `c' = W D c + b`
    /// (`D` the 0/1 phases), in f64, with the error bound
    /// `e' = |W| D e + gamma(inp + 1) (|W| D m + |b|)`, `m = |A| xmax + |c|` (the sums'
    /// rounding, Higham's bound, plus the earlier error carried through), raised by
    /// [`inflate`] for its own rounding.
    fn extend(
        mut self,
        maps: &[(Affine, bool)],
        nb: &[Vec<(f64, f64)>],
        xmax: &[f64],
        to: usize,
    ) -> Prefix {
        let n = xmax.len();
        for j in self.at + 1..=to {
            let m = &maps[j].0;
            let relu = maps[j - 1].1;
            // An inactive neuron passes 0; every other neuron of these layers is active.
            let on: Vec<f64> = (0..m.inp)
                .map(|s| {
                    if relu && nb[j - 1][s].1 <= 0.0 {
                        0.0
                    } else {
                        1.0
                    }
                })
                .collect();
            let mut mag: Vec<f64> = self.cols[n].iter().map(|v| v.abs()).collect();
            for (col, x) in self.cols[..n].iter().zip(xmax) {
                for (mg, v) in mag.iter_mut().zip(col) {
                    *mg += v.abs() * x;
                }
            }
            let masked: Vec<Vec<f64>> = self
                .cols
                .iter()
                .map(|col| col.iter().zip(&on).map(|(v, d)| v * d).collect())
                .collect();
            let me: Vec<f64> = self.e.iter().zip(&on).map(|(v, d)| v * d).collect();
            let mm: Vec<f64> = mag.iter().zip(&on).map(|(v, d)| v * d).collect();
            let g = gamma(m.inp + 1);
            let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
            let absdot =
                |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x.abs() * y).sum::<f64>();
            let mut cols = vec![vec![0.0; m.out]; n + 1];
            let mut e = vec![0.0; m.out];
            for i in 0..m.out {
                let row = m.dense_row(i);
                let row = &row[..];
                for (col, v) in cols.iter_mut().zip(&masked) {
                    col[i] = dot(row, v);
                }
                cols[n][i] += m.b[i];
                e[i] = inflate(absdot(row, &me) + g * (absdot(row, &mm) + m.b[i].abs()));
            }
            self = Prefix { cols, e, at: j };
        }
        self
    }
}

/// The [`Chain`] of a node with bounds `nb` from its earliest layer with a neuron not
/// shown stable (the last hidden layer when there is none): `parent` itself when it
/// starts there, else `parent`'s prefix extended (composed through layers that are
/// stable in `nb` too).
fn chain(t: &Tree, nb: &[Vec<(f64, f64)>], parent: &Arc<Chain>) -> Arc<Chain> {
    let (maps, lo, hi) = (t.maps, t.lo, t.hi);
    // The earliest layer with a neuron not shown stable (unstable, or a NaN bound).
    let last = maps.len() - 2;
    let at = (0..last)
        .find(|&j| maps[j].1 && nb[j].iter().any(|&(l, u)| !(u <= 0.0 || l >= 0.0)))
        .unwrap_or(last);
    if at == parent.at {
        return parent.clone();
    }
    let prefix = &parent.prefix;
    let n = lo.len();
    let xmax: Vec<f64> = lo
        .iter()
        .zip(hi)
        .map(|(a, b)| a.abs().max(b.abs()))
        .collect();
    let start = if prefix.at <= at {
        prefix.clone()
    } else {
        Prefix::root(maps)
    };
    let p = start.extend(maps, nb, &xmax, at);
    let out = maps[at].0.out;
    let mut w = vec![0.0; out * n];
    for (t, col) in p.cols[..n].iter().enumerate() {
        for (i, v) in col.iter().enumerate() {
            w[i * n + t] = *v;
        }
    }
    let first = Affine::new(n, out, w, p.cols[n].clone());
    let mut rows = vec![symbolic::rows_with_error(&first, lo, hi, &p.e)];
    rows.extend(t.rows[at + 1..].iter().cloned());
    let mut cm = vec![(first, maps[at].1)];
    cm.extend(maps[at + 1..].iter().cloned());
    Arc::new(Chain {
        maps: cm,
        rows,
        at,
        prefix: p,
    })
}

/// Decide the open cases `open` on the piece `[lo, hi]` (pre-activation bounds `pre`,
/// valid on the whole piece) by splitting its unstable ReLUs, examining at most
/// `budget` nodes and stopping at `deadline`. See the module doc. The two children of a
/// node run as a `rayon::join`, so an idle core takes over half of a large tree (the
/// search's batch of pieces otherwise waits for its largest tree on one core); which
/// point is reported, when there are several, may depend on the schedule, the verdict
/// does not (a budget spent in a different order only hands the piece back to input
/// splitting).
#[allow(clippy::too_many_arguments)]
pub(crate) fn split_phases(
    maps: &[(Affine, bool)],
    cases: &[Case],
    open: &[usize],
    pre: &[Vec<(f64, f64)>],
    lo: &[f64],
    hi: &[f64],
    budget: usize,
    deadline: Option<Instant>,
    nodes: &mut u64,
) -> PhaseResult {
    let Some(&(j0, i0)) = unstable(maps, pre).first() else {
        return PhaseResult::GaveUp;
    };
    let t = Tree::new(maps, cases, pre, lo, hi, budget, deadline);
    let root = t.root_chain();
    rayon::join(
        || node(&t, (j0, i0, true), open, pre, &[], &root),
        || node(&t, (j0, i0, false), open, pre, &[], &root),
    );
    *nodes += t.seen.load(Ordering::Relaxed);
    if let Some((ci, x)) = t.found.into_inner().unwrap_or_else(|e| e.into_inner()) {
        PhaseResult::Found(ci, x)
    } else if t.gave_up.load(Ordering::Relaxed) {
        PhaseResult::GaveUp
    } else if t.thin.load(Ordering::Relaxed) {
        PhaseResult::Thin
    } else {
        PhaseResult::Closed
    }
}

/// One node of [`split_phases`]: the parent's set with the phase `fix` added, the cases
/// `open` still open on the parent, the parent's bounds and phase constraints (valid on
/// its set, so on this one). Records a point, a give-up or a thin leaf in `t`; returns
/// when the node is closed or its children are done.
fn node(
    t: &Tree,
    fix: Fix,
    open: &[usize],
    parent: &[Vec<(f64, f64)>],
    parent_fs: &[Linear],
    parent_ch: &Arc<Chain>,
) {
    let (maps, lo, hi) = (t.maps, t.lo, t.hi);
    if t.stop.load(Ordering::Relaxed) {
        return;
    }
    let seen = t.seen.fetch_add(1, Ordering::Relaxed) + 1;
    if seen > t.budget as u64 || t.deadline.is_some_and(|d| Instant::now() >= d) {
        t.give_up();
        return;
    }
    // Bounds valid on S: the parent's, clamped by the new phase; the maps after it are
    // re-bounded by full CROWN below (once).
    let mut nb = parent.to_vec();
    let (jl, il, on) = fix;
    {
        let b = &mut nb[jl][il];
        if on {
            b.0 = b.0.max(0.0);
        } else {
            b.1 = b.1.min(0.0);
        }
    }
    // The phases as constraints `h <= 0` with linear lower bounds of `h`: the parent's
    // (valid on its set, so on this one), and the new phase's. Phases are fixed in layer
    // order, so every earlier layer is fixed or stable and the new phase's bound is exact
    // up to rounding; it only needs the maps before `jl`, whose bounds the clamp did not
    // change.
    let mut phase_fs: Vec<Linear> = Vec::with_capacity(parent_fs.len() + 1);
    phase_fs.extend_from_slice(parent_fs);
    {
        let mut c = vec![0.0; maps[jl].0.out];
        c[il] = if on { -1.0 } else { 1.0 };
        let f = symbolic::backward_lower_rows(
            &maps[..=jl],
            &nb[..jl],
            &Objective { c, d: 0.0 },
            &t.rows,
        );
        if f.min_over(lo, hi) > 0.0 {
            return;
        }
        phase_fs.push(f);
    }
    // The earliest layer with unstable neurons is affine on S (every earlier neuron is
    // fixed or stable): bound its neurons over S, not the box, by the LP with the phases
    // as constraints (nnenum's exact bounds of a star set), certified by weak duality;
    // then re-bound the later layers by CROWN (once per layer bounded so). A layer that
    // becomes stable lets the next one be bounded the same way. Every pull-back runs on
    // the [`Chain`] of S from that layer on. Before the first re-bound (the node's
    // largest cost) the cases are checked with the bounds at hand (valid on S, the later
    // layers' still the parent's): a case closed by them is closed on S, and a node whose
    // cases all close so needs no re-bound.
    let mut open = open.to_vec();
    // The layers after the new phase's do not reflect it yet.
    let mut stale = true;
    let mut prechecked = false;
    let mut ch = parent_ch.clone();
    let ch = loop {
        ch = chain(t, &nb, &ch);
        let at = ch.at;
        let Some(changed) = lp_layer(
            &ch.maps[..1],
            &[],
            &ch.rows,
            &mut nb[at],
            &phase_fs,
            lo,
            hi,
            None,
            None,
        ) else {
            return;
        };
        if !(changed || stale) || at + 2 >= maps.len() {
            break ch;
        }
        if !prechecked {
            prechecked = true;
            open.retain(|&ci| t.case_open(&ch, &nb, &phase_fs, ci).is_some());
            if open.is_empty() {
                return;
            }
        }
        let later = symbolic::crown_pre_from_rows(&ch.maps, lo, hi, &nb[at..], 1, &ch.rows);
        for (k, b) in later.into_iter().enumerate().skip(1) {
            nb[at + k] = b;
        }
        // A bound that crosses shows S empty (every bound is valid on S).
        if nb.iter().flatten().any(|&(l, u)| l > u) {
            return;
        }
        stale = false;
        if unstable(maps, &nb).first().is_some_and(|u| u.0 == at) {
            break ch;
        }
    };
    let mut still = Vec::new();
    // Whether every case left open here is thin (see [`PhaseResult::Thin`]).
    let mut all_thin = true;
    for &ci in &open {
        let Some((fs, mm)) = t.case_open(&ch, &nb, &phase_fs, ci) else {
            continue;
        };
        let cs = &t.cases[ci].constraints;
        if fs.is_empty() {
            // An empty conjunction without phases: the centre is a point.
            let x: Vec<f64> = lo.iter().zip(hi).map(|(a, b)| 0.5 * (a + b)).collect();
            t.found(ci, x);
            return;
        }
        let mut cands = Vec::with_capacity(2);
        all_thin &= mm
            .as_ref()
            .is_some_and(|m| thin_value(m.value, &fs, lo, hi));
        if let Some(mm) = mm {
            cands.push(mm.x);
        }
        cands.push(fs[fs.len() - 1].argmin_corner(lo, hi));
        for x in cands {
            let y = forward(maps, &x, None);
            if satisfies(cs, &y) {
                t.found(ci, x);
                return;
            }
        }
        still.push(ci);
    }
    if still.is_empty() {
        return;
    }
    // Split in the earliest layer with unstable neurons on S, the neuron whose range is
    // the most balanced (both phases far from excluded).
    let un = unstable(maps, &nb);
    let Some(&(j0, _)) = un.first() else {
        // Fully split: the network is affine on S and the LP exact up to rounding.
        if all_thin {
            t.thin.store(true, Ordering::Relaxed);
        } else {
            t.give_up();
        }
        return;
    };
    let (j, i) = un
        .iter()
        .take_while(|u| u.0 == j0)
        .max_by(|a, b| {
            let s = |u: &(usize, usize)| {
                let (l, h) = nb[u.0][u.1];
                (-l).min(h)
            };
            s(a).total_cmp(&s(b))
        })
        .copied()
        .expect("some neuron");
    rayon::join(
        || node(t, (j, i, true), &still, &nb, &phase_fs, &ch),
        || node(t, (j, i, false), &still, &nb, &phase_fs, &ch),
    );
}

/// A sound lower bound over `S` of a function with linear lower bound `g` (valid on
/// `S`), where `fs` are linear lower bounds (valid on `S`) of functions `<= 0` on `S`:
/// `min over the box of g + sum_p lambda_p f_p` for the multipliers of the LP over
/// `fs`'s rows (`lp`, [`crate::lp::MinLinearSolver`], warm-started from its last solve;
/// weak duality), formed and minimised with outward rounding ([`Linear::combine`],
/// [`Linear::min_over`]); never below `g`'s own minimum, which it is without an LP.
fn min_over_set(
    g: &Linear,
    fs: &[Linear],
    lo: &[f64],
    hi: &[f64],
    lp: Option<&mut crate::lp::MinLinearSolver>,
) -> f64 {
    let own = g.min_over(lo, hi);
    let Some(lam) = lp.and_then(|lp| lp.solve(&g.coef)).map(|r| r.duals) else {
        return own;
    };
    let mut h = g.clone();
    for (f, &l) in fs.iter().zip(&lam) {
        if l > 0.0 && l.is_finite() {
            h = h.combine(1.0, f, l, lo, hi);
        }
    }
    let v = h.min_over(lo, hi);
    if v.is_nan() {
        own
    } else {
        v.max(own)
    }
}

/// Tighten the bounds `layer` of the unstable neurons of the last map of `pull` (a
/// chain whose earlier layers are all stable or fixed on `S`, with bounds `pre` and row
/// magnitudes `rows`) to their minimum and maximum over `S` by [`min_over_set`] with the
/// phase constraints `fs`; with `only`, just the neurons it marks; from `deadline` on,
/// none (the bounds left are sound). `Some(changed)`, or `None` when a bound crosses
/// (`S` empty).
#[allow(clippy::too_many_arguments)]
fn lp_layer(
    pull: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    rows: &[Vec<f64>],
    layer: &mut [(f64, f64)],
    fs: &[Linear],
    lo: &[f64],
    hi: &[f64],
    only: Option<&[bool]>,
    deadline: Option<Instant>,
) -> Option<bool> {
    let mut changed = false;
    // One LP tableau per direction over the phase rows, each solve warm-started from
    // the previous neuron's basis (the rows do not change within the layer).
    let mut lps: Option<[crate::lp::MinLinearSolver; 2]> = None;
    for i in 0..layer.len() {
        let b = &mut layer[i];
        if !(b.0 < 0.0 && b.1 > 0.0) || only.is_some_and(|o| !o.get(i).copied().unwrap_or(true)) {
            continue;
        }
        if deadline.is_some_and(|d| Instant::now() >= d) {
            break;
        }
        if lps.is_none() && !fs.is_empty() {
            let a: Vec<&[f64]> = fs.iter().map(|f| &f.coef[..]).collect();
            let d: Vec<f64> = fs.iter().map(|f| f.cst - f.slack).collect();
            lps = crate::lp::MinLinearSolver::new(&a, &d, lo, hi).map(|s| [s.clone(), s]);
        }
        let (lp_l, lp_u) = match lps.as_mut() {
            Some([a, b]) => (Some(a), Some(b)),
            None => (None, None),
        };
        let mut c = vec![0.0; pull.last().map_or(0, |m| m.0.out)];
        c[i] = 1.0;
        let obj = Objective { c, d: 0.0 };
        // Every layer before this one is stable or fixed on S, so the pull-back of `z_i`
        // relaxes nothing: the one of `-z_i` is its exact negation (the same products
        // with the sign flipped, the same rounding bound).
        let g = symbolic::backward_lower_rows(pull, pre, &obj, rows);
        let l = min_over_set(&g, fs, lo, hi, lp_l);
        let u = -min_over_set(&g.negated(), fs, lo, hi, lp_u);
        if l > b.0 {
            b.0 = l;
            changed = true;
        }
        if u < b.1 {
            b.1 = u;
            changed = true;
        }
        if b.0 > b.1 {
            return None;
        }
    }
    Some(changed)
}

/// Tighten the bounds `nb` (valid on `S`) of the earliest layers with unstable neurons
/// by [`min_over_set`], recomputing the later layers by CROWN after each; `None` when
/// the bounds show `S` empty.
pub(crate) fn tighten(
    maps: &[(Affine, bool)],
    nb: &mut Vec<Vec<(f64, f64)>>,
    fs: &[Linear],
    lo: &[f64],
    hi: &[f64],
) -> Option<()> {
    let rows = symbolic::row_magnitudes(maps, nb, lo, hi);
    tighten_rows(maps, nb, fs, lo, hi, &rows).map(|_| ())
}

/// [`tighten`] for a set whose earliest layer with unstable neurons is the last ReLU
/// layer (no later bounds to recompute): only its neurons `t` with `only[t]` are bounded
/// over `S` (the others keep their bounds, which stay sound); `None` when the bounds
/// show `S` empty; from `deadline` on it bounds no more neurons (a time limit holds on
/// wide layers). For ReLU splitting on networks with one hidden layer, where only the
/// neurons a bound passes by their chord gain from tighter bounds.
pub(crate) fn tighten_last(
    maps: &[(Affine, bool)],
    nb: &mut [Vec<(f64, f64)>],
    fs: &[Linear],
    lo: &[f64],
    hi: &[f64],
    only: &[bool],
    deadline: Option<Instant>,
) -> Option<()> {
    let Some(&(lj, _)) = unstable(maps, nb).first() else {
        return Some(());
    };
    if lj + 1 != nb.len() {
        return tighten_vec(maps, nb, fs, lo, hi);
    }
    let rows = symbolic::row_magnitudes(maps, nb, lo, hi);
    let (before, rest) = nb.split_at_mut(lj);
    lp_layer(
        &maps[..=lj],
        before,
        &rows,
        &mut rest[0],
        fs,
        lo,
        hi,
        Some(only),
        deadline,
    )
    .map(|_| ())
}

/// [`tighten`] on a slice of bounds.
fn tighten_vec(
    maps: &[(Affine, bool)],
    nb: &mut [Vec<(f64, f64)>],
    fs: &[Linear],
    lo: &[f64],
    hi: &[f64],
) -> Option<()> {
    let mut v = nb.to_vec();
    tighten(maps, &mut v, fs, lo, hi)?;
    nb.clone_from_slice(&v);
    Some(())
}

/// [`tighten`] with the row magnitudes of its pull-backs given (`rows`:
/// [`symbolic::row_magnitudes`] of bounds containing `nb`); `Some(true)` when it
/// recomputed the later layers (so that the caller need not).
fn tighten_rows(
    maps: &[(Affine, bool)],
    nb: &mut Vec<Vec<(f64, f64)>>,
    fs: &[Linear],
    lo: &[f64],
    hi: &[f64],
    rows: &[Vec<f64>],
) -> Option<bool> {
    let mut recomputed = false;
    loop {
        let un = unstable(maps, nb);
        let Some(&(lj, _)) = un.first() else {
            return Some(recomputed);
        };
        let (before, rest) = nb.split_at_mut(lj);
        let changed = lp_layer(
            &maps[..=lj],
            before,
            rows,
            &mut rest[0],
            fs,
            lo,
            hi,
            None,
            None,
        )?;
        if !changed {
            return Some(recomputed);
        }
        *nb = symbolic::crown_pre_from(maps, lo, hi, Some(nb), lj + 1);
        recomputed = true;
        if nb.iter().flatten().any(|&(l, u)| l > u) {
            return None;
        }
        if unstable(maps, nb).first().is_some_and(|u| u.0 == lj) {
            return Some(recomputed);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testnet::{pre_activations, random_maps};
    use rand::{Rng, SeedableRng};

    /// What the node step of [`split_phases`] now relies on: with every neuron before a
    /// layer stable or fixed, the pull-back of `-z_i` is the exact negation of that of
    /// `z_i`; pull-backs with row magnitudes computed once ([`symbolic::row_magnitudes`])
    /// equal the ones that sum magnitudes per call, up to the regrouped sum's rounding
    /// (far inside the slack's inflation); and magnitudes from the looser bounds of a
    /// parent node are never below those of the child's tighter bounds (so a child's
    /// rounding bound from its parent's magnitudes stays sound). Also checks that the
    /// functions bound sampled points of the clamped set.
    #[test]
    fn one_pullback_per_neuron_and_shared_magnitudes_equal_the_separate_ones() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(43);
        let mut checked = 0;
        for trial in 0..60 {
            let n = 2 + trial % 4;
            let maps = random_maps(&mut rng, &[n, 8, 7, 6, 3]);
            let lo: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..0.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|l| l + rng.gen_range(0.1..1.5)).collect();
            let pre = symbolic::crown_pre(&maps, &lo, &hi, None);
            // Fix every unstable neuron before layer `j` to its phase at a random point
            // (the set S of points with those phases contains that point).
            let x0: Vec<f64> = (0..n).map(|t| rng.gen_range(lo[t]..=hi[t])).collect();
            let zs = pre_activations(&maps, &x0);
            let j = 1 + trial % 3;
            let mut nb = pre.clone();
            for (k, layer) in nb.iter_mut().enumerate().take(j) {
                for (i, b) in layer.iter_mut().enumerate() {
                    if b.0 < 0.0 && b.1 > 0.0 {
                        if zs[k][i] > 0.0 {
                            b.0 = 0.0;
                        } else {
                            b.1 = 0.0;
                        }
                    }
                }
            }
            let rows_parent = symbolic::row_magnitudes(&maps, &pre, &lo, &hi);
            let rows = symbolic::row_magnitudes(&maps, &nb, &lo, &hi);
            for (rp, r) in rows_parent.iter().flatten().zip(rows.iter().flatten()) {
                assert!(rp >= r, "trial {trial}: parent magnitude below the child's");
            }
            for i in 0..maps[j].0.out {
                let mut c = vec![0.0; maps[j].0.out];
                c[i] = 1.0;
                let up = Objective {
                    c: c.clone(),
                    d: 0.0,
                };
                c[i] = -1.0;
                let dn = Objective { c, d: 0.0 };
                let g = symbolic::backward_lower(&maps[..=j], &nb[..j], &up, &lo, &hi);
                let h = symbolic::backward_lower(&maps[..=j], &nb[..j], &dn, &lo, &hi);
                assert_eq!(g.negated(), h, "trial {trial} neuron {i}");
                for r in [&rows, &rows_parent] {
                    let gr = symbolic::backward_lower_rows(&maps[..=j], &nb[..j], &up, r);
                    assert_eq!(gr.coef, g.coef);
                    assert_eq!(gr.cst, g.cst);
                    assert!(gr.slack >= g.slack * (1.0 - 1e-12), "trial {trial}");
                }
                // Both functions bound z_i at the point x0 (which lies in S).
                let v = zs[j][i];
                let at =
                    |f: &Linear| f.cst + f.coef.iter().zip(&x0).map(|(a, b)| a * b).sum::<f64>();
                assert!(at(&g) - g.slack <= v + 1e-12, "trial {trial}");
                assert!(at(&h) - h.slack <= -v + 1e-12, "trial {trial}");
                checked += 1;
            }
        }
        assert!(checked > 300);
    }

    /// The [`Chain`] of a node (maps composed up to its earliest unstable layer, the
    /// composition's error carried in its row magnitudes): on 80 random networks with
    /// the phases of a random point fixed in the layers before a random one, (1) the
    /// composed map agrees with the layer-by-layer f64 evaluation at points of S within
    /// its error bound plus that evaluation's own rounding (Higham's bound), (2) a chain
    /// extended from its parent's equals one composed from map 0, and (3) the chain's
    /// linear lower bounds of random output objectives have the coefficients of the
    /// layer-by-layer pull-back (up to rounding), a slack at least as large, and bound
    /// the objective at every sampled point of S.
    #[test]
    fn composed_chains_bound_the_network_on_the_phase_set() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(44);
        let mut points = 0;
        for trial in 0..80 {
            let n = 2 + trial % 4;
            let scale = [1.0, 30.0, 1e-3][trial % 3];
            let mut maps = random_maps(&mut rng, &[n, 9, 8, 7, 6, 3]);
            for (m, _) in maps.iter_mut() {
                m.map_weights(|w| *w *= scale);
            }
            let lo: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..0.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|l| l + rng.gen_range(0.1..1.5)).collect();
            let pre = crate::search::piece_bounds(&maps, &lo, &hi, None, None);
            let x0: Vec<f64> = (0..n).map(|t| rng.gen_range(lo[t]..=hi[t])).collect();
            let zs = |x: &[f64]| pre_activations(&maps, x);
            let z0 = zs(&x0);
            // Fix the phases of x0 in the layers before `j` (S: the points of the box
            // with those phases), and make one neuron of layer j unstable when none is.
            let j = 1 + trial % 4;
            let mut nb = pre.clone();
            for (k, layer) in nb.iter_mut().enumerate().take(j) {
                for (i, b) in layer.iter_mut().enumerate() {
                    if z0[k][i] > 0.0 {
                        b.0 = b.0.max(0.0);
                    } else {
                        b.1 = b.1.min(0.0);
                    }
                }
            }
            let t = Tree::new(&maps, &[], &pre, &lo, &hi, 0, None);
            let root = t.root_chain();
            let ch = chain(&t, &nb, &root);
            let want = unstable(&maps, &nb).first().map_or(maps.len() - 2, |u| u.0);
            assert_eq!(ch.at, want, "trial {trial}");
            // (2) from a parent composed to an earlier layer.
            let mut half = nb.clone();
            if ch.at >= 2 {
                half[ch.at / 2].iter_mut().for_each(|b| *b = (-1.0, 1.0));
                let mid = chain(&t, &half, &root);
                let again = chain(&t, &nb, &mid);
                assert_eq!(again.at, ch.at);
                assert_eq!(
                    again.maps[0].0.stored_weights(),
                    ch.maps[0].0.stored_weights(),
                    "trial {trial}"
                );
                assert_eq!(again.prefix.e, ch.prefix.e, "trial {trial}");
            }
            let (first, _) = &ch.maps[0];
            let objs: Vec<Objective> = (0..3)
                .map(|_| Objective {
                    c: (0..3).map(|_| rng.gen_range(-1.0..1.0)).collect(),
                    d: rng.gen_range(-1.0..1.0),
                })
                .collect();
            let rows_now = symbolic::row_magnitudes(&maps, &nb, &lo, &hi);
            let fs: Vec<(Linear, Linear)> = objs
                .iter()
                .map(|o| {
                    let f = symbolic::backward_lower_rows(&ch.maps, &nb[ch.at..], o, &ch.rows);
                    let g = symbolic::backward_lower_rows(&maps, &nb, o, &rows_now);
                    (f, g)
                })
                .collect();
            // (3) the same function as the layer-by-layer pull-back.
            for (f, g) in &fs {
                let size = 1.0 + g.cst.abs() + g.coef.iter().map(|v| v.abs()).sum::<f64>();
                for (a, b) in f.coef.iter().zip(&g.coef) {
                    assert!((a - b).abs() <= 1e-9 * size, "trial {trial}: {a} vs {b}");
                }
                assert!((f.cst - g.cst).abs() <= 1e-9 * size, "trial {trial}");
                assert!(f.slack > 0.0, "trial {trial}");
            }
            for _ in 0..300 {
                let x: Vec<f64> = (0..n).map(|t| rng.gen_range(lo[t]..=hi[t])).collect();
                let z = zs(&x);
                let in_s = (0..j.min(maps.len() - 1))
                    .all(|k| (0..z[k].len()).all(|i| (z[k][i] > 0.0) == (z0[k][i] > 0.0)));
                if !in_s {
                    continue;
                }
                points += 1;
                // (1) the composed map against the evaluation, within the error bound
                // plus the evaluation's own rounding.
                let mut y = vec![0.0; first.out];
                first.apply_f64(&x, &mut y);
                let mag: f64 = maps
                    .iter()
                    .take(ch.at + 1)
                    .map(|(m, _)| {
                        m.stored_weights().iter().map(|w| w.abs()).sum::<f64>()
                            + m.b.iter().map(|b| b.abs()).sum::<f64>()
                    })
                    .product::<f64>()
                    * (1.0 + x.iter().map(|v| v.abs()).sum::<f64>());
                for i in 0..first.out {
                    let d = (y[i] - z[ch.at][i]).abs();
                    assert!(
                        d <= ch.prefix.e[i] + 1e-13 * mag,
                        "trial {trial}: {d} > {}",
                        ch.prefix.e[i]
                    );
                }
                let out = &z[maps.len() - 1];
                for ((f, _), o) in fs.iter().zip(&objs) {
                    let v = o.d + o.c.iter().zip(out).map(|(a, b)| a * b).sum::<f64>();
                    let at =
                        f.cst + f.coef.iter().zip(&x).map(|(a, b)| a * b).sum::<f64>() - f.slack;
                    assert!(
                        at <= v + 1e-12 * (1.0 + v.abs()),
                        "trial {trial}: {at} > {v}"
                    );
                }
            }
        }
        assert!(points > 2000, "{points} points of S sampled");
    }
}
