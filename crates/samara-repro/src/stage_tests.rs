//! Tests of the stages (2-6) and the spec checks: shared helpers (a linear network with
//! known critical values, edited copies of the spec) in one place.

use crate::common::{METHODS, P1_TO_P4};
use crate::results::{reals, CriticalRow, Real, Stages, TrainResult};
use crate::train_stage::*;
use crate::verify_stage::*;
use crate::{Ctx, ReproError};
use samara_nn::Network;
use samara_plant::{Model, Plant};
use samara_sim::{fly, initial_state, LoopSettings, NetworkController};
use samara_spec::normal::{Goal, Sense};
use samara_spec::Spec;
use samara_train::{with_units, MinMax};
use samara_verify::{Prepared, Settings};
use std::collections::HashMap;

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
    let c = critical_row(
        "p1",
        &crit(None, Some(UnknownReason::Timeout { nodes: 7 }), false),
    );
    assert!(!c.complete);
    assert_eq!(c.unknown_reason.as_ref().unwrap().kind, "timeout");
    let cell = critical_cell(&c);
    assert!(
        cell.starts_with("unknown (timeout: time limit reached after 7 nodes"),
        "{cell}"
    );
    assert!(!cell.contains("holds"), "{cell}");
    // With a witness but the gap open: both ends, and the reason.
    let c = critical_row(
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
    // An incomplete result without a reason makes no claim either.
    let bare: CriticalRow = serde_json::from_str(
        r#"{"attained": false, "bound": null, "complete": false, "critical": null,
            "domain_extreme": null, "property": "p1", "unknown_reason": null, "vacuous": false}"#,
    )
    .unwrap();
    assert!(critical_cell(&bare).starts_with("unknown"));
}

#[test]
fn a_complete_search_reads_its_value_or_holds() {
    let c = critical_row("p1", &crit(None, None, false));
    assert!(c.unknown_reason.is_none());
    assert_eq!(
        serde_json::to_value(&c).unwrap()["unknown_reason"],
        serde_json::Value::Null
    );
    assert_eq!(critical_cell(&c), "holds for every ystar");
    assert_eq!(
        critical_cell(&critical_row("p1", &crit(Some(3.5), None, true))),
        "3.5000"
    );
    assert_eq!(
        critical_cell(&critical_row("p1", &crit(Some(3.25), None, false))),
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
    assert_eq!(c[0].property, "p1");
    assert!(c[0].complete);
    c[0].critical.get().unwrap()
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

/// Run `stage` as the reproduction runs it on a spec `spec`, with [`linear_net`] as
/// every samara controller: the stage reads the networks and the data the train stage
/// left in the output directory (here a temporary one, removed afterwards), and the
/// data's box and units from the train stage's result.
fn run_stage(
    spec: ReproSpec,
    tag: &str,
    stage: fn(&Ctx, &mut Stages) -> Result<Vec<String>, ReproError>,
) -> Stages {
    let out = std::env::temp_dir().join(format!("samara-repro-stage-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(out.join("networks")).unwrap();
    std::fs::create_dir_all(out.join("data")).unwrap();
    std::fs::create_dir_all(out.join("figures")).unwrap();
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
    let mut up = Stages {
        train: Some(TrainResult {
            closed_loop: None,
            domain_lo: domain.iter().map(|d| Real(d.0)).collect(),
            domain_hi: domain.iter().map(|d| Real(d.1)).collect(),
            networks: vec![],
            norm_min: reals(&[1.0, -0.6, -0.4, -1.0, 0.0, -42.0, 0.18]),
            norm_range: reals(&[2.5, 0.6, 0.5, 1.0, 42.0, 46.0, 0.01]),
        }),
        ..Stages::default()
    };
    let opts = crate::ReproduceOptions {
        out: out.clone(),
        quick: true,
        published: None,
        fresh: true,
        progress: false,
        command_line: String::new(),
        spec,
    };
    let bars = indicatif::MultiProgress::with_draw_target(indicatif::ProgressDrawTarget::hidden());
    let ctx = Ctx {
        opts: &opts,
        bars: &bars,
    };
    stage(&ctx, &mut up).unwrap();
    std::fs::remove_dir_all(&out).unwrap();
    up
}

/// The critical values of P1-P4 as the verify stage writes them into results.json,
/// for a run whose spec is `spec` ([`run_stage`]).
fn verify_stage_criticals(spec: ReproSpec, tag: &str) -> Vec<Vec<CriticalRow>> {
    let r = run_stage(spec, tag, verify).verify.unwrap();
    assert_eq!(r.networks.len(), METHODS.len());
    r.networks.into_iter().map(|n| n.critical).collect()
}

/// Issue 12: the reachability stage flies the spec's closed loop. A copy of the shipped
/// spec with the loop edited (start y in [2, 2.2] instead of the published interval,
/// horizon 1.5, goal |x + y| <= 5 from t = 0.5) gives a reach stage whose results say
/// so, whose enclosures at t = 1.5 contain independent simulations of the edited loop
/// (samara_sim's sample-and-hold flight of the reduced model with the same network, from
/// three starts in the edited interval, none in the published one), and whose verdict
/// is `proved` (the flights stay far inside the band: |x + y| < 3.2).
#[test]
fn the_reach_stage_flies_the_specs_loop() {
    let mut text = samara_train::CASE_STUDY_SPEC.to_string();
    for (from, to) in [
        (
            "y in [1.4285714285714286, 4.285714285714286]",
            "y in [2, 2.2]",
        ),
        ("period 0.5, horizon 20,", "period 0.5, horizon 1.5,"),
        ("|x + y| <= 2 at 20", "|x + y| <= 5 from 0.5"),
    ] {
        assert_eq!(text.matches(from).count(), 1, "{from}");
        text = text.replace(from, to);
    }
    let spec = ReproSpec::parse(&text, "edited.spec", Path::new(".")).unwrap();
    let r = run_stage(spec, "reach", crate::reach_stage::reach)
        .reach
        .unwrap();
    assert_eq!(r.y0, [Real(2.0), Real(2.2)]);
    assert_eq!(r.horizon, Real(1.5));
    assert_eq!(r.goal_ystar, Real(5.0));
    assert_eq!(r.goal_from, Real(0.5));
    assert_eq!(r.loop_name, "published");
    let nets = &r.networks;
    assert_eq!(nets.len(), METHODS.len());
    let plant = Plant::new(Model::Reduced);
    let settings = LoopSettings {
        horizon: 1.5,
        period: 0.5,
        ..LoopSettings::default()
    };
    let mut ctl = NetworkController::new(linear_net(), Some(samara_plant::EX_RANGE), "linear");
    for n in nets {
        assert_eq!(n.verdict, "proved", "{n:?}");
        let f = &n.final_x_plus_y;
        let (lo, hi) = (f[0].get().unwrap(), f[1].get().unwrap());
        for y0 in [2.0, 2.1, 2.2] {
            let flight = fly(&plant, &mut ctl, &initial_state(&plant, y0), &settings).unwrap();
            let last = &flight.steps.last().unwrap().state_end;
            let s = last[4] + last[5];
            assert!(lo <= s && s <= hi, "{y0}: {s} outside [{lo}, {hi}]");
            assert!(s.abs() < 3.2, "{s}");
        }
    }
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
                assert_eq!(c.property, P1_TO_P4[k]);
                assert!(c.complete, "{tag} {c:?}");
                let v = c.critical.get().unwrap();
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
    // The reachability stage and closed-loop training fly the spec's loop.
    let no_loop: String = samara_train::CASE_STUDY_SPEC
        .lines()
        .filter(|l| {
            !l.starts_with("loop ")
                && !l.starts_with("start ")
                && !l.starts_with("goal ")
                && !l.trim_start().starts_with("y in [")
        })
        .collect::<Vec<_>>()
        .join("\n");
    let e = parse(&no_loop).unwrap_err().to_string();
    assert!(e.contains("e.spec: states no closed loop"), "{e}");
    let no_goal = samara_train::CASE_STUDY_SPEC.replace("goal published: |x + y| <= 2 at 20", "");
    let e = parse(&no_goal).unwrap_err().to_string();
    assert!(e.contains("loop `published` has no goal"), "{e}");
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
