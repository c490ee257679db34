//! Piecewise-linear view of a network (the exact verifier's encoding, and DeepPoly's
//! back-substitution that reachability uses too): affine maps, each followed
//! by a ReLU or not (clamps are rewritten as two ReLUs:
//! `clamp(z, lo, hi) = lo + relu(z - lo) - relu(z - hi)`), and sound interval bounds
//! with outward rounding.

use crate::rules::relu;
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

/// The `n x n` identity map.
pub(crate) fn identity(n: usize) -> Affine {
    let mut w = vec![0.0; n * n];
    for i in 0..n {
        w[i * n + i] = 1.0;
    }
    Affine::new(n, n, w, vec![0.0; n])
}

impl PwlNet {
    /// Build from a network in raw units (normalisation layers included).
    pub fn from_network(net: &Network) -> Result<Self, EncodeError> {
        Self::from_network_until(net, None).map(|p| p.expect("no deadline"))
    }

    /// [`PwlNet::from_network`] that gives up (`Ok(None)`) once `deadline` has passed,
    /// checked before each layer is copied: a lowered convolutional network's layers
    /// take gigabytes, and copying them took tens of seconds past an instance's limit.
    pub fn from_network_until(
        net: &Network,
        deadline: Option<std::time::Instant>,
    ) -> Result<Option<Self>, EncodeError> {
        // Refused before any weight is copied (an image-sized network's are gigabytes).
        if let Some(a) = net.layers.iter().find_map(|l| match l {
            Layer::Act(a @ (Activation::Sigmoid | Activation::Tanh | Activation::Sign)) => Some(a),
            _ => None,
        }) {
            return Err(EncodeError::Unsupported(format!("{a:?}")));
        }
        let mut maps: Vec<(Affine, bool)> = Vec::new();
        let mut dim = net.n_inputs();
        let norm = net.input_norm.iter().map(|a| Layer::Affine(a.clone()));
        let denorm = net.output_denorm.iter().map(|a| Layer::Affine(a.clone()));
        // Layers are cloned one at a time, as the iterator reaches them.
        let layers = norm.chain(net.layers.iter().cloned()).chain(denorm);
        let late = || deadline.is_some_and(|d| std::time::Instant::now() >= d);
        for l in layers {
            if late() {
                return Ok(None);
            }
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
        Ok(Some(PwlNet { maps }))
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
                // NaN propagates (f64::max(NaN, 0) would be 0).
                z.iter_mut().for_each(|v| {
                    if *v <= 0.0 {
                        *v = 0.0
                    }
                });
            }
            a = z;
        }
        a
    }
}

/// Outward rounding by one ulp (NaN to the infinite end): samara-num's one definition.
pub use samara_num::round::{down, up};

/// Sound bounds of `W a + b` for `a` in the box `[alo, ahi]` (outward rounded).
pub fn affine_bounds(m: &Affine, alo: &[f64], ahi: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut lo = vec![0.0; m.out];
    let mut hi = vec![0.0; m.out];
    for i in 0..m.out {
        let (mut l, mut h) = (m.b[i], m.b[i]);
        m.row(i).for_each_nonzero(|j, w| {
            let (p, q) = (w * alo[j], w * ahi[j]);
            l = down(l + down(p.min(q)));
            h = up(h + up(p.max(q)));
        });
        lo[i] = l;
        hi[i] = h;
    }
    (lo, hi)
}

/// Cut the bounds `lo`/`hi` of a ReLU layer's pre-activations by the neurons' phases
/// (`1` active: at least 0; `-1` inactive: at most 0; `0` free: unchanged).
pub fn clamp_to_phases(phase: &[i8], lo: &mut [f64], hi: &mut [f64]) {
    for ((p, l), h) in phase.iter().zip(lo.iter_mut()).zip(hi.iter_mut()) {
        match p {
            1 => *l = l.max(0.0),
            -1 => *h = h.min(0.0),
            _ => {}
        }
    }
}

/// Symbolic linear bounds by back-substitution (DeepPoly, Singh et al., POPL 2019; the
/// same relaxation as CROWN, Zhang et al., NeurIPS 2018): each pre-activation is bounded
/// by a linear function of the inputs, through the ReLU relaxations of every earlier
/// layer (`a <= u (z - l) / (u - l)` above; `a >= z` or `a >= 0` below, whichever loses
/// less area), then concretised over the input box. `fixed` gives per ReLU layer the phase
/// of each neuron (1 active, -1 inactive, 0 free); `lo`/`hi` are the current bounds of
/// every map's pre-activations (tightened in place).
///
/// Floating point: the concretised bounds are widened by `1e-10 (1 + sum |terms|)`, far
/// above the rounding error of the few hundred operations per bound (stated tolerance,
/// checked by the sampling tests).
pub fn deeppoly(
    net: &PwlNet,
    x_lo: &[f64],
    x_hi: &[f64],
    fixed: &[Vec<i8>],
    lo: &mut [Vec<f64>],
    hi: &mut [Vec<f64>],
) {
    let relu_idx = relu_indices(net);
    for k in 0..net.maps.len() {
        for i in 0..net.maps[k].0.out {
            for upper in [false, true] {
                let b = back_substitute(net, &relu_idx, fixed, lo, hi, k, i, upper, false);
                // Concretise over the input box.
                let mut v = b.cst;
                let mut mag = b.mag;
                for (t, c) in b.coef.iter().enumerate() {
                    let term = (c * x_lo[t]).max(c * x_hi[t]);
                    v += term;
                    mag += term.abs();
                }
                let v = v + 1e-10 * (1.0 + mag);
                if upper {
                    hi[k][i] = hi[k][i].min(v);
                } else {
                    lo[k][i] = lo[k][i].max(-v);
                }
            }
        }
    }
}

/// The index of each map's ReLU layer among the ReLU layers (`None`: no ReLU follows).
pub fn relu_indices(net: &PwlNet) -> Vec<Option<usize>> {
    let mut r = 0;
    net.maps
        .iter()
        .map(|(_, relu)| {
            relu.then(|| {
                r += 1;
                r - 1
            })
        })
        .collect()
}

/// A linear bound `s z_k[i] <= coef . x + cst` over the network's inputs (`s = 1` for
/// an upper bound, `-1` for a lower one), with `mag` the sum of the magnitudes of the
/// terms that went into `cst` (for the rounding tolerance).
#[derive(Clone, Debug)]
pub struct LinearBound {
    /// Coefficients over the inputs.
    pub coef: Vec<f64>,
    /// Constant.
    pub cst: f64,
    /// Sum of magnitudes of the accumulated terms.
    pub mag: f64,
}

/// Back-substitution of one pre-activation `z_k[i]` down to the inputs through the ReLU
/// relaxations of every earlier layer (DeepPoly/CROWN): `a <= u (z - l) / (u - l)` above,
/// `a >= z` or `a >= 0` below (whichever loses less area); neurons fixed by `fixed`
/// (1 active, -1 inactive) or by their bounds `lo`/`hi` are exact. With
/// `weights_in_mag` the products `c w` are added to `mag` as well (callers whose
/// tolerance must also cover cancellation in the coefficients).
#[allow(clippy::too_many_arguments)]
pub fn back_substitute(
    net: &PwlNet,
    relu_idx: &[Option<usize>],
    fixed: &[Vec<i8>],
    lo: &[Vec<f64>],
    hi: &[Vec<f64>],
    k: usize,
    i: usize,
    upper: bool,
    weights_in_mag: bool,
) -> LinearBound {
    let s = if upper { 1.0 } else { -1.0 };
    let mut coef = vec![0.0; net.maps[k].0.out];
    coef[i] = s;
    let mut cst = 0.0f64;
    let mut mag = 0.0f64;
    // z_j = W_j a_{j-1} + b_j, going down from j = k.
    for j in (0..=k).rev() {
        let m = &net.maps[j].0;
        // coef . z_j = coef . (W a + b)
        let mut next = vec![0.0; m.inp];
        for (row, c) in coef.iter().enumerate() {
            if *c == 0.0 {
                continue;
            }
            cst += c * m.b[row];
            mag += (c * m.b[row]).abs();
            m.row(row).for_each_nonzero(|col, w| {
                next[col] += c * w;
                if weights_in_mag {
                    mag += (c * w).abs();
                }
            });
        }
        if j == 0 {
            coef = next;
            break;
        }
        // next is over a_{j-1}: the output of map j-1 (ReLU or not).
        let pj = j - 1;
        let Some(ri) = relu_idx[pj] else {
            coef = next;
            continue;
        };
        // Relax a = relu(z) of map pj, maximising coef . a.
        let mut zc = vec![0.0; next.len()];
        for (t, c) in next.iter().enumerate() {
            if *c == 0.0 {
                continue;
            }
            let (l, u) = (lo[pj][t], hi[pj][t]);
            let ph = fixed[ri][t];
            if ph == 1 || l >= 0.0 {
                zc[t] = *c;
            } else if ph == -1 || u <= 0.0 {
            } else {
                let slope = relu::chord_slope(l, u);
                if *c > 0.0 {
                    // a <= slope (z - l)
                    zc[t] = c * slope;
                    cst += -c * slope * l;
                    mag += (c * slope * l).abs();
                } else {
                    // a >= lambda z, lambda in {0, 1}.
                    let lambda = relu::default_lower_slope(l, u);
                    zc[t] = c * lambda;
                }
            }
        }
        coef = zc;
    }
    LinearBound { coef, cst, mag }
}
