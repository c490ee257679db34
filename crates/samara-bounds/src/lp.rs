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

use std::time::Instant;

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
    // Every entry comes from `a`, `e` and `big` (the rest are 0 and 1).
    if !big.is_finite() || !e.iter().chain(a.iter().flatten()).all(|v| v.is_finite()) {
        return None;
    }
    let mut basis: Vec<usize> = (nv..nv + m).collect();
    let piv_tol = 1e-12 * scale.max(1.0);
    let mut solved = false;
    let mut rule = Pricing::default();
    let mut nz = Vec::with_capacity(cols);
    for _ in 0..50 * (m + nv) {
        let Some(q) = rule.entering(&tab[m * cols..m * cols + nv + m], 1e-12) else {
            solved = true;
            break;
        };
        // Ratio test; ties to the lowest basic index.
        let p = leaving_row(&tab, cols, m, &basis, q, piv_tol, |r| r)?; // unbounded cannot happen (tau <= T - e_k); bail out if so
        rule.record(tab[p * cols + cols - 1]);
        pivot(&mut tab, cols, m, &mut basis, p, q, &mut nz);
    }
    if !solved || !read_out_finite(&tab, cols, m) {
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

/// Weights for `min c . x` over `{x in [lo, hi] : a_p . x + d_p <= 0 (all p)}`: the
/// optimal dual multipliers `lambda_p >= 0` of the constraints, by the dense tableau
/// simplex method with Bland's rule (Bland, 1977) on the box shifted to `[0, 1]^n`, with
/// a single artificial variable of large cost entering on the most violated row first
/// (so the start is feasible). By weak duality, for *any* `lambda >= 0`,
/// `min over the box of c . x + sum_p lambda_p (a_p . x + d_p)` is at most the
/// constrained minimum, so the caller gets a sound bound from these weights by
/// evaluating that combination with outward rounding; the solver itself is plain f64.
/// `None` when the simplex method does not finish within its iteration cap or meets
/// non-finite numbers.
pub fn min_linear_duals(
    c: &[f64],
    a: &[&[f64]],
    d: &[f64],
    lo: &[f64],
    hi: &[f64],
) -> Option<Vec<f64>> {
    if a.is_empty() && d.is_empty() {
        return Some(Vec::new());
    }
    min_linear(c, a, d, lo, hi).map(|r| r.duals)
}

/// The result of [`min_linear`]: the LP's dual multipliers, a primal point, and whether
/// that point is feasible in f64 (the artificial variable left the basis or ended at 0).
#[derive(Clone, Debug, PartialEq)]
pub struct MinLinear {
    /// Multipliers `lambda_p >= 0` of the constraint rows (see [`min_linear_duals`]).
    pub duals: Vec<f64>,
    /// The primal minimiser (clamped into the box); only a proposal, to be re-checked.
    pub x: Vec<f64>,
    /// Whether the simplex ended feasible (the constraints have a point in f64).
    pub feasible: bool,
}

/// [`min_linear_duals`] with the primal point: `min c . x` over `{x in [lo, hi] :
/// a_p . x + d_p <= 0}`. Plain f64; the caller certifies bounds from the multipliers and
/// re-checks the point. `None` as for [`min_linear_duals`].
pub fn min_linear(c: &[f64], a: &[&[f64]], d: &[f64], lo: &[f64], hi: &[f64]) -> Option<MinLinear> {
    if a.is_empty() && d.is_empty() {
        let x = c
            .iter()
            .enumerate()
            .map(|(t, ci)| if *ci < 0.0 { hi[t] } else { lo[t] })
            .collect();
        return Some(MinLinear {
            duals: Vec::new(),
            x,
            feasible: true,
        });
    }
    MinLinearSolver::new(a, d, lo, hi)?.solve(c)
}

/// [`min_linear`] for one objective, started at the box corner that minimises it: every
/// input with a negative cost is mirrored (`x_t = -x'_t` over `[-hi_t, -lo_t]`, its
/// coefficients negated), so that the simplex method's start `s = 0` is that corner
/// and only the constraints it violates need pivots (on a 784-input MNIST box the
/// unmirrored start spends one pivot per input that the minimiser takes at its upper
/// end). The constraint rows are the same functions, so the multipliers are those of
/// the original problem; the point is mapped back. Solves stop unsolved (`None`) past
/// `deadline`. `None` as for [`min_linear`].
pub fn min_linear_from_corner(
    c: &[f64],
    a: &[&[f64]],
    d: &[f64],
    lo: &[f64],
    hi: &[f64],
    deadline: Option<Instant>,
) -> Option<MinLinear> {
    if a.is_empty() {
        return min_linear(c, a, d, lo, hi);
    }
    let flip: Vec<bool> = c.iter().map(|v| *v < 0.0).collect();
    let sg = |t: usize| if flip[t] { -1.0 } else { 1.0 };
    let c2: Vec<f64> = c.iter().enumerate().map(|(t, v)| sg(t) * v).collect();
    let a2: Vec<Vec<f64>> = a
        .iter()
        .map(|r| r.iter().enumerate().map(|(t, v)| sg(t) * v).collect())
        .collect();
    let lo2: Vec<f64> = (0..lo.len())
        .map(|t| if flip[t] { -hi[t] } else { lo[t] })
        .collect();
    let hi2: Vec<f64> = (0..lo.len())
        .map(|t| if flip[t] { -lo[t] } else { hi[t] })
        .collect();
    let refs: Vec<&[f64]> = a2.iter().map(|r| &r[..]).collect();
    let mut r = MinLinearSolver::new(&refs, d, &lo2, &hi2)?
        .with_deadline(deadline)
        .solve(&c2)?;
    for (t, x) in r.x.iter_mut().enumerate() {
        *x = (sg(t) * *x).clamp(lo[t], hi[t]);
    }
    Some(r)
}

/// [`min_linear`] over one set of constraints for several objectives: the tableau is
/// built once, and each solve starts from the basis the previous one ended with (a
/// basis feasible for the constraints stays feasible when only the objective changes:
/// the objective row is rebuilt from the new costs and the basic columns eliminated,
/// then the primal simplex method goes on). Each solve is optimal for its own objective
/// like a cold [`min_linear`], so its multipliers give the same bound (they can differ
/// where the optimal multipliers are not unique).
#[derive(Clone, Debug)]
pub struct MinLinearSolver {
    tab: Vec<f64>,
    basis: Vec<usize>,
    /// Constraint rows (`m`) and box rows (`n`).
    rows: usize,
    cols: usize,
    m: usize,
    n: usize,
    /// Each constraint row's scale (its multiplier is scaled back).
    scale: Vec<f64>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    /// False once a solve met non-finite numbers (the tableau is then unusable).
    finite: bool,
    /// Solves stop unsolved (`None`) past this instant.
    deadline: Option<Instant>,
}

impl MinLinearSolver {
    /// The tableau of `{x in [lo, hi] : a_p . x + d_p <= 0}` (at least one row), on the
    /// box shifted to `[0, 1]^n`, each row scaled to unit size, with a single artificial
    /// variable `r` entered on the most violated row (so the start is feasible; `r` is
    /// priced at a large cost in every objective). `None` when a row is not finite.
    pub fn new(a: &[&[f64]], d: &[f64], lo: &[f64], hi: &[f64]) -> Option<Self> {
        let m = a.len();
        let n = lo.len();
        if d.len() != m || m == 0 {
            return None;
        }
        let w: Vec<f64> = lo.iter().zip(hi).map(|(l, h)| h - l).collect();
        let mut scale = vec![1.0; m];
        let rows = m + n;
        let nv = n + 1; // s, r
        let cols = nv + rows + 1;
        let mut tab = vec![0.0; (rows + 1) * cols];
        for p in 0..m {
            let e = d[p] + a[p].iter().zip(lo).map(|(ai, l)| ai * l).sum::<f64>();
            let sz = a[p]
                .iter()
                .zip(&w)
                .map(|(ai, wi)| (ai * wi).abs())
                .sum::<f64>()
                .max(e.abs())
                .max(1e-300);
            scale[p] = sz;
            let r = &mut tab[p * cols..(p + 1) * cols];
            for t in 0..n {
                r[t] = a[p][t] * w[t] / sz;
            }
            r[n] = -1.0;
            r[nv + p] = 1.0;
            r[cols - 1] = -e / sz;
        }
        for t in 0..n {
            let r = &mut tab[(m + t) * cols..(m + t + 1) * cols];
            r[t] = 1.0;
            r[nv + m + t] = 1.0;
            r[cols - 1] = 1.0;
        }
        // The constraint rows (scaled) and their right-hand sides: the rest of the
        // tableau is 0 and 1.
        if !(0..m).all(|p| {
            tab[p * cols..p * cols + n]
                .iter()
                .chain(std::iter::once(&tab[p * cols + cols - 1]))
                .all(|v| v.is_finite())
        }) {
            return None;
        }
        let mut basis: Vec<usize> = (nv..nv + rows).collect();
        // The most violated row takes the artificial variable r.
        let (q, minr) = (0..m)
            .map(|p| (p, tab[p * cols + cols - 1]))
            .fold((0, 0.0), |b, x| if x.1 < b.1 { x } else { b });
        if minr < 0.0 {
            let mut nz = Vec::with_capacity(cols);
            pivot(&mut tab, cols, rows, &mut basis, q, n, &mut nz);
        }
        Some(MinLinearSolver {
            tab,
            basis,
            rows,
            cols,
            m,
            n,
            scale,
            lo: lo.to_vec(),
            hi: hi.to_vec(),
            finite: true,
            deadline: None,
        })
    }

    /// Solves stop unsolved (`None`) past `deadline` (checked every few pivots; one
    /// pivot of a 784-input tableau with 150 rows takes about a millisecond).
    pub fn with_deadline(mut self, deadline: Option<Instant>) -> Self {
        self.deadline = deadline;
        self
    }

    /// `min c . x` over the constraints, from the current basis; `None` when the
    /// simplex method does not finish within its iteration cap (its basis, still
    /// feasible, is where the next solve starts) or meets non-finite numbers (then every
    /// later solve is `None` too).
    pub fn solve(&mut self, c: &[f64]) -> Option<MinLinear> {
        let (rows, cols, m, n) = (self.rows, self.cols, self.m, self.n);
        let nv = n + 1;
        let w: Vec<f64> = self.lo.iter().zip(&self.hi).map(|(l, h)| h - l).collect();
        let cs: Vec<f64> = c.iter().zip(&w).map(|(ci, wi)| ci * wi).collect();
        let big = 1e4 * (1.0 + cs.iter().map(|v| v.abs()).sum::<f64>());
        if !big.is_finite() || !self.finite {
            return None;
        }
        let tab = &mut self.tab;
        let basis = &mut self.basis;
        // The objective row from the costs, with the basic columns eliminated.
        {
            let o = &mut tab[rows * cols..];
            o.iter_mut().for_each(|v| *v = 0.0);
            o[..n].copy_from_slice(&cs);
            o[n] = big;
        }
        for i in 0..rows {
            let b = basis[i];
            let f = tab[rows * cols + b];
            if f != 0.0 {
                let (body, obj) = tab.split_at_mut(rows * cols);
                let row = &body[i * cols..(i + 1) * cols];
                for (o, v) in obj.iter_mut().zip(row) {
                    *o -= f * v;
                }
                obj[b] = 0.0;
            }
        }
        let tol = 1e-12;
        let mut solved = false;
        let mut rule = Pricing::default();
        let mut nz = Vec::with_capacity(cols);
        for it in 0..50 * (rows + nv) {
            if it % 8 == 7 && self.deadline.is_some_and(|d| Instant::now() >= d) {
                break;
            }
            let Some(q) = rule.entering(&tab[rows * cols..rows * cols + nv + rows], 1e-12 * big)
            else {
                solved = true;
                break;
            };
            let Some(p) = leaving_row(tab, cols, rows, basis, q, tol, |r| r.max(0.0)) else {
                break;
            };
            rule.record(tab[p * cols + cols - 1]);
            pivot(tab, cols, rows, basis, p, q, &mut nz);
        }
        if !read_out_finite(tab, cols, rows) {
            self.finite = false;
            return None;
        }
        if !solved {
            return None;
        }
        let mut sv = vec![0.0; nv];
        for (i, &b) in basis.iter().enumerate() {
            if b < nv {
                sv[b] = tab[i * cols + cols - 1];
            }
        }
        let x = (0..n)
            .map(|t| (self.lo[t] + w[t] * sv[t].clamp(0.0, 1.0)).clamp(self.lo[t], self.hi[t]))
            .collect();
        Some(MinLinear {
            duals: (0..m)
                .map(|p| (tab[rows * cols + nv + p].max(0.0) / self.scale[p]).max(0.0))
                .collect(),
            x,
            feasible: sv[n] <= 1e-9,
        })
    }
}

/// Whether what a solver reads out of its final tableau is finite: the right-hand side
/// column (the primal point) and the objective row (the duals). Checking these instead of
/// the whole tableau costs O(rows + cols) instead of O(rows cols); the solvers only
/// propose, and their callers certify every bound and re-check every point.
fn read_out_finite(tab: &[f64], cols: usize, rows: usize) -> bool {
    (0..rows).all(|i| tab[i * cols + cols - 1].is_finite())
        && tab[rows * cols..].iter().all(|v| v.is_finite())
}

/// The entering-column rule of both solvers: Dantzig's (the most negative reduced cost
/// enters), which needs far fewer pivots than Bland's on these tableaux, until a run of
/// degenerate pivots (a zero step, where Dantzig's rule can cycle) is seen; from then on
/// Bland's rule (the lowest-index negative reduced cost, Bland 1977), which cannot cycle,
/// so every solve still terminates.
#[derive(Default)]
struct Pricing {
    /// Consecutive degenerate pivots seen so far.
    degenerate: usize,
    /// Bland's rule from now on.
    bland: bool,
}

impl Pricing {
    /// Degenerate pivots in a row after which Bland's rule takes over.
    const MAX_DEGENERATE: usize = 20;

    /// The entering column among the reduced costs `obj` below `-tol`, if any.
    fn entering(&self, obj: &[f64], tol: f64) -> Option<usize> {
        if self.bland {
            return obj.iter().position(|&v| v < -tol);
        }
        let (q, v) = obj
            .iter()
            .enumerate()
            .fold((0, 0.0), |b, (c, &v)| if v < b.1 { (c, v) } else { b });
        (v < -tol).then_some(q)
    }

    /// Record a pivot whose leaving row had right-hand side `rhs` (zero: degenerate).
    fn record(&mut self, rhs: f64) {
        if rhs <= 0.0 {
            self.degenerate += 1;
            if self.degenerate >= Self::MAX_DEGENERATE {
                self.bland = true;
            }
        } else {
            self.degenerate = 0;
        }
    }
}

/// The ratio test of a simplex step on the dense tableau `tab` (`cols` columns, `rows`
/// constraint rows, right-hand side last): among the rows whose entry in the entering
/// column `q` exceeds `tol`, the one with the smallest ratio `rhs(b_i) / a_iq`, ties to
/// the lowest basic index (Bland's rule); `None` when no row qualifies (unbounded).
fn leaving_row(
    tab: &[f64],
    cols: usize,
    rows: usize,
    basis: &[usize],
    q: usize,
    tol: f64,
    rhs: impl Fn(f64) -> f64,
) -> Option<usize> {
    let mut best: Option<(f64, usize)> = None;
    for i in 0..rows {
        let piv = tab[i * cols + q];
        if piv > tol {
            let ratio = rhs(tab[i * cols + cols - 1]) / piv;
            best = match best {
                Some((br, bi)) if ratio > br || (ratio == br && basis[i] > basis[bi]) => {
                    Some((br, bi))
                }
                _ => Some((ratio, i)),
            };
        }
    }
    best.map(|(_, p)| p)
}

/// One simplex pivot on the dense tableau `tab` (`cols` columns, rows `0..=last`, the
/// objective row included) at row `p`, column `q`; `q` enters the basis at row `p`.
/// `nz` is scratch space for the pivot row's non-zero entries (kept between pivots so
/// that a solve allocates it once).
fn pivot(
    tab: &mut [f64],
    cols: usize,
    last: usize,
    basis: &mut [usize],
    p: usize,
    q: usize,
    nz: &mut Vec<(usize, f64)>,
) {
    let piv = tab[p * cols + q];
    for c in 0..cols {
        tab[p * cols + c] /= piv;
    }
    // The pivot row's non-zero entries, so that each row update touches only those.
    nz.clear();
    nz.extend(
        tab[p * cols..(p + 1) * cols]
            .iter()
            .enumerate()
            .filter(|(_, v)| **v != 0.0)
            .map(|(c, v)| (c, *v)),
    );
    for i in 0..=last {
        if i == p {
            continue;
        }
        let f = tab[i * cols + q];
        if f != 0.0 {
            let row = &mut tab[i * cols..(i + 1) * cols];
            for &(c, v) in nz.iter() {
                row[c] -= f * v;
            }
        }
    }
    basis[p] = q;
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// A random box of `n` inputs: lower ends in [-2, 0], widths in [0.01, 3].
    fn random_box(rng: &mut rand_chacha::ChaCha8Rng, n: usize) -> (Vec<f64>, Vec<f64>) {
        let lo: Vec<f64> = (0..n).map(|_| rng.gen_range(-2.0..0.0)).collect();
        let hi: Vec<f64> = lo.iter().map(|l| l + rng.gen_range(0.01..3.0)).collect();
        (lo, hi)
    }

    /// `m` random rows `d_p + a_p . x <= 0` over `n` inputs: `a` in [-1, 1], `d` in
    /// [-1, d_hi).
    fn random_rows(
        rng: &mut rand_chacha::ChaCha8Rng,
        n: usize,
        m: usize,
        d_hi: f64,
    ) -> (Vec<Vec<f64>>, Vec<f64>) {
        let a: Vec<Vec<f64>> = (0..m)
            .map(|_| (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect())
            .collect();
        let d: Vec<f64> = (0..m).map(|_| rng.gen_range(-1.0..d_hi)).collect();
        (a, d)
    }

    /// The weak-duality bound of multipliers `lam`: the minimum over the box of the
    /// Lagrangian `c . x + sum_p lam_p (d_p + a_p . x)` (f64, for comparisons only).
    fn dual_bound(
        c: &[f64],
        a: &[Vec<f64>],
        d: &[f64],
        lo: &[f64],
        hi: &[f64],
        lam: &[f64],
    ) -> f64 {
        let coef: Vec<f64> = (0..c.len())
            .map(|t| c[t] + (0..a.len()).map(|p| lam[p] * a[p][t]).sum::<f64>())
            .collect();
        (0..a.len()).map(|p| lam[p] * d[p]).sum::<f64>()
            + (0..c.len())
                .map(|t| (coef[t] * lo[t]).min(coef[t] * hi[t]))
                .sum::<f64>()
    }

    /// Whether `x` satisfies every row `d_p + a_p . x <= 0`.
    fn feasible(a: &[Vec<f64>], d: &[f64], x: &[f64]) -> bool {
        (0..a.len()).all(|p| d[p] + a[p].iter().zip(x).map(|(u, v)| u * v).sum::<f64>() <= 0.0)
    }

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

    /// The multipliers of [`min_linear_duals`] give, by weak duality, a lower bound of
    /// the constrained minimum that no feasible sample beats, and close to the best
    /// feasible sample (the LP optimum) on random small problems.
    #[test]
    fn duals_bound_the_constrained_minimum() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut tight = 0;
        for trial in 0..200 {
            let n = 1 + trial % 3;
            let m = 1 + trial % 5;
            let (lo, hi) = random_box(&mut rng, n);
            let c: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let (a, d) = random_rows(&mut rng, n, m, 0.5);
            let refs: Vec<&[f64]> = a.iter().map(|r| &r[..]).collect();
            let lam = min_linear_duals(&c, &refs, &d, &lo, &hi).expect("solved");
            assert!(lam.iter().all(|l| *l >= 0.0 && l.is_finite()));
            // The Lagrangian's minimum over the box (a lower bound by weak duality).
            let lb = dual_bound(&c, &a, &d, &lo, &hi, &lam);
            let mut best = f64::INFINITY;
            for _ in 0..4000 {
                let x: Vec<f64> = (0..n).map(|t| rng.gen_range(lo[t]..=hi[t])).collect();
                if feasible(&a, &d, &x) {
                    let v = c.iter().zip(&x).map(|(u, v)| u * v).sum::<f64>();
                    assert!(v >= lb - 1e-9, "trial {trial}: sample {v} below bound {lb}");
                    best = best.min(v);
                }
            }
            if best.is_finite() && best - lb < 0.05 * (1.0 + best.abs()) {
                tight += 1;
            }
        }
        assert!(tight > 100, "the multipliers are rarely tight: {tight}");
    }

    /// [`MinLinearSolver`] warm-started from one objective's basis to the next gives the
    /// cold solve's optimum: on 300 random LPs (1-5 variables, 1-14 rows, some of them
    /// infeasible), for 8 objectives in turn, the weak-duality bound of the warm solve's
    /// multipliers (the Lagrangian's exact minimum over the box) equals that of a cold
    /// [`min_linear`] within 1e-9, and no feasible sample lies below it.
    #[test]
    fn warm_started_solves_equal_cold_ones() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(44);
        let mut compared = 0;
        for trial in 0..300 {
            let n = 1 + trial % 5;
            let m = 1 + trial % 14;
            let (lo, hi) = random_box(&mut rng, n);
            let (a, d) = random_rows(&mut rng, n, m, 0.3);
            let refs: Vec<&[f64]> = a.iter().map(|r| &r[..]).collect();
            let bound = |c: &[f64], lam: &[f64]| dual_bound(c, &a, &d, &lo, &hi, lam);
            let samples: Vec<Vec<f64>> = (0..2000)
                .map(|_| (0..n).map(|t| rng.gen_range(lo[t]..=hi[t])).collect())
                .filter(|x: &Vec<f64>| feasible(&a, &d, x))
                .collect();
            let mut warm = MinLinearSolver::new(&refs, &d, &lo, &hi).expect("finite rows");
            for _ in 0..8 {
                let c: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
                let w = warm.solve(&c).expect("warm solve");
                let cold = min_linear(&c, &refs, &d, &lo, &hi).expect("cold solve");
                assert_eq!(w.feasible, cold.feasible, "trial {trial}");
                let (bw, bc) = (bound(&c, &w.duals), bound(&c, &cold.duals));
                let size = 1.0 + bw.abs().max(bc.abs());
                assert!(
                    (bw - bc).abs() <= 1e-9 * size,
                    "trial {trial}: warm {bw} cold {bc}"
                );
                for x in &samples {
                    let v = c.iter().zip(x).map(|(u, v)| u * v).sum::<f64>();
                    assert!(v >= bw - 1e-9, "trial {trial}: sample {v} below {bw}");
                }
                compared += 1;
            }
        }
        assert_eq!(compared, 2400);
    }

    /// [`min_linear_from_corner`] (inputs of negative cost mirrored) solves the same
    /// LP as [`min_linear`]: on 300 random LPs (1-6 variables, 1-10 rows, some
    /// infeasible) the weak-duality bounds of the two solves' multipliers agree within
    /// 1e-9 (both positive when infeasible), no feasible sample lies below them, and the point is in the box (and
    /// satisfies the rows within 1e-9 when the solve says feasible).
    #[test]
    fn corner_start_solves_the_same_lp() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(51);
        for trial in 0..300 {
            let n = 1 + trial % 6;
            let m = 1 + trial % 10;
            let (lo, hi) = random_box(&mut rng, n);
            let c: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let (a, d) = random_rows(&mut rng, n, m, 0.3);
            let refs: Vec<&[f64]> = a.iter().map(|r| &r[..]).collect();
            let bound = |lam: &[f64]| dual_bound(&c, &a, &d, &lo, &hi, lam);
            let r = min_linear_from_corner(&c, &refs, &d, &lo, &hi, None).expect("solved");
            let cold = min_linear(&c, &refs, &d, &lo, &hi).expect("cold");
            assert_eq!(r.feasible, cold.feasible, "trial {trial}");
            let (b, bc) = (bound(&r.duals), bound(&cold.duals));
            // An infeasible LP's multipliers only need a positive bound (their size
            // follows the artificial variable's cost and the path taken).
            assert!(
                (b - bc).abs() <= 1e-9 * (1.0 + b.abs().max(bc.abs()))
                    || (!r.feasible && b > 0.0 && bc > 0.0),
                "trial {trial}: corner {b} cold {bc}"
            );
            assert!((0..n).all(|t| lo[t] <= r.x[t] && r.x[t] <= hi[t]));
            if r.feasible {
                for p in 0..m {
                    let v = d[p] + a[p].iter().zip(&r.x).map(|(u, v)| u * v).sum::<f64>();
                    assert!(v <= 1e-9, "trial {trial}: row {p} at {v}");
                }
            }
            for _ in 0..2000 {
                let x: Vec<f64> = (0..n).map(|t| rng.gen_range(lo[t]..=hi[t])).collect();
                if feasible(&a, &d, &x) {
                    let v = c.iter().zip(&x).map(|(u, v)| u * v).sum::<f64>();
                    assert!(v >= b - 1e-9, "trial {trial}: sample {v} below {b}");
                }
            }
        }
    }

    /// The LP size of a deep MNIST node decided exactly (784 inputs, 150 phase rows):
    /// timing only (`cargo test --release -p samara-bounds --lib lp_speed_mnist --
    /// --ignored --nocapture`). Rows are random dense ones through a point of the
    /// box (so the set is not empty), the box an eps-ball of 0.05 in [0, 1].
    #[test]
    #[ignore]
    fn lp_speed_mnist() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let n = 784;
        for m in [20usize, 60, 110, 150] {
            let x0: Vec<f64> = (0..n).map(|_| rng.gen_range(0.0..1.0)).collect();
            let lo: Vec<f64> = x0.iter().map(|v| (v - 0.05f64).max(0.0)).collect();
            let hi: Vec<f64> = x0.iter().map(|v| (v + 0.05f64).min(1.0)).collect();
            let a: Vec<Vec<f64>> = (0..m)
                .map(|_| (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect())
                .collect();
            let d: Vec<f64> = a
                .iter()
                .map(|r| -r.iter().zip(&x0).map(|(u, v)| u * v).sum::<f64>() - 0.05)
                .collect();
            let refs: Vec<&[f64]> = a.iter().map(|r| &r[..]).collect();
            let c: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let t = std::time::Instant::now();
            let r = min_linear_from_corner(&c, &refs, &d, &lo, &hi, None).expect("solved");
            let t1 = t.elapsed().as_secs_f64();
            let t = std::time::Instant::now();
            let r2 = min_linear(&c, &refs, &d, &lo, &hi).expect("solved");
            let t2 = t.elapsed().as_secs_f64();
            eprintln!(
                "784 x {m}: from the corner {t1:.3} s (feasible {}), plain {t2:.3} s (feasible {})",
                r.feasible, r2.feasible
            );
        }
    }
}
