//! The exact decision of a ReLU-splitting node with no unstable neuron left
//! ([`crate::relusplit`]'s nodes that cannot be split).
//!
//! On such a node every neuron's phase is known on the node's set `S` (fixed by a split,
//! or decided by the node's pre-activation bounds, valid on `S`), so the network is one
//! affine function on `S`, and so is each pre-activation `z_t(x)`: `S` is the polytope
//! of the box's points where every neuron has its phase, and a constraint `g(y) <= 0` of
//! a case is decided by the linear program `min g(x)` over `S` (the LP of a fixed
//! activation pattern in Reluplex / Planet-style complete search; Ehlers, ATVA 2017).
//! beta-CROWN's bound on the node tends to that LP's value only as its multipliers
//! converge (Wang et al., NeurIPS 2021: the optimal multipliers are the LP's duals);
//! on mnist_fc's deep networks a node's few Adam steps left the bound near `-0.1` for
//! dozens of levels.
//!
//! Each phase is a row `f_p(x) <= 0`, CROWN's pull-back of `z_t` (inactive) or `-z_t`
//! (active) through the node's bounds, which relaxes no neuron here (so it is exact up
//! to its rounding slack, and a lower bound of `+-z_t` on `S` in any case); the
//! objective is the pull-back of `g`, exact in the same way. The LP starts with the
//! rows of the split phases only (a relaxation `F` of `S`, as the other neurons'
//! phases hold on `S` by the bounds) and adds, in a few rounds, the rows of the neurons
//! whose phase its minimiser breaks (lazy constraint generation), until the minimiser
//! is in `S`. Its multipliers `lambda_p >= 0` are checked by weak duality with outward
//! rounding: `g + sum_p lambda_p f_p` ([`Linear::combine`]) is a lower bound of `g` on
//! every point of `F` (so of `S`), and its minimum over the box ([`Linear::min_over`])
//! closes the constraint when positive; an empty `F` shows up as a large positive such
//! bound (the multipliers of the LP's artificial variable). The LP's own f64 value is
//! never used as a bound, and its minimiser is only a candidate, evaluated concretely
//! ([`satisfies`], with a margin). The LP is solved by [`lp::min_linear_from_corner`]
//! (dense simplex; one objective per node).

use crate::lp;
use crate::query::{forward, satisfies, Case};
use crate::symbolic::{self, Linear, Objective};
use samara_nn::Affine;
use std::time::Instant;

/// What the exact LP decided on a node for one case.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Exact {
    /// A constraint's certified lower bound on the node's set is positive (non-negative
    /// for a strict one): the case has no point there.
    Closed,
    /// A point of the box satisfying every constraint of the case (with a margin).
    Found(Vec<f64>),
    /// Neither (the LP did not finish in time or its minimiser fails by rounding); the
    /// best certified bound of the case.
    Open(f64),
}

/// Lazy-row rounds of [`decide`] per constraint.
const ROUNDS: usize = 6;

/// The row `f(x) <= 0` of the phase `on` of neuron `t` of ReLU map `j` on a set where
/// the bounds `pre` hold: CROWN's lower bound of `z_t` (inactive) or `-z_t` (active).
pub(crate) fn phase_row(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    (j, t, on): (usize, usize, bool),
    lo: &[f64],
    hi: &[f64],
) -> Linear {
    let mut c = vec![0.0; maps[j].0.out];
    c[t] = if on { -1.0 } else { 1.0 };
    let obj = Objective { c, d: 0.0 };
    symbolic::backward_lower(&maps[..=j], &pre[..j], &obj, lo, hi)
}

/// Whether no ReLU map's neuron is unstable under `pre` (`l < 0 < u`).
pub(crate) fn all_stable(maps: &[(Affine, bool)], pre: &[Vec<(f64, f64)>]) -> bool {
    pre.iter()
        .enumerate()
        .all(|(j, l)| !maps[j].1 || l.iter().all(|&(a, b)| !(a < 0.0 && b > 0.0)))
}

/// Decide the case `case` on a node with bounds `pre` (valid on its set, every neuron
/// stable under them: [`all_stable`]) and phases `splits` fixed, by the exact LP of
/// the module doc. Sound for any `pre` valid on the set (with unstable neurons the
/// objective's pull-back only relaxes them, and the bound stays a lower bound), but
/// exact only when all are stable.
pub(crate) fn decide(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    splits: &[(usize, usize, bool)],
    case: &Case,
    lo: &[f64],
    hi: &[f64],
    deadline: Option<Instant>,
) -> Exact {
    let mut rows = Rows::new(maps, pre, splits, lo, hi);
    let mut best = f64::INFINITY;
    for con in &case.constraints {
        let closes = |lb: f64| if con.strict { lb >= 0.0 } else { lb > 0.0 };
        let mut found = None;
        let lb = rows.minimise(&con.obj, deadline, |lb, x| {
            if closes(lb) {
                return true;
            }
            if satisfies(&case.constraints, &forward(maps, x, None)) {
                found = Some(x.to_vec());
                return true;
            }
            false
        });
        if closes(lb) {
            return Exact::Closed;
        }
        if let Some(x) = found {
            return Exact::Found(x);
        }
        best = best.min(lb);
    }
    Exact::Open(best)
}

/// The LP's rows: the phases of the node (split first, then those added lazily) and
/// their functions ([`phase_row`]).
pub(crate) struct Rows<'a> {
    maps: &'a [(Affine, bool)],
    pre: &'a [Vec<(f64, f64)>],
    lo: &'a [f64],
    hi: &'a [f64],
    phases: Vec<(usize, usize, bool)>,
    lins: Vec<Linear>,
    /// The last LP's multipliers (one per row of `phases` then), when it was solved.
    duals: Option<Vec<f64>>,
}

impl<'a> Rows<'a> {
    /// The rows of the phases `splits`.
    pub(crate) fn new(
        maps: &'a [(Affine, bool)],
        pre: &'a [Vec<(f64, f64)>],
        splits: &[(usize, usize, bool)],
        lo: &'a [f64],
        hi: &'a [f64],
    ) -> Self {
        let lins = splits
            .iter()
            .map(|&r| phase_row(maps, pre, r, lo, hi))
            .collect();
        Rows {
            maps,
            pre,
            lo,
            hi,
            phases: splits.to_vec(),
            lins,
            duals: None,
        }
    }

    /// The phases of the rows.
    pub(crate) fn phases(&self) -> &[(usize, usize, bool)] {
        &self.phases
    }

    /// The multipliers of the last LP of [`Rows::minimise_linear`] that was solved (one
    /// per row of [`Rows::phases`] at that time, a prefix of them now).
    pub(crate) fn duals(&self) -> Option<&[f64]> {
        self.duals.as_deref()
    }

    /// How many rows.
    pub(crate) fn len(&self) -> usize {
        self.lins.len()
    }

    /// The certified lower bound of `obj` on the node's set after at most [`ROUNDS`]
    /// LPs, each adding the rows of the phases its minimiser breaks; `stop(lb, x)` is
    /// asked after each LP with the bound so far and the LP's (f64-feasible)
    /// minimiser, and ends the rounds when true.
    pub(crate) fn minimise(
        &mut self,
        obj: &Objective,
        deadline: Option<Instant>,
        stop: impl FnMut(f64, &[f64]) -> bool,
    ) -> f64 {
        let g = symbolic::backward_lower(self.maps, self.pre, obj, self.lo, self.hi);
        self.minimise_linear(&g, deadline, stop)
    }

    /// [`Rows::minimise`] of a lower bound `g` of the objective on the node's set (the
    /// objective's pull-back, or a beta-CROWN bound: with unstable neurons left the LP
    /// only finds the best multipliers of the rows for `g`'s relaxation, and the bound
    /// stays a lower bound).
    pub(crate) fn minimise_linear(
        &mut self,
        g: &Linear,
        deadline: Option<Instant>,
        mut stop: impl FnMut(f64, &[f64]) -> bool,
    ) -> f64 {
        let (maps, pre, lo, hi) = (self.maps, self.pre, self.lo, self.hi);
        let mut lb = g.min_over(lo, hi);
        for _ in 0..ROUNDS {
            if deadline.is_some_and(|d| Instant::now() >= d) {
                break;
            }
            let a: Vec<&[f64]> = self.lins.iter().map(|l| &l.coef[..]).collect();
            let d: Vec<f64> = self.lins.iter().map(|l| l.cst).collect();
            let Some(r) = lp::min_linear_from_corner(&g.coef, &a, &d, lo, hi, deadline) else {
                break;
            };
            lb = lb.max(certify(g, &self.lins, &r.duals, lo, hi));
            self.duals = Some(r.duals.clone());
            if !r.feasible {
                stop(lb, &r.x);
                break;
            }
            if stop(lb, &r.x) {
                break;
            }
            // The neurons whose phase (fixed, or decided by the bounds) the minimiser
            // breaks: their rows join the LP.
            let new: Vec<(usize, usize, bool)> = broken_phases(maps, pre, &r.x)
                .into_iter()
                .filter(|b| !self.phases.contains(b))
                .collect();
            if new.is_empty() {
                break;
            }
            for b in new {
                self.lins.push(phase_row(maps, pre, b, lo, hi));
                self.phases.push(b);
            }
        }
        lb
    }
}

/// The weak-duality bound `min over the box of g + sum_p lambda_p f_p`, rounded
/// outward (every multiplier non-negative and finite, else left out: any subset of
/// non-negative multipliers gives a valid bound).
fn certify(g: &Linear, rows: &[Linear], lambda: &[f64], lo: &[f64], hi: &[f64]) -> f64 {
    let mut h = g.clone();
    for (f, &l) in rows.iter().zip(lambda) {
        if l > 0.0 && l.is_finite() {
            h = h.combine(1.0, f, l, lo, hi);
        }
    }
    h.min_over(lo, hi)
}

/// The neurons whose concrete pre-activation at `x` contradicts the phase the bounds
/// `pre` give it (`z < 0` where `l >= 0`, `z > 0` where `u <= 0`), as phases
/// `(map, neuron, active)` of the bounds.
fn broken_phases(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    x: &[f64],
) -> Vec<(usize, usize, bool)> {
    let mut out = Vec::new();
    let mut a = x.to_vec();
    for (j, (m, r)) in maps.iter().enumerate().take(pre.len()) {
        let mut z = vec![0.0; m.out];
        m.apply_f64(&a, &mut z);
        if *r {
            for (t, (&v, &(l, u))) in z.iter().zip(&pre[j]).enumerate() {
                if l >= 0.0 && v < 0.0 {
                    out.push((j, t, true));
                } else if u <= 0.0 && v > 0.0 && l < u {
                    out.push((j, t, false));
                } else if u <= 0.0 && l >= 0.0 && v != 0.0 {
                    // A neuron pinned at 0 on the set: both rows.
                    out.push((j, t, v < 0.0));
                }
            }
            z.iter_mut().for_each(|v| *v = v.max(0.0));
        }
        a = z;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::query::OutputConstraint;
    use crate::testnet::{affine_of_2d, pre_activations, random_maps, region_vertices};
    use rand::{Rng, SeedableRng};

    /// A node driven to every neuron stable: from the box's CROWN bounds, the first
    /// unstable neuron (in layer order) is fixed to its phase at `x0` (or a random
    /// phase when `x0` is `None`), the later layers re-bounded by CROWN over the
    /// clamped bounds, until none is unstable. `None` when a phase empties the bounds.
    #[allow(clippy::type_complexity)]
    fn drive(
        maps: &[(Affine, bool)],
        lo: &[f64],
        hi: &[f64],
        x0: Option<&[f64]>,
        rng: &mut rand_chacha::ChaCha8Rng,
    ) -> Option<(Vec<Vec<(f64, f64)>>, Vec<(usize, usize, bool)>)> {
        let fwd = symbolic::hidden_pre(maps, lo, hi, None);
        let mut pre = symbolic::crown_pre(maps, lo, hi, Some(&fwd));
        pre.truncate(maps.len() - 1);
        let z0 = x0.map(|x| pre_activations(maps, x));
        let mut splits = Vec::new();
        loop {
            let next = pre.iter().enumerate().find_map(|(j, l)| {
                l.iter()
                    .position(|&(a, b)| a < 0.0 && b > 0.0)
                    .map(|t| (j, t))
            });
            let Some((j, t)) = next else {
                return Some((pre, splits));
            };
            let on = match &z0 {
                Some(z) => z[j][t] >= 0.0,
                None => rng.gen_bool(0.5),
            };
            let b = &mut pre[j][t];
            if on {
                b.0 = 0.0;
            } else {
                b.1 = 0.0;
            }
            splits.push((j, t, on));
            if j + 1 < pre.len() {
                let re = symbolic::crown_pre_from(maps, lo, hi, Some(&pre), j + 1);
                for (old, new) in pre.iter_mut().zip(&re).skip(j + 1) {
                    for (o, n) in old.iter_mut().zip(new) {
                        *o = (o.0.max(n.0), o.1.min(n.1));
                    }
                }
            }
            if pre.iter().flatten().any(|&(l, u)| l > u) {
                return None;
            }
        }
    }

    /// The exact minimum of `g` over the node's set on a 2-input network, computed
    /// independently of the LP: the set is the polygon of the box's points where every
    /// neuron has the phase the bounds give it (each pre-activation an affine function
    /// of `x` along that pattern, composed here in f64); its vertices are among the
    /// pairwise intersections of the lines of the box's edges and of those functions'
    /// zero sets, and a linear `g` attains its minimum at one of them. `None` when the
    /// polygon is empty (no intersection point inside it).
    fn polygon_min(
        maps: &[(Affine, bool)],
        pre: &[Vec<(f64, f64)>],
        obj: &Objective,
        lo: &[f64],
        hi: &[f64],
    ) -> Option<f64> {
        // Affine functions (a0, a1, b) of x along the pattern.
        let mut cur: Vec<[f64; 3]> = vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let mut lines: Vec<([f64; 3], bool)> = Vec::new(); // (z, active)
        let mut out = Vec::new();
        for (j, (m, r)) in maps.iter().enumerate() {
            let mut z = affine_of_2d(m, &cur);
            if *r {
                for (t, zt) in z.iter_mut().enumerate() {
                    let (l, u) = pre[j][t];
                    let active = l >= 0.0 && u > 0.0;
                    if l >= 0.0 && u <= 0.0 {
                        lines.push((*zt, true));
                        lines.push((*zt, false));
                    } else {
                        lines.push((*zt, active));
                    }
                    if !active {
                        *zt = [0.0; 3];
                    }
                }
            } else {
                out = z.clone();
            }
            cur = z;
        }
        let g = |x: [f64; 2]| {
            obj.d
                + obj
                    .c
                    .iter()
                    .zip(&out)
                    .map(|(c, f)| c * (f[0] * x[0] + f[1] * x[1] + f[2]))
                    .sum::<f64>()
        };
        region_vertices(lo, hi, &lines, 1e-9, 1e-9)
            .into_iter()
            .map(g)
            .reduce(f64::min)
    }

    /// On random 2-input networks with 2-3 hidden layers and nodes driven to every
    /// neuron stable (phases of a random point of the box, or random phases): the
    /// certified bound after the LP rounds is below the objective at every one of the
    /// 10,000 sampled points that fall in the node's set, below the polygon's exact
    /// minimum and within 1e-6 of it (positive when the polygon is empty); a case
    /// [`decide`] closes has no sampled point with `g <= 0` and an exact minimum above
    /// 0, and a point it finds is in the box and violates.
    #[test]
    fn exact_lp_bound_matches_the_polygons_minimum() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(51);
        let (mut exact, mut closed, mut found, mut empty, mut open, mut checked) =
            (0, 0, 0, 0, 0, 0usize);
        for trial in 0..120 {
            let widths: &[usize] = match trial % 3 {
                0 => &[2, 6, 6, 2],
                1 => &[2, 8, 5, 6, 2],
                _ => &[2, 5, 7, 2],
            };
            let maps = random_maps(&mut rng, widths);
            let lo: Vec<f64> = (0..2).map(|_| rng.gen_range(-1.0..0.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|l| l + rng.gen_range(0.3..2.0)).collect();
            let x0: Vec<f64> = (0..2).map(|k| rng.gen_range(lo[k]..=hi[k])).collect();
            let random_phases = trial % 4 == 3;
            let Some((pre, splits)) = drive(
                &maps,
                &lo,
                &hi,
                (!random_phases).then_some(&x0[..]),
                &mut rng,
            ) else {
                continue;
            };
            assert!(all_stable(&maps, &pre));
            let obj = Objective {
                c: vec![1.0, -1.0],
                d: rng.gen_range(-0.5..0.5),
            };
            let case = Case {
                lo: lo.clone(),
                hi: hi.clone(),
                constraints: vec![OutputConstraint {
                    obj: obj.clone(),
                    strict: false,
                }],
            };
            // The node's set: the box's points where every split phase holds.
            let in_set = |x: &[f64]| {
                let z = pre_activations(&maps, x);
                splits.iter().all(|&(j, t, on)| (z[j][t] >= 0.0) == on)
            };
            let gval = |x: &[f64]| {
                let y = forward(&maps, x, None);
                obj.d + y[0] - y[1]
            };
            let samples: Vec<f64> = (0..10_000)
                .map(|_| -> Vec<f64> { (0..2).map(|k| rng.gen_range(lo[k]..=hi[k])).collect() })
                .filter(|x| in_set(x))
                .map(|x| gval(&x))
                .collect();
            let pmin = polygon_min(&maps, &pre, &obj, &lo, &hi);
            let out = decide(&maps, &pre, &splits, &case, &lo, &hi, None);
            // The bound after the rounds (no early stop): below every sample and the
            // exact minimum, and equal to the latter within 1e-6.
            let lb = Rows::new(&maps, &pre, &splits, &lo, &hi).minimise(&obj, None, |_, _| false);
            for v in &samples {
                assert!(lb <= *v, "trial {trial}: bound {lb} above sample {v}");
            }
            match pmin {
                Some(p) => {
                    assert!(lb <= p + 1e-9, "trial {trial}: bound {lb} above min {p}");
                    assert!(
                        lb >= p - 1e-6 * (1.0 + p.abs()),
                        "trial {trial}: bound {lb} loose, exact min {p}"
                    );
                    exact += 1;
                }
                None => assert!(lb > 0.0, "trial {trial}: empty set, bound {lb}"),
            }
            match &out {
                Exact::Closed => {
                    closed += 1;
                    assert!(
                        samples.iter().all(|v| *v > 0.0),
                        "trial {trial}: closed with a sampled point at or below 0"
                    );
                    if let Some(p) = pmin {
                        assert!(p > -1e-9, "trial {trial}: closed but exact min {p}");
                    } else {
                        empty += 1;
                    }
                }
                Exact::Found(x) => {
                    found += 1;
                    assert!(gval(x) < 0.0, "trial {trial}: found point not violating");
                    assert!(x
                        .iter()
                        .zip(&lo)
                        .zip(&hi)
                        .all(|((v, l), h)| l <= v && v <= h));
                }
                Exact::Open(b) => {
                    open += 1;
                    assert!(*b <= lb + 1e-9, "trial {trial}: open at {b}, rounds {lb}");
                }
            }
            checked += samples.len();
            if pmin.is_none() {
                assert!(
                    samples.is_empty(),
                    "trial {trial}: polygon empty but {} samples",
                    samples.len()
                );
            }
        }
        assert!(checked > 150_000, "{checked}");
        eprintln!("closed {closed} found {found} open {open} exact {exact} empty {empty}");
        assert!(
            closed > 20 && found > 20 && exact > 60 && empty > 5,
            "closed {closed} found {found} exact {exact} empty {empty}"
        );
    }
}
