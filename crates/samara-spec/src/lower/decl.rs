//! Declarations: networks, parameters, properties, the spec they form, values bound from
//! outside, and the checks of the declarations themselves.

use super::suggest::nearest;
use crate::syntax::{parse, Binder, Formula, Pos, SpecError, Stmt};
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
    /// Where it is declared (bound values outside `range` are refused there).
    pub pos: Pos,
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
    /// Closed loops in order ([`super::closed_loop`]).
    pub loops: Vec<super::LoopDecl>,
    pub(super) source: String,
    pub(super) pending_domains: Vec<(String, String, Pos)>,
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

impl Spec {
    pub(super) fn error(
        &self,
        pos: Pos,
        message: impl Into<String>,
        hint: impl Into<String>,
    ) -> SpecError {
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

    /// The text the spec was parsed from, as read.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// Parse and check a spec file.
    pub fn read(path: &Path) -> Result<Spec, SpecError> {
        let file = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|e| SpecError {
            file: file.clone(),
            pos: Pos::default(), // no position: not printed
            message: format!("cannot read the spec: {e}"),
            hint: "check the path".into(),
            source_line: String::new(),
        })?;
        let src = crate::syntax::decode(&bytes, &file)?;
        Spec::parse(src, &file, path.parent().unwrap_or(Path::new(".")))
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
            loops: Vec::new(),
            source: src.into(),
            pending_domains: Vec::new(),
        };
        let mut domain_from: Vec<(String, String, Pos)> = Vec::new();
        let mut param_pos: Vec<(String, Pos)> = Vec::new();
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
                    if min.iter().chain(&range).any(|v| !v.is_finite()) {
                        return Err(spec.error(
                            pos,
                            format!(
                                "{} holds a value that is not a finite number",
                                full.display()
                            ),
                            "write finite minima and ranges",
                        ));
                    }
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
                    if scale.contains(&0.0) {
                        return Err(spec.error(
                            pos,
                            "an output scale is zero",
                            "scales must be non-zero",
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
                    pos,
                } => {
                    if spec.datasets.contains_key(&name) {
                        return Err(spec.error(
                            pos,
                            format!("data set `{name}` is declared twice"),
                            "declare each data set once",
                        ));
                    }
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
                    if spec.params.contains_key(&name) {
                        return Err(spec.error(
                            pos,
                            format!("parameter `{name}` is declared twice"),
                            "declare each parameter once",
                        ));
                    }
                    if let Some((a, b)) = range {
                        if a > b {
                            return Err(spec.error(
                                pos,
                                format!("empty range [{a}, {b}]"),
                                "write [lo, hi] with lo <= hi",
                            ));
                        }
                        if let Some(v) = default {
                            if !(a <= v && v <= b) {
                                return Err(spec.error(
                                    pos,
                                    format!(
                                        "the default {v} of parameter `{name}` is outside its range [{a}, {b}]"
                                    ),
                                    format!("give a default within [{a}, {b}] or widen the range"),
                                ));
                            }
                        }
                    }
                    param_pos.push((name.clone(), pos));
                    spec.params.insert(
                        name,
                        ParamDecl {
                            range,
                            default,
                            pos,
                        },
                    );
                }
                Stmt::Loop {
                    name,
                    net,
                    clauses,
                    pos,
                } => spec.add_loop(name, net, clauses, pos)?,
                Stmt::Start { lp, states, pos } => spec.add_start(&lp, states, pos)?,
                Stmt::Goal {
                    lp,
                    expr,
                    bound,
                    from,
                    time,
                    pos,
                } => spec.add_goal(&lp, &expr, bound, (from, time), pos)?,
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
        // A bare name means the first network's input or output before a parameter:
        // a parameter of the same name would be silently shadowed.
        let first = &spec.networks[0];
        for (name, pos) in &param_pos {
            if first.inputs.contains(name) || first.outputs.contains(name) {
                return Err(spec.error(
                    *pos,
                    format!(
                        "parameter `{name}` has the name of an input or output of network `{}`",
                        first.name
                    ),
                    "rename the parameter",
                ));
            }
        }
        spec.check_loops()?;
        spec.pending_domains = domain_from;
        // Check every property once with default bindings (types, names, linearity).
        for p in spec.properties.clone() {
            spec.check_property(&p)?;
        }
        Ok(spec)
    }

    pub(super) fn net_index(&self, net: &str, pos: Pos) -> Result<usize, SpecError> {
        let names: Vec<&str> = self.networks.iter().map(|n| n.name.as_str()).collect();
        self.index_named(
            &names,
            net,
            pos,
            (
                "network",
                "declare it first: network NAME(inputs) -> (outputs)",
            ),
        )
    }

    /// The index of `name` among `names`, or the error `unknown KIND `name`` at `pos`
    /// with the closest name as the hint (else `declare`).
    pub(super) fn index_named(
        &self,
        names: &[&str],
        name: &str,
        pos: Pos,
        (kind, declare): (&str, &str),
    ) -> Result<usize, SpecError> {
        names.iter().position(|n| *n == name).ok_or_else(|| {
            let hint = nearest(name, names.iter().copied())
                .map(|s| format!("did you mean `{s}`?"))
                .unwrap_or_else(|| declare.into());
            self.error(pos, format!("unknown {kind} `{name}`"), hint)
        })
    }
}
