//! A plain big-M MILP encoding solved by HiGHS (feature `highs`): the cross-check and
//! alternative engine. Each ReLU with pre-activation bounds `l < 0 < u` gets a binary
//! `d`: `a >= z, a >= 0, a <= z - l (1 - d), a <= u d` (Tjeng, Xiao & Tedrake, ICLR
//! 2019). Tight big-M constants are what makes such MILPs solvable (Tjeng et al.), so the
//! bounds are tightened twice before a layer is encoded:
//! - the tightest of interval arithmetic, CROWN and 20 alpha-CROWN steps over the input
//!   box (sound, outward-rounded);
//! - then, for each ReLU still unstable, the minimum and maximum of its pre-activation
//!   over the **LP relaxation** built so far (earlier layers with `d` in `[0, 1]`, and
//!   the region's constraints on the inputs alone, such as P1's `x + y >= ystar`): the
//!   "LP-tightened bounds" of Tjeng et al., section 4. An input constraint that cuts
//!   the box to a sliver turns most ReLUs stable this way, which interval and CROWN
//!   bounds over the box cannot see.
//!
//! Strict constraints are taken non-strictly (the closure), so the optimum is the
//! supremum. HiGHS works in floating point: each LP bound is widened by
//! [`LP_MARGIN`] (relative) before it is used, and this engine is for cross-checks, not
//! proofs. Each disjunct's MILP stops at [`TIME_LIMIT_S`] (an error then, never a value).

use crate::net::{affine_bounds, PwlNet};
use crate::point::tighten;
use highs::{Col, HighsModelStatus, RowProblem, Sense as HSense};
use samara_bounds::symbolic;
use samara_spec::normal::{Cmp, Goal, Query, Sense, Var};
use std::collections::HashMap;

/// HiGHS's time limit per disjunct, in seconds.
pub const TIME_LIMIT_S: f64 = 120.0;

/// The relative widening of a bound found by an LP (HiGHS's feasibility tolerance is
/// 1e-7): `v +- LP_MARGIN * (1 + |v|)`.
pub const LP_MARGIN: f64 = 1e-6;

/// The MILP and its LP relaxation, built column by column in step (a column's handle
/// is the same in both); only the MILP's ReLU indicators are integer.
#[derive(Default)]
struct Pair {
    milp: RowProblem,
    lp: RowProblem,
}

impl Pair {
    fn column(&mut self, cost: f64, lo: f64, hi: f64, integer: bool) -> Col {
        let c = self
            .milp
            .add_column_with_integrality(cost, lo..=hi, integer);
        let r = self.lp.add_column(0.0, lo..=hi);
        debug_assert_eq!(c, r);
        c
    }

    fn row(&mut self, lo: f64, hi: f64, row: &[(Col, f64)]) {
        self.milp.add_row(lo..=hi, row);
        self.lp.add_row(lo..=hi, row);
    }

    /// The range of `sum row + constant` over the LP relaxation, widened by
    /// [`LP_MARGIN`]; `None` if the relaxation is infeasible (then so is the MILP).
    /// A solve that ends otherwise (a time limit, numerical trouble) gives
    /// `(-inf, inf)`: the caller keeps the bounds it had.
    fn lp_range(&self, row: &[(Col, f64)], constant: f64) -> Option<(f64, f64)> {
        let mut out = [f64::NEG_INFINITY, f64::INFINITY];
        for (k, sense) in [HSense::Minimise, HSense::Maximise].into_iter().enumerate() {
            let mut pb = self.lp.clone();
            let t = pb.add_column(1.0, f64::NEG_INFINITY..=f64::INFINITY);
            let mut r = vec![(t, 1.0)];
            r.extend(row.iter().map(|&(c, w)| (c, -w)));
            pb.add_row(0.0..=0.0, r);
            let mut model = pb.optimise(sense);
            model.make_quiet();
            model.set_option("time_limit", TIME_LIMIT_S);
            let solved = model.solve();
            match solved.status() {
                HighsModelStatus::Optimal => {
                    let v = solved.objective_value() + constant;
                    let m = LP_MARGIN * (1.0 + v.abs());
                    out[k] = if k == 0 { v - m } else { v + m };
                }
                HighsModelStatus::Infeasible => return None,
                _ => {}
            }
        }
        Some((out[0], out[1]))
    }
}

/// The optimum of an `Optimise` query (over every disjunct), `None` if the region is
/// empty; for a `Prove` query, `Some(0.0)` if the region is non-empty.
pub fn optimise_milp(q: &Query, nets: &HashMap<String, PwlNet>) -> Result<Option<f64>, String> {
    let (obj, sense) = match &q.goal {
        Goal::Optimise {
            objective, sense, ..
        } => (Some(objective.clone()), *sense),
        Goal::Prove => (None, Sense::Max),
    };
    let coef = |v: Var| -> f64 {
        obj.as_ref()
            .map(|o| o.terms.iter().filter(|t| t.0 == v).map(|t| t.1).sum())
            .unwrap_or(0.0)
    };
    let mut best: Option<f64> = None;
    'disjunct: for conj in &q.region {
        let boxes = tighten(
            &q.applications
                .iter()
                .map(|a| a.input_box.clone())
                .collect::<Vec<_>>(),
            conj,
        );
        if boxes.iter().flatten().any(|(l, h)| l > h) {
            continue;
        }
        let mut pb = Pair::default();
        // Every input and free variable first, then the region's constraints on them
        // alone: the LP bounds of every layer see those.
        let ins: Vec<Vec<Col>> = boxes
            .iter()
            .enumerate()
            .map(|(ai, b)| {
                b.iter()
                    .enumerate()
                    .map(|(i, (l, h))| {
                        pb.column(coef(Var::Input { app: ai, index: i }), *l, *h, false)
                    })
                    .collect()
            })
            .collect();
        let frees: Vec<Col> = q
            .free_vars
            .iter()
            .enumerate()
            .map(|(k, f)| pb.column(coef(Var::Free(k)), f.1, f.2, false))
            .collect();
        let on_inputs = |c: &samara_spec::normal::Constraint| {
            c.expr
                .terms
                .iter()
                .all(|(v, _)| !matches!(v, Var::Output { .. }))
        };
        let mut outs = Vec::new();
        let add_rows = |pb: &mut Pair, outs: &[Vec<Col>], inputs_only: bool| {
            let col = |v: Var| match v {
                Var::Input { app, index } => ins[app][index],
                Var::Output { app, index } => outs[app][index],
                Var::Free(k) => frees[k],
            };
            for c in conj.iter().filter(|c| on_inputs(c) == inputs_only) {
                let row: Vec<_> = c.expr.terms.iter().map(|(v, a)| (col(*v), *a)).collect();
                let k = -c.expr.constant;
                let (lo, hi) = match c.cmp {
                    Cmp::Eq => (k, k),
                    Cmp::Le | Cmp::Lt => (f64::NEG_INFINITY, k),
                };
                if inputs_only {
                    pb.row(lo, hi, &row);
                } else {
                    pb.milp.add_row(lo..=hi, row);
                }
            }
        };
        add_rows(&mut pb, &outs, true);
        for (ai, app) in q.applications.iter().enumerate() {
            let net = nets
                .get(&app.network)
                .ok_or_else(|| format!("network `{}` missing", app.network))?;
            let (mut lo, mut hi): (Vec<f64>, Vec<f64>) = boxes[ai].iter().copied().unzip();
            let mut pre = symbolic::crown_pre(&net.maps, &lo, &hi, None);
            symbolic::alpha_pre_until(&net.maps, &mut pre, &lo, &hi, 20, None);
            let mut prev = ins[ai].clone();
            let n_maps = net.maps.len();
            for (k, (m, relu)) in net.maps.iter().enumerate() {
                let (mut zl, mut zh) = affine_bounds(m, &lo, &hi);
                if let Some(p) = pre.get(k) {
                    for (r, &(l, h)) in p.iter().enumerate() {
                        (zl[r], zh[r]) = (zl[r].max(l), zh[r].min(h));
                    }
                }
                let rows: Vec<Vec<(Col, f64)>> = (0..m.out)
                    .map(|r| m.row(r).nonzeros().map(|(j, w)| (prev[j], w)).collect())
                    .collect();
                if *relu {
                    for r in 0..m.out {
                        if zl[r] < 0.0 && zh[r] > 0.0 {
                            let Some((l, h)) = pb.lp_range(&rows[r], m.b[r]) else {
                                continue 'disjunct;
                            };
                            (zl[r], zh[r]) = (zl[r].max(l), zh[r].min(h));
                        }
                    }
                }
                let last = k + 1 == n_maps;
                let mut zs = Vec::new();
                for r in 0..m.out {
                    let c = if last && !*relu {
                        coef(Var::Output { app: ai, index: r })
                    } else {
                        0.0
                    };
                    let z = pb.column(c, zl[r], zh[r], false);
                    let mut row = vec![(z, 1.0)];
                    row.extend(rows[r].iter().map(|&(c, w)| (c, -w)));
                    pb.row(m.b[r], m.b[r], &row);
                    zs.push(z);
                }
                if *relu {
                    let mut a_s = Vec::new();
                    for r in 0..m.out {
                        let (l, u) = (zl[r], zh[r]);
                        let c = if last {
                            coef(Var::Output { app: ai, index: r })
                        } else {
                            0.0
                        };
                        let a = pb.column(c, 0.0, u.max(0.0), false);
                        if l >= 0.0 {
                            pb.row(0.0, 0.0, &[(a, 1.0), (zs[r], -1.0)]);
                        } else if u <= 0.0 {
                            pb.row(0.0, 0.0, &[(a, 1.0)]);
                        } else {
                            let d = pb.column(0.0, 0.0, 1.0, true);
                            pb.row(0.0, f64::INFINITY, &[(a, 1.0), (zs[r], -1.0)]);
                            pb.row(f64::NEG_INFINITY, -l, &[(a, 1.0), (zs[r], -1.0), (d, -l)]);
                            pb.row(f64::NEG_INFINITY, 0.0, &[(a, 1.0), (d, -u)]);
                        }
                        a_s.push(a);
                    }
                    lo = zl.iter().map(|v| v.max(0.0)).collect();
                    hi = zh.iter().map(|v| v.max(0.0)).collect();
                    prev = a_s;
                } else {
                    lo = zl;
                    hi = zh;
                    prev = zs;
                }
            }
            outs.push(prev);
        }
        add_rows(&mut pb, &outs, false);
        let mut model = pb.milp.optimise(if sense == Sense::Max {
            HSense::Maximise
        } else {
            HSense::Minimise
        });
        model.make_quiet();
        model.set_option("time_limit", TIME_LIMIT_S);
        let solved = model.solve();
        match solved.status() {
            HighsModelStatus::Optimal => {
                let v = solved.objective_value() + obj.as_ref().map(|o| o.constant).unwrap_or(0.0);
                best = Some(match (best, sense) {
                    (None, _) => v,
                    (Some(b), Sense::Max) => b.max(v),
                    (Some(b), Sense::Min) => b.min(v),
                });
            }
            HighsModelStatus::Infeasible => {}
            s => return Err(format!("HiGHS: {s:?}")),
        }
    }
    Ok(best)
}
