//! The exact engine ([`samara_verify::single`], `samara_bounds::optimise`) against an
//! independent computation and against sampling: on random small ReLU networks with
//! random boxes, input constraints, a free variable and an output constraint (one
//! network application, or two different networks in one relational query), its value
//! agrees with the enumeration of every activation pattern (on each pattern the network
//! is affine and the question one LP, solved by Clarabel through `samara_verify::lp`),
//! and its sound bound is beaten neither by that enumeration's optimum nor by 10,000
//! random feasible points; its result does not depend on the number of threads; a time
//! limit holds.

use rand::{Rng, SeedableRng};
use samara_nn::{Activation, Network};
use samara_spec::normal::{Cmp, Constraint, LinExpr, Var};
use samara_verify::lp::{Lp, LpResult};
use samara_verify::net::PwlNet;
use samara_verify::point::{BabResult, Limits, Point, Problem};
use samara_verify::single::{product, solve};
use samara_verify::Timeout;

/// A random query over the networks `nets` (applications 0, 1, ...): boxes, `a . x <=
/// c` over all inputs, `x0 + x1 - t >= 0` with `t` free (inputs of the first
/// application), the sum of the first outputs below a sampled median; objective
/// `t + b . x + e . y` maximised.
struct Case {
    nets: Vec<Network>,
    boxes: Vec<Vec<(f64, f64)>>,
    free: Vec<(f64, f64)>,
    constraints: Vec<Constraint>,
    objective: LinExpr,
}

fn case(seed: u64, dims: &[&[usize]]) -> Case {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let nets: Vec<Network> = dims
        .iter()
        .map(|d| Network::random_mlp(d, Activation::Relu, 1.0, 0.3, &mut r))
        .collect();
    let boxes: Vec<Vec<(f64, f64)>> = dims
        .iter()
        .map(|d| {
            (0..d[0])
                .map(|_| {
                    let l = r.gen_range(-1.0..0.5);
                    (l, l + r.gen_range(0.2..1.5))
                })
                .collect()
        })
        .collect();
    let ysum = |nets: &[Network], xs: &[Vec<f64>]| -> f64 {
        nets.iter().zip(xs).map(|(n, x)| n.eval_f64(x)[0]).sum()
    };
    let mut ys: Vec<f64> = (0..200)
        .map(|_| {
            let xs: Vec<Vec<f64>> = boxes
                .iter()
                .map(|b| b.iter().map(|b| r.gen_range(b.0..=b.1)).collect())
                .collect();
            ysum(&nets, &xs)
        })
        .collect();
    ys.sort_by(f64::total_cmp);
    let thr = ys[100];
    let inputs: Vec<Var> = boxes
        .iter()
        .enumerate()
        .flat_map(|(app, b)| (0..b.len()).map(move |index| Var::Input { app, index }))
        .collect();
    let flat: Vec<(f64, f64)> = boxes.iter().flatten().copied().collect();
    let a: Vec<f64> = inputs.iter().map(|_| r.gen_range(-1.0..1.0)).collect();
    let mid: f64 = a
        .iter()
        .zip(&flat)
        .map(|(c, b)| c * 0.5 * (b.0 + b.1))
        .sum();
    let outs: Vec<(Var, f64)> = (0..nets.len())
        .map(|app| (Var::Output { app, index: 0 }, 1.0))
        .collect();
    let inp = |k: usize| Var::Input { app: 0, index: k };
    let constraints = vec![
        Constraint {
            expr: LinExpr {
                terms: outs,
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
                terms: inputs.iter().zip(&a).map(|(v, c)| (*v, *c)).collect(),
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
    let mut terms: Vec<(Var, f64)> = inputs
        .iter()
        .map(|v| (*v, r.gen_range(-0.5..0.5)))
        .collect();
    terms.push((Var::Free(0), 1.0));
    for app in 0..nets.len() {
        terms.push((Var::Output { app, index: 0 }, r.gen_range(-1.0..1.0)));
    }
    Case {
        nets,
        boxes,
        free: vec![(-3.0, 3.0)],
        constraints,
        objective: LinExpr {
            terms,
            constant: 0.5,
        },
    }
}

fn problem<'a>(c: &'a Case, pwl: &'a [PwlNet]) -> Problem<'a> {
    Problem {
        nets: pwl.iter().collect(),
        plain: c.nets.iter().collect(),
        boxes: c.boxes.clone(),
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

fn pwls(c: &Case) -> Vec<PwlNet> {
    c.nets
        .iter()
        .map(|n| PwlNet::from_network(n).unwrap())
        .collect()
}

/// An affine form over the variables `(inputs of every application, free)`.
type Form = (Vec<f64>, f64);

/// The reference: every activation pattern of every application, one LP each. Returns
/// (the best LP optimum at its primal point, the largest sound LP bound, patterns
/// whose LP failed).
fn enumerate(c: &Case, pwl: &[PwlNet]) -> (Option<f64>, f64, usize) {
    let nx: usize = c.boxes.iter().map(|b| b.len()).sum();
    let n = nx + c.free.len();
    let relus: usize = pwl
        .iter()
        .flat_map(|p| &p.maps)
        .filter(|m| m.1)
        .map(|m| m.0.out)
        .sum();
    assert!(relus <= 12, "too many ReLUs to enumerate: {relus}");
    let (mut best, mut upper, mut failed) = (None::<f64>, f64::NEG_INFINITY, 0);
    for pattern in 0u32..(1 << relus) {
        let mut bit = 0;
        let mut rows: Vec<Form> = Vec::new();
        let mut outs: Vec<Vec<Form>> = Vec::new();
        let mut off = 0;
        for p in pwl {
            let mut a: Vec<Form> = (0..p.n_inputs())
                .map(|j| {
                    let mut f = vec![0.0; n];
                    f[off + j] = 1.0;
                    (f, 0.0)
                })
                .collect();
            off += p.n_inputs();
            for (m, relu) in &p.maps {
                let z: Vec<Form> = (0..m.out)
                    .map(|i| {
                        let mut f = vec![0.0; n];
                        let mut d = m.b[i];
                        for (j, (aj, dj)) in a.iter().enumerate() {
                            let w = m.weight(i, j);
                            for (fk, ak) in f.iter_mut().zip(aj) {
                                *fk += w * ak;
                            }
                            d += w * dj;
                        }
                        (f, d)
                    })
                    .collect();
                a = if *relu {
                    z.into_iter()
                        .map(|(f, d)| {
                            let on = pattern >> bit & 1 == 1;
                            bit += 1;
                            if on {
                                rows.push((f.iter().map(|v| -v).collect(), -d));
                                (f, d)
                            } else {
                                rows.push((f, d));
                                (vec![0.0; n], 0.0)
                            }
                        })
                        .collect()
                } else {
                    z
                };
            }
            outs.push(a);
        }
        let offs: Vec<usize> = c
            .boxes
            .iter()
            .scan(0, |s, b| {
                let o = *s;
                *s += b.len();
                Some(o)
            })
            .collect();
        let form = |e: &LinExpr| -> Form {
            let mut f = vec![0.0; n];
            let mut d = e.constant;
            for (v, a) in &e.terms {
                match *v {
                    Var::Input { app, index } => f[offs[app] + index] += a,
                    Var::Free(k) => f[nx + k] += a,
                    Var::Output { app, index } => {
                        let (g, e) = &outs[app][index];
                        for (fk, gk) in f.iter_mut().zip(g) {
                            *fk += a * gk;
                        }
                        d += a * e;
                    }
                }
            }
            (f, d)
        };
        for k in &c.constraints {
            rows.push(form(&k.expr));
        }
        let sparse = |f: &[f64]| -> Vec<(usize, f64)> {
            f.iter()
                .enumerate()
                .filter(|(_, v)| **v != 0.0)
                .map(|(j, v)| (j, *v))
                .collect()
        };
        let (obj, d0) = form(&c.objective);
        let flat: Vec<(f64, f64)> = c.boxes.iter().flatten().chain(&c.free).copied().collect();
        let lp = Lp {
            n,
            eq: Vec::new(),
            le: rows.iter().map(|(f, d)| (sparse(f), -d)).collect(),
            lo: flat.iter().map(|b| b.0).collect(),
            hi: flat.iter().map(|b| b.1).collect(),
            c: obj.clone(),
        };
        match lp.solve() {
            LpResult::Infeasible => {}
            LpResult::Bound { upper: u, x } => {
                upper = upper.max(u + d0);
                let v = d0 + obj.iter().zip(&x).map(|(a, b)| a * b).sum::<f64>();
                best = Some(best.map_or(v, |b| b.max(v)));
            }
            LpResult::Failed { upper: u } => {
                upper = upper.max(u + d0);
                failed += 1;
            }
        }
    }
    (best, upper, failed)
}

/// The checks of one case; returns whether a value was compared.
fn check(seed: u64, c: &Case) -> bool {
    let pwl = pwls(c);
    let new: BabResult = solve(&problem(c, &pwl), limits(60.0));
    assert!(new.complete, "seed {seed}: {:?}", new.stop);
    let (rv, rup, failed) = enumerate(c, &pwl);
    let nv = new.best.as_ref().map(|b| b.1);
    // The engine's bound is beaten neither by the enumeration's optimum nor by its
    // witness; the enumeration's bound is not beaten by the engine's witness.
    for v in [nv, rv].into_iter().flatten() {
        assert!(
            v <= new.upper + 1e-7 * (1.0 + v.abs()),
            "seed {seed}: {v} > {}",
            new.upper
        );
    }
    if let Some(v) = nv {
        assert!(
            v <= rup + 1e-7 * (1.0 + v.abs()),
            "seed {seed}: {v} > {rup}"
        );
    }
    let compared = match (nv, rv) {
        // Leaves where no point was accepted (the engine's answer is then "thin region",
        // not a critical value): its witness is a lower bound only.
        (Some(a), Some(b)) if new.thin_leaves > 0 => {
            assert!(a <= b + 1e-7 * (1.0 + b.abs()), "seed {seed}: {a} > {b}");
            false
        }
        (Some(a), Some(b)) => {
            assert!(
                (a - b).abs() <= 1e-5 * (1.0 + b.abs()),
                "seed {seed}: engine {a} vs enumeration {b} (bound {}, {} thin leaves)",
                new.upper,
                new.thin_leaves
            );
            true
        }
        (None, None) => false,
        (None, Some(b)) if failed == 0 => {
            // A feasible pattern of measure zero (an LP optimum on a strict
            // constraint's boundary) is no witness: the engine must not claim less.
            assert!(new.upper >= b - 1e-7 * (1.0 + b.abs()), "seed {seed}");
            false
        }
        (a, b) => panic!("seed {seed}: engine {a:?}, enumeration {b:?} ({failed} failed)"),
    };
    // The witness is real.
    if let Some((p, v)) = &new.best {
        assert!(p.satisfies(&c.constraints), "seed {seed}");
        let e = c.objective.eval(|x| p.value(x));
        assert_eq!(e, *v, "seed {seed}");
        for (k, net) in c.nets.iter().enumerate() {
            assert_eq!(p.outputs[k], net.eval_f64(&p.inputs[k]));
        }
    }
    // No feasible sample beats the sound bound.
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(1000 + seed);
    for _ in 0..10_000 {
        let xs: Vec<Vec<f64>> = c
            .boxes
            .iter()
            .map(|b| b.iter().map(|b| r.gen_range(b.0..=b.1)).collect())
            .collect();
        let t = r.gen_range(c.free[0].0..=c.free[0].1);
        let p = Point {
            outputs: c.nets.iter().zip(&xs).map(|(n, x)| n.eval_f64(x)).collect(),
            inputs: xs,
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
    compared
}

#[test]
fn one_network_agrees_with_pattern_enumeration_and_sampling() {
    let mut compared = 0;
    for seed in 0..16u64 {
        let dims: &[usize] = if seed.is_multiple_of(2) {
            &[4, 6, 4, 1]
        } else {
            &[3, 8, 3, 1]
        };
        compared += check(seed, &case(seed, &[dims])) as usize;
    }
    assert!(compared >= 8, "too few feasible cases compared: {compared}");
}

/// P1's shape, maximise the free `t` alone (`x0 + x1 >= t`) with the output bound
/// pushed down so that the region is often empty: a node whose bound falls below `t`'s
/// least value is closed as empty (no incumbent is needed), so the searches that end
/// without a point must agree with the enumeration (no feasible pattern) and with
/// sampling, and those that find one with its value.
#[test]
fn objectives_without_outputs_agree_when_the_region_is_empty_or_not() {
    let (mut empty, mut found) = (0, 0);
    for seed in 200..216u64 {
        let dims: &[usize] = if seed.is_multiple_of(2) {
            &[4, 6, 4, 1]
        } else {
            &[3, 8, 3, 1]
        };
        let mut c = case(seed, &[dims]);
        c.objective = LinExpr {
            terms: vec![(Var::Free(0), 1.0)],
            constant: 0.0,
        };
        c.constraints[0].expr.constant += [0.0, 0.1, 0.3, 1.0][(seed % 4) as usize];
        check(seed, &c);
        let pwl = pwls(&c);
        let r = solve(&problem(&c, &pwl), limits(60.0));
        if r.best.is_none() {
            empty += 1;
        } else {
            found += 1;
        }
    }
    assert!(
        empty >= 3 && found >= 3,
        "{empty} empty, {found} with a point"
    );
}

/// Two different networks (of different depths, so the product carries the shorter
/// one's output through a ReLU layer) in one relational query.
#[test]
fn two_networks_agree_with_pattern_enumeration_and_sampling() {
    let mut compared = 0;
    for seed in 100..112u64 {
        let c = case(seed, &[&[2, 3, 1], &[3, 4, 3, 1]]);
        compared += check(seed, &c) as usize;
    }
    assert!(compared >= 6, "too few feasible cases compared: {compared}");
}

/// The product network computes the applications' values: bit for bit where the
/// networks have the same shape, to rounding where a shorter one is carried through a
/// ReLU layer as `(a, -a)` (a sum in another order).
#[test]
fn the_product_network_computes_every_application() {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let shapes: [&[&[usize]]; 3] = [
        &[&[3, 5, 2], &[3, 5, 2]],
        &[&[2, 4, 1], &[3, 6, 5, 2], &[1, 2]],
        &[&[4, 8, 8, 8, 1], &[2, 3, 1]],
    ];
    for dims in shapes {
        let nets: Vec<Network> = dims
            .iter()
            .map(|d| Network::random_mlp(d, Activation::Relu, 1.0, 0.5, &mut r))
            .collect();
        let pwl: Vec<PwlNet> = nets
            .iter()
            .map(|n| PwlNet::from_network(n).unwrap())
            .collect();
        let prod = PwlNet {
            maps: product(&pwl.iter().collect::<Vec<_>>()),
        };
        let same = dims.iter().all(|d| *d == dims[0]);
        for _ in 0..500 {
            let xs: Vec<Vec<f64>> = dims
                .iter()
                .map(|d| (0..d[0]).map(|_| r.gen_range(-2.0..2.0)).collect())
                .collect();
            let want: Vec<f64> = nets
                .iter()
                .zip(&xs)
                .flat_map(|(n, x)| n.eval_f64(x))
                .collect();
            let got = prod.eval(&xs.concat());
            assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                if same {
                    assert_eq!(g, w, "{dims:?}");
                } else {
                    assert!(
                        (g - w).abs() <= 1e-12 * (1.0 + w.abs()),
                        "{dims:?}: {g} vs {w}"
                    );
                }
            }
        }
    }
}

#[test]
fn same_result_with_one_and_two_threads() {
    for seed in [3u64, 4] {
        let c = case(seed, &[&[4, 16, 8, 1]]);
        let pwl = pwls(&c);
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| solve(&problem(&c, &pwl), limits(60.0)))
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
    let c = case(7, &[&[6, 64, 32, 1]]);
    let pwl = pwls(&c);
    let t = std::time::Instant::now();
    let r = solve(&problem(&c, &pwl), limits(0.3));
    let dt = t.elapsed().as_secs_f64();
    assert!(dt < 1.3, "took {dt} s for a 0.3 s limit");
    if !r.complete {
        assert!(matches!(
            r.stop,
            Some(samara_verify::UnknownReason::Timeout { .. })
        ));
    }
}

/// A free variable declared without a finite range gets one from the constraints it
/// appears in (here `t <= x0 + x1`, bounded by the box) and the answer is the one with
/// a wide range given; with no constraint to limit it, the answer is `Unsupported`, not a
/// claim.
#[test]
fn infinite_free_ranges_are_bounded_from_the_constraints_or_refused() {
    let c = case(3, &[&[3, 8, 3, 1]]);
    let pwl = pwls(&c);
    let mut p = problem(&c, &pwl);
    p.free = vec![(-3.0, 100.0)];
    let finite = solve(&p, limits(60.0));
    let mut p = problem(&c, &pwl);
    p.free = vec![(-3.0, f64::INFINITY)];
    let open = solve(&p, limits(60.0));
    assert!(finite.complete && open.complete);
    let (a, b) = (finite.best.unwrap().1, open.best.unwrap().1);
    assert!((a - b).abs() <= 1e-9 * (1.0 + a.abs()), "{a} vs {b}");
    // The objective's free term pushes t up; drop the only row that bounds it above.
    let mut p = problem(&c, &pwl);
    p.free = vec![(-3.0, f64::INFINITY)];
    p.constraints.pop();
    let r = solve(&p, limits(60.0));
    assert!(!r.complete);
    assert!(matches!(
        r.stop,
        Some(samara_verify::UnknownReason::Unsupported { .. })
    ));
}
