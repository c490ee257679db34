//! A plain big-M MILP encoding solved by HiGHS (feature `highs`): the cross-check and
//! alternative engine. Each ReLU with pre-activation bounds `l < 0 < u` gets a binary
//! `d`: `a >= z, a >= 0, a <= z - l (1 - d), a <= u d` (Tjeng, Xiao & Tedrake, ICLR
//! 2019). The bounds are the tightest of interval arithmetic, CROWN and 20 alpha-CROWN
//! steps over the input box (all sound, so the encoding stays exact; tight big-M
//! constants are what makes such MILPs solvable, as Tjeng et al. show). Strict
//! constraints are taken non-strictly (the closure), so the optimum is the supremum.
//! HiGHS works in floating point: this engine is for cross-checks, not proofs. Each
//! disjunct's solve stops at [`TIME_LIMIT_S`] (an error then, never a value).

use crate::net::{affine_bounds, PwlNet};
use crate::point::tighten;
use highs::{HighsModelStatus, RowProblem, Sense as HSense};
use samara_bounds::symbolic;
use samara_spec::normal::{Cmp, Goal, Query, Sense, Var};
use std::collections::HashMap;

/// HiGHS's time limit per disjunct, in seconds.
pub const TIME_LIMIT_S: f64 = 120.0;

/// The optimum of an `Optimise` query (over every disjunct), `None` if the region is
/// empty; for a `Prove` query, `Some(0.0)` if the region is non-empty.
pub fn optimise_milp(q: &Query, nets: &HashMap<String, PwlNet>) -> Result<Option<f64>, String> {
    let (obj, sense) = match &q.goal {
        Goal::Optimise {
            objective, sense, ..
        } => (Some(objective.clone()), *sense),
        Goal::Prove => (None, Sense::Max),
    };
    let mut best: Option<f64> = None;
    for conj in &q.region {
        let mut pb = RowProblem::default();
        let boxes = tighten(
            &q.applications
                .iter()
                .map(|a| a.input_box.clone())
                .collect::<Vec<_>>(),
            conj,
        );
        let mut ins = Vec::new();
        let mut outs = Vec::new();
        let coef = |v: Var| -> f64 {
            obj.as_ref()
                .map(|o| o.terms.iter().filter(|t| t.0 == v).map(|t| t.1).sum())
                .unwrap_or(0.0)
        };
        for (ai, app) in q.applications.iter().enumerate() {
            let net = nets
                .get(&app.network)
                .ok_or_else(|| format!("network `{}` missing", app.network))?;
            let b = &boxes[ai];
            if b.iter().any(|(l, h)| l > h) {
                ins.clear();
                break;
            }
            let x: Vec<_> = b
                .iter()
                .enumerate()
                .map(|(i, (l, h))| pb.add_column(coef(Var::Input { app: ai, index: i }), *l..=*h))
                .collect();
            let (mut lo, mut hi): (Vec<f64>, Vec<f64>) = b.iter().copied().unzip();
            let mut pre = symbolic::crown_pre(&net.maps, &lo, &hi, None);
            symbolic::alpha_pre_until(&net.maps, &mut pre, &lo, &hi, 20, None);
            let mut prev = x.clone();
            let n_maps = net.maps.len();
            for (k, (m, relu)) in net.maps.iter().enumerate() {
                let (mut zl, mut zh) = affine_bounds(m, &lo, &hi);
                if let Some(p) = pre.get(k) {
                    for (r, &(l, h)) in p.iter().enumerate() {
                        (zl[r], zh[r]) = (zl[r].max(l), zh[r].min(h));
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
                    let z = pb.add_column(c, zl[r]..=zh[r]);
                    let mut row = vec![(z, 1.0)];
                    for j in 0..m.inp {
                        let w = m.w[r * m.inp + j];
                        if w != 0.0 {
                            row.push((prev[j], -w));
                        }
                    }
                    pb.add_row(m.b[r]..=m.b[r], row);
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
                        let a = pb.add_column(c, 0.0..=u.max(0.0));
                        if l >= 0.0 {
                            pb.add_row(0.0..=0.0, [(a, 1.0), (zs[r], -1.0)]);
                        } else if u <= 0.0 {
                            pb.add_row(0.0..=0.0, [(a, 1.0)]);
                        } else {
                            let d = pb.add_integer_column(0.0, 0.0..=1.0);
                            pb.add_row(0.0.., [(a, 1.0), (zs[r], -1.0)]);
                            pb.add_row(..=-l, [(a, 1.0), (zs[r], -1.0), (d, -l)]);
                            pb.add_row(..=0.0, [(a, 1.0), (d, -u)]);
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
            ins.push(x);
            outs.push(prev);
        }
        if ins.len() != q.applications.len() {
            continue;
        }
        let frees: Vec<_> = q
            .free_vars
            .iter()
            .enumerate()
            .map(|(k, f)| pb.add_column(coef(Var::Free(k)), f.1..=f.2))
            .collect();
        let col = |v: Var| match v {
            Var::Input { app, index } => ins[app][index],
            Var::Output { app, index } => outs[app][index],
            Var::Free(k) => frees[k],
        };
        for c in conj {
            let row: Vec<_> = c.expr.terms.iter().map(|(v, a)| (col(*v), *a)).collect();
            match c.cmp {
                Cmp::Eq => pb.add_row(-c.expr.constant..=-c.expr.constant, row),
                Cmp::Le | Cmp::Lt => pb.add_row(..=-c.expr.constant, row),
            };
        }
        let mut model = pb.optimise(if sense == Sense::Max {
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
