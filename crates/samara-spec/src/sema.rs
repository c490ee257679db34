//! Name resolution, type checking and lowering of a parsed spec to the linear normal
//! form ([`crate::normal`]).
//!
//! Expressions evaluate to piecewise-linear values: a linear part plus weighted maxima of
//! linear forms (`|e| = max(e, -e)`, `||v||_inf = max_i max(v_i, -v_i)`). A comparison
//! `e <= 0` with a max of positive weight holds iff it holds for every branch (a
//! conjunction); with negative weight iff it holds for some branch (a disjunction). The
//! negated property is pushed to negation normal form on the comparisons *before* this
//! expansion, so the expansion is exact, and the result is put in disjunctive normal form.

use crate::data::Table;
use crate::diag::{nearest, SpecError, Span};
use crate::normal::{Application, Cmp, Constraint, Goal, LinExpr, Query, Sense, Var};
use crate::syntax::{Ast, BinOp, Binder, Body, CmpOp, Expr, Name, PropertyDecl, Units};
use std::collections::BTreeMap;

/// Largest number of disjuncts a query may lower to.
pub const MAX_DISJUNCTS: usize = 4096;

/// Unit constants of a network: `raw = min + range * normalised`.
#[derive(Clone, Debug, PartialEq)]
pub struct Constants {
    /// Input minima.
    pub in_min: Vec<f64>,
    /// Input ranges.
    pub in_range: Vec<f64>,
    /// Output minima.
    pub out_min: Vec<f64>,
    /// Output ranges.
    pub out_range: Vec<f64>,
}

/// A network as the spec sees it.
#[derive(Clone, Debug, PartialEq)]
pub struct NetInfo {
    /// Name in the spec.
    pub name: String,
    /// Input names.
    pub inputs: Vec<String>,
    /// Output names.
    pub outputs: Vec<String>,
    /// Whether the network file is applied to normalised values (`true`) or raw ones.
    pub applied_normalised: bool,
    /// Unit constants, if known (always for normalised networks; for raw networks when
    /// the loaded network carries diagonal normalisation layers).
    pub constants: Option<Constants>,
    /// Input domain in raw units (infinite where undeclared).
    pub domain_raw: Vec<(f64, f64)>,
    /// Whether a domain was declared.
    pub has_domain: bool,
    /// Default file from the spec (resolved against the spec's folder).
    pub file: Option<std::path::PathBuf>,
}

impl NetInfo {
    fn in_map(&self, i: usize) -> (f64, f64) {
        match &self.constants {
            Some(c) => (c.in_min[i], c.in_range[i]),
            None => (0.0, 1.0),
        }
    }
    fn out_map(&self, i: usize) -> (f64, f64) {
        match &self.constants {
            Some(c) => (c.out_min[i], c.out_range[i]),
            None => (0.0, 1.0),
        }
    }
    /// The input domain in the units the network is applied in.
    pub fn domain_applied(&self) -> Vec<(f64, f64)> {
        self.domain_raw
            .iter()
            .enumerate()
            .map(|(i, &(lo, hi))| {
                if self.applied_normalised {
                    let (m, r) = self.in_map(i);
                    sorted((lo - m) / r, (hi - m) / r)
                } else {
                    (lo, hi)
                }
            })
            .collect()
    }
}

fn sorted(a: f64, b: f64) -> (f64, f64) {
    if a <= b {
        (a, b)
    } else {
        (b, a)
    }
}

/// A data set, values converted to raw units.
#[derive(Clone, Debug, PartialEq)]
pub struct DataInfo {
    /// Name.
    pub name: String,
    /// Input column names.
    pub inputs: Vec<String>,
    /// Label column names.
    pub outputs: Vec<String>,
    /// Rows: inputs then labels, raw units.
    pub table: Table,
}

/// A parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamInfo {
    /// Name.
    pub name: String,
    /// Value (from the command line or the spec's default).
    pub value: Option<f64>,
    /// Bounds for critical queries (infinite if undeclared).
    pub bounds: (f64, f64),
}

/// The resolved parts of a spec (the AST with networks, data and parameters bound).
pub(crate) struct Ctx<'a> {
    pub file: &'a str,
    pub src: &'a str,
    pub nets: &'a [NetInfo],
    pub data: &'a [DataInfo],
    pub params: &'a [ParamInfo],
}

/// How parameters evaluate during one lowering.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum ParamMode {
    /// Lower for real: unbound parameters are errors, except `free` (a critical query).
    Lower { free: Option<usize> },
    /// Type-check only: unbound parameters stand for 1.
    Check,
}

/// A piecewise-linear scalar.
#[derive(Clone, Debug, PartialEq, Default)]
struct Pl {
    lin: LinExpr,
    maxes: Vec<(f64, Vec<LinExpr>)>,
}

impl Pl {
    fn c(v: f64) -> Pl {
        Pl {
            lin: LinExpr {
                terms: vec![],
                constant: v,
            },
            maxes: vec![],
        }
    }
    fn var(v: Var, scale: f64, offset: f64) -> Pl {
        Pl {
            lin: LinExpr {
                terms: vec![(v, scale)],
                constant: offset,
            },
            maxes: vec![],
        }
    }
    fn constant(&self) -> Option<f64> {
        (self.lin.terms.iter().all(|t| t.1 == 0.0) && self.maxes.is_empty()).then_some(self.lin.constant)
    }
    fn scale(mut self, k: f64) -> Pl {
        self.lin.terms.iter_mut().for_each(|t| t.1 *= k);
        self.lin.constant *= k;
        self.maxes.iter_mut().for_each(|m| m.0 *= k);
        self.maxes.retain(|m| m.0 != 0.0);
        self
    }
    fn add(mut self, o: Pl) -> Pl {
        self.lin.terms.extend(o.lin.terms);
        self.lin.constant += o.lin.constant;
        self.maxes.extend(o.maxes);
        self.lin = std::mem::take(&mut self.lin).normalised();
        self
    }
}

/// A value of an expression.
#[derive(Clone, Debug)]
enum Val {
    Num(Pl),
    Vector(Vec<Pl>),
    Bool(Bf),
    /// A point variable (index into the lowering's points).
    Point(usize),
    /// A data point: (data set, row).
    DataPoint(usize, usize),
    /// A network (only as the callee of an application).
    Net,
}

/// A formula over piecewise-linear atoms `pl cmp 0`.
#[derive(Clone, Debug, PartialEq)]
enum Bf {
    Const(bool),
    Atom(Pl, Cmp),
    And(Vec<Bf>),
    Or(Vec<Bf>),
}

impl Bf {
    fn negate(self) -> Bf {
        match self {
            Bf::Const(b) => Bf::Const(!b),
            Bf::Atom(e, Cmp::Le) => Bf::Atom(e.scale(-1.0), Cmp::Lt),
            Bf::Atom(e, Cmp::Lt) => Bf::Atom(e.scale(-1.0), Cmp::Le),
            Bf::Atom(e, Cmp::Eq) => Bf::Or(vec![
                Bf::Atom(e.clone(), Cmp::Lt),
                Bf::Atom(e.scale(-1.0), Cmp::Lt),
            ]),
            Bf::And(v) => Bf::Or(v.into_iter().map(Bf::negate).collect()),
            Bf::Or(v) => Bf::And(v.into_iter().map(Bf::negate).collect()),
        }
    }
}

/// A point variable of one lowering.
struct Point {
    name: String,
    net: usize,
    /// Box in applied units (domain, intersected with a ball).
    bbox: Vec<(f64, f64)>,
    /// Applications at this point: (network, application index).
    apps: Vec<(usize, usize)>,
}

/// A per-instance binding of a quantified name.
#[derive(Clone, Debug)]
enum Bound {
    Data(usize, usize),
    Value(f64),
    Point(usize),
}

/// State of one lowering.
pub(crate) struct Lowering<'c, 'a> {
    ctx: &'c Ctx<'a>,
    mode: ParamMode,
    normalised: bool,
    points: Vec<Point>,
    apps: Vec<Application>,
    /// Application inputs pinned to constants (data points): (net, row values applied).
    pinned: Vec<(usize, Vec<u64>, usize)>,
    ties: Vec<Constraint>,
    scope: Vec<(String, Bound)>,
    /// The ball structure of the last bound ball point: (app, centre, radius) applied units.
    pub ball: Option<(usize, Vec<f64>, f64)>,
}

/// One instance of a property's quantifiers.
#[derive(Clone, Debug, PartialEq)]
pub struct InstanceKey {
    /// The data row of each `p in data` binder, in order.
    pub rows: Vec<usize>,
    /// The value of each `e in {..}` binder, in order.
    pub values: Vec<(String, f64)>,
}

impl<'c, 'a> Lowering<'c, 'a> {
    pub(crate) fn new(ctx: &'c Ctx<'a>, mode: ParamMode, normalised: bool) -> Self {
        Lowering {
            ctx,
            mode,
            normalised,
            points: vec![],
            apps: vec![],
            pinned: vec![],
            ties: vec![],
            scope: vec![],
            ball: None,
        }
    }

    fn err(&self, span: Span, msg: impl Into<String>) -> SpecError {
        SpecError::at(self.ctx.file, self.ctx.src, span, msg)
    }

    fn net_index(&self, n: &Name) -> Result<usize, SpecError> {
        self.ctx
            .nets
            .iter()
            .position(|x| x.name == n.text)
            .ok_or_else(|| {
                let mut e = self
                    .err(n.span, format!("unknown network `{}`", n.text))
                    .expected("a declared network");
                if let Some(s) = nearest(&n.text, self.ctx.nets.iter().map(|x| x.name.as_str())) {
                    e = e.help(format!("did you mean `{s}`?"));
                } else {
                    e = e.help(format!("declare it: `network {}(inputs) -> (outputs);`", n.text));
                }
                e
            })
    }

    /// Bind the quantifiers of `prop` for one instance.
    pub(crate) fn bind(&mut self, prop: &PropertyDecl, key: &InstanceKey) -> Result<(), SpecError> {
        let (mut ri, mut vi) = (0, 0);
        for b in &prop.binders {
            match b {
                Binder::Data(v, d) => {
                    let di = data_index(self.ctx, d)?;
                    let row = key.rows.get(ri).copied().unwrap_or(0);
                    ri += 1;
                    self.scope.push((v.text.clone(), Bound::Data(di, row)));
                }
                Binder::Values(v, _) => {
                    let val = key.values.get(vi).map(|x| x.1).unwrap_or(1.0);
                    vi += 1;
                    self.scope.push((v.text.clone(), Bound::Value(val)));
                }
                Binder::Point(v, net, ball) => {
                    let ni = match net {
                        Some(n) => self.net_index(n)?,
                        None => {
                            // Infer from the ball's centre dimension (the first network
                            // whose input count matches), else the only network.
                            let dim = match ball {
                                Some((c, _, _)) => match self.eval(c)? {
                                    Val::DataPoint(d, _) => Some(self.ctx.data[d].inputs.len()),
                                    Val::Vector(v) => Some(v.len()),
                                    _ => None,
                                },
                                None => None,
                            };
                            let cand: Vec<usize> = (0..self.ctx.nets.len())
                                .filter(|&i| dim.is_none_or(|d| self.ctx.nets[i].inputs.len() == d))
                                .collect();
                            if cand.len() != 1 {
                                return Err(self
                                    .err(v.span, format!("cannot tell which network's inputs `{}` ranges over", v.text))
                                    .help(format!("write `{} : NETWORK`", v.text)));
                            }
                            cand[0]
                        }
                    };
                    let net = &self.ctx.nets[ni];
                    let mut bbox = net.domain_applied();
                    if let Some((c, r, sp)) = ball {
                        let centre = self.const_vector(c)?;
                        let radius = self.const_scalar(r)?;
                        if centre.len() != net.inputs.len() {
                            return Err(self
                                .err(*sp, format!(
                                    "dimension mismatch: ball centre has {} components, network `{}` has {} inputs",
                                    centre.len(), net.name, net.inputs.len()))
                                .help("the centre must be a point of the network's inputs (a data point with the same input columns)"));
                        }
                        if radius.is_nan() || radius < 0.0 {
                            return Err(self.err(*sp, format!("ball radius {radius} is negative")).expected("a radius >= 0"));
                        }
                        let mut centre_applied = Vec::new();
                        for (i, b) in bbox.iter_mut().enumerate() {
                            let (lo, hi) = (centre[i] - radius, centre[i] + radius);
                            let (lo, hi) = self.prop_to_applied_in(ni, i, lo, hi)?;
                            let cc = self.prop_to_applied_in(ni, i, centre[i], centre[i])?.0;
                            centre_applied.push(cc);
                            b.0 = b.0.max(lo);
                            b.1 = b.1.min(hi);
                        }
                        let radius_applied = if self.normalised == net.applied_normalised || net.constants.is_none() {
                            radius
                        } else {
                            f64::NAN // per-coordinate radii differ; only the box is exact
                        };
                        let pi = self.points.len();
                        self.points.push(Point {
                            name: v.text.clone(),
                            net: ni,
                            bbox,
                            apps: vec![],
                        });
                        let app = self.point_app(pi, ni, v.span)?;
                        self.ball = Some((app, centre_applied, radius_applied));
                        self.scope.push((v.text.clone(), Bound::Point(pi)));
                        continue;
                    }
                    let pi = self.points.len();
                    self.points.push(Point {
                        name: v.text.clone(),
                        net: ni,
                        bbox,
                        apps: vec![],
                    });
                    self.scope.push((v.text.clone(), Bound::Point(pi)));
                }
            }
        }
        Ok(())
    }

    /// Convert an interval of input `i` of network `n` from property units to applied units.
    fn prop_to_applied_in(&self, n: usize, i: usize, lo: f64, hi: f64) -> Result<(f64, f64), SpecError> {
        let net = &self.ctx.nets[n];
        if self.normalised == net.applied_normalised {
            return Ok((lo, hi));
        }
        let (m, r) = net.in_map(i);
        if net.constants.is_none() {
            return Err(SpecError::plain(self.ctx.file, format!("network `{}` has no normalisation constants", net.name)));
        }
        Ok(if net.applied_normalised {
            sorted((lo - m) / r, (hi - m) / r) // raw property -> normalised network
        } else {
            sorted(m + r * lo, m + r * hi)
        })
    }

    /// The application of network `n` at point `p` (created on first use).
    fn point_app(&mut self, p: usize, n: usize, span: Span) -> Result<usize, SpecError> {
        if let Some(&(_, a)) = self.points[p].apps.iter().find(|(nn, _)| *nn == n) {
            return Ok(a);
        }
        let home = self.points[p].net;
        let net = &self.ctx.nets[n];
        let hnet = &self.ctx.nets[home];
        if net.inputs.len() != hnet.inputs.len() {
            return Err(self
                .err(span, format!(
                    "dimension mismatch: `{}` takes {} inputs but point `{}` has {} (the inputs of `{}`)",
                    net.name, net.inputs.len(), self.points[p].name, hnet.inputs.len(), hnet.name))
                .help("apply the network to a point of its own input space"));
        }
        let a = self.apps.len();
        let bbox = if n == home {
            self.points[p].bbox.clone()
        } else {
            net.domain_applied()
        };
        self.apps.push(Application {
            network: net.name.clone(),
            n_inputs: net.inputs.len(),
            n_outputs: net.outputs.len(),
            input_box: bbox,
        });
        if n != home {
            // Tie the inputs to the home application's, in raw units.
            let ha = self.point_app(p, home, span)?;
            for i in 0..net.inputs.len() {
                let x = self.input_value(ha, home, i, false)?;
                let y = self.input_value(a, n, i, false)?;
                self.ties.push(Constraint {
                    expr: x.add(y.scale(-1.0)).lin,
                    cmp: Cmp::Eq,
                });
            }
        }
        self.points[p].apps.push((n, a));
        Ok(a)
    }

    /// Input `i` of application `a` (network `n`) in raw (`normalised = false`) or the
    /// property's units.
    fn input_value(&self, a: usize, n: usize, i: usize, prop_units: bool) -> Result<Pl, SpecError> {
        let net = &self.ctx.nets[n];
        let want_norm = prop_units && self.normalised;
        let v = Var::Input { app: a, index: i };
        self.convert(net, want_norm, v, net.in_map(i))
    }

    fn output_value(&self, a: usize, n: usize, i: usize) -> Result<Pl, SpecError> {
        let net = &self.ctx.nets[n];
        let v = Var::Output { app: a, index: i };
        self.convert(net, self.normalised, v, net.out_map(i))
    }

    fn convert(&self, net: &NetInfo, want_norm: bool, v: Var, (m, r): (f64, f64)) -> Result<Pl, SpecError> {
        if want_norm == net.applied_normalised {
            return Ok(Pl::var(v, 1.0, 0.0));
        }
        if net.constants.is_none() {
            return Err(SpecError::plain(
                self.ctx.file,
                format!("network `{}` has no normalisation constants, so a `normalised` property cannot speak about it", net.name),
            )
            .help("declare `normalised constants \"FILE\"` or load a network with normalisation layers"));
        }
        Ok(if net.applied_normalised {
            Pl::var(v, r, m) // raw = m + r * n
        } else {
            Pl::var(v, 1.0 / r, -m / r) // n = (raw - m) / r
        })
    }

    /// The application of network `n` to a data point (pinned inputs).
    fn data_app(&mut self, n: usize, d: usize, row: usize, span: Span) -> Result<usize, SpecError> {
        let net = &self.ctx.nets[n];
        let data = &self.ctx.data[d];
        if data.inputs.len() != net.inputs.len() {
            return Err(self
                .err(span, format!(
                    "dimension mismatch: `{}` takes {} inputs but data set `{}` has {} input columns",
                    net.name, net.inputs.len(), data.name, data.inputs.len()))
                .help("declare the data set's `inputs (..)` with the network's input columns"));
        }
        let raw = data.table.row(row);
        let vals: Vec<f64> = (0..net.inputs.len())
            .map(|i| {
                if net.applied_normalised {
                    let (m, r) = net.in_map(i);
                    (raw[i] - m) / r
                } else {
                    raw[i]
                }
            })
            .collect();
        let key: Vec<u64> = vals.iter().map(|v| v.to_bits()).collect();
        if let Some((_, _, a)) = self.pinned.iter().find(|(nn, k, _)| *nn == n && *k == key) {
            return Ok(*a);
        }
        let a = self.apps.len();
        self.apps.push(Application {
            network: net.name.clone(),
            n_inputs: net.inputs.len(),
            n_outputs: net.outputs.len(),
            input_box: vals.iter().map(|&v| (v, v)).collect(),
        });
        self.pinned.push((n, key, a));
        Ok(a)
    }

    /// A data column's value in property units.
    fn data_value(&self, d: usize, row: usize, col: usize) -> Result<f64, SpecError> {
        let data = &self.ctx.data[d];
        let raw = data.table.row(row)[col];
        if !self.normalised {
            return Ok(raw);
        }
        let name = if col < data.inputs.len() {
            &data.inputs[col]
        } else {
            &data.outputs[col - data.inputs.len()]
        };
        for n in self.ctx.nets {
            if let Some(c) = &n.constants {
                if let Some(i) = n.inputs.iter().position(|x| x == name) {
                    return Ok((raw - c.in_min[i]) / c.in_range[i]);
                }
                if let Some(i) = n.outputs.iter().position(|x| x == name) {
                    return Ok((raw - c.out_min[i]) / c.out_range[i]);
                }
            }
        }
        Err(SpecError::plain(
            self.ctx.file,
            format!("no network gives normalisation constants for column `{name}` of data set `{}`", data.name),
        ))
    }

    fn const_scalar(&mut self, e: &Expr) -> Result<f64, SpecError> {
        match self.eval(e)? {
            Val::Num(p) => p
                .constant()
                .ok_or_else(|| self.err(e.span(), "expected a constant").expected("a number or parameter")),
            Val::Vector(v) if v.len() == 1 && v[0].constant().is_some() => Ok(v[0].lin.constant),
            _ => Err(self.err(e.span(), "expected a constant number").expected("a number or parameter")),
        }
    }

    fn const_vector(&mut self, e: &Expr) -> Result<Vec<f64>, SpecError> {
        let v = self.eval(e)?;
        let v = self.as_vector(v, e.span())?;
        v.iter()
            .map(|p| {
                p.constant()
                    .ok_or_else(|| self.err(e.span(), "expected a constant point").expected("a data point or numbers"))
            })
            .collect()
    }

    fn as_vector(&mut self, v: Val, span: Span) -> Result<Vec<Pl>, SpecError> {
        match v {
            Val::Vector(v) => Ok(v),
            Val::Num(p) => Ok(vec![p]),
            Val::Point(p) => {
                let n = self.points[p].net;
                let a = self.point_app(p, n, span)?;
                (0..self.ctx.nets[n].inputs.len())
                    .map(|i| self.input_value(a, n, i, true))
                    .collect()
            }
            Val::DataPoint(d, row) => (0..self.ctx.data[d].inputs.len())
                .map(|c| self.data_value(d, row, c).map(Pl::c))
                .collect(),
            Val::Bool(_) => Err(self.err(span, "expected a number, found a formula").expected("an arithmetic expression")),
            Val::Net => Err(self.err(span, "a network is not a value").help("apply it: `f(x)`")),
        }
    }

    fn as_num(&mut self, v: Val, span: Span) -> Result<Pl, SpecError> {
        match v {
            Val::Num(p) => Ok(p),
            Val::Bool(_) => Err(self.err(span, "expected a number, found a formula").expected("an arithmetic expression")),
            other => {
                let v = self.as_vector(other, span)?;
                if v.len() == 1 {
                    Ok(v.into_iter().next().unwrap())
                } else {
                    Err(self
                        .err(span, format!("dimension mismatch: expected a scalar, found a vector of {} components", v.len()))
                        .expected("a scalar")
                        .help("select a component (`x'.y`, `f(x).ex`) or take a norm `||..||_inf`"))
                }
            }
        }
    }

    fn as_bool(&mut self, v: Val, span: Span) -> Result<Bf, SpecError> {
        match v {
            Val::Bool(b) => Ok(b),
            _ => Err(self
                .err(span, "expected a formula, found a number")
                .expected("a comparison such as `ex >= 0.187`")),
        }
    }

    fn lookup(&self, name: &str) -> Option<Bound> {
        self.scope.iter().rev().find(|(n, _)| n == name).map(|(_, b)| b.clone())
    }

    fn default_point(&mut self, n: usize) -> usize {
        let name = format!("{}()", self.ctx.nets[n].name);
        if let Some(p) = self.points.iter().position(|p| p.name == name) {
            return p;
        }
        let bbox = self.ctx.nets[n].domain_applied();
        self.points.push(Point {
            name,
            net: n,
            bbox,
            apps: vec![],
        });
        self.points.len() - 1
    }

    fn var(&mut self, n: &Name) -> Result<Val, SpecError> {
        if let Some(b) = self.lookup(&n.text) {
            return Ok(match b {
                Bound::Data(d, r) => Val::DataPoint(d, r),
                Bound::Value(v) => Val::Num(Pl::c(v)),
                Bound::Point(p) => Val::Point(p),
            });
        }
        if let Some(pi) = self.ctx.params.iter().position(|p| p.name == n.text) {
            let p = &self.ctx.params[pi];
            return match (self.mode, p.value) {
                (ParamMode::Lower { free: Some(f) }, _) if f == pi => Ok(Val::Num(Pl::var(Var::Free(0), 1.0, 0.0))),
                (_, Some(v)) => Ok(Val::Num(Pl::c(v))),
                (ParamMode::Check, None) => Ok(Val::Num(Pl::c(1.0))),
                (ParamMode::Lower { .. }, None) => Err(self
                    .err(n.span, format!("parameter `{}` is not bound", n.text))
                    .expected("a value for the parameter")
                    .help(format!("pass `--param {}=VALUE`, declare `param {} = VALUE;`, or ask for its critical value", n.text, n.text))),
            };
        }
        if self.ctx.nets.iter().any(|x| x.name == n.text) {
            return Ok(Val::Net);
        }
        // A bare input or output name: the default application of the network declaring it.
        let owners: Vec<(usize, bool, usize)> = self
            .ctx
            .nets
            .iter()
            .enumerate()
            .flat_map(|(ni, net)| {
                let i = net.inputs.iter().position(|x| *x == n.text).map(|i| (ni, true, i));
                let o = net.outputs.iter().position(|x| *x == n.text).map(|i| (ni, false, i));
                i.into_iter().chain(o)
            })
            .collect();
        match owners.as_slice() {
            [(ni, is_in, i)] => {
                let p = self.default_point(*ni);
                let a = self.point_app(p, *ni, n.span)?;
                let v = if *is_in {
                    self.input_value(a, *ni, *i, true)?
                } else {
                    self.output_value(a, *ni, *i)?
                };
                Ok(Val::Num(v))
            }
            [] => {
                let mut cands: Vec<&str> = self.scope.iter().map(|(s, _)| s.as_str()).collect();
                cands.extend(self.ctx.params.iter().map(|p| p.name.as_str()));
                for net in self.ctx.nets {
                    cands.extend(net.inputs.iter().map(|s| s.as_str()));
                    cands.extend(net.outputs.iter().map(|s| s.as_str()));
                }
                let mut e = self
                    .err(n.span, format!("unknown variable `{}`", n.text))
                    .expected("an input or output name, a parameter or a bound variable");
                if let Some(s) = nearest(&n.text, cands) {
                    e = e.help(format!("did you mean `{s}`?"));
                } else {
                    e = e.help(format!("declare it with `param {};` or bind it with `forall`", n.text));
                }
                Err(e)
            }
            _ => Err(self
                .err(n.span, format!("`{}` is ambiguous: several networks have it", n.text))
                .help(format!("name the application: `f(x).{}` with `forall x : f`", n.text))),
        }
    }

    fn field(&mut self, base: &Expr, f: &Name) -> Result<Val, SpecError> {
        let b = self.eval(base)?;
        match b {
            Val::Point(p) => {
                let n = self.points[p].net;
                let net = &self.ctx.nets[n];
                match net.inputs.iter().position(|x| *x == f.text) {
                    Some(i) => {
                        let a = self.point_app(p, n, f.span)?;
                        Ok(Val::Num(self.input_value(a, n, i, true)?))
                    }
                    None => Err(self.unknown_field(f, net.inputs.iter())),
                }
            }
            Val::DataPoint(d, row) => {
                let data = &self.ctx.data[d];
                match data.inputs.iter().chain(data.outputs.iter()).position(|x| *x == f.text) {
                    Some(c) => Ok(Val::Num(Pl::c(self.data_value(d, row, c)?))),
                    None => Err(self.unknown_field(f, data.inputs.iter().chain(data.outputs.iter()))),
                }
            }
            _ => {
                // An application result f(x).out: resolve by the callee's output names.
                if let Expr::Call(callee, _, _) = base {
                    if let Some(ni) = self.ctx.nets.iter().position(|x| x.name == callee.text) {
                        let net = &self.ctx.nets[ni];
                        let Val::Vector(v) = b else { unreachable!("applications give vectors") };
                        return match net.outputs.iter().position(|x| *x == f.text) {
                            Some(i) => Ok(Val::Num(v[i].clone())),
                            None => Err(self.unknown_field(f, net.outputs.iter())),
                        };
                    }
                }
                Err(self
                    .err(f.span, format!("`.{}` needs a point, a data point or an application", f.text))
                    .expected("a point such as `x'.y` or `f(x).ex`"))
            }
        }
    }

    fn unknown_field<'s>(&self, f: &Name, cands: impl Iterator<Item = &'s String>) -> SpecError {
        let c: Vec<&str> = cands.map(|s| s.as_str()).collect();
        let mut e = self
            .err(f.span, format!("unknown field `{}`", f.text))
            .expected(format!("one of {}", c.join(", ")));
        if let Some(s) = nearest(&f.text, c) {
            e = e.help(format!("did you mean `{s}`?"));
        }
        e
    }

    fn call(&mut self, callee: &Name, args: &[Expr], span: Span) -> Result<Val, SpecError> {
        let arity = |me: &Self, k: usize| -> Result<(), SpecError> {
            if args.len() != k {
                Err(me.err(span, format!("`{}` takes {k} argument(s), found {}", callee.text, args.len())))
            } else {
                Ok(())
            }
        };
        match callee.text.as_str() {
            "abs" => {
                arity(self, 1)?;
                let v = self.eval(&args[0])?;
                let p = self.as_num(v, args[0].span())?;
                return self.abs(p, span).map(Val::Num);
            }
            "norm_inf" => {
                arity(self, 1)?;
                let v = self.eval(&args[0])?;
                let v = self.as_vector(v, args[0].span())?;
                return self.norm(v, span).map(Val::Num);
            }
            _ => {}
        }
        let Some(ni) = self.ctx.nets.iter().position(|x| x.name == callee.text) else {
            let mut cands: Vec<&str> = vec!["abs", "norm_inf"];
            cands.extend(self.ctx.nets.iter().map(|x| x.name.as_str()));
            let mut e = self
                .err(callee.span, format!("unknown function `{}`", callee.text))
                .expected("a network name, `abs` or `norm_inf`");
            if let Some(s) = nearest(&callee.text, cands) {
                e = e.help(format!("did you mean `{s}`?"));
            }
            return Err(e);
        };
        arity(self, 1)?;
        let a = match self.eval(&args[0])? {
            Val::Point(p) => self.point_app(p, ni, span)?,
            Val::DataPoint(d, row) => self.data_app(ni, d, row, span)?,
            _ => {
                return Err(self
                    .err(args[0].span(), "a network is applied to a point variable or a data point")
                    .expected("a name bound by `forall x : f` or `forall p in DATA`"))
            }
        };
        let outs = (0..self.ctx.nets[ni].outputs.len())
            .map(|i| self.output_value(a, ni, i))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Val::Vector(outs))
    }

    fn abs(&self, p: Pl, span: Span) -> Result<Pl, SpecError> {
        if !p.maxes.is_empty() {
            return Err(self
                .err(span, "nested absolute value or norm")
                .help("write the inner expression without `|..|`; nested maxima are not lowered"));
        }
        if let Some(c) = p.constant() {
            return Ok(Pl::c(c.abs()));
        }
        let neg = p.lin.clone();
        let neg = LinExpr {
            terms: neg.terms.iter().map(|(v, c)| (*v, -c)).collect(),
            constant: -neg.constant,
        };
        Ok(Pl {
            lin: LinExpr::default(),
            maxes: vec![(1.0, vec![p.lin, neg])],
        })
    }

    fn norm(&self, v: Vec<Pl>, span: Span) -> Result<Pl, SpecError> {
        let mut forms = Vec::new();
        let mut cmax: f64 = 0.0;
        for p in v {
            if !p.maxes.is_empty() {
                return Err(self.err(span, "nested absolute value or norm").help("norm a linear vector expression"));
            }
            if let Some(c) = p.constant() {
                cmax = cmax.max(c.abs());
                continue;
            }
            let neg = LinExpr {
                terms: p.lin.terms.iter().map(|(v, c)| (*v, -c)).collect(),
                constant: -p.lin.constant,
            };
            forms.push(p.lin);
            forms.push(neg);
        }
        if forms.is_empty() {
            return Ok(Pl::c(cmax));
        }
        if cmax > 0.0 {
            forms.push(LinExpr {
                terms: vec![],
                constant: cmax,
            });
        }
        Ok(Pl {
            lin: LinExpr::default(),
            maxes: vec![(1.0, forms)],
        })
    }

    fn arith(&mut self, op: BinOp, a: &Expr, b: &Expr) -> Result<Val, SpecError> {
        let va = self.eval(a)?;
        let vb = self.eval(b)?;
        let is_vec = |v: &Val| matches!(v, Val::Point(_) | Val::DataPoint(..)) || matches!(v, Val::Vector(x) if x.len() != 1);
        match op {
            BinOp::Add | BinOp::Sub => {
                let k = if op == BinOp::Sub { -1.0 } else { 1.0 };
                if is_vec(&va) || is_vec(&vb) {
                    let x = self.as_vector(va, a.span())?;
                    let y = self.as_vector(vb, b.span())?;
                    if x.len() != y.len() {
                        return Err(self
                            .err(a.span().to(b.span()), format!(
                                "dimension mismatch: {} components {} {} components",
                                x.len(), if k < 0.0 { "minus" } else { "plus" }, y.len()))
                            .expected("vectors of the same dimension")
                            .help("both sides must be points of the same network's inputs"));
                    }
                    return Ok(Val::Vector(x.into_iter().zip(y).map(|(p, q)| p.add(q.scale(k))).collect()));
                }
                let x = self.as_num(va, a.span())?;
                let y = self.as_num(vb, b.span())?;
                Ok(Val::Num(x.add(y.scale(k))))
            }
            BinOp::Mul | BinOp::Div => {
                let sb = b.span();
                if op == BinOp::Div {
                    let y = self.as_num(vb, sb)?;
                    let Some(c) = y.constant() else {
                        return Err(self
                            .err(sb, "nonlinear term: division by a variable expression")
                            .expected("a constant divisor")
                            .help("multiply the inequality through by the divisor, or bind the parameter with --param"));
                    };
                    if c == 0.0 {
                        return Err(self.err(sb, "division by zero"));
                    }
                    return match va {
                        v if is_vec(&v) => {
                            let x = self.as_vector(v, a.span())?;
                            Ok(Val::Vector(x.into_iter().map(|p| p.scale(1.0 / c)).collect()))
                        }
                        v => Ok(Val::Num(self.as_num(v, a.span())?.scale(1.0 / c))),
                    };
                }
                // Multiplication: one side must be a constant scalar.
                let (vec_side, other, os) = if is_vec(&va) { (va, vb, sb) } else { (vb, va, a.span()) };
                if is_vec(&vec_side) {
                    let k = self.as_num(other, os)?;
                    let Some(c) = k.constant() else {
                        return Err(self.err(a.span().to(sb), "nonlinear term: product of two variable expressions")
                            .help("one factor must be a number or a bound parameter"));
                    };
                    let x = self.as_vector(vec_side, a.span().to(sb))?;
                    return Ok(Val::Vector(x.into_iter().map(|p| p.scale(c)).collect()));
                }
                let x = self.as_num(other, os)?;
                let y = self.as_num(vec_side, if os == sb { a.span() } else { sb })?;
                match (x.constant(), y.constant()) {
                    (Some(c), _) => Ok(Val::Num(y.scale(c))),
                    (_, Some(c)) => Ok(Val::Num(x.scale(c))),
                    _ => Err(self
                        .err(a.span().to(sb), "nonlinear term: product of two variable expressions")
                        .expected("a linear expression")
                        .help("one factor must be a number or a bound parameter (a parameter being optimised may only appear linearly; bind it with --param)")),
                }
            }
            _ => unreachable!("logical operators are handled by eval"),
        }
    }

    fn eval(&mut self, e: &Expr) -> Result<Val, SpecError> {
        Ok(match e {
            Expr::Num(v, _) => Val::Num(Pl::c(*v)),
            Expr::Bool(b, _) => Val::Bool(Bf::Const(*b)),
            Expr::Var(n) => self.var(n)?,
            Expr::Field(b, f) => self.field(b, f)?,
            Expr::Call(c, args, s) => self.call(c, args, *s)?,
            Expr::Abs(x, s) => {
                let v = self.eval(x)?;
                let p = self.as_num(v, x.span())?;
                Val::Num(self.abs(p, *s)?)
            }
            Expr::Norm(x, s) => {
                let v = self.eval(x)?;
                let v = self.as_vector(v, x.span())?;
                Val::Num(self.norm(v, *s)?)
            }
            Expr::Neg(x, s) => match self.eval(x)? {
                Val::Num(p) => Val::Num(p.scale(-1.0)),
                v => Val::Vector(self.as_vector(v, *s)?.into_iter().map(|p| p.scale(-1.0)).collect()),
            },
            Expr::Not(x, _) => {
                let v = self.eval(x)?;
                Val::Bool(self.as_bool(v, x.span())?.negate())
            }
            Expr::Bin(op @ (BinOp::And | BinOp::Or | BinOp::Implies), a, b) => {
                let va = self.eval(a)?;
                let x = self.as_bool(va, a.span())?;
                let vb = self.eval(b)?;
                let y = self.as_bool(vb, b.span())?;
                Val::Bool(match op {
                    BinOp::And => Bf::And(vec![x, y]),
                    BinOp::Or => Bf::Or(vec![x, y]),
                    _ => Bf::Or(vec![x.negate(), y]),
                })
            }
            Expr::Bin(op, a, b) => self.arith(*op, a, b)?,
            Expr::Chain(es, ops) => {
                let mut vals = Vec::new();
                for x in es {
                    let v = self.eval(x)?;
                    vals.push(self.as_num(v, x.span())?);
                }
                let mut atoms = Vec::new();
                for (i, (op, _)) in ops.iter().enumerate() {
                    let (l, r) = (vals[i].clone(), vals[i + 1].clone());
                    let d = l.add(r.scale(-1.0)); // l - r
                    atoms.push(match op {
                        CmpOp::Le => Bf::Atom(d, Cmp::Le),
                        CmpOp::Lt => Bf::Atom(d, Cmp::Lt),
                        CmpOp::Ge => Bf::Atom(d.scale(-1.0), Cmp::Le),
                        CmpOp::Gt => Bf::Atom(d.scale(-1.0), Cmp::Lt),
                        CmpOp::Eq => Bf::Atom(d, Cmp::Eq),
                    });
                }
                Val::Bool(if atoms.len() == 1 { atoms.pop().unwrap() } else { Bf::And(atoms) })
            }
        })
    }

    /// Evaluate a formula.
    pub(crate) fn formula(&mut self, e: &Expr) -> Result<FormulaRef, SpecError> {
        let v = self.eval(e)?;
        Ok(FormulaRef(self.as_bool(v, e.span())?))
    }

    /// Evaluate a linear objective.
    pub(crate) fn objective(&mut self, e: &Expr) -> Result<LinExpr, SpecError> {
        let v = self.eval(e)?;
        let p = self.as_num(v, e.span())?;
        if !p.maxes.is_empty() {
            return Err(self
                .err(e.span(), "the objective must be linear")
                .help("for the largest |e| ask `sup e` and `inf e` separately"));
        }
        Ok(p.lin)
    }

    /// The applications created so far and the tie constraints.
    pub(crate) fn finish(self) -> (Vec<Application>, Vec<Constraint>) {
        (self.apps, self.ties)
    }
}

/// An evaluated formula (opaque).
pub(crate) struct FormulaRef(Bf);

impl FormulaRef {
    /// The negation.
    pub(crate) fn negate(self) -> FormulaRef {
        FormulaRef(self.0.negate())
    }
    /// Disjunctive normal form, conjoined with `extra` in every disjunct.
    pub(crate) fn dnf(self, extra: &[Constraint], file: &str) -> Result<Vec<Vec<Constraint>>, SpecError> {
        let lin = expand(self.0);
        let mut out = dnf(&lin, file)?;
        for d in &mut out {
            let mut v = extra.to_vec();
            v.append(d);
            *d = v;
        }
        Ok(out
            .into_iter()
            .filter_map(|d| simplify(d))
            .collect())
    }
}

/// Expand piecewise-linear atoms into linear ones (see the module doc).
fn expand(f: Bf) -> Bf {
    match f {
        Bf::Const(b) => Bf::Const(b),
        Bf::And(v) => Bf::And(v.into_iter().map(expand).collect()),
        Bf::Or(v) => Bf::Or(v.into_iter().map(expand).collect()),
        Bf::Atom(e, Cmp::Eq) if !e.maxes.is_empty() => Bf::And(vec![
            expand(Bf::Atom(e.clone(), Cmp::Le)),
            expand(Bf::Atom(e.scale(-1.0), Cmp::Le)),
        ]),
        Bf::Atom(mut e, cmp) => {
            if e.maxes.is_empty() {
                return Bf::Atom(e, cmp);
            }
            let (w, forms) = e.maxes.remove(0);
            let branches: Vec<Bf> = forms
                .into_iter()
                .map(|f| {
                    let mut b = e.clone();
                    b.lin = LinExpr {
                        terms: b.lin.terms.into_iter().chain(f.terms.into_iter().map(|(v, c)| (v, c * w))).collect(),
                        constant: b.lin.constant + w * f.constant,
                    }
                    .normalised();
                    expand(Bf::Atom(b, cmp))
                })
                .collect();
            if w > 0.0 {
                Bf::And(branches)
            } else {
                Bf::Or(branches)
            }
        }
    }
}

fn dnf(f: &Bf, file: &str) -> Result<Vec<Vec<Constraint>>, SpecError> {
    Ok(match f {
        Bf::Const(true) => vec![vec![]],
        Bf::Const(false) => vec![],
        Bf::Atom(e, c) => vec![vec![Constraint {
            expr: e.lin.clone().normalised(),
            cmp: *c,
        }]],
        Bf::Or(v) => {
            let mut out = Vec::new();
            for x in v {
                out.extend(dnf(x, file)?);
                if out.len() > MAX_DISJUNCTS {
                    return Err(too_big(file));
                }
            }
            out
        }
        Bf::And(v) => {
            let mut acc: Vec<Vec<Constraint>> = vec![vec![]];
            for x in v {
                let d: Vec<Vec<Constraint>> = dnf(x, file)?.into_iter().filter_map(simplify).collect();
                if acc.len().saturating_mul(d.len()) > MAX_DISJUNCTS {
                    return Err(too_big(file));
                }
                let mut next = Vec::with_capacity(acc.len() * d.len());
                for a in &acc {
                    for b in &d {
                        let mut c = a.clone();
                        c.extend(b.iter().cloned());
                        next.push(c);
                    }
                }
                acc = next;
            }
            acc
        }
    })
}

fn too_big(file: &str) -> SpecError {
    SpecError::plain(file, format!("the query has more than {MAX_DISJUNCTS} disjuncts"))
        .help("split the property, or avoid absolute values and norms on the concave side of comparisons")
}

/// Drop constant-true constraints and duplicates; `None` if a constraint is constant-false.
fn simplify(d: Vec<Constraint>) -> Option<Vec<Constraint>> {
    let mut out: Vec<Constraint> = Vec::with_capacity(d.len());
    for c in d {
        if c.expr.terms.is_empty() {
            let k = c.expr.constant;
            let ok = match c.cmp {
                Cmp::Le => k <= 0.0,
                Cmp::Lt => k < 0.0,
                Cmp::Eq => k == 0.0,
            };
            if ok {
                continue;
            }
            return None;
        }
        if !out.contains(&c) {
            out.push(c);
        }
    }
    Some(out)
}

pub(crate) fn data_index(ctx: &Ctx<'_>, d: &Name) -> Result<usize, SpecError> {
    ctx.data.iter().position(|x| x.name == d.text).ok_or_else(|| {
        let mut e = SpecError::at(ctx.file, ctx.src, d.span, format!("unknown data set `{}`", d.text))
            .expected("a declared data set");
        if let Some(s) = nearest(&d.text, ctx.data.iter().map(|x| x.name.as_str())) {
            e = e.help(format!("did you mean `{s}`?"));
        } else {
            e = e.help(format!("declare it: `data {} = csv \"FILE\" inputs (..);`", d.text));
        }
        e
    })
}

/// Decide the direction of a critical query from the region's monotonicity in the free
/// parameter `Free(0)`: if every constraint has a positive coefficient on it (`.. + c t
/// <= 0`, `c > 0`), the region is closed downwards in `t`, counterexamples exist for
/// every `t` below the supremum, and the property holds above it: the critical value is
/// `sup t` (Max). All negative: `inf t` (Min). Otherwise `None` (not monotone).
pub(crate) fn critical_sense(region: &[Vec<Constraint>]) -> Option<Sense> {
    let mut pos = false;
    let mut neg = false;
    for c in region.iter().flatten() {
        for (v, k) in &c.expr.terms {
            if *v == Var::Free(0) {
                if c.cmp == Cmp::Eq {
                    return None;
                }
                if *k > 0.0 {
                    pos = true
                } else {
                    neg = true
                }
            }
        }
    }
    match (pos, neg) {
        (true, false) => Some(Sense::Max),
        (false, true) => Some(Sense::Min),
        _ => None,
    }
}

/// Lower one instance of a property.
pub(crate) fn lower_instance(
    ctx: &Ctx<'_>,
    prop: &PropertyDecl,
    key: &InstanceKey,
    mode: ParamMode,
    name: String,
) -> Result<(Query, Option<(usize, Vec<f64>, f64)>), SpecError> {
    let mut l = Lowering::new(ctx, mode, prop.normalised);
    l.bind(prop, key)?;
    let (region_f, goal_obj) = match &prop.body {
        Body::Holds(f) => (l.formula(f)?.negate(), None),
        Body::Optimise { sup, objective, region } => {
            let f = l.formula(region)?;
            let o = l.objective(objective)?;
            (f, Some((o, *sup)))
        }
    };
    let ball = l.ball.clone();
    let (apps, ties) = l.finish();
    let region = region_f.dnf(&ties, ctx.file)?;
    let mut free_vars = Vec::new();
    let goal = match (goal_obj, mode) {
        (Some((o, sup)), _) => Goal::Optimise {
            objective: o.normalised(),
            sense: if sup { Sense::Max } else { Sense::Min },
            label: prop.name.text.clone(),
        },
        (None, ParamMode::Lower { free: Some(pi) }) => {
            let p = &ctx.params[pi];
            free_vars.push((p.name.clone(), p.bounds.0, p.bounds.1));
            let sense = critical_sense(&region).ok_or_else(|| {
                SpecError::at(ctx.file, ctx.src, prop.name.span, format!(
                    "property `{}` is not monotone in `{}`, so it has no critical value",
                    prop.name.text, p.name))
                .help("a critical value needs the parameter on one side of comparisons only, with the same sign; bind it with --param and ask `prove` instead")
            })?;
            Goal::Optimise {
                objective: LinExpr {
                    terms: vec![(Var::Free(0), 1.0)],
                    constant: 0.0,
                },
                sense,
                label: p.name.clone(),
            }
        }
        _ => Goal::Prove,
    };
    if let Goal::Optimise { objective, .. } = &goal {
        if objective.terms.iter().any(|(v, _)| matches!(v, Var::Free(_))) && free_vars.is_empty() {
            unreachable!("free variables only come from critical parameters");
        }
    }
    Ok((
        Query {
            name,
            applications: apps,
            free_vars,
            region,
            goal,
        },
        ball,
    ))
}

/// The instance keys of a property (cartesian product of its data and value binders).
pub(crate) fn instance_space(
    ctx: &Ctx<'_>,
    prop: &PropertyDecl,
) -> Result<Vec<InstanceDim>, SpecError> {
    let mut dims = Vec::new();
    for b in &prop.binders {
        match b {
            Binder::Data(_, d) => {
                let di = data_index(ctx, d)?;
                dims.push(InstanceDim::Rows(ctx.data[di].table.rows));
            }
            Binder::Values(v, vals) => {
                let mut l = Lowering::new(ctx, ParamMode::Lower { free: None }, prop.normalised);
                let mut out = Vec::new();
                for e in vals {
                    out.push(l.const_scalar(e)?);
                }
                dims.push(InstanceDim::Values(v.text.clone(), out));
            }
            Binder::Point(..) => {}
        }
    }
    Ok(dims)
}

/// One axis of a property's instance space.
#[derive(Clone, Debug, PartialEq)]
pub enum InstanceDim {
    /// Rows of a data set.
    Rows(usize),
    /// Named values.
    Values(String, Vec<f64>),
}

/// Units of a network declaration, resolved (constants file read).
pub(crate) fn resolve_units(
    file: &str,
    src: &str,
    base: &std::path::Path,
    units: &Units,
    n_in: usize,
    n_out: usize,
    loaded: Option<&samara_nn::Network>,
) -> Result<(bool, Option<Constants>), SpecError> {
    let check = |c: Constants, span: Span| -> Result<Constants, SpecError> {
        if c.in_min.len() != n_in || c.in_range.len() != n_in || c.out_min.len() != n_out || c.out_range.len() != n_out {
            return Err(SpecError::at(file, src, span, format!(
                "dimension mismatch: normalisation constants have {}/{} input and {}/{} output entries, the network declares {n_in} inputs and {n_out} outputs",
                c.in_min.len(), c.in_range.len(), c.out_min.len(), c.out_range.len()))
                .help("give one minimum and one range per input and per output"));
        }
        if c.in_range.iter().chain(c.out_range.iter()).any(|r| *r == 0.0 || !r.is_finite()) {
            return Err(SpecError::at(file, src, span, "a normalisation range is zero or not finite"));
        }
        Ok(c)
    };
    match units {
        Units::Raw => Ok((false, loaded.and_then(constants_of_network))),
        Units::Normalised { in_min, in_range, out_min, out_range } => Ok((
            true,
            Some(check(
                Constants {
                    in_min: in_min.clone(),
                    in_range: in_range.clone(),
                    out_min: out_min.clone(),
                    out_range: out_range.clone(),
                },
                Span::default(),
            )?),
        )),
        Units::NormalisedFile(p, span) => {
            let path = base.join(p);
            let t = crate::data::read_csv(&path).map_err(|e| {
                SpecError::at(file, src, *span, format!("cannot read the constants file: {e}"))
                    .help("the path is relative to the spec's folder")
            })?;
            if t.rows < 2 || t.cols != n_in + n_out {
                return Err(SpecError::at(file, src, *span, format!(
                    "constants file has {} rows of {} columns; expected 2 rows (minimum, range) of {} columns",
                    t.rows, t.cols, n_in + n_out)));
            }
            let r0 = t.row(0);
            let r1 = t.row(1);
            Ok((
                true,
                Some(check(
                    Constants {
                        in_min: r0[..n_in].to_vec(),
                        in_range: r1[..n_in].to_vec(),
                        out_min: r0[n_in..].to_vec(),
                        out_range: r1[n_in..].to_vec(),
                    },
                    *span,
                )?),
            ))
        }
    }
}

/// Constants of a loaded network's diagonal normalisation layers, if it has both.
pub fn constants_of_network(net: &samara_nn::Network) -> Option<Constants> {
    let a = net.input_norm.as_ref()?;
    let d = net.output_denorm.as_ref()?;
    let diag = |x: &samara_nn::Affine| -> Option<Vec<(f64, f64)>> {
        if x.inp != x.out {
            return None;
        }
        (0..x.out)
            .map(|i| {
                (0..x.inp)
                    .all(|j| i == j || x.weight(i, j) == 0.0)
                    .then(|| (x.weight(i, i), x.b[i]))
            })
            .collect()
    };
    let (a, d) = (diag(a)?, diag(d)?);
    if a.iter().any(|(w, _)| *w == 0.0) {
        return None;
    }
    // n = w raw + b  =>  raw = -b/w + (1/w) n ;  raw_out = w n + b.
    Some(Constants {
        in_min: a.iter().map(|(w, b)| -b / w).collect(),
        in_range: a.iter().map(|(w, _)| 1.0 / w).collect(),
        out_min: d.iter().map(|(_, b)| *b).collect(),
        out_range: d.iter().map(|(w, _)| *w).collect(),
    })
}

/// Map of parameter values given on the command line.
pub type ParamValues = BTreeMap<String, f64>;
