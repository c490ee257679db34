//! Piecewise-linear view of a network for the exact engine: affine maps, each followed
//! by a ReLU or not (clamps are rewritten as two ReLUs:
//! `clamp(z, lo, hi) = lo + relu(z - lo) - relu(z - hi)`), and sound interval bounds
//! with outward rounding.

use samara_nn::{Activation, Affine, Layer, Network};

/// The network as a chain of affine maps `z = W a + b`, each followed by a ReLU or not.
/// No maps are composed, so the encoding is the network's own arithmetic exactly.
#[derive(Clone, Debug)]
pub struct PwlNet {
    /// Affine maps with "a ReLU follows" flags.
    pub maps: Vec<(Affine, bool)>,
}

/// Why a network has no exact encoding.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EncodeError {
    /// A smooth activation (sigmoid, tanh) or another non-piecewise-linear layer.
    #[error("unsupported: the exact engine handles ReLU and clamp networks; this network has a {0} layer")]
    Unsupported(String),
}

fn identity(n: usize) -> Affine {
    let mut w = vec![0.0; n * n];
    for i in 0..n {
        w[i * n + i] = 1.0;
    }
    Affine::new(n, n, w, vec![0.0; n])
}

impl PwlNet {
    /// Build from a network in raw units (normalisation layers included).
    pub fn from_network(net: &Network) -> Result<Self, EncodeError> {
        let mut maps: Vec<(Affine, bool)> = Vec::new();
        let mut dim = net.n_inputs();
        for l in net.raw_layers() {
            match l {
                Layer::Affine(a) => {
                    dim = a.out;
                    maps.push((a, false));
                }
                Layer::Act(Activation::Relu) => match maps.last_mut() {
                    Some((_, r)) if !*r => *r = true,
                    _ => maps.push((identity(dim), true)),
                },
                Layer::Act(Activation::Clamp { lo, hi }) => {
                    if !lo.is_finite() || !hi.is_finite() {
                        return Err(EncodeError::Unsupported("one-sided clamp".into()));
                    }
                    // clamp(z) = lo + relu(z - lo) - relu(z - hi).
                    let n = dim;
                    let mut w = vec![0.0; 2 * n * n];
                    for i in 0..n {
                        w[i * n + i] = 1.0;
                        w[(n + i) * n + i] = 1.0;
                    }
                    let b: Vec<f64> = (0..2 * n).map(|i| if i < n { -lo } else { -hi }).collect();
                    maps.push((Affine::new(n, 2 * n, w, b), true));
                    let mut w2 = vec![0.0; n * 2 * n];
                    for i in 0..n {
                        w2[i * 2 * n + i] = 1.0;
                        w2[i * 2 * n + n + i] = -1.0;
                    }
                    maps.push((Affine::new(2 * n, n, w2, vec![lo; n]), false));
                }
                Layer::Act(a) => return Err(EncodeError::Unsupported(format!("{a:?}"))),
            }
        }
        if maps.is_empty() || maps.last().map(|m| m.1).unwrap_or(false) {
            maps.push((identity(dim), false));
        }
        Ok(PwlNet { maps })
    }

    /// Number of inputs.
    pub fn n_inputs(&self) -> usize {
        self.maps[0].0.inp
    }

    /// Number of outputs.
    pub fn n_outputs(&self) -> usize {
        self.maps.last().map(|a| a.0.out).unwrap_or(0)
    }

    /// Evaluate in f64.
    pub fn eval(&self, x: &[f64]) -> Vec<f64> {
        let mut a = x.to_vec();
        for (m, relu) in &self.maps {
            let mut z = vec![0.0; m.out];
            m.apply_f64(&a, &mut z);
            if *relu {
                z.iter_mut().for_each(|v| *v = v.max(0.0));
            }
            a = z;
        }
        a
    }
}

/// Interval `[lo, hi]` arithmetic helpers with outward rounding (one ulp per operation).
pub(crate) fn down(x: f64) -> f64 {
    if x.is_finite() {
        x.next_down()
    } else {
        x
    }
}

pub(crate) fn up(x: f64) -> f64 {
    if x.is_finite() {
        x.next_up()
    } else {
        x
    }
}

/// Sound bounds of `W a + b` for `a` in the box `[alo, ahi]` (outward rounded).
pub fn affine_bounds(m: &Affine, alo: &[f64], ahi: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut lo = vec![0.0; m.out];
    let mut hi = vec![0.0; m.out];
    for i in 0..m.out {
        let (mut l, mut h) = (m.b[i], m.b[i]);
        for j in 0..m.inp {
            let w = m.w[i * m.inp + j];
            if w == 0.0 {
                continue;
            }
            let (p, q) = (w * alo[j], w * ahi[j]);
            l = down(l + down(p.min(q)));
            h = up(h + up(p.max(q)));
        }
        lo[i] = l;
        hi[i] = h;
    }
    (lo, hi)
}
