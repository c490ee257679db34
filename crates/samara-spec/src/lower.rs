//! Checking and lowering: from the syntax tree to queries in the linear normal form.
//!
//! A property `P` becomes its counterexample region `domain and not P`: negation normal
//! form, then atoms with `|e|` and `norm(p - q)` expanded by exact case splits
//! (`phi(|u|) = (u >= 0 and phi(u)) or (u <= 0 and phi(-u))`;
//! `phi(max_k a_k) = or_k (and_j a_k >= a_j and phi(a_k))`), then a disjunctive normal
//! form. Raw-unit names are rewritten through the network's normalisation
//! (`raw = C + S z`, `out_raw = offset + scale out`), so the normal form speaks the
//! units of the network files.

use crate::normal::{Application, Cmp, Constraint, Goal, LinExpr, Query, Sense, Var};
use crate::syntax::{parse, Binder, Expr, Formula, Pos, Rel, SpecError, Stmt};
use samara_nn::data::{read_table, Table};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A network's signature and units as the spec sees it.
#[derive(Clone, Debug, PartialEq)]
pub struct NetDecl {
    /// Name.
    pub name: String,
    /// Input names.
    pub inputs: Vec<String>,
    /// Output names.
    pub outputs: Vec<String>,
    /// Input normalisation (C, S) if the network file takes normalised inputs.
    pub in_norm: Option<(Vec<f64>, Vec<f64>)>,
    /// Output denormalisation (offset, scale) if the file gives normalised outputs.
    pub out_norm: Option<(Vec<f64>, Vec<f64>)>,
    /// Raw-unit domain box (may be infinite).
    pub domain: Vec<(f64, f64)>,
    /// Where it was declared.
    pub pos: Pos,
}

impl NetDecl {
    /// Raw input k as `(C_k, S_k)`: raw = C + S z.
    pub fn input_map(&self, k: usize) -> (f64, f64) {
        self.in_norm
            .as_ref()
            .map(|(c, s)| (c[k], s[k]))
            .unwrap_or((0.0, 1.0))
    }

    /// Raw output k as `(offset, scale)`.
    pub fn output_map(&self, k: usize) -> (f64, f64) {
        self.out_norm
            .as_ref()
            .map(|(c, s)| (c[k], s[k]))
            .unwrap_or((0.0, 1.0))
    }

    /// The domain box in network units.
    pub fn network_box(&self) -> Vec<(f64, f64)> {
        self.domain
            .iter()
            .enumerate()
            .map(|(k, (l, h))| {
                let (c, s) = self.input_map(k);
                let (a, b) = ((l - c) / s, (h - c) / s);
                (a.min(b), a.max(b))
            })
            .collect()
    }
}

/// A parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamDecl {
    /// Range for critical queries.
    pub range: Option<(f64, f64)>,
    /// Default value.
    pub default: Option<f64>,
}

/// A property (not yet lowered).
#[derive(Clone, Debug, PartialEq)]
pub struct PropertyDecl {
    /// Name.
    pub name: String,
    /// Binders.
    pub binders: Vec<Binder>,
    /// Formula.
    pub formula: Formula,
    /// Position.
    pub pos: Pos,
}

/// A checked specification.
#[derive(Clone, Debug)]
pub struct Spec {
    /// File name (for messages).
    pub file: String,
    /// Directory of the file (data paths are relative to it).
    pub dir: PathBuf,
    /// Networks in declaration order.
    pub networks: Vec<NetDecl>,
    /// Parameters.
    pub params: HashMap<String, ParamDecl>,
    /// Data sets: name -> path.
    pub datasets: HashMap<String, PathBuf>,
    /// Data sets whose rows are in the first network's (normalised) units.
    pub normalised_datasets: Vec<String>,
    /// Properties in order.
    pub properties: Vec<PropertyDecl>,
    source: String,
    pending_domains: Vec<(String, String, Pos)>,
}

/// Values bound from outside (command line).
#[derive(Clone, Debug, Default)]
pub struct Bindings {
    /// Parameter values.
    pub params: HashMap<String, f64>,
    /// Data set paths overriding the spec's.
    pub datasets: HashMap<String, PathBuf>,
    /// Network signatures from loaded files: name -> (inputs, outputs). Checked against
    /// the declarations.
    pub network_dims: HashMap<String, (usize, usize)>,
}

fn levenshtein(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1];
        for (j, cb) in b.iter().enumerate() {
            cur.push(
                (prev[j] + usize::from(ca != *cb))
                    .min(prev[j + 1] + 1)
                    .min(cur[j] + 1),
            );
        }
        prev = cur;
    }
    prev[b.len()]
}

/// The closest candidate to `name`, for "did you mean" hints.
pub fn nearest<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    candidates
        .into_iter()
        .map(|c| (levenshtein(name, c), c))
        .filter(|(d, c)| *d <= 2.max(c.len() / 3))
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

impl Spec {
    fn error(&self, pos: Pos, message: impl Into<String>, hint: impl Into<String>) -> SpecError {
        SpecError {
            file: self.file.clone(),
            pos,
            message: message.into(),
            hint: hint.into(),
            source_line: self
                .source
                .lines()
                .nth(pos.line.wrapping_sub(1))
                .unwrap_or("")
                .to_string(),
        }
    }

    /// Parse and check a spec file.
    pub fn read(path: &Path) -> Result<Spec, SpecError> {
        let file = path.display().to_string();
        let src = std::fs::read_to_string(path).map_err(|e| SpecError {
            file: file.clone(),
            pos: Pos { line: 0, col: 0 },
            message: format!("cannot read the spec: {e}"),
            hint: "check the path".into(),
            source_line: String::new(),
        })?;
        Spec::parse(&src, &file, path.parent().unwrap_or(Path::new(".")))
    }

    /// Parse and check spec text.
    pub fn parse(src: &str, file: &str, dir: &Path) -> Result<Spec, SpecError> {
        let stmts = parse(src, file)?;
        let mut spec = Spec {
            file: file.into(),
            dir: dir.to_path_buf(),
            networks: Vec::new(),
            params: HashMap::new(),
            datasets: HashMap::new(),
            normalised_datasets: Vec::new(),
            properties: Vec::new(),
            source: src.into(),
            pending_domains: Vec::new(),
        };
        let mut domain_from: Vec<(String, String, Pos)> = Vec::new();
        for st in stmts {
            match st {
                Stmt::Network {
                    name,
                    inputs,
                    outputs,
                    pos,
                } => {
                    if spec.networks.iter().any(|n| n.name == name) {
                        return Err(spec.error(
                            pos,
                            format!("network `{name}` is declared twice"),
                            "rename one of them",
                        ));
                    }
                    let n = inputs.len();
                    spec.networks.push(NetDecl {
                        name,
                        inputs,
                        outputs,
                        in_norm: None,
                        out_norm: None,
                        domain: vec![(f64::NEG_INFINITY, f64::INFINITY); n],
                        pos,
                    });
                }
                Stmt::NormInput {
                    net,
                    min,
                    range,
                    pos,
                } => {
                    let k = spec.net_index(&net, pos)?;
                    let n = spec.networks[k].inputs.len();
                    if min.len() != n || range.len() != n {
                        return Err(spec.error(
                            pos,
                            format!("dimension mismatch: network `{net}` has {n} inputs but min has {} and range {} values", min.len(), range.len()),
                            format!("give {n} values to each"),
                        ));
                    }
                    if range.contains(&0.0) {
                        return Err(spec.error(
                            pos,
                            "a normalisation range is zero",
                            "ranges must be non-zero",
                        ));
                    }
                    spec.networks[k].in_norm = Some((min, range));
                }
                Stmt::NormFile { net, path, pos } => {
                    let k = spec.net_index(&net, pos)?;
                    let full = if Path::new(&path).is_absolute() {
                        PathBuf::from(&path)
                    } else {
                        spec.dir.join(&path)
                    };
                    let t = samara_nn::data::read_csv(&full).map_err(|e| {
                        spec.error(
                            pos,
                            format!("normalisation constants: {e}"),
                            "give a CSV with two rows: minima, then ranges",
                        )
                    })?;
                    let (ni, no) = (
                        spec.networks[k].inputs.len(),
                        spec.networks[k].outputs.len(),
                    );
                    if t.rows() != 2 || t.cols < ni {
                        return Err(spec.error(
                            pos,
                            format!("dimension mismatch: {} has {} rows of {} columns; expected 2 rows (minima, ranges) of at least {ni} columns", full.display(), t.rows(), t.cols),
                            format!("write the {ni} inputs' constants, then the {no} outputs'"),
                        ));
                    }
                    let (min, range) = (t.row(0).to_vec(), t.row(1).to_vec());
                    if range.contains(&0.0) {
                        return Err(spec.error(
                            pos,
                            "a normalisation range is zero",
                            "ranges must be non-zero",
                        ));
                    }
                    spec.networks[k].in_norm = Some((min[..ni].to_vec(), range[..ni].to_vec()));
                    if t.cols >= ni + no {
                        spec.networks[k].out_norm =
                            Some((min[ni..ni + no].to_vec(), range[ni..ni + no].to_vec()));
                    }
                }
                Stmt::NormOutput {
                    net,
                    offset,
                    scale,
                    pos,
                } => {
                    let k = spec.net_index(&net, pos)?;
                    let n = spec.networks[k].outputs.len();
                    if offset.len() != n || scale.len() != n {
                        return Err(spec.error(
                            pos,
                            format!("dimension mismatch: network `{net}` has {n} outputs but offset has {} and scale {} values", offset.len(), scale.len()),
                            format!("give {n} values to each"),
                        ));
                    }
                    spec.networks[k].out_norm = Some((offset, scale));
                }
                Stmt::Domain { net, bounds, pos } => {
                    let k = spec.net_index(&net, pos)?;
                    for (name, lo, hi, p) in bounds {
                        let Some(j) = spec.networks[k].inputs.iter().position(|i| *i == name)
                        else {
                            let hint =
                                nearest(&name, spec.networks[k].inputs.iter().map(String::as_str))
                                    .map(|s| format!("did you mean `{s}`?"))
                                    .unwrap_or_else(|| {
                                        format!(
                                            "inputs of `{net}`: {}",
                                            spec.networks[k].inputs.join(", ")
                                        )
                                    });
                            return Err(spec.error(
                                p,
                                format!("`{name}` is not an input of network `{net}`"),
                                hint,
                            ));
                        };
                        if lo > hi {
                            return Err(spec.error(
                                p,
                                format!("empty interval [{lo}, {hi}]"),
                                "write [lo, hi] with lo <= hi",
                            ));
                        }
                        spec.networks[k].domain[j] = (lo, hi);
                    }
                }
                Stmt::DomainFrom { net, dataset, pos } => {
                    spec.net_index(&net, pos)?;
                    domain_from.push((net, dataset, pos));
                }
                Stmt::Dataset {
                    name,
                    path,
                    normalised,
                    ..
                } => {
                    if normalised {
                        spec.normalised_datasets.push(name.clone());
                    }
                    spec.datasets.insert(name, PathBuf::from(path));
                }
                Stmt::Param {
                    name,
                    range,
                    default,
                    pos,
                } => {
                    if let Some((a, b)) = range {
                        if a > b {
                            return Err(spec.error(
                                pos,
                                format!("empty range [{a}, {b}]"),
                                "write [lo, hi] with lo <= hi",
                            ));
                        }
                    }
                    spec.params.insert(name, ParamDecl { range, default });
                }
                Stmt::Property {
                    name,
                    binders,
                    formula,
                    pos,
                } => {
                    if spec.properties.iter().any(|p| p.name == name) {
                        return Err(spec.error(
                            pos,
                            format!("property `{name}` is declared twice"),
                            "rename one of them",
                        ));
                    }
                    spec.properties.push(PropertyDecl {
                        name,
                        binders,
                        formula,
                        pos,
                    });
                }
            }
        }
        if spec.networks.is_empty() {
            return Err(spec.error(
                Pos { line: 1, col: 1 },
                "the spec declares no network",
                "add e.g. `network f(a, b) -> (y)`",
            ));
        }
        spec.pending_domains = domain_from;
        // Check every property once with default bindings (types, names, linearity).
        for p in spec.properties.clone() {
            spec.check_property(&p)?;
        }
        Ok(spec)
    }

    fn net_index(&self, net: &str, pos: Pos) -> Result<usize, SpecError> {
        self.networks
            .iter()
            .position(|n| n.name == net)
            .ok_or_else(|| {
                let hint = nearest(net, self.networks.iter().map(|n| n.name.as_str()))
                    .map(|s| format!("did you mean `{s}`?"))
                    .unwrap_or_else(|| {
                        "declare it first: network NAME(inputs) -> (outputs)".into()
                    });
                self.error(pos, format!("unknown network `{net}`"), hint)
            })
    }
}

/// A symbol of a linear expression during lowering.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
enum Sym {
    In(usize, usize),
    Out(usize, usize),
    Free(usize),
}

#[derive(Clone, Debug, PartialEq, Default)]
struct Lin {
    terms: Vec<(Sym, f64)>,
    c: f64,
}

impl Lin {
    fn constant(c: f64) -> Self {
        Lin { terms: vec![], c }
    }
    fn sym(s: Sym, a: f64, c: f64) -> Self {
        Lin {
            terms: vec![(s, a)],
            c,
        }
    }
    fn is_const(&self) -> bool {
        self.terms.iter().all(|t| t.1 == 0.0)
    }
    fn scale(mut self, k: f64) -> Self {
        self.terms.iter_mut().for_each(|t| t.1 *= k);
        self.c *= k;
        self
    }
    fn add(mut self, o: &Lin) -> Self {
        self.terms.extend(o.terms.iter().copied());
        self.c += o.c;
        self
    }
    fn sub(self, o: &Lin) -> Self {
        self.add(&o.clone().scale(-1.0))
    }
}

/// A piecewise-linear value: cases (conditions, value); the conditions of the cases
/// cover every point.
type Cases = Vec<(Vec<(Lin, Cmp)>, Lin)>;

#[derive(Clone, Debug)]
enum PointKind {
    Implicit,
    Data(Vec<f64>),
    Ball(usize, f64),
}

#[derive(Clone, Debug)]
struct PointInfo {
    name: String,
    net: usize,
    kind: PointKind,
}

/// A lowered property instance.
#[derive(Clone, Debug, PartialEq)]
pub struct Instance {
    /// Label, e.g. `p5[17]` for the data row 17.
    pub label: String,
    /// The query.
    pub query: Query,
}

struct Lowering<'a> {
    spec: &'a Spec,
    b: &'a Bindings,
    points: Vec<PointInfo>,
    critical: Option<String>,
    check_only: bool,
    /// Data tables by dataset name.
    tables: HashMap<String, Table>,
    row_of: HashMap<String, (String, usize)>,
    extra: Vec<(Lin, Cmp)>,
}

impl Spec {
    fn check_property(&self, p: &PropertyDecl) -> Result<(), SpecError> {
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

    fn property(&self, name: &str) -> Result<&PropertyDecl, SpecError> {
        self.properties
            .iter()
            .find(|p| p.name == name)
            .ok_or_else(|| {
                let hint = nearest(name, self.properties.iter().map(|p| p.name.as_str()))
                    .map(|s| format!("did you mean `{s}`?"))
                    .unwrap_or_else(|| format!("properties: {}", self.property_names().join(", ")));
                self.error(
                    Pos { line: 0, col: 0 },
                    format!("no property named `{name}`"),
                    hint,
                )
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

    fn lower(
        &self,
        p: &PropertyDecl,
        b: &Bindings,
        critical: Option<String>,
    ) -> Result<Vec<Instance>, SpecError> {
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
    fn err(&self, pos: Pos, m: impl Into<String>, h: impl Into<String>) -> SpecError {
        self.spec.error(pos, m, h)
    }

    fn table(&mut self, name: &str, pos: Pos) -> Result<Table, SpecError> {
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
    fn data_column(&self, net: usize, t_names: &[String], row: &[f64], col: &str) -> Option<f64> {
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

    fn point(&self, name: &str) -> Option<usize> {
        self.points.iter().position(|p| p.name == name)
    }

    fn implicit(&mut self) -> usize {
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

    fn instance(&mut self, p: &PropertyDecl, row: Option<usize>) -> Result<Instance, SpecError> {
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
                        t.row(row.unwrap_or(0)).to_vec()
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
                    if r < 0.0 {
                        return Err(self.err(
                            *pos,
                            format!("negative radius {r}"),
                            "use a radius >= 0",
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
        let mut dnf = self.dnf(&nnf)?;
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

    fn constant(&mut self, e: &Expr, pos: Pos) -> Result<f64, SpecError> {
        let cases = self.expr(e)?;
        match cases.as_slice() {
            [(conds, v)] if conds.is_empty() && v.is_const() => Ok(v.c),
            _ => Err(self.err(
                pos,
                "expected a constant",
                "use numbers and bound parameters here",
            )),
        }
    }

    fn param(&self, name: &str, pos: Pos) -> Result<Lin, SpecError> {
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

    fn unknown_name(&self, name: &str, pos: Pos) -> SpecError {
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
    fn raw_input(&mut self, p: usize, k: usize) -> Lin {
        let nd = &self.spec.networks[self.points[p].net];
        let (c, s) = nd.input_map(k);
        match &self.points[p].kind {
            PointKind::Data(v) => Lin::constant(v[k]),
            _ => Lin::sym(Sym::In(p, k), s, c),
        }
    }

    /// Network-unit input `k` of point `p`.
    fn net_input(&self, p: usize, k: usize) -> Lin {
        let nd = &self.spec.networks[self.points[p].net];
        let (c, s) = nd.input_map(k);
        match &self.points[p].kind {
            PointKind::Data(v) => Lin::constant((v[k] - c) / s),
            _ => Lin::sym(Sym::In(p, k), 1.0, 0.0),
        }
    }

    fn raw_output(&mut self, p: usize, k: usize) -> Lin {
        let nd = &self.spec.networks[self.points[p].net];
        let (c, s) = nd.output_map(k);
        Lin::sym(Sym::Out(p, k), s, c)
    }

    fn expr(&mut self, e: &Expr) -> Result<Cases, SpecError> {
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
            Expr::Add(a, b) => self.combine(a, b, |x, y| x.add(y))?,
            Expr::Sub(a, b) => self.combine(a, b, |x, y| x.sub(y))?,
            Expr::Neg(a) => self
                .expr(a)?
                .into_iter()
                .map(|(c, v)| (c, v.scale(-1.0)))
                .collect(),
            Expr::Mul(a, b, pos) => {
                let (ca, cb) = (self.expr(a)?, self.expr(b)?);
                let mut out = Vec::new();
                for (c1, v1) in &ca {
                    for (c2, v2) in &cb {
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
                out
            }
            Expr::Div(a, b, pos) => {
                let ca = self.expr(a)?;
                let cb = self.expr(b)?;
                let d = match cb.as_slice() {
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
                ca.into_iter().map(|(c, v)| (c, v.scale(1.0 / d))).collect()
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

    fn combine(
        &mut self,
        a: &Expr,
        b: &Expr,
        f: impl Fn(Lin, &Lin) -> Lin,
    ) -> Result<Cases, SpecError> {
        let (ca, cb) = (self.expr(a)?, self.expr(b)?);
        let mut out = Vec::new();
        for (c1, v1) in &ca {
            for (c2, v2) in &cb {
                out.push((c1.iter().chain(c2).cloned().collect(), f(v1.clone(), v2)));
            }
        }
        Ok(out)
    }
}

/// Negation normal form with atoms `(lhs, rel, rhs)`.
#[derive(Clone, Debug)]
enum Nnf {
    Atom(Expr, Rel, Expr, Pos),
    And(Vec<Nnf>),
    Or(Vec<Nnf>),
}

fn flip(r: Rel) -> Vec<Rel> {
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
    fn nnf(&mut self, f: &Formula, negate: bool) -> Result<Nnf, SpecError> {
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

    fn dnf(&mut self, f: &Nnf) -> Result<Vec<Vec<(Lin, Cmp)>>, SpecError> {
        const LIMIT: usize = 4096;
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
                    out.extend(self.dnf(g)?);
                }
                out
            }
            Nnf::And(v) => {
                let mut acc: Vec<Vec<(Lin, Cmp)>> = vec![vec![]];
                for g in v {
                    let d = self.dnf(g)?;
                    let mut next = Vec::new();
                    for a in &acc {
                        for b in &d {
                            next.push(a.iter().chain(b).cloned().collect());
                        }
                    }
                    if next.len() > LIMIT {
                        return Err(self.err(
                            Pos::default(),
                            format!("the property expands to more than {LIMIT} cases"),
                            "split it into smaller properties",
                        ));
                    }
                    acc = next;
                }
                acc
            }
        })
    }
}
