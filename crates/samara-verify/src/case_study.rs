//! The case study's global properties P1-P4 as critical-value queries in normal form,
//! for a network with the case study's conventions: either raw units (inputs v_xp, v_yp,
//! omega, theta, x, y; output ex) or normalised units with the published constants
//! (`z = (x - C) / S`, `ex = 0.181 + 0.012 out`).
//!
//! Critical values (each one optimisation, no scan):
//! - P1 `y >= -x + ystar => ex >= 0.187` holds iff ystar > sup{x + y : ex < 0.187}.
//! - P2 `y <= -x - ystar => ex <= 0.187` holds iff ystar > sup{-(x + y) : ex > 0.187}.
//! - P3 `|x + y| <= ystar and -0.786 <= theta <= -0.747 => 0.184 <= ex <= 0.19` holds iff
//!   ystar < inf{|x + y| : theta in range, ex < 0.184 or ex > 0.19}.
//! - P4 `0 <= x + y <= ystar and omega <= -0.12 and v_yp <= -0.3 => ex <= 0.187` holds
//!   iff ystar < inf{x + y : x + y >= 0, omega <= -0.12, v_yp <= -0.3, ex > 0.187}.

use samara_spec::normal::{Application, Cmp, Constraint, Goal, LinExpr, Query, Sense, Var};

/// Units of the network's inputs and output.
#[derive(Clone, Debug)]
pub struct Units {
    /// Input offsets C (raw = C + S z); zeros and ones for raw networks.
    pub c: Vec<f64>,
    /// Input scales S.
    pub s: Vec<f64>,
    /// Output: ex = c_out + s_out * out.
    pub c_out: f64,
    /// Output scale.
    pub s_out: f64,
}

impl Units {
    /// Raw units.
    pub fn raw() -> Self {
        Units {
            c: vec![0.0; 6],
            s: vec![1.0; 6],
            c_out: 0.0,
            s_out: 1.0,
        }
    }

    /// Raw input `k` as a linear expression of the network input.
    fn input(&self, k: usize, coef: f64) -> LinExpr {
        LinExpr {
            terms: vec![(Var::Input { app: 0, index: k }, coef * self.s[k])],
            constant: coef * self.c[k],
        }
    }

    /// `ex - t` as a linear expression of the output.
    fn ex_minus(&self, t: f64) -> LinExpr {
        LinExpr {
            terms: vec![(Var::Output { app: 0, index: 0 }, self.s_out)],
            constant: self.c_out - t,
        }
    }
}

fn add(a: LinExpr, b: LinExpr) -> LinExpr {
    LinExpr {
        terms: a.terms.into_iter().chain(b.terms).collect(),
        constant: a.constant + b.constant,
    }
    .normalised()
}

fn neg(a: LinExpr) -> LinExpr {
    LinExpr {
        terms: a.terms.into_iter().map(|(v, c)| (v, -c)).collect(),
        constant: -a.constant,
    }
}

fn c(expr: LinExpr, cmp: Cmp) -> Constraint {
    Constraint { expr, cmp }
}

/// The four critical-value queries over the raw input box `[lo, hi]` (converted to the
/// network's units).
pub fn p1_to_p4(network: &str, u: &Units, lo: &[f64], hi: &[f64]) -> Vec<Query> {
    let input_box: Vec<(f64, f64)> = (0..6)
        .map(|k| ((lo[k] - u.c[k]) / u.s[k], (hi[k] - u.c[k]) / u.s[k]))
        .collect();
    let app = Application {
        network: network.into(),
        n_inputs: 6,
        n_outputs: 1,
        input_box,
    };
    let xy = add(u.input(4, 1.0), u.input(5, 1.0));
    let q = |name: &str, region: Vec<Vec<Constraint>>, objective: LinExpr, sense: Sense| Query {
        name: name.into(),
        applications: vec![app.clone()],
        free_vars: vec![],
        region,
        goal: Goal::Optimise {
            objective,
            sense,
            label: "ystar".into(),
        },
    };
    // Raw single-variable bounds as constraints on the input.
    let le_raw = |k: usize, t: f64| {
        c(
            add(
                u.input(k, 1.0),
                LinExpr {
                    terms: vec![],
                    constant: -t,
                },
            ),
            Cmp::Le,
        )
    };
    let ge_raw = |k: usize, t: f64| {
        c(
            add(
                u.input(k, -1.0),
                LinExpr {
                    terms: vec![],
                    constant: t,
                },
            ),
            Cmp::Le,
        )
    };
    vec![
        q(
            "p1",
            vec![vec![c(u.ex_minus(0.187), Cmp::Lt)]],
            xy.clone(),
            Sense::Max,
        ),
        q(
            "p2",
            vec![vec![c(neg(u.ex_minus(0.187)), Cmp::Lt)]],
            neg(xy.clone()),
            Sense::Max,
        ),
        {
            // |x + y| <= t with t free in [0, max |x + y| over the box]; minimise t.
            let t = LinExpr {
                terms: vec![(Var::Free(0), -1.0)],
                constant: 0.0,
            };
            let span = (lo[4] + lo[5]).abs().max((hi[4] + hi[5]).abs()) * 1.000001 + 1.0;
            let band = vec![
                c(add(xy.clone(), t.clone()), Cmp::Le),
                c(add(neg(xy.clone()), t), Cmp::Le),
            ];
            let theta = vec![ge_raw(3, -0.786), le_raw(3, -0.747)];
            let mut out_lo = band.clone();
            out_lo.extend(theta.clone());
            out_lo.push(c(u.ex_minus(0.184), Cmp::Lt));
            let mut out_hi = band;
            out_hi.extend(theta);
            out_hi.push(c(neg(u.ex_minus(0.19)), Cmp::Lt));
            let mut q3 = q(
                "p3",
                vec![out_lo, out_hi],
                LinExpr {
                    terms: vec![(Var::Free(0), 1.0)],
                    constant: 0.0,
                },
                Sense::Min,
            );
            q3.free_vars = vec![("t".into(), 0.0, span)];
            q3
        },
        q(
            "p4",
            vec![vec![
                c(neg(xy.clone()), Cmp::Le),
                le_raw(2, -0.12),
                le_raw(1, -0.3),
                c(neg(u.ex_minus(0.187)), Cmp::Lt),
            ]],
            xy,
            Sense::Min,
        ),
    ]
}
