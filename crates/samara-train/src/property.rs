//! Properties for property-driven training and their differentiable-logic losses.
//!
//! A property is `x in region => formula(f(x))` where the formula combines atoms
//! `coef * out + constant <= 0` on the (single) normalised output with and/or. Its
//! loss at a point follows one of two differentiable logics (Slusarz et al., "Logic of
//! Differentiable Logics", LPAR 2023):
//! - DL2 (Fischer et al., ICML 2019): atom `a <= b` -> `max(0, a - b)`, and = sum,
//!   or = product; loss 0 iff satisfied.
//! - Goedel: atom truth `1 - min(1, max(0, a - b))`, and = min, or = max; loss =
//!   1 - truth.
//!
//! [`case_study`] builds P1..P4 of the SAIV 2025 case study from raw-unit thresholds.

use crate::region::Region;

/// A formula over the network output.
#[derive(Clone, Debug, PartialEq)]
pub enum Formula {
    /// `coef * out + constant <= 0`.
    Atom {
        /// Coefficient of the output.
        coef: f64,
        /// Constant.
        constant: f64,
    },
    /// Conjunction.
    And(Vec<Formula>),
    /// Disjunction.
    Or(Vec<Formula>),
}

/// Which differentiable logic turns a formula into a loss.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Logic {
    /// DL2.
    Dl2,
    /// Goedel fuzzy logic.
    Goedel,
}

impl Formula {
    /// Whether the formula holds at output `o`.
    pub fn holds(&self, o: f64) -> bool {
        match self {
            Formula::Atom { coef, constant } => coef * o + constant <= 0.0,
            Formula::And(v) => v.iter().all(|f| f.holds(o)),
            Formula::Or(v) => v.iter().any(|f| f.holds(o)),
        }
    }

    /// DL2 loss and its derivative w.r.t. the output.
    fn dl2(&self, o: f64) -> (f64, f64) {
        match self {
            Formula::Atom { coef, constant } => {
                let v = coef * o + constant;
                if v > 0.0 {
                    (v, *coef)
                } else {
                    (0.0, 0.0)
                }
            }
            Formula::And(v) => v
                .iter()
                .map(|f| f.dl2(o))
                .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1)),
            Formula::Or(v) => {
                let parts: Vec<(f64, f64)> = v.iter().map(|f| f.dl2(o)).collect();
                let prod: f64 = parts.iter().map(|p| p.0).product();
                let mut d = 0.0;
                for i in 0..parts.len() {
                    let others: f64 = parts
                        .iter()
                        .enumerate()
                        .filter(|(j, _)| *j != i)
                        .map(|(_, p)| p.0)
                        .product();
                    d += parts[i].1 * others;
                }
                (prod, d)
            }
        }
    }

    /// Goedel truth and its derivative w.r.t. the output.
    fn goedel(&self, o: f64) -> (f64, f64) {
        match self {
            Formula::Atom { coef, constant } => {
                let v = coef * o + constant;
                if v <= 0.0 {
                    (1.0, 0.0)
                } else if v >= 1.0 {
                    (0.0, 0.0)
                } else {
                    (1.0 - v, -coef)
                }
            }
            Formula::And(v) => v
                .iter()
                .map(|f| f.goedel(o))
                .fold((f64::INFINITY, 0.0), |a, b| if b.0 < a.0 { b } else { a }),
            Formula::Or(v) => {
                v.iter()
                    .map(|f| f.goedel(o))
                    .fold(
                        (f64::NEG_INFINITY, 0.0),
                        |a, b| if b.0 > a.0 { b } else { a },
                    )
            }
        }
    }

    /// Loss (0 when satisfied) and its derivative w.r.t. the output under `logic`.
    pub fn loss(&self, logic: Logic, o: f64) -> (f64, f64) {
        match logic {
            Logic::Dl2 => self.dl2(o),
            Logic::Goedel => {
                let (t, d) = self.goedel(o);
                (1.0 - t, -d)
            }
        }
    }
}

/// A property: inputs in `region` imply `formula` on the output.
#[derive(Clone, Debug, PartialEq)]
pub struct Property {
    /// Name (e.g. `p1`).
    pub name: String,
    /// Precondition region (normalised input units).
    pub region: Region,
    /// Postcondition.
    pub formula: Formula,
}

/// The affine maps between raw and normalised units: `z = (x - c) / s` per input and
/// `ex = c_out + s_out * out`.
#[derive(Clone, Debug, PartialEq)]
pub struct Units {
    /// Input minimum.
    pub c: Vec<f64>,
    /// Input range.
    pub s: Vec<f64>,
    /// Output offset.
    pub c_out: f64,
    /// Output scale.
    pub s_out: f64,
}

impl Units {
    /// Atom `raw_ex <= t` as an atom on the normalised output.
    pub fn ex_le(&self, t: f64) -> Formula {
        Formula::Atom {
            coef: self.s_out,
            constant: self.c_out - t,
        }
    }

    /// Atom `raw_ex >= t` as an atom on the normalised output.
    pub fn ex_ge(&self, t: f64) -> Formula {
        Formula::Atom {
            coef: -self.s_out,
            constant: t - self.c_out,
        }
    }

    /// The raw band `lo <= a.x <= hi` in normalised inputs: `a.(c + s z) = (a s).z + a.c`.
    pub fn band(&self, a: &[f64], lo: f64, hi: f64) -> (Vec<f64>, f64, f64) {
        let ac: f64 = a.iter().zip(&self.c).map(|(x, y)| x * y).sum();
        (
            a.iter().zip(&self.s).map(|(x, y)| x * y).collect(),
            lo - ac,
            hi - ac,
        )
    }

    /// A raw box in normalised units.
    pub fn boxed(&self, lo: &[f64], hi: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let z = |v: &[f64]| {
            v.iter()
                .enumerate()
                .map(|(k, x)| (x - self.c[k]) / self.s[k])
                .collect::<Vec<_>>()
        };
        (z(lo), z(hi))
    }
}

/// P1..P4 of the case study over the raw input box `[lo, hi]` (inputs v_xp, v_yp,
/// omega, theta, x, y), with threshold `ystar`:
/// - P1: y >= -x + ystar => ex >= 0.187
/// - P2: y <= -x - ystar => ex <= 0.187
/// - P3: -x - ystar <= y <= -x + ystar and -0.786 <= theta <= -0.747 => 0.184 <= ex <= 0.19
/// - P4: -x <= y <= -x + ystar and omega <= -0.12 and v_yp <= -0.3 => ex <= 0.187
pub fn case_study(u: &Units, lo: &[f64], hi: &[f64], ystar: f64) -> Vec<Property> {
    let xy = [0.0, 0.0, 0.0, 0.0, 1.0, 1.0];
    let mk = |name: &str, blo: Vec<f64>, bhi: Vec<f64>, band: (f64, f64), formula: Formula| {
        let (zl, zh) = u.boxed(&blo, &bhi);
        Property {
            name: name.into(),
            region: Region {
                lo: zl,
                hi: zh,
                band: Some(u.band(&xy, band.0, band.1)),
            },
            formula,
        }
    };
    let mut p3lo = lo.to_vec();
    let mut p3hi = hi.to_vec();
    p3lo[3] = p3lo[3].max(-0.786);
    p3hi[3] = p3hi[3].min(-0.747);
    let mut p4hi = hi.to_vec();
    p4hi[2] = p4hi[2].min(-0.12);
    p4hi[1] = p4hi[1].min(-0.3);
    vec![
        mk(
            "p1",
            lo.to_vec(),
            hi.to_vec(),
            (ystar, f64::INFINITY),
            u.ex_ge(0.187),
        ),
        mk(
            "p2",
            lo.to_vec(),
            hi.to_vec(),
            (f64::NEG_INFINITY, -ystar),
            u.ex_le(0.187),
        ),
        mk(
            "p3",
            p3lo,
            p3hi,
            (-ystar, ystar),
            Formula::And(vec![u.ex_ge(0.184), u.ex_le(0.19)]),
        ),
        mk("p4", lo.to_vec(), p4hi, (0.0, ystar), u.ex_le(0.187)),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn losses_vanish_exactly_when_satisfied_and_derivatives_match() {
        let f = Formula::Or(vec![
            Formula::And(vec![
                Formula::Atom {
                    coef: 1.0,
                    constant: -0.5,
                },
                Formula::Atom {
                    coef: -2.0,
                    constant: 0.2,
                },
            ]),
            Formula::Atom {
                coef: -1.0,
                constant: 0.9,
            },
        ]);
        for logic in [Logic::Dl2, Logic::Goedel] {
            for k in 0..200 {
                let o = -0.5 + k as f64 * 0.01 + 0.003;
                let (l, d) = f.loss(logic, o);
                assert_eq!(l == 0.0, f.holds(o), "{logic:?} at {o}");
                let h = 1e-7;
                let fd = (f.loss(logic, o + h).0 - f.loss(logic, o - h).0) / (2.0 * h);
                assert!((fd - d).abs() < 1e-5, "{logic:?} at {o}: {fd} vs {d}");
            }
        }
    }

    #[test]
    fn raw_atoms_map_to_normalised_units() {
        let u = Units {
            c: vec![0.0; 6],
            s: vec![1.0; 6],
            c_out: 0.181,
            s_out: 0.012,
        };
        // out = 0.5 -> ex = 0.187 (up to rounding): the boundary of both atoms.
        assert!(u.ex_ge(0.187).holds(0.5 + 1e-12) && u.ex_le(0.187).holds(0.5 - 1e-12));
        assert!(!u.ex_ge(0.187).holds(0.49) && !u.ex_le(0.187).holds(0.51));
    }
}

/// Why a normal-form query cannot drive property-driven training.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("property `{0}` cannot be used for training: {1}")]
pub struct FromQueryError(pub String, pub String);

/// Properties for DL2/Goedel training from a lowered `Prove` query of the property
/// language (network units). Each disjunct of the counterexample region becomes one
/// property: its input constraints are the precondition (single-input bounds plus at
/// most one general linear constraint, or two with opposite normals forming a band),
/// its output atoms `a_i(out) <= 0` (or `< 0`) are what a counterexample satisfies, so
/// the property asks for `or_i a_i(out) > 0`, written as the atoms `-a_i <= 0`.
pub fn from_query(q: &samara_spec::normal::Query) -> Result<Vec<Property>, FromQueryError> {
    use samara_spec::normal::{Cmp, Goal, Var};
    let err = |m: &str| FromQueryError(q.name.clone(), m.into());
    if q.applications.len() != 1 || !q.free_vars.is_empty() || q.goal != Goal::Prove {
        return Err(err(
            "only single-network properties with every parameter bound can be trained",
        ));
    }
    let app = &q.applications[0];
    if app.n_outputs != 1 {
        return Err(err("the trainer handles single-output networks"));
    }
    let mut out = Vec::new();
    for (d, conj) in q.region.iter().enumerate() {
        let mut lo: Vec<f64> = app.input_box.iter().map(|b| b.0).collect();
        let mut hi: Vec<f64> = app.input_box.iter().map(|b| b.1).collect();
        let mut general: Vec<(Vec<f64>, f64)> = Vec::new(); // a.x <= b
        let mut atoms = Vec::new();
        for c in conj {
            let has_out = c
                .expr
                .terms
                .iter()
                .any(|(v, _)| matches!(v, Var::Output { .. }));
            let has_in = c
                .expr
                .terms
                .iter()
                .any(|(v, _)| matches!(v, Var::Input { .. }));
            if c.cmp == Cmp::Eq {
                return Err(err("equality constraints are not supported"));
            }
            match (has_in, has_out) {
                (_, false) => {
                    let mut a = vec![0.0; app.n_inputs];
                    for (v, k) in &c.expr.terms {
                        if let Var::Input { index, .. } = v {
                            a[*index] += k;
                        }
                    }
                    let b = -c.expr.constant;
                    let nz: Vec<usize> = (0..a.len()).filter(|k| a[*k] != 0.0).collect();
                    if nz.len() == 1 {
                        let k = nz[0];
                        if a[k] > 0.0 {
                            hi[k] = hi[k].min(b / a[k]);
                        } else {
                            lo[k] = lo[k].max(b / a[k]);
                        }
                    } else if !nz.is_empty() {
                        general.push((a, b));
                    }
                }
                (false, true) => {
                    let coef: f64 = c.expr.terms.iter().map(|(_, k)| k).sum();
                    // Counterexample atom coef*out + c <= 0; the property wants its negation.
                    atoms.push(Formula::Atom {
                        coef: -coef,
                        constant: -c.expr.constant,
                    });
                }
                (true, true) => {
                    return Err(err(
                        "constraints mixing inputs and outputs are not supported",
                    ))
                }
            }
        }
        let band = match general.len() {
            0 => None,
            1 => Some((general[0].0.clone(), f64::NEG_INFINITY, general[0].1)),
            2 => {
                let (a1, b1) = &general[0];
                let (a2, b2) = &general[1];
                if a1
                    .iter()
                    .zip(a2)
                    .all(|(x, y)| (x + y).abs() <= 1e-12 * (x.abs() + 1.0))
                {
                    Some((a1.clone(), -b2, *b1))
                } else {
                    return Err(err("more than one general input constraint"));
                }
            }
            _ => return Err(err("more than one general input constraint")),
        };
        if atoms.is_empty() {
            return Err(err("a disjunct without output constraints (the precondition alone is a counterexample)"));
        }
        out.push(Property {
            name: format!("{}#{d}", q.name),
            region: Region { lo, hi, band },
            formula: if atoms.len() == 1 {
                atoms.pop().expect("one")
            } else {
                Formula::Or(atoms)
            },
        });
    }
    Ok(out)
}

/// Re-express a query's network variables in new units: `old = a * new + b` per input
/// (`inputs[k] = (a, b)`) and per output (`outputs[k]`). Used to move a property stated
/// for a network with one normalisation onto a network trained with another.
pub fn rescale_query(
    q: &samara_spec::normal::Query,
    inputs: &[(f64, f64)],
    outputs: &[(f64, f64)],
) -> samara_spec::normal::Query {
    use samara_spec::normal::Var;
    let mut q = q.clone();
    for app in &mut q.applications {
        for (k, b) in app.input_box.iter_mut().enumerate() {
            let (a, c) = inputs[k];
            let (x, y) = ((b.0 - c) / a, (b.1 - c) / a);
            *b = (x.min(y), x.max(y));
        }
    }
    for conj in &mut q.region {
        for c in conj.iter_mut() {
            let mut extra = 0.0;
            for (v, k) in c.expr.terms.iter_mut() {
                let (a, b) = match v {
                    Var::Input { index, .. } => inputs[*index],
                    Var::Output { index, .. } => outputs[*index],
                    Var::Free(_) => (1.0, 0.0),
                };
                extra += *k * b;
                *k *= a;
            }
            c.expr.constant += extra;
        }
    }
    q
}
