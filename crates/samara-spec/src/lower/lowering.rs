//! Lowering a checked property to query instances: points, data rows, parameters and
//! expressions to piecewise-linear cases.

use super::decl::{Bindings, PropertyDecl, Spec};
use super::linear::{product, Cases, Lin, Sym};
use super::suggest::nearest;
use crate::normal::{Application, Cmp, Constraint, Goal, LinExpr, Query, Sense, Var};
use crate::syntax::{Binder, Expr, Pos, SpecError};
use samara_nn::data::{read_table, Table};
use std::collections::HashMap;

/// The most cases (conjunctions) the counterexample region of one property may have;
/// a property that would expand to more is refused before anything is expanded.
pub const MAX_CASES: u64 = 4096;

/// The most terms (cases times the terms of one case, an upper bound counted before
/// expanding) the counterexample region of one property may hold.
pub const MAX_TERMS: u64 = 1 << 25;

#[derive(Clone, Debug)]
pub(super) enum PointKind {
    Implicit,
    Data(Vec<f64>),
    Ball(usize, f64),
}

#[derive(Clone, Debug)]
pub(super) struct PointInfo {
    pub(super) name: String,
    pub(super) net: usize,
    pub(super) kind: PointKind,
}

/// A lowered property instance.
#[derive(Clone, Debug, PartialEq)]
pub struct Instance {
    /// Label, e.g. `p5[17]` for the data row 17.
    pub label: String,
    /// The query.
    pub query: Query,
}

pub(super) struct Lowering<'a> {
    pub(super) spec: &'a Spec,
    pub(super) b: &'a Bindings,
    pub(super) points: Vec<PointInfo>,
    pub(super) critical: Option<String>,
    pub(super) check_only: bool,
    /// Data tables by dataset name.
    pub(super) tables: HashMap<String, Table>,
    pub(super) row_of: HashMap<String, (String, usize)>,
    pub(super) extra: Vec<(Lin, Cmp)>,
}

impl Spec {
    pub(super) fn check_property(&self, p: &PropertyDecl) -> Result<(), SpecError> {
        let b = Bindings::default();
        let mut l = Lowering {
            spec: self,
            b: &b,
            points: vec![],
            critical: None,
            check_only: true,
            tables: HashMap::new(),
            row_of: HashMap::new(),
            extra: vec![],
        };
        l.instance(p, None).map(|_| ())
    }

    /// Property names.
    pub fn property_names(&self) -> Vec<&str> {
        self.properties.iter().map(|p| p.name.as_str()).collect()
    }

    pub(super) fn property(&self, name: &str) -> Result<&PropertyDecl, SpecError> {
        self.properties
            .iter()
            .find(|p| p.name == name)
            .ok_or_else(|| {
                let hint = nearest(name, self.properties.iter().map(|p| p.name.as_str()))
                    .map(|s| format!("did you mean `{s}`?"))
                    .unwrap_or_else(|| format!("properties: {}", self.property_names().join(", ")));
                // A name from the command line: no position in the file (not printed).
                self.error(Pos::default(), format!("no property named `{name}`"), hint)
            })
    }

    /// Lower a property to `Prove` queries (one per data-set instance), every parameter
    /// bound.
    pub fn lower_prove(&self, name: &str, b: &Bindings) -> Result<Vec<Instance>, SpecError> {
        let p = self.property(name)?;
        self.lower(p, b, None)
    }

    /// Lower a property to critical-value queries over the parameter `param` (a free
    /// variable within its declared range): the supremum (`Max`) of the parameter over
    /// the counterexample region; flip the sense for the infimum.
    pub fn lower_critical(
        &self,
        name: &str,
        param: &str,
        b: &Bindings,
    ) -> Result<Vec<Instance>, SpecError> {
        let p = self.property(name)?;
        let Some(decl) = self.params.get(param) else {
            let hint = nearest(param, self.params.keys().map(String::as_str))
                .map(|s| format!("did you mean `{s}`?"))
                .unwrap_or_else(|| "declare it: param NAME in [lo, hi]".into());
            return Err(self.error(p.pos, format!("unknown parameter `{param}`"), hint));
        };
        if decl.range.is_none() {
            return Err(self.error(
                p.pos,
                format!("parameter `{param}` has no range"),
                format!(
                    "declare it as `param {param} in [lo, hi]` to search for its critical value"
                ),
            ));
        }
        self.lower(p, b, Some(param.to_string()))
    }

    /// Check bound parameter values against the declared ranges: a value outside
    /// `param NAME in [lo, hi]` is refused (naming the parameter, the range and the
    /// declaration's line), since a property is only meant for the range it declares
    /// (e.g. `ystar` beyond the domain's reach makes every premise empty). Every
    /// lowering calls it; callers may call it early to fail before loading anything else.
    pub fn check_bindings(&self, b: &Bindings) -> Result<(), SpecError> {
        let mut names: Vec<&String> = b.params.keys().collect();
        names.sort();
        for name in names {
            let v = b.params[name];
            let Some(decl) = self.params.get(name) else {
                continue;
            };
            if let Some((lo, hi)) = decl.range {
                if !(lo <= v && v <= hi) {
                    return Err(self.error(
                        decl.pos,
                        format!(
                            "the value {v} bound to parameter `{name}` is outside its declared range [{lo}, {hi}]"
                        ),
                        format!(
                            "pass a value within [{lo}, {hi}] (e.g. --param {name}={}) or widen the range declared here",
                            decl.default.unwrap_or(lo)
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    pub(super) fn lower(
        &self,
        p: &PropertyDecl,
        b: &Bindings,
        critical: Option<String>,
    ) -> Result<Vec<Instance>, SpecError> {
        self.check_bindings(b)?;
        for (name, (ni, no)) in &b.network_dims {
            if let Some(n) = self.networks.iter().find(|n| n.name == *name) {
                if n.inputs.len() != *ni || n.outputs.len() != *no {
                    return Err(self.error(
                        n.pos,
                        format!("dimension mismatch: network `{name}` is declared with {} inputs and {} outputs but the file has {ni} and {no}", n.inputs.len(), n.outputs.len()),
                        "fix the declaration or pass the right --network file",
                    ));
                }
            }
        }
        // Domains taken from data sets.
        let mut resolved;
        let mut spec = self;
        if !self.pending_domains.is_empty() {
            resolved = self.clone();
            let mut tl = Lowering {
                spec: self,
                b,
                points: vec![],
                critical: None,
                check_only: false,
                tables: HashMap::new(),
                row_of: HashMap::new(),
                extra: vec![],
            };
            for (net, ds, pos) in &self.pending_domains {
                let t = tl.table(ds, *pos)?;
                let k = self.net_index(net, *pos)?;
                let n = self.networks[k].inputs.len();
                if t.cols < n {
                    return Err(self.error(*pos, format!("dimension mismatch: data set `{ds}` has {} columns but `{net}` has {n} inputs", t.cols), "use a data set whose first columns are the network's inputs"));
                }
                for j in 0..n {
                    let col = (0..t.rows()).map(|r| t.row(r)[j]);
                    if col.clone().any(|v| !v.is_finite()) || t.rows() == 0 {
                        return Err(self.error(
                            *pos,
                            format!("data set `{ds}`: column {} is empty or holds a value that is not a finite number", j + 1),
                            "give the domain's data set finite values",
                        ));
                    }
                    let lo = col.clone().fold(f64::INFINITY, f64::min);
                    let hi = col.fold(f64::NEG_INFINITY, f64::max);
                    resolved.networks[k].domain[j] = (lo, hi);
                }
            }
            resolved.pending_domains.clear();
            spec = &resolved;
        }
        let mut l = Lowering {
            spec,
            b,
            points: vec![],
            critical,
            check_only: false,
            tables: HashMap::new(),
            row_of: HashMap::new(),
            extra: vec![],
        };
        // Data binders: iterate over rows (only one data binder is supported).
        let data: Vec<&Binder> = p
            .binders
            .iter()
            .filter(|x| matches!(x, Binder::Data { .. }))
            .collect();
        if data.len() > 1 {
            return Err(self.error(
                p.pos,
                "at most one `for p in data` binder per property",
                "split the property",
            ));
        }
        match data.first() {
            None => Ok(vec![l.instance(p, None)?]),
            Some(Binder::Data { dataset, pos, .. }) => {
                let t = l.table(dataset, *pos)?;
                let n = t.rows();
                let mut out = Vec::with_capacity(n);
                for r in 0..n {
                    out.push(l.instance(p, Some(r))?);
                }
                Ok(out)
            }
            _ => unreachable!("filtered"),
        }
    }
}

impl Lowering<'_> {
    pub(super) fn err(&self, pos: Pos, m: impl Into<String>, h: impl Into<String>) -> SpecError {
        self.spec.error(pos, m, h)
    }

    pub(super) fn table(&mut self, name: &str, pos: Pos) -> Result<Table, SpecError> {
        if let Some(t) = self.tables.get(name) {
            return Ok(t.clone());
        }
        let path = match self.b.datasets.get(name) {
            Some(p) => p.clone(),
            None => match self.spec.datasets.get(name) {
                Some(p) if p.is_absolute() => p.clone(),
                Some(p) => self.spec.dir.join(p),
                None => {
                    return Err(self.err(
                        pos,
                        format!("unknown data set `{name}`"),
                        format!(
                        "declare it: dataset {name} = \"file.csv\", or pass --dataset {name}=FILE"
                    ),
                    ))
                }
            },
        };
        let mut t = read_table(&path).map_err(|e| {
            self.err(
                pos,
                format!("data set `{name}`: {e}"),
                format!("pass --dataset {name}=FILE"),
            )
        })?;
        if self.spec.normalised_datasets.iter().any(|d| d == name) {
            // Rows in network units: back to raw (inputs, then outputs).
            let nd = &self.spec.networks[0];
            let (ni, no) = (nd.inputs.len(), nd.outputs.len());
            let cols = t.cols;
            for r in 0..t.rows() {
                for j in 0..cols.min(ni + no) {
                    let (c, s) = if j < ni {
                        nd.input_map(j)
                    } else {
                        nd.output_map(j - ni)
                    };
                    t.values[r * cols + j] = c + s * t.values[r * cols + j];
                }
            }
        }
        self.tables.insert(name.into(), t.clone());
        Ok(t)
    }

    /// Raw value of column `col` (input or output name of `net`) in a data row.
    pub(super) fn data_column(
        &self,
        net: usize,
        t_names: &[String],
        row: &[f64],
        col: &str,
    ) -> Option<f64> {
        let n = &self.spec.networks[net];
        if let Some(j) = t_names.iter().position(|c| c == col) {
            return row.get(j).copied();
        }
        let j = n.inputs.iter().position(|c| c == col).or_else(|| {
            n.outputs
                .iter()
                .position(|c| c == col)
                .map(|k| n.inputs.len() + k)
        })?;
        row.get(j).copied()
    }

    pub(super) fn point(&self, name: &str) -> Option<usize> {
        self.points.iter().position(|p| p.name == name)
    }

    pub(super) fn implicit(&mut self) -> usize {
        if let Some(i) = self
            .points
            .iter()
            .position(|p| matches!(p.kind, PointKind::Implicit))
        {
            return i;
        }
        self.points.push(PointInfo {
            name: "<x>".into(),
            net: 0,
            kind: PointKind::Implicit,
        });
        self.points.len() - 1
    }

    pub(super) fn instance(
        &mut self,
        p: &PropertyDecl,
        row: Option<usize>,
    ) -> Result<Instance, SpecError> {
        self.points.clear();
        self.extra.clear();
        self.row_of.clear();
        for bnd in &p.binders {
            match bnd {
                Binder::Data {
                    point,
                    dataset,
                    pos,
                } => {
                    let net = 0;
                    let values = if self.check_only {
                        vec![
                            0.0;
                            self.spec.networks[net].inputs.len()
                                + self.spec.networks[net].outputs.len()
                        ]
                    } else {
                        let t = self.table(dataset, *pos)?;
                        let r = row.unwrap_or(0);
                        let n = self.spec.networks[net].inputs.len();
                        if t.cols < n || r >= t.rows() {
                            return Err(self.err(
                                *pos,
                                format!(
                                    "dimension mismatch: data set `{dataset}` has {} columns but `{}` has {n} inputs",
                                    t.cols, self.spec.networks[net].name
                                ),
                                "use a data set whose first columns are the network's inputs",
                            ));
                        }
                        let v = t.row(r).to_vec();
                        if let Some(j) = v.iter().position(|x| !x.is_finite()) {
                            return Err(self.err(
                                *pos,
                                format!(
                                    "data set `{dataset}`, row {}, column {}: {} is not a finite number",
                                    r + 1,
                                    j + 1,
                                    v[j]
                                ),
                                "remove or fix the row",
                            ));
                        }
                        v
                    };
                    self.row_of
                        .insert(point.clone(), (dataset.clone(), row.unwrap_or(0)));
                    self.points.push(PointInfo {
                        name: point.clone(),
                        net,
                        kind: PointKind::Data(values),
                    });
                }
                Binder::Ball {
                    point,
                    centre,
                    radius,
                    pos,
                } => {
                    let Some(c) = self.point(centre) else {
                        return Err(self.err(
                            *pos,
                            format!("unknown point `{centre}`"),
                            "bind it first: for q in data NAME, for p in ball(q, eps)",
                        ));
                    };
                    let r = self.constant(radius, *pos)?;
                    if !(r >= 0.0 && r.is_finite()) {
                        return Err(self.err(
                            *pos,
                            format!("radius {r} is not a finite number >= 0"),
                            "use a finite radius >= 0",
                        ));
                    }
                    let net = self.points[c].net;
                    self.points.push(PointInfo {
                        name: point.clone(),
                        net,
                        kind: PointKind::Ball(c, r),
                    });
                    if !matches!(self.points[c].kind, PointKind::Data(_)) {
                        // |z_p - z_c|_inf <= r as linear constraints.
                        let pi = self.points.len() - 1;
                        for k in 0..self.spec.networks[net].inputs.len() {
                            let d = self.net_input(pi, k).sub(&self.net_input(c, k));
                            self.extra.push((d.clone().sub(&Lin::constant(r)), Cmp::Le));
                            self.extra
                                .push((d.scale(-1.0).sub(&Lin::constant(r)), Cmp::Le));
                        }
                    }
                }
            }
        }
        // Counterexample region: not P, in negation normal form, then DNF.
        let nnf = self.nnf(&p.formula, true)?;
        self.check_size(p, &nnf)?;
        let mut dnf = self.dnf(&nnf, p.pos)?;
        // Ball constraints between variable points, and constant-centre balls as boxes.
        for c in &mut dnf {
            c.extend(self.extra.iter().cloned());
        }
        // Applications: one per referenced non-data point.
        let mut app_of: HashMap<usize, usize> = HashMap::new();
        let mut used: Vec<usize> = dnf
            .iter()
            .flatten()
            .flat_map(|(l, _)| {
                l.terms.iter().filter_map(|(s, _)| match s {
                    Sym::In(p, _) | Sym::Out(p, _) => Some(*p),
                    Sym::Free(_) => None,
                })
            })
            .collect();
        used.sort();
        used.dedup();
        let mut apps = Vec::new();
        for pidx in used {
            let pt = &self.points[pidx];
            let nd = &self.spec.networks[pt.net];
            let dom = nd.network_box();
            let input_box = match &pt.kind {
                PointKind::Implicit => dom,
                PointKind::Data(v) => (0..nd.inputs.len())
                    .map(|k| {
                        let (c, s) = nd.input_map(k);
                        let z = (v[k] - c) / s;
                        (z, z)
                    })
                    .collect(),
                PointKind::Ball(centre, r) => match &self.points[*centre].kind {
                    PointKind::Data(v) => (0..nd.inputs.len())
                        .map(|k| {
                            let (c, s) = nd.input_map(k);
                            let z = (v[k] - c) / s;
                            ((z - r).max(dom[k].0), (z + r).min(dom[k].1))
                        })
                        .collect(),
                    _ => dom,
                },
            };
            app_of.insert(pidx, apps.len());
            apps.push(Application {
                network: nd.name.clone(),
                n_inputs: nd.inputs.len(),
                n_outputs: nd.outputs.len(),
                input_box,
            });
        }
        let to_var = |s: Sym| match s {
            Sym::In(p, k) => Var::Input {
                app: app_of[&p],
                index: k,
            },
            Sym::Out(p, k) => Var::Output {
                app: app_of[&p],
                index: k,
            },
            Sym::Free(k) => Var::Free(k),
        };
        let region: Vec<Vec<Constraint>> = dnf
            .into_iter()
            .map(|conj| {
                conj.into_iter()
                    .map(|(l, cmp)| Constraint {
                        expr: LinExpr {
                            terms: l.terms.into_iter().map(|(s, a)| (to_var(s), a)).collect(),
                            constant: l.c,
                        }
                        .normalised(),
                        cmp,
                    })
                    .collect()
            })
            .collect();
        if region
            .iter()
            .flatten()
            .any(|c| !c.expr.constant.is_finite() || c.expr.terms.iter().any(|t| !t.1.is_finite()))
        {
            return Err(self.err(
                p.pos,
                format!(
                    "property `{}`: a coefficient overflows (is not a finite number) once the normalisation is composed in",
                    p.name
                ),
                "use smaller constants (e.g. no 1e300 * 1e300) and non-tiny normalisation ranges",
            ));
        }
        let (free_vars, goal) = match &self.critical {
            Some(pname) => {
                let (lo, hi) = self.spec.params[pname].range.expect("checked");
                (
                    vec![(pname.clone(), lo, hi)],
                    Goal::Optimise {
                        objective: LinExpr {
                            terms: vec![(Var::Free(0), 1.0)],
                            constant: 0.0,
                        },
                        sense: Sense::Max,
                        label: pname.clone(),
                    },
                )
            }
            None => (vec![], Goal::Prove),
        };
        let label = match row {
            Some(r) => format!("{}[{r}]", p.name),
            None => p.name.clone(),
        };
        Ok(Instance {
            label: label.clone(),
            query: Query {
                name: label,
                applications: apps,
                free_vars,
                region,
                goal,
            },
        })
    }

    pub(super) fn constant(&mut self, e: &Expr, pos: Pos) -> Result<f64, SpecError> {
        // More than one case is never a constant: refuse before expanding them.
        let cases = if self.expr_cases(e) > 1 {
            vec![]
        } else {
            self.expr(e)?
        };
        match cases.as_slice() {
            [(conds, v)] if conds.is_empty() && v.is_const() => Ok(v.c),
            _ => Err(self.err(
                pos,
                "expected a constant",
                "use numbers and bound parameters here",
            )),
        }
    }

    pub(super) fn param(&self, name: &str, pos: Pos) -> Result<Lin, SpecError> {
        if self.critical.as_deref() == Some(name) {
            return Ok(Lin::sym(Sym::Free(0), 1.0, 0.0));
        }
        if let Some(v) = self.b.params.get(name) {
            return Ok(Lin::constant(*v));
        }
        let decl = &self.spec.params[name];
        match decl.default {
            Some(v) => Ok(Lin::constant(v)),
            None if self.check_only => Ok(Lin::constant(1.0)),
            None => Err(self.err(
                pos,
                format!("parameter `{name}` is not bound"),
                format!("pass --param {name}=VALUE or give it a default: param {name} = VALUE"),
            )),
        }
    }

    pub(super) fn unknown_name(&self, name: &str, pos: Pos) -> SpecError {
        let n = &self.spec.networks[0];
        let cands: Vec<&str> = n
            .inputs
            .iter()
            .chain(&n.outputs)
            .map(String::as_str)
            .chain(self.spec.params.keys().map(String::as_str))
            .chain(self.points.iter().map(|p| p.name.as_str()))
            .collect();
        let hint = nearest(name, cands.iter().copied())
            .map(|s| format!("did you mean `{s}`?"))
            .unwrap_or_else(|| format!("known names: {}", cands.join(", ")));
        self.err(pos, format!("unknown name `{name}`"), hint)
    }

    /// Raw input `k` of point `p`.
    pub(super) fn raw_input(&mut self, p: usize, k: usize) -> Lin {
        let nd = &self.spec.networks[self.points[p].net];
        let (c, s) = nd.input_map(k);
        match &self.points[p].kind {
            PointKind::Data(v) => Lin::constant(v[k]),
            _ => Lin::sym(Sym::In(p, k), s, c),
        }
    }

    /// Network-unit input `k` of point `p`.
    pub(super) fn net_input(&self, p: usize, k: usize) -> Lin {
        let nd = &self.spec.networks[self.points[p].net];
        let (c, s) = nd.input_map(k);
        match &self.points[p].kind {
            PointKind::Data(v) => Lin::constant((v[k] - c) / s),
            _ => Lin::sym(Sym::In(p, k), 1.0, 0.0),
        }
    }

    pub(super) fn raw_output(&mut self, p: usize, k: usize) -> Lin {
        let nd = &self.spec.networks[self.points[p].net];
        let (c, s) = nd.output_map(k);
        Lin::sym(Sym::Out(p, k), s, c)
    }

    pub(super) fn expr(&mut self, e: &Expr) -> Result<Cases, SpecError> {
        let single = |l: Lin| vec![(vec![], l)];
        Ok(match e {
            Expr::Num(v) => single(Lin::constant(*v)),
            Expr::Name(None, name, pos) => {
                let n = &self.spec.networks[0];
                if let Some(k) = n.inputs.iter().position(|i| i == name) {
                    let p = self.implicit();
                    single(self.raw_input(p, k))
                } else if let Some(k) = n.outputs.iter().position(|i| i == name) {
                    let p = self.implicit();
                    single(self.raw_output(p, k))
                } else if self.spec.params.contains_key(name) {
                    single(self.param(name, *pos)?)
                } else {
                    return Err(self.unknown_name(name, *pos));
                }
            }
            Expr::Name(Some(pt), comp, pos) => {
                let Some(p) = self.point(pt) else {
                    return Err(self.unknown_name(pt, *pos));
                };
                let nd = &self.spec.networks[self.points[p].net];
                if let Some(k) = nd.inputs.iter().position(|i| i == comp) {
                    single(self.raw_input(p, k))
                } else if let Some(k) = nd.outputs.iter().position(|i| i == comp) {
                    match &self.points[p].kind {
                        PointKind::Data(v) => {
                            if self.check_only {
                                single(Lin::constant(0.0))
                            } else {
                                let (ds, _) = self.row_of[pt].clone();
                                let names = self
                                    .tables
                                    .get(&ds)
                                    .map(|t| t.names.clone())
                                    .unwrap_or_default();
                                let val = self
                                    .data_column(self.points[p].net, &names, v, comp)
                                    .ok_or_else(|| {
                                        self.err(
                                            *pos,
                                            format!("data set `{ds}` has no column `{comp}`"),
                                            "add the label column to the data set",
                                        )
                                    })?;
                                let _ = k;
                                single(Lin::constant(val))
                            }
                        }
                        _ => single(self.raw_output(p, k)),
                    }
                } else {
                    let hint = nearest(
                        comp,
                        nd.inputs.iter().chain(&nd.outputs).map(String::as_str),
                    )
                    .map(|s| format!("did you mean `{s}`?"))
                    .unwrap_or_default();
                    return Err(self.err(
                        *pos,
                        format!("`{comp}` is not a component of point `{pt}`"),
                        hint,
                    ));
                }
            }
            Expr::Call(net, pt, out, pos) => {
                let ni = self.spec.net_index(net, *pos)?;
                let Some(p) = self.point(pt) else {
                    return Err(self.unknown_name(pt, *pos));
                };
                if self.points[p].net != ni {
                    return Err(self.err(
                        *pos,
                        format!("point `{pt}` ranges over the inputs of another network"),
                        "apply the network its point was bound for",
                    ));
                }
                let nd = &self.spec.networks[ni];
                let k = match out {
                    None if nd.outputs.len() == 1 => 0,
                    None => {
                        return Err(self.err(
                            *pos,
                            format!(
                                "dimension mismatch: `{net}` has {} outputs",
                                nd.outputs.len()
                            ),
                            format!("pick one: {net}({pt}).NAME"),
                        ))
                    }
                    Some(o) => nd.outputs.iter().position(|x| x == o).ok_or_else(|| {
                        self.err(
                            *pos,
                            format!("`{o}` is not an output of `{net}`"),
                            format!("outputs: {}", nd.outputs.join(", ")),
                        )
                    })?,
                };
                single(self.raw_output(p, k))
            }
            Expr::Sum(terms) => {
                let mut acc: Cases = vec![(vec![], Lin::default())];
                for (minus, t) in terms {
                    let ct = self.expr(t)?;
                    let k = if *minus { -1.0 } else { 1.0 };
                    acc = product(acc, &ct, |x, y| x.add_scaled(y, k));
                }
                acc
            }
            Expr::Neg(a) => self
                .expr(a)?
                .into_iter()
                .map(|(c, v)| (c, v.scale(-1.0)))
                .collect(),
            Expr::Prod(first, rest) => {
                let mut acc = self.expr(first)?;
                for (div, f, pos) in rest {
                    let cf = self.expr(f)?;
                    if *div {
                        let d = match cf.as_slice() {
                            [(c, v)] if c.is_empty() && v.is_const() => v.c,
                            _ => {
                                return Err(self.err(
                                    *pos,
                                    "nonlinear term: division by a variable",
                                    "divide by constants or bound parameters only",
                                ))
                            }
                        };
                        if d == 0.0 {
                            return Err(self.err(
                                *pos,
                                "division by zero",
                                "check the divisor (a parameter bound to 0?)",
                            ));
                        }
                        acc = acc
                            .into_iter()
                            .map(|(c, v)| (c, v.scale(1.0 / d)))
                            .collect();
                    } else {
                        let mut out = Vec::with_capacity(acc.len() * cf.len());
                        for (c1, v1) in &acc {
                            for (c2, v2) in &cf {
                                let v = if v1.is_const() {
                                    v2.clone().scale(v1.c)
                                } else if v2.is_const() {
                                    v1.clone().scale(v2.c)
                                } else {
                                    return Err(self.err(*pos, "nonlinear term: both factors depend on variables", "properties must be linear; multiply by constants or bound parameters only"));
                                };
                                out.push((c1.iter().chain(c2).cloned().collect(), v));
                            }
                        }
                        acc = out;
                    }
                }
                acc
            }
            Expr::Abs(a) => {
                let mut out = Vec::new();
                for (c, v) in self.expr(a)? {
                    let mut c1 = c.clone();
                    c1.push((v.clone().scale(-1.0), Cmp::Le)); // v >= 0
                    out.push((c1, v.clone()));
                    let mut c2 = c;
                    c2.push((v.clone(), Cmp::Le)); // v <= 0
                    out.push((c2, v.scale(-1.0)));
                }
                out
            }
            Expr::Norm(a, b, pos) => {
                let (Some(pa), Some(pb)) = (self.point(a), self.point(b)) else {
                    return Err(
                        self.unknown_name(if self.point(a).is_none() { a } else { b }, *pos)
                    );
                };
                if self.points[pa].net != self.points[pb].net {
                    return Err(self.err(
                        *pos,
                        "dimension mismatch: norm of points of different networks",
                        "compare points of the same network",
                    ));
                }
                let n = self.spec.networks[self.points[pa].net].inputs.len();
                let d: Vec<Lin> = (0..n)
                    .map(|k| self.net_input(pa, k).sub(&self.net_input(pb, k)))
                    .collect();
                let mut out = Vec::new();
                for k in 0..n {
                    for s in [1.0, -1.0] {
                        let v = d[k].clone().scale(s);
                        let mut conds = Vec::new();
                        for dj in &d {
                            conds.push((dj.clone().sub(&v), Cmp::Le)); // d_j <= v
                            conds.push((dj.clone().scale(-1.0).sub(&v), Cmp::Le));
                            // -d_j <= v
                        }
                        out.push((conds, v));
                    }
                }
                out
            }
        })
    }

    pub(super) fn combine(
        &mut self,
        a: &Expr,
        b: &Expr,
        f: impl Fn(Lin, &Lin) -> Lin,
    ) -> Result<Cases, SpecError> {
        let (ca, cb) = (self.expr(a)?, self.expr(b)?);
        Ok(product(ca, &cb, f))
    }
}
