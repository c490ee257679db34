//! Regions for attacks and property-driven training: a box intersected with at most one
//! linear band `lo <= a.x <= hi` (a half-space when one side is infinite), and the exact
//! Euclidean projection onto it.
//!
//! Projection onto box ∩ {a.x <= b}: by the KKT conditions the solution is
//! `x(λ) = clip(p - λ a, lo, hi)` for the smallest `λ >= 0` with `a.x(λ) <= b`; `a.x(λ)`
//! is continuous and non-increasing in λ, so λ is found by bisection (the classical
//! approach for a single linear constraint plus bounds, e.g. Helgason, Kennington & Lall
//! 1980, or Kiwiel 2008 "Breakpoint searching algorithms for the continuous quadratic
//! knapsack problem"). A band reduces to the half-space on the violated side.

/// A box with an optional band constraint, in the network's (normalised) input units.
#[derive(Clone, Debug, PartialEq)]
pub struct Region {
    /// Lower corner.
    pub lo: Vec<f64>,
    /// Upper corner.
    pub hi: Vec<f64>,
    /// Optional band `(a, lo, hi)`: `lo <= a.x <= hi` (either bound may be infinite).
    pub band: Option<(Vec<f64>, f64, f64)>,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl Region {
    /// A plain box.
    pub fn boxed(lo: Vec<f64>, hi: Vec<f64>) -> Self {
        Region { lo, hi, band: None }
    }

    /// Whether `x` is in the region up to `tol`.
    pub fn contains(&self, x: &[f64], tol: f64) -> bool {
        let in_box = x
            .iter()
            .zip(self.lo.iter().zip(&self.hi))
            .all(|(v, (l, h))| *v >= l - tol && *v <= h + tol);
        in_box
            && match &self.band {
                None => true,
                Some((a, l, h)) => {
                    let s = dot(a, x);
                    s >= l - tol && s <= h + tol
                }
            }
    }

    /// Whether the region is (numerically) non-empty: the band meets the box.
    pub fn is_nonempty(&self) -> bool {
        if self.lo.iter().zip(&self.hi).any(|(l, h)| l > h) {
            return false;
        }
        match &self.band {
            None => true,
            Some((a, l, h)) => {
                let (mut smin, mut smax) = (0.0, 0.0);
                for (k, ak) in a.iter().enumerate() {
                    let (p, q) = (ak * self.lo[k], ak * self.hi[k]);
                    smin += p.min(q);
                    smax += p.max(q);
                }
                smax >= *l && smin <= *h
            }
        }
    }

    /// The Euclidean projection of `p` (exact up to the bisection tolerance, 1e-13
    /// relative in λ). `None` if the region is empty.
    pub fn project(&self, p: &[f64]) -> Option<Vec<f64>> {
        if !self.is_nonempty() {
            return None;
        }
        let clip = |lam: f64, a: &[f64]| -> Vec<f64> {
            p.iter()
                .enumerate()
                .map(|(k, v)| (v - lam * a[k]).clamp(self.lo[k], self.hi[k]))
                .collect()
        };
        let zero = vec![0.0; p.len()];
        let x0 = clip(0.0, &zero);
        let Some((a, l, h)) = &self.band else {
            return Some(x0);
        };
        let s = dot(a, &x0);
        // Reduce to a.x <= b with sign sg (a -> sg a).
        let (sg, b) = if s > *h {
            (1.0, *h)
        } else if s < *l {
            (-1.0, -*l)
        } else {
            return Some(x0);
        };
        let av: Vec<f64> = a.iter().map(|v| sg * v).collect();
        let g = |lam: f64| dot(&av, &clip(lam, &av)) - b;
        let (mut lo_l, mut hi_l) = (0.0f64, 1.0f64);
        let mut guard = 0;
        while g(hi_l) > 0.0 && guard < 200 {
            hi_l *= 2.0;
            guard += 1;
        }
        for _ in 0..200 {
            let mid = 0.5 * (lo_l + hi_l);
            if g(mid) > 0.0 {
                lo_l = mid;
            } else {
                hi_l = mid;
            }
            if hi_l - lo_l <= 1e-13 * hi_l.max(1e-300) {
                break;
            }
        }
        Some(clip(hi_l, &av))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Brute force: the closest of many feasible points, refined by coordinate search.
    fn brute(r: &Region, p: &[f64]) -> f64 {
        let mut best = f64::INFINITY;
        let n = p.len();
        let steps = 40;
        let mut idx = vec![0usize; n];
        loop {
            let x: Vec<f64> = (0..n)
                .map(|k| r.lo[k] + (r.hi[k] - r.lo[k]) * idx[k] as f64 / steps as f64)
                .collect();
            if r.contains(&x, 0.0) {
                let d: f64 = x.iter().zip(p).map(|(a, b)| (a - b).powi(2)).sum();
                best = best.min(d);
            }
            let mut k = 0;
            loop {
                if k == n {
                    return best.sqrt();
                }
                idx[k] += 1;
                if idx[k] <= steps {
                    break;
                }
                idx[k] = 0;
                k += 1;
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(60))]
        #[test]
        fn projection_is_feasible_and_no_farther_than_brute_force(
            p in proptest::collection::vec(-1.0f64..2.0, 3),
            a in proptest::collection::vec(-1.0f64..1.0, 3),
            l in -1.0f64..1.0, w in 0.0f64..1.0,
        ) {
            let r = Region { lo: vec![0.0; 3], hi: vec![1.0; 3], band: Some((a.clone(), l, l + w)) };
            match r.project(&p) {
                None => prop_assert!(!r.is_nonempty()),
                Some(x) => {
                    prop_assert!(r.contains(&x, 1e-9));
                    let d: f64 = x.iter().zip(&p).map(|(u, v)| (u - v).powi(2)).sum::<f64>().sqrt();
                    // The grid's best point is feasible, so the exact projection is at least as close.
                    prop_assert!(d <= brute(&r, &p) + 1e-9, "projection {d} farther than a grid point");
                    // KKT check: moving along any feasible direction does not decrease distance.
                    let grad: Vec<f64> = x.iter().zip(&p).map(|(u, v)| u - v).collect();
                    for k in 0..3 {
                        for s in [-1e-4, 1e-4] {
                            let mut y = x.clone();
                            y[k] += s;
                            if r.contains(&y, 0.0) {
                                let dd: f64 = y.iter().zip(&p).map(|(u, v)| (u - v).powi(2)).sum::<f64>().sqrt();
                                prop_assert!(dd >= d - 1e-9, "direction {k} {s} improves: {grad:?}");
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn halfspace_projection_matches_closed_form_when_box_is_inactive() {
        // Box large enough: projection onto x + y <= 1 of (2, 2) is (0.5, 0.5).
        let r = Region {
            lo: vec![-10.0; 2],
            hi: vec![10.0; 2],
            band: Some((vec![1.0, 1.0], f64::NEG_INFINITY, 1.0)),
        };
        let x = r.project(&[2.0, 2.0]).unwrap();
        assert!((x[0] - 0.5).abs() < 1e-12 && (x[1] - 0.5).abs() < 1e-12);
        // Clamping the box alone would return (2, 2), violating the constraint.
        let empty = Region {
            lo: vec![0.0; 2],
            hi: vec![1.0; 2],
            band: Some((vec![1.0, 1.0], 3.0, 4.0)),
        };
        assert!(empty.project(&[0.5, 0.5]).is_none());
    }
}
