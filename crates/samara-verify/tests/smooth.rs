//! Smooth activations: every Proved survives 10,000 samples, every Violated is real,
//! and the published sigmoid network gets sound answers.

use rand::{Rng, SeedableRng};
use samara_nn::{Activation, Affine, Layer, Network};
use samara_spec::normal::{Application, Cmp, Constraint, Goal, LinExpr, Query, Var};
use samara_verify::{prove, Prepared, Settings, Timeout, Verdict};
use std::collections::HashMap;

fn net(r: &mut impl Rng, act: Activation) -> Network {
    let dims = [2, 6, 4, 1];
    let mut layers = Vec::new();
    for (k, w) in dims.windows(2).enumerate() {
        layers.push(Layer::Affine(Affine::new(
            w[0],
            w[1],
            (0..w[0] * w[1]).map(|_| r.gen_range(-2.0..2.0)).collect(),
            (0..w[1]).map(|_| r.gen_range(-0.5..0.5)).collect(),
        )));
        if k < 2 {
            layers.push(Layer::Act(act));
        }
    }
    Network {
        input_names: vec!["a".into(), "b".into()],
        output_names: vec!["y".into()],
        input_norm: None,
        layers,
        output_denorm: None,
    }
}

fn query(t: f64, n_in: usize) -> Query {
    Query {
        name: "q".into(),
        applications: vec![Application {
            network: "f".into(),
            n_inputs: n_in,
            n_outputs: 1,
            input_box: vec![(-1.0, 1.0); n_in],
        }],
        free_vars: vec![],
        // Counterexample: y > t.
        region: vec![vec![Constraint {
            expr: LinExpr {
                terms: vec![(Var::Output { app: 0, index: 0 }, -1.0)],
                constant: t,
            },
            cmp: Cmp::Lt,
        }]],
        goal: Goal::Prove,
    }
}

/// Over 30 random networks (`act(case)` between the layers, seeded by `seed`), two
/// thresholds each (the sampled maximum +- 0.05): every Proved survives the 10,000
/// samples, every Violated is a real point of the box. Returns the counts decided.
fn checked_verdicts(seed: u64, act: impl Fn(usize) -> Activation, secs: u64) -> (usize, usize) {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let (mut proved, mut violated) = (0, 0);
    for case in 0..30 {
        let f = net(&mut r, act(case));
        let samples: Vec<f64> = (0..10_000)
            .map(|_| f.eval_f64(&[r.gen_range(-1.0..1.0), r.gen_range(-1.0..1.0)])[0])
            .collect();
        let max = samples.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), f.clone());
        let prep = Prepared::new(&nets);
        for t in [max + 0.05, max - 0.05] {
            match prove(
                &query(t, 2),
                &prep,
                &Settings {
                    timeout: Timeout::from_secs(secs),
                    ..Default::default()
                },
            )
            .unwrap()
            {
                Verdict::Proved => {
                    assert!(
                        samples.iter().all(|y| *y <= t),
                        "case {case}: Proved y <= {t} but a sample exceeds it"
                    );
                    proved += 1;
                }
                Verdict::Violated(c) => {
                    assert!(
                        f.eval_f64(&c.point.inputs[0])[0] > t
                            && c.point.inputs[0].iter().all(|v| v.abs() <= 1.0),
                        "case {case}: fake counterexample"
                    );
                    violated += 1;
                }
                Verdict::Unknown(_) => {}
            }
        }
    }
    (proved, violated)
}

#[test]
fn smooth_verdicts_are_sound() {
    let sigmoid_or_tanh = |case: usize| {
        if case.is_multiple_of(2) {
            Activation::Sigmoid
        } else {
            Activation::Tanh
        }
    };
    let (proved, violated) = checked_verdicts(21, sigmoid_or_tanh, 20);
    assert!(
        proved >= 25 && violated >= 25,
        "proved {proved}, violated {violated}"
    );
}

/// Networks with `Sign` layers (a step, VNN-COMP 2023's binarised networks): every
/// Proved survives 10,000 samples, every Violated is a real point of the box.
#[test]
fn sign_verdicts_are_sound() {
    let (proved, violated) = checked_verdicts(23, |_| Activation::Sign, 2);
    // Most are decided (at 5 s each: 17 proved, 27 violated of 60); a step's region can
    // be too thin for the attack or too close to a jump for the interval search.
    assert!(
        proved >= 8 && violated >= 15,
        "proved {proved}, violated {violated}"
    );
}

#[test]
fn published_sigmoid_network_bounds() {
    let f = samara_nn::onnx::load(samara_testkit::reference("merged_model_base.onnx")).unwrap();
    let mut nets = HashMap::new();
    nets.insert("f".to_string(), f.clone());
    let prep = Prepared::new(&nets);
    let mut q = query(1.0, 12);
    q.applications[0].n_outputs = 2;
    q.applications[0].input_box = vec![(0.0, 1.0); 12];
    // A sigmoid output never exceeds 1: proved.
    assert_eq!(
        prove(&q, &prep, &Settings::default()).unwrap(),
        Verdict::Proved
    );
    // Exceeding its value at the box centre is possible: violated, with a real point.
    let centre = f.eval_f64(&[0.5; 12])[0];
    let q2 = {
        let mut q2 = query(centre - 1e-3, 12);
        q2.applications = q.applications.clone();
        q2
    };
    match prove(&q2, &prep, &Settings::default()).unwrap() {
        Verdict::Violated(c) => assert!(f.eval_f64(&c.point.inputs[0])[0] > centre - 1e-3),
        v => panic!("{v:?}"),
    }
}
