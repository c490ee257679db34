//! The network step on Taylor-model sets (`samara_reach::system::network_over`) must
//! enclose the network's output at every point of its input set: random networks (ReLU,
//! tanh, sigmoid and mixed) over random polynomial inputs with remainders, checked at
//! sampled parameters against the network evaluated concretely in f64.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_nn::{Activation, Layer, Network};
use samara_num::{Interval, Scalar, Tm};
use samara_reach::system::network_over;

const ACTS: [Activation; 3] = [Activation::Relu, Activation::Tanh, Activation::Sigmoid];

/// A random polynomial input of degree `order` in `n` parameters with a remainder.
fn rand_input(rng: &mut ChaCha8Rng, n: usize, order: u32) -> Tm {
    let mut t = Tm::constant(rng.gen_range(-2.0..2.0), n, order);
    for k in 0..n {
        let v = Tm::var(k, n, order);
        let w = Tm::var((k + 1) % n, n, order);
        t += v.clone() * rng.gen_range(-1.0..1.0);
        t += v.sqr() * rng.gen_range(-0.4..0.4);
        t += v.clone() * w.clone() * rng.gen_range(-0.3..0.3);
        if order >= 3 {
            t += v.sqr() * w * rng.gen_range(-0.2..0.2);
        }
    }
    let r = rng.gen_range(0.0..0.05);
    t.with_rem(Interval::new(-r, rng.gen_range(0.0..0.05)))
}

#[test]
fn network_step_encloses_the_network_on_polynomial_inputs() {
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let mut checked = 0usize;
    for case in 0..240 {
        let n_in = 1 + case % 4;
        let dims = [
            n_in,
            rng.gen_range(3..=10),
            rng.gen_range(3..=10),
            1 + case % 3,
        ];
        let mut net = Network::random_mlp(&dims, ACTS[case % 3], 1.0, 0.5, &mut rng);
        if case % 5 == 4 {
            for l in net.layers.iter_mut() {
                if let Layer::Act(a) = l {
                    *a = ACTS[rng.gen_range(0..3)];
                }
            }
        }
        let n = 1 + case % 5;
        let order = 2 + (case % 2) as u32;
        let obs: Vec<Tm> = (0..n_in).map(|_| rand_input(&mut rng, n, order)).collect();
        let y = network_over(&net, &obs, order);
        assert_eq!(y.len(), net.n_outputs());
        for _ in 0..150 {
            let xi: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..=1.0)).collect();
            // A point of the input set: the polynomial at xi (midpoint of its outward
            // enclosure) plus a point of the remainder.
            let x: Vec<f64> = obs
                .iter()
                .map(|o| {
                    let (p, r) = o.clone().split_rem();
                    p.eval_at(&xi).value() + rng.gen_range(r.lo..=r.hi)
                })
                .collect();
            let out = net.eval_f64(&x);
            for (j, (v, m)) in out.iter().zip(&y).enumerate() {
                let e = m.eval_at(&xi);
                // Tolerance: the f64 evaluation of the network and of the sampled
                // point (a few ulps of the values involved).
                let tol = 1e-9 * (1.0 + v.abs());
                assert!(
                    e.lo - tol <= *v && *v <= e.hi + tol,
                    "case {case}, output {j}: {v} outside [{}, {}] at xi = {xi:?}",
                    e.lo,
                    e.hi
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 50_000, "{checked} checks");
}
