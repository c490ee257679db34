//! Negation normal form of a property's counterexample region, its size checks, and
//! the disjunctive normal form.

use super::decl::PropertyDecl;
use super::linear::Lin;
use super::lowering::{Lowering, MAX_CASES, MAX_TERMS};
use crate::normal::Cmp;
use crate::syntax::{Expr, Formula, Pos, Rel, SpecError};

/// Negation normal form with atoms `(lhs, rel, rhs)`.
#[derive(Clone, Debug)]
pub(super) enum Nnf {
    Atom(Expr, Rel, Expr, Pos),
    And(Vec<Nnf>),
    Or(Vec<Nnf>),
}

pub(super) fn flip(r: Rel) -> Vec<Rel> {
    match r {
        Rel::Le => vec![Rel::Gt],
        Rel::Lt => vec![Rel::Ge],
        Rel::Ge => vec![Rel::Lt],
        Rel::Gt => vec![Rel::Le],
        Rel::Eq => vec![Rel::Lt, Rel::Gt],
    }
}

impl Lowering<'_> {
    /// `negate = true` gives the NNF of `not f`.
    pub(super) fn nnf(&mut self, f: &Formula, negate: bool) -> Result<Nnf, SpecError> {
        Ok(match f {
            Formula::Chain(es, rs, pos) => {
                let atoms: Vec<Nnf> = rs
                    .iter()
                    .enumerate()
                    .map(|(i, r)| {
                        if negate {
                            let v: Vec<Nnf> = flip(*r)
                                .into_iter()
                                .map(|fr| Nnf::Atom(es[i].clone(), fr, es[i + 1].clone(), *pos))
                                .collect();
                            if v.len() == 1 {
                                v.into_iter().next().expect("one")
                            } else {
                                Nnf::Or(v)
                            }
                        } else {
                            Nnf::Atom(es[i].clone(), *r, es[i + 1].clone(), *pos)
                        }
                    })
                    .collect();
                if atoms.len() == 1 {
                    atoms.into_iter().next().expect("one")
                } else if negate {
                    Nnf::Or(atoms)
                } else {
                    Nnf::And(atoms)
                }
            }
            Formula::Not(g) => self.nnf(g, !negate)?,
            Formula::And(v) => {
                let parts = v
                    .iter()
                    .map(|g| self.nnf(g, negate))
                    .collect::<Result<Vec<_>, _>>()?;
                if negate {
                    Nnf::Or(parts)
                } else {
                    Nnf::And(parts)
                }
            }
            Formula::Or(v) => {
                let parts = v
                    .iter()
                    .map(|g| self.nnf(g, negate))
                    .collect::<Result<Vec<_>, _>>()?;
                if negate {
                    Nnf::And(parts)
                } else {
                    Nnf::Or(parts)
                }
            }
            Formula::Implies(a, b) => {
                // a => b  ==  not a or b;  not (a => b) == a and not b.
                if negate {
                    Nnf::And(vec![self.nnf(a, false)?, self.nnf(b, true)?])
                } else {
                    Nnf::Or(vec![self.nnf(a, true)?, self.nnf(b, false)?])
                }
            }
        })
    }

    /// Refuse, before expanding anything, a property whose counterexample region would
    /// have more than [`MAX_CASES`] cases or more than [`MAX_TERMS`] terms in all.
    pub(super) fn check_size(&self, p: &PropertyDecl, f: &Nnf) -> Result<(), SpecError> {
        let cases = self.nnf_cases(f);
        let fmt = |n: u64| {
            if n == u64::MAX {
                "more than 10^19".to_string()
            } else {
                n.to_string()
            }
        };
        if cases > MAX_CASES {
            return Err(self.err(
                p.pos,
                format!(
                    "property `{}` expands to {} cases, more than the cap of {MAX_CASES}",
                    p.name,
                    fmt(cases)
                ),
                "each |e| doubles the cases, norm(p - q) multiplies them by twice the inputs, \
                 and `or` (`and` under `not`) adds them: split the property into smaller ones",
            ));
        }
        let terms = cases.saturating_mul(self.nnf_size(f).saturating_add(self.extra.len() as u64));
        if terms > MAX_TERMS {
            return Err(self.err(
                p.pos,
                format!(
                    "property `{}` expands to {} cases of up to {} terms each, more than the cap of {MAX_TERMS} terms",
                    p.name,
                    fmt(cases),
                    fmt(self.nnf_size(f))
                ),
                "split the property into smaller ones",
            ));
        }
        Ok(())
    }

    /// The number of cases `dnf` gives for `f` (saturating).
    pub(super) fn nnf_cases(&self, f: &Nnf) -> u64 {
        match f {
            Nnf::Atom(a, _, b, _) => self.expr_cases(a).saturating_mul(self.expr_cases(b)),
            Nnf::Or(v) => v
                .iter()
                .fold(0u64, |n, g| n.saturating_add(self.nnf_cases(g))),
            Nnf::And(v) => v
                .iter()
                .fold(1u64, |n, g| n.saturating_mul(self.nnf_cases(g).max(1))),
        }
    }

    /// The number of cases `expr` gives for `e` (saturating; an upper bound).
    pub(super) fn expr_cases(&self, e: &Expr) -> u64 {
        match e {
            Expr::Num(_) | Expr::Name(..) | Expr::Call(..) => 1,
            Expr::Sum(v) => v.iter().fold(1u64, |n, (_, t)| {
                n.saturating_mul(self.expr_cases(t).max(1))
            }),
            Expr::Prod(a, v) => v.iter().fold(self.expr_cases(a).max(1), |n, (_, t, _)| {
                n.saturating_mul(self.expr_cases(t).max(1))
            }),
            Expr::Neg(a) => self.expr_cases(a),
            Expr::Abs(a) => self.expr_cases(a).saturating_mul(2),
            Expr::Norm(..) => (self.max_inputs() as u64).saturating_mul(2),
        }
    }

    /// An upper bound of the terms one case of `f` holds.
    pub(super) fn nnf_size(&self, f: &Nnf) -> u64 {
        match f {
            Nnf::Atom(a, _, b, _) => self.expr_size(a).saturating_add(self.expr_size(b)),
            Nnf::Or(v) | Nnf::And(v) => v
                .iter()
                .fold(0u64, |n, g| n.saturating_add(self.nnf_size(g))),
        }
    }

    /// An upper bound of the terms of one case of `e`, its conditions included.
    pub(super) fn expr_size(&self, e: &Expr) -> u64 {
        match e {
            Expr::Num(_) | Expr::Name(..) | Expr::Call(..) => 1,
            Expr::Sum(v) => v
                .iter()
                .fold(0u64, |n, (_, t)| n.saturating_add(self.expr_size(t))),
            Expr::Prod(a, v) => v.iter().fold(self.expr_size(a), |n, (_, t, _)| {
                n.saturating_add(self.expr_size(t))
            }),
            Expr::Neg(a) => self.expr_size(a),
            Expr::Abs(a) => self.expr_size(a).saturating_mul(2),
            Expr::Norm(..) => (self.max_inputs() as u64).saturating_mul(10),
        }
    }

    pub(super) fn max_inputs(&self) -> usize {
        self.spec
            .networks
            .iter()
            .map(|n| n.inputs.len())
            .max()
            .unwrap_or(0)
    }

    pub(super) fn dnf(&mut self, f: &Nnf, pos: Pos) -> Result<Vec<Vec<(Lin, Cmp)>>, SpecError> {
        Ok(match f {
            Nnf::Atom(a, r, b, pos) => {
                let cases = self.combine(a, b, |x, y| x.sub(y))?;
                cases
                    .into_iter()
                    .map(|(mut conds, d)| {
                        // d r 0
                        let atoms: Vec<(Lin, Cmp)> = match r {
                            Rel::Le => vec![(d, Cmp::Le)],
                            Rel::Lt => vec![(d, Cmp::Lt)],
                            Rel::Ge => vec![(d.scale(-1.0), Cmp::Le)],
                            Rel::Gt => vec![(d.scale(-1.0), Cmp::Lt)],
                            Rel::Eq => vec![(d, Cmp::Eq)],
                        };
                        conds.extend(atoms);
                        let _ = pos;
                        conds
                    })
                    .collect()
            }
            Nnf::Or(v) => {
                let mut out = Vec::new();
                for g in v {
                    out.extend(self.dnf(g, pos)?);
                }
                out
            }
            Nnf::And(v) => {
                let mut acc: Vec<Vec<(Lin, Cmp)>> = vec![vec![]];
                for g in v {
                    let d = self.dnf(g, pos)?;
                    if acc.len().saturating_mul(d.len()) as u64 > MAX_CASES {
                        // Not reached: `check_size` counted the cases before expanding.
                        return Err(self.err(
                            pos,
                            format!("the property expands to more than {MAX_CASES} cases"),
                            "split it into smaller properties",
                        ));
                    }
                    let mut next = Vec::new();
                    for a in &acc {
                        for b in &d {
                            next.push(a.iter().chain(b).cloned().collect());
                        }
                    }
                    acc = next;
                }
                acc
            }
        })
    }
}
