//! The one-network optimiser ([`samara_verify::single`], `samara_bounds::optimise`)
//! against an independent engine and against sampling: on random small ReLU networks
//! with random boxes, input constraints, a free variable and an output constraint, its
//! value agrees with the ReLU-phase engine's (Clarabel LPs, `engine.rs`) and its sound
//! bound is beaten neither by that engine's witness nor by 10,000 random feasible
//! points; its result does not depend on the number of threads; a time limit holds.

use rand::{Rng, SeedableRng};
use samara_nn::{Activation, Network};
use samara_spec::normal::{Cmp, Constraint, LinExpr, Var};
use samara_verify::engine::{BabResult, Limits, Point, Problem};
use samara_verify::net::PwlNet;
use samara_verify::single::solve_single;
use samara_verify::Timeout;

/// A random query on `net`: box, `a . x <= c`, `x0 + x1 - t >= 0` with `t` free, the
/// output below a sampled median; objective `t + b . x + e y` maximised.
struct Case {
    net: Network,
    boxes: Vec<(f64, f64)>,
    free: Vec<(f64, f64)>,
    constraints: Vec<Constraint>,
    objective: LinExpr,
}

fn case(seed: u64, dims: &[usize]) -> Case {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let net = Network::random_mlp(dims, Activation::Relu, 1.0, 0.3, &mut r);
    let n = dims[0];
    let boxes: Vec<(f64, f64)> = (0..n)
        .map(|_| {
            let l = r.gen_range(-1.0..0.5);
            (l, l + r.gen_range(0.2..1.5))
        })
        .collect();
    let mut ys: Vec<f64> = (0..200)
        .map(|_| {
            let x: Vec<f64> = boxes.iter().map(|b| r.gen_range(b.0..=b.1)).collect();
            net.eval_f64(&x)[0]
        })
        .collect();
    ys.sort_by(f64::total_cmp);
    let thr = ys[100];
    let inp = |k: usize| Var::Input { app: 0, index: k };
    let a: Vec<f64> = (0..n).map(|_| r.gen_range(-1.0..1.0)).collect();
    let mid: f64 = a
        .iter()
        .zip(&boxes)
        .map(|(c, b)| c * 0.5 * (b.0 + b.1))
        .sum();
    let constraints = vec![
        Constraint {
            expr: LinExpr {
                terms: vec![(Var::Output { app: 0, index: 0 }, 1.0)],
                constant: -thr,
            },
            cmp: if seed.is_multiple_of(2) {
                Cmp::Lt
            } else {
                Cmp::Le
            },
        },
        Constraint {
            expr: LinExpr {
                terms: a.iter().enumerate().map(|(k, c)| (inp(k), *c)).collect(),
                constant: -mid - 0.2,
            },
            cmp: Cmp::Le,
        },
        Constraint {
            expr: LinExpr {
                terms: vec![(inp(0), -1.0), (inp(1), -1.0), (Var::Free(0), 1.0)],
                constant: 0.0,
            },
            cmp: Cmp::Le,
        },
    ];
    let mut terms: Vec<(Var, f64)> = (0..n).map(|k| (inp(k), r.gen_range(-0.5..0.5))).collect();
    terms.push((Var::Free(0), 1.0));
    terms.push((Var::Output { app: 0, index: 0 }, r.gen_range(-1.0..1.0)));
    Case {
        net,
        boxes,
        free: vec![(-3.0, 3.0)],
        constraints,
        objective: LinExpr {
            terms,
            constant: 0.5,
        },
    }
}

fn problem<'a>(c: &'a Case, pwl: &'a PwlNet) -> Problem<'a> {
    Problem {
        nets: vec![pwl],
        plain: vec![&c.net],
        boxes: vec![c.boxes.clone()],
        free: c.free.clone(),
        constraints: c.constraints.clone(),
        objective: Some(c.objective.clone()),
        floor: f64::NEG_INFINITY,
        stop_when: None,
    }
}

fn limits(seconds: f64) -> Limits {
    Limits {
        timeout: Timeout::from_secs_f64(seconds).unwrap(),
        ..Limits::default()
    }
}

fn new_engine(c: &Case, pwl: &PwlNet) -> BabResult {
    solve_single(&problem(c, pwl), limits(60.0)).expect("a one-network problem")
}

#[test]
fn agrees_with_the_phase_engine_and_sampling() {
    let mut compared = 0;
    for seed in 0..16u64 {
        let dims: &[usize] = if seed.is_multiple_of(2) {
            &[4, 12, 8, 1]
        } else {
            &[3, 16, 8, 1]
        };
        let c = case(seed, dims);
        let pwl = PwlNet::from_network(&c.net).unwrap();
        let new = new_engine(&c, &pwl);
        let old = problem(&c, &pwl).solve(limits(60.0));
        assert!(new.complete, "seed {seed}: {:?}", new.stop);
        assert!(old.complete, "seed {seed}: old engine incomplete");
        let nv = new.best.as_ref().map(|b| b.1);
        let ov = old.best.as_ref().map(|b| b.1);
        // Each engine's bound is beaten by neither engine's witness.
        for v in [nv, ov].into_iter().flatten() {
            assert!(
                v <= new.upper + 1e-9 * (1.0 + v.abs()),
                "seed {seed}: {v} > {}",
                new.upper
            );
            assert!(
                v <= old.upper + 1e-9 * (1.0 + v.abs()),
                "seed {seed}: {v} > {}",
                old.upper
            );
        }
        match (nv, ov) {
            (Some(a), Some(b)) => {
                assert!(
                    (a - b).abs() <= 1e-5 * (1.0 + b.abs()),
                    "seed {seed}: {a} vs {b}"
                );
                compared += 1;
            }
            (None, None) => {}
            (a, b) => panic!("seed {seed}: new {a:?}, old {b:?}"),
        }
        // The witness is real.
        if let Some((p, v)) = &new.best {
            assert!(p.satisfies(&c.constraints), "seed {seed}");
            let e = c.objective.eval(|x| p.value(x));
            assert_eq!(e, *v, "seed {seed}");
            assert_eq!(p.outputs[0], c.net.eval_f64(&p.inputs[0]));
        }
        // No feasible sample beats the sound bound.
        let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(1000 + seed);
        for _ in 0..10_000 {
            let x: Vec<f64> = c.boxes.iter().map(|b| r.gen_range(b.0..=b.1)).collect();
            let t = r.gen_range(c.free[0].0..=c.free[0].1);
            let p = Point {
                outputs: vec![c.net.eval_f64(&x)],
                inputs: vec![x],
                free: vec![t],
            };
            if p.satisfies(&c.constraints) {
                let v = c.objective.eval(|x| p.value(x));
                assert!(
                    v <= new.upper,
                    "seed {seed}: sample {v} above bound {}",
                    new.upper
                );
            }
        }
    }
    assert!(compared >= 8, "too few feasible cases compared: {compared}");
}

#[test]
fn same_result_with_one_and_two_threads() {
    for seed in [3u64, 4] {
        let c = case(seed, &[4, 16, 8, 1]);
        let pwl = PwlNet::from_network(&c.net).unwrap();
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| new_engine(&c, &pwl))
        };
        let (a, b) = (run(1), run(2));
        assert_eq!(a.best.as_ref().map(|b| b.1), b.best.as_ref().map(|b| b.1));
        assert_eq!(a.upper, b.upper);
        assert_eq!(a.nodes, b.nodes);
    }
}

#[test]
fn a_time_limit_holds() {
    // A wide random network with a tight output constraint: not solved in 0.3 s.
    let c = case(7, &[6, 64, 32, 1]);
    let pwl = PwlNet::from_network(&c.net).unwrap();
    let t = std::time::Instant::now();
    let r = solve_single(&problem(&c, &pwl), limits(0.3)).unwrap();
    let dt = t.elapsed().as_secs_f64();
    assert!(dt < 1.3, "took {dt} s for a 0.3 s limit");
    if !r.complete {
        assert!(matches!(
            r.stop,
            Some(samara_verify::UnknownReason::Timeout { .. })
        ));
    }
}
