//! Exact re-check of counterexamples in rational arithmetic. Every f64 is a rational
//! number, so a ReLU/clamp network's output at an f64 input is computed exactly with
//! big rationals, and the constraints are checked exactly (strict ones strictly). Used
//! for counterexamples within 1e-6 of a threshold, where f64 rounding could decide.

use crate::net::PwlNet;
use crate::point::Point;
use num_rational::BigRational;
use num_traits::{Signed, Zero};
use samara_spec::normal::{Cmp, Constraint, Var};

/// An f64 as the rational it is exactly (`None` for non-finite values).
pub(crate) fn q(v: f64) -> Option<BigRational> {
    BigRational::from_float(v)
}

/// Exact outputs of a piecewise-linear network at an f64 input (`None` for non-finite).
pub fn exact_outputs(net: &PwlNet, x: &[f64]) -> Option<Vec<BigRational>> {
    let mut a: Vec<BigRational> = x.iter().map(|v| q(*v)).collect::<Option<_>>()?;
    for (m, relu) in &net.maps {
        let mut z = Vec::with_capacity(m.out);
        for i in 0..m.out {
            let mut acc = q(m.b[i])?;
            for (j, w) in m.row(i).nonzeros() {
                acc += q(w)? * &a[j];
            }
            if *relu && acc.is_negative() {
                acc = BigRational::zero();
            }
            z.push(acc);
        }
        a = z;
    }
    Some(a)
}

/// Whether the point satisfies the constraints in exact arithmetic, its outputs
/// recomputed exactly (`None` if a value is not finite).
pub fn exact_satisfies(nets: &[&PwlNet], p: &Point, cs: &[Constraint]) -> Option<bool> {
    let outs: Vec<Vec<BigRational>> = nets
        .iter()
        .zip(&p.inputs)
        .map(|(n, x)| exact_outputs(n, x))
        .collect::<Option<_>>()?;
    for c in cs {
        let mut e = q(c.expr.constant)?;
        for (v, k) in &c.expr.terms {
            let val = match v {
                Var::Input { app, index } => q(p.inputs[*app][*index])?,
                Var::Output { app, index } => outs[*app][*index].clone(),
                Var::Free(k) => q(p.free[*k])?,
            };
            e += q(*k)? * val;
        }
        let ok = match c.cmp {
            Cmp::Le => !e.is_positive(),
            Cmp::Lt => e.is_negative(),
            Cmp::Eq => e.is_zero(),
        };
        if !ok {
            return Some(false);
        }
    }
    Some(true)
}

/// Whether the point satisfies the constraints, decided rigorously and fast when
/// possible: the outputs are enclosed by interval arithmetic that rounds only where an
/// operation was inexact ([`samara_bounds::constant`]), and a constraint that holds (or
/// fails) on the whole enclosure is decided; only when the enclosure leaves one undecided
/// are the outputs recomputed in exact rational arithmetic ([`exact_satisfies`], whose
/// cost grows with the bit length of every weight and is seconds on an MNIST-size
/// network). `None` if a value is not finite.
pub fn rigorous_satisfies(nets: &[&PwlNet], p: &Point, cs: &[Constraint]) -> Option<bool> {
    use samara_bounds::constant::{layer_intervals, Iv};
    let mut outs = Vec::with_capacity(nets.len());
    for (n, x) in nets.iter().zip(&p.inputs) {
        if x.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let (_, y) = layer_intervals(&n.maps, x, x);
        outs.push(y);
    }
    let mut all = true;
    for c in cs {
        let mut e = Iv::point(c.expr.constant);
        for (v, k) in &c.expr.terms {
            let t = match v {
                Var::Input { app, index } => Iv::point(*p.inputs.get(*app)?.get(*index)?),
                Var::Output { app, index } => *outs.get(*app)?.get(*index)?,
                Var::Free(f) => Iv::point(*p.free.get(*f)?),
            };
            e = e.plus(t.scale(*k));
        }
        if !(e.lo.is_finite() && e.hi.is_finite()) {
            all = false;
            continue;
        }
        let (holds, fails) = match c.cmp {
            Cmp::Lt => (e.hi < 0.0, e.lo >= 0.0),
            Cmp::Le => (e.hi <= 0.0, e.lo > 0.0),
            Cmp::Eq => (e.lo == 0.0 && e.hi == 0.0, e.lo > 0.0 || e.hi < 0.0),
        };
        if fails {
            return Some(false);
        }
        all &= holds;
    }
    if all {
        Some(true)
    } else {
        exact_satisfies(nets, p, cs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use samara_nn::{Affine, Layer, Network};
    use samara_spec::normal::LinExpr;

    #[test]
    fn exact_arithmetic_overrules_f64_at_the_rounding_level() {
        // y = 0.1 x + 0.2 at x = 1: f64 gives 0.30000000000000004, exactly it is
        // 0.3000000000000000166..., below the f64 number 0.30000000000000004.
        let net = Network {
            input_names: vec!["x".into()],
            output_names: vec!["y".into()],
            input_norm: None,
            layers: vec![Layer::Affine(Affine::new(1, 1, vec![0.1], vec![0.2]))],
            output_denorm: None,
        };
        let pwl = PwlNet::from_network(&net).unwrap();
        let y = net.eval_f64(&[1.0])[0];
        assert_eq!(y, 0.30000000000000004);
        let p = Point {
            inputs: vec![vec![1.0]],
            outputs: vec![vec![y]],
            free: vec![],
        };
        // y >= 0.30000000000000004, as `0.30000000000000004 - y <= 0`.
        let c = Constraint {
            expr: LinExpr {
                terms: vec![(Var::Output { app: 0, index: 0 }, -1.0)],
                constant: 0.30000000000000004,
            },
            cmp: Cmp::Le,
        };
        assert!(p.satisfies(std::slice::from_ref(&c)), "f64 says it holds");
        assert_eq!(
            exact_satisfies(&[&pwl], &p, &[c]),
            Some(false),
            "exactly it does not"
        );
        let c2 = Constraint {
            expr: LinExpr {
                terms: vec![(Var::Output { app: 0, index: 0 }, -1.0)],
                constant: 0.3,
            },
            cmp: Cmp::Lt,
        };
        assert_eq!(exact_satisfies(&[&pwl], &p, &[c2]), Some(true));
    }
}
