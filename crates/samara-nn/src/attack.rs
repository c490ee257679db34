//! A projected-gradient attack on an input box (issue 37, "attacks first"): minimise a
//! linear function of a chain network's outputs over a box by signed-gradient steps
//! from random starts, returning the best point found. A verifier runs it before its
//! search: a point whose outputs violate the property is a counterexample found in
//! milliseconds (to be re-checked by the caller's exact evaluation, as every
//! counterexample is); finding none proves nothing.

use crate::ir::{Activation, Layer, Network};
use rand::{Rng, SeedableRng};

/// Settings of [`pgd_min`].
#[derive(Clone, Debug)]
pub struct PgdSettings {
    /// Random starts (the box centre is always tried first).
    pub restarts: usize,
    /// Gradient steps per start.
    pub steps: usize,
    /// First step as a fraction of each input's range (shrinking by 0.85 a step: the
    /// steps add up to 1.7 ranges, the 50th is 7e-5 of the first).
    pub step: f64,
    /// Seed of the random starts.
    pub seed: u64,
}

impl Default for PgdSettings {
    fn default() -> Self {
        PgdSettings {
            restarts: 8,
            steps: 50,
            step: 0.25,
            seed: 37,
        }
    }
}

/// `c . f(x)` and its gradient in `x` (a subgradient at ReLU kinks; through `Sign`,
/// the straight-through estimator, see [`outputs_and_gradient`]).
pub fn objective_and_gradient(net: &Network, c: &[f64], x: &[f64]) -> (f64, Vec<f64>) {
    let (y, g) = outputs_and_gradient(net, x, |_| c.to_vec());
    (c.iter().zip(&y).map(|(a, b)| a * b).sum(), g)
}

/// The outputs `f(x)` and the gradient of `c . f(x)` in `x`, where the weights
/// `c = pick(f(x))` are chosen from the outputs (an attack aims at the constraint
/// nearest to holding there). `Sign` has derivative 0 almost everywhere; its
/// gradient here is the straight-through estimator's 1 (Bengio et al., 2013; the
/// binarised networks are trained with it), a search direction only: the outputs are
/// exact, and an attack checks its points on them.
pub fn outputs_and_gradient(
    net: &Network,
    x: &[f64],
    pick: impl FnOnce(&[f64]) -> Vec<f64>,
) -> (Vec<f64>, Vec<f64>) {
    let layers = net.raw_layer_refs();
    // Forward, keeping every layer's input.
    let mut acts: Vec<Vec<f64>> = Vec::with_capacity(layers.len() + 1);
    let mut z = x.to_vec();
    for l in &layers {
        acts.push(z.clone());
        z = match l.as_ref() {
            Layer::Affine(a) => {
                let mut y = vec![0.0; a.out];
                a.apply_f64(&z, &mut y);
                y
            }
            Layer::Act(act) => z.iter().map(|&v| act.apply_f64(v)).collect(),
        };
    }
    // Backward.
    let mut g = pick(&z);
    for (l, inp) in layers.iter().zip(&acts).rev() {
        g = match l.as_ref() {
            Layer::Affine(a) => {
                let mut gi = vec![0.0; a.inp];
                for (i, gv) in g.iter().enumerate() {
                    if *gv != 0.0 {
                        a.row(i).for_each_nonzero(|j, w| gi[j] += gv * w);
                    }
                }
                gi
            }
            Layer::Act(act) => g
                .iter()
                .zip(inp)
                .map(|(gv, &v)| {
                    gv * match *act {
                        Activation::Relu => f64::from(u8::from(v > 0.0)),
                        Activation::Sigmoid => {
                            let s = 1.0 / (1.0 + (-v).exp());
                            s * (1.0 - s)
                        }
                        Activation::Tanh => 1.0 - v.tanh().powi(2),
                        Activation::Clamp { lo, hi } => f64::from(u8::from(v > lo && v < hi)),
                        // The straight-through estimator (see `outputs_and_gradient`).
                        Activation::Sign => 1.0,
                    }
                })
                .collect(),
        };
    }
    (z, g)
}

/// Minimise `c . f(x)` over the box `[lo, hi]`: the best point found and its value.
pub fn pgd_min(
    net: &Network,
    lo: &[f64],
    hi: &[f64],
    c: &[f64],
    s: &PgdSettings,
) -> (Vec<f64>, f64) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(s.seed);
    let centre: Vec<f64> = lo.iter().zip(hi).map(|(a, b)| 0.5 * (a + b)).collect();
    let mut best = (centre.clone(), f64::INFINITY);
    for r in 0..=s.restarts {
        let mut x = if r == 0 {
            centre.clone()
        } else {
            lo.iter()
                .zip(hi)
                .map(|(&a, &b)| if a < b { rng.gen_range(a..=b) } else { a })
                .collect()
        };
        for k in 0..s.steps {
            let (v, g) = objective_and_gradient(net, c, &x);
            if v < best.1 {
                best = (x.clone(), v);
            }
            let frac = s.step * 0.85f64.powi(k as i32);
            for (((xi, gi), a), b) in x.iter_mut().zip(&g).zip(lo).zip(hi) {
                let sign = if *gi > 0.0 {
                    1.0
                } else if *gi < 0.0 {
                    -1.0
                } else {
                    0.0
                };
                let d = (b - a) * frac * sign;
                *xi = (*xi - d).clamp(*a, *b);
            }
        }
        let (v, _) = objective_and_gradient(net, c, &x);
        if v < best.1 {
            best = (x, v);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ir::Affine;

    /// The gradient equals central differences (away from kinks) on a random network.
    #[test]
    fn gradient_matches_finite_differences() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let net = Network::random_mlp(&[4, 8, 8, 3], Activation::Tanh, 1.0, 0.5, &mut rng);
        let c = [1.0, -2.0, 0.5];
        let x = [0.1, -0.3, 0.7, 0.2];
        let (_, g) = objective_and_gradient(&net, &c, &x);
        for j in 0..4 {
            let h = 1e-6;
            let (mut xp, mut xm) = (x, x);
            xp[j] += h;
            xm[j] -= h;
            let fd = (objective_and_gradient(&net, &c, &xp).0
                - objective_and_gradient(&net, &c, &xm).0)
                / (2.0 * h);
            assert!((fd - g[j]).abs() < 1e-6, "{j}: {fd} vs {}", g[j]);
        }
    }

    /// On a ReLU network of one input, the attack reaches the minimum found by a fine
    /// grid (an independent search) to within the grid's resolution.
    #[test]
    fn attack_reaches_the_grid_minimum() {
        // y = relu(x - 0.3) - 2 relu(x - 0.6) + relu(x - 0.9): a tent of height 0.3 at
        // x = 0.6, flat 0 elsewhere; minimise -y over [0, 2] (the centre, 1, is flat).
        let net = Network {
            input_names: vec!["x".into()],
            output_names: vec!["y".into()],
            input_norm: None,
            layers: vec![
                Layer::Affine(Affine::new(
                    1,
                    3,
                    vec![1.0, 1.0, 1.0],
                    vec![-0.3, -0.6, -0.9],
                )),
                Layer::Act(Activation::Relu),
                Layer::Affine(Affine::new(3, 1, vec![1.0, -2.0, 1.0], vec![0.0])),
            ],
            output_denorm: None,
        };
        let (x, v) = pgd_min(&net, &[0.0], &[2.0], &[-1.0], &PgdSettings::default());
        let grid = (0..=20000)
            .map(|k| -net.eval_f64(&[k as f64 * 1e-4])[0])
            .fold(f64::INFINITY, f64::min);
        assert!(v <= grid + 1e-3, "attack {v} at {x:?}, grid {grid}");
        assert!(grid < -0.29 && (0.0..=2.0).contains(&x[0]));
    }
}
