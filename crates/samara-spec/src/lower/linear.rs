//! Linear expressions over network inputs, outputs and free variables during lowering,
//! and piecewise-linear values as cases.

use crate::normal::Cmp;

/// A symbol of a linear expression during lowering.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(super) enum Sym {
    In(usize, usize),
    Out(usize, usize),
    Free(usize),
}

#[derive(Clone, Debug, PartialEq, Default)]
pub(super) struct Lin {
    pub(super) terms: Vec<(Sym, f64)>,
    pub(super) c: f64,
}

impl Lin {
    pub(super) fn constant(c: f64) -> Self {
        Lin { terms: vec![], c }
    }
    pub(super) fn sym(s: Sym, a: f64, c: f64) -> Self {
        Lin {
            terms: vec![(s, a)],
            c,
        }
    }
    pub(super) fn is_const(&self) -> bool {
        self.terms.iter().all(|t| t.1 == 0.0)
    }
    pub(super) fn scale(mut self, k: f64) -> Self {
        self.terms.iter_mut().for_each(|t| t.1 *= k);
        self.c *= k;
        self
    }
    pub(super) fn sub(self, o: &Lin) -> Self {
        self.add_scaled(o, -1.0)
    }
    pub(super) fn add_scaled(mut self, o: &Lin, k: f64) -> Self {
        self.terms.extend(o.terms.iter().map(|&(s, a)| (s, k * a)));
        self.c += k * o.c;
        self
    }
}

/// A piecewise-linear value: cases (conditions, value); the conditions of the cases
/// cover every point.
pub(super) type Cases = Vec<(Vec<(Lin, Cmp)>, Lin)>;

/// All pairs of cases of `a` and `b`, values combined by `f` (without copying `a`'s value
/// when `b` has a single case, so a long flat sum costs linear time).
pub(super) fn product(a: Cases, b: &Cases, f: impl Fn(Lin, &Lin) -> Lin) -> Cases {
    let mut out = Vec::with_capacity(a.len() * b.len());
    for (c1, v1) in a {
        if let [(c2, v2)] = b.as_slice() {
            let mut c = c1;
            c.extend(c2.iter().cloned());
            out.push((c, f(v1, v2)));
            continue;
        }
        for (c2, v2) in b {
            out.push((c1.iter().chain(c2).cloned().collect(), f(v1.clone(), v2)));
        }
    }
    out
}
