//! The network step of the closed loop on a set: the controller output over a zonotope,
//! as an affine function of the zonotope's generator coordinates plus a deviation,
//! `ex ∈ a . xi + b ± d`, so the control keeps its dependence on the initial set.
//!
//! For piecewise-linear networks (ReLU, clamp) the generator map `s = c + G xi` is
//! prepended to the network as one more affine layer and the output is bounded by the
//! DeepPoly/CROWN back-substitution (Singh et al., POPL 2019; Zhang et al., NeurIPS
//! 2018) over the box `xi ∈ [-1, 1]^k`: every intermediate bound is thus taken over the
//! zonotope, not its interval hull. The closed loop's clip is appended to the network as
//! a clamp layer, which the encoding turns into two ReLUs. Smooth networks (sigmoid,
//! tanh) fall back to interval evaluation over the hull (no dependence kept).

// Numeric kernels index several arrays by one index; the explicit forms mirror the formulas.
#![allow(clippy::assign_op_pattern, clippy::needless_range_loop)]

use super::set::Zonotope;
use samara_bounds::pwl::{affine_bounds, back_substitute, deeppoly, relu_indices, PwlNet};
use samara_bounds::rules::relu;
use samara_nn::{Activation, Affine, Layer, Network};
use samara_num::Interval;

/// A controller network prepared for set evaluation.
#[derive(Clone, Debug)]
pub struct SetController {
    /// The network with the clip appended (raw units).
    pub net: Network,
    /// Its piecewise-linear form, if it has one.
    pwl: Option<PwlNet>,
}

/// The controller output over a set: `ex = cst + coef . xi + [-dev, dev]`.
#[derive(Clone, Debug)]
pub struct ControlSet {
    /// Coefficients over the zonotope's generators.
    pub coef: Vec<f64>,
    /// Constant.
    pub cst: f64,
    /// Deviation bound.
    pub dev: f64,
    /// Sound interval of the output.
    pub range: Interval,
}

impl SetController {
    /// Prepare `net` (6 raw inputs, 1 output); `clip` is appended as a clamp.
    pub fn new(net: &Network, clip: Option<(f64, f64)>) -> Self {
        let mut net = net.clone();
        if let Some((lo, hi)) = clip {
            let mut body = net.layers.clone();
            if let Some(d) = net.output_denorm.take() {
                body.push(Layer::Affine(d));
            }
            body.push(Layer::Act(Activation::Clamp { lo, hi }));
            net.layers = body;
        }
        let pwl = PwlNet::from_network(&net).ok();
        SetController { net, pwl }
    }

    /// Evaluate at a point (f64), clip included.
    pub fn eval(&self, s: &[f64]) -> f64 {
        self.net.eval_f64(&s[..6])[0]
    }

    /// The output over the zonotope `z` (its first six rows are the network inputs).
    pub fn over(&self, z: &Zonotope) -> ControlSet {
        let k = z.gens.len();
        match &self.pwl {
            None => {
                let bb = z.bbox();
                let r = self.net.eval::<Interval>(&bb[..6])[0];
                let m = 0.5 * (r.lo + r.hi);
                ControlSet {
                    coef: vec![0.0; k],
                    cst: m,
                    dev: (r.hi - m).max(m - r.lo).next_up(),
                    range: r,
                }
            }
            Some(p) => {
                // s = c + G xi as the first map (k -> 6).
                let mut w = vec![0.0; 6 * k];
                for i in 0..6 {
                    for (j, g) in z.gens.iter().enumerate() {
                        w[i * k + j] = g[i];
                    }
                }
                let first = Affine::new(k, 6, w, z.c[..6].to_vec());
                let mut maps = vec![(first, false)];
                maps.extend(p.maps.iter().cloned());
                let net = PwlNet { maps };
                crown(&net, k)
            }
        }
    }
}

/// Interval bounds of every map (outward rounded), then DeepPoly on top, then the final
/// output's linear bounds over `xi ∈ [-1, 1]^k`.
fn crown(net: &PwlNet, k: usize) -> ControlSet {
    let xlo = vec![-1.0; k];
    let xhi = vec![1.0; k];
    let mut lo: Vec<Vec<f64>> = Vec::new();
    let mut hi: Vec<Vec<f64>> = Vec::new();
    let (mut alo, mut ahi) = (xlo.clone(), xhi.clone());
    for (m, relu) in &net.maps {
        let (l, h) = affine_bounds(m, &alo, &ahi);
        lo.push(l.clone());
        hi.push(h.clone());
        if *relu {
            (alo, ahi) = l
                .iter()
                .zip(&h)
                .map(|(&a, &b)| relu::interval(a, b))
                .unzip();
        } else {
            alo = l;
            ahi = h;
        }
    }
    let fixed: Vec<Vec<i8>> = net
        .maps
        .iter()
        .filter(|m| m.1)
        .map(|m| vec![0i8; m.0.out])
        .collect();
    deeppoly(net, &xlo, &xhi, &fixed, &mut lo, &mut hi);
    let last = net.maps.len() - 1;
    let range = Interval {
        lo: lo[last][0],
        hi: hi[last][0],
    };
    // ex <= cu . xi + bu and -ex <= lcoef . xi + lcst, i.e. ex >= cl . xi + bl. The
    // weights count in the tolerance's magnitude too (cancellation in the coefficients).
    let relu_idx = relu_indices(net);
    let up = back_substitute(net, &relu_idx, &fixed, &lo, &hi, last, 0, true, true);
    let dn = back_substitute(net, &relu_idx, &fixed, &lo, &hi, last, 0, false, true);
    let (cu, bu, mu) = (up.coef, up.cst, up.mag);
    let cl: Vec<f64> = dn.coef.iter().map(|c| -c).collect();
    let (bl, ml) = (-dn.cst, dn.mag);
    // ex in [cl . xi + bl, cu . xi + bu] on the box.
    let coef: Vec<f64> = cu.iter().zip(&cl).map(|(u, l)| 0.5 * (u + l)).collect();
    let cst = 0.5 * (bu + bl);
    let mut dev = 0.5 * (bu - bl);
    for (u, l) in cu.iter().zip(&cl) {
        dev += 0.5 * (u - l).abs();
    }
    // Stated tolerance for the rounding of the back-substitution, as in `deeppoly`.
    dev = (dev + 1e-10 * (1.0 + mu + ml)).next_up();
    let half = 0.5 * (range.hi - range.lo);
    if dev >= half {
        let m = 0.5 * (range.lo + range.hi);
        return ControlSet {
            coef: vec![0.0; k],
            cst: m,
            dev: (range.hi - m).max(m - range.lo).next_up(),
            range,
        };
    }
    ControlSet {
        coef,
        cst,
        dev,
        range,
    }
}
