//! The search for networks with any activation ([`samara_bounds::smooth`]) with some
//! inputs fixed, which it folds into the first layer's bias: on random networks with
//! ReLU, sigmoid and tanh layers, (1) the folded constraint bounds contain the original
//! network's f64 evaluation (samara-nn's IR evaluator, not the folded chain) at 10,000
//! sampled points of the box; (2) on ReLU networks, its verdicts agree with the
//! ReLU-chain search of [`samara_bounds::search`], which does not fold; (3) a `Proved`
//! survives 10,000 samples and a point found satisfies its case on the original network,
//! with every fixed input at its value.

use crate::support::{self, chain};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_bounds::search::{self, Case, CasePoint, Outcome, OutputConstraint, Settings};
use samara_bounds::smooth;
use samara_bounds::symbolic::Objective;
use samara_nn::{Activation, Layer, Network};
use samara_num::Timeout;

/// A random network `dims` with the activation of each hidden layer drawn from `acts`.
fn random_net(rng: &mut ChaCha8Rng, dims: &[usize], acts: &[Activation]) -> Network {
    let mut net = Network::random_mlp(dims, Activation::Relu, 0.6, 0.3, rng);
    for l in net.layers.iter_mut() {
        if let Layer::Act(a) = l {
            *a = acts[rng.gen_range(0..acts.len())];
        }
    }
    net
}

/// A box over `n` inputs of which the first `fixed` are fixed (some at 0, as an image's
/// background pixels), the rest free.
fn random_box(rng: &mut ChaCha8Rng, n: usize, fixed: usize) -> (Vec<f64>, Vec<f64>) {
    let mut lo = Vec::new();
    let mut hi = Vec::new();
    for i in 0..n {
        if i < fixed {
            let v = if rng.gen_bool(0.3) {
                0.0
            } else {
                rng.gen_range(-2.0..2.0)
            };
            lo.push(v);
            hi.push(v);
        } else {
            let c = rng.gen_range(-1.0..1.0);
            let w = rng.gen_range(0.05..1.0);
            lo.push(c - w);
            hi.push(c + w);
        }
    }
    (lo, hi)
}

fn sample(rng: &mut ChaCha8Rng, lo: &[f64], hi: &[f64], k: usize) -> Vec<f64> {
    support::sample(rng, lo, hi, k, 5)
}

fn value(k: &OutputConstraint, y: &[f64]) -> f64 {
    k.obj.d + k.obj.c.iter().zip(y).map(|(c, v)| c * v).sum::<f64>()
}

fn random_constraint(rng: &mut ChaCha8Rng, n_out: usize, d: f64) -> OutputConstraint {
    OutputConstraint {
        obj: Objective {
            c: (0..n_out).map(|_| rng.gen_range(-1.0..1.0)).collect(),
            d,
        },
        strict: false,
    }
}

const ACTS: [Activation; 3] = [Activation::Relu, Activation::Sigmoid, Activation::Tanh];

#[test]
fn folded_bounds_contain_the_original_network() {
    let mut rng = ChaCha8Rng::seed_from_u64(4711);
    for trial in 0..12 {
        let net = random_net(&mut rng, &[10, 14, 12, 3], &ACTS);
        let (lo, hi) = random_box(&mut rng, 10, 7);
        let cases: Vec<Case> = (0..2)
            .map(|_| Case {
                lo: lo.clone(),
                hi: hi.clone(),
                constraints: (0..2)
                    .map(|_| random_constraint(&mut rng, 3, 0.1))
                    .collect(),
            })
            .collect();
        let lbs = smooth::constraint_lower_bounds(&smooth::Apps::one(&net), &cases).unwrap();
        let mut least_gap = f64::INFINITY;
        for k in 0..10_000 {
            let x = sample(&mut rng, &lo, &hi, k);
            let y = net.eval_f64(&x);
            for (case, lb) in cases.iter().zip(&lbs) {
                for (c, b) in case.constraints.iter().zip(lb) {
                    let v = value(c, &y);
                    assert!(
                        *b <= v + 1e-12 * (1.0 + v.abs()),
                        "trial {trial}: bound {b} above the value {v} at {x:?}"
                    );
                    least_gap = least_gap.min(v - b);
                }
            }
        }
        // The bounds are not vacuous: within a few units of the sampled minimum.
        assert!(
            least_gap < 5.0,
            "trial {trial}: loose bounds (gap {least_gap})"
        );
    }
}

/// The sampled range of `c . f(x)` over the box.
fn sampled_range(
    rng: &mut ChaCha8Rng,
    net: &Network,
    lo: &[f64],
    hi: &[f64],
    c: &[f64],
) -> (f64, f64) {
    let mut r = (f64::INFINITY, f64::NEG_INFINITY);
    for k in 0..400 {
        let y = net.eval_f64(&sample(rng, lo, hi, k));
        let v: f64 = c.iter().zip(&y).map(|(a, b)| a * b).sum();
        r = (r.0.min(v), r.1.max(v));
    }
    r
}

fn settings() -> Settings {
    Settings {
        timeout: Timeout::from_secs_f64(20.0).unwrap(),
        ..Default::default()
    }
}

fn check_point(net: &Network, cases: &[Case], p: &CasePoint) {
    let case = &cases[p.case];
    for (i, x) in p.x.iter().enumerate() {
        assert!(
            case.lo[i] <= *x && *x <= case.hi[i],
            "input {i} = {x} outside the box"
        );
    }
    let y = net.eval_f64(&p.x);
    assert!(
        search::satisfies(&case.constraints, &y),
        "the point does not hold: {y:?}"
    );
}

/// Networks side by side ([`smooth::Apps`]: two networks of different depths, with
/// `Sign` among the activations, and two inputs carried to the outputs, one fixed and
/// one free): the constraint bounds contain the composite's f64 evaluation
/// ([`smooth::Apps::eval`], each network's own evaluator) at 10,000 sampled points.
#[test]
fn bounds_of_networks_side_by_side_contain_their_evaluation() {
    let mut rng = ChaCha8Rng::seed_from_u64(49);
    let acts = [ACTS[0], ACTS[1], ACTS[2], Activation::Sign];
    for trial in 0..12 {
        let f = random_net(&mut rng, &[4, 8, 6, 2], &acts);
        let g = random_net(&mut rng, &[3, 6, 2], &acts);
        let apps = smooth::Apps {
            nets: vec![&f, &g],
            through: vec![5, 1],
        };
        let (lo, hi) = random_box(&mut rng, 7, 3);
        let cases: Vec<Case> = (0..2)
            .map(|_| Case {
                lo: lo.clone(),
                hi: hi.clone(),
                constraints: (0..2)
                    .map(|_| random_constraint(&mut rng, 6, 0.1))
                    .collect(),
            })
            .collect();
        let lbs = smooth::constraint_lower_bounds(&apps, &cases).unwrap();
        for k in 0..10_000 {
            let x = sample(&mut rng, &lo, &hi, k);
            let y = apps.eval(&x);
            assert_eq!(&y[4..], &[x[5], x[1]]);
            for (case, lb) in cases.iter().zip(&lbs) {
                for (c, b) in case.constraints.iter().zip(lb) {
                    let v = value(c, &y);
                    assert!(
                        *b <= v + 1e-12 * (1.0 + v.abs()),
                        "trial {trial}: bound {b} above the value {v} at {x:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn folded_search_agrees_with_the_relu_search() {
    let mut rng = ChaCha8Rng::seed_from_u64(36);
    let (mut proved, mut violated) = (0, 0);
    for trial in 0..24 {
        let net = random_net(&mut rng, &[9, 12, 12, 2], &[Activation::Relu]);
        let (lo, hi) = random_box(&mut rng, 9, 6);
        let c: Vec<f64> = vec![1.0, -1.0];
        // Thresholds around the sampled range: some queries with points, some without.
        let (a, b) = sampled_range(&mut rng, &net, &lo, &hi, &c);
        let t = a + (b - a) * [-0.3, -0.05, 0.02, 0.3][trial % 4];
        let cases = support::threshold_case(&lo, &hi, &c, t);
        let (folded, _) = smooth::solve(&net, &cases, &settings());
        let (plain, _) = search::solve(&chain(&net), &cases, &settings());
        match (&folded, &plain) {
            (Outcome::Proved, Outcome::Proved) => proved += 1,
            (Outcome::Violated(p), Outcome::Violated(q)) => {
                check_point(&net, &cases, p);
                check_point(&net, &cases, q);
                violated += 1;
            }
            other => panic!("trial {trial}: the searches disagree: {other:?}"),
        }
    }
    assert!(
        proved >= 4 && violated >= 4,
        "{proved} proved, {violated} violated"
    );
}

#[test]
fn smooth_verdicts_survive_sampling() {
    let mut rng = ChaCha8Rng::seed_from_u64(2023);
    let (mut proved, mut violated) = (0, 0);
    for trial in 0..16 {
        let net = random_net(&mut rng, &[10, 16, 10, 3], &ACTS);
        let (lo, hi) = random_box(&mut rng, 10, 6);
        let c: Vec<f64> = vec![1.0, -0.5, -0.5];
        let (a, b) = sampled_range(&mut rng, &net, &lo, &hi, &c);
        let t = a + (b - a) * [-0.2, -0.02, 0.05, 0.5][trial % 4];
        let cases = support::threshold_case(&lo, &hi, &c, t);
        match smooth::solve(&net, &cases, &settings()).0 {
            Outcome::Proved => {
                proved += 1;
                for k in 0..10_000 {
                    let x = sample(&mut rng, &lo, &hi, k);
                    let y = net.eval_f64(&x);
                    assert!(
                        !search::satisfies(&cases[0].constraints, &y),
                        "trial {trial}: proved, but {x:?} is a point"
                    );
                }
            }
            Outcome::Violated(p) => {
                check_point(&net, &cases, &p);
                violated += 1;
            }
            Outcome::Unknown(r) => panic!("trial {trial}: undecided ({r:?})"),
        }
    }
    assert!(
        proved >= 3 && violated >= 3,
        "{proved} proved, {violated} violated"
    );
}
