//! Issue 17 at the engine: a result only from a completed argument. Every search cut
//! short (time, nodes), every value outside the encoding and every point that is in the
//! counterexample region only at the rounding level gives `Unknown` with a typed reason;
//! a query naming a variable that does not exist is an error, never a panic.

use rand::{Rng, SeedableRng};
use samara_nn::{Activation, Affine, Layer, Network};
use samara_spec::normal::{Application, Cmp, Constraint, Goal, LinExpr, Query, Sense, Var};
use samara_verify::{
    empty_input_box, optimise, premise_empty, prove, vacuity, Prepared, Settings, Timeout,
    UnknownReason, Verdict, VerifyError,
};
use std::collections::HashMap;

fn mlp(seed: u64, dims: &[usize]) -> Network {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut layers = Vec::new();
    for (k, w) in dims.windows(2).enumerate() {
        let (i, o) = (w[0], w[1]);
        layers.push(Layer::Affine(Affine::new(
            i,
            o,
            (0..i * o).map(|_| r.gen_range(-1.0..1.0)).collect(),
            (0..o).map(|_| r.gen_range(-0.3..0.3)).collect(),
        )));
        if k + 2 < dims.len() {
            layers.push(Layer::Act(Activation::Relu));
        }
    }
    Network {
        input_names: (0..dims[0]).map(|i| format!("x{i}")).collect(),
        output_names: vec!["y".into()],
        input_norm: None,
        layers,
        output_denorm: None,
    }
}

fn out(index: usize) -> Var {
    Var::Output { app: 0, index }
}

fn query(n: usize, region: Vec<Vec<Constraint>>, goal: Goal, free: usize) -> Query {
    Query {
        name: "q".into(),
        applications: vec![Application {
            network: "f".into(),
            n_inputs: n,
            n_outputs: 1,
            input_box: vec![(-1.0, 1.0); n],
        }],
        free_vars: (0..free).map(|k| (format!("p{k}"), -10.0, 10.0)).collect(),
        region,
        goal,
    }
}

fn c(terms: Vec<(Var, f64)>, constant: f64, cmp: Cmp) -> Constraint {
    Constraint {
        expr: LinExpr { terms, constant },
        cmp,
    }
}

fn nets(n: Network) -> HashMap<String, Network> {
    let mut m = HashMap::new();
    m.insert("f".to_string(), n);
    m
}

/// A property that needs branching on a wide random network (f(x) >= t for t a bit
/// below the true minimum is proved only after a search).
fn hard() -> (HashMap<String, Network>, Query) {
    let m = nets(mlp(7, &[4, 24, 24, 1]));
    let q = query(
        4,
        vec![vec![c(vec![(out(0), 1.0)], 50.0, Cmp::Lt)]],
        Goal::Prove,
        0,
    );
    (m, q)
}

#[test]
fn no_time_or_no_nodes_is_unknown_never_proved() {
    let (m, q) = hard();
    let prep = Prepared::new(&m);
    let full = prove(&q, &prep, &Settings::default()).unwrap();
    assert_eq!(full, Verdict::Proved, "the reference answer");
    // A NaN or negative limit cannot reach the search: `Timeout` refuses it.
    assert!(Timeout::from_secs_f64(f64::NAN).is_err());
    assert!(Timeout::from_secs_f64(-1.0).is_err());
    for (s, kind) in [
        (
            Settings {
                timeout: Timeout::from_secs(0),
                ..Default::default()
            },
            "timeout",
        ),
        (
            Settings {
                max_nodes: 0,
                ..Default::default()
            },
            "node_limit",
        ),
    ] {
        match prove(&q, &prep, &s).unwrap() {
            Verdict::Unknown(r) => assert_eq!(r.kind(), kind, "{r}"),
            v => panic!("{s:?}: {v:?}"),
        }
    }
}

#[test]
fn critical_values_cut_short_are_incomplete_with_a_reason() {
    let m = nets(mlp(3, &[3, 16, 16, 1]));
    let prep = Prepared::new(&m);
    // sup { p : f(x) <= p - 100 } over the box: with no time, no claim.
    let q = query(
        3,
        vec![vec![c(
            vec![(out(0), 1.0), (Var::Free(0), -1.0)],
            100.0,
            Cmp::Le,
        )]],
        Goal::Optimise {
            objective: LinExpr {
                terms: vec![(Var::Free(0), 1.0)],
                constant: 0.0,
            },
            sense: Sense::Max,
            label: "p".into(),
        },
        1,
    );
    let r = optimise(
        &q,
        &prep,
        &Settings {
            timeout: Timeout::from_secs(0),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(!r.complete);
    assert!(
        matches!(r.unknown, Some(UnknownReason::Timeout { .. })),
        "{r:?}"
    );
    let r = optimise(
        &q,
        &prep,
        &Settings {
            max_nodes: 0,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(!r.complete);
    assert!(
        matches!(r.unknown, Some(UnknownReason::NodeLimit { .. })),
        "{r:?}"
    );
}

#[test]
fn huge_or_non_finite_values_are_out_of_range() {
    let (m, q) = hard();
    let prep = Prepared::new(&m);
    for v in [1e20, f64::INFINITY, f64::NAN] {
        let mut q2 = q.clone();
        q2.region[0][0].expr.terms[0].1 = v;
        match prove(&q2, &prep, &Settings::default()).unwrap() {
            Verdict::Unknown(UnknownReason::OutOfRange { .. }) => {}
            other => panic!("{v}: {other:?}"),
        }
        let mut q3 = q.clone();
        q3.applications[0].input_box[0] = (-v, v);
        assert!(matches!(
            prove(&q3, &prep, &Settings::default()).unwrap(),
            Verdict::Unknown(UnknownReason::OutOfRange { .. })
        ));
    }
}

#[test]
fn variables_beyond_the_network_are_errors_not_panics() {
    let (m, q) = hard();
    let prep = Prepared::new(&m);
    for v in [
        Var::Output { app: 0, index: 1 },
        Var::Output { app: 0, index: 5 },
        Var::Input { app: 0, index: 4 },
        Var::Input { app: 1, index: 0 },
        Var::Free(0),
    ] {
        let mut q2 = q.clone();
        q2.region[0].push(c(vec![(v, 1.0)], -0.5, Cmp::Le));
        match prove(&q2, &prep, &Settings::default()) {
            Err(VerifyError::Variable { detail, .. }) => assert!(!detail.is_empty()),
            other => panic!("{v:?}: {other:?}"),
        }
    }
    let mut q2 = q.clone();
    q2.applications[0].input_box.pop();
    assert!(matches!(
        prove(&q2, &prep, &Settings::default()),
        Err(VerifyError::Variable { .. })
    ));
}

/// f(x) = relu(x) on x in [1, 1]: `0.3 f - 0.1 x - 0.2 x < 0` is `0 < 0` in exact
/// arithmetic over the intended reals but -2.8e-17 < 0 with the f64 coefficients: a
/// counterexample at the rounding level only, which must not be reported as violated.
#[test]
fn rounding_level_points_are_not_counterexamples() {
    let n = Network {
        input_names: vec!["x".into()],
        output_names: vec!["y".into()],
        input_norm: None,
        layers: vec![
            Layer::Affine(Affine::new(1, 1, vec![1.0], vec![0.0])),
            Layer::Act(Activation::Relu),
        ],
        output_denorm: None,
    };
    let m = nets(n);
    let prep = Prepared::new(&m);
    let x = Var::Input { app: 0, index: 0 };
    let mut q = query(
        1,
        vec![vec![c(
            vec![(out(0), 0.3), (x, -0.1), (x, -0.2)],
            0.0,
            Cmp::Lt,
        )]],
        Goal::Prove,
        0,
    );
    q.applications[0].input_box = vec![(1.0, 1.0)];
    let (a, b, d) = (std::hint::black_box(0.3f64), 0.1, 0.2);
    assert!(a - b - d < 0.0, "the premise of the test");
    match prove(&q, &prep, &Settings::default()).unwrap() {
        Verdict::Violated(cx) => panic!("rounding-level counterexample reported: {cx:?}"),
        Verdict::Unknown(r) => assert!(matches!(r.kind(), "rounding" | "thin_region"), "{r}"),
        Verdict::Proved => {}
    }
    // A real violation (margin 0.1) is still reported, with its margin.
    q.region[0][0].expr.constant = -0.1;
    match prove(&q, &prep, &Settings::default()).unwrap() {
        Verdict::Violated(cx) => assert!(cx.margin < -0.05, "{cx:?}"),
        v => panic!("{v:?}"),
    }
}

#[test]
fn empty_domains_are_vacuous_and_rounding_empty_boxes_are_not() {
    let (m, mut q) = hard();
    let prep = Prepared::new(&m);
    q.applications[0].input_box[2] = (0.5, 0.4);
    assert_eq!(empty_input_box(&q), Some((0, 2)));
    assert_eq!(
        prove(&q, &prep, &Settings::default()).unwrap(),
        Verdict::Proved
    );
    // Empty by one ulp only: widened, searched, not called vacuous.
    q.applications[0].input_box[2] = (0.5 + f64::EPSILON, 0.5);
    assert_eq!(empty_input_box(&q), None);
    // f >= -50 everywhere on the box (see `hard`), so still proved, non-vacuously.
    assert_eq!(
        prove(&q, &prep, &Settings::default()).unwrap(),
        Verdict::Proved
    );
}

fn inp(index: usize) -> Var {
    Var::Input { app: 0, index }
}

/// Issue 35 item 9: a premise no domain point meets makes `Proved` vacuous. The premise
/// `x0 + x1 >= t` over the box [-1, 1]^4 is empty exactly when t > 2 (the largest
/// x0 + x1 of the box, by hand); a premise met by one point (t = 2, the corner) or
/// more must never be called empty, and an undecided one is not either.
#[test]
fn premises_empty_over_the_domain_are_vacuous_and_only_those() {
    let (m, _) = hard();
    let prep = Prepared::new(&m);
    let s = Settings {
        timeout: Timeout::from_secs(10),
        ..Default::default()
    };
    let region = |t: f64, strict: bool| {
        // x0 + x1 >= t (or > t) and f(x) < 50 (the negated conclusion).
        vec![vec![
            c(
                vec![(inp(0), -1.0), (inp(1), -1.0)],
                t,
                if strict { Cmp::Lt } else { Cmp::Le },
            ),
            c(vec![(out(0), 1.0)], -50.0, Cmp::Lt),
        ]]
    };
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(35);
    for k in 0..24 {
        let t = match k {
            0 => 2.0,
            1 => 2.0 - 1e-9,
            2 => 2.0 + 1e-3,
            _ => r.gen_range(1.5..2.5),
        };
        for strict in [false, true] {
            let q = query(4, region(t, strict), Goal::Prove, 0);
            let empty = premise_empty(&q, &prep, &s).unwrap();
            // Never empty when a point meets it (the corner (1, 1) reaches 2).
            if t < 2.0 || (t == 2.0 && !strict) {
                assert!(
                    !empty,
                    "t = {t}, strict {strict}: a point meets the premise"
                );
            }
            if t > 2.0 + 1e-6 {
                assert!(empty, "t = {t}: no point of the box reaches x0 + x1 = t");
                assert!(vacuity(&q, &prep, &s).unwrap().is_some());
                assert_eq!(prove(&q, &prep, &s).unwrap(), Verdict::Proved);
            }
        }
    }
    // A conclusion-only property (no premise) is never vacuous.
    let q = query(
        4,
        vec![vec![c(vec![(out(0), 1.0)], 50.0, Cmp::Lt)]],
        Goal::Prove,
        0,
    );
    assert_eq!(vacuity(&q, &prep, &s).unwrap(), None);
}
