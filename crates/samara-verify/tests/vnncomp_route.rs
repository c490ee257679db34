//! Engine routing (`route::prove_routed`): box-shaped queries go to the input-split
//! engine, others to the ReLU-phase engine, and both agree with each other on random
//! networks where both apply; an infinite time limit is accepted.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_nn::{Activation, Network};
use samara_spec::normal::{Application, Cmp, Constraint, Goal, LinExpr, Query, Var};
use samara_verify::route::{prove_routed, Engine};
use samara_verify::{prove, Prepared, Settings, Timeout, Verdict};
use std::collections::HashMap;

fn query(input_box: Vec<(f64, f64)>, terms: Vec<(Var, f64)>, constant: f64) -> Query {
    Query {
        name: "q".into(),
        applications: vec![Application {
            network: "f".into(),
            n_inputs: input_box.len(),
            n_outputs: 2,
            input_box,
        }],
        free_vars: vec![],
        region: vec![vec![Constraint {
            expr: LinExpr { terms, constant },
            cmp: Cmp::Le,
        }]],
        goal: Goal::Prove,
    }
}

#[test]
fn box_queries_take_the_input_split_route_and_others_the_phase_route() {
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let out = |i| Var::Output { app: 0, index: i };
    let inp = |i| Var::Input { app: 0, index: i };
    for trial in 0..12 {
        let net = Network::random_mlp(&[3, 8, 6, 2], Activation::Relu, 1.0, 0.5, &mut rng);
        let bx: Vec<(f64, f64)> = (0..3).map(|_| (-1.0, 1.0)).collect();
        let t: f64 = rng.gen_range(-1.0..1.0);
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), net);
        let prep = Prepared::new(&nets);
        let s = Settings {
            timeout: if trial % 2 == 0 {
                Timeout::none()
            } else {
                Timeout::from_secs(60)
            },
            ..Default::default()
        };
        // y0 - y1 <= t: box-shaped.
        let qb = query(bx.clone(), vec![(out(0), 1.0), (out(1), -1.0)], -t);
        let (v, e) = prove_routed(&qb, &prep, &s).unwrap();
        assert_eq!(e, Engine::InputSplit, "trial {trial}");
        let reference = prove(&qb, &prep, &Settings::default()).unwrap();
        assert_eq!(
            matches!(v, Verdict::Proved),
            matches!(reference, Verdict::Proved),
            "trial {trial}: {v:?} vs {reference:?}"
        );
        if let Verdict::Violated(c) = &v {
            assert_eq!(c.exact, Some(true));
        }
        // y0 - y1 + x0 <= t mixes an input with the outputs: the phase route.
        let qp = query(bx, vec![(out(0), 1.0), (out(1), -1.0), (inp(0), 1.0)], -t);
        let (v, e) = prove_routed(&qp, &prep, &s).unwrap();
        assert_eq!(e, Engine::Phase, "trial {trial}");
        assert_eq!(v, prove(&qp, &prep, &s).unwrap(), "trial {trial}");
    }
}
