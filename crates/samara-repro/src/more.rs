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
use samara_train::{
    case_study, read_table, train as train_net, Attack, Logic, Method, MinMax, TrainOptions, Units,
};
use samara_verify::case_study::{p1_to_p4, Units as VUnits};
use samara_verify::robustness::{lipschitz_cell, published_cell, sweep, Reference};
use samara_verify::{optimise, Prepared, Settings};
use serde_json::{json, Value};
use std::collections::HashMap;

const METHODS: [&str; 5] = ["plain", "adversarial", "lipschitz", "dl2", "goedel"];
const EPS: [f64; 4] = [1e-5, 1e-4, 1e-3, 1e-2];
const LS: [f64; 4] = [1e-5, 1e-4, 1e-3, 1e-2];
/// The published normalisation constants (Normalisation_Constants.csv), used only to
/// give the published networks their units when `--published` is passed.
fn published_constants(dir: &std::path::Path) -> Result<(Vec<f64>, Vec<f64>), String> {
    let rows = read_plain_csv(&dir.join("Normalisation_Constants.csv"))?;
    if rows.len() < 2 || rows[0].len() < 6 {
        return Err("Normalisation_Constants.csv: expected two rows of at least 6 columns".into());
    }
    Ok((rows[0][..6].to_vec(), rows[1][..6].to_vec()))
}

/// Stage 2: train the five controllers on the regenerated data.
pub fn train(ctx: &Ctx, _up: &Value) -> Result<StageOutput, ReproError> {
    let data =
        read_table(&ctx.path("data/training_data.csv")).map_err(|e| stage_err("train", e))?;
    let mm = MinMax::of(&data);
    let units = Units {
        c: mm.min[..6].to_vec(),
        s: mm.range[..6].to_vec(),
        c_out: mm.min[6],
        s_out: mm.range[6],
    };
    let lo = mm.min[..6].to_vec();
    let hi: Vec<f64> = (0..6).map(|j| mm.min[j] + mm.range[j]).collect();
    let epochs = if ctx.opts.quick { 200 } else { 1000 };
    let pb = ctx.bar(METHODS.len() as u64, "training controllers");
    let mut rows = Vec::new();
    let mut files = Vec::new();
    for m in METHODS {
        let method = match m {
            "plain" => Method::Plain,
            "adversarial" => Method::Adversarial(Attack::Fgsm),
            "lipschitz" => Method::Lipschitz {
                l: 0.5,
                weight: 10.0,
            },
            "dl2" => Method::Properties {
                logic: Logic::Dl2,
                props: case_study(&units, &lo, &hi, 2.0),
                weight: 1.0,
            },
            _ => Method::Properties {
                logic: Logic::Goedel,
                props: case_study(&units, &lo, &hi, 2.0),
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
        rows.push(json!({"method": m, "file": rel, "r2": k.r2, "rmse": k.rmse, "mae": k.mae,
            "attack_worst": k.attack_worst, "attack_mean": k.attack_mean, "eps": o.eps, "epochs": epochs, "seconds": secs}));
        pb.inc(1);
    }
    pb.finish_and_clear();
    Ok(StageOutput {
        result: json!({"networks": rows, "domain_lo": lo, "domain_hi": hi, "norm_min": mm.min, "norm_range": mm.range}),
        files,
    })
}

struct Subject {
    label: String,
    net: Network,
    units: VUnits,
    lo: Vec<f64>,
    hi: Vec<f64>,
    /// Body network and data rows in its (normalised) units, for P5.
    p5: Option<(Network, Vec<Vec<f64>>)>,
    raw_controller: Option<Network>,
}

fn subjects(ctx: &Ctx, up: &Value) -> Result<Vec<Subject>, ReproError> {
    let mut v = Vec::new();
    let tr = &up["train"];
    let lo: Vec<f64> =
        serde_json::from_value(tr["domain_lo"].clone()).map_err(|e| stage_err("verify", e))?;
    let hi: Vec<f64> =
        serde_json::from_value(tr["domain_hi"].clone()).map_err(|e| stage_err("verify", e))?;
    let nmin: Vec<f64> =
        serde_json::from_value(tr["norm_min"].clone()).map_err(|e| stage_err("verify", e))?;
    let nrange: Vec<f64> =
        serde_json::from_value(tr["norm_range"].clone()).map_err(|e| stage_err("verify", e))?;
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
            units: VUnits::raw(),
            lo: lo.clone(),
            hi: hi.clone(),
            p5: Some((body, rows_norm.clone())),
            raw_controller: Some(net),
        });
    }
    if let Some(dir) = &ctx.opts.published {
        let (c, s) = published_constants(dir).map_err(|e| stage_err("verify", e))?;
        let plo = c.clone();
        let phi: Vec<f64> = c.iter().zip(&s).map(|(a, b)| a + b).collect();
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
                units: if norm {
                    VUnits {
                        c: c.clone(),
                        s: s.clone(),
                        c_out: 0.181,
                        s_out: 0.012,
                    }
                } else {
                    VUnits::raw()
                },
                lo: plo.clone(),
                hi: phi.clone(),
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
        let mut crit = Vec::new();
        for q in p1_to_p4("f", &s.units, &s.lo, &s.hi) {
            let r =
                optimise(&q, &prep, &Settings::default()).map_err(|e| stage_err("verify", e))?;
            crit.push(json!({"property": q.name, "critical": r.value, "bound": r.bound, "attained": r.attained,
                "vacuous": r.vacuous, "domain_extreme": r.domain_extreme, "complete": r.complete}));
        }
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
        samara_reach::figure(&r, &format!("{}, reduced model", s.label), Some(2.0))
            .render(&ctx.path(&png), &ctx.path(&svg))
            .map_err(|e| stage_err("reach", e))?;
        let reason = match &r.verdict {
            samara_reach::Verdict::Unknown { reason } => reason.clone(),
            samara_reach::Verdict::Violated {
                initial,
                t,
                x_plus_y,
            } => format!(
                "simulated from y0 = {:.4}: x + y = {:.4} at t = {}",
                initial[5], x_plus_y, t
            ),
            _ => String::new(),
        };
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
                            format!("{:.2e}", n["rmse"].as_f64().unwrap_or(f64::NAN)),
                            format!("{:.2e}", n["attack_worst"].as_f64().unwrap_or(f64::NAN)),
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
                "RMSE (ex)",
                "worst attack deviation (ex)",
                "seconds",
            ],
            rows,
        ));
    }
    if let Some(v) = st.get("verify") {
        d.push(Block::Heading(
            1,
            "3-4. Verification: critical values of P1-P4".into(),
        ));
        d.push(Block::Para("P1 and P2 hold for ystar above the critical value, P3 and P4 below it. Each value is one exact optimisation (branch and bound with sound LP bounds), reported with a concrete witness; `vacuous` marks a threshold that equals the extreme of x + y over the input box, where the property's precondition is empty; \"holds for every ystar\" means the counterexample region is empty for every value.".into()));
        let mut rows = Vec::new();
        let mut vac: Vec<String> = Vec::new();
        for n in v["networks"].as_array().into_iter().flatten() {
            let mut row = vec![n["network"].as_str().unwrap_or("").to_string()];
            for c in n["critical"].as_array().into_iter().flatten() {
                let val = c["critical"]
                    .as_f64()
                    .map(|x| format!("{x:.4}"))
                    .unwrap_or("holds for every ystar".into());
                let v = c["vacuous"].as_bool() == Some(true);
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
            findings.push(format!(
                "Reachability of the reduced model over the whole published interval of y0 takes {secs:.0} s for {} networks (the published CORA runs needed manual splitting into 8-16 pieces and over 8 hours in some cases). The goal |x + y| <= 2 at t = 20 is proved for every start for: {}; it is violated (by a simulated trajectory) for: {}.",
                nets.len(),
                if proved.is_empty() { "none".to_string() } else { proved.join(", ") },
                if violated.is_empty() { "none".to_string() } else { violated.join(", ") },
            ));
        }
    }
}
