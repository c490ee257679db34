//! What the search ([`crate::search`]), ReLU-phase splitting ([`crate::phases`]) and the
//! constant fates ([`crate::constant`]) share: the query's shape (a [`Case`]: an input box
//! and a conjunction of [`OutputConstraint`]s), the network's concrete f64 evaluation
//! ([`forward`]), the check of a candidate point ([`satisfies`]), and the certificate that
//! a conjunction has no point on a box from linear bounds of its constraints
//! ([`combination_certifies`]). A module of its own so that those three import it and not
//! each other.

use crate::symbolic::{self, Objective};
use samara_nn::Affine;

/// One output constraint `c . y + d <= 0` (or `< 0` when `strict`).
#[derive(Clone, Debug, PartialEq)]
pub struct OutputConstraint {
    /// The linear function.
    pub obj: Objective,
    /// Strict inequality.
    pub strict: bool,
}

/// One case of a query: an input box and a conjunction over the outputs. The query asks
/// whether some case has a point.
#[derive(Clone, Debug, PartialEq)]
pub struct Case {
    /// Lower ends of the input box.
    pub lo: Vec<f64>,
    /// Upper ends of the input box.
    pub hi: Vec<f64>,
    /// The conjunction (an empty one holds everywhere).
    pub constraints: Vec<OutputConstraint>,
}

/// Evaluate the chain in f64, keeping each ReLU map's activation mask.
pub(crate) fn forward(
    maps: &[(Affine, bool)],
    x: &[f64],
    masks: Option<&mut Vec<Vec<bool>>>,
) -> Vec<f64> {
    let mut a = x.to_vec();
    let mut ms = Vec::new();
    for (m, r) in maps {
        let mut z = vec![0.0; m.out];
        m.apply_f64(&a, &mut z);
        if *r {
            ms.push(z.iter().map(|v| *v > 0.0).collect::<Vec<_>>());
            z.iter_mut().for_each(|v| *v = v.max(0.0));
        }
        a = z;
    }
    if let Some(out) = masks {
        *out = ms;
    }
    a
}

/// Whether `y` satisfies every constraint with a margin larger than the rounding error
/// of its f64 evaluation (`1e-9` relative to the magnitudes involved, far above the
/// error of the network's few thousand operations).
pub fn satisfies(cs: &[OutputConstraint], y: &[f64]) -> bool {
    cs.iter().all(|k| {
        let mut v = k.obj.d;
        let mut mag = k.obj.d.abs();
        for (c, yo) in k.obj.c.iter().zip(y) {
            v += c * yo;
            mag += (c * yo).abs();
        }
        v < -1e-9 * (1.0 + mag)
    })
}

/// Look for weights `l >= 0` with `min_x sum_k l_k f_k(x) > 0` over the box: the exact
/// min-max LP [`crate::lp::minmax`] (its optimal dual weights), and failing that a
/// matrix game between the weights and the box corners played by multiplicative weights
/// against the best-response corner (Freund and Schapire, 1999). Weights are certified
/// only by the rigorous combination [`symbolic::Linear::combine`]. Also returns the LP's
/// minimiser (where the bounds leave room for a point).
pub(crate) fn combination_certifies(
    fs: &[symbolic::Linear],
    lo: &[f64],
    hi: &[f64],
) -> (bool, Option<crate::lp::MinMax>) {
    let certify = |lam: &[f64]| {
        let mut h = fs[0].combine(lam[0], &fs[1], lam[1], lo, hi);
        for j in 2..fs.len() {
            h = h.combine(1.0, &fs[j], lam[j], lo, hi);
        }
        h.min_over(lo, hi) > 0.0
    };
    let coefs: Vec<&[f64]> = fs.iter().map(|f| &f.coef[..]).collect();
    let csts: Vec<f64> = fs.iter().map(|f| f.cst - f.slack).collect();
    let mm = crate::lp::minmax(&coefs, &csts, lo, hi);
    if let Some(mm) = &mm {
        if mm.value <= 0.0 {
            return (false, Some(mm.clone()));
        }
        if certify(&mm.lambda) {
            return (true, None);
        }
    }
    let k = fs.len();
    let mut lam = vec![1.0 / k as f64; k];
    let mut avg = vec![0.0; k];
    let n = lo.len();
    for it in 1..=120 {
        let mut coef = vec![0.0; n];
        for (f, l) in fs.iter().zip(&lam) {
            for (c, fc) in coef.iter_mut().zip(&f.coef) {
                *c += l * fc;
            }
        }
        let corner: Vec<f64> = (0..n)
            .map(|t| if coef[t] < 0.0 { hi[t] } else { lo[t] })
            .collect();
        let vals: Vec<f64> = fs
            .iter()
            .map(|f| f.cst + f.coef.iter().zip(&corner).map(|(c, x)| c * x).sum::<f64>())
            .collect();
        let scale = vals.iter().fold(1e-300, |m: f64, v| m.max(v.abs()));
        let mut tot = 0.0;
        for (l, v) in lam.iter_mut().zip(&vals) {
            *l *= (0.5 * v / scale).exp();
            tot += *l;
        }
        for (a, l) in avg.iter_mut().zip(lam.iter_mut()) {
            *l /= tot;
            *a += *l;
        }
        if it % 20 == 0 && certify(&avg) {
            return (true, None);
        }
    }
    (false, mm)
}
