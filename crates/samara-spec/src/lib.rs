//! The samara property language: parser, checker, lowering to the linear normal form
//! ([`normal`]) and VNN-LIB 1.0 export/import ([`vnnlib`]).
//!
//! A spec states each property once, in physical units; every part of samara reads it.
//! The language reference is `docs/spec.md`; the case study's spec is
//! `models/alsomitra/alsomitra.samara`.
//!
//! ```text
//! network f(v_xp, v_yp, omega, theta, x, y) -> (ex) normalised constants "c.csv";
//! domain f = box { x in [0.48, 41.7], y in [-41.7, 4.2], ... };
//! param ystar;
//! property p1: y >= -x + ystar => ex >= 0.187;
//! ```
//!
//! Use: [`Spec::load`] (or [`Spec::from_source`]) parses, resolves and type-checks;
//! [`Spec::prove`], [`Spec::critical`] and [`Spec::instances`] lower queries.

pub mod data;
pub mod diag;
pub mod normal;
mod sema;
pub mod syntax;
pub mod vnnlib;

pub use diag::SpecError;
pub use sema::{constants_of_network, Constants, DataInfo, InstanceDim, InstanceKey, NetInfo, ParamInfo};

use normal::Query;
use sema::{Ctx, ParamMode};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use syntax::{Ast, Binder, DomainDecl, PropertyDecl};

/// What the command line binds: parameter values, networks (loaded by the caller, e.g.
/// from `--network f=FILE`) and data-set files (`--data train=FILE`).
#[derive(Clone, Debug, Default)]
pub struct Bindings {
    /// Parameter values (override the spec's defaults).
    pub params: BTreeMap<String, f64>,
    /// Loaded networks by spec name; their dimensions are checked against the
    /// declarations, and a `raw` network's normalisation layers give its constants.
    pub networks: BTreeMap<String, samara_nn::Network>,
    /// Data-set files by spec name (override the spec's paths).
    pub data: BTreeMap<String, PathBuf>,
}

/// A parsed, resolved and type-checked spec.
#[derive(Debug)]
pub struct Spec {
    file: String,
    src: String,
    ast: Ast,
    nets: Vec<NetInfo>,
    data: Vec<DataInfo>,
    params: Vec<ParamInfo>,
}

/// One instance of a quantified property (e.g. one data point and one eps).
#[derive(Clone, Debug, PartialEq)]
pub struct Instance {
    /// The quantifier values.
    pub key: InstanceKey,
    /// The lowered query.
    pub query: Query,
    /// If the property binds a point in an eps-ball: the application it belongs to, the
    /// ball's centre and radius in that network's applied units (radius NaN when the
    /// ball is not a cube in applied units). The application's `input_box` is already
    /// the ball intersected with the domain. A verifier can compute the extreme outputs
    /// over that box once per (point, eps) and decide every instance from them.
    pub ball: Option<(usize, Vec<f64>, f64)>,
}

impl Spec {
    /// Read, parse, resolve and type-check a spec file; relative paths inside it are
    /// resolved against its folder.
    pub fn load(path: impl AsRef<Path>, b: &Bindings) -> Result<Spec, SpecError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let src = std::fs::read_to_string(path)
            .map_err(|e| SpecError::plain(&name, format!("cannot read the spec: {e}")).help("check the path"))?;
        let base = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        Spec::from_source(&name, &src, &base, b)
    }

    /// Parse, resolve and type-check spec text named `file`, paths relative to `base`.
    pub fn from_source(file: &str, src: &str, base: &Path, b: &Bindings) -> Result<Spec, SpecError> {
        let ast = syntax::parse(file, src)?;
        let err = |span, m: String| SpecError::at(file, src, span, m);
        // Duplicate names.
        let mut seen: BTreeMap<String, ()> = BTreeMap::new();
        let decls = ast.networks.iter().map(|n| &n.name)
            .chain(ast.data.iter().map(|d| &d.name))
            .chain(ast.params.iter().map(|p| &p.name))
            .chain(ast.properties.iter().map(|p| &p.name));
        for n in decls {
            if seen.insert(n.text.clone(), ()).is_some() {
                return Err(err(n.span, format!("`{}` is declared twice", n.text)).help("rename one of them"));
            }
        }
        // Networks.
        let mut nets = Vec::new();
        for d in &ast.networks {
            let loaded = b.networks.get(&d.name.text);
            if let Some(n) = loaded {
                if n.n_inputs() != d.inputs.len() || n.n_outputs() != d.outputs.len() {
                    return Err(err(d.name.span, format!(
                        "dimension mismatch: network `{}` is declared with {} inputs and {} outputs, the loaded file has {} and {}",
                        d.name.text, d.inputs.len(), d.outputs.len(), n.n_inputs(), n.n_outputs()))
                        .help("pass a network with the declared signature, or fix the declaration"));
                }
            }
            let mut names: Vec<&syntax::Name> = d.inputs.iter().chain(d.outputs.iter()).collect();
            names.sort_by(|a, b| a.text.cmp(&b.text));
            for w in names.windows(2) {
                if w[0].text == w[1].text {
                    return Err(err(w[1].span, format!("`{}` names two inputs/outputs of `{}`", w[1].text, d.name.text)));
                }
            }
            let (applied_normalised, constants) = sema::resolve_units(
                file, src, base, &d.units, d.inputs.len(), d.outputs.len(), loaded,
            ).map_err(|e| if e.line == 1 && e.column == 1 && !matches!(d.units, syntax::Units::NormalisedFile(..)) {
                SpecError { ..SpecError::at(file, src, d.name.span, e.message.clone()) }.help(e.help.clone().unwrap_or_default())
            } else { e })?;
            nets.push(NetInfo {
                name: d.name.text.clone(),
                inputs: d.inputs.iter().map(|n| n.text.clone()).collect(),
                outputs: d.outputs.iter().map(|n| n.text.clone()).collect(),
                applied_normalised,
                constants,
                domain_raw: vec![(f64::NEG_INFINITY, f64::INFINITY); d.inputs.len()],
                has_domain: false,
                file: d.file.as_ref().map(|(p, _)| base.join(p)),
            });
        }
        for name in b.networks.keys() {
            if !nets.iter().any(|n| &n.name == name) {
                let mut e = SpecError::plain(file, format!("--network {name}=...: the spec declares no network `{name}`"));
                if let Some(s) = diag::nearest(name, nets.iter().map(|n| n.name.as_str())) {
                    e = e.help(format!("did you mean `{s}`?"));
                }
                return Err(e);
            }
        }
        // Data.
        let mut data = Vec::new();
        for d in &ast.data {
            let path = b.data.get(&d.name.text).cloned().unwrap_or_else(|| base.join(&d.path.0));
            let t = if d.format == "idx" { data::read_idx(&path) } else { data::read_csv(&path) };
            let mut t = t.map_err(|e| err(d.path.1, format!("cannot read data set `{}`: {e}", d.name.text))
                .help(format!("the path is relative to the spec's folder; or pass --data {}=FILE", d.name.text)))?;
            let need = d.inputs.len() + d.outputs.len();
            if t.cols < need {
                return Err(err(d.path.1, format!(
                    "dimension mismatch: data set `{}` has {} columns, the declaration names {need}", d.name.text, t.cols))
                    .help("name only the leading columns that exist"));
            }
            // Keep the named leading columns.
            let mut vals = Vec::with_capacity(t.rows * need);
            for r in 0..t.rows {
                vals.extend_from_slice(&t.row(r)[..need]);
            }
            t = data::Table { rows: t.rows, cols: need, values: vals };
            if let Some(by) = &d.normalised_by {
                let Some(net) = nets.iter().find(|n| n.name == by.text) else {
                    return Err(err(by.span, format!("unknown network `{}`", by.text)).expected("a declared network"));
                };
                let Some(c) = &net.constants else {
                    return Err(err(by.span, format!("network `{}` has no normalisation constants", by.text)));
                };
                let names: Vec<&syntax::Name> = d.inputs.iter().chain(d.outputs.iter()).collect();
                let mut maps = Vec::new();
                for n in &names {
                    if let Some(i) = net.inputs.iter().position(|x| *x == n.text) {
                        maps.push((c.in_min[i], c.in_range[i]));
                    } else if let Some(i) = net.outputs.iter().position(|x| *x == n.text) {
                        maps.push((c.out_min[i], c.out_range[i]));
                    } else {
                        let mut e = err(n.span, format!("column `{}` is not an input or output of `{}`", n.text, by.text));
                        if let Some(s) = diag::nearest(&n.text, net.inputs.iter().chain(net.outputs.iter()).map(|s| s.as_str())) {
                            e = e.help(format!("did you mean `{s}`?"));
                        }
                        return Err(e);
                    }
                }
                for r in 0..t.rows {
                    for (j, (m, s)) in maps.iter().enumerate() {
                        let v = &mut t.values[r * need + j];
                        *v = m + s * *v;
                    }
                }
            }
            data.push(DataInfo {
                name: d.name.text.clone(),
                inputs: d.inputs.iter().map(|n| n.text.clone()).collect(),
                outputs: d.outputs.iter().map(|n| n.text.clone()).collect(),
                table: t,
            });
        }
        // Domains.
        for dd in &ast.domains {
            let (net_name, span) = match dd {
                DomainDecl::Box(n, _) | DomainDecl::Range(n, _) => (n, n.span),
            };
            let Some(ni) = nets.iter().position(|n| n.name == net_name.text) else {
                let mut e = err(span, format!("unknown network `{}`", net_name.text)).expected("a declared network");
                if let Some(s) = diag::nearest(&net_name.text, nets.iter().map(|n| n.name.as_str())) {
                    e = e.help(format!("did you mean `{s}`?"));
                }
                return Err(e);
            };
            let nin = nets[ni].inputs.len();
            let bx = match dd {
                DomainDecl::Box(_, items) => {
                    let mut bx = vec![(f64::NEG_INFINITY, f64::INFINITY); nin];
                    if items.iter().all(|i| i.0.is_none()) && items.len() != nin {
                        return Err(err(span, format!(
                            "dimension mismatch: the box has {} intervals, `{}` has {nin} inputs", items.len(), net_name.text))
                            .help("give one interval per input, or name them: `box { x in [lo, hi], .. }`"));
                    }
                    for (k, (n, lo, hi)) in items.iter().enumerate() {
                        let i = match n {
                            None => k,
                            Some(n) => nets[ni].inputs.iter().position(|x| *x == n.text).ok_or_else(|| {
                                let mut e = err(n.span, format!("`{}` is not an input of `{}`", n.text, net_name.text))
                                    .expected(format!("one of {}", nets[ni].inputs.join(", ")));
                                if let Some(s) = diag::nearest(&n.text, nets[ni].inputs.iter().map(|s| s.as_str())) {
                                    e = e.help(format!("did you mean `{s}`?"));
                                }
                                e
                            })?,
                        };
                        if lo > hi || lo.is_nan() || hi.is_nan() {
                            return Err(err(span, format!("empty interval [{lo}, {hi}] for input {}", nets[ni].inputs[i]))
                                .help("write [lower, upper] with lower <= upper"));
                        }
                        bx[i] = (*lo, *hi);
                    }
                    bx
                }
                DomainDecl::Range(_, dn) => {
                    let ctx = Ctx { file, src, nets: &nets, data: &data, params: &[] };
                    let di = sema::data_index(&ctx, dn)?;
                    let d = &data[di];
                    if d.inputs.len() != nin {
                        return Err(err(dn.span, format!(
                            "dimension mismatch: data set `{}` has {} input columns, `{}` has {nin} inputs",
                            d.name, d.inputs.len(), net_name.text)));
                    }
                    (0..nin)
                        .map(|i| {
                            (0..d.table.rows).map(|r| d.table.row(r)[i]).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)))
                        })
                        .collect()
                }
            };
            nets[ni].domain_raw = bx;
            nets[ni].has_domain = true;
        }
        // Parameters.
        let mut params = Vec::new();
        for p in &ast.params {
            let value = b.params.get(&p.name.text).copied().or(p.default);
            let bounds = p.bounds.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
            if bounds.0 > bounds.1 {
                return Err(err(p.name.span, format!("empty bounds for `{}`", p.name.text)));
            }
            params.push(ParamInfo { name: p.name.text.clone(), value, bounds });
        }
        for name in b.params.keys() {
            if !params.iter().any(|p| &p.name == name) {
                let mut e = SpecError::plain(file, format!("--param {name}=...: the spec declares no parameter `{name}`"));
                e = match diag::nearest(name, params.iter().map(|p| p.name.as_str())) {
                    Some(s) => e.help(format!("did you mean `{s}`?")),
                    None => e.help(format!("declare it: `param {name};`")),
                };
                return Err(e);
            }
        }
        for name in b.data.keys() {
            if !data.iter().any(|d| &d.name == name) {
                return Err(SpecError::plain(file, format!("--data {name}=...: the spec declares no data set `{name}`")));
            }
        }
        let spec = Spec { file: file.to_string(), src: src.to_string(), ast, nets, data, params };
        // Type-check every property on its first instance, unbound parameters as 1.
        for p in &spec.ast.properties {
            let ctx = spec.ctx();
            sema::instance_space(&ctx, p)?;
            let key = InstanceKey { rows: vec![], values: vec![] };
            if p.binders.iter().any(|b| matches!(b, Binder::Data(..))) && spec.data.iter().any(|d| d.table.rows == 0) {
                continue;
            }
            sema::lower_instance(&ctx, p, &key, ParamMode::Check, p.name.text.clone())?;
        }
        Ok(spec)
    }

    fn ctx(&self) -> Ctx<'_> {
        Ctx { file: &self.file, src: &self.src, nets: &self.nets, data: &self.data, params: &self.params }
    }

    /// The spec's file name.
    pub fn file(&self) -> &str {
        &self.file
    }

    /// The networks as declared (with resolved constants and domains).
    pub fn networks(&self) -> &[NetInfo] {
        &self.nets
    }

    /// The data sets (raw units).
    pub fn data(&self) -> &[DataInfo] {
        &self.data
    }

    /// The parameters with their values.
    pub fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    /// Property names in order.
    pub fn properties(&self) -> Vec<&str> {
        self.ast.properties.iter().map(|p| p.name.text.as_str()).collect()
    }

    fn property(&self, name: &str) -> Result<&PropertyDecl, SpecError> {
        self.ast.properties.iter().find(|p| p.name.text == name).ok_or_else(|| {
            let mut e = SpecError::plain(&self.file, format!("no property `{name}`"))
                .expected(format!("one of {}", self.properties().join(", ")));
            if let Some(s) = diag::nearest(name, self.properties()) {
                e = e.help(format!("did you mean `{s}`?"));
            }
            e
        })
    }

    /// Parameters a property mentions that have no value.
    pub fn unbound_params(&self, name: &str) -> Result<Vec<String>, SpecError> {
        let p = self.property(name)?;
        let text = &self.src[span_of(p)];
        let toks = syntax::lex(&self.file, text)?;
        let mut out: Vec<String> = Vec::new();
        for t in toks {
            if let syntax::Tok::Ident(s) = t.tok {
                if self.params.iter().any(|q| q.name == s && q.value.is_none()) && !out.contains(&s) {
                    out.push(s);
                }
            }
        }
        Ok(out)
    }

    /// Whether the property quantifies over data or value sets (several instances).
    pub fn is_quantified(&self, name: &str) -> Result<bool, SpecError> {
        Ok(self.property(name)?.binders.iter().any(|b| matches!(b, Binder::Data(..) | Binder::Values(..))))
    }

    /// The axes of the property's instance space (data rows, value sets).
    pub fn instance_space(&self, name: &str) -> Result<Vec<InstanceDim>, SpecError> {
        sema::instance_space(&self.ctx(), self.property(name)?)
    }

    /// Lower one instance. `free`: the parameter of a critical query.
    pub fn instance(&self, name: &str, key: &InstanceKey, free: Option<&str>) -> Result<Instance, SpecError> {
        let p = self.property(name)?;
        let free = match free {
            None => None,
            Some(f) => Some(self.params.iter().position(|q| q.name == f).ok_or_else(|| {
                SpecError::plain(&self.file, format!("no parameter `{f}`"))
            })?),
        };
        let mut qname = name.to_string();
        if !key.rows.is_empty() || !key.values.is_empty() {
            let mut parts: Vec<String> = key.rows.iter().map(|r| r.to_string()).collect();
            parts.extend(key.values.iter().map(|(n, v)| format!("{n}={v}")));
            qname = format!("{name}[{}]", parts.join(","));
        }
        let (query, ball) = sema::lower_instance(&self.ctx(), p, key, ParamMode::Lower { free }, qname)?;
        Ok(Instance { key: key.clone(), query, ball })
    }

    /// All instances of a property, lazily (each lowered when the iterator reaches it).
    /// For P5 over 360 points and 3 eps values: 1080 instances.
    pub fn instances<'s>(&'s self, name: &str, free: Option<&'s str>) -> Result<impl Iterator<Item = Result<Instance, SpecError>> + 's, SpecError> {
        let dims = self.instance_space(name)?;
        let name = name.to_string();
        let sizes: Vec<usize> = dims.iter().map(|d| match d { InstanceDim::Rows(n) => *n, InstanceDim::Values(_, v) => v.len() }).collect();
        let total: usize = sizes.iter().product();
        Ok((0..total).map(move |mut k| {
            let mut key = InstanceKey { rows: vec![], values: vec![] };
            let mut idx = vec![0; sizes.len()];
            for j in (0..sizes.len()).rev() {
                idx[j] = k % sizes[j];
                k /= sizes[j];
            }
            for (j, d) in dims.iter().enumerate() {
                match d {
                    InstanceDim::Rows(_) => key.rows.push(idx[j]),
                    InstanceDim::Values(n, v) => key.values.push((n.clone(), v[idx[j]])),
                }
            }
            self.instance(&name, &key, free)
        }))
    }

    /// The prove query of a property (for a quantified property, all instances).
    pub fn prove(&self, name: &str) -> Result<Vec<Query>, SpecError> {
        self.instances(name, None)?.map(|r| r.map(|i| i.query)).collect()
    }

    /// The critical query of a property in parameter `param`: the region of
    /// counterexamples with `param` a free variable and the objective `param`,
    /// maximised if the property holds above the critical value, minimised if below
    /// (decided from the region's monotonicity; see `docs/spec.md`).
    pub fn critical(&self, name: &str, param: &str) -> Result<Vec<Query>, SpecError> {
        if !self.params.iter().any(|p| p.name == param) {
            let mut e = SpecError::plain(&self.file, format!("no parameter `{param}`"));
            if let Some(s) = diag::nearest(param, self.params.iter().map(|p| p.name.as_str())) {
                e = e.help(format!("did you mean `{s}`?"));
            }
            return Err(e);
        }
        self.instances(name, Some(param))?.map(|r| r.map(|i| i.query)).collect()
    }

    /// The natural query of a property: `prove` if every parameter it mentions is
    /// bound; `critical` in the one unbound parameter otherwise.
    pub fn default_queries(&self, name: &str) -> Result<Vec<Query>, SpecError> {
        let u = self.unbound_params(name)?;
        match u.as_slice() {
            [] => self.prove(name),
            [p] => self.critical(name, p),
            _ => self.prove(name), // reports the first unbound parameter with its place
        }
    }
}

fn span_of(p: &PropertyDecl) -> std::ops::Range<usize> {
    let start = p.name.span.start;
    let end = match &p.body {
        syntax::Body::Holds(e) => e.span().end,
        syntax::Body::Optimise { region, .. } => region.span().end,
    };
    start..end.max(start)
}
