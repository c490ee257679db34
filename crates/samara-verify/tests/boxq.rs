//! The input-split route (`boxq`, on samara-bounds) against independent references:
//! the VNN-COMP 2021 consensus on ACAS Xu networks from the field, and the ReLU-phase
//! LP branch and bound of this crate (another algorithm) on random networks.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_nn::{Activation, Network};
use samara_spec::normal::{Application, Cmp, Constraint, Goal, LinExpr, Query, Var};
use samara_verify::boxq::{prove_boxes, BoxAnswer};
use samara_verify::net::PwlNet;
use samara_verify::{prove, Prepared, Settings, Timeout, Verdict};
use std::collections::HashMap;
use std::path::Path;

fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/acasxu")
        .join(name)
}

#[test]
fn acas_xu_fixtures_match_the_competition_consensus() {
    for (net, prop, sat) in [
        ("1_1", "prop_1", false),
        ("1_2", "prop_1", false),
        ("1_1", "prop_2", false),
        ("1_2", "prop_2", true),
    ] {
        let n =
            samara_nn::onnx::load(fixture(&format!("ACASXU_run2a_{net}_batch_2000.onnx"))).unwrap();
        let text = std::fs::read_to_string(fixture(&format!("{prop}.vnnlib"))).unwrap();
        let q = samara_spec::vnnlib::import(&text, prop, "f", prop).unwrap();
        let pwl = PwlNet::from_network(&n).unwrap();
        let a =
            prove_boxes(&q, &pwl, Timeout::from_secs(120)).expect("ACAS Xu queries are box-shaped");
        match (a, sat) {
            (BoxAnswer::Proved, false) => {}
            (BoxAnswer::Violated(c), true) => {
                // Re-evaluated by the IR's own evaluator too.
                let y = n.eval_f64(&c.point.inputs[0]);
                assert!(
                    (1..5).all(|j| y[0] >= y[j]),
                    "{net} {prop}: {y:?} is not a counterexample"
                );
                assert_eq!(c.exact, Some(true));
            }
            (other, _) => panic!(
                "{net} {prop}: expected {}, got {other:?}",
                if sat { "sat" } else { "unsat" }
            ),
        }
    }
}

fn var_out(i: usize) -> Var {
    Var::Output { app: 0, index: i }
}

#[test]
fn random_box_queries_agree_with_the_lp_branch_and_bound() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (mut proved, mut violated) = (0, 0);
    for trial in 0..30 {
        let dims: &[usize] = if trial % 2 == 0 {
            &[3, 8, 8, 2]
        } else {
            &[4, 10, 6, 2]
        };
        let net = Network::random_mlp(dims, Activation::Relu, 1.0, 0.5, &mut rng);
        let n_in = dims[0];
        let input_box: Vec<(f64, f64)> = (0..n_in)
            .map(|_| {
                let c: f64 = rng.gen_range(-1.0..1.0);
                let w: f64 = rng.gen_range(0.1..1.0);
                (c - w, c + w)
            })
            .collect();
        // Sample y0 - y1 to put the threshold where either answer can occur.
        let vals: Vec<f64> = (0..300)
            .map(|_| {
                let x: Vec<f64> = input_box
                    .iter()
                    .map(|(a, b)| rng.gen_range(*a..=*b))
                    .collect();
                let y = net.eval_f64(&x);
                y[0] - y[1]
            })
            .collect();
        let min = vals.iter().cloned().fold(f64::INFINITY, f64::min);
        let max = vals.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let t = min - (max - min) * rng.gen_range(-0.2..0.3);
        let q = Query {
            name: format!("r{trial}"),
            applications: vec![Application {
                network: "f".into(),
                n_inputs: n_in,
                n_outputs: 2,
                input_box: input_box.clone(),
            }],
            free_vars: vec![],
            region: vec![vec![Constraint {
                expr: LinExpr {
                    terms: vec![(var_out(0), 1.0), (var_out(1), -1.0)],
                    constant: -t,
                },
                cmp: Cmp::Le,
            }]],
            goal: Goal::Prove,
        };
        let pwl = PwlNet::from_network(&net).unwrap();
        let a = prove_boxes(&q, &pwl, Timeout::from_secs(60)).unwrap();
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), net.clone());
        let prep = Prepared::new(&nets);
        let b = prove(
            &q,
            &prep,
            &Settings {
                timeout: Timeout::from_secs(60),
                ..Default::default()
            },
        )
        .unwrap();
        match (&a, &b) {
            (BoxAnswer::Proved, Verdict::Proved) => proved += 1,
            (BoxAnswer::Violated(c), Verdict::Violated(_)) => {
                violated += 1;
                let y = net.eval_f64(&c.point.inputs[0]);
                assert!(y[0] - y[1] <= t, "trial {trial}");
            }
            _ => panic!("trial {trial}: input split says {a:?}, LP branch and bound says {b:?} (t {t}, sampled {min}..{max}, box {input_box:?})"),
        }
    }
    assert!(
        proved >= 5 && violated >= 5,
        "{proved} proved, {violated} violated"
    );
}
