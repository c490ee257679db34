//! Sampling soundness of the bounds and of the search on random ReLU networks: every
//! bound must contain the network's own f64 evaluation (samara-nn's IR evaluator, an
//! independent code path from the chain the bounds read) at thousands of points, and
//! every `Empty` verdict must survive dense sampling; every point found must satisfy its
//! constraints when re-evaluated.

use crate::support::{self, chain};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_bounds::search::{solve, Case, CasePoint, Outcome, OutputConstraint, Settings};
use samara_bounds::symbolic::{self, Objective};
use samara_nn::{Activation, Affine, Layer, Network};

/// Pre-activations of every map, by the IR's layers (affine then ReLU).
fn pre_activations(net: &Network, x: &[f64]) -> Vec<Vec<f64>> {
    let mut out = Vec::new();
    let mut a = x.to_vec();
    for l in net.raw_layers() {
        match l {
            Layer::Affine(m) => {
                a = m.apply(&a);
                out.push(a.clone());
            }
            Layer::Act(act) => a = a.iter().map(|v| act.apply_f64(*v)).collect(),
        }
    }
    out
}

fn random_box(rng: &mut ChaCha8Rng, n: usize, scale: f64) -> (Vec<f64>, Vec<f64>) {
    let mut lo = Vec::new();
    let mut hi = Vec::new();
    for _ in 0..n {
        let c = rng.gen_range(-1.0..1.0) * scale;
        let w = rng.gen_range(0.0..1.0) * scale;
        lo.push(c - w);
        hi.push(c + w);
    }
    (lo, hi)
}

fn sample(rng: &mut ChaCha8Rng, lo: &[f64], hi: &[f64], k: usize) -> Vec<f64> {
    support::sample(rng, lo, hi, k, 7)
}

#[test]
fn forward_crown_and_objective_bounds_contain_samples() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let shapes: [&[usize]; 4] = [
        &[2, 6, 1],
        &[3, 8, 8, 2],
        &[5, 10, 10, 10, 3],
        &[4, 16, 12, 8, 6, 5],
    ];
    for trial in 0..48 {
        let dims = shapes[trial % shapes.len()];
        let wscale = [0.5, 1.0, 3.0, 1e3][trial % 4];
        let net = Network::random_mlp(dims, Activation::Relu, wscale, 0.5 * wscale, &mut rng);
        let maps = chain(&net);
        let (lo, hi) = random_box(&mut rng, dims[0], [1.0, 1e-3, 10.0][trial % 3]);
        let (a, last, fwd) = symbolic::hidden(&maps, &lo, &hi, None);
        let crown = symbolic::crown_pre(&maps, &lo, &hi, Some(&fwd));
        let objs: Vec<Objective> = (0..3)
            .map(|_| Objective {
                c: (0..*dims.last().unwrap())
                    .map(|_| rng.gen_range(-1.0..1.0))
                    .collect(),
                d: rng.gen_range(-1.0..1.0),
            })
            .collect();
        let lbs: Vec<(f64, f64, f64)> = objs
            .iter()
            .map(|o| {
                (
                    symbolic::objective_lower(&a, last, o, &lo, &hi).min_over(&lo, &hi),
                    symbolic::backward_lower(&maps, &crown, o, &lo, &hi).min_over(&lo, &hi),
                    symbolic::alpha_lower(&maps, &crown, o, &lo, &hi, 15).min_over(&lo, &hi),
                )
            })
            .collect();
        for k in 0..2000 {
            let x = sample(&mut rng, &lo, &hi, k);
            let z = pre_activations(&net, &x);
            for (layer, bounds) in [&fwd, &crown].into_iter().enumerate() {
                for (j, b) in bounds.iter().enumerate() {
                    for (i, &(l, u)) in b.iter().enumerate() {
                        let v = z[j][i];
                        assert!(
                            l <= v && v <= u,
                            "trial {trial} ({}) map {j} neuron {i}: {v} outside [{l}, {u}] at {x:?}",
                            ["forward", "crown"][layer]
                        );
                    }
                }
            }
            let y = net.eval_f64(&x);
            for (o, (l1, l2, l3)) in objs.iter().zip(&lbs) {
                let g = o.d + o.c.iter().zip(&y).map(|(c, v)| c * v).sum::<f64>();
                assert!(
                    *l1 <= g && *l2 <= g && *l3 <= g,
                    "trial {trial}: objective {g} below bounds {l1} / {l2} / {l3}"
                );
            }
        }
    }
}

#[test]
fn search_verdicts_survive_sampling_and_points_are_real() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (mut empty, mut found) = (0, 0);
    for trial in 0..40 {
        let dims: &[usize] = if trial % 2 == 0 {
            &[3, 10, 10, 2]
        } else {
            &[5, 12, 12, 12, 3]
        };
        let net = Network::random_mlp(dims, Activation::Relu, 1.0, 0.5, &mut rng);
        let maps = chain(&net);
        let (lo, hi) = random_box(&mut rng, dims[0], 1.0);
        // Threshold near the sampled range of y_0 - y_1, so both answers occur.
        let ys: Vec<f64> = (0..400)
            .map(|k| {
                let y = net.eval_f64(&sample(&mut rng, &lo, &hi, k));
                y[0] - y[1]
            })
            .collect();
        let min = ys.iter().cloned().fold(f64::INFINITY, f64::min);
        let max = ys.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let t = min - (max - min) * rng.gen_range(-0.2..0.3);
        let mut c = vec![0.0; *dims.last().unwrap()];
        c[0] = 1.0;
        c[1] = -1.0;
        // Counterexample region: y_0 - y_1 <= t.
        let cons = vec![OutputConstraint {
            obj: Objective {
                c: c.clone(),
                d: -t,
            },
            strict: false,
        }];
        let case = Case {
            lo: lo.clone(),
            hi: hi.clone(),
            constraints: cons.clone(),
        };
        let (o, _) = solve(
            &maps,
            std::slice::from_ref(&case),
            &Settings {
                timeout: samara_num::Timeout::none(),
                ..Default::default()
            },
        );
        match o {
            Outcome::Proved => {
                empty += 1;
                for k in 0..20_000 {
                    let y = net.eval_f64(&sample(&mut rng, &lo, &hi, k));
                    assert!(
                        y[0] - y[1] > t - 1e-9,
                        "trial {trial}: Empty contradicted: {} <= {t}",
                        y[0] - y[1]
                    );
                }
            }
            Outcome::Violated(CasePoint { x, .. }) => {
                found += 1;
                assert!(x
                    .iter()
                    .zip(lo.iter().zip(&hi))
                    .all(|(v, (a, b))| a <= v && v <= b));
                let y = net.eval_f64(&x);
                assert!(
                    y[0] - y[1] <= t,
                    "trial {trial}: point does not satisfy: {} > {t}",
                    y[0] - y[1]
                );
            }
            Outcome::Unknown(r) => panic!("trial {trial}: no limit was set, yet {r:?}"),
        }
    }
    assert!(
        empty >= 5 && found >= 5,
        "both verdicts exercised: {empty} empty, {found} found"
    );
}

#[test]
fn limits_give_unknown_never_a_verdict() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let net = Network::random_mlp(&[5, 20, 20, 20, 2], Activation::Relu, 1.0, 0.5, &mut rng);
    let maps = chain(&net);
    let lo = vec![-1.0; 5];
    let hi = vec![1.0; 5];
    // A region that the attack cannot hit and the bounds cannot close at once: y_0 - y_1
    // below its true minimum by a hair (found by sampling).
    let min = (0..5000)
        .map(|k| {
            let y = net.eval_f64(&sample(&mut rng, &lo, &hi, k));
            y[0] - y[1]
        })
        .fold(f64::INFINITY, f64::min);
    let cons = vec![OutputConstraint {
        obj: Objective {
            c: vec![1.0, -1.0],
            d: -(min - 1e-3),
        },
        strict: false,
    }];
    let case = Case {
        lo,
        hi,
        constraints: cons,
    };
    for s in [
        Settings {
            timeout: samara_num::Timeout::from_duration(std::time::Duration::ZERO),
            ..Default::default()
        },
        Settings {
            timeout: samara_num::Timeout::none(),
            max_pieces: 1,
            batch: 1,
            ..Default::default()
        },
    ] {
        let (o, _) = solve(&maps, std::slice::from_ref(&case), &s);
        assert!(
            matches!(o, Outcome::Unknown(_) | Outcome::Violated(CasePoint { .. })),
            "a limited search claimed {o:?}"
        );
        if let Outcome::Violated(CasePoint { x, .. }) = o {
            let y = net.eval_f64(&x);
            assert!(y[0] - y[1] <= min - 1e-3);
        }
    }
}

#[test]
fn alpha_crown_is_never_looser_than_crown_and_tightens_somewhere() {
    let mut rng = ChaCha8Rng::seed_from_u64(19);
    let mut tighter = 0;
    for _ in 0..30 {
        let net = Network::random_mlp(&[4, 16, 16, 16, 3], Activation::Relu, 1.0, 0.5, &mut rng);
        let maps = chain(&net);
        let (lo, hi) = random_box(&mut rng, 4, 1.0);
        let (_, _, fwd) = symbolic::hidden(&maps, &lo, &hi, None);
        let pre = symbolic::crown_pre(&maps, &lo, &hi, Some(&fwd));
        let o = Objective {
            c: vec![1.0, -1.0, 0.5],
            d: 0.0,
        };
        let base = symbolic::backward_lower(&maps, &pre, &o, &lo, &hi).min_over(&lo, &hi);
        let opt = symbolic::alpha_lower(&maps, &pre, &o, &lo, &hi, 20).min_over(&lo, &hi);
        assert!(opt >= base, "{opt} < {base}");
        if opt > base + 1e-9 * (1.0 + base.abs()) {
            tighter += 1;
        }
    }
    assert!(
        tighter >= 5,
        "alpha-CROWN improved only {tighter} of 30 bounds"
    );
}

#[test]
fn flat_forward_pass_equals_the_linear_one() {
    // hidden_pre must be hidden's third result bit for bit (same operations, same order),
    // with and without bounds of a containing box.
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    for trial in 0..40 {
        let dims: &[usize] = [&[5, 20, 20, 20, 5][..], &[3, 8, 8, 2], &[6, 30, 1]][trial % 3];
        let wscale = [0.5, 1.0, 3.0][trial % 3];
        let net = Network::random_mlp(dims, Activation::Relu, wscale, 0.5 * wscale, &mut rng);
        let maps = chain(&net);
        let (lo, hi) = random_box(&mut rng, dims[0], [1.0, 1e-3, 10.0][trial % 3]);
        let (_, _, a) = symbolic::hidden(&maps, &lo, &hi, None);
        let b = symbolic::hidden_pre(&maps, &lo, &hi, None);
        assert_eq!(a, b, "trial {trial}");
        // A sub-box with the parent's CROWN bounds as known bounds.
        let parent = symbolic::crown_pre(&maps, &lo, &hi, Some(&a));
        let mut h = hi.clone();
        h[trial % dims[0]] = 0.5 * (lo[trial % dims[0]] + hi[trial % dims[0]]);
        let (_, _, a) = symbolic::hidden(&maps, &lo, &h, Some(&parent));
        let b = symbolic::hidden_pre(&maps, &lo, &h, Some(&parent));
        assert_eq!(a, b, "trial {trial} (sub-box)");
    }
}

#[test]
fn conjunction_and_disjunction_verdicts_survive_sampling() {
    // Conjunctions of two or three output constraints (closed by the min-max LP and the
    // bound of the combined objective) and several cases sharing one box (the shared
    // pieces): every Empty must survive dense sampling and every point must be real.
    conjunctions_survive_sampling(29, &Settings::default());
}

#[test]
fn phase_splitting_verdicts_survive_sampling() {
    // The same queries decided by ReLU-phase splitting on every piece (any number of
    // unstable ReLUs, no opening attack): the LP bounds over each phase set and the
    // certified combinations with the phase constraints must never prove a false Empty.
    conjunctions_survive_sampling(
        31,
        &Settings {
            phase_max_unstable: usize::MAX,
            phase_budget: 1 << 20,
            attack_seconds: 0.0,
            restarts: 1,
            ..Default::default()
        },
    );
}

fn conjunctions_survive_sampling(seed: u64, settings: &Settings) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut empty, mut found) = (0, 0);
    for trial in 0..40 {
        let dims: &[usize] = if trial % 2 == 0 {
            &[3, 10, 10, 4]
        } else {
            &[4, 12, 12, 12, 4]
        };
        let net = Network::random_mlp(dims, Activation::Relu, 1.0, 0.5, &mut rng);
        let maps = chain(&net);
        let (lo, hi) = random_box(&mut rng, dims[0], 1.0);
        let no = *dims.last().unwrap();
        // "y_0 is the largest" (as ACAS Xu property 2), shifted so that both answers occur.
        let ys: Vec<Vec<f64>> = (0..400)
            .map(|k| net.eval_f64(&sample(&mut rng, &lo, &hi, k)))
            .collect();
        let gap = |y: &[f64]| {
            (1..no)
                .map(|j| y[j] - y[0])
                .fold(f64::NEG_INFINITY, f64::max)
        };
        let best = ys.iter().map(|y| gap(y)).fold(f64::INFINITY, f64::min);
        let shift = best + rng.gen_range(-0.3..0.3) * best.abs().max(0.1);
        let conj: Vec<OutputConstraint> = (1..no)
            .take(2 + trial % 2)
            .map(|j| {
                let mut c = vec![0.0; no];
                c[j] = 1.0;
                c[0] = -1.0;
                OutputConstraint {
                    obj: Objective { c, d: -shift },
                    strict: false,
                }
            })
            .collect();
        let mut cases = vec![Case {
            lo: lo.clone(),
            hi: hi.clone(),
            constraints: conj.clone(),
        }];
        if trial % 3 == 0 {
            // A second case on the same box: y_1 - y_2 <= t, t below its sampled range.
            let t = ys.iter().map(|y| y[1] - y[2]).fold(f64::INFINITY, f64::min) - 0.05;
            let mut c = vec![0.0; no];
            c[1] = 1.0;
            c[2] = -1.0;
            cases.push(Case {
                lo: lo.clone(),
                hi: hi.clone(),
                constraints: vec![OutputConstraint {
                    obj: Objective { c, d: -t },
                    strict: false,
                }],
            });
        }
        let holds = |ci: usize, y: &[f64]| {
            cases[ci]
                .constraints
                .iter()
                .all(|k| k.obj.d + k.obj.c.iter().zip(y).map(|(c, v)| c * v).sum::<f64>() <= 0.0)
        };
        let (o, _) = solve(
            &maps,
            &cases,
            &Settings {
                timeout: samara_num::Timeout::none(),
                ..settings.clone()
            },
        );
        match o {
            Outcome::Proved => {
                empty += 1;
                for k in 0..20_000 {
                    let y = net.eval_f64(&sample(&mut rng, &lo, &hi, k));
                    for (ci, case) in cases.iter().enumerate() {
                        let margin = case
                            .constraints
                            .iter()
                            .map(|c| {
                                c.obj.d + c.obj.c.iter().zip(&y).map(|(a, v)| a * v).sum::<f64>()
                            })
                            .fold(f64::NEG_INFINITY, f64::max);
                        assert!(
                            margin > -1e-9,
                            "trial {trial}: Empty contradicted in case {ci}: {margin}"
                        );
                    }
                }
            }
            Outcome::Violated(CasePoint { case, x, .. }) => {
                found += 1;
                assert!(x
                    .iter()
                    .zip(lo.iter().zip(&hi))
                    .all(|(v, (a, b))| a <= v && v <= b));
                assert!(
                    holds(case, &net.eval_f64(&x)),
                    "trial {trial}: point not real"
                );
            }
            Outcome::Unknown(r) => panic!("trial {trial}: no limit was set, yet {r:?}"),
        }
    }
    assert!(
        empty >= 5 && found >= 5,
        "both verdicts exercised: {empty} empty, {found} found"
    );
}

/// Image-size classifiers (100 inputs, so the attack runs jointly over the nine "class
/// j beats the label" cases of one box, with sign steps): wherever sampling finds a
/// point where another class wins, the search must report a point (never `Empty`), and
/// the point must satisfy the case it is reported for, re-evaluated by the IR.
#[test]
fn joint_attack_points_on_many_inputs_are_real_and_name_their_case() {
    let mut rng = ChaCha8Rng::seed_from_u64(2027);
    let mut checked = 0;
    for trial in 0..12 {
        let net = Network::random_mlp(&[100, 32, 32, 10], Activation::Relu, 1.0, 0.5, &mut rng);
        let maps = chain(&net);
        let x0: Vec<f64> = (0..100).map(|_| rng.gen_range(0.0..1.0)).collect();
        let y0 = net.eval_f64(&x0);
        let label = (0..10).max_by(|a, b| y0[*a].total_cmp(&y0[*b])).unwrap();
        let eps = 0.02 * (1 + trial % 4) as f64;
        let lo: Vec<f64> = x0.iter().map(|v| v - eps).collect();
        let hi: Vec<f64> = x0.iter().map(|v| v + eps).collect();
        let cases: Vec<Case> = (0..10)
            .filter(|j| *j != label)
            .map(|j| {
                let mut c = vec![0.0; 10];
                c[label] = 1.0;
                c[j] = -1.0;
                Case {
                    lo: lo.clone(),
                    hi: hi.clone(),
                    constraints: vec![OutputConstraint {
                        obj: Objective { c, d: 0.0 },
                        strict: false,
                    }],
                }
            })
            .collect();
        let sampled_point = (0..2000).any(|k| {
            let y = net.eval_f64(&sample(&mut rng, &lo, &hi, k));
            (0..10).any(|j| j != label && y[j] >= y[label])
        });
        let (o, _) = solve(
            &maps,
            &cases,
            &Settings {
                timeout: samara_num::Timeout::from_duration(std::time::Duration::from_secs(5)),
                ..Default::default()
            },
        );
        match o {
            Outcome::Violated(CasePoint { case, x, .. }) => {
                let y = net.eval_f64(&x);
                let k = &cases[case].constraints[0];
                let g = k.obj.c.iter().zip(&y).map(|(c, v)| c * v).sum::<f64>();
                assert!(g <= 1e-9, "trial {trial}: case {case} does not hold: {g}");
                assert!(x
                    .iter()
                    .zip(lo.iter().zip(&hi))
                    .all(|(v, (a, b))| a <= v && v <= b));
                checked += 1;
            }
            Outcome::Proved => assert!(!sampled_point, "trial {trial}: Empty, yet sampled"),
            Outcome::Unknown(r) => assert!(!sampled_point, "trial {trial}: {r:?}, yet sampled"),
        }
    }
    assert!(checked >= 3, "points exercised: {checked}");
}

#[test]
fn reconcretised_crown_functions_bound_every_sub_box() {
    // The look-ahead's cheap bounds of a half: the parent box's CROWN linear functions
    // minimised over a sub-box. Every sampled pre-activation of the sub-box (the IR's
    // evaluation) must lie inside them, and they must be inside the parent's bounds.
    let mut rng = ChaCha8Rng::seed_from_u64(41);
    let shapes: [&[usize]; 3] = [&[5, 12, 12, 12, 3], &[3, 8, 8, 2], &[2, 20, 10, 1]];
    let mut tighter = 0;
    for trial in 0..30 {
        let dims = shapes[trial % shapes.len()];
        let wscale = [0.5, 1.0, 3.0][trial % 3];
        let net = Network::random_mlp(dims, Activation::Relu, wscale, 0.5 * wscale, &mut rng);
        let maps = chain(&net);
        let (lo, hi) = random_box(&mut rng, dims[0], [1.0, 1e-3, 10.0][trial % 3]);
        let fwd = symbolic::hidden_pre(&maps, &lo, &hi, None);
        let (pre, lins) = symbolic::crown_pre_lin_until(&maps, &lo, &hi, &fwd, None);
        // The concrete bounds equal crown_pre's (same pull-backs).
        assert_eq!(
            pre,
            symbolic::crown_pre(&maps, &lo, &hi, Some(&fwd)),
            "trial {trial}"
        );
        // A random sub-box: each side cut at a random point, one of the two parts kept.
        let (mut sl, mut sh) = (lo.clone(), hi.clone());
        for t in 0..dims[0] {
            let m = rng.gen_range(lo[t]..=hi[t]);
            if rng.gen_bool(0.5) {
                sh[t] = m;
            } else {
                sl[t] = m;
            }
        }
        let sub = symbolic::reconcretise(&pre, &lins, &sl, &sh);
        for (j, layer) in sub.iter().enumerate() {
            for (i, &(l, u)) in layer.iter().enumerate() {
                assert!(l >= pre[j][i].0 && u <= pre[j][i].1, "trial {trial}");
                if l > pre[j][i].0 || u < pre[j][i].1 {
                    tighter += 1;
                }
            }
        }
        for k in 0..2000 {
            let x = sample(&mut rng, &sl, &sh, k);
            let z = pre_activations(&net, &x);
            for (j, layer) in sub.iter().enumerate() {
                for (i, &(l, u)) in layer.iter().enumerate() {
                    let v = z[j][i];
                    assert!(
                        l <= v && v <= u,
                        "trial {trial}: map {j} neuron {i}: {v} outside [{l}, {u}]"
                    );
                }
            }
        }
    }
    // The sub-boxes' bounds are not just the parent's.
    assert!(tighter > 100, "only {tighter} bounds tightened");
}

/// The gradient of `y_0 - y_1` at `x` through the chain (its active linear piece), for
/// the test's own attack: an independent code path from the search's.
fn margin_gradient(maps: &[(Affine, bool)], x: &[f64]) -> Vec<f64> {
    let mut acts = vec![x.to_vec()];
    let mut masks = Vec::new();
    for (m, r) in maps {
        let z = m.apply(acts.last().unwrap());
        masks.push(z.iter().map(|v| !*r || *v > 0.0).collect::<Vec<bool>>());
        acts.push(z.iter().map(|v| if *r { v.max(0.0) } else { *v }).collect());
    }
    let no = maps.last().unwrap().0.out;
    let mut g = vec![0.0; no];
    g[0] = 1.0;
    g[1] = -1.0;
    for (k, (m, _)) in maps.iter().enumerate().rev() {
        let gz: Vec<f64> = g
            .iter()
            .zip(&masks[k])
            .map(|(v, on)| if *on { *v } else { 0.0 })
            .collect();
        let mut next = vec![0.0; m.inp];
        for (i, gi) in gz.iter().enumerate() {
            for (j, nx) in next.iter_mut().enumerate() {
                *nx += gi * m.weight(i, j);
            }
        }
        g = next;
    }
    g
}

#[test]
fn relu_splitting_proofs_on_many_inputs_survive_sampling_and_pgd() {
    relu_splitting_trials(4242, &[80, 16, 16, 3], None);
}

#[test]
fn relu_splitting_proofs_on_sparse_conv_like_layers_survive_sampling_and_pgd() {
    // The hidden maps keep one weight in six, as a lowered convolution keeps its
    // kernel's patch: the bounds then run over the sparse rows (symbolic::Sparse), whose
    // proofs must survive the same sampling and attack.
    relu_splitting_trials(4343, &[96, 48, 24, 3], Some(1.0 / 6.0));
}

#[test]
fn relu_splitting_proofs_on_deep_dense_networks_survive_sampling_and_pgd() {
    // Three dense ReLU layers on 80 inputs: the first nodes branch in the early layer
    // (relusplit's `Deep`, the route of mnist_fc's 256x4 and 256x6 networks).
    relu_splitting_trials(4949, &[80, 16, 16, 16, 3], None);
}

#[test]
fn relu_splitting_proofs_on_one_hidden_layer_survive_sampling_and_pgd() {
    // 30 inputs and one ReLU layer: ReLU splitting with the phases as LP constraints
    // (relusplit's `lp_bounds`, the route of VNN-COMP 2024 safenlp's networks).
    relu_splitting_trials(4848, &[30, 48, 3], None);
}

/// 16 trials of ReLU splitting on random networks of `dims` (weights kept with
/// probability `keep` in the hidden maps when given): every proof survives 10,000
/// samples and 20 sign-gradient descents, every point found satisfies its constraint,
/// and both verdicts occur, proofs by splitting among them.
fn relu_splitting_trials(seed: u64, dims: &[usize], keep: Option<f64>) {
    // 80 inputs: the search splits ReLUs (beta-CROWN bounds), not inputs. The threshold
    // sits just below the sampled minimum of y_0 - y_1, where the root bounds do not
    // decide and both answers occur.
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut proved, mut split_proofs, mut found) = (0, 0, 0);
    let nin = dims[0];
    for trial in 0..16 {
        let mut net = Network::random_mlp(dims, Activation::Relu, 1.0, 0.5, &mut rng);
        if let Some(p) = keep {
            let last = net.layers.len() - 1;
            for (k, l) in net.layers.iter_mut().enumerate() {
                if let (Layer::Affine(a), true) = (l, k < last) {
                    a.map_weights(|w| {
                        if !rng.gen_bool(p) {
                            *w = 0.0;
                        }
                    });
                }
            }
        }
        let maps = chain(&net);
        let x0: Vec<f64> = (0..nin).map(|_| rng.gen_range(0.0..1.0)).collect();
        let eps = 0.05;
        let lo: Vec<f64> = x0.iter().map(|v| v - eps).collect();
        let hi: Vec<f64> = x0.iter().map(|v| v + eps).collect();
        let margin = |x: &[f64]| {
            let y = net.eval_f64(x);
            y[0] - y[1]
        };
        let ms: Vec<f64> = (0..2000)
            .map(|k| margin(&sample(&mut rng, &lo, &hi, k)))
            .collect();
        let min = ms.iter().cloned().fold(f64::INFINITY, f64::min);
        let max = ms.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        // The lowest margin the test's own attack finds (sampling in 80 dimensions stays
        // far from the extremes).
        let descend = |mut x: Vec<f64>| {
            for s in 0..100 {
                let g = margin_gradient(&maps, &x);
                let step = 0.5 * eps * (1.0 - s as f64 / 100.0);
                for (t, xi) in x.iter_mut().enumerate() {
                    *xi = (*xi - step * g[t].signum()).clamp(lo[t], hi[t]);
                }
            }
            margin(&x)
        };
        let low = (0..10)
            .map(|k| descend(sample(&mut rng, &lo, &hi, k)))
            .fold(min, f64::min);
        let t = low - (max - low) * 0.04 * ((trial % 8) as f64 - 1.5);
        let case = Case {
            lo: lo.clone(),
            hi: hi.clone(),
            constraints: vec![OutputConstraint {
                obj: Objective {
                    c: vec![1.0, -1.0, 0.0],
                    d: -t,
                },
                strict: false,
            }],
        };
        let (o, st) = solve(
            &maps,
            std::slice::from_ref(&case),
            &Settings {
                timeout: samara_num::Timeout::from_duration(std::time::Duration::from_secs(20)),
                ..Default::default()
            },
        );
        match o {
            Outcome::Proved => {
                proved += 1;
                split_proofs += (st.pieces > 1) as usize;
                for k in 0..10_000 {
                    let v = margin(&sample(&mut rng, &lo, &hi, k));
                    assert!(
                        v > t - 1e-9,
                        "trial {trial}: proof contradicted: {v} <= {t}"
                    );
                }
                // Sign-gradient descent on y_0 - y_1 from random starts.
                for k in 0..20 {
                    let v = descend(sample(&mut rng, &lo, &hi, k));
                    assert!(v > t - 1e-9, "trial {trial}: PGD contradicts: {v} <= {t}");
                }
            }
            Outcome::Violated(CasePoint { x, .. }) => {
                found += 1;
                assert!(x
                    .iter()
                    .zip(lo.iter().zip(&hi))
                    .all(|(v, (a, b))| a <= v && v <= b));
                assert!(margin(&x) <= t, "trial {trial}: point does not satisfy");
            }
            Outcome::Unknown(_) => {}
        }
    }
    assert!(
        split_proofs >= 3 && found >= 2,
        "both verdicts exercised: {proved} proved ({split_proofs} by splitting), {found} found"
    );
}

/// Intermediate bounds by alpha-CROWN with Adam's steps ([`symbolic::Ascent::Adam`], ReLU
/// splitting's root on images): on random deep networks and boxes, every neuron's bounds
/// lie within CROWN's (they only replace looser ones) and contain the IR evaluator's
/// pre-activation at 10,000 sampled points; over all trials they leave no more neurons
/// unstable, and no more total width, than the same number of normalised steps.
#[test]
fn adam_intermediate_bounds_hold_and_are_within_crowns() {
    let mut rng = ChaCha8Rng::seed_from_u64(29);
    let shapes: [&[usize]; 3] = [
        &[6, 24, 24, 24, 24, 3],
        &[10, 32, 32, 32, 32, 32, 2],
        &[4, 16, 16, 16, 16, 16, 16, 2],
    ];
    let (mut un_adam, mut un_norm, mut un_crown) = (0usize, 0usize, 0usize);
    let (mut w_adam, mut w_norm) = (0.0f64, 0.0f64);
    let unstable = |p: &[Vec<(f64, f64)>]| {
        p.iter()
            .flatten()
            .filter(|b| b.0 < 0.0 && b.1 > 0.0)
            .count()
    };
    let width = |p: &[Vec<(f64, f64)>]| p.iter().flatten().map(|b| b.1 - b.0).sum::<f64>();
    for trial in 0..12 {
        let dims = shapes[trial % shapes.len()];
        let wscale = [1.0, 0.5, 2.0, 1.0][trial % 4];
        let net = Network::random_mlp(dims, Activation::Relu, wscale, 0.5 * wscale, &mut rng);
        let maps = chain(&net);
        let (lo, hi) = random_box(&mut rng, dims[0], [1.0, 0.3, 3.0][trial % 3]);
        let (_, _, fwd) = symbolic::hidden(&maps, &lo, &hi, None);
        let crown = symbolic::crown_pre(&maps, &lo, &hi, Some(&fwd));
        let mut adam = crown.clone();
        symbolic::alpha_pre_with(
            &maps,
            &mut adam,
            &lo,
            &hi,
            15,
            symbolic::Ascent::Adam(0.3),
            false,
            None,
        );
        let mut norm = crown.clone();
        symbolic::alpha_pre_with(
            &maps,
            &mut norm,
            &lo,
            &hi,
            15,
            symbolic::Ascent::Normalised,
            false,
            None,
        );
        for (j, (a, c)) in adam.iter().zip(&crown).enumerate() {
            for (i, (x, y)) in a.iter().zip(c).enumerate() {
                assert!(
                    x.0 >= y.0 && x.1 <= y.1,
                    "trial {trial} map {j} neuron {i}: {x:?} not within CROWN's {y:?}"
                );
            }
        }
        for k in 0..10_000 {
            let x = sample(&mut rng, &lo, &hi, k);
            let z = pre_activations(&net, &x);
            for (j, b) in adam.iter().enumerate() {
                for (i, &(l, u)) in b.iter().enumerate() {
                    let v = z[j][i];
                    assert!(
                        l <= v && v <= u,
                        "trial {trial} map {j} neuron {i}: {v} outside [{l}, {u}] at {x:?}"
                    );
                }
            }
        }
        un_adam += unstable(&adam);
        un_norm += unstable(&norm);
        un_crown += unstable(&crown);
        w_adam += width(&adam);
        w_norm += width(&norm);
    }
    assert!(
        un_adam < un_crown,
        "Adam left {un_adam} unstable, CROWN {un_crown}"
    );
    assert!(
        un_adam <= un_norm && w_adam <= w_norm,
        "Adam: {un_adam} unstable, width {w_adam}; normalised: {un_norm}, {w_norm}"
    );
}

/// A node's re-bound with the root's intermediate slopes
/// ([`symbolic::rebound_with_slopes`]): on random deep networks, one unstable neuron of
/// the first layer fixed to a phase (its bounds clamped), the later layers re-bounded by
/// CROWN over the clamped bounds and then with the slopes alpha-CROWN (Adam's and the
/// normalised steps) chose on the whole box: every bound lies within CROWN's re-bound and
/// contains the IR evaluator's pre-activations at every one of 10,000 sampled points of
/// the box where the phase holds; somewhere the slopes tighten CROWN's re-bound.
#[test]
fn rebound_with_the_roots_slopes_holds_on_the_nodes_set() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let shapes: [&[usize]; 2] = [&[6, 24, 24, 24, 24, 3], &[5, 20, 20, 20, 20, 20, 2]];
    let (mut tighter, mut checked) = (0usize, 0usize);
    for trial in 0..12 {
        let dims = shapes[trial % shapes.len()];
        let wscale = [1.0, 0.5, 2.0][trial % 3];
        let net = Network::random_mlp(dims, Activation::Relu, wscale, 0.5 * wscale, &mut rng);
        let maps = chain(&net);
        let (lo, hi) = random_box(&mut rng, dims[0], [1.0, 0.3][trial % 2]);
        let (_, _, fwd) = symbolic::hidden(&maps, &lo, &hi, None);
        let mut root = symbolic::crown_pre(&maps, &lo, &hi, Some(&fwd));
        let ascent = [symbolic::Ascent::Adam(0.3), symbolic::Ascent::Normalised][trial % 2];
        let slopes = symbolic::alpha_pre_with(&maps, &mut root, &lo, &hi, 10, ascent, true, None);
        let Some(t) = root[0].iter().position(|b| b.0 < 0.0 && b.1 > 0.0) else {
            continue;
        };
        let on = trial % 4 < 2;
        let mut node = root.clone();
        if on {
            node[0][t].0 = 0.0;
        } else {
            node[0][t].1 = 0.0;
        }
        let crown = symbolic::crown_pre_from(&maps, &lo, &hi, Some(&node), 1);
        let mut re = crown.clone();
        symbolic::rebound_with_slopes(&maps, &mut re, &lo, &hi, 1, &slopes, None);
        for (j, (a, c)) in re.iter().zip(&crown).enumerate() {
            for (i, (x, y)) in a.iter().zip(c).enumerate() {
                assert!(
                    x.0 >= y.0 && x.1 <= y.1,
                    "trial {trial} map {j} neuron {i}: {x:?} not within CROWN's {y:?}"
                );
                if x.0 > y.0 + 1e-9 * (1.0 + y.0.abs()) || x.1 < y.1 - 1e-9 * (1.0 + y.1.abs()) {
                    tighter += 1;
                }
            }
        }
        let mut inside = 0;
        for k in 0..10_000 {
            let x = sample(&mut rng, &lo, &hi, k);
            let z = pre_activations(&net, &x);
            if (z[0][t] >= 0.0) != on {
                continue;
            }
            inside += 1;
            for (j, b) in re.iter().enumerate() {
                for (i, &(l, u)) in b.iter().enumerate() {
                    let v = z[j][i];
                    assert!(
                        l <= v && v <= u,
                        "trial {trial} map {j} neuron {i}: {v} outside [{l}, {u}] at {x:?}"
                    );
                }
            }
        }
        checked += inside;
    }
    assert!(
        checked > 10_000,
        "only {checked} samples in the nodes' sets"
    );
    assert!(
        tighter > 0,
        "the root's slopes never tightened a node's CROWN re-bound"
    );
}
