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

use crate::query::{combination_certifies, forward, satisfies, Case};
use crate::symbolic::{self, Linear, Objective};
use samara_nn::Affine;
use std::sync::Arc;

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

/// Decide the open cases `open` on the piece `[lo, hi]` (pre-activation bounds `pre`,
/// valid on the whole piece) by splitting its unstable ReLUs, examining at most
/// `budget` nodes and stopping at `deadline`. See the module doc.
#[allow(clippy::too_many_arguments)]
pub(crate) fn split_phases(
    maps: &[(Affine, bool)],
    cases: &[Case],
    open: &[usize],
    pre: &[Vec<(f64, f64)>],
    lo: &[f64],
    hi: &[f64],
    budget: usize,
    deadline: Option<std::time::Instant>,
    nodes: &mut u64,
) -> PhaseResult {
    // Each node: its phases, the cases still open, bounds valid on its set (the
    // parent's, to be clamped by the last phase and tightened).
    #[allow(clippy::type_complexity)]
    let mut stack: Vec<(
        Vec<Fix>,
        Vec<usize>,
        Arc<Vec<Vec<(f64, f64)>>>,
        Arc<Vec<Linear>>,
    )> = Vec::new();
    let Some(&(j0, i0)) = unstable(maps, pre).first() else {
        return PhaseResult::GaveUp;
    };
    let root = Arc::new(pre.to_vec());
    let none = Arc::new(Vec::new());
    stack.push((
        vec![(j0, i0, false)],
        open.to_vec(),
        root.clone(),
        none.clone(),
    ));
    stack.push((vec![(j0, i0, true)], open.to_vec(), root, none));
    let mut seen = 0usize;
    let mut thin = false;
    while let Some((fixes, open, parent, parent_fs)) = stack.pop() {
        seen += 1;
        *nodes += 1;
        if seen > budget || deadline.is_some_and(|d| std::time::Instant::now() >= d) {
            return PhaseResult::GaveUp;
        }
        // Bounds valid on S: the parent's, clamped by the new phase; the maps after it
        // are re-bounded by full CROWN below (once).
        let mut nb = (*parent).clone();
        let &(jl, il, on) = fixes.last().expect("a node has a phase");
        {
            let b = &mut nb[jl][il];
            if on {
                b.0 = b.0.max(0.0);
            } else {
                b.1 = b.1.min(0.0);
            }
        }
        // Row magnitudes for the rounding bounds of this node's pull-backs: from the
        // clamped parent bounds, which contain every bound computed below.
        let rows = symbolic::row_magnitudes(maps, &nb, lo, hi);
        // The phases as constraints `h <= 0` with linear lower bounds of `h`: the
        // parent's (valid on its set, so on this one), and the new phase's. Phases are
        // fixed in layer order, so every earlier layer is fixed or stable and the new
        // phase's bound is exact up to rounding; it only needs the maps before `jl`,
        // whose bounds the clamp did not change.
        let mut phase_fs: Vec<Linear> = (*parent_fs).clone();
        {
            let (j, i) = (jl, il);
            let mut c = vec![0.0; maps[j].0.out];
            c[i] = if on { -1.0 } else { 1.0 };
            let f = symbolic::backward_lower_rows(
                &maps[..=j],
                &nb[..j],
                &Objective { c, d: 0.0 },
                &rows,
            );
            if f.min_over(lo, hi) > 0.0 {
                continue;
            }
            phase_fs.push(f);
        }
        // The earliest layer with unstable neurons is affine on S (every earlier neuron
        // is fixed or stable): bound its neurons over S, not the box, by the LP with the
        // phases as constraints (nnenum's exact bounds of a star set), certified by weak
        // duality; layers that become stable let the next one be bounded the same way.
        // When that layer is at or before the new phase's (the usual case: splits go in
        // layer order), its LP bounds need only the bounds before it, and the maps after
        // it are re-bounded by CROWN once, after the LPs, instead of before and after.
        let early = unstable(maps, &nb).first().is_some_and(|u| u.0 <= jl);
        if !early {
            nb = symbolic::crown_pre_from(maps, lo, hi, Some(&nb), jl + 1);
            // A bound that crosses shows S empty (every bound is valid on S).
            if nb.iter().flatten().any(|&(l, u)| l > u) {
                continue;
            }
        }
        match tighten_rows(maps, &mut nb, &phase_fs, lo, hi, &rows) {
            None => continue,
            Some(false) if early => {
                nb = symbolic::crown_pre_from(maps, lo, hi, Some(&nb), jl + 1);
                if nb.iter().flatten().any(|&(l, u)| l > u) {
                    continue;
                }
            }
            Some(_) => {}
        }
        let mut still = Vec::new();
        // Whether every case left open here is thin (see [`PhaseResult::Thin`]).
        let mut all_thin = true;
        for &ci in &open {
            let cs = &cases[ci].constraints;
            let mut fs = phase_fs.clone();
            let mut closed = false;
            for k in cs {
                let f = symbolic::backward_lower_rows(maps, &nb, &k.obj, &rows);
                let lb = f.min_over(lo, hi);
                if if k.strict { lb >= 0.0 } else { lb > 0.0 } {
                    closed = true;
                    break;
                }
                fs.push(f);
            }
            if closed {
                continue;
            }
            if fs.is_empty() {
                // An empty conjunction without phases: the centre is a point.
                let x: Vec<f64> = lo.iter().zip(hi).map(|(a, b)| 0.5 * (a + b)).collect();
                return PhaseResult::Found(ci, x);
            }
            let (ok, mm) = if fs.len() >= 2 {
                combination_certifies(&fs, lo, hi)
            } else {
                (false, None)
            };
            if ok {
                continue;
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
                    return PhaseResult::Found(ci, x);
                }
            }
            still.push(ci);
        }
        if still.is_empty() {
            continue;
        }
        // Split in the earliest layer with unstable neurons on S, the neuron whose
        // range is the most balanced (both phases far from excluded).
        let un = unstable(maps, &nb);
        let Some(&(j0, _)) = un.first() else {
            // Fully split: the network is affine on S and the LP exact up to rounding.
            if all_thin {
                thin = true;
                continue;
            }
            return PhaseResult::GaveUp;
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
        let nb = Arc::new(nb);
        let fsa = Arc::new(phase_fs);
        for on in [false, true] {
            let mut f = fixes.clone();
            f.push((j, i, on));
            stack.push((f, still.clone(), nb.clone(), fsa.clone()));
        }
    }
    if thin {
        PhaseResult::Thin
    } else {
        PhaseResult::Closed
    }
}

/// A sound lower bound over `S` of a function with linear lower bound `g` (valid on
/// `S`), where `fs` are linear lower bounds (valid on `S`) of functions `<= 0` on `S`:
/// `min over the box of g + sum_p lambda_p f_p` for the LP's multipliers
/// ([`crate::lp::min_linear_duals`]; weak duality), formed and minimised with outward
/// rounding ([`Linear::combine`], [`Linear::min_over`]); never below `g`'s own minimum.
fn min_over_set(g: &Linear, fs: &[Linear], lo: &[f64], hi: &[f64]) -> f64 {
    let own = g.min_over(lo, hi);
    let a: Vec<&[f64]> = fs.iter().map(|f| &f.coef[..]).collect();
    let d: Vec<f64> = fs.iter().map(|f| f.cst - f.slack).collect();
    let Some(lam) = crate::lp::min_linear_duals(&g.coef, &a, &d, lo, hi) else {
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
        let mut changed = false;
        for &(j, i) in un.iter().take_while(|u| u.0 == lj) {
            let mut c = vec![0.0; maps[j].0.out];
            c[i] = 1.0;
            let obj = Objective { c, d: 0.0 };
            // Every layer before `j` is stable or fixed on S, so the pull-back of `z_i`
            // relaxes nothing: the one of `-z_i` is its exact negation (the same
            // products with the sign flipped, the same rounding bound).
            let g = symbolic::backward_lower_rows(&maps[..=j], &nb[..j], &obj, rows);
            let l = min_over_set(&g, fs, lo, hi);
            let u = -min_over_set(&g.negated(), fs, lo, hi);
            let b = &mut nb[j][i];
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
    use rand::{Rng, SeedableRng};

    fn random_maps(rng: &mut rand_chacha::ChaCha8Rng, widths: &[usize]) -> Vec<(Affine, bool)> {
        let last = widths.len() - 2;
        (0..widths.len() - 1)
            .map(|k| {
                let (inp, out) = (widths[k], widths[k + 1]);
                let w = (0..inp * out).map(|_| rng.gen_range(-1.0..1.0)).collect();
                let b = (0..out).map(|_| rng.gen_range(-0.5..0.5)).collect();
                (Affine { inp, out, w, b }, k < last)
            })
            .collect()
    }

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
            let mut z = x0.clone();
            let mut zs = Vec::new();
            for (m, r) in &maps {
                let mut o = vec![0.0; m.out];
                m.apply_f64(&z, &mut o);
                zs.push(o.clone());
                if *r {
                    o.iter_mut().for_each(|v| *v = v.max(0.0));
                }
                z = o;
            }
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
}
