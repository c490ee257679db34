//! Soundness and tightness of `samara_bounds::linset::bound_over_linear_set` (CROWN over a
//! linear set with input noise).
//!
//! Soundness is checked against the f64 reference evaluator `Network::eval_f64` at
//! sampled points of the set (uniform, and corners of `xi` and `eta`). The bound holds in
//! exact arithmetic; the f64 evaluation itself (the point `x = c + G xi + noise * eta`
//! and the network) is off by rounding, so a point counts as inside when
//! `|y - (cst + coef . xi)| <= dev + TOL * (1 + |y|)` with `TOL = 1e-12`: these networks
//! are at most 4 layers of width <= 12 with weights in [-1, 1], so the f64 evaluation
//! error is below `1e-13 (1 + |y|)` (a few hundred operations of relative error `1.1e-16`
//! amplified by Lipschitz constants below 100).

#![allow(clippy::needless_range_loop)] // index loops mirror the maths

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_bounds::linset::{bound_over_linear_set, LinearSetBound, LinsetError};
use samara_nn::{Activation, Affine, Layer, Network};
use samara_num::Interval;

const TOL: f64 = 1e-12;

const ACTS: [Activation; 5] = [
    Activation::Relu,
    Activation::Tanh,
    Activation::Sigmoid,
    Activation::Clamp { lo: -0.5, hi: 0.75 },
    Activation::Clamp {
        lo: 0.0,
        hi: f64::INFINITY,
    },
];

/// A random network; `mix` picks each activation layer's function at random, else all
/// are `ACTS[kind]`; `norm` adds a random input normalisation and output
/// denormalisation; `last_act` appends an activation after the last affine map.
fn random_net(rng: &mut ChaCha8Rng, kind: usize, mix: bool, norm: bool) -> Network {
    let depth = rng.gen_range(1..=3);
    let mut dims = vec![rng.gen_range(1..=5)];
    for _ in 0..depth {
        dims.push(rng.gen_range(2..=12));
    }
    dims.push(rng.gen_range(1..=3));
    let mut net = Network::random_mlp(&dims, ACTS[kind], 1.0, 0.5, rng);
    if mix {
        for l in net.layers.iter_mut() {
            if let Layer::Act(a) = l {
                *a = ACTS[rng.gen_range(0..ACTS.len())];
            }
        }
    }
    if rng.gen_bool(0.2) {
        net.layers
            .push(Layer::Act(ACTS[rng.gen_range(0..ACTS.len())]));
    }
    if norm {
        let n = dims[0];
        let c: Vec<f64> = (0..n).map(|_| rng.gen_range(-3.0..3.0)).collect();
        let s: Vec<f64> = (0..n).map(|_| rng.gen_range(0.3..4.0)).collect();
        net.input_norm = Some(Affine::normalise(&c, &s));
        let m = net.n_outputs();
        let c: Vec<f64> = (0..m).map(|_| rng.gen_range(-1.0..1.0)).collect();
        let s: Vec<f64> = (0..m).map(|_| rng.gen_range(0.01..5.0)).collect();
        net.output_denorm = Some(Affine::denormalise(&c, &s));
    }
    net
}

struct Set {
    c: Vec<f64>,
    gens: Vec<Vec<f64>>,
    noise: Vec<f64>,
}

fn random_set(rng: &mut ChaCha8Rng, n: usize, scale: f64) -> Set {
    let p = rng.gen_range(0..=4);
    Set {
        c: (0..n).map(|_| rng.gen_range(-2.0..2.0)).collect(),
        gens: (0..p)
            .map(|_| (0..n).map(|_| scale * rng.gen_range(-1.0..1.0)).collect())
            .collect(),
        noise: (0..n)
            .map(|_| {
                if rng.gen_bool(0.3) {
                    0.0
                } else {
                    scale * rng.gen_range(0.0..0.3)
                }
            })
            .collect(),
    }
}

/// A point of the set: `xi`, and `x` (in f64).
fn sample(rng: &mut ChaCha8Rng, s: &Set) -> (Vec<f64>, Vec<f64>) {
    let corner = rng.gen_bool(0.3);
    let draw = |rng: &mut ChaCha8Rng| {
        if corner {
            if rng.gen_bool(0.5) {
                1.0
            } else {
                -1.0
            }
        } else {
            rng.gen_range(-1.0..=1.0)
        }
    };
    let xi: Vec<f64> = (0..s.gens.len()).map(|_| draw(rng)).collect();
    let x = (0..s.c.len())
        .map(|i| {
            let mut v = s.c[i] + s.noise[i] * draw(rng);
            for (k, g) in s.gens.iter().enumerate() {
                v += xi[k] * g[i];
            }
            v
        })
        .collect();
    (xi, x)
}

fn check_points(
    rng: &mut ChaCha8Rng,
    net: &Network,
    s: &Set,
    b: &LinearSetBound,
    count: usize,
) -> usize {
    for _ in 0..count {
        let (xi, x) = sample(rng, s);
        let y = net.eval_f64(&x);
        for j in 0..y.len() {
            let pred = b.cst[j] + b.coef[j].iter().zip(&xi).map(|(a, v)| a * v).sum::<f64>();
            assert!(
                (y[j] - pred).abs() <= b.dev[j] + TOL * (1.0 + y[j].abs()),
                "output {j}: y = {}, pred = {pred}, dev = {}\nxi = {xi:?}\nx = {x:?}\nnet = {net:?}",
                y[j],
                b.dev[j]
            );
        }
    }
    count
}

#[test]
fn sound_on_random_networks_and_sets() {
    let mut rng = ChaCha8Rng::seed_from_u64(20240611);
    let mut points = 0;
    let mut cases = 0;
    for case in 0..400 {
        let kind = case % ACTS.len();
        let mix = case % 3 == 0;
        let norm = case % 2 == 0;
        let net = random_net(&mut rng, kind, mix, norm);
        let scale = [0.01, 0.3, 1.0, 3.0][case % 4];
        let s = random_set(&mut rng, net.n_inputs(), scale);
        let b = bound_over_linear_set(&net, &s.c, &s.gens, &s.noise).unwrap();
        assert_eq!(b.coef.len(), net.n_outputs());
        assert!(b.coef.iter().all(|r| r.len() == s.gens.len()));
        assert!(b.dev.iter().all(|d| *d >= 0.0));
        points += check_points(&mut rng, &net, &s, &b, 80);
        cases += 1;
    }
    assert!(points >= 20_000, "{points} points over {cases} cases");
}

/// The product of the affine maps of a network without activations, raw units.
fn composed(net: &Network) -> (Vec<Vec<f64>>, Vec<f64>) {
    let n = net.n_inputs();
    let mut w: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
        .collect();
    let mut b = vec![0.0; n];
    for l in net.raw_layers() {
        let Layer::Affine(a) = l else {
            panic!("not affine")
        };
        let nw: Vec<Vec<f64>> = (0..a.out)
            .map(|i| {
                (0..n)
                    .map(|j| (0..a.inp).map(|t| a.weight(i, t) * w[t][j]).sum())
                    .collect()
            })
            .collect();
        let nb: Vec<f64> = (0..a.out)
            .map(|i| a.b[i] + (0..a.inp).map(|t| a.weight(i, t) * b[t]).sum::<f64>())
            .collect();
        w = nw;
        b = nb;
    }
    (w, b)
}

#[test]
fn affine_network_is_exact_up_to_rounding() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for _ in 0..50 {
        let mut net = random_net(&mut rng, 0, false, true);
        net.layers.retain(|l| matches!(l, Layer::Affine(_)));
        let n = net.n_inputs();
        let s = random_set(&mut rng, n, 1.0);
        let noise = vec![0.0; n];
        let b = bound_over_linear_set(&net, &s.c, &s.gens, &noise).unwrap();
        let (w, bias) = composed(&net);
        for j in 0..net.n_outputs() {
            let scale = 1.0
                + bias[j].abs()
                + w[j].iter().map(|v| v.abs()).sum::<f64>()
                    * (1.0 + s.c.iter().map(|v| v.abs()).sum::<f64>());
            assert!(b.dev[j] <= 1e-12 * scale, "dev {} scale {scale}", b.dev[j]);
            // cst = f(c); coef_k = W g_k.
            let cst: f64 = bias[j] + (0..n).map(|i| w[j][i] * s.c[i]).sum::<f64>();
            assert!((b.cst[j] - cst).abs() <= 1e-12 * scale);
            for (k, g) in s.gens.iter().enumerate() {
                let ck: f64 = (0..n).map(|i| w[j][i] * g[i]).sum();
                assert!((b.coef[j][k] - ck).abs() <= 1e-12 * scale);
            }
        }
        // With noise, dev is the noise's image sum_i |W_ji| noise_i (plus rounding).
        let b = bound_over_linear_set(&net, &s.c, &s.gens, &s.noise).unwrap();
        for j in 0..net.n_outputs() {
            let want: f64 = (0..n).map(|i| w[j][i].abs() * s.noise[i]).sum();
            assert!(
                (b.dev[j] - want).abs() <= 1e-11 * (1.0 + want),
                "{} vs {want}",
                b.dev[j]
            );
        }
    }
}

#[test]
fn dev_shrinks_with_the_set() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for kind in 0..ACTS.len() {
        let net = random_net(&mut rng, kind, false, true);
        let n = net.n_inputs();
        let base = random_set(&mut rng, n, 1.0);
        let mut prev = f64::INFINITY;
        for eps in [1.0, 1e-2, 1e-4, 1e-6] {
            let gens: Vec<Vec<f64>> = base
                .gens
                .iter()
                .map(|g| g.iter().map(|v| v * eps).collect())
                .collect();
            let noise: Vec<f64> = base.noise.iter().map(|v| v * eps).collect();
            let b = bound_over_linear_set(&net, &base.c, &gens, &noise).unwrap();
            let dev = b.dev.iter().cloned().fold(0.0, f64::max);
            assert!(
                dev <= prev * 1.0001 + 1e-14,
                "{:?}: dev {dev} grew from {prev}",
                ACTS[kind]
            );
            if eps == 1e-6 {
                // First-order terms are in coef; what is left is the noise's first-order
                // image and second-order terms.
                assert!(dev < 1e-4, "{:?}: dev {dev} at eps {eps}", ACTS[kind]);
            }
            prev = dev;
        }
    }
}

#[test]
fn tighter_than_plain_intervals_on_average() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut ratios = Vec::new();
    for case in 0..200 {
        let net = random_net(&mut rng, case % ACTS.len(), case % 4 == 0, case % 2 == 0);
        let s = random_set(&mut rng, net.n_inputs(), [0.05, 0.3, 1.0][case % 3]);
        let b = bound_over_linear_set(&net, &s.c, &s.gens, &s.noise).unwrap();
        let x: Vec<Interval> = (0..net.n_inputs())
            .map(|i| {
                let r = s.noise[i] + s.gens.iter().map(|g| g[i].abs()).sum::<f64>();
                Interval::new(s.c[i] - r, s.c[i] + r)
            })
            .collect();
        let y = net.eval::<Interval>(&x);
        for j in 0..net.n_outputs() {
            let iw = y[j].hi - y[j].lo;
            let lw = 2.0 * (b.coef[j].iter().map(|v| v.abs()).sum::<f64>() + b.dev[j]);
            if iw > 1e-9 {
                ratios.push(lw / iw);
            }
        }
    }
    let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
    let worse = ratios.iter().filter(|r| **r > 1.0 + 1e-9).count();
    eprintln!(
        "linset/interval width: mean {mean:.3}, max {:.3}, {worse} of {} wider",
        ratios.iter().cloned().fold(0.0, f64::max),
        ratios.len()
    );
    assert!(mean <= 1.0, "mean ratio {mean}");
    // Never wider than intervals by more than the 10% margin kept for the affine form.
    assert!(ratios.iter().all(|r| *r <= 1.0 / 0.9 + 1e-9));
}

#[test]
fn no_generators_and_errors() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let net = random_net(&mut rng, 1, false, true);
    let n = net.n_inputs();
    let c = vec![0.1; n];
    let b = bound_over_linear_set(&net, &c, &[], &vec![0.0; n]).unwrap();
    let y = net.eval_f64(&c);
    for j in 0..y.len() {
        assert!(b.coef[j].is_empty());
        assert!((y[j] - b.cst[j]).abs() <= b.dev[j] + TOL * (1.0 + y[j].abs()));
        assert!(
            b.dev[j] < 1e-12 * (1.0 + y[j].abs()),
            "point set: dev {}",
            b.dev[j]
        );
    }
    let e = bound_over_linear_set(&net, &vec![0.0; n + 1], &[], &vec![0.0; n]).unwrap_err();
    assert!(matches!(e, LinsetError::Center { .. }), "{e}");
    assert!(e.to_string().contains("centre"));
    let e = bound_over_linear_set(&net, &c, &[vec![1.0; n + 2]], &vec![0.0; n]).unwrap_err();
    assert!(matches!(e, LinsetError::Generator { index: 0, .. }), "{e}");
    let e = bound_over_linear_set(&net, &c, &[], &[0.0]).unwrap_err();
    if n != 1 {
        assert!(matches!(e, LinsetError::Noise { .. }), "{e}");
    }
    let mut bad = c.clone();
    bad[0] = f64::NAN;
    let e = bound_over_linear_set(&net, &bad, &[], &vec![0.0; n]).unwrap_err();
    assert!(matches!(e, LinsetError::NonFinite { .. }), "{e}");
    let e = bound_over_linear_set(&net, &c, &[vec![f64::INFINITY; n]], &vec![0.0; n]).unwrap_err();
    assert!(matches!(e, LinsetError::NonFinite { .. }), "{e}");
    let e = bound_over_linear_set(&net, &c, &[], &vec![-1.0; n]).unwrap_err();
    assert!(matches!(e, LinsetError::NegativeNoise { .. }), "{e}");
    let mut bad_net = net.clone();
    bad_net
        .layers
        .push(Layer::Act(Activation::Clamp { lo: 1.0, hi: 0.0 }));
    let e = bound_over_linear_set(&bad_net, &c, &[], &vec![0.0; n]).unwrap_err();
    assert!(matches!(e, LinsetError::Unsupported { .. }), "{e}");
    let mut bad_net = net.clone();
    bad_net.output_names.push("extra".into());
    let e = bound_over_linear_set(&bad_net, &c, &[], &vec![0.0; n]).unwrap_err();
    assert!(matches!(e, LinsetError::Network(_)), "{e}");
}

#[test]
fn wide_tanh_network_of_realistic_width_runs() {
    // Width 200, 3 hidden layers: a size the reachability code uses.
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let net = Network::random_mlp(&[6, 200, 200, 200, 2], Activation::Tanh, 0.1, 0.1, &mut rng);
    let s = random_set(&mut rng, 6, 0.1);
    let t = std::time::Instant::now();
    let b = bound_over_linear_set(&net, &s.c, &s.gens, &s.noise).unwrap();
    eprintln!("width 200 x 3: {:?}, dev {:?}", t.elapsed(), b.dev);
    let mut rng2 = ChaCha8Rng::seed_from_u64(10);
    check_points(&mut rng2, &net, &s, &b, 500);
}
