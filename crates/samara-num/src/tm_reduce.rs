//! Reduction of vectors of Taylor models (sets `x(xi)`, `xi in [-1, 1]^n`) that keep
//! every value they held:
//! - [`precondition`]: the set re-parameterised as a parallelotope in fresh parameters
//!   (Lohner's frames, Makino & Berz's preconditioning), its higher-order terms and
//!   remainders becoming parameters, with an approximate matrix inverse whose error is
//!   enclosed;
//! - [`reduce`] / [`reduce_with`]: order reduction to a budget of parameters, the
//!   heaviest kept, the dropped dependence folded into one fresh parameter per state;
//! - the small helpers both need ([`mid_rad`], [`linear_parts`], [`fresh_param`]) and
//!   the test of when it pays ([`needs_precondition`], [`remainders_past`]).
//!
//! Used by the reachability code's Taylor-model engine at control instants and inside
//! its flowpipe; kept beside [`Tm`] because it is arithmetic on Taylor models, with no
//! knowledge of plants or networks.

use crate::{Interval, Scalar, Tm};

/// A midpoint `m` and radius `r` with `[m - r, m + r]` containing `i` in exact
/// arithmetic (the ends checked with outward-rounded interval sums); `(lo, 0)` for a
/// point.
pub fn mid_rad(i: Interval) -> (f64, f64) {
    if i.lo == i.hi {
        return (i.lo, 0.0);
    }
    let m = 0.5 * i.lo + 0.5 * i.hi;
    let mut r = (i.hi - m).max(m - i.lo).max(0.0).next_up();
    let (pm, pr) = (Interval::point(m), Interval::point(r));
    let (mut lo, mut hi) = ((pm - pr).hi, (pm + pr).lo);
    // Grow by a step that doubles: one ulp of `r` at a time would take up to 2^52
    // rounds when `r` is tiny against `m` (a point-like interval away from 0).
    let mut step = (r * f64::EPSILON)
        .max(m.abs() * f64::EPSILON)
        .max(f64::MIN_POSITIVE);
    while lo > i.lo || hi < i.hi {
        r = (r + step).next_up();
        step *= 2.0;
        let pr = Interval::point(r);
        (lo, hi) = ((pm - pr).hi, (pm + pr).lo);
    }
    (m, r)
}

/// The constant coefficients of `x` and their degree-1 coefficients over every
/// parameter any of them depends on (rows padded to that count).
pub fn linear_parts(x: &[Tm]) -> (Vec<f64>, Vec<Vec<f64>>) {
    let n = x.iter().map(|v| v.n_vars()).max().unwrap_or(0);
    x.iter()
        .map(|v| {
            let (c, mut g) = v.linear_part();
            g.resize(n, 0.0);
            (c, g)
        })
        .unzip()
}

/// The parameter `xi_k` of `total` for a symbolic remainder of `p`: on `p`'s own table
/// kind (a mixed-degree `p` gives it its lifted weight), or a classic one of `order`
/// when `p` has no order of its own (a constant).
pub fn fresh_param(p: &Tm, k: usize, total: usize, order: u32) -> Tm {
    if p.order() == order {
        p.param(k, total)
    } else {
        Tm::var(k, total, order)
    }
}

/// Whether the interval remainders of `x` are large enough, against the sets' own
/// widths (`hull`, the models' bounds), that turning them into parameters pays
/// ([`precondition`], [`reduce`], and inside a period the flow's own lifting).
pub fn needs_precondition(x: &[Tm], hull: &[Interval]) -> bool {
    remainders_past(x, hull, 0.05)
}

/// Whether some state's interval remainder is wider than `share` of its width.
pub fn remainders_past(x: &[Tm], hull: &[Interval], share: f64) -> bool {
    x.iter().zip(hull).any(|(v, b)| {
        let r = v.rem();
        let w = b.hi - b.lo;
        w > 0.0 && (r.hi - r.lo) > share * w
    })
}

/// Columns of `l` (`d x n`, taken in order of decreasing norm, then the unit vectors)
/// that are far from the span of the ones chosen before (Gram-Schmidt residual above
/// `1e-3` of the norm, so the chosen set is well conditioned): `(the chosen columns as
/// they are, their orthonormalised versions)`, each up to `d` of them.
fn independent_columns(l: &[Vec<f64>], d: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let n = l.first().map_or(0, |r| r.len());
    let mut cols: Vec<Vec<f64>> = (0..n).map(|k| (0..d).map(|i| l[i][k]).collect()).collect();
    let norm = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>().sqrt();
    cols.sort_by(|a, b| norm(b).total_cmp(&norm(a)));
    cols.extend((0..d).map(|j| (0..d).map(|i| if i == j { 1.0 } else { 0.0 }).collect()));
    let mut raw: Vec<Vec<f64>> = Vec::with_capacity(d);
    let mut q: Vec<Vec<f64>> = Vec::with_capacity(d);
    for v0 in cols {
        if q.len() == d {
            break;
        }
        let n0 = norm(&v0);
        if !(n0.is_finite() && n0 > 0.0) {
            continue;
        }
        let mut v = v0.clone();
        for _ in 0..2 {
            for u in &q {
                let dot: f64 = u.iter().zip(&v).map(|(a, b)| a * b).sum();
                for (vi, ui) in v.iter_mut().zip(u) {
                    *vi -= dot * ui;
                }
            }
        }
        let n1 = norm(&v);
        if n1 > 1e-3 * n0 {
            q.push(v.iter().map(|a| a / n1).collect());
            raw.push(v0);
        }
    }
    (raw, q)
}

/// Inverse of the `d x d` matrix with columns `a` by Gauss-Jordan elimination with
/// partial pivoting, as rows; `None` when a pivot vanishes or an entry is not finite.
/// Only an approximation: [`reparameterise`] encloses the error `I - A B` it leaves.
fn inverse(a: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let d = a.len();
    // m = [A | I], rows.
    let mut m: Vec<Vec<f64>> = (0..d)
        .map(|i| {
            let mut r: Vec<f64> = (0..d).map(|k| a[k][i]).collect();
            r.extend((0..d).map(|j| if i == j { 1.0 } else { 0.0 }));
            r
        })
        .collect();
    for col in 0..d {
        let piv = (col..d).max_by(|&x, &y| m[x][col].abs().total_cmp(&m[y][col].abs()))?;
        if m[piv][col] == 0.0 || !m[piv][col].is_finite() {
            return None;
        }
        m.swap(col, piv);
        let p = m[col][col];
        for v in m[col].iter_mut() {
            *v /= p;
        }
        let pivot_row = m[col].clone();
        for (r, row) in m.iter_mut().enumerate() {
            let f = row[col];
            if r != col && f != 0.0 {
                for (x, t) in row.iter_mut().zip(&pivot_row) {
                    *x -= f * t;
                }
            }
        }
    }
    let b: Vec<Vec<f64>> = m.into_iter().map(|r| r[d..].to_vec()).collect();
    b.iter()
        .all(|r| r.iter().all(|v| v.is_finite()))
        .then_some(b)
}

/// Order reduction of a set of Taylor models to at most `max_params` parameters, keeping
/// the higher-order dependence on the parameters that matter: the parameters are ranked
/// by the share of each state's width that depends on them (`Tm::param_weights` over the
/// state's width, summed over states, as Girard's reduction ranks a zonotope's
/// generators; Girard, HSCC 2005), the `max_params - d` heaviest kept and renumbered, every
/// monomial of a dropped one bounded into the remainder (`Tm::reparam`), and each state's
/// remainder then given a fresh parameter of its own (`d` of them): the dropped
/// dependence becomes an axis-aligned box, as a zonotope's reduced generators do. Unlike
/// [`precondition`], the kept parameters keep their nonlinear terms and nothing is
/// inverted.
pub fn reduce(x: &[Tm], max_params: usize, order: u32) -> Vec<Tm> {
    reduce_with(x, &[], max_params, order).0
}

/// [`reduce`] of the states `x` with the models `u` that share their parameters (the
/// held plant inputs inside a period): the parameters are ranked on `x` alone, and `u`
/// is renumbered by the same map (its dropped monomials bounded into its remainder, its
/// remainder left an interval), so the two stay consistent.
pub fn reduce_with(x: &[Tm], u: &[Tm], max_params: usize, order: u32) -> (Vec<Tm>, Vec<Tm>) {
    let d = x.len();
    let n = x.iter().chain(u).map(|v| v.n_vars()).max().unwrap_or(0);
    let keep = max_params.saturating_sub(d).min(n);
    let mut score = vec![0.0; n];
    for v in x {
        let w = v.bound().width();
        if !(w.is_finite() && w > 0.0) {
            continue;
        }
        for (k, pw) in v.param_weights().into_iter().enumerate() {
            score[k] += pw / w;
        }
    }
    // On mixed-degree models the weight-1 parameters (the initial set's) are always
    // kept, in place: they carry the nonlinear dependence, and a lifted parameter moved
    // into their places would be a waste of the weights.
    let full = x
        .iter()
        .chain(u)
        .filter_map(|v| v.full_params())
        .min()
        .unwrap_or(0)
        .min(n);
    let keep = keep.max(full);
    let mut rank: Vec<usize> = (full..n).collect();
    rank.sort_by(|&a, &b| score[b].total_cmp(&score[a]));
    let mut kept: Vec<usize> = (0..full)
        .chain(rank[..keep - full].iter().copied())
        .collect();
    kept.sort_unstable();
    let mut map: Vec<Option<usize>> = vec![None; n];
    for (j, &k) in kept.iter().enumerate() {
        map[k] = Some(j);
    }
    let total = keep + d;
    let xs = x
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let (p, r) = v.reparam(&map, total).split_rem();
            let (m, rad) = mid_rad(r);
            if rad > 0.0 {
                let xi = fresh_param(&p, keep + i, total, order);
                p + xi * rad + m
            } else {
                p + m
            }
        })
        .collect();
    let us = u.iter().map(|v| v.reparam(&map, total)).collect();
    (xs, us)
}

/// Re-parameterise a set of Taylor models as a parallelotope in fresh parameters
/// `zeta in [-1, 1]^d` (Lohner, *Einschliessung der Loesung gewoehnlicher Anfangs- und
/// Randwertaufgaben*, 1988; the preconditioning of Makino & Berz, *Int. J. Diff. Eq.
/// Appl.* 10, 2005, and 2009). Two frames are tried and the one whose new set has the
/// smaller hull (the sum of its widths, each relative to the old set's) is kept:
/// - the **parallelepiped** frame `A` = the linear part's own columns (the largest,
///   well-conditioned ones, completed by unit vectors): the linear part maps to the
///   identity, so a set whose higher-order terms and remainders are small keeps its
///   shape exactly and only those are wrapped;
/// - the **QR** frame `A = Q`, an orthonormal basis aligned with the linear part, which
///   stays well conditioned when the set is thin and the parallelepiped frame would
///   amplify the remainders by its condition number.
///
/// With `c` the constant coefficients and `B` an approximate inverse of `A`,
/// `y = B (x - c)` is bounded in Taylor-model arithmetic by boxes `m_k +- r_k`, and
/// `x = c + A y + (I - A B)(x - c)`; the new models are `c + A (m + r zeta)` with every
/// rounding of their f64 coefficients, and the term `(I - A B)(x - c)` (A B is the
/// identity only to rounding), enclosed by interval arithmetic in the remainders. The
/// remainders and higher-order terms become parameters, so the network and the dynamics
/// see them as directions they can map (and feedback can contract), at the price of the
/// higher-order dependence.
pub fn precondition(x: &[Tm], order: u32) -> Vec<Tm> {
    let d = x.len();
    let (c, l) = linear_parts(x);
    let (raw, q) = independent_columns(&l, d);
    if q.len() != d {
        return x.to_vec();
    }
    let hull: Vec<Interval> = x.iter().map(|v| v.bound()).collect();
    let size = |y: &[Tm]| -> f64 {
        y.iter()
            .zip(&hull)
            .map(|(v, h)| {
                let w = v.bound().width();
                let h = h.width();
                if h > 0.0 {
                    w / h
                } else {
                    w
                }
            })
            .sum()
    };
    let qr = reparameterise(x, &c, &q, &q, order);
    let pp = inverse(&raw).and_then(|b| reparameterise(x, &c, &raw, &b, order));
    match (qr, pp) {
        (Some(a), Some(b)) => {
            if size(&b) <= size(&a) {
                b
            } else {
                a
            }
        }
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => x.to_vec(),
    }
}

/// The set `x` written as `c + A (m + r zeta)` (see [`precondition`]): `a[k]` the `k`-th
/// column of `A`, `b[k]` the `k`-th row of an approximate inverse `B`. `None` when a
/// bound is not finite.
fn reparameterise(
    x: &[Tm],
    c: &[f64],
    a: &[Vec<f64>],
    b: &[Vec<f64>],
    order: u32,
) -> Option<Vec<Tm>> {
    let d = x.len();
    // Centred models and their boxes.
    let dx: Vec<Tm> = x.iter().zip(c).map(|(v, ci)| v.clone() - *ci).collect();
    let dbox: Vec<Interval> = dx.iter().map(|v| v.bound()).collect();
    if dbox.iter().any(|b| !(b.lo.is_finite() && b.hi.is_finite())) {
        return None;
    }
    // y_k = sum_i b[k][i] dx_i, bounded.
    let ys: Vec<(f64, Interval)> = b
        .iter()
        .map(|bk| {
            let mut acc = Tm::cst(0.0);
            for (bi, dxi) in bk.iter().zip(&dx) {
                if *bi != 0.0 {
                    acc += dxi.clone() * *bi;
                }
            }
            let (m, r) = mid_rad(acc.bound());
            (m, Interval::point(r))
        })
        .collect();
    if ys.iter().any(|(m, r)| !(m.is_finite() && r.hi.is_finite())) {
        return None;
    }
    let out: Vec<Tm> = (0..d)
        .map(|i| {
            // Exact x_i = c_i + sum_k A_ik y_k + e_i with e = (I - A B)(x - c).
            let mut e = Interval::point(0.0);
            for j in 0..d {
                let mut mij = Interval::point(if i == j { 1.0 } else { 0.0 });
                for (ak, bk) in a.iter().zip(b) {
                    mij -= Interval::point(ak[i]) * bk[j];
                }
                e += mij * dbox[j];
            }
            let mut cst = Interval::point(c[i]);
            let mut coef = Vec::with_capacity(d);
            let mut slack = Interval::point(0.0);
            for (k, ak) in a.iter().enumerate() {
                let (m, r) = ys[k];
                cst += Interval::point(ak[i]) * m;
                // (coefficient - mid) zeta_k with |zeta_k| <= 1.
                let (mid, dev) = mid_rad(r * ak[i]);
                coef.push(mid);
                slack += Interval::new(-dev, dev);
            }
            let (cm, cdev) = mid_rad(cst);
            let rem = e + slack + Interval::new(-cdev, cdev);
            Tm::affine(cm, &coef, order)
                .with_rem(Interval::new(rem.lo.next_down(), rem.hi.next_up()))
        })
        .collect();
    out.iter()
        .all(|v| {
            let b = v.bound();
            b.lo.is_finite() && b.hi.is_finite()
        })
        .then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `mid_rad` ends for intervals whose radius is tiny against their midpoint (it
    /// looped ~2^52 times on `[1, 1 + ulp]`), its range contains the interval under
    /// outward-rounded sums, and its radius stays within a few ulps of the half-width.
    #[test]
    fn mid_rad_contains_and_ends_on_narrow_intervals() {
        let mut cases = vec![
            Interval::new(1.0, 1.0f64.next_up()),
            Interval::new(1e300, 1e300f64.next_up()),
            Interval::new(-1e-300, 1e-300),
            Interval::new(-5e-324, 5e-324),
            Interval::new(-3.0, 7.5),
            Interval::new(0.1, 0.3),
            Interval::new(-1.0f64.next_down(), -1.0),
        ];
        let mut x = 0.7f64;
        for k in 0..2000 {
            x = (x * 3.9 * (1.0 - x)).clamp(1e-9, 1.0 - 1e-9);
            let lo = (x - 0.5) * 10f64.powi(k % 20 - 10);
            let ulps = 1 + (k % 7) as u32;
            let mut hi = lo;
            for _ in 0..ulps {
                hi = hi.next_up();
            }
            cases.push(Interval::new(lo, hi));
        }
        for i in cases {
            let (m, r) = mid_rad(i);
            let (pm, pr) = (Interval::point(m), Interval::point(r));
            assert!(
                (pm - pr).hi <= i.lo && (pm + pr).lo >= i.hi,
                "{i:?}: {m} {r}"
            );
            let half = 0.5 * (i.hi - i.lo);
            let slack = 8.0 * f64::EPSILON * (m.abs() + half) + 1e-320;
            assert!(r <= half * (1.0 + 1e-12) + slack, "{i:?}: radius {r}");
        }
    }
}
