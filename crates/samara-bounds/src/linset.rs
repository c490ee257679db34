//! CROWN over a linear set with input noise: sound affine bounds of a network's outputs
//! as functions of the set's parameters.
//!
//! The input set is `x = c + sum_k xi_k g_k + diag(noise) eta` with `xi in [-1, 1]^p` and
//! `eta in [-1, 1]^n` (a zonotope-like linear set plus a box of noise). The input is the
//! affine image of `v = (xi, eta)`, so the network composed with that map is bounded over
//! the box `v in [-1, 1]^(p + n)` by CROWN (Zhang, Weng, Chen, Hsieh, Daniel, "Efficient
//! Neural Network Robustness Certification with General Activation Functions", NeurIPS
//! 2018): every activation is replaced by a lower and an upper line valid over its
//! pre-activation range, and the ranges of every layer are found by back-substitution of
//! the layer's neurons through the relaxations of the earlier layers (the backward form
//! of DeepPoly, Singh et al., POPL 2019). The final lower and upper linear functions of
//! `(xi, eta)` lose `eta` by the magnitudes of its coefficients; what is returned is their
//! midpoint over `xi` and a deviation covering both.
//!
//! Relaxations: each activation's lines and interval rule come from [`crate::rules`]
//! (ReLU and clamp as piecewise-linear functions, tanh and sigmoid by chords and
//! tangents); each is sound for *any* slope, so the slope choice only affects tightness.
//!
//! Rounding (the discipline of [`crate::symbolic`]): every f64 dot product of the
//! back-substitution has its error bounded by `(k + 2) * EPSILON` (twice Higham's
//! `gamma_k`) times the sum of the magnitudes of its terms times a bound of the variable
//! it multiplies; the activation functions are evaluated in `samara_num::Interval`
//! (outward rounding, libm widened by 4 ulps); the error terms are inflated by `1e-9`
//! relative and rounded up; concrete bounds are rounded outward with `next_up` /
//! `next_down`. The guarantee holds in exact real arithmetic over the stored f64 weights.

use rayon::prelude::*;
use samara_nn::ir::IrError;
use samara_nn::{Activation, Affine, Layer, Network};
use samara_num::{Interval, Scalar};

/// Affine bounds of the outputs over a linear set: for every `xi in [-1, 1]^p`, every
/// input of the set and every output `j`, `|y_j - (cst_j + coef_j . xi)| <= dev_j`.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearSetBound {
    /// Constant term per output.
    pub cst: Vec<f64>,
    /// Coefficients over `xi`, `n_out` rows of `p` values.
    pub coef: Vec<Vec<f64>>,
    /// Non-negative deviation per output (covers the relaxations, the noise, the rounding).
    pub dev: Vec<f64>,
}

/// Why [`bound_over_linear_set`] could not run.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LinsetError {
    /// The centre's length is not the network's input count.
    #[error("the centre has {found} entries but the network has {expected} inputs")]
    Center {
        /// Network inputs.
        expected: usize,
        /// Entries given.
        found: usize,
    },
    /// A generator's length is not the network's input count.
    #[error("generator {index} has {found} entries but the network has {expected} inputs")]
    Generator {
        /// Which generator (0-based).
        index: usize,
        /// Network inputs.
        expected: usize,
        /// Entries given.
        found: usize,
    },
    /// The noise vector's length is not the network's input count.
    #[error("the noise has {found} radii but the network has {expected} inputs")]
    Noise {
        /// Network inputs.
        expected: usize,
        /// Radii given.
        found: usize,
    },
    /// A NaN or infinite entry of the set.
    #[error("{what} is {value}, not finite; the set must be finite")]
    NonFinite {
        /// Which entry (e.g. `centre[2]`, `generator 1 [0]`, `noise[3]`).
        what: String,
        /// Its value.
        value: f64,
    },
    /// A negative noise radius.
    #[error("noise[{index}] is {value}; radii must be >= 0")]
    NegativeNoise {
        /// Input index.
        index: usize,
        /// The radius.
        value: f64,
    },
    /// The network is structurally invalid.
    #[error("invalid network: {0}")]
    Network(#[from] IrError),
    /// A layer this bound cannot handle.
    #[error("layer {layer} (raw layers, normalisation counted): unsupported: {what}")]
    Unsupported {
        /// Index in [`Network::raw_layers`].
        layer: usize,
        /// What is unsupported.
        what: String,
    },
    /// Intermediate bounds overflowed f64 (weights or inputs far too large).
    #[error("layer {layer} (raw layers, normalisation counted): the bounds overflow f64; the weights or the input set are too large")]
    Overflow {
        /// Index in [`Network::raw_layers`].
        layer: usize,
    },
}

use crate::rules::{self, Relax};
use samara_num::round::{gamma, inflate};

enum Op {
    Aff(Affine),
    Act(Activation),
}

/// Sound affine bounds of `net`'s outputs (raw units: `input_norm`, body,
/// `output_denorm`, the semantics of [`Network::eval_f64`] in exact arithmetic) over the
/// linear set `x = c + sum_k xi_k gens[k] + diag(noise) eta`, `xi in [-1, 1]^p`,
/// `eta in [-1, 1]^n`, by CROWN (Zhang et al., NeurIPS 2018) on the network composed with
/// the set's affine map; see the module documentation for the relaxations and the
/// rounding. `gens` may be empty (`p = 0`). `dev_j = (B_u - B_l)/2 + sum_k |a_u - a_l|_k
/// / 2` for the final lower and upper functions `a_l . xi + B_l`, `a_u . xi + B_u`
/// (noise eliminated), rounded up; when plain interval propagation of the last layer
/// (from CROWN's bounds of the layer before) is narrower than that affine form's range
/// over the whole set by more than 10%, the output gets the constant form of that
/// interval instead (`coef_j = 0`).
pub fn bound_over_linear_set(
    net: &Network,
    c: &[f64],
    gens: &[Vec<f64>],
    noise: &[f64],
) -> Result<LinearSetBound, LinsetError> {
    let n = net.n_inputs();
    if c.len() != n {
        return Err(LinsetError::Center {
            expected: n,
            found: c.len(),
        });
    }
    for (k, g) in gens.iter().enumerate() {
        if g.len() != n {
            return Err(LinsetError::Generator {
                index: k,
                expected: n,
                found: g.len(),
            });
        }
    }
    if noise.len() != n {
        return Err(LinsetError::Noise {
            expected: n,
            found: noise.len(),
        });
    }
    let finite = |what: String, v: f64| {
        if v.is_finite() {
            Ok(())
        } else {
            Err(LinsetError::NonFinite { what, value: v })
        }
    };
    for (i, &v) in c.iter().enumerate() {
        finite(format!("centre[{i}]"), v)?;
    }
    for (k, g) in gens.iter().enumerate() {
        for (i, &v) in g.iter().enumerate() {
            finite(format!("generator {k} [{i}]"), v)?;
        }
    }
    for (i, &v) in noise.iter().enumerate() {
        finite(format!("noise[{i}]"), v)?;
        if v < 0.0 {
            return Err(LinsetError::NegativeNoise { index: i, value: v });
        }
    }
    net.validate()?;
    let p = gens.len();
    let m = p + n;

    // Op 0: the set's map v -> x; then the raw layers.
    let mut w0 = vec![0.0; n * m];
    for i in 0..n {
        for (k, g) in gens.iter().enumerate() {
            w0[i * m + k] = g[i];
        }
        w0[i * m + p + i] = noise[i];
    }
    let mut ops = vec![Op::Aff(Affine::new(m, n, w0, c.to_vec()))];
    for (k, l) in net.raw_layers().into_iter().enumerate() {
        ops.push(match l {
            Layer::Affine(a) => Op::Aff(a),
            Layer::Act(act) => {
                if let Activation::Clamp { lo, hi } = act {
                    if lo.is_nan() || hi.is_nan() || lo > hi {
                        return Err(LinsetError::Unsupported {
                            layer: k,
                            what: format!("Clamp with lo = {lo} > hi = {hi} (or NaN)"),
                        });
                    }
                }
                Op::Act(act)
            }
        });
    }

    let mut st = State {
        ops,
        inmag: Vec::new(),
        rel: Vec::new(),
    };
    // bounds[k]: bounds of the output of op k.
    let mut bounds: Vec<Vec<(f64, f64)>> = Vec::new();
    let last = st.ops.len() - 1;
    for k in 0..st.ops.len() {
        // Bound of |input of op k|.
        let inmag: Vec<f64> = if k == 0 {
            vec![1.0; m]
        } else {
            bounds[k - 1]
                .iter()
                .map(|&(l, u)| l.abs().max(u.abs()))
                .collect()
        };
        st.inmag.push(inmag);
        let rel = match &st.ops[k] {
            Op::Act(act) => bounds[k - 1]
                .iter()
                .map(|&(l, u)| rules::relax(*act, l, u))
                .collect(),
            Op::Aff(_) => Vec::new(),
        };
        st.rel.push(rel);
        if k == last {
            break;
        }
        let b: Vec<(f64, f64)> = match &st.ops[k] {
            Op::Act(act) => bounds[k - 1]
                .iter()
                .map(|&(l, u)| rules::interval(*act, l, u))
                .collect(),
            Op::Aff(a) => (0..a.out)
                .into_par_iter()
                .map(|i| {
                    let mut e = vec![0.0; a.out];
                    e[i] = 1.0;
                    let lo = st.pull(k, e.clone()).min_over_box();
                    e[i] = -1.0;
                    let hi = -st.pull(k, e).min_over_box();
                    // Intersect with plain interval propagation from the previous
                    // layer's bounds (both are sound; intervals win where relaxations
                    // stack up, e.g. saturated tanh).
                    match k.checked_sub(1).map(|q| forward_interval(a, i, &bounds[q])) {
                        Some(f) => (lo.max(f.lo), hi.min(f.hi)),
                        None => (lo, hi),
                    }
                })
                .collect(),
        };
        if b.iter().any(|&(l, u)| !l.is_finite() || !u.is_finite()) {
            return Err(LinsetError::Overflow {
                layer: k.saturating_sub(1),
            });
        }
        bounds.push(b);
    }

    // Final lower and upper functions of every output.
    let n_out = net.n_outputs();
    let rows: Vec<(f64, Vec<f64>, f64)> = (0..n_out)
        .into_par_iter()
        .map(|j| {
            let mut e = vec![0.0; n_out];
            e[j] = 1.0;
            let lower = st.pull(last, e.clone());
            e[j] = -1.0;
            let neg = st.pull(last, e);
            finish(&lower, &neg, p)
        })
        .collect();
    let mut out = LinearSetBound {
        cst: Vec::with_capacity(n_out),
        coef: Vec::with_capacity(n_out),
        dev: Vec::with_capacity(n_out),
    };
    for (j, (mut cst, mut coef, mut dev)) in rows.into_iter().enumerate() {
        // Where plain interval propagation of the last layer from the previous layer's
        // bounds gives a narrower range than the affine form over the whole set, return
        // that range as a constant form (sound either way; the affine form keeps the
        // xi-dependence, so it is kept unless the interval is 10% narrower).
        if last >= 1 {
            let f = match &st.ops[last] {
                Op::Aff(a) => forward_interval(a, j, &bounds[last - 1]),
                Op::Act(act) => {
                    let (l, u) =
                        rules::interval(*act, bounds[last - 1][j].0, bounds[last - 1][j].1);
                    Interval::new(l, u)
                }
            };
            let aff_half = coef.iter().map(|v| v.abs()).sum::<f64>() + dev;
            let half = (0.5 * f.hi - 0.5 * f.lo).next_up();
            if f.lo.is_finite() && f.hi.is_finite() && half < 0.9 * aff_half {
                let mid = 0.5 * f.lo + 0.5 * f.hi;
                let d = ((f.hi - mid).next_up()).max((mid - f.lo).next_up());
                cst = mid;
                coef = vec![0.0; p];
                dev = d;
            }
        }
        if !dev.is_finite() || !cst.is_finite() || coef.iter().any(|v| !v.is_finite()) {
            return Err(LinsetError::Overflow {
                layer: last.saturating_sub(1),
            });
        }
        out.cst.push(cst);
        out.coef.push(coef);
        out.dev.push(dev);
    }
    Ok(out)
}

/// Outward-rounded interval of row `i` of `a` over the box `b` of its input.
fn forward_interval(a: &Affine, i: usize, b: &[(f64, f64)]) -> Interval {
    let mut acc = Interval::point(a.b[i]);
    a.row(i).for_each_nonzero(|j, w| {
        let (l, u) = b[j];
        acc += Interval::new(l, u) * Interval::point(w);
    });
    acc
}

/// A linear function `coef . v + cst` of `v in [-1, 1]^m` with an error bound `err`:
/// the pulled-back quantity is `>= coef . v + cst - err` in exact arithmetic.
struct Pulled {
    coef: Vec<f64>,
    cst: f64,
    err: f64,
}

impl Pulled {
    /// A sound lower bound over the whole box `[-1, 1]^m`.
    fn min_over_box(&self) -> f64 {
        let (s, mag) = sum_minus_abs(self.cst, &self.coef);
        (s - inflate(gamma(self.coef.len() + 1) * mag + self.err)).next_down()
    }
}

/// `cst - sum |coef|` in f64 and the sum of the magnitudes of the terms.
fn sum_minus_abs(cst: f64, coef: &[f64]) -> (f64, f64) {
    let mut s = cst;
    let mut mag = cst.abs();
    for c in coef {
        s -= c.abs();
        mag += c.abs();
    }
    (s, mag)
}

/// Midpoint form from the pulled-back lower bounds of `y_j` (`lower`) and of `-y_j`
/// (`neg`): `(cst, coef over xi, dev)`.
fn finish(lower: &Pulled, neg: &Pulled, p: usize) -> (f64, Vec<f64>, f64) {
    // y >= a_l . xi + B_l, eta eliminated.
    let (s, mag) = sum_minus_abs(lower.cst, &lower.coef[p..]);
    let bl = (s - inflate(gamma(lower.coef.len() + 1) * mag + lower.err)).next_down();
    let al = &lower.coef[..p];
    // -y >= a_n . xi + B_n  =>  y <= -a_n . xi - B_n.
    let (s, mag) = sum_minus_abs(neg.cst, &neg.coef[p..]);
    let bn = (s - inflate(gamma(neg.coef.len() + 1) * mag + neg.err)).next_down();
    let bu = -bn;
    let au: Vec<f64> = neg.coef[..p].iter().map(|v| -v).collect();
    let coef: Vec<f64> = al.iter().zip(&au).map(|(a, b)| 0.5 * a + 0.5 * b).collect();
    let cst = 0.5 * bl + 0.5 * bu;
    // dev >= sum |a_u - coef| + (B_u - cst) and >= sum |coef - a_l| + (cst - B_l),
    // every operation rounded up.
    let side = |a: &[f64], b_gap: f64| {
        let mut d = b_gap;
        for (x, y) in a.iter().zip(&coef) {
            d = (d + (x - y).abs().next_up()).next_up();
        }
        d
    };
    let up = side(&au, (bu - cst).next_up());
    let dn = side(al, (cst - bl).next_up());
    (cst, coef, up.max(dn).max(0.0))
}

struct State {
    ops: Vec<Op>,
    /// Per op, bounds of `|input|`.
    inmag: Vec<Vec<f64>>,
    /// Per op, the relaxations of an activation op (empty for affine ops).
    rel: Vec<Vec<Relax>>,
}

impl State {
    /// CROWN's back-substitution of `lam . (output of op top)` to a lower bound linear
    /// in `v`, with every rounding error bounded.
    fn pull(&self, top: usize, mut lam: Vec<f64>) -> Pulled {
        let mut cst = 0.0f64;
        let mut err = 0.0f64;
        for j in (0..=top).rev() {
            let inmag = &self.inmag[j];
            match &self.ops[j] {
                Op::Aff(a) => {
                    let mut nu = vec![0.0; a.inp];
                    let mut mag = vec![0.0; a.inp];
                    let mut cmag = cst.abs();
                    for (i, &li) in lam.iter().enumerate() {
                        if li == 0.0 {
                            continue;
                        }
                        let p = li * a.b[i];
                        cst += p;
                        cmag += p.abs();
                        a.row(i).for_each_nonzero(|t, w| {
                            let p = li * w;
                            nu[t] += p;
                            mag[t] += p.abs();
                        });
                    }
                    let g = gamma(a.out + 1);
                    err += g * cmag;
                    for (mt, im) in mag.iter().zip(inmag) {
                        if *mt > 0.0 {
                            err += g * mt * im;
                        }
                    }
                    lam = nu;
                }
                Op::Act(_) => {
                    let rel = &self.rel[j];
                    let mut cmag = cst.abs();
                    for ((lt, r), im) in lam.iter_mut().zip(rel).zip(inmag) {
                        let l = *lt;
                        if l == 0.0 {
                            continue;
                        }
                        let (a, b) = if l > 0.0 { (r.al, r.bl) } else { (r.au, r.bu) };
                        let nl = l * a;
                        if nl != 0.0 {
                            err += f64::EPSILON * nl.abs() * im;
                        }
                        if b != 0.0 {
                            let p = l * b;
                            cst += p;
                            cmag += p.abs();
                        }
                        *lt = nl;
                    }
                    err += gamma(lam.len() + 1) * cmag;
                }
            }
        }
        Pulled {
            coef: lam,
            cst,
            err: inflate(err),
        }
    }
}
