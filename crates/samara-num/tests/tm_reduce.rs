//! The re-parameterisation of Taylor-model sets at control instants
//! (`samara_num::tm_reduce::precondition`) must enclose the set it replaces: points of
//! the old set (a sampled parameter, a sampled point of the remainder) are found inside
//! the new parallelotope, by solving for its parameters independently in the test.

#![allow(clippy::needless_range_loop)] // Gaussian elimination reads clearest indexed

use rand::{Rng, SeedableRng};
use samara_num::tm_reduce::precondition;
use samara_num::{Interval, Scalar, Tm};

/// Solve `a z = b` (d x d) by Gaussian elimination with partial pivoting.
fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let d = b.len();
    for c in 0..d {
        let p = (c..d)
            .max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))
            .unwrap();
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..d {
            let f = a[r][c] / a[c][c];
            for k in c..d {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut z = vec![0.0; d];
    for c in (0..d).rev() {
        let s: f64 = (c + 1..d).map(|k| a[c][k] * z[k]).sum();
        z[c] = (b[c] - s) / a[c][c];
    }
    z
}

#[test]
fn the_new_parallelotope_contains_the_old_set() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let mut checked = 0;
    for case in 0..200 {
        let d = 2 + case % 3;
        let n = 1 + case % 3;
        let order = 3;
        // A nonlinear set in n parameters with remainders.
        let x: Vec<Tm> = (0..d)
            .map(|_| {
                let mut t = Tm::cst(rng.gen_range(-5.0..5.0));
                for k in 0..n {
                    let v = Tm::var(k, n, order);
                    t += v.clone() * rng.gen_range(-1.0..1.0);
                    t += v.sqr() * rng.gen_range(-0.2..0.2);
                    t += v.clone() * Tm::var((k + 1) % n, n, order) * rng.gen_range(-0.1..0.1);
                }
                let r = rng.gen_range(0.0..0.3);
                t.with_rem(Interval::new(-r, rng.gen_range(0.0..0.3)))
            })
            .collect();
        let y = precondition(&x, order);
        assert_eq!(y.len(), d);
        // The new models are affine in d parameters: y_i = c_i + a_i . zeta + rem_i.
        let lin: Vec<(f64, Vec<f64>)> = y
            .iter()
            .map(|t| {
                let (c, mut g) = t.linear_part();
                g.resize(d, 0.0);
                (c, g)
            })
            .collect();
        for _ in 0..200 {
            let xi: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..=1.0)).collect();
            // A point of the old set: inside the enclosure at xi (shrunk by a hair so
            // that eval_at's own outward rounding does not matter).
            let z: Vec<f64> = x
                .iter()
                .map(|t| {
                    let e = t.eval_at(&xi);
                    let w = e.hi - e.lo;
                    e.lo + 1e-9 * w + rng.gen_range(0.0..=1.0) * (1.0 - 2e-9) * w
                })
                .collect();
            // Parameters of the new set that reproduce the point's linear part.
            let a: Vec<Vec<f64>> = lin.iter().map(|(_, g)| g.clone()).collect();
            let b: Vec<f64> = z.iter().zip(&lin).map(|(zi, (c, _))| zi - c).collect();
            let zeta = solve(a, b);
            assert!(
                zeta.iter().all(|v| v.abs() <= 1.0 + 1e-7),
                "case {case}: parameters {zeta:?} outside [-1, 1]"
            );
            let zc: Vec<f64> = zeta.iter().map(|v| v.clamp(-1.0, 1.0)).collect();
            for (i, t) in y.iter().enumerate() {
                let e = t.eval_at(&zc);
                let tol = 1e-7 * (1.0 + z[i].abs());
                assert!(
                    e.lo - tol <= z[i] && z[i] <= e.hi + tol,
                    "case {case}: state {i}: {} not in {e:?}",
                    z[i]
                );
            }
            checked += 1;
        }
    }
    assert_eq!(checked, 40_000);
}

/// A skewed parallelotope with a small remainder (the shape a closed loop's set takes
/// after a period: its linear part far from orthogonal, though not degenerate) keeps
/// its interval hull to within 1 %: the parallelepiped frame (the linear part's own
/// columns) only wraps the remainder, where the orthonormal QR frame alone bounds a
/// rotated box (with the QR frame alone this test fails on its first set, 4.8 % wider
/// on average). Reference: the
/// exact hull of `c + G xi + [-r, r]`, `c +- (sum_k |G_ik| + r)`, computed in the test.
#[test]
fn a_skewed_parallelotope_keeps_its_hull() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let order = 4;
    for case in 0..200 {
        let d = 2 + case % 4;
        // G = I + 0.7 U with U uniform in [-1, 1]: slanted, rarely near-singular.
        let g: Vec<Vec<f64>> = (0..d)
            .map(|i| {
                (0..d)
                    .map(|k| 0.1 * (f64::from(u8::from(i == k)) + 0.7 * rng.gen_range(-1.0..1.0)))
                    .collect()
            })
            .collect();
        let r = 1e-5;
        let x: Vec<Tm> = (0..d)
            .map(|i| {
                Tm::affine(rng.gen_range(-2.0..2.0), &g[i], order).with_rem(Interval::new(-r, r))
            })
            .collect();
        let y = precondition(&x, order);
        let total: f64 = (0..d)
            .map(|i| {
                let exact = 2.0 * (g[i].iter().map(|v| v.abs()).sum::<f64>() + r);
                y[i].bound().width() / exact
            })
            .sum();
        assert!(
            total <= d as f64 * 1.01,
            "case {case}: the hull widths grew by {} on average",
            total / d as f64
        );
    }
}

/// Order reduction for symbolic remainders (`samara_num::tm_reduce::reduce`) must
/// enclose the set it replaces. The reduced models are `p_i(kept) + rad_i zeta_i + rem`
/// with one fresh parameter `zeta_i` per state, so a point `z` of the old set (at
/// parameter `xi`) is inside when it lies between the new models evaluated at the
/// point's kept coordinates with `zeta_i = -1` and `zeta_i = +1`; the kept coordinates
/// are found independently, by matching the new models' linear parts on the old ones.
#[test]
fn order_reduction_contains_the_old_set() {
    use samara_num::tm_reduce::reduce;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
    let mut checked = 0;
    let mut dropped_some = 0;
    for case in 0..200 {
        let d = 2 + case % 3;
        let n = 3 + case % 6;
        let order = 1 + (case % 3) as u32;
        let x: Vec<Tm> = (0..d)
            .map(|_| {
                let mut t = Tm::cst(rng.gen_range(-5.0..5.0));
                for k in 0..n {
                    let v = Tm::var(k, n, order);
                    // Parameters of very different weight, so the ranking matters.
                    let s = 10f64.powf(rng.gen_range(-3.0..0.0));
                    t += v.clone() * (s * rng.gen_range(-1.0..1.0));
                    t += v.sqr() * (0.2 * s * rng.gen_range(-1.0..1.0));
                    t += v.clone() * Tm::var((k + 1) % n, n, order) * rng.gen_range(-0.05..0.05);
                }
                let r = rng.gen_range(0.0..0.1);
                t.with_rem(Interval::new(-r, rng.gen_range(0.0..0.1)))
            })
            .collect();
        let max_params = d + 1 + case % 4;
        let y = reduce(&x, max_params, order);
        assert_eq!(y.len(), d);
        let total = y.iter().map(|v| v.n_vars()).max().unwrap();
        assert!(total <= max_params, "case {case}: {total} parameters");
        let keep = total - d;
        if keep < n {
            dropped_some += 1;
        }
        // Which old parameter each kept one is: the new linear coefficient of kept
        // parameter j equals the old one of exactly one old parameter in every state.
        let old_lin: Vec<Vec<f64>> = x.iter().map(|t| t.linear_part().1).collect();
        let new_lin: Vec<Vec<f64>> = y
            .iter()
            .map(|t| {
                let mut g = t.linear_part().1;
                g.resize(total, 0.0);
                g
            })
            .collect();
        let origin: Vec<usize> = (0..keep)
            .map(|j| {
                (0..n)
                    .find(|&k| (0..d).all(|i| old_lin[i][k] == new_lin[i][j]))
                    .unwrap_or_else(|| panic!("case {case}: kept parameter {j} has no origin"))
            })
            .collect();
        for _ in 0..200 {
            let xi: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..=1.0)).collect();
            let mut at = vec![0.0; total];
            for (j, &k) in origin.iter().enumerate() {
                at[j] = xi[k];
            }
            for (i, t) in x.iter().enumerate() {
                let e = t.eval_at(&xi);
                let w = e.hi - e.lo;
                let z = e.lo + 1e-9 * w + rng.gen_range(0.0..=1.0) * (1.0 - 2e-9) * w;
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for s in [-1.0, 1.0] {
                    at[keep + i] = s;
                    let f = y[i].eval_at(&at);
                    lo = lo.min(f.lo);
                    hi = hi.max(f.hi);
                }
                at[keep + i] = 0.0;
                assert!(
                    lo <= z && z <= hi,
                    "case {case}: state {i}: {z} not in [{lo}, {hi}]"
                );
                checked += 1;
            }
        }
    }
    assert!(
        dropped_some > 100,
        "only {dropped_some} cases dropped a parameter"
    );
    assert_eq!(checked, 119_800);
}
