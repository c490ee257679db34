//! A dense multilayer perceptron with hand-written reverse-mode gradients, contiguous
//! parameters and no allocation per sample (caches are reused).

use rand::Rng;
use samara_nn::{Activation, Affine, Layer};
use samara_num::Scalar;

/// A dense MLP: `sizes[0]` inputs, hidden layers with ReLU, output with ReLU when
/// `relu_output` (the published setting) or linear.
#[derive(Clone, Debug, PartialEq)]
pub struct Mlp {
    /// Layer widths, input first.
    pub sizes: Vec<usize>,
    /// All weights and biases: per layer, `W` (out x in, row-major) then `b`.
    pub params: Vec<f64>,
    /// ReLU on the output layer too.
    pub relu_output: bool,
    offsets: Vec<usize>,
}

/// Forward-pass storage reused across samples.
#[derive(Clone, Debug, Default)]
pub struct Cache {
    /// Activations per layer (index 0 = input).
    pub acts: Vec<Vec<f64>>,
    /// Pre-activations per layer (index l = layer l+1's `W a + b`).
    pub pre: Vec<Vec<f64>>,
    delta: Vec<Vec<f64>>,
}

impl Mlp {
    /// Glorot-uniform weights (Keras' default initialiser, Glorot & Bengio 2010) and zero
    /// biases, from `rng`.
    pub fn new(sizes: &[usize], relu_output: bool, rng: &mut impl Rng) -> Self {
        let mut params = Vec::new();
        let mut offsets = Vec::new();
        for w in sizes.windows(2) {
            let (i, o) = (w[0], w[1]);
            offsets.push(params.len());
            let lim = (6.0 / (i + o) as f64).sqrt();
            params.extend((0..i * o).map(|_| rng.gen_range(-lim..lim)));
            params.extend(std::iter::repeat_n(0.0, o));
        }
        Mlp {
            sizes: sizes.to_vec(),
            params,
            relu_output,
            offsets,
        }
    }

    /// Number of layers (affine maps).
    pub fn depth(&self) -> usize {
        self.sizes.len() - 1
    }

    /// A cache sized for this network.
    pub fn cache(&self) -> Cache {
        Cache {
            acts: self.sizes.iter().map(|&n| vec![0.0; n]).collect(),
            pre: self.sizes[1..].iter().map(|&n| vec![0.0; n]).collect(),
            delta: self.sizes.iter().map(|&n| vec![0.0; n]).collect(),
        }
    }

    fn relu_at(&self, l: usize) -> bool {
        l + 1 < self.depth() || self.relu_output
    }

    /// Forward pass; the output is `c.acts[depth]`.
    pub fn forward<'c>(&self, x: &[f64], c: &'c mut Cache) -> &'c [f64] {
        c.acts[0].copy_from_slice(x);
        for l in 0..self.depth() {
            let (i, o) = (self.sizes[l], self.sizes[l + 1]);
            let off = self.offsets[l];
            let (w, b) = (
                &self.params[off..off + i * o],
                &self.params[off + i * o..off + i * o + o],
            );
            let (before, after) = c.acts.split_at_mut(l + 1);
            let a_in = &before[l];
            let a_out = &mut after[0];
            let relu = self.relu_at(l);
            for r in 0..o {
                let row = &w[r * i..(r + 1) * i];
                let mut z = b[r];
                for (wv, av) in row.iter().zip(a_in.iter()) {
                    z += wv * av;
                }
                c.pre[l][r] = z;
                a_out[r] = if relu && z <= 0.0 { 0.0 } else { z };
            }
        }
        &c.acts[self.depth()]
    }

    /// Forward pass over any [`Scalar`] with the parameters given separately (same layout
    /// as [`Mlp::params`]), so derivatives with respect to them can be seeded (e.g. with
    /// [`samara_num::Dual`]); on `f64` it computes what [`Mlp::forward`] computes, in the
    /// same order.
    pub fn forward_with<S: Scalar>(&self, params: &[S], x: &[S]) -> Vec<S> {
        let mut a: Vec<S> = x.to_vec();
        for l in 0..self.depth() {
            let (i, o) = (self.sizes[l], self.sizes[l + 1]);
            let off = self.offsets[l];
            let relu = self.relu_at(l);
            a = (0..o)
                .map(|r| {
                    let mut z = params[off + i * o + r].clone();
                    for j in 0..i {
                        z += params[off + r * i + j].clone() * a[j].clone();
                    }
                    if relu {
                        z.relu()
                    } else {
                        z
                    }
                })
                .collect();
        }
        a
    }

    /// Back-propagate `dout` (gradient of a scalar loss w.r.t. the output) through the
    /// last forward pass in `c`; adds `scale * dloss/dparams` into `grad` and, if given,
    /// writes `dloss/dx` into `grad_x`. ReLU's derivative at 0 is taken as 0.
    pub fn backward(
        &self,
        c: &mut Cache,
        dout: &[f64],
        scale: f64,
        grad: &mut [f64],
        grad_x: Option<&mut [f64]>,
    ) {
        let depth = self.depth();
        c.delta[depth].copy_from_slice(dout);
        for l in (0..depth).rev() {
            let (i, o) = (self.sizes[l], self.sizes[l + 1]);
            let off = self.offsets[l];
            let relu = self.relu_at(l);
            // delta_out <- delta_out * relu'(pre)
            for r in 0..o {
                if relu && c.pre[l][r] <= 0.0 {
                    c.delta[l + 1][r] = 0.0;
                }
            }
            let (lo, hi) = c.delta.split_at_mut(l + 1);
            let d_out = &hi[0];
            let d_in = &mut lo[l];
            d_in.iter_mut().for_each(|v| *v = 0.0);
            let a_in = &c.acts[l];
            for r in 0..o {
                let dr = d_out[r];
                if dr == 0.0 {
                    continue;
                }
                let row = off + r * i;
                let gs = dr * scale;
                for j in 0..i {
                    grad[row + j] += gs * a_in[j];
                    d_in[j] += dr * self.params[row + j];
                }
                grad[off + i * o + r] += gs;
            }
        }
        if let Some(gx) = grad_x {
            gx.copy_from_slice(&c.delta[0]);
        }
    }

    /// The network as IR layers (normalised units).
    pub fn to_layers(&self) -> Vec<Layer> {
        let mut v = Vec::new();
        for l in 0..self.depth() {
            let (i, o) = (self.sizes[l], self.sizes[l + 1]);
            let off = self.offsets[l];
            v.push(Layer::Affine(Affine::new(
                i,
                o,
                self.params[off..off + i * o].to_vec(),
                self.params[off + i * o..off + i * o + o].to_vec(),
            )));
            if self.relu_at(l) {
                v.push(Layer::Act(Activation::Relu));
            }
        }
        v
    }
}

/// Adam (Kingma & Ba 2015) with the usual defaults beta1 0.9, beta2 0.999; epsilon 1e-7
/// as in Keras.
#[derive(Clone, Debug)]
pub struct Adam {
    lr: f64,
    m: Vec<f64>,
    v: Vec<f64>,
    t: i32,
}

impl Adam {
    /// A new optimiser for `n` parameters.
    pub fn new(n: usize, lr: f64) -> Self {
        Adam {
            lr,
            m: vec![0.0; n],
            v: vec![0.0; n],
            t: 0,
        }
    }

    /// One update with gradient `g`.
    pub fn step(&mut self, params: &mut [f64], g: &[f64]) {
        const B1: f64 = 0.9;
        const B2: f64 = 0.999;
        self.t += 1;
        let c1 = 1.0 - B1.powi(self.t);
        let c2 = 1.0 - B2.powi(self.t);
        let a = self.lr * c2.sqrt() / c1;
        for k in 0..params.len() {
            self.m[k] = B1 * self.m[k] + (1.0 - B1) * g[k];
            self.v[k] = B2 * self.v[k] + (1.0 - B2) * g[k] * g[k];
            params[k] -= a * self.m[k] / (self.v[k].sqrt() + 1e-7);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn gradients_match_central_differences() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for relu_out in [false, true] {
            let mut net = Mlp::new(&[6, 7, 4, 2], relu_out, &mut rng);
            // Move biases off zero so few ReLUs sit exactly at their kink.
            for p in net.params.iter_mut() {
                *p += 0.05;
            }
            let x: Vec<f64> = (0..6).map(|_| rng.gen_range(0.0..1.0)).collect();
            let loss = |n: &Mlp, x: &[f64]| {
                let mut c = n.cache();
                let y = n.forward(x, &mut c);
                0.5 * y[0] * y[0] + 0.3 * y[1]
            };
            let mut c = net.cache();
            let y = net.forward(&x, &mut c).to_vec();
            let mut g = vec![0.0; net.params.len()];
            let mut gx = vec![0.0; 6];
            net.backward(&mut c, &[y[0], 0.3], 1.0, &mut g, Some(&mut gx));
            let h = 1e-6;
            for k in 0..net.params.len() {
                let mut p = net.clone();
                p.params[k] += h;
                let mut m = net.clone();
                m.params[k] -= h;
                let fd = (loss(&p, &x) - loss(&m, &x)) / (2.0 * h);
                assert!(
                    (fd - g[k]).abs() < 1e-6 * (1.0 + fd.abs()),
                    "param {k}: {fd} vs {}",
                    g[k]
                );
            }
            for j in 0..6 {
                let (mut xp, mut xm) = (x.clone(), x.clone());
                xp[j] += h;
                xm[j] -= h;
                let fd = (loss(&net, &xp) - loss(&net, &xm)) / (2.0 * h);
                assert!((fd - gx[j]).abs() < 1e-6 * (1.0 + fd.abs()), "input {j}");
            }
            net.params[0] += 0.0;
        }
    }

    #[test]
    fn layers_evaluate_like_the_mlp() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let net = Mlp::new(&[6, 6, 4, 1], true, &mut rng);
        let ir = samara_nn::Network {
            input_names: (0..6).map(|i| format!("x{i}")).collect(),
            output_names: vec!["y".into()],
            input_norm: None,
            layers: net.to_layers(),
            output_denorm: None,
        };
        let mut c = net.cache();
        for _ in 0..50 {
            let x: Vec<f64> = (0..6).map(|_| rng.gen_range(0.0..1.0)).collect();
            assert_eq!(net.forward(&x, &mut c)[0], ir.eval_f64(&x)[0]);
            assert_eq!(
                net.forward(&x, &mut c),
                &net.forward_with(&net.params, &x)[..]
            );
        }
    }
}
