//! Stages 3-4 of the reproduction: critical values of P1-P4 and the P5 robustness
//! tables, for samara's networks and the published ones.

use crate::common::{read_plain_csv, stage_err, METHODS, P1_TO_P4};
use crate::results::{
    reals, CriticalRow, P5Tables, Real, ReasonRow, Stages, VerifiedNetwork, VerifyResult,
};
use crate::{Ctx, ReproError};
use samara_nn::Network;
use samara_spec::normal::{Goal, LinExpr, Query, Sense, Var};
use samara_spec::{Bindings, Spec};
use samara_train::{read_table, with_units};
use samara_verify::robustness::{lipschitz_cell, published_cell, sweep, Reference};
use samara_verify::{optimise, Prepared, Settings};
use std::collections::HashMap;

pub(crate) const EPS: [f64; 4] = [1e-5, 1e-4, 1e-3, 1e-2];
pub(crate) const LS: [f64; 4] = [1e-5, 1e-4, 1e-3, 1e-2];

pub(crate) struct Subject {
    pub(crate) label: String,
    pub(crate) net: Network,
    /// The case-study spec, its network given this network's units and domain.
    pub(crate) spec: Spec,
    /// Body network and data rows in its (normalised) units, for P5.
    pub(crate) p5: Option<(Network, Vec<Vec<f64>>)>,
    pub(crate) raw_controller: Option<Network>,
}

/// The train stage's box of the data and the min-max constants the networks were
/// trained in (the verify, flights and reach stages need the train stage first).
pub(crate) fn subjects(ctx: &Ctx, st: &Stages) -> Result<Vec<Subject>, ReproError> {
    let mut v = Vec::new();
    let tr = st
        .train
        .as_ref()
        .ok_or_else(|| stage_err("verify", "the train stage has not run"))?;
    let f = |r: &[Real]| r.iter().map(|x| x.0).collect::<Vec<f64>>();
    let (lo, hi, nmin, nrange) = (
        f(&tr.domain_lo),
        f(&tr.domain_hi),
        f(&tr.norm_min),
        f(&tr.norm_range),
    );
    let spec = ctx.spec();
    // samara's networks take raw units (their normalisation is inside the file); their
    // domain is the box of the data they were trained on.
    let domain: Vec<(f64, f64)> = lo.iter().cloned().zip(hi.iter().cloned()).collect();
    let data =
        read_table(&ctx.path("data/training_data.csv")).map_err(|e| stage_err("verify", e))?;
    let rows_norm: Vec<Vec<f64>> = (0..data.rows())
        .map(|i| {
            data.row(i)
                .iter()
                .enumerate()
                .map(|(j, x)| (x - nmin[j]) / nrange[j])
                .collect()
        })
        .collect();
    for m in METHODS {
        let net = samara_nn::onnx::load(ctx.path(&format!("networks/{m}.onnx")))
            .map_err(|e| stage_err("verify", e))?;
        let body = Network {
            input_norm: None,
            output_denorm: None,
            ..net.clone()
        };
        v.push(Subject {
            label: format!("samara {m}"),
            net: net.clone(),
            spec: with_units(spec, None, None, Some(domain.clone())),
            p5: Some((body, rows_norm.clone())),
            raw_controller: Some(net),
        });
    }
    if let Some(dir) = &ctx.opts.published {
        let pdata = read_plain_csv(&dir.join("Training_Data_Normalised.csv"))
            .map_err(|e| stage_err("verify", e))?;
        for name in [
            "base_model_norm",
            "adversarial_model_norm",
            "base_model_denorm",
            "adversarial_model_denorm",
        ] {
            let net = samara_nn::onnx::load(dir.join(format!("{name}.onnx")))
                .map_err(|e| stage_err("verify", e))?;
            let norm = !name.contains("denorm");
            v.push(Subject {
                label: format!("published {name}"),
                net: net.clone(),
                // The published normalised networks have the spec's units; the
                // denormalised ones take raw units over the same domain.
                spec: if norm {
                    spec.clone()
                } else {
                    with_units(spec, None, None, None)
                },
                p5: if norm {
                    Some((net.clone(), pdata.clone()))
                } else {
                    None
                },
                raw_controller: if norm { None } else { Some(net) },
            });
        }
    }
    Ok(v)
}

/// The critical query of `ystar` for a property the spec lowers, and whether the
/// property holds above (`Max`: the supremum of counterexample values) or below (`Min`:
/// the infimum) it. The direction comes from the lowering: every constraint on the
/// parameter bounds it from one side, so the counterexample set is monotone in it.
/// When one constraint alone mentions the parameter (`ystar <= e(x)` or `ystar >=
/// e(x)`), the parameter is eliminated and `e` optimised directly: the critical value is
/// the network's, not clipped to the parameter's declared range.
pub fn critical_query(spec: &Spec, property: &str, param: &str) -> Result<Query, String> {
    let inst = spec
        .lower_critical(property, param, &Bindings::default())
        .map_err(|e| e.to_string())?;
    let [inst] = inst.as_slice() else {
        return Err(format!(
            "`{property}` has {} instances; critical values need one",
            inst.len()
        ));
    };
    let mut q = inst.query.clone();
    let Goal::Optimise { objective, .. } = &q.goal else {
        return Err(format!("`{property}`: not an optimisation"));
    };
    let [(Var::Free(p), one)] = objective.terms.as_slice() else {
        return Err(format!("`{property}`: the objective is not the parameter"));
    };
    let (p, one) = (*p, *one);
    let coef = |c: &samara_spec::normal::Constraint| -> f64 {
        c.expr
            .terms
            .iter()
            .filter(|(v, _)| *v == Var::Free(p))
            .map(|(_, k)| k)
            .sum()
    };
    let signs: Vec<f64> = q
        .region
        .iter()
        .flatten()
        .map(coef)
        .filter(|k| *k != 0.0)
        .collect();
    let sense = if !signs.is_empty() && signs.iter().all(|k| *k > 0.0) {
        Sense::Max
    } else if !signs.is_empty() && signs.iter().all(|k| *k < 0.0) {
        Sense::Min
    } else {
        return Err(format!("`{property}` is not monotone in `{param}`"));
    };
    let label = param.to_string();
    if q.region.len() == 1 && signs.len() == 1 && one == 1.0 {
        let conj = &mut q.region[0];
        let at = conj.iter().position(|c| coef(c) != 0.0).expect("one");
        let c = conj.remove(at);
        let k = coef(&c);
        // k ystar + rest (<=|<) 0  =>  ystar bounded by -rest / k.
        let objective = LinExpr {
            terms: c
                .expr
                .terms
                .iter()
                .filter(|(v, _)| *v != Var::Free(p))
                .map(|(v, a)| (*v, -a / k))
                .collect(),
            constant: -c.expr.constant / k,
        }
        .normalised();
        if p + 1 == q.free_vars.len() {
            q.free_vars.pop();
        }
        q.goal = Goal::Optimise {
            objective,
            sense,
            label,
        };
    } else if let Goal::Optimise { sense: s, .. } = &mut q.goal {
        *s = sense;
    }
    Ok(q)
}

/// The critical values of P1-P4 as the spec states them, for the network `f` of `prep`,
/// as stored in results.json.
pub fn critical_values(
    spec: &Spec,
    prep: &Prepared,
    settings: &Settings,
) -> Result<Vec<CriticalRow>, String> {
    P1_TO_P4
        .iter()
        .map(|name| {
            let q = critical_query(spec, name, "ystar")?;
            let r = optimise(&q, prep, settings).map_err(|e| e.to_string())?;
            Ok(critical_row(name, &r))
        })
        .collect()
}

/// One critical value as stored in results.json: the search's value, bound, flags, and
/// why it is incomplete (`unknown_reason`, null for a complete search).
pub(crate) fn critical_row(property: &str, r: &samara_verify::Critical) -> CriticalRow {
    CriticalRow {
        attained: r.attained,
        bound: Real(r.bound),
        complete: r.complete,
        critical: Real::of(r.value),
        domain_extreme: Real::of(r.domain_extreme),
        property: property.to_string(),
        unknown_reason: r.unknown.as_ref().map(|u| ReasonRow {
            kind: u.kind().to_string(),
            message: u.to_string(),
        }),
        vacuous: r.vacuous,
    }
}

/// The report's cell for one critical value. Only a complete search makes a claim: an
/// incomplete one reads "unknown" with its reason, never "holds"; a value whose gap to
/// the sound bound is open shows both.
pub(crate) fn critical_cell(c: &CriticalRow) -> String {
    let value = c.critical.get();
    let bound = c.bound.get();
    if !c.complete {
        let why = match &c.unknown_reason {
            Some(r) => format!("{}: {}", r.kind, r.message),
            None => "search incomplete".into(),
        };
        let seen = match (value, bound) {
            (Some(v), Some(b)) => format!("; witness {v:.4}, bound {b:.4}"),
            (None, Some(b)) => format!("; no witness, bound {b:.4}"),
            _ => String::new(),
        };
        return format!("unknown ({why}){seen}");
    }
    match value {
        None => "holds for every ystar".into(),
        Some(v) if c.attained => format!("{v:.4}"),
        Some(v) => match bound {
            Some(b) => format!("{v:.4} (gap open: sound bound {b:.4})"),
            None => format!("{v:.4} (gap open)"),
        },
    }
}

/// Stage 4: critical values of P1-P4 and P5 tables, for every network.
pub fn verify(ctx: &Ctx, st: &mut Stages) -> Result<Vec<String>, ReproError> {
    let subs = subjects(ctx, st)?;
    let pb = ctx.bar(subs.len() as u64, "verification");
    let mut out = Vec::new();
    for s in &subs {
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), s.net.clone());
        let prep = Prepared::new(&nets);
        let t = std::time::Instant::now();
        let crit = critical_values(&s.spec, &prep, &Settings::default())
            .map_err(|e| stage_err("verify", e))?;
        let crit_secs = t.elapsed().as_secs_f64();
        let mut p5 = None;
        if let Some((body, rows)) = &s.p5 {
            let t = std::time::Instant::now();
            let lab = sweep(body, rows, &EPS, Reference::Label, None)
                .map_err(|e| stage_err("verify", e))?;
            let netref = sweep(body, rows, &EPS, Reference::Network, None)
                .map_err(|e| stage_err("verify", e))?;
            let cells =
                |f: &dyn Fn(f64, f64) -> samara_verify::robustness::Cell| -> Vec<Vec<Real>> {
                    EPS.iter()
                        .map(|e| {
                            LS.iter()
                                .map(|l| Real(f(*e, *l).proved as f64 / rows.len() as f64))
                                .collect()
                        })
                        .collect()
                };
            let label_gap = rows
                .iter()
                .map(|r| (body.eval_f64(&r[..6])[0] - r[6]).abs())
                .fold(0.0, f64::max);
            p5 = Some(P5Tables {
                lipschitz: cells(&|e, l| lipschitz_cell(&netref, e, l)),
                lipschitz_unknown: EPS
                    .iter()
                    .map(|e| {
                        LS.iter()
                            .map(|l| lipschitz_cell(&netref, *e, *l).unknown)
                            .collect()
                    })
                    .collect(),
                max_label_gap: Real(label_gap),
                points: rows.len(),
                published_label: cells(&|e, l| published_cell(&lab, e, l)),
                published_network: cells(&|e, l| published_cell(&netref, e, l)),
                seconds: Real(t.elapsed().as_secs_f64()),
            });
        }
        out.push(VerifiedNetwork {
            critical: crit,
            critical_seconds: Real(crit_secs),
            network: s.label.clone(),
            p5,
        });
        pb.inc(1);
    }
    pb.finish_and_clear();
    st.verify = Some(VerifyResult {
        l: reals(&LS),
        eps: reals(&EPS),
        networks: out,
    });
    Ok(vec![])
}
