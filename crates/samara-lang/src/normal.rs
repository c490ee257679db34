//! The normal form a solver takes: a disjunction of conjunctions of linear constraints
//! over the inputs and outputs of one or more network applications (and optional free
//! scalar variables such as the parameter of a `critical` query).
//!
//! A property P holds iff its *counterexample region* (the normal form of `not P`
//! together with the input domain) is empty. A `critical` query asks for the supremum
//! (or infimum) of an objective over that region: e.g. the smallest `ystar` for which
//! P1 (`y >= -x + ystar => ex >= 0.187`) holds is `sup { x + y : ex < 0.187 }`.
//!
//! All coefficients speak in the units of the networks as they are applied (the
//! lowering composes any unit conversion into the coefficients).

use serde::{Deserialize, Serialize};

/// A variable of the normal form.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Var {
    /// Input `index` of application `app`.
    Input {
        /// Index into [`Query::applications`].
        app: usize,
        /// Input index of that network.
        index: usize,
    },
    /// Output `index` of application `app`.
    Output {
        /// Index into [`Query::applications`].
        app: usize,
        /// Output index of that network.
        index: usize,
    },
    /// A free scalar variable (index into [`Query::free_vars`]), e.g. a parameter being
    /// optimised by a `critical` query.
    Free(usize),
}

/// `sum coeff * var + constant`.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct LinExpr {
    /// The terms (a variable may appear once; use [`LinExpr::normalised`]).
    pub terms: Vec<(Var, f64)>,
    /// The constant term.
    pub constant: f64,
}

impl LinExpr {
    /// Merge repeated variables and drop zero coefficients; sort by variable.
    pub fn normalised(mut self) -> Self {
        self.terms.sort_by_key(|t| t.0);
        let mut out: Vec<(Var, f64)> = Vec::with_capacity(self.terms.len());
        for (v, c) in self.terms {
            match out.last_mut() {
                Some((lv, lc)) if *lv == v => *lc += c,
                _ => out.push((v, c)),
            }
        }
        out.retain(|(_, c)| *c != 0.0);
        LinExpr {
            terms: out,
            constant: self.constant,
        }
    }

    /// Evaluate given a value for every variable.
    pub fn eval(&self, value: impl Fn(Var) -> f64) -> f64 {
        self.terms.iter().map(|(v, c)| c * value(*v)).sum::<f64>() + self.constant
    }
}

/// Comparison of a [`LinExpr`] with zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Cmp {
    /// `expr <= 0`.
    Le,
    /// `expr < 0` (strict).
    Lt,
    /// `expr == 0`.
    Eq,
}

/// `expr cmp 0`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Constraint {
    /// Left-hand side.
    pub expr: LinExpr,
    /// Comparison with zero.
    pub cmp: Cmp,
}

impl Constraint {
    /// Whether the constraint holds at a point, up to `tol` (strict constraints need
    /// `expr < -0.0 + tol`, i.e. they are checked as `expr < tol`; pass 0 for exactness).
    pub fn holds(&self, value: impl Fn(Var) -> f64, tol: f64) -> bool {
        let e = self.expr.eval(value);
        match self.cmp {
            Cmp::Le => e <= tol,
            Cmp::Lt => e < tol,
            Cmp::Eq => e.abs() <= tol,
        }
    }
}

/// One call of a network inside a query: `outputs = network(inputs)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Application {
    /// The network's name in the spec (e.g. `f`).
    pub network: String,
    /// Number of inputs.
    pub n_inputs: usize,
    /// Number of outputs.
    pub n_outputs: usize,
    /// Box on this application's inputs, `(lo, hi)` per input (the input domain).
    pub input_box: Vec<(f64, f64)>,
}

/// Whether a critical query maximises or minimises.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Sense {
    /// Supremum.
    Max,
    /// Infimum.
    Min,
}

/// What is asked about the counterexample region.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Goal {
    /// Is the region empty? (Proved if empty, Violated with a point otherwise.)
    Prove,
    /// The supremum/infimum of `objective` over the region. For a parameter `p`
    /// lowered as a free variable, this is the critical value of `p`.
    Optimise {
        /// The objective.
        objective: LinExpr,
        /// Max or min.
        sense: Sense,
        /// Name of the parameter or expression (for reports).
        label: String,
    },
}

/// A query in normal form.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Query {
    /// Property name (e.g. `p1`), with a suffix for data-set instances (e.g. `p5[17]`).
    pub name: String,
    /// The network applications; variables refer to them by index.
    pub applications: Vec<Application>,
    /// Names of free variables and their bounds (may be infinite).
    pub free_vars: Vec<(String, f64, f64)>,
    /// The counterexample region: a disjunction of conjunctions.
    pub region: Vec<Vec<Constraint>>,
    /// What is asked.
    pub goal: Goal,
}
