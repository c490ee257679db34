//! The smallest linear programs of the search: over a box, the minimum of the largest of
//! a few affine functions, `t* = min_{x in [lo, hi]} max_k (c_k . x + d_k)`, solved by
//! the dense tableau simplex method with Bland's rule (Bland, 1977; no cycling), together
//! with the optimal dual weights `lambda_k >= 0`, `sum_k lambda_k = 1`. By LP duality
//! `t* = max_lambda min_x sum_k lambda_k (c_k . x + d_k)`: when `t* > 0` the weights
//! combine the functions into one that is positive on the whole box, the certificate that
//! the conjunction `c_k . x + d_k <= 0 (all k)` has no point there (the LP step of
//! nnenum, Bak et al., CAV 2020, and of the Planet/Reluplex family, taken here only over
//! the linear bounds).
//!
//! The solver is plain f64 and only *proposes* the weights and the minimiser: the caller
//! checks the weights with rigorous rounding ([`crate::symbolic::Linear::combine`] and
//! `min_over`) and re-evaluates any point, so an inaccurate solve can cost a proof or a
//! point but never make a wrong one.

/// The result of [`minmax`]: the optimal value (f64, approximate), a minimiser `x`, and
/// dual weights `lambda` (non-negative, summing to one).
#[derive(Clone, Debug, PartialEq)]
pub struct MinMax {
    /// `min_x max_k f_k(x)` as computed in f64.
    pub value: f64,
    /// A minimiser in the box.
    pub x: Vec<f64>,
    /// Weights of the functions (non-negative, summing to one).
    pub lambda: Vec<f64>,
}

/// `min_{x in [lo, hi]} max_k (coef_k . x + cst_k)` (see the module doc); `None` when
/// the simplex method fails to finish within its iteration cap or meets non-finite
/// numbers, or when there are no functions.
pub fn minmax(coef: &[&[f64]], cst: &[f64], lo: &[f64], hi: &[f64]) -> Option<MinMax> {
    let k = coef.len();
    let n = lo.len();
    if k == 0 || cst.len() != k {
        return None;
    }
    // Shift and scale the box to [0, 1]^n: x = lo + w s, f_k = a_k . s + e_k.
    let w: Vec<f64> = lo.iter().zip(hi).map(|(a, b)| b - a).collect();
    let a: Vec<Vec<f64>> = coef
        .iter()
        .map(|c| c.iter().zip(&w).map(|(ci, wi)| ci * wi).collect())
        .collect();
    let e: Vec<f64> = coef
        .iter()
        .zip(cst)
        .map(|(c, d)| d + c.iter().zip(lo).map(|(ci, l)| ci * l).sum::<f64>())
        .collect();
    // T bounds every f_k above on the box, so t = T - tau with tau >= 0 at the optimum:
    // maximise tau s.t. a_k . s + tau <= T - e_k, s_t <= 1, s, tau >= 0 (feasible at 0).
    let big = (0..k)
        .map(|j| e[j] + a[j].iter().map(|v| v.max(0.0)).sum::<f64>())
        .fold(f64::NEG_INFINITY, f64::max);
    let scale = (0..k)
        .map(|j| e[j].abs() + a[j].iter().map(|v| v.abs()).sum::<f64>())
        .fold(1e-300, f64::max);
    let m = k + n; // rows
    let nv = n + 1; // structural variables: s, tau
    let cols = nv + m + 1; // + slacks + rhs
    let mut tab = vec![0.0; (m + 1) * cols];
    for j in 0..k {
        let r = &mut tab[j * cols..(j + 1) * cols];
        r[..n].copy_from_slice(&a[j]);
        r[n] = 1.0;
        r[nv + j] = 1.0;
        r[cols - 1] = (big - e[j]).max(0.0);
    }
    for t in 0..n {
        let r = &mut tab[(k + t) * cols..(k + t + 1) * cols];
        r[t] = 1.0;
        r[nv + k + t] = 1.0;
        r[cols - 1] = 1.0;
    }
    // Objective row: z - tau = 0.
    tab[m * cols + n] = -1.0;
    if tab.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let mut basis: Vec<usize> = (nv..nv + m).collect();
    let piv_tol = 1e-12 * scale.max(1.0);
    let mut solved = false;
    for _ in 0..50 * (m + nv) {
        // Bland: the lowest-index column with a negative reduced cost enters.
        let obj = &tab[m * cols..];
        let Some(q) = (0..nv + m).find(|&c| obj[c] < -1e-12) else {
            solved = true;
            break;
        };
        // Ratio test; ties to the lowest basic index.
        let mut best: Option<(f64, usize)> = None;
        for i in 0..m {
            let piv = tab[i * cols + q];
            if piv > piv_tol {
                let ratio = tab[i * cols + cols - 1] / piv;
                best = match best {
                    Some((br, bi)) if ratio > br || (ratio == br && basis[i] > basis[bi]) => {
                        Some((br, bi))
                    }
                    _ => Some((ratio, i)),
                };
            }
        }
        let (_, p) = best?; // unbounded cannot happen (tau <= T - e_k); bail out if so
        let piv = tab[p * cols + q];
        for c in 0..cols {
            tab[p * cols + c] /= piv;
        }
        for i in 0..=m {
            if i == p {
                continue;
            }
            let f = tab[i * cols + q];
            if f != 0.0 {
                for c in 0..cols {
                    let v = tab[p * cols + c];
                    tab[i * cols + c] -= f * v;
                }
            }
        }
        basis[p] = q;
    }
    if !solved || tab.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let mut s = vec![0.0; nv];
    for (i, &b) in basis.iter().enumerate() {
        if b < nv {
            s[b] = tab[i * cols + cols - 1];
        }
    }
    let tau = s[n];
    let x: Vec<f64> = (0..n)
        .map(|t| (lo[t] + w[t] * s[t].clamp(0.0, 1.0)).clamp(lo[t], hi[t]))
        .collect();
    // Duals of the k function rows: the reduced costs of their slacks.
    let mut lambda: Vec<f64> = (0..k).map(|j| tab[m * cols + nv + j].max(0.0)).collect();
    let tot: f64 = lambda.iter().sum();
    if tot <= 0.0 || !tot.is_finite() {
        return None;
    }
    lambda.iter_mut().for_each(|l| *l /= tot);
    Some(MinMax {
        value: big - tau,
        x,
        lambda,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Brute force: the max over functions on a fine grid of the box (an upper bound of
    /// the min-max), and the min over lambda on a grid of the simplex of the exact inner
    /// minimum over the box's corners (a lower bound, by weak duality).
    #[test]
    fn agrees_with_grid_search_and_duality() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for trial in 0..300 {
            let n = 1 + trial % 3;
            let k = 1 + trial % 4;
            let lo: Vec<f64> = (0..n).map(|_| rng.gen_range(-2.0..0.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|l| l + rng.gen_range(0.01..3.0)).collect();
            let coefs: Vec<Vec<f64>> = (0..k)
                .map(|_| (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect())
                .collect();
            let cst: Vec<f64> = (0..k).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let refs: Vec<&[f64]> = coefs.iter().map(|c| &c[..]).collect();
            let r = minmax(&refs, &cst, &lo, &hi).expect("solved");
            let f = |x: &[f64]| {
                (0..k)
                    .map(|j| cst[j] + coefs[j].iter().zip(x).map(|(c, v)| c * v).sum::<f64>())
                    .fold(f64::NEG_INFINITY, f64::max)
            };
            // The reported minimiser attains the value.
            assert!((f(&r.x) - r.value).abs() < 1e-9, "trial {trial}");
            // No grid point does better.
            let g = 24usize;
            let mut idx = vec![0usize; n];
            loop {
                let x: Vec<f64> = (0..n)
                    .map(|t| lo[t] + (hi[t] - lo[t]) * idx[t] as f64 / g as f64)
                    .collect();
                assert!(f(&x) >= r.value - 1e-9, "trial {trial}: grid beats LP");
                let mut t = 0;
                while t < n && idx[t] == g {
                    idx[t] = 0;
                    t += 1;
                }
                if t == n {
                    break;
                }
                idx[t] += 1;
            }
            // The weights attain the value (strong duality).
            let comb: Vec<f64> = (0..n)
                .map(|t| (0..k).map(|j| r.lambda[j] * coefs[j][t]).sum())
                .collect();
            let inner = (0..k).map(|j| r.lambda[j] * cst[j]).sum::<f64>()
                + (0..n)
                    .map(|t| (comb[t] * lo[t]).min(comb[t] * hi[t]))
                    .sum::<f64>();
            assert!(
                (inner - r.value).abs() < 1e-9,
                "trial {trial}: dual {inner} primal {}",
                r.value
            );
            assert!(r.lambda.iter().all(|l| *l >= 0.0));
            assert!((r.lambda.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
    }
}
