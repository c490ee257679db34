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
use samara_verify::milp::optimise_milp;
use samara_verify::net::PwlNet;
use samara_verify::{optimise, Prepared, Settings};
use std::collections::HashMap;

fn check(q: &Query, nets: &HashMap<String, Network>) {
    let prep = Prepared::new(nets);
    let pwl: HashMap<String, PwlNet> = nets
        .iter()
        .map(|(k, v)| (k.clone(), PwlNet::from_network(v).unwrap()))
        .collect();
    let ours = optimise(q, &prep, &Settings::default()).unwrap();
    let theirs = optimise_milp(q, &pwl).unwrap();
    match (ours.value, theirs) {
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
            check(&q, &nets);
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
        let q = Query {
            name: format!("r{case}"),
            applications: vec![Application {
                network: "f".into(),
                n_inputs: 4,
                n_outputs: 1,
                input_box: vec![(-1.0, 1.0); 4],
            }],
            free_vars: vec![],
            region: vec![vec![]],
            goal: Goal::Optimise {
                objective: LinExpr {
                    terms: vec![(Var::Output { app: 0, index: 0 }, 1.0)],
                    constant: 0.0,
                },
                sense: if case % 2 == 0 {
                    Sense::Max
                } else {
                    Sense::Min
                },
                label: "y".into(),
            },
        };
        check(&q, &nets);
    }
}
