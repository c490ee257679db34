//! Sparse storage of lowered convolutions (issue 37): the bounds read a map's weights
//! through its rows, so the same network with its maps stored dense and stored sparse
//! (compressed rows) must give the same bounds, both computed: interval, forward
//! symbolic, CROWN and alpha-CROWN, on the lowered conv / pooling / residual /
//! upsampling fixtures of samara-nn (checked there against onnxruntime) and on random
//! sparse ReLU networks. The bounds are also checked to contain the network's f64
//! evaluation at sampled points (samara-nn's IR evaluator, another code path).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_bounds::constant;
use samara_bounds::pwl::PwlNet;
use samara_bounds::search::{solve, Case, OutputConstraint, Settings};
use samara_bounds::symbolic::{self, Objective};
use samara_nn::{Activation, Affine, Layer, Network};

type Maps = Vec<(Affine, bool)>;

/// The maps with every weight matrix stored dense, and stored sparse.
fn both(maps: &Maps) -> (Maps, Maps) {
    let dense = maps.iter().map(|(a, r)| (a.densified(), *r)).collect();
    let sparse = maps.iter().map(|(a, r)| (a.sparsified(), *r)).collect();
    (dense, sparse)
}

fn fixture(stem: &str) -> Network {
    let path = format!(
        "{}/../samara-nn/tests/data/{stem}.onnx",
        env!("CARGO_MANIFEST_DIR")
    );
    samara_nn::onnx::load(&path).unwrap()
}

/// A ReLU network whose weights are non-zero with probability `p`.
fn random_sparse(dims: &[usize], p: f64, rng: &mut ChaCha8Rng) -> Network {
    let mut net = Network::random_mlp(dims, Activation::Relu, 1.0, 0.5, rng);
    for l in net.layers.iter_mut() {
        if let Layer::Affine(a) = l {
            a.map_weights(|w| {
                if !rng.gen_bool(p) {
                    *w = 0.0;
                }
            });
        }
    }
    net
}

/// Every bound computed on both storages, asserted equal; the bounds contain the
/// network's evaluation at `samples` points of the box.
fn check(net: &Network, eps: f64, samples: usize, rng: &mut ChaCha8Rng, what: &str) {
    let maps = PwlNet::from_network(net).unwrap().maps;
    let (dense, sparse) = both(&maps);
    assert!(sparse.iter().all(|(a, _)| a.is_sparse()));
    assert!(dense.iter().all(|(a, _)| !a.is_sparse()));
    let n = net.n_inputs();
    let x0: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let lo: Vec<f64> = x0.iter().map(|v| v - eps).collect();
    let hi: Vec<f64> = x0.iter().map(|v| v + eps).collect();

    // Evaluation: the same values (zero weights are skipped by both forms).
    for _ in 0..samples {
        let x: Vec<f64> = (0..n).map(|t| rng.gen_range(lo[t]..=hi[t])).collect();
        let (yd, ys) = (
            PwlNet {
                maps: dense.clone(),
            }
            .eval(&x),
            PwlNet {
                maps: sparse.clone(),
            }
            .eval(&x),
        );
        assert_eq!(yd, ys, "{what}: evaluation");
    }

    // Interval.
    let id = constant::layer_intervals(&dense, &lo, &hi);
    let is = constant::layer_intervals(&sparse, &lo, &hi);
    assert_eq!(id, is, "{what}: interval bounds");
    // Forward symbolic.
    let fd = symbolic::hidden_pre(&dense, &lo, &hi, None);
    let fs = symbolic::hidden_pre(&sparse, &lo, &hi, None);
    assert_eq!(fd, fs, "{what}: forward symbolic bounds");
    // CROWN.
    let cd = symbolic::crown_pre(&dense, &lo, &hi, Some(&fd));
    let cs = symbolic::crown_pre(&sparse, &lo, &hi, Some(&fs));
    assert_eq!(cd, cs, "{what}: CROWN bounds");
    let m = net.n_outputs();
    let mut c = vec![0.0; m];
    c[0] = 1.0;
    if m > 1 {
        c[m - 1] = -1.0;
    }
    let obj = Objective {
        c: c.clone(),
        d: 0.0,
    };
    let bd = symbolic::backward_lower(&dense, &cd, &obj, &lo, &hi);
    let bs = symbolic::backward_lower(&sparse, &cs, &obj, &lo, &hi);
    assert_eq!(bd, bs, "{what}: CROWN objective bound");
    let ad = symbolic::alpha_lower(&dense, &cd, &obj, &lo, &hi, 5);
    let as_ = symbolic::alpha_lower(&sparse, &cs, &obj, &lo, &hi, 5);
    assert_eq!(ad, as_, "{what}: alpha-CROWN objective bound");

    // The bounds contain the evaluation (an independent evaluator: samara-nn's).
    let value = |l: &symbolic::Linear, x: &[f64]| -> f64 {
        l.cst + l.coef.iter().zip(x).map(|(a, b)| a * b).sum::<f64>() - l.slack
    };
    for _ in 0..samples {
        let x: Vec<f64> = (0..n).map(|t| rng.gen_range(lo[t]..=hi[t])).collect();
        let y = net.eval_f64(&x);
        let v: f64 = c.iter().zip(&y).map(|(a, b)| a * b).sum();
        for (k, iv) in is.1.iter().enumerate() {
            assert!(iv.lo <= y[k] && y[k] <= iv.hi, "{what}: output {k} outside");
        }
        // The linear bound's own evaluation rounds: a relative margin.
        assert!(value(&bs, &x) <= v + 1e-9 * (1.0 + v.abs()), "{what}");
        assert!(value(&as_, &x) <= v + 1e-9 * (1.0 + v.abs()), "{what}");
    }

    // The search: the same verdict on a threshold just under the CROWN bound's
    // concrete minimum (proved) and on one above a sampled value (violated or unknown).
    let min_lin: f64 = bs.cst - bs.slack
        + bs.coef
            .iter()
            .zip(lo.iter().zip(&hi))
            .map(|(a, (l, h))| (a * l).min(a * h))
            .sum::<f64>();
    for t in [
        min_lin - 1.0,
        net.eval_f64(&x0)
            .iter()
            .zip(&c)
            .map(|(y, c)| y * c)
            .sum::<f64>()
            + 1e-3,
    ] {
        let case = Case {
            lo: lo.clone(),
            hi: hi.clone(),
            constraints: vec![OutputConstraint {
                obj: Objective {
                    c: c.clone(),
                    d: -t,
                },
                strict: false,
            }],
        };
        let s = Settings {
            timeout: samara_num::Timeout::none(),
            max_pieces: 200,
            ..Default::default()
        };
        let (od, _) = solve(&dense, std::slice::from_ref(&case), &s);
        let (os, _) = solve(&sparse, std::slice::from_ref(&case), &s);
        assert_eq!(
            format!("{od:?}"),
            format!("{os:?}"),
            "{what}: search verdict at {t}"
        );
    }
}

#[test]
fn lowered_conv_fixtures_bound_the_same_dense_and_sparse() {
    let mut rng = ChaCha8Rng::seed_from_u64(46);
    let mut sparse_layers = Vec::new();
    for stem in ["conv_residual", "ops_mix", "upsample", "skip_slice"] {
        let net = fixture(stem);
        sparse_layers.push(
            net.layers
                .iter()
                .filter(|l| matches!(l, Layer::Affine(a) if a.is_sparse()))
                .count(),
        );
        for eps in [0.01, 0.2] {
            check(&net, eps, 50, &mut rng, stem);
        }
    }
    // The lowering stores the convolutions' maps sparse (the small fixtures' maps,
    // under 64 inputs, stay dense).
    assert!(sparse_layers[0] > 0, "{sparse_layers:?}");
}

#[test]
fn random_sparse_networks_bound_the_same_dense_and_sparse() {
    let mut rng = ChaCha8Rng::seed_from_u64(37);
    for trial in 0..6 {
        // Wide inputs (the search's sparse rows) and narrow ones (its dense loops).
        let dims: &[usize] = if trial % 2 == 0 {
            &[100, 120, 80, 4]
        } else {
            &[20, 90, 70, 3]
        };
        let net = random_sparse(dims, 0.08, &mut rng);
        check(&net, 0.05, 50, &mut rng, &format!("trial {trial}"));
    }
}
