//! Stages 2-5 of the reproduction: training, verification (critical values and P5
//! tables, for samara's networks and the published ones), closed-loop flights, and their
//! report sections and computed findings.

use crate::doc::{Block, Document};
use crate::stages::{f4, flights_figure, read_plain_csv, stage_err};
use crate::{table, Ctx, ReproError, StageOutput};
use samara_nn::Network;
use samara_plant::{Model, Plant};
use samara_sim::{
    fly, initial_state, published_starts, LoopSettings, NetworkController, PidController,
};
use samara_spec::normal::{Goal, LinExpr, Query, Sense, Var};
use samara_spec::{Bindings, Spec};
use samara_train::{
    from_query, read_table, spec_properties, train as train_net, train_closed_loop, with_units,
    Attack, CegisOptions, Logic, Method, MinMax, Property, TrainOptions,
};
use samara_verify::robustness::{lipschitz_cell, published_cell, sweep, Reference};
use samara_verify::{optimise, Prepared, Settings};
use serde::Deserialize;
use serde_json::{json, Value};
use std::collections::HashMap;

const METHODS: [&str; 6] = [
    "plain",
    "adversarial",
    "lipschitz",
    "dl2",
    "goedel",
    "closed-loop",
];
/// The spec's global properties, verified by critical values and trained for by DL2 and
/// Goedel.
const P1_TO_P4: [&str; 4] = ["p1", "p2", "p3", "p4"];
const EPS: [f64; 4] = [1e-5, 1e-4, 1e-3, 1e-2];
const LS: [f64; 4] = [1e-5, 1e-4, 1e-3, 1e-2];
/// R^2 of a raw-unit network against every row of `data` (raw units).
fn r2_all(net: &Network, data: &samara_train::Table) -> f64 {
    r2_rows(net, data, &(0..data.rows()).collect::<Vec<_>>()).0
}

/// R^2 and RMSE of a raw-unit network against the rows `idx` of `data` (raw units).
fn r2_rows(net: &Network, data: &samara_train::Table, idx: &[usize]) -> (f64, f64) {
    let n = idx.len() as f64;
    let mean = idx.iter().map(|&i| data.row(i)[6]).sum::<f64>() / n;
    let (mut sse, mut sst) = (0.0, 0.0);
    for &i in idx {
        let r = data.row(i);
        sse += (net.eval_f64(&r[..6])[0] - r[6]).powi(2);
        sst += (r[6] - mean).powi(2);
    }
    (1.0 - sse / sst, (sse / n).sqrt())
}

/// Stage 2: train the six controllers on the regenerated data: the five data-driven
/// methods, and the closed-loop method (issue 18) with its reach rounds.
pub fn train(ctx: &Ctx, _up: &Value) -> Result<StageOutput, ReproError> {
    let data =
        read_table(&ctx.path("data/training_data.csv")).map_err(|e| stage_err("train", e))?;
    let mm = MinMax::of(&data);
    let lo = mm.min[..6].to_vec();
    let hi: Vec<f64> = (0..6).map(|j| mm.min[j] + mm.range[j]).collect();
    let props =
        training_properties(ctx.spec(), &mm, &lo, &hi).map_err(|e| stage_err("train", e))?;
    let epochs = if ctx.opts.quick { 200 } else { 1000 };
    let pb = ctx.bar(METHODS.len() as u64, "training controllers");
    let mut rows = Vec::new();
    let mut files = Vec::new();
    let mut cegis = Value::Null;
    for m in METHODS {
        if m == "closed-loop" {
            let (row, extra, figs) = train_closed_loop_stage(ctx, &data, &mm, epochs)?;
            rows.push(row);
            cegis = extra;
            files.extend(figs);
            pb.inc(1);
            continue;
        }
        let method = match m {
            "plain" => Method::Plain,
            "adversarial" => Method::Adversarial(Attack::Fgsm),
            "lipschitz" => Method::Lipschitz {
                l: 0.5,
                weight: 10.0,
            },
            "dl2" => Method::Properties {
                logic: Logic::Dl2,
                props: props.clone(),
                weight: 1.0,
            },
            _ => Method::Properties {
                logic: Logic::Goedel,
                props: props.clone(),
                weight: 1.0,
            },
        };
        let o = TrainOptions {
            epochs,
            method,
            ..Default::default()
        };
        let t = std::time::Instant::now();
        let out = train_net(&data, Some(&mm), &o).map_err(|e| stage_err("train", e))?;
        let secs = t.elapsed().as_secs_f64();
        let net = out
            .network
            .with_names(&samara_nn::STATE_INPUTS, &["ex"])
            .map_err(|e| stage_err("train", e))?;
        let rel = format!("networks/{m}.onnx");
        samara_nn::onnx::save(&net, ctx.path(&rel), &Default::default())
            .map_err(|e| stage_err("train", e))?;
        files.push(rel.clone());
        let k = &out.metrics;
        rows.push(json!({"method": m, "file": rel, "r2": k.r2, "r2_all": r2_all(&net, &data), "rmse": k.rmse, "mae": k.mae,
            "attack_worst": k.attack_worst, "attack_mean": k.attack_mean, "eps": o.eps, "epochs": epochs, "seconds": secs}));
        pb.inc(1);
    }
    pb.finish_and_clear();
    Ok(StageOutput {
        result: json!({"networks": rows, "closed_loop": cegis, "domain_lo": lo, "domain_hi": hi, "norm_min": mm.min, "norm_range": mm.range}),
        files,
    })
}

/// P1-P4 as `spec` states them (`ystar` at its default), lowered in the trainer's
/// min-max units `mm` over the raw box `[lo, hi]` of the regenerated data: the DL2 and
/// Goedel constraints of the train stage.
fn training_properties(
    spec: &Spec,
    mm: &MinMax,
    lo: &[f64],
    hi: &[f64],
) -> Result<Vec<Property>, samara_train::SpecPropertyError> {
    spec_properties(
        spec,
        &P1_TO_P4.map(String::from),
        &Bindings::default(),
        mm,
        Some(lo.iter().cloned().zip(hi.iter().cloned()).collect()),
    )
}

/// Whether `spec` states what the stages lower: a first network with the six state
/// inputs and one output, and `p1`-`p4` both as critical-value queries over `ystar` (the
/// verify stage) and as training properties with `ystar` at its default (the train
/// stage). The message names the spec, and the place where the spec has one.
pub(crate) fn check_spec(spec: &Spec) -> Result<(), String> {
    let file = &spec.file;
    let Some(net) = spec.networks.first() else {
        return Err(format!(
            "{file}: declares no network; the reproduction needs `network f(v_xp, v_yp, omega, theta, x, y) -> (ex)`"
        ));
    };
    if net.inputs.len() != samara_nn::STATE_INPUTS.len() || net.outputs.len() != 1 {
        return Err(format!(
            "{file}: network `{}` takes {} inputs and gives {} outputs; the reproduction's controllers take the six states (v_xp, v_yp, omega, theta, x, y) and give one output (ex)",
            net.name,
            net.inputs.len(),
            net.outputs.len()
        ));
    }
    const TRAIN: &str =
        "the reproduction's DL2/Goedel training lowers p1-p4 with `ystar` at its default";
    let note = |e: &str, why: &str| format!("{}\n  = note: {why}", e.trim_end());
    for name in P1_TO_P4 {
        critical_query(spec, name, "ystar").map_err(|e| {
            note(
                &e,
                "the reproduction computes the critical value of `ystar` for each of p1-p4",
            )
        })?;
        let insts = spec
            .lower_prove(name, &Bindings::default())
            .map_err(|e| note(&e.to_string(), TRAIN))?;
        for inst in insts {
            from_query(&inst.query).map_err(|e| note(&format!("{file}: {e}"), TRAIN))?;
        }
    }
    Ok(())
}

/// The closed-loop method: data-only training of `epochs`, then train-and-reach rounds
/// (the reach budget of a round is the quick reproduction's: 16 sub-boxes, 50 samples).
/// Returns its row of the training table, its rounds, and the files written.
fn train_closed_loop_stage(
    ctx: &Ctx,
    data: &samara_train::Table,
    mm: &MinMax,
    epochs: usize,
) -> Result<(Value, Value, Vec<String>), ReproError> {
    let o = CegisOptions {
        pretrain: TrainOptions {
            epochs,
            min_r2: 0.9,
            ..Default::default()
        },
        ..Default::default()
    };
    let t = std::time::Instant::now();
    let out = train_closed_loop(data, Some(mm), &o).map_err(|e| stage_err("train", e))?;
    let secs = t.elapsed().as_secs_f64();
    let net = out.network.clone();
    let rel = "networks/closed-loop.onnx".to_string();
    samara_nn::onnx::save(&net, ctx.path(&rel), &Default::default())
        .map_err(|e| stage_err("train", e))?;
    let (png, svg) = (
        "figures/closed_loop_rounds.png".to_string(),
        "figures/closed_loop_rounds.svg".to_string(),
    );
    samara_train::cegis::rounds_figure(
        &out.rounds,
        o.goal,
        &format!(
            "closed-loop training rounds: |x + y| <= {} at t = 20, {}",
            o.goal,
            if out.proved { "proved" } else { "not proved" }
        ),
        &ctx.path(&png),
        &ctx.path(&svg),
    )
    .map_err(|e| stage_err("train", e))?;
    let rounds: Vec<Value> = out
        .rounds
        .iter()
        .map(|r| {
            json!({"round": r.round, "steps": r.steps, "loss": r.loss, "mse": r.mse,
                "penalty": r.penalty, "r2": r.r2, "starts": r.starts, "verdict": r.verdict,
                "enclosure": r.enclosure, "sampled": r.sampled, "max_leaves": r.max_leaves,
                "added": r.added, "seconds": r.train_seconds + r.reach_seconds})
        })
        .collect();
    // Test R^2 on the rows the data-only training held out (its split, seed 0).
    let (_, test) =
        samara_train::data::split(data.rows(), o.pretrain.test_fraction, o.pretrain.seed);
    let (r2_test, rmse_test) = r2_rows(&net, data, &test);
    let row = json!({"method": "closed-loop", "file": rel, "r2": r2_test, "r2_all": out.r2,
        "rmse": rmse_test, "mae": Value::Null, "attack_worst": Value::Null,
        "attack_mean": Value::Null, "eps": Value::Null, "epochs": epochs, "seconds": secs});
    let extra = json!({"proved": out.proved, "verdict": out.reach.verdict.name(),
        "enclosure": out.reach.final_x_plus_y, "r2_all": out.r2, "rounds": rounds,
        "goal_ystar": o.goal, "training_bound": o.loss.bound, "data_weight": o.data_weight,
        "steps_per_round": o.steps_per_round, "seconds": secs, "figure": png});
    Ok((row, extra, vec![rel, png, svg]))
}

struct Subject {
    label: String,
    net: Network,
    /// The case-study spec, its network given this network's units and domain.
    spec: Spec,
    /// Body network and data rows in its (normalised) units, for P5.
    p5: Option<(Network, Vec<Vec<f64>>)>,
    raw_controller: Option<Network>,
}

/// What the verify stage takes from the train stage's result: the data's box and the
/// min-max constants the networks were trained in (read once, as one struct).
#[derive(serde::Deserialize)]
struct TrainUnits {
    domain_lo: Vec<f64>,
    domain_hi: Vec<f64>,
    norm_min: Vec<f64>,
    norm_range: Vec<f64>,
}

fn subjects(ctx: &Ctx, up: &Value) -> Result<Vec<Subject>, ReproError> {
    let mut v = Vec::new();
    let TrainUnits {
        domain_lo: lo,
        domain_hi: hi,
        norm_min: nmin,
        norm_range: nrange,
    } = TrainUnits::deserialize(&up["train"]).map_err(|e| stage_err("verify", e))?;
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
) -> Result<Vec<Value>, String> {
    P1_TO_P4
        .iter()
        .map(|name| {
            let q = critical_query(spec, name, "ystar")?;
            let r = optimise(&q, prep, settings).map_err(|e| e.to_string())?;
            Ok(critical_json(name, &r))
        })
        .collect()
}

/// One critical value as stored in results.json: the search's value, bound, flags, and
/// why it is incomplete (`unknown_reason`, null for a complete search).
fn critical_json(property: &str, r: &samara_verify::Critical) -> Value {
    json!({"property": property, "critical": r.value, "bound": r.bound, "attained": r.attained,
        "vacuous": r.vacuous, "domain_extreme": r.domain_extreme, "complete": r.complete,
        "unknown_reason": r.unknown.as_ref().map(|u| json!({"kind": u.kind(), "message": u.to_string()}))})
}

/// The report's cell for one critical value. Only a complete search makes a claim: an
/// incomplete one (or a result without `complete`) reads "unknown" with its reason,
/// never "holds"; a value whose gap to the sound bound is open shows both.
fn critical_cell(c: &Value) -> String {
    let value = c["critical"].as_f64();
    let bound = c["bound"].as_f64();
    if c["complete"].as_bool() != Some(true) {
        let reason = &c["unknown_reason"];
        let why = match (reason["kind"].as_str(), reason["message"].as_str()) {
            (Some(k), Some(m)) => format!("{k}: {m}"),
            _ => "search incomplete".into(),
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
        Some(v) if c["attained"].as_bool() == Some(true) => format!("{v:.4}"),
        Some(v) => match bound {
            Some(b) => format!("{v:.4} (gap open: sound bound {b:.4})"),
            None => format!("{v:.4} (gap open)"),
        },
    }
}

/// Stage 4: critical values of P1-P4 and P5 tables, for every network.
pub fn verify(ctx: &Ctx, up: &Value) -> Result<StageOutput, ReproError> {
    let subs = subjects(ctx, up)?;
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
        let mut p5 = Value::Null;
        if let Some((body, rows)) = &s.p5 {
            let t = std::time::Instant::now();
            let lab = sweep(body, rows, &EPS, Reference::Label, None)
                .map_err(|e| stage_err("verify", e))?;
            let netref = sweep(body, rows, &EPS, Reference::Network, None)
                .map_err(|e| stage_err("verify", e))?;
            let cells = |f: &dyn Fn(f64, f64) -> samara_verify::robustness::Cell| -> Vec<Vec<f64>> {
                EPS.iter()
                    .map(|e| {
                        LS.iter()
                            .map(|l| f(*e, *l).proved as f64 / rows.len() as f64)
                            .collect()
                    })
                    .collect()
            };
            let label_gap = rows
                .iter()
                .map(|r| (body.eval_f64(&r[..6])[0] - r[6]).abs())
                .fold(0.0, f64::max);
            p5 = json!({
                "points": rows.len(),
                "published_label": cells(&|e, l| published_cell(&lab, e, l)),
                "published_network": cells(&|e, l| published_cell(&netref, e, l)),
                "lipschitz": cells(&|e, l| lipschitz_cell(&netref, e, l)),
                "lipschitz_unknown": EPS.iter().map(|e| LS.iter().map(|l| lipschitz_cell(&netref, *e, *l).unknown).collect::<Vec<_>>()).collect::<Vec<_>>(),
                "max_label_gap": label_gap,
                "seconds": t.elapsed().as_secs_f64(),
            });
        }
        out.push(
            json!({"network": s.label, "critical": crit, "critical_seconds": crit_secs, "p5": p5}),
        );
        pb.inc(1);
    }
    pb.finish_and_clear();
    Ok(StageOutput {
        result: json!({"networks": out, "eps": EPS, "L": LS}),
        files: vec![],
    })
}

/// Stage 5: every controller flown in the closed loop (plate6, ode45, clipped).
pub fn closed_loop(ctx: &Ctx, up: &Value) -> Result<StageOutput, ReproError> {
    let subs = subjects(ctx, up)?;
    let plant = Plant::new(Model::Plate6);
    let settings = LoopSettings::default();
    let mut out = Vec::new();
    let mut figure_flights = Vec::new();
    let mid = published_starts()[4];
    let mut pid = PidController::default();
    figure_flights.push(
        fly(&plant, &mut pid, &initial_state(&plant, mid), &settings)
            .map_err(|e| stage_err("closed_loop", e))?,
    );
    let mut labels = vec!["PID".to_string()];
    for s in subs.iter().filter(|s| s.raw_controller.is_some()) {
        let mut c = NetworkController::new(
            s.raw_controller.clone().expect("filtered"),
            Some((0.181, 0.193)),
            s.label.clone(),
        );
        let mut finals = Vec::new();
        for y0 in published_starts() {
            let f = fly(&plant, &mut c, &initial_state(&plant, y0), &settings)
                .map_err(|e| stage_err("closed_loop", e))?;
            let st = &f.steps.last().expect("steps").state_end;
            finals.push(st[4] + st[5]);
            if y0 == mid {
                figure_flights.push(f);
                labels.push(s.label.clone());
            }
        }
        out.push(json!({"controller": s.label, "final_x_plus_y": finals,
            "worst": finals.iter().map(|v| v.abs()).fold(0.0, f64::max)}));
    }
    let mut fig = flights_figure(
        &format!("Closed loop from y0 = {mid:.4} (plate6, clipped controllers)"),
        &figure_flights,
        Some(2.0),
    );
    for (c, l) in fig.curves.iter_mut().zip(&labels) {
        c.label = l.clone();
    }
    fig.render(
        &ctx.path("figures/closed_loop.png"),
        &ctx.path("figures/closed_loop.svg"),
    )
    .map_err(|e| stage_err("closed_loop", e))?;
    Ok(StageOutput {
        result: json!({"controllers": out, "starts": published_starts()}),
        files: vec![
            "figures/closed_loop.png".into(),
            "figures/closed_loop.svg".into(),
        ],
    })
}

/// Stage 6: sound reachable sets of every raw-unit controller (reduced model, the
/// published interval of y0, clipped as in simulation) with the goal |x + y| <= 2 at
/// t = 20: verdict, width against the sampled range, figure.
pub fn reach(ctx: &Ctx, up: &Value) -> Result<StageOutput, ReproError> {
    let subs = subjects(ctx, up)?;
    let subs: Vec<&Subject> = subs.iter().filter(|s| s.raw_controller.is_some()).collect();
    let pb = ctx.bar(subs.len() as u64, "reachability");
    let mut out = Vec::new();
    let mut files = Vec::new();
    for (i, s) in subs.iter().enumerate() {
        let net = s.raw_controller.as_ref().expect("filtered");
        let mut rs = samara_reach::ReachSettings::published(Model::Reduced);
        rs.goal = Some(samara_reach::Goal {
            ystar: 2.0,
            from: None,
        });
        if ctx.opts.quick {
            rs.max_leaves = 16;
            rs.samples = 50;
        }
        let r = samara_reach::reach(net, &rs).map_err(|e| stage_err("reach", e))?;
        let png = format!("figures/reach_{i}.png");
        let svg = format!("figures/reach_{i}.svg");
        samara_report::reach::figure(&r, &format!("{}, reduced model", s.label), Some(2.0))
            .render(&ctx.path(&png), &ctx.path(&svg))
            .map_err(|e| stage_err("reach", e))?;
        let reason = r.verdict.reason();
        let stopped: Vec<f64> = r
            .leaves
            .iter()
            .filter(|l| l.failure.is_some())
            .filter_map(|l| l.steps.last().map(|st| st.t))
            .collect();
        out.push(json!({
            "controller": s.label,
            "stopped": stopped.len(),
            "stopped_at": stopped.iter().cloned().fold(f64::INFINITY, f64::min),
            "verdict": r.verdict.name(),
            "reason": reason,
            "final_x_plus_y": r.final_x_plus_y,
            "sampled_x_plus_y": r.sampled_x_plus_y,
            "ratio": r.width_ratio(),
            "subproblems": r.subproblems(),
            "seconds": r.seconds,
            "figure": png,
        }));
        files.push(png);
        files.push(svg);
        pb.inc(1);
    }
    pb.finish_and_clear();
    Ok(StageOutput {
        result: json!({"networks": out, "model": "reduced", "y0": [0.1 / 0.07, 0.3 / 0.07],
            "horizon": 20.0, "goal_ystar": 2.0}),
        files,
    })
}

/// The closed-loop method's rounds (issue 18 item 2).
fn closed_loop_section(cl: &Value, d: &mut Document) {
    d.push(Block::Heading(
        2,
        "2b. Closed-loop training (samara closed-loop)".into(),
    ));
    d.push(Block::Para(format!(
        "The plain network is trained on through the closed loop: each round takes up to {} full-batch Adam steps on {} x the data MSE plus the mean of max(0, |x + y|(20) - {})^2 over a set of flights of the reduced model (sample-and-hold, RK4, output clipped), differentiated through the loop; then `samara reach` checks |x + y| <= {} at t = 20 over y0 in [1.4286, 4.2857] (16 sub-boxes, 64 when undecided), and the starts of violating trajectories and of refuted or undecided sub-boxes join the flight set for the next round. Result: {} (x + y at t = 20 in [{}, {}]), R^2 {} against every PID data row, {:.1} s.",
        cl["steps_per_round"],
        cl["data_weight"],
        cl["training_bound"],
        cl["goal_ystar"],
        cl["verdict"].as_str().unwrap_or("?"),
        f4(&cl["enclosure"][0]),
        f4(&cl["enclosure"][1]),
        f4(&cl["r2_all"]),
        cl["seconds"].as_f64().unwrap_or(0.0)
    )));
    let rows = cl["rounds"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|r| {
            vec![
                r["round"].to_string(),
                r["steps"].to_string(),
                r["starts"].to_string(),
                format!("{:.3e}", r["loss"].as_f64().unwrap_or(f64::NAN)),
                f4(&r["r2"]),
                r["verdict"].as_str().unwrap_or("").to_string(),
                if r["enclosure"][0].is_null() {
                    "lost".into()
                } else {
                    format!("[{}, {}]", f4(&r["enclosure"][0]), f4(&r["enclosure"][1]))
                },
                r["max_leaves"].to_string(),
                r["added"]
                    .as_array()
                    .map(|a| a.len())
                    .unwrap_or(0)
                    .to_string(),
                format!("{:.1}", r["seconds"].as_f64().unwrap_or(0.0)),
            ]
        })
        .collect();
    d.push(table(
        &[
            "round",
            "Adam steps",
            "flights",
            "loss",
            "R^2 (all PID rows)",
            "reach verdict",
            "x + y at t = 20 (enclosure)",
            "sub-boxes",
            "starts added",
            "seconds",
        ],
        rows,
    ));
    if let Some(p) = cl["figure"].as_str() {
        d.push(Block::Image {
            path: p.to_string(),
            caption: "Closed-loop training rounds: reach's enclosure of x + y at t = 20, the sampled range and the goal band".into(),
        });
    }
}

fn pct(v: &Value) -> String {
    v.as_f64()
        .map(|x| format!("{:.1}%", 100.0 * x))
        .unwrap_or_else(|| "-".into())
}

/// Report sections 2-6 and the findings they support.
pub fn report(st: &Value, d: &mut Document, findings: &mut Vec<String>) {
    if let Some(tr) = st.get("train") {
        d.push(Block::Heading(1, "2. Controllers trained by samara".into()));
        d.push(Block::Para("6-6-4-1 ReLU networks (ReLU on every layer), Adam lr 0.06, batch 50, 10% test split, seed 0; worst deviation found by a PGD attack within eps = 0.005 (normalised inputs) on the test points, in ex units.".into()));
        let rows = tr["networks"]
            .as_array()
            .map(|a| {
                a.iter()
                    .map(|n| {
                        vec![
                            n["method"].as_str().unwrap_or("").to_string(),
                            f4(&n["r2"]),
                            f4(&n["r2_all"]),
                            format!("{:.2e}", n["rmse"].as_f64().unwrap_or(f64::NAN)),
                            n["attack_worst"]
                                .as_f64()
                                .map(|v| format!("{v:.2e}"))
                                .unwrap_or_else(|| "-".into()),
                            format!("{:.2}", n["seconds"].as_f64().unwrap_or(0.0)),
                        ]
                    })
                    .collect()
            })
            .unwrap_or_default();
        d.push(table(
            &[
                "method",
                "test R^2",
                "R^2 (all PID rows)",
                "RMSE (ex)",
                "worst attack deviation (ex)",
                "seconds",
            ],
            rows,
        ));
    }
    if let Some(cl) = st
        .get("train")
        .map(|t| &t["closed_loop"])
        .filter(|v| !v.is_null())
    {
        closed_loop_section(cl, d);
    }
    if let Some(v) = st.get("verify") {
        d.push(Block::Heading(
            1,
            "3-4. Verification: critical values of P1-P4".into(),
        ));
        d.push(Block::Para("P1 and P2 hold for ystar above the critical value, P3 and P4 below it. Each value is one exact optimisation (branch and bound with sound LP bounds), reported with a concrete witness; `vacuous` marks a threshold that equals the extreme of x + y over the input box, where the property's precondition is empty; \"holds for every ystar\" means a complete search found the counterexample region empty for every value; \"unknown\" marks a search cut short (time or node limit), with its reason, and makes no claim; an open gap between the witness value and the sound bound is shown as both.".into()));
        let mut rows = Vec::new();
        let mut vac: Vec<String> = Vec::new();
        for n in v["networks"].as_array().into_iter().flatten() {
            let mut row = vec![n["network"].as_str().unwrap_or("").to_string()];
            for c in n["critical"].as_array().into_iter().flatten() {
                let val = critical_cell(c);
                let v =
                    c["complete"].as_bool() == Some(true) && c["vacuous"].as_bool() == Some(true);
                if v {
                    vac.push(format!(
                        "{} {}",
                        n["network"].as_str().unwrap_or(""),
                        c["property"].as_str().unwrap_or("")
                    ));
                }
                row.push(if v { format!("{val} (vacuous)") } else { val });
            }
            row.push(format!(
                "{:.3}",
                n["critical_seconds"].as_f64().unwrap_or(0.0)
            ));
            rows.push(row);
        }
        d.push(table(
            &[
                "network",
                "P1 ystar >",
                "P2 ystar >",
                "P3 ystar <",
                "P4 ystar <",
                "seconds",
            ],
            rows,
        ));
        if !vac.is_empty() {
            findings.push(format!(
                "{} of the thresholds computed hold only vacuously (the critical value is the extreme of x + y over the input box, so the property's precondition is empty where it holds): {}.",
                vac.len(),
                vac.join("; ")
            ));
        }
        d.push(Block::Heading(1, "4. Local robustness (P5)".into()));
        for n in v["networks"].as_array().into_iter().flatten() {
            let p5 = &n["p5"];
            if p5.is_null() {
                continue;
            }
            for (key, title) in [
                (
                    "published_label",
                    "published form |f(x') - label| <= L / eps",
                ),
                ("published_network", "published form with f(x) as reference"),
                (
                    "lipschitz",
                    "intended form |f(x') - f(x)| <= L ||x' - x||_inf (proved share)",
                ),
            ] {
                let rows: Vec<Vec<String>> = EPS
                    .iter()
                    .enumerate()
                    .map(|(i, e)| {
                        std::iter::once(format!("{e:.0e}"))
                            .chain((0..LS.len()).map(|j| pct(&p5[key][i][j])))
                            .collect()
                    })
                    .collect();
                d.push(Block::Para(format!(
                    "{}: {title}, {} points, success rate (rows eps, columns L):",
                    n["network"].as_str().unwrap_or(""),
                    p5["points"]
                )));
                d.push(table(&["eps \\ L", "1e-5", "1e-4", "1e-3", "1e-2"], rows));
            }
        }
        // Findings on P5, from the first network with tables.
        if let Some(n) = v["networks"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|n| {
                !n["p5"].is_null()
                    && n["network"]
                        .as_str()
                        .is_some_and(|s| s.starts_with("published"))
            })
            .or_else(|| {
                v["networks"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .find(|n| !n["p5"].is_null())
            })
        {
            let p5 = &n["p5"];
            let name = n["network"].as_str().unwrap_or("");
            findings.push(format!(
                "The published P5 bounds the deviation by L/eps, which grows as the ball shrinks: at eps = L = 1e-5 the admissible deviation is 1, the whole normalised output range, so its {} success rate ({name}) says nothing; the intended local-Lipschitz form |f(x') - f(x)| <= L ||x' - x||, checked exactly, holds at {} of the points in that cell and {} at eps = 1e-2, L = 1e-2.",
                pct(&p5["published_label"][0][0]),
                pct(&p5["lipschitz"][0][0]),
                pct(&p5["lipschitz"][3][3])
            ));
            findings.push(format!(
                "The published P5 compares f(x') with the data label, not with f(x): {name} already misses the labels by up to {:.3} (normalised output units), so at eps = 1e-2, L = 1e-4 the label form holds at {} of the points against {} with f(x) as reference; the label form measures accuracy as much as robustness.",
                p5["max_label_gap"].as_f64().unwrap_or(f64::NAN),
                pct(&p5["published_label"][3][1]),
                pct(&p5["published_network"][3][1])
            ));
        }
    }
    if let Some(cl) = st.get("closed_loop") {
        d.push(Block::Heading(1, "5. Closed-loop flights".into()));
        d.push(Block::Para("Every raw-unit controller flown from the nine published starts (plate6 model, MATLAB-ode45-compatible integration, output clipped to [0.181, 0.193]); x + y at t = 20.".into()));
        let rows = cl["controllers"]
            .as_array()
            .map(|a| {
                a.iter()
                    .map(|c| {
                        let mut r = vec![c["controller"].as_str().unwrap_or("").to_string()];
                        r.extend(c["final_x_plus_y"].as_array().into_iter().flatten().map(f4));
                        r
                    })
                    .collect()
            })
            .unwrap_or_default();
        let starts: Vec<String> = cl["starts"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|v| format!("y0={}", f4(v)))
            .collect();
        let mut header = vec!["controller"];
        header.extend(starts.iter().map(String::as_str));
        d.push(table(&header, rows));
        d.push(Block::Image {
            path: "figures/closed_loop.png".into(),
            caption: "Closed-loop flights from the middle start, with the band |x + y| <= 2".into(),
        });
        let worst: Vec<String> = cl["controllers"]
            .as_array()
            .into_iter()
            .flatten()
            .filter(|c| c["worst"].as_f64().is_some_and(|w| w > 2.0))
            .map(|c| {
                format!(
                    "{} ({:.2})",
                    c["controller"].as_str().unwrap_or(""),
                    c["worst"].as_f64().unwrap_or(0.0)
                )
            })
            .collect();
        if !worst.is_empty() {
            findings.push(format!(
                "Simulation alone already refutes the goal |x + y| <= 2 at t = 20 for: {} (largest |x + y| over the nine starts in brackets).",
                worst.join(", ")
            ));
        }
    }
    d.push(Block::Heading(1, "6. Reachability".into()));
    match st.get("reach") {
        None => d.push(Block::Para("The reachability stage has not run.".into())),
        Some(rc) => {
            d.push(Block::Para("Sound reachable sets (validated Taylor integration on zonotopes, network bounded by CROWN over each set, outward rounding) of the reduced model, the model the published CORA analysis used, from y0 in [1.4286, 4.2857] with the other states at (1, 0, 0, 0, 0), horizon 20, period 0.5, controller output clipped to [0.181, 0.193] as in simulation. Goal: |x + y| <= 2 at t = 20. 'proved' holds for every start in the interval; 'violated' comes with a simulated trajectory; the ratio is the width of the enclosure of x + y at t = 20 over the range of the sampled trajectories.".into()));
            let nets: Vec<&Value> = rc["networks"].as_array().into_iter().flatten().collect();
            let rows = nets
                .iter()
                .map(|n| {
                    let f = &n["final_x_plus_y"];
                    let enclosure = if n["stopped"].as_u64().unwrap_or(0) > 0 {
                        format!(
                            "not enclosed to t = 20: {} sub-boxes lost validation (first at t = {})",
                            n["stopped"],
                            f4(&n["stopped_at"])
                        )
                    } else {
                        format!("[{}, {}]", f4(&f[0]), f4(&f[1]))
                    };
                    vec![
                        n["controller"].as_str().unwrap_or("").to_string(),
                        n["verdict"].as_str().unwrap_or("").to_string(),
                        enclosure,
                        format!(
                            "[{}, {}]",
                            f4(&n["sampled_x_plus_y"][0]),
                            f4(&n["sampled_x_plus_y"][1])
                        ),
                        match n["ratio"].as_f64() {
                            Some(r) if r.is_finite() => format!("{r:.3}"),
                            _ => "-".into(),
                        },
                        n["subproblems"].to_string(),
                        format!("{:.1}", n["seconds"].as_f64().unwrap_or(0.0)),
                    ]
                })
                .collect();
            d.push(table(
                &[
                    "controller",
                    "verdict",
                    "x + y at t = 20 (enclosure)",
                    "sampled range",
                    "ratio",
                    "sub-boxes",
                    "seconds",
                ],
                rows,
            ));
            for n in &nets {
                if let Some(p) = n["figure"].as_str() {
                    d.push(Block::Image {
                        path: p.to_string(),
                        caption: format!(
                            "Reachable sets of {} (boxes at the control instants), sampled trajectories, the band |x + y| <= 2",
                            n["controller"].as_str().unwrap_or("")
                        ),
                    });
                }
            }
            let proved: Vec<&str> = nets
                .iter()
                .filter(|n| n["verdict"] == "proved")
                .filter_map(|n| n["controller"].as_str())
                .collect();
            let violated: Vec<&str> = nets
                .iter()
                .filter(|n| n["verdict"] == "violated")
                .filter_map(|n| n["controller"].as_str())
                .collect();
            let secs: f64 = nets.iter().filter_map(|n| n["seconds"].as_f64()).sum();
            let r2_of = |method: &str| {
                st["train"]["networks"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .find(|n| n["method"] == method)
                    .map(|n| f4(&n["r2_all"]))
                    .unwrap_or_else(|| "-".into())
            };
            let samara: Vec<(String, &Value)> = nets
                .iter()
                .filter_map(|n| {
                    n["controller"]
                        .as_str()
                        .and_then(|c| c.strip_prefix("samara "))
                        .map(|m| (m.to_string(), *n))
                })
                .collect();
            let proved_methods: Vec<String> = samara
                .iter()
                .filter(|(_, n)| n["verdict"] == "proved")
                .map(|(m, n)| {
                    format!(
                        "{m} (x + y at t = 20 in [{}, {}], R^2 {} against the PID data)",
                        f4(&n["final_x_plus_y"][0]),
                        f4(&n["final_x_plus_y"][1]),
                        r2_of(m)
                    )
                })
                .collect();
            let others: Vec<String> = samara
                .iter()
                .filter(|(_, n)| n["verdict"] != "proved")
                .map(|(m, n)| format!("{m} {}", n["verdict"].as_str().unwrap_or("?")))
                .collect();
            if !samara.is_empty() {
                findings.push(format!(
                    "Of samara's {} training methods, {} produced a controller that reach proves for |x + y| <= 2 at t = 20 over the whole published interval of y0 (reduced model, clipped): {}; the others: {}.",
                    samara.len(),
                    proved_methods.len(),
                    if proved_methods.is_empty() { "none".to_string() } else { proved_methods.join("; ") },
                    if others.is_empty() { "none".to_string() } else { others.join(", ") },
                ));
            }
            findings.push(format!(
                "Reachability of the reduced model over the whole published interval of y0 takes {secs:.0} s for {} networks (the published CORA runs needed manual splitting into 8-16 pieces and over 8 hours in some cases). The goal |x + y| <= 2 at t = 20 is proved for every start for: {}; it is violated (by a simulated trajectory) for: {}.",
                nets.len(),
                if proved.is_empty() { "none".to_string() } else { proved.join(", ") },
                if violated.is_empty() { "none".to_string() } else { violated.join(", ") },
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ReproSpec;
    use samara_train::case_study_spec;
    use samara_verify::{Critical, UnknownReason};
    use std::path::Path;

    fn crit(value: Option<f64>, unknown: Option<UnknownReason>, attained: bool) -> Critical {
        Critical {
            value,
            bound: 3.5,
            witness: None,
            attained,
            domain_extreme: Some(3.6),
            vacuous: false,
            complete: unknown.is_none(),
            unknown,
            nodes: 7,
            seconds: 0.0,
        }
    }

    #[test]
    fn an_incomplete_search_reads_unknown_with_its_reason_never_holds() {
        let c = critical_json(
            "p1",
            &crit(None, Some(UnknownReason::Timeout { nodes: 7 }), false),
        );
        assert_eq!(c["complete"], json!(false));
        assert_eq!(c["unknown_reason"]["kind"], json!("timeout"));
        let cell = critical_cell(&c);
        assert!(
            cell.starts_with("unknown (timeout: time limit reached after 7 nodes"),
            "{cell}"
        );
        assert!(!cell.contains("holds"), "{cell}");
        // With a witness but the gap open: both ends, and the reason.
        let c = critical_json(
            "p3",
            &crit(
                Some(1.25),
                Some(UnknownReason::NodeLimit { nodes: 7 }),
                false,
            ),
        );
        let cell = critical_cell(&c);
        assert!(
            cell.starts_with("unknown (node_limit: node limit reached after 7 nodes)"),
            "{cell}"
        );
        assert!(cell.contains("witness 1.2500, bound 3.5000"), "{cell}");
        // A result without `complete` makes no claim either.
        assert!(critical_cell(&json!({"critical": null})).starts_with("unknown"));
    }

    #[test]
    fn a_complete_search_reads_its_value_or_holds() {
        let c = critical_json("p1", &crit(None, None, false));
        assert_eq!(c["unknown_reason"], Value::Null);
        assert_eq!(critical_cell(&c), "holds for every ystar");
        assert_eq!(
            critical_cell(&critical_json("p1", &crit(Some(3.5), None, true))),
            "3.5000"
        );
        assert_eq!(
            critical_cell(&critical_json("p1", &crit(Some(3.25), None, false))),
            "3.2500 (gap open: sound bound 3.5000)"
        );
    }

    /// ex = 0.187 + 0.01 (x + y) in raw units.
    fn linear_net() -> Network {
        Network {
            input_names: samara_nn::STATE_INPUTS
                .iter()
                .map(|s| s.to_string())
                .collect(),
            output_names: vec!["ex".into()],
            input_norm: None,
            layers: vec![samara_nn::Layer::Affine(samara_nn::Affine::new(
                6,
                1,
                vec![0.0, 0.0, 0.0, 0.0, 0.01, 0.01],
                vec![0.187],
            ))],
            output_denorm: None,
        }
    }

    fn p1_critical(spec: &Spec) -> f64 {
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), linear_net());
        let prep = Prepared::new(&nets);
        let spec = with_units(spec, None, None, None);
        let c = critical_values(&spec, &prep, &Settings::default()).unwrap();
        assert_eq!(c[0]["property"], json!("p1"));
        assert_eq!(c[0]["complete"], json!(true));
        c[0]["critical"].as_f64().unwrap()
    }

    #[test]
    fn the_verify_stage_reads_p1_from_the_spec() {
        // ex < 0.187 iff x + y < 0: P1 holds for ystar above 0.
        let c = p1_critical(&case_study_spec());
        assert!(c.abs() < 1e-6, "{c}");
        // Edit a copy of the spec: ex < 0.2 iff x + y < 1.3, and the threshold moves.
        let edited = samara_train::CASE_STUDY_SPEC.replace("=> ex >= 0.187", "=> ex >= 0.2");
        assert_ne!(edited, samara_train::CASE_STUDY_SPEC);
        let spec = Spec::parse(&edited, "edited.spec", std::path::Path::new(".")).unwrap();
        let c = p1_critical(&spec);
        assert!((c - 1.3).abs() < 1e-6, "{c}");
    }

    /// The shipped spec's text with P1-P4's output constants edited: P1 `ex >= 0.2`,
    /// P2 `ex <= 0.18`, P3 `0.183 <= ex <= 0.192`, P4 `ex <= 0.19`.
    fn edited_p1_to_p4() -> String {
        let mut t = samara_train::CASE_STUDY_SPEC.to_string();
        for (from, to) in [
            (
                "property p1: y >= -x + ystar => ex >= 0.187",
                "property p1: y >= -x + ystar => ex >= 0.2",
            ),
            (
                "property p2: y <= -x - ystar => ex <= 0.187",
                "property p2: y <= -x - ystar => ex <= 0.18",
            ),
            ("=> 0.184 <= ex <= 0.19\n", "=> 0.183 <= ex <= 0.192\n"),
            (
                "and v_yp <= -0.3 => ex <= 0.187",
                "and v_yp <= -0.3 => ex <= 0.19",
            ),
        ] {
            assert_eq!(t.matches(from).count(), 1, "{from}");
            t = t.replace(from, to);
        }
        t
    }

    /// The critical values of P1-P4 as the verify stage writes them into results.json,
    /// for a run whose spec is `spec`, with [`linear_net`] as every samara controller
    /// (the stage reads the networks and the data the train stage left in the output
    /// directory, and the data's box and units from the train stage's result).
    fn verify_stage_criticals(spec: ReproSpec, tag: &str) -> Vec<Vec<Value>> {
        let out =
            std::env::temp_dir().join(format!("samara-repro-verify-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(out.join("networks")).unwrap();
        std::fs::create_dir_all(out.join("data")).unwrap();
        for m in METHODS {
            samara_nn::onnx::save(
                &linear_net(),
                out.join(format!("networks/{m}.onnx")),
                &Default::default(),
            )
            .unwrap();
        }
        // Three data rows (P5 is computed on them too), any values inside the box.
        let rows = [
            [1.5, -0.4, -0.2, -0.76, 10.0, -9.0, 0.186],
            [2.0, -0.3, -0.1, -0.5, 20.0, -20.5, 0.188],
            [3.0, -0.1, 0.0, -0.2, 30.0, -29.0, 0.19],
        ];
        std::fs::write(
            out.join("data/training_data.csv"),
            samara_sim::dataset::training_csv(&rows),
        )
        .unwrap();
        let domain = &samara_train::case_study_spec().networks[0].domain;
        let up = json!({"train": {
            "domain_lo": domain.iter().map(|d| d.0).collect::<Vec<_>>(),
            "domain_hi": domain.iter().map(|d| d.1).collect::<Vec<_>>(),
            "norm_min": [1.0, -0.6, -0.4, -1.0, 0.0, -42.0, 0.18],
            "norm_range": [2.5, 0.6, 0.5, 1.0, 42.0, 46.0, 0.01],
        }});
        let opts = crate::ReproduceOptions {
            out: out.clone(),
            quick: true,
            published: None,
            fresh: true,
            progress: false,
            command_line: String::new(),
            spec,
        };
        let bars =
            indicatif::MultiProgress::with_draw_target(indicatif::ProgressDrawTarget::hidden());
        let ctx = Ctx {
            opts: &opts,
            bars: &bars,
        };
        let r = verify(&ctx, &up).unwrap().result;
        std::fs::remove_dir_all(&out).unwrap();
        let nets = r["networks"].as_array().unwrap();
        assert_eq!(nets.len(), METHODS.len());
        nets.iter()
            .map(|n| n["critical"].as_array().unwrap().clone())
            .collect()
    }

    /// Issue 12: the reproduction reads P1-P4 from the spec it is given. A copy of the
    /// spec with P1-P4's output constants edited, read from a file as `samara reproduce
    /// --spec FILE` reads it, moves the verify stage's critical values in results.json
    /// to the values computed by hand for the network ex = 0.187 + 0.01 s (s = x + y,
    /// raw units): P1 (holds above) sup{s : ex(s) < c1} = (c1 - 0.187) / 0.01; P2 (holds
    /// above) sup{-s : ex(s) > c2} = (0.187 - c2) / 0.01; P3 (holds below) inf{|s| : ex(s)
    /// outside [a, b]} = min((0.187 - a), (b - 0.187)) / 0.01; P4 (holds below) inf{s >= 0
    /// : ex(s) > c4} = max(0, c4 - 0.187) / 0.01.
    #[test]
    fn the_verify_stage_thresholds_move_with_an_edited_spec() {
        let predicted = |c1: f64, c2: f64, (a, b): (f64, f64), c4: f64| {
            [
                (c1 - 0.187) / 0.01,
                (0.187 - c2) / 0.01,
                (0.187 - a).min(b - 0.187) / 0.01,
                (c4 - 0.187).max(0.0) / 0.01,
            ]
        };
        let dir = std::env::temp_dir().join(format!("samara-repro-spec-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("edited.spec");
        std::fs::write(&file, edited_p1_to_p4()).unwrap();
        let edited = ReproSpec::read(&file).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        for (spec, tag, want) in [
            (
                ReproSpec::shipped(),
                "shipped",
                predicted(0.187, 0.187, (0.184, 0.19), 0.187),
            ),
            (edited, "edited", predicted(0.2, 0.18, (0.183, 0.192), 0.19)),
        ] {
            for crit in verify_stage_criticals(spec, tag) {
                for (k, (c, w)) in crit.iter().zip(want).enumerate() {
                    assert_eq!(c["property"], json!(P1_TO_P4[k]));
                    assert_eq!(c["complete"], json!(true), "{tag} {c}");
                    let v = c["critical"].as_f64().unwrap();
                    assert!((v - w).abs() < 1e-6, "{tag} {}: {v} != {w}", P1_TO_P4[k]);
                }
            }
        }
    }

    /// The train stage's DL2/Goedel constraints come from the run's spec: editing P1's
    /// constant to `ex >= 0.2` moves P1's boundary on the normalised output from
    /// (0.187 - 0.18) / 0.01 = 0.7 to (0.2 - 0.18) / 0.01 = 2.
    #[test]
    fn the_train_stage_constraints_move_with_an_edited_spec() {
        let mm = MinMax {
            min: vec![1.0, -0.6, -0.4, -1.0, 0.0, -42.0, 0.18],
            range: vec![2.5, 0.6, 0.5, 1.0, 42.0, 46.0, 0.01],
        };
        let lo: Vec<f64> = mm.min[..6].to_vec();
        let hi: Vec<f64> = (0..6).map(|j| mm.min[j] + mm.range[j]).collect();
        let edited = ReproSpec::parse(&edited_p1_to_p4(), "edited.spec", Path::new(".")).unwrap();
        for (spec, boundary) in [(ReproSpec::shipped(), 0.7), (edited, 2.0)] {
            let props = training_properties(spec.spec(), &mm, &lo, &hi).unwrap();
            let p1 = props.iter().find(|p| p.name == "p1").unwrap();
            assert!(p1.formula.holds(boundary + 1e-9), "{boundary}");
            assert!(!p1.formula.holds(boundary - 1e-9), "{boundary}");
        }
    }

    /// A spec the stages cannot lower is refused before any stage runs, with its place.
    #[test]
    fn a_spec_without_what_the_stages_lower_is_refused() {
        let parse = |t: &str| ReproSpec::parse(t, "e.spec", Path::new(".")).map(|_| ());
        assert!(parse(samara_train::CASE_STUDY_SPEC).is_ok());
        let no_p4 = samara_train::CASE_STUDY_SPEC.replace("property p4:", "property q4:");
        let e = parse(&no_p4).unwrap_err().to_string();
        assert!(e.contains("e.spec") && e.contains("p4"), "{e}");
        let syntax = samara_train::CASE_STUDY_SPEC.replace("=> ex >= 0.187", "=> ex >= ");
        let e = parse(&syntax).unwrap_err().to_string();
        assert!(e.starts_with("e.spec:"), "{e}");
        let no_default = samara_train::CASE_STUDY_SPEC.replace("[0, 100] = 2", "[0, 100]");
        assert!(parse(&no_default).is_err());
    }

    #[test]
    fn critical_queries_take_their_direction_from_the_lowering() {
        let spec = case_study_spec();
        let sense = |p: &str| match critical_query(&spec, p, "ystar").unwrap().goal {
            Goal::Optimise { sense, .. } => sense,
            _ => unreachable!(),
        };
        assert_eq!(
            P1_TO_P4.map(sense),
            [Sense::Max, Sense::Max, Sense::Min, Sense::Min]
        );
        // P1, P2, P4: the parameter is eliminated; P3 keeps it (two bounds on it).
        assert!(critical_query(&spec, "p1", "ystar")
            .unwrap()
            .free_vars
            .is_empty());
        assert_eq!(
            critical_query(&spec, "p3", "ystar")
                .unwrap()
                .free_vars
                .len(),
            1
        );
        assert!(critical_query(&spec, "p5", "ystar").is_err());
    }
}
