//! The P5 sweep against sampling: the exact output extremes over each ball contain every
//! sampled output (and are reached by samples to within the LP tolerance), and the local
//! Lipschitz certificate is never below a sampled secant slope.

use rand::{Rng, SeedableRng};
use samara_nn::{Activation, Network};
use samara_verify::robustness::{sweep, Reference};

#[test]
fn extremes_and_lipschitz_certificates_bound_samples() {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    for case in 0..12 {
        let net = Network::random_mlp(&[3, 8, 6, 1], Activation::Relu, 1.0, 0.3, &mut r);
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

/// DeepPoly bounds contain every sampled pre-activation and are no looser than intervals.
#[test]
fn deeppoly_bounds_contain_samples() {
    use samara_verify::net::{affine_bounds, deeppoly, PwlNet};
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(23);
    for _ in 0..20 {
        let net = Network::random_mlp(&[4, 12, 10, 3], Activation::Relu, 1.0, 0.3, &mut r);
        let p = PwlNet::from_network(&net).unwrap();
        let xl: Vec<f64> = (0..4).map(|_| r.gen_range(-1.0..0.0)).collect();
        let xh: Vec<f64> = xl.iter().map(|l| l + r.gen_range(0.1..1.0)).collect();
        // Interval bounds first (as the engine does), then DeepPoly.
        let (mut lo, mut hi) = (Vec::new(), Vec::new());
        let (mut al, mut ah) = (xl.clone(), xh.clone());
        for (m, relu) in &p.maps {
            let (l, h) = affine_bounds(m, &al, &ah);
            al = if *relu {
                l.iter().map(|v| v.max(0.0)).collect()
            } else {
                l.clone()
            };
            ah = if *relu {
                h.iter().map(|v| v.max(0.0)).collect()
            } else {
                h.clone()
            };
            lo.push(l);
            hi.push(h);
        }
        let (ilo, ihi) = (lo.clone(), hi.clone());
        let fixed: Vec<Vec<i8>> = p
            .maps
            .iter()
            .filter(|m| m.1)
            .map(|m| vec![0; m.0.out])
            .collect();
        deeppoly(&p, &xl, &xh, &fixed, &mut lo, &mut hi);
        for _ in 0..2000 {
            let x: Vec<f64> = xl
                .iter()
                .zip(&xh)
                .map(|(l, h)| r.gen_range(*l..=*h))
                .collect();
            let mut a = x.clone();
            for (k, (m, relu)) in p.maps.iter().enumerate() {
                let mut z = vec![0.0; m.out];
                m.apply_f64(&a, &mut z);
                for i in 0..m.out {
                    assert!(
                        lo[k][i] <= z[i] && z[i] <= hi[k][i],
                        "map {k} neuron {i}: {} not in [{}, {}]",
                        z[i],
                        lo[k][i],
                        hi[k][i]
                    );
                    assert!(lo[k][i] >= ilo[k][i] && hi[k][i] <= ihi[k][i]);
                }
                a = if *relu {
                    z.iter().map(|v| v.max(0.0)).collect()
                } else {
                    z
                };
            }
        }
    }
}
