//! With `--features highs`: samara's exact critical values agree with a big-M MILP solved
//! by HiGHS on the case-study queries (all four published ReLU networks) and on random
//! networks.
#![cfg(feature = "highs")]

use rand::SeedableRng;
use samara_nn::{Activation, Network};
use samara_spec::normal::{Application, Goal, LinExpr, Query, Sense, Var};
#[path = "support/case_study.rs"]
mod case_study;
use case_study::p1_to_p4;
use samara_verify::milp::{optimise_milp, optimise_milp_with, MilpError, MilpOptions};
use samara_verify::net::PwlNet;
use samara_verify::{optimise, Prepared, Settings};
use std::collections::HashMap;
use std::time::Instant;

fn check(q: &Query, nets: &HashMap<String, Network>, opts: &MilpOptions) {
    let prep = Prepared::new(nets);
    let pwl: HashMap<String, PwlNet> = nets
        .iter()
        .map(|(k, v)| (k.clone(), PwlNet::from_network(v).unwrap()))
        .collect();
    let ours = optimise(q, &prep, &Settings::default()).unwrap();
    let theirs = optimise_milp_with(q, &pwl, opts).unwrap();
    match (ours.value, theirs.value) {
        (Some(a), Some(b)) => assert!(
            (a - b).abs() <= 1e-5 * (1.0 + b.abs())
                && (ours.bound - b).abs() <= 1e-5 * (1.0 + b.abs()),
            "{}: samara {a} (bound {}) vs HiGHS {b}",
            q.name,
            ours.bound
        ),
        (None, None) => {}
        (a, b) => panic!("{}: samara {a:?} vs HiGHS {b:?}", q.name),
    }
}

#[test]
fn case_study_critical_values_agree_with_highs() {
    for f in [
        "base_model_norm",
        "adversarial_model_norm",
        "base_model_denorm",
        "adversarial_model_denorm",
    ] {
        let mut nets = HashMap::new();
        nets.insert(
            "f".to_string(),
            samara_nn::onnx::load(samara_testkit::reference(&format!("{f}.onnx"))).unwrap(),
        );
        for q in p1_to_p4(f.contains("denorm")) {
            check(&q, &nets, &MilpOptions::default());
        }
    }
}

#[test]
fn random_networks_agree_with_highs() {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    for case in 0..30 {
        let net = Network::random_mlp(&[4, 10, 8, 1], Activation::Relu, 1.0, 0.3, &mut r);
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), net);
        let sense = if case % 2 == 0 {
            Sense::Max
        } else {
            Sense::Min
        };
        let q = box_query(&format!("r{case}"), 4, sense);
        // With and without the second (output-constrained) bound sweep, and with
        // HiGHS's feasibility tolerances tightened to 1e-9.
        for (sweep, tol) in [(true, None), (false, None), (true, Some(1e-9))] {
            check(
                &q,
                &nets,
                &MilpOptions {
                    sweep,
                    feasibility_tolerance: tol,
                    ..Default::default()
                },
            );
        }
    }
}

/// `max f(x)` or `min f(x)` (`sense`) over `[-1, 1]^n` for the one-output network `f`
/// of input width `n`.
fn box_query(name: &str, n: usize, sense: Sense) -> Query {
    Query {
        name: name.into(),
        applications: vec![Application {
            network: "f".into(),
            n_inputs: n,
            n_outputs: 1,
            input_box: vec![(-1.0, 1.0); n],
        }],
        free_vars: vec![],
        region: vec![vec![]],
        goal: Goal::Optimise {
            objective: LinExpr {
                terms: vec![(Var::Output { app: 0, index: 0 }, 1.0)],
                constant: 0.0,
            },
            sense,
            label: "y".into(),
        },
    }
}

/// The time limit covers the whole computation, the LP-bound phase included (it had
/// none: 200 s were seen on P3 of a 6-64-32-1 network): on a network with about a
/// thousand ReLUs unstable over the box, two LPs each before the MILP is even built,
/// every limit ends in `TimeLimit`, within a second of it.
#[test]
fn the_time_limit_bounds_the_lp_bound_phase() {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let net = Network::random_mlp(&[8, 400, 400, 400, 1], Activation::Relu, 1.0, 0.3, &mut r);
    let pwl: HashMap<String, PwlNet> =
        HashMap::from([("f".to_string(), PwlNet::from_network(&net).unwrap())]);
    let q = box_query("big", 8, Sense::Max);
    for limit in [0.0, 0.5, 2.0] {
        let t = Instant::now();
        let got = optimise_milp_with(
            &q,
            &pwl,
            &MilpOptions {
                time_limit: limit,
                ..Default::default()
            },
        );
        let took = t.elapsed().as_secs_f64();
        // At 0 s nothing starts; otherwise the limit falls among the LPs (the alpha-CROWN
        // steps before them stop at the deadline too, and the first LP then reports it).
        let want = if limit == 0.0 {
            "CROWN bounds"
        } else {
            "LP bounds"
        };
        assert!(
            matches!(got, Err(MilpError::TimeLimit { phase, .. }) if phase == want),
            "limit {limit}: {got:?}"
        );
        assert!(
            took <= limit + 1.0,
            "limit {limit}: returned after {took:.2} s"
        );
    }
}

/// A limit that is not a number of seconds is an error, not a panic; an infinite one
/// is no limit (the value as with the default).
#[test]
fn time_limit_options_are_checked() {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let net = Network::random_mlp(&[3, 6, 1], Activation::Relu, 1.0, 0.3, &mut r);
    let pwl: HashMap<String, PwlNet> =
        HashMap::from([("f".to_string(), PwlNet::from_network(&net).unwrap())]);
    let q = box_query("small", 3, Sense::Max);
    for bad in [-1.0, f64::NAN] {
        let got = optimise_milp_with(
            &q,
            &pwl,
            &MilpOptions {
                time_limit: bad,
                ..Default::default()
            },
        );
        assert!(matches!(got, Err(MilpError::Options(_))), "{bad}: {got:?}");
    }
    let unlimited = optimise_milp_with(
        &q,
        &pwl,
        &MilpOptions {
            time_limit: f64::INFINITY,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(unlimited.value, optimise_milp(&q, &pwl).unwrap());
}
