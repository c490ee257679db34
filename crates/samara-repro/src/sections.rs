//! Sections 2-6 of the report and the computed findings, rendered from the stages'
//! JSON results (a cached run renders the same report).

use crate::common::f4;
use crate::doc::{Block, Document};
use crate::table;
use crate::verify_stage::{critical_cell, EPS, LS};
use serde_json::Value;

/// The closed-loop method's rounds (issue 18 item 2).
pub(crate) fn closed_loop_section(cl: &Value, d: &mut Document) {
    d.push(Block::Heading(
        2,
        "2b. Closed-loop training (samara closed-loop)".into(),
    ));
    d.push(Block::Para(format!(
        "The plain network is trained on through the closed loop: each round takes up to {} full-batch Adam steps on {} x the data MSE plus the mean of max(0, |x + y|({}) - {})^2 over a set of flights of the reduced model (sample-and-hold, RK4, output clipped), differentiated through the loop; then `samara reach` checks |x + y| <= {} at t = {} over y0 in [{}, {}] (the spec's closed loop; 16 sub-boxes, 64 when undecided), and the starts of violating trajectories and of refuted or undecided sub-boxes join the flight set for the next round. Result: {} (x + y at t = {} in [{}, {}]), R^2 {} against every PID data row, {:.1} s.",
        cl["steps_per_round"],
        cl["data_weight"],
        cl["horizon"],
        cl["training_bound"],
        cl["goal_ystar"],
        cl["horizon"],
        f4(&cl["y0"][0]),
        f4(&cl["y0"][1]),
        cl["verdict"].as_str().unwrap_or("?"),
        cl["horizon"],
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

pub(crate) fn pct(v: &Value) -> String {
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
            let lp = LoopText::of(rc);
            d.push(Block::Para(format!("Sound reachable sets (validated Taylor integration on zonotopes, network bounded by CROWN over each set, outward rounding) of the spec's closed loop `{}`: the {} model (the shipped spec's loop is the published CORA analysis's setting), from y0 in [{}, {}] with the other states at (1, 0, 0, 0, 0), horizon {}, period {}, {}. Goal: {}. 'proved' holds for every start in the interval; 'violated' comes with a simulated trajectory; the ratio is the width of the enclosure of x + y at t = {} over the range of the sampled trajectories.", lp.name, lp.model, f4(&rc["y0"][0]), f4(&rc["y0"][1]), lp.horizon, lp.period, lp.clip, lp.goal, lp.horizon)));
            let nets: Vec<&Value> = rc["networks"].as_array().into_iter().flatten().collect();
            let rows = nets
                .iter()
                .map(|n| {
                    let f = &n["final_x_plus_y"];
                    let enclosure = if n["stopped"].as_u64().unwrap_or(0) > 0 {
                        format!(
                            "not enclosed to t = {}: {} sub-boxes lost validation (first at t = {})",
                            lp.horizon,
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
                    &format!("x + y at t = {} (enclosure)", lp.horizon),
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
                            "Reachable sets of {} (boxes at the control instants), sampled trajectories, the band |x + y| <= {}",
                            n["controller"].as_str().unwrap_or(""),
                            lp.bound
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
                        "{m} (x + y at t = {} in [{}, {}], R^2 {} against the PID data)",
                        lp.horizon,
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
                    "Of samara's {} training methods, {} produced a controller that reach proves for {} over the whole interval of y0 of the spec's loop `{}` ({} model, {}): {}; the others: {}.",
                    samara.len(),
                    proved_methods.len(),
                    lp.goal,
                    lp.name,
                    lp.model,
                    lp.clip,
                    if proved_methods.is_empty() { "none".to_string() } else { proved_methods.join("; ") },
                    if others.is_empty() { "none".to_string() } else { others.join(", ") },
                ));
            }
            findings.push(format!(
                "Reachability of the {} model over the whole interval of y0 of the spec's loop `{}` takes {secs:.0} s for {} networks (the published CORA runs needed manual splitting into 8-16 pieces and over 8 hours in some cases). The goal {} is proved for every start for: {}; it is violated (by a simulated trajectory) for: {}.",
                lp.model,
                lp.name,
                nets.len(),
                lp.goal,
                if proved.is_empty() { "none".to_string() } else { proved.join(", ") },
                if violated.is_empty() { "none".to_string() } else { violated.join(", ") },
            ));
        }
    }
}

/// The spec's closed loop in words, from the reach stage's result (a cached run renders
/// the same report).
struct LoopText {
    name: String,
    model: String,
    horizon: String,
    period: String,
    /// "controller output clipped to [a, b]" or "controller output not clipped".
    clip: String,
    bound: String,
    /// "|x + y| <= B at t = T" or "... for every t in [T0, T]".
    goal: String,
}

impl LoopText {
    fn of(rc: &Value) -> LoopText {
        let num = |v: &Value| v.as_f64().map_or("?".to_string(), |x| x.to_string());
        let (horizon, bound) = (num(&rc["horizon"]), num(&rc["goal_ystar"]));
        LoopText {
            name: rc["loop"].as_str().unwrap_or("published").to_string(),
            model: rc["model"].as_str().unwrap_or("?").to_string(),
            period: num(&rc["period"]),
            clip: match rc["clip"].as_array() {
                Some(c) if c.len() == 2 => format!(
                    "controller output clipped to [{}, {}] as in simulation",
                    num(&c[0]),
                    num(&c[1])
                ),
                _ => "controller output not clipped".into(),
            },
            goal: match rc["goal_from"].as_f64() {
                Some(f) => format!("|x + y| <= {bound} for every t in [{f}, {horizon}]"),
                None => format!("|x + y| <= {bound} at t = {horizon}"),
            },
            horizon,
            bound,
        }
    }
}
