//! Soundness against concrete evaluation, on random small ReLU networks and random
//! linear properties: every Proved survives 10,000 random samples and a PGD-style
//! attack; every Violated carries a point that really violates; every critical value's
//! bound is not beaten by any sample, and its witness is real.

use rand::{Rng, SeedableRng};
use samara_nn::{Activation, Affine, Layer, Network};
use samara_spec::normal::{Application, Cmp, Constraint, Goal, LinExpr, Query, Sense, Var};
use samara_verify::{optimise, prove, Prepared, Settings, Verdict};
use std::collections::HashMap;

fn random_net(r: &mut impl Rng, dims: &[usize], clamp: bool) -> Network {
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
    if clamp {
        layers.push(Layer::Act(Activation::Clamp { lo: -0.2, hi: 0.3 }));
    }
    Network {
        input_names: (0..dims[0]).map(|i| format!("x{i}")).collect(),
        output_names: vec!["y".into()],
        input_norm: None,
        layers,
        output_denorm: None,
    }
}

fn out_le(t: f64) -> Constraint {
    Constraint {
        expr: LinExpr {
            terms: vec![(Var::Output { app: 0, index: 0 }, 1.0)],
            constant: -t,
        },
        cmp: Cmp::Le,
    }
}

fn input_le(a: &[f64], t: f64) -> Constraint {
    Constraint {
        expr: LinExpr {
            terms: a
                .iter()
                .enumerate()
                .map(|(k, c)| (Var::Input { app: 0, index: k }, *c))
                .collect(),
            constant: -t,
        },
        cmp: Cmp::Le,
    }
}

/// Samples plus a coordinate-wise local search for the max of the output over the
/// region defined by input constraints `cs` (the attack).
fn attack_max(net: &Network, n: usize, cs: &[Constraint], r: &mut impl Rng) -> f64 {
    let ok = |x: &[f64]| {
        cs.iter().all(|c| {
            c.holds(
                |v| {
                    if let Var::Input { index, .. } = v {
                        x[index]
                    } else {
                        0.0
                    }
                },
                0.0,
            )
        })
    };
    let mut best = f64::NEG_INFINITY;
    let mut pts = Vec::new();
    for _ in 0..10_000 {
        let x: Vec<f64> = (0..n).map(|_| r.gen_range(-1.0..1.0)).collect();
        if ok(&x) {
            let y = net.eval_f64(&x)[0];
            if y > best {
                best = y;
                pts.push(x);
            }
        }
    }
    // Local ascent from the best few samples.
    for mut x in pts.into_iter().rev().take(5) {
        let mut step = 0.1;
        for _ in 0..200 {
            let mut improved = false;
            for k in 0..n {
                for s in [-step, step] {
                    let mut y = x.clone();
                    y[k] = (y[k] + s).clamp(-1.0, 1.0);
                    if ok(&y) && net.eval_f64(&y)[0] > net.eval_f64(&x)[0] {
                        x = y;
                        improved = true;
                    }
                }
            }
            if !improved {
                step *= 0.5;
            }
        }
        best = best.max(net.eval_f64(&x)[0]);
    }
    best
}

#[test]
fn random_networks_verdicts_and_bounds_are_sound() {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let (mut proved, mut violated) = (0, 0);
    for case in 0..40 {
        let n = 3;
        let net = random_net(&mut r, &[n, 8, 6, 1], case % 4 == 0);
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), net.clone());
        let prep = Prepared::new(&nets);
        let a: Vec<f64> = (0..n).map(|_| r.gen_range(-1.0..1.0)).collect();
        let pre = vec![input_le(&a, r.gen_range(-0.5..0.5))];
        let app = Application {
            network: "f".into(),
            n_inputs: n,
            n_outputs: 1,
            input_box: vec![(-1.0, 1.0); n],
        };
        // Critical: sup of the output over the precondition region.
        let q = Query {
            name: format!("max{case}"),
            applications: vec![app.clone()],
            free_vars: vec![],
            region: vec![pre.clone()],
            goal: Goal::Optimise {
                objective: LinExpr {
                    terms: vec![(Var::Output { app: 0, index: 0 }, 1.0)],
                    constant: 0.0,
                },
                sense: Sense::Max,
                label: "y".into(),
            },
        };
        let c = optimise(&q, &prep, &Settings::default()).unwrap();
        let sampled = attack_max(&net, n, &pre, &mut r);
        assert!(c.complete, "case {case}");
        assert!(
            c.bound >= sampled - 1e-12,
            "case {case}: bound {} below a sampled value {sampled}",
            c.bound
        );
        let w = c.witness.as_ref().unwrap();
        assert_eq!(net.eval_f64(&w.inputs[0])[0], w.outputs[0][0]);
        assert!(w.satisfies(&pre), "witness outside the region");
        assert!(
            (c.bound - c.value.unwrap()).abs() <= 1e-6,
            "case {case}: gap {} vs {}",
            c.bound,
            c.value.unwrap()
        );
        // Prove "precondition => y <= t" for t just above and just below the maximum.
        for (t, expect_proved) in [(c.bound + 1e-6, true), (c.value.unwrap() - 1e-3, false)] {
            let mut region = pre.clone();
            region.push(Constraint {
                expr: LinExpr {
                    terms: vec![(Var::Output { app: 0, index: 0 }, -1.0)],
                    constant: t,
                },
                cmp: Cmp::Lt,
            });
            let pq = Query {
                name: format!("p{case}"),
                applications: vec![app.clone()],
                free_vars: vec![],
                region: vec![region.clone()],
                goal: Goal::Prove,
            };
            match prove(&pq, &prep, &Settings::default()).unwrap() {
                Verdict::Proved => {
                    assert!(
                        expect_proved,
                        "case {case}: proved y <= {t} but a witness reaches {}",
                        c.value.unwrap()
                    );
                    assert!(
                        sampled <= t,
                        "case {case}: Proved but the attack found {sampled} > {t}"
                    );
                    proved += 1;
                }
                Verdict::Violated(cx) => {
                    let y = net.eval_f64(&cx.point.inputs[0])[0];
                    assert!(
                        y > t && pre.iter().all(|c| c.holds(|v| cx.point.value(v), 0.0)),
                        "case {case}: fake counterexample"
                    );
                    assert!(
                        !expect_proved,
                        "case {case}: violated below the sound bound"
                    );
                    violated += 1;
                }
                Verdict::Unknown(u) => panic!("case {case}: unknown {u}"),
            }
        }
        let _ = out_le;
    }
    assert_eq!((proved, violated), (40, 40));
}
