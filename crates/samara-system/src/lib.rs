//! The samara system language (docs/system.md): a plant, its controller interface,
//! initial set, horizon and goal in one text file, checked and compiled once into an
//! expression [`Graph`] that is evaluated generically over [`Scalar`], so `f64`,
//! [`samara_num::Dual`], [`samara_num::Interval`], [`samara_num::IDual`] and
//! [`samara_num::Series`] all run the same equations.
//!
//! ```
//! let src = "state x, v\ninput u\nx' = v\nv' = -sin(x) + u\nperiod 0.1\nhorizon 1\n\
//!            actuate u = net[0] clip [-1, 1]\ninit x in [0, 0.1]\ninit v = 0\n\
//!            goal reach x in [-0.5, 0.5] at end\n";
//! let sys = samara_system::System::parse(src, "pendulum.sys").unwrap();
//! let mut dx = [0.0; 2];
//! sys.rhs(&[0.5, 1.0], &[0.25], &mut dx);
//! assert_eq!(dx, [1.0, -(0.5f64.sin()) + 0.25]);
//! ```
#![warn(missing_docs)]

mod compile;
mod error;
mod graph;
mod lex;
mod parse;
pub mod plate;
pub mod sim;
pub mod taylor;

pub use error::{Pos, SystemError};
pub use graph::{Affine, Bin2, Cond, Graph, Op, StandIn, Un};
pub use lex::MAX_SOURCE_BYTES;
pub use parse::MAX_NESTING;

use samara_num::{Dual, Interval, Scalar};

/// A plant's continuous dynamics `x' = f(x, u)` over any [`Scalar`]: samara-sim's one
/// trait (the built-in plant and a [`System`] implement it), re-exported here where it
/// was first defined.
pub use samara_sim::Dynamics;

/// When a goal is checked.
#[derive(Clone, Debug, PartialEq)]
pub enum When {
    /// At the horizon.
    End,
    /// At every time of `[t1, t2]`.
    Always(f64, f64),
    /// At some time of `[t1, t2]`.
    Eventually(f64, f64),
}

/// What a goal asks of the state at a checked time.
#[derive(Clone, Debug, PartialEq)]
pub enum GoalKind {
    /// Inside the box (one interval per state; unconstrained states are `(-inf, inf)`).
    Reach(Vec<(f64, f64)>),
    /// Not inside the box.
    Avoid(Vec<(f64, f64)>),
    /// `lo <= g(x) <= hi` (an end may be infinite); `linear` is `(a, b)` with
    /// `g(x) = a.x + b` when `g` is affine.
    Band {
        /// The expression `g` over the states (one output).
        graph: Graph,
        /// Lower bound (may be `-inf`).
        lo: f64,
        /// Upper bound (may be `inf`).
        hi: f64,
        /// The affine form of `g`, if it is affine.
        linear: Option<(Vec<f64>, f64)>,
    },
}

/// A goal: what, when, and its source text.
#[derive(Clone, Debug, PartialEq)]
pub struct Goal {
    /// The predicate.
    pub kind: GoalKind,
    /// When it is checked.
    pub when: When,
    /// The goal line of the file (for reports).
    pub text: String,
    /// Where it is in the file.
    pub pos: Pos,
}

impl Goal {
    /// Whether the predicate holds at one state.
    pub fn holds(&self, x: &[f64]) -> bool {
        let inside = |b: &[(f64, f64)]| x.iter().zip(b).all(|(v, (l, h))| l <= v && v <= h);
        match &self.kind {
            GoalKind::Reach(b) => inside(b),
            GoalKind::Avoid(b) => !inside(b),
            GoalKind::Band { graph, lo, hi, .. } => {
                let mut o = [0.0];
                graph.eval(x, &[], &mut o);
                *lo <= o[0] && o[0] <= *hi
            }
        }
    }

    /// Whether the predicate holds on a whole box of states: `Some(true)` at every
    /// point, `Some(false)` at no point, `None` undecided (sound, by intervals).
    pub fn decide(&self, x: &[Interval]) -> Option<bool> {
        let boxed = |b: &[(f64, f64)]| -> Option<bool> {
            if x.iter().zip(b).all(|(v, (l, h))| *l <= v.lo && v.hi <= *h) {
                Some(true)
            } else if x.iter().zip(b).any(|(v, (l, h))| v.hi < *l || v.lo > *h) {
                Some(false)
            } else {
                None
            }
        };
        match &self.kind {
            GoalKind::Reach(b) => boxed(b),
            GoalKind::Avoid(b) => boxed(b).map(|v| !v),
            GoalKind::Band { graph, lo, hi, .. } => {
                let mut o = [Interval::point(0.0)];
                graph.eval(x, &[], &mut o);
                band_decision(o[0], *lo, *hi)
            }
        }
    }
}

/// A band `lo <= g <= hi` decided on an enclosure `r` of `g` over a set: `Some(true)`
/// when `r` lies inside, `Some(false)` when it misses the band, `None` when it
/// straddles an end or has a NaN end. Shared by every set representation that bounds a
/// band's expression (intervals here, Taylor models in `samara-reach`).
pub fn band_decision(r: Interval, lo: f64, hi: f64) -> Option<bool> {
    if r.lo.is_nan() || r.hi.is_nan() {
        None
    } else if lo <= r.lo && r.hi <= hi {
        Some(true)
    } else if r.hi < lo || r.lo > hi {
        Some(false)
    } else {
        None
    }
}

/// An `if` of the equations: where it is in the file. Its condition is the matching
/// output of [`System::switch_conditions`].
#[derive(Clone, Debug, PartialEq)]
pub struct Switch {
    /// Place of the `if` in the file.
    pub pos: Pos,
    /// Its source line, trimmed.
    pub text: String,
}

/// A finite discrete state (`mode NAME in [V1, V2, ...]`) of a discrete-time system:
/// its new value at every step is the index of the largest output of the network
/// (`next NAME = argmax(net)`; ties go to the lowest index), and it may choose the
/// network (`networks by NAME`) and the inputs' values (`actuate u = ... when NAME =
/// V`). See docs/system.md, "Discrete-time systems".
#[derive(Clone, Debug, PartialEq)]
pub struct ModeVar {
    /// The mode's name.
    pub name: String,
    /// Its values, in order (value `k` is chosen when output `k` is the largest).
    pub values: Vec<String>,
    /// The index of its initial value (`init NAME = V`).
    pub init: usize,
    /// Whether the network is chosen by the mode's current value (`networks by NAME`):
    /// one network per value, in the order of `values`.
    pub networks_by: bool,
    /// The inputs set by a per-value table, with, per mode value, the values the input
    /// may take (the first, middle or all of them: a setting of the analysis).
    pub tables: Vec<InputTable>,
}

/// The values one input may take under each mode value (`actuate u = a, b, c when
/// MODE = V`, one line per value).
#[derive(Clone, Debug, PartialEq)]
pub struct InputTable {
    /// Index of the input.
    pub input: usize,
    /// Per mode value (in the mode's order), the listed values, in file order.
    pub values: Vec<Vec<f64>>,
}

/// The discrete-time part of a system written with `next` updates instead of
/// derivatives (docs/system.md, "Discrete-time systems").
#[derive(Clone, Debug, PartialEq)]
pub struct Discrete {
    /// `x_{k+1} = next(x_k, u_k)`: one output per state, over the states and inputs.
    pub next: Graph,
    /// The finite discrete state, if any.
    pub mode: Option<ModeVar>,
}

/// A checked, compiled system file.
#[derive(Clone, Debug, PartialEq)]
pub struct System {
    /// The `system` name (empty if none).
    pub name: String,
    /// The file name given to the parser.
    pub file: String,
    /// State names, in order.
    pub states: Vec<String>,
    /// Input names, in order.
    pub inputs: Vec<String>,
    /// Parameters and their values (after overrides), in file order.
    pub params: Vec<(String, f64)>,
    /// Control period.
    pub period: f64,
    /// Horizon (a whole number of periods).
    pub horizon: f64,
    /// Initial set: one interval per state.
    pub init: Vec<(f64, f64)>,
    /// Network inputs as functions of the states (default: the states in order).
    pub observe: Graph,
    /// Inputs as functions of the network outputs (read as the graph's inputs).
    pub actuate: Graph,
    /// Optional clip of each input, applied after `actuate`.
    pub clips: Vec<Option<(f64, f64)>>,
    /// Number of network outputs read (`1 + ` the largest `net[i]`).
    pub n_net_outputs: usize,
    /// States restored to a value at every control instant.
    pub resets: Vec<(usize, f64)>,
    /// Goals (all must hold).
    pub goals: Vec<Goal>,
    /// The `if`s of the equations whose condition is not constant, in file order.
    pub switches: Vec<Switch>,
    /// Their conditions over the states and inputs, output `k` for `switches[k]`: `a -
    /// b` for `if a < b` or `a <= b`, `b - a` for `>` and `>=` (the branch changes where
    /// it changes sign).
    pub switch_conditions: Graph,
    /// For a discrete-time system (`next x = ...` updates): its update and mode; `None`
    /// for a continuous one (`x' = ...`), whose `rhs` this is. A discrete system's
    /// `rhs` is zero: commands that integrate a flow refuse it.
    pub discrete: Option<Discrete>,
    rhs: Graph,
    src: String,
}

impl System {
    /// Parse, check and compile a system file's text (`file` names it in errors).
    pub fn parse(src: &str, file: &str) -> Result<System, SystemError> {
        Self::parse_with(src, file, &[])
    }

    /// As [`System::parse`], with parameter values overriding the file's
    /// (parameters defined from an overridden one follow it).
    pub fn parse_with(
        src: &str,
        file: &str,
        overrides: &[(&str, f64)],
    ) -> Result<System, SystemError> {
        let toks = lex::lex(src, file)?;
        let stmts = parse::parse(&toks, file, src)?;
        compile::compile(&stmts, file, src, overrides)
    }

    /// Read, parse, check and compile a file.
    pub fn from_file(path: &std::path::Path) -> Result<System, SystemError> {
        let file = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|e| SystemError {
            file: file.clone(),
            pos: Pos::default(),
            message: format!("cannot read the file: {e}"),
            hint: "check the path".into(),
            source_line: String::new(),
        })?;
        let src = std::str::from_utf8(&bytes).map_err(|e| {
            let ok = &bytes[..e.valid_up_to()];
            let line = ok.iter().filter(|b| **b == b'\n').count() + 1;
            SystemError {
                file: file.clone(),
                pos: Pos { line, col: 1 },
                message: "the file is not UTF-8 text".into(),
                hint: "save the file as UTF-8".into(),
                source_line: String::new(),
            }
        })?;
        Self::parse(src, &file)
    }

    /// The same file recompiled with parameter overrides (relative to the file's own
    /// values; earlier overrides are not kept).
    pub fn with_params(&self, overrides: &[(&str, f64)]) -> Result<System, SystemError> {
        Self::parse_with(&self.src, &self.file, overrides)
    }

    /// The file's text as parsed (before parameter overrides): what identifies the
    /// system across processes, e.g. in the run record of shard files.
    pub fn source(&self) -> &str {
        &self.src
    }

    /// The value of a parameter.
    pub fn param(&self, name: &str) -> Option<f64> {
        self.params.iter().find(|(n, _)| n == name).map(|p| p.1)
    }

    /// Index of a state by name.
    pub fn state_index(&self, name: &str) -> Option<usize> {
        self.states.iter().position(|s| s == name)
    }

    /// The compiled right-hand side (one output per state).
    pub fn rhs_graph(&self) -> &Graph {
        &self.rhs
    }

    /// `out = f(x, u)` reusing `scratch` (no allocation once it has grown).
    pub fn rhs_with<S: Scalar>(&self, scratch: &mut Vec<S>, x: &[S], u: &[S], out: &mut [S]) {
        self.rhs.eval_with(scratch, x, u, out)
    }

    /// Number of network inputs (outputs of `observe`).
    pub fn n_observed(&self) -> usize {
        self.observe.outputs.len()
    }

    /// Whether a controller with `n_in` inputs and `n_out` outputs fits the file: it
    /// reads exactly the `observe` list and has every `net[i]` the file uses.
    pub fn fits_controller(&self, n_in: usize, n_out: usize) -> bool {
        n_in == self.n_observed() && n_out >= self.n_net_outputs
    }

    /// Network inputs for a state.
    pub fn observe<S: Scalar>(&self, x: &[S], out: &mut [S]) {
        self.observe.eval(x, &[], out)
    }

    /// Plant inputs for the network outputs: the actuation map, then the clips.
    pub fn actuate<S: Scalar>(&self, net_out: &[S], u: &mut [S]) {
        self.actuate.eval(&[], net_out, u);
        for (v, c) in u.iter_mut().zip(&self.clips) {
            if let Some((lo, hi)) = c {
                *v = v.clamp_to(*lo, *hi);
            }
        }
    }

    /// The observation as an affine map of the states, if it is affine.
    pub fn observe_affine(&self) -> Option<Affine> {
        self.observe.affine(self.dim(), 0)
    }

    /// The actuation (before clipping) as an affine map of the network outputs
    /// (`Affine::input`), if it is affine.
    pub fn actuate_affine(&self) -> Option<Affine> {
        self.actuate.affine(0, self.n_net_outputs)
    }

    /// Apply the `reset` statements to a state, unconditionally. Code that flies the
    /// closed loop calls [`System::initial_state`] and [`System::begin_period`] instead,
    /// which say *when* resets fire (see "Semantics of a closed loop" in docs/system.md).
    pub fn apply_resets<S: Scalar>(&self, x: &mut [S]) {
        for &(i, v) in &self.resets {
            x[i] = S::cst(v);
        }
    }

    /// The state at `t = 0` from a point (or set) of the `init` box: the resets fire at
    /// the first control instant before anything reads the state, so a reset state's
    /// `init` value is overwritten at once. One definition for the simulator
    /// ([`sim::fly`]) and the reachability code (`samara_reach::system`), so that both
    /// give the same meaning to a plant.
    pub fn initial_state<S: Scalar>(&self, x: &mut [S]) {
        self.apply_resets(x)
    }

    /// The state that the period starting at control instant `k` (time `k * period`)
    /// flies from and that the network reads, from the state at that instant: the
    /// resets fire at the instants `k = 0 .. steps() - 1`, before the network reads the
    /// state, and **never at the horizon** (`k >= steps()` leaves `x` as it is). The
    /// state *at* an instant `k >= 1` (what goals, "at end" and the recorded flights
    /// see) is the previous period's flow at its end, before this call; see
    /// docs/system.md, "Semantics of a closed loop".
    pub fn begin_period<S: Scalar>(&self, k: usize, x: &mut [S]) {
        if k < self.steps() {
            self.apply_resets(x)
        }
    }

    /// The `if`s whose condition changes sign within a relative distance `rel` of the
    /// state `x` (under the held inputs `u`): the condition evaluated on intervals over
    /// the box `x_i +- rel (1 + |x_i|)` contains 0. Names the switch at which a flight's
    /// step size collapsed ([`sim::SimError::StepCollapse`]).
    pub fn switches_at(&self, x: &[f64], u: &[f64], rel: f64) -> Vec<&Switch> {
        let xb: Vec<Interval> = x
            .iter()
            .map(|&v| {
                let r = rel * (1.0 + v.abs());
                Interval::new(v - r, v + r)
            })
            .collect();
        let ub: Vec<Interval> = u.iter().map(|&v| Interval::point(v)).collect();
        let mut o = vec![Interval::point(0.0); self.switches.len()];
        self.switch_conditions.eval(&xb, &ub, &mut o);
        self.switches
            .iter()
            .zip(&o)
            .filter(|(_, c)| !(c.lo > 0.0 || c.hi < 0.0))
            .map(|(w, _)| w)
            .collect()
    }

    /// Whether the system is discrete-time (`next` updates; see [`System::discrete`]).
    pub fn is_discrete(&self) -> bool {
        self.discrete.is_some()
    }

    /// One discrete step `out = next(x, u)`; for a continuous system `out = x`.
    pub fn next_state<S: Scalar>(&self, x: &[S], u: &[S], out: &mut [S]) {
        match &self.discrete {
            Some(d) => d.next.eval(x, u, out),
            None => out.clone_from_slice(x),
        }
    }

    /// Number of control periods in the horizon.
    pub fn steps(&self) -> usize {
        (self.horizon / self.period).round() as usize
    }

    /// Jacobians `df/dx` (row-major `dim x dim`) and `df/du` (`dim x n_inputs`) at a
    /// point, by forward-mode AD through the same graph (8 directions per pass).
    pub fn jacobian(&self, x: &[f64], u: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (n, m) = (self.dim(), self.n_inputs());
        let mut jx = vec![0.0; n * n];
        let mut ju = vec![0.0; n * m];
        let mut scratch = Vec::new();
        let mut out = vec![Dual::<8>::constant(0.0); n];
        let mut start = 0;
        while start < n + m {
            let seed = |k: usize, v: f64| {
                if k >= start && k < start + 8 {
                    Dual::<8>::var(v, k - start)
                } else {
                    Dual::<8>::constant(v)
                }
            };
            let xs: Vec<Dual<8>> = x.iter().enumerate().map(|(k, &v)| seed(k, v)).collect();
            let us: Vec<Dual<8>> = u.iter().enumerate().map(|(k, &v)| seed(n + k, v)).collect();
            self.rhs.eval_with(&mut scratch, &xs, &us, &mut out);
            for i in 0..n {
                for k in start..(start + 8).min(n + m) {
                    let d = out[i].d[k - start];
                    if k < n {
                        jx[i * n + k] = d;
                    } else {
                        ju[i * m + (k - n)] = d;
                    }
                }
            }
            start += 8;
        }
        (jx, ju)
    }
}

impl Dynamics for System {
    fn dim(&self) -> usize {
        self.states.len()
    }
    fn n_inputs(&self) -> usize {
        self.inputs.len()
    }
    fn rhs<S: Scalar>(&self, x: &[S], u: &[S], out: &mut [S]) {
        self.rhs.eval(x, u, out)
    }
    fn rhs_buffered<S: Scalar>(&self, scratch: &mut Vec<S>, x: &[S], u: &[S], out: &mut [S]) {
        self.rhs.eval_with(scratch, x, u, out)
    }
}

impl System {
    /// Number of states (also [`Dynamics::dim`]).
    pub fn dim(&self) -> usize {
        self.states.len()
    }
    /// Number of inputs (also [`Dynamics::n_inputs`]).
    pub fn n_inputs(&self) -> usize {
        self.inputs.len()
    }
    /// `out = f(x, u)` (also [`Dynamics::rhs`]).
    pub fn rhs<S: Scalar>(&self, x: &[S], u: &[S], out: &mut [S]) {
        self.rhs.eval(x, u, out)
    }
}
