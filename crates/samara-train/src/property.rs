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
//! The case study's P1..P4 come from its specification ([`case_study_spec`]) through
//! [`spec_properties`].

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

/// The case-study specification, `models/alsomitra/alsomitra.spec`, compiled in: the one
/// statement of P1-P5 that training, verification and the reproduction all lower.
pub const CASE_STUDY_SPEC: &str = include_str!("../../../models/alsomitra/alsomitra.spec");

/// [`CASE_STUDY_SPEC`] parsed and checked (its data paths resolve against the source
/// tree's `models/alsomitra`).
pub fn case_study_spec() -> samara_spec::Spec {
    let dir = std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/alsomitra"
    ));
    samara_spec::Spec::parse(CASE_STUDY_SPEC, "models/alsomitra/alsomitra.spec", dir)
        .expect("the compiled-in case-study spec parses")
}

/// The spec with its first network given other units and another raw-unit domain: the
/// properties stay as stated, the network they are lowered for changes. `in_norm` is
/// `(min, range)` per input (`raw = min + range z`), `None` for a network that takes raw
/// inputs; `out_norm` likewise per output (`raw = offset + scale out`).
pub fn with_units(
    spec: &samara_spec::Spec,
    in_norm: Option<(Vec<f64>, Vec<f64>)>,
    out_norm: Option<(Vec<f64>, Vec<f64>)>,
    domain: Option<Vec<(f64, f64)>>,
) -> samara_spec::Spec {
    let mut s = spec.clone();
    if let Some(n) = s.networks.first_mut() {
        n.in_norm = in_norm;
        n.out_norm = out_norm;
        if let Some(d) = domain {
            n.domain = d;
        }
    }
    s
}

/// Why a spec's properties cannot drive training.
#[derive(Debug, thiserror::Error)]
pub enum SpecPropertyError {
    /// The spec does not lower (unknown property, unbound parameter, ...).
    #[error("{0}")]
    Spec(#[from] samara_spec::SpecError),
    /// A lowered property is outside what the trainer handles.
    #[error(transparent)]
    Train(#[from] FromQueryError),
}

/// The spec's properties `names` for training a network in the min-max units `mm`
/// (inputs then the one output) over the raw box `domain` (`None`: the spec's own
/// domain): lowered by `samara_spec` directly in the trainer's units, then
/// [`from_query`].
pub fn spec_properties(
    spec: &samara_spec::Spec,
    names: &[String],
    b: &samara_spec::Bindings,
    mm: &crate::data::MinMax,
    domain: Option<Vec<(f64, f64)>>,
) -> Result<Vec<Property>, SpecPropertyError> {
    let n = spec.networks.first().map(|d| d.inputs.len()).unwrap_or(0);
    let spec = with_units(
        spec,
        Some((mm.min[..n].to_vec(), mm.range[..n].to_vec())),
        Some((mm.min[n..].to_vec(), mm.range[n..].to_vec())),
        domain,
    );
    let mut props = Vec::new();
    for name in names {
        for i in spec.lower_prove(name, b)? {
            props.extend(from_query(&i.query)?);
        }
    }
    Ok(props)
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
}

/// Why a normal-form query cannot drive property-driven training.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("property `{0}` cannot be used for training: {1}")]
pub struct FromQueryError(pub String, pub String);

/// Properties for DL2/Goedel training from a lowered `Prove` query of the property
/// language (network units). Each disjunct of the counterexample region becomes one
/// property (disjuncts with the same precondition become one, named after the query
/// when it is the only one): its input constraints are the precondition (single-input bounds plus at
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
        // Bands are written with their first non-zero coefficient positive, so one
        // precondition has one representation whichever way the spec states it.
        let positive = |a: &[f64]| a.iter().find(|x| **x != 0.0).is_some_and(|x| *x > 0.0);
        let band = match general.len() {
            0 => None,
            1 => {
                let (a, b) = &general[0];
                if positive(a) {
                    Some((a.clone(), f64::NEG_INFINITY, *b))
                } else {
                    Some((a.iter().map(|x| -x).collect(), -b, f64::INFINITY))
                }
            }
            2 => {
                let (a1, b1) = &general[0];
                let (a2, b2) = &general[1];
                if a1
                    .iter()
                    .zip(a2)
                    .all(|(x, y)| (x + y).abs() <= 1e-12 * (x.abs() + 1.0))
                {
                    if positive(a1) {
                        Some((a1.clone(), -b2, *b1))
                    } else {
                        Some((a2.clone(), -b1, *b2))
                    }
                } else {
                    return Err(err("more than one general input constraint"));
                }
            }
            _ => return Err(err("more than one general input constraint")),
        };
        if atoms.is_empty() {
            return Err(err("a disjunct without output constraints (the precondition alone is a counterexample)"));
        }
        let formula = if atoms.len() == 1 {
            atoms.pop().expect("one")
        } else {
            Formula::Or(atoms)
        };
        let region = Region { lo, hi, band };
        // Disjuncts over the same precondition (e.g. `ex < a or ex > b`) are one
        // property whose formula is the conjunction of their negations.
        match out.iter_mut().find(|p: &&mut Property| p.region == region) {
            Some(p) => match &mut p.formula {
                Formula::And(v) => v.push(formula),
                f => *f = Formula::And(vec![f.clone(), formula]),
            },
            None => out.push(Property {
                name: format!("{}#{d}", q.name),
                region,
                formula,
            }),
        }
    }
    if out.len() == 1 {
        out[0].name = q.name.clone();
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
