//! The P5 sweep against sampling: the exact output extremes over each ball contain every
//! sampled output (and are reached by samples to within the LP tolerance), and the local
//! Lipschitz certificate is never below a sampled secant slope.

use rand::{Rng, SeedableRng};
use samara_nn::{Activation, Affine, Layer, Network};
use samara_verify::robustness::{sweep, Reference};

#[test]
fn extremes_and_lipschitz_certificates_bound_samples() {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    for case in 0..12 {
        let dims = [3, 8, 6, 1];
        let mut layers = Vec::new();
        for (k, w) in dims.windows(2).enumerate() {
            layers.push(Layer::Affine(Affine::new(
                w[0],
                w[1],
                (0..w[0] * w[1]).map(|_| r.gen_range(-1.0..1.0)).collect(),
                (0..w[1]).map(|_| r.gen_range(-0.3..0.3)).collect(),
            )));
            if k < 2 {
                layers.push(Layer::Act(Activation::Relu));
            }
        }
        let net = Network {
            input_names: vec!["a".into(), "b".into(), "c".into()],
            output_names: vec!["y".into()],
            input_norm: None,
            layers,
            output_denorm: None,
        };
        let rows: Vec<Vec<f64>> = (0..5)
            .map(|_| (0..4).map(|_| r.gen_range(0.0..1.0)).collect())
            .collect();
        let eps = [0.01, 0.2];
        let pts = sweep(&net, &rows, &eps, Reference::Network, None).unwrap();
        assert_eq!(pts.len(), rows.len() * eps.len());
        for p in &pts {
            let x = &rows[p.index][..3];
            let fx = net.eval_f64(x)[0];
            let (mut smin, mut smax, mut slope) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
            for _ in 0..3000 {
                let xp: Vec<f64> = x.iter().map(|v| v + r.gen_range(-p.eps..=p.eps)).collect();
                let y = net.eval_f64(&xp)[0];
                smin = smin.min(y);
                smax = smax.max(y);
                let d = xp
                    .iter()
                    .zip(x)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                if d > 0.0 {
                    slope = slope.max((y - fx).abs() / d);
                }
            }
            assert!(
                p.f_min <= smin + 1e-12 && p.f_max >= smax - 1e-12,
                "case {case}: extremes [{}, {}] miss samples [{smin}, {smax}]",
                p.f_min,
                p.f_max
            );
            assert!(
                p.lipschitz_upper >= slope * (1.0 - 1e-9),
                "case {case}: certificate {} below a secant slope {slope}",
                p.lipschitz_upper
            );
            assert!(p.lipschitz_lower <= p.lipschitz_upper * (1.0 + 1e-12));
        }
    }
}
