//! Linear programs for branch-and-bound nodes, solved by Clarabel (interior point), with
//! bounds made sound from the dual solution by weak duality:
//! for any multipliers `y` in the dual cone (free on equalities, `>= 0` on
//! inequalities) and any feasible `v` inside the box `[lo, hi]`,
//! `c.v = y.(A v) + r.v <= y.b + max_{v in box} r.v` with `r = c - A^T y`.
//! Every sum is evaluated with an a-priori floating-point error bound
//! (`|fl(sum) - sum| <= gamma_n sum |terms|`, Higham, *Accuracy and Stability of
//! Numerical Algorithms*, 2nd ed., section 3.1) and rounded outward, so the bound holds in
//! exact arithmetic whatever the solver's accuracy. Infeasibility is accepted only when
//! the same inequality with `c = 0` proves it (a Farkas certificate checked the same way).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus, ZeroConeT,
};
use samara_num::round::{gamma, up};

/// A sparse row `sum coef * var`.
pub type Row = Vec<(usize, f64)>;

/// `max c.v` s.t. `eq rows = rhs`, `le rows <= rhs`, `lo <= v <= hi` (finite).
#[derive(Clone, Debug, Default)]
pub struct Lp {
    /// Number of variables.
    pub n: usize,
    /// Equalities.
    pub eq: Vec<(Row, f64)>,
    /// Inequalities.
    pub le: Vec<(Row, f64)>,
    /// Variable lower bounds (finite).
    pub lo: Vec<f64>,
    /// Variable upper bounds (finite).
    pub hi: Vec<f64>,
    /// Objective (maximised).
    pub c: Vec<f64>,
}

/// Outcome of one LP.
#[derive(Clone, Debug)]
pub enum LpResult {
    /// Proved infeasible (certificate checked).
    Infeasible,
    /// A sound upper bound on the optimum and the solver's primal point.
    Bound {
        /// Sound upper bound of `max c.v`.
        upper: f64,
        /// Primal point (approximate optimiser).
        x: Vec<f64>,
    },
    /// The solver failed; only the box bound is known.
    Failed {
        /// Sound upper bound from the box alone.
        upper: f64,
    },
}

/// Upper bound on `sum terms` in exact arithmetic: the float sum plus twice `gamma` of
/// the term count times the sum of magnitudes (which is itself rounded).
fn sum_up(terms: &[f64]) -> f64 {
    let s: f64 = terms.iter().sum();
    let a: f64 = terms.iter().map(|t| t.abs()).sum();
    up(up(s) + up(2.0 * gamma(terms.len()) * a))
}

impl Lp {
    /// Sound box bound of `max c.v`.
    pub fn box_bound(&self) -> f64 {
        let t: Vec<f64> = (0..self.n)
            .map(|j| (self.c[j] * self.lo[j]).max(self.c[j] * self.hi[j]))
            .collect();
        sum_up(&t)
    }

    /// `y.b + max_box (c - A^T y).v`, soundly, for multipliers `y_eq` (free) and
    /// `y_le` (clipped at 0).
    fn dual_bound(&self, c: &[f64], y_eq: &[f64], y_le: &[f64]) -> f64 {
        // r = c - A^T y, with an error radius per component.
        let mut r = c.to_vec();
        let mut rad = vec![0.0f64; self.n];
        let mut yb = Vec::with_capacity(self.eq.len() + self.le.len());
        for ((row, rhs), &y) in self.eq.iter().zip(y_eq).chain(self.le.iter().zip(y_le)) {
            if y == 0.0 {
                continue;
            }
            yb.push(y * rhs);
            for &(j, a) in row {
                let p = y * a;
                r[j] -= p;
                // The product's and the difference's rounding: `gamma(0) = 2^-51`, four
                // unit roundoffs, on the larger magnitudes.
                rad[j] += gamma(0) * (p.abs() + r[j].abs());
            }
        }
        let mut terms = yb;
        for j in 0..self.n {
            let (rl, rh) = (r[j] - rad[j], r[j] + rad[j]);
            let m = (rl * self.lo[j])
                .max(rl * self.hi[j])
                .max(rh * self.lo[j])
                .max(rh * self.hi[j]);
            terms.push(up(m));
        }
        sum_up(&terms)
    }

    /// Solve with Clarabel and return a sound result.
    pub fn solve(&self) -> LpResult {
        let n = self.n;
        let (ne, nl) = (self.eq.len(), self.le.len());
        // Rows: equalities, inequalities, then the box (v <= hi, -v <= -lo).
        let m = ne + nl + 2 * n;
        let mut cols: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
        let mut b = Vec::with_capacity(m);
        for (i, (row, rhs)) in self.eq.iter().chain(self.le.iter()).enumerate() {
            for &(j, a) in row {
                cols[j].push((i, a));
            }
            b.push(*rhs);
        }
        for j in 0..n {
            cols[j].push((ne + nl + j, 1.0));
            cols[j].push((ne + nl + n + j, -1.0));
        }
        b.extend(self.hi.iter().copied());
        b.extend(self.lo.iter().map(|v| -v));
        let mut colptr = vec![0usize];
        let mut rowval = Vec::new();
        let mut nzval = Vec::new();
        for col in &mut cols {
            col.sort_by_key(|e| e.0);
            // Merge duplicates.
            let mut last: Option<usize> = None;
            for &(i, a) in col.iter() {
                if last == Some(i) {
                    *nzval.last_mut().expect("entry") += a;
                } else {
                    rowval.push(i);
                    nzval.push(a);
                    last = Some(i);
                }
            }
            colptr.push(rowval.len());
        }
        let a = CscMatrix::new(m, n, colptr, rowval, nzval);
        let p = CscMatrix::<f64>::zeros((n, n));
        let q: Vec<f64> = self.c.iter().map(|v| -v).collect();
        let mut cones = Vec::new();
        if ne > 0 {
            cones.push(ZeroConeT(ne));
        }
        cones.push(NonnegativeConeT(nl + 2 * n));
        let settings = match DefaultSettingsBuilder::default()
            .verbose(false)
            .max_iter(200)
            .build()
        {
            Ok(s) => s,
            Err(_) => {
                return LpResult::Failed {
                    upper: self.box_bound(),
                }
            }
        };
        let mut solver = match DefaultSolver::new(&p, &q, &a, &b, &cones, settings) {
            Ok(s) => s,
            Err(_) => {
                return LpResult::Failed {
                    upper: self.box_bound(),
                }
            }
        };
        solver.solve();
        let sol = &solver.solution;
        let z = &sol.z;
        let y_eq: Vec<f64> = z[..ne].to_vec();
        let y_le: Vec<f64> = z[ne..ne + nl].iter().map(|v| v.max(0.0)).collect();
        match sol.status {
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
                // Farkas: with c = 0 the dual bound must be negative.
                let zero = vec![0.0; n];
                if self.dual_bound(&zero, &y_eq, &y_le) < 0.0 {
                    LpResult::Infeasible
                } else {
                    LpResult::Failed {
                        upper: self.box_bound(),
                    }
                }
            }
            SolverStatus::Solved | SolverStatus::AlmostSolved => {
                let upper = self.dual_bound(&self.c, &y_eq, &y_le).min(self.box_bound());
                LpResult::Bound {
                    upper,
                    x: sol.x.clone(),
                }
            }
            _ => LpResult::Failed {
                upper: self.box_bound(),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_lp_bound_is_sound_and_tight() {
        // max x + y s.t. x + 2y <= 4, 3x + y <= 6, 0 <= x, y <= 10: optimum 2.8 at (1.6, 1.2).
        let lp = Lp {
            n: 2,
            eq: vec![],
            le: vec![
                (vec![(0, 1.0), (1, 2.0)], 4.0),
                (vec![(0, 3.0), (1, 1.0)], 6.0),
            ],
            lo: vec![0.0; 2],
            hi: vec![10.0; 2],
            c: vec![1.0, 1.0],
        };
        match lp.solve() {
            LpResult::Bound { upper, x } => {
                assert!((2.8..2.8 + 1e-6).contains(&upper), "{upper}");
                assert!((x[0] - 1.6).abs() < 1e-6 && (x[1] - 1.2).abs() < 1e-6);
            }
            r => panic!("{r:?}"),
        }
    }

    #[test]
    fn infeasible_lp_is_certified() {
        let lp = Lp {
            n: 1,
            eq: vec![],
            le: vec![(vec![(0, 1.0)], 1.0), (vec![(0, -1.0)], -2.0)],
            lo: vec![-5.0],
            hi: vec![5.0],
            c: vec![1.0],
        };
        assert!(matches!(lp.solve(), LpResult::Infeasible));
    }
}
