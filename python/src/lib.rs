//! `samara._samara`: the native part of the `samara` Python package.
//!
//! The Python layer (`python/samara/__init__.py`) does the numpy and file handling; this
//! module takes plain bytes (float64, row-major), strings and dicts, and returns bytes
//! or JSON text with the same fields as the CLI's `--json` output (the verification
//! paths mirror `crates/samara-cli/src/verify.rs`). Long computations release the GIL.

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use samara_spec::lower::{nearest, NetDecl};
use samara_spec::normal::{Goal, Query, Sense};
use samara_spec::syntax::Binder;
use samara_spec::{Bindings, Instance};
use samara_verify::engine::Point;
use samara_verify::robustness::{lipschitz_cell, published_cell, sweep_with, Reference};
use samara_verify::{
    left_after, optimise, prove, vacuity, LpTighten, Prepared, Settings, UnknownReason, Verdict,
};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

create_exception!(
    _samara,
    SamaraError,
    PyException,
    "A computation of samara failed (not a bad argument: those raise ValueError)."
);

/// An error on the Rust side: a bad argument (ValueError) or a failed computation.
enum Error {
    Value(String),
    Samara(String),
}

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        match e {
            Error::Value(m) => PyValueError::new_err(m),
            Error::Samara(m) => SamaraError::new_err(m),
        }
    }
}

fn value<T>(m: impl Into<String>) -> Result<T, Error> {
    Err(Error::Value(m.into()))
}

type R<T> = Result<T, Error>;

/// A feed-forward network (samara's IR).
#[pyclass(module = "samara._samara", name = "Network", frozen)]
#[derive(Clone)]
struct PyNetwork {
    net: samara_nn::Network,
}

#[pymethods]
impl PyNetwork {
    /// Import ONNX bytes; `name` only labels messages.
    #[staticmethod]
    fn from_onnx_bytes(py: Python<'_>, data: &[u8], name: &str) -> PyResult<Self> {
        let data = data.to_vec();
        let name = name.to_string();
        let net = py
            .allow_threads(move || samara_nn::onnx::from_bytes(&data, &name))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(PyNetwork { net })
    }

    /// The ONNX bytes (with the normalisation layers the network carries); float32
    /// tensors unless `float64`.
    #[pyo3(signature = (with_normalisation = true, float64 = false))]
    fn to_onnx<'py>(
        &self,
        py: Python<'py>,
        with_normalisation: bool,
        float64: bool,
    ) -> Bound<'py, PyBytes> {
        use samara_nn::onnx::ExportOptions;
        let o = ExportOptions {
            with_normalisation,
            float64,
            ..Default::default()
        };
        let bytes = samara_nn::onnx::export(&self.net, &o);
        PyBytes::new(py, &prost_encode(bytes))
    }

    #[getter]
    fn n_inputs(&self) -> usize {
        self.net.n_inputs()
    }

    #[getter]
    fn n_outputs(&self) -> usize {
        self.net.n_outputs()
    }

    #[getter]
    fn input_names(&self) -> Vec<String> {
        self.net.input_names.clone()
    }

    #[getter]
    fn output_names(&self) -> Vec<String> {
        self.net.output_names.clone()
    }

    /// Evaluate `n` rows of float64 inputs (row-major bytes) in raw units; returns the
    /// outputs as float64 bytes (`n` rows).
    fn eval_rows<'py>(
        &self,
        py: Python<'py>,
        xs: &[u8],
        n: usize,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let d = self.net.n_inputs();
        if xs.len() != n * d * 8 {
            return Err(PyValueError::new_err(format!(
                "eval: {} bytes for {n} rows of {d} float64 inputs",
                xs.len()
            )));
        }
        let x = f64s(xs);
        // NaN, infinite or None (NaN through numpy) inputs are refused: a network
        // evaluated there has no meaningful value (ReLUs would turn NaN into 0 in
        // max-based code, and +-inf into an arbitrary number).
        if let Some(k) = x.iter().position(|v| !v.is_finite()) {
            let (r, c) = (k / d.max(1), k % d.max(1));
            let name = self.net.input_names.get(c).cloned().unwrap_or_default();
            return Err(PyValueError::new_err(format!(
                "Network.eval: input [{r}, {c}] (`{name}`, row {r}) is {}; pass finite numbers (NaN, inf and None have no network value)",
                x[k]
            )));
        }
        let net = &self.net;
        let y = py.allow_threads(|| net.eval_batch_f64(&x, n));
        Ok(PyBytes::new(py, &f64_bytes(&y)))
    }
}

fn prost_encode(m: samara_nn::onnx::proto::ModelProto) -> Vec<u8> {
    use prost::Message;
    m.encode_to_vec()
}

fn f64s(b: &[u8]) -> Vec<f64> {
    b.chunks_exact(8)
        .map(|c| f64::from_ne_bytes(c.try_into().expect("8 bytes")))
        .collect()
}

fn f64_bytes(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_ne_bytes()).collect()
}

/// A checked specification.
#[pyclass(module = "samara._samara", name = "Spec", frozen)]
struct PySpec {
    spec: samara_spec::Spec,
}

#[pymethods]
impl PySpec {
    /// Parse spec text; `file` names it in messages, `dir` is where its relative data
    /// paths are resolved.
    #[new]
    fn new(text: &str, file: &str, dir: &str) -> PyResult<Self> {
        let spec = samara_spec::Spec::parse(text, file, Path::new(dir))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(PySpec { spec })
    }

    #[getter]
    fn properties(&self) -> Vec<String> {
        self.spec
            .property_names()
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    #[getter]
    fn networks(&self) -> Vec<(String, Vec<String>, Vec<String>)> {
        self.spec
            .networks
            .iter()
            .map(|n| (n.name.clone(), n.inputs.clone(), n.outputs.clone()))
            .collect()
    }

    #[getter]
    fn params(&self) -> HashMap<String, Option<(f64, f64)>> {
        self.spec
            .params
            .iter()
            .map(|(k, p)| (k.clone(), p.range))
            .collect()
    }

    #[getter]
    fn file(&self) -> String {
        self.spec.file.clone()
    }

    /// Verify properties (all, or `property`); JSON text: a list with one object per
    /// instance, fields as `samara verify --json`. Also returns warnings.
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (networks, params, datasets, property, timeout, max_nodes, lp_tighten))]
    fn verify(
        &self,
        py: Python<'_>,
        networks: HashMap<String, PyRef<'_, PyNetwork>>,
        params: HashMap<String, f64>,
        datasets: HashMap<String, String>,
        property: Option<String>,
        timeout: f64,
        max_nodes: usize,
        lp_tighten: bool,
    ) -> PyResult<(String, Vec<String>)> {
        let nets: HashMap<String, samara_nn::Network> = networks
            .into_iter()
            .map(|(k, v)| (k, v.net.clone()))
            .collect();
        let spec = &self.spec;
        let r = py.allow_threads(move || {
            let l = load(spec, nets, &params, None, &datasets)?;
            run_verify(&l, property, settings(timeout, max_nodes, lp_tighten)?)
                .map(|v| (v.to_string(), l.warnings))
        })?;
        Ok(r)
    }

    /// The critical value of parameter `param` for `property`; JSON text with the fields
    /// of `samara critical --json`.
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (property, param, networks, params, datasets, timeout, max_nodes, lp_tighten))]
    fn critical(
        &self,
        py: Python<'_>,
        property: String,
        param: String,
        networks: HashMap<String, PyRef<'_, PyNetwork>>,
        params: HashMap<String, f64>,
        datasets: HashMap<String, String>,
        timeout: f64,
        max_nodes: usize,
        lp_tighten: bool,
    ) -> PyResult<(String, Vec<String>)> {
        let nets: HashMap<String, samara_nn::Network> = networks
            .into_iter()
            .map(|(k, v)| (k, v.net.clone()))
            .collect();
        let spec = &self.spec;
        let r = py.allow_threads(move || {
            let l = load(spec, nets, &params, Some(&param), &datasets)?;
            let s = settings(timeout, max_nodes, lp_tighten)?;
            critical_value(&l, &property, &param, &s).map(|v| (v.to_string(), l.warnings))
        })?;
        Ok(r)
    }
}

fn settings(timeout: f64, max_nodes: usize, lp_tighten: bool) -> R<Settings> {
    if timeout.is_nan() || timeout < 0.0 {
        return value(format!(
            "timeout {timeout}: must be a number of seconds >= 0 (float('inf') for no limit)"
        ));
    }
    Ok(Settings {
        timeout,
        max_nodes,
        lp_tighten: if lp_tighten {
            LpTighten::Root
        } else {
            LpTighten::Off
        },
        ..Default::default()
    })
}

/// A spec with its bindings (as the CLI's `Loaded`).
struct Loaded<'a> {
    spec: &'a samara_spec::Spec,
    nets: HashMap<String, samara_nn::Network>,
    b: Bindings,
    warnings: Vec<String>,
}

fn suggest<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str> + Clone) -> String {
    match nearest(name, candidates.clone()) {
        Some(c) => format!("did you mean `{c}`?"),
        None => {
            let mut all: Vec<&str> = candidates.into_iter().collect();
            all.sort();
            if all.is_empty() {
                "it declares none".into()
            } else {
                format!("it declares {}", all.join(", "))
            }
        }
    }
}

/// Check the bindings as `samara_cli::verify::load` does (same messages, argument names
/// instead of flags).
fn load<'a>(
    spec: &'a samara_spec::Spec,
    nets: HashMap<String, samara_nn::Network>,
    params: &HashMap<String, f64>,
    free: Option<&str>,
    datasets: &HashMap<String, String>,
) -> R<Loaded<'a>> {
    let mut b = Bindings::default();
    let mut warnings = Vec::new();
    let mut names: Vec<&String> = nets.keys().collect();
    names.sort();
    for k in names {
        let net = &nets[k];
        let Some(nd) = spec.networks.iter().find(|n| &n.name == k) else {
            return value(format!(
                "networks[{k:?}]: the spec {} declares no network `{k}`; {}",
                spec.file,
                suggest(k, spec.networks.iter().map(|n| n.name.as_str()))
            ));
        };
        if net.n_inputs() != nd.inputs.len() || net.n_outputs() != nd.outputs.len() {
            return value(format!(
                "networks[{k:?}]: dimension mismatch: the network has {} inputs and {} outputs but {} declares `{k}({})` with {} inputs and {} outputs; pass a network of that signature",
                net.n_inputs(),
                net.n_outputs(),
                spec.file,
                nd.inputs.join(", "),
                nd.inputs.len(),
                nd.outputs.len()
            ));
        }
        units_check(spec, k, nd, net, &mut warnings)?;
        b.network_dims
            .insert(k.clone(), (net.n_inputs(), net.n_outputs()));
    }
    if let Some(k) = free {
        if !spec.params.contains_key(k) {
            return value(format!(
                "param {k:?}: the spec {} declares no parameter `{k}`; {}",
                spec.file,
                suggest(k, spec.params.keys().map(String::as_str))
            ));
        }
    }
    for (k, &x) in params {
        if !spec.params.contains_key(k) {
            return value(format!(
                "params[{k:?}]: the spec {} declares no parameter `{k}`; {}",
                spec.file,
                suggest(k, spec.params.keys().map(String::as_str))
            ));
        }
        if !x.is_finite() {
            return value(format!(
                "params[{k:?}] = {x}: not a finite number; pass a finite value"
            ));
        }
        if Some(k.as_str()) == free {
            return value(format!(
                "params[{k:?}]: `{k}` is also the parameter to search (param={k:?}); drop one of them"
            ));
        }
        b.params.insert(k.clone(), x);
    }
    for (k, v) in datasets {
        if !spec.datasets.contains_key(k) {
            return value(format!(
                "datasets[{k:?}]: the spec {} declares no data set `{k}`; {}",
                spec.file,
                suggest(k, spec.datasets.keys().map(String::as_str))
            ));
        }
        let p = PathBuf::from(v);
        if !p.is_file() {
            return value(format!(
                "datasets[{k:?}] = {v:?}: no such file; pass the CSV or IDX file (or a numpy array) of data set `{k}`"
            ));
        }
        b.datasets.insert(k.clone(), p);
    }
    Ok(Loaded {
        spec,
        nets,
        b,
        warnings,
    })
}

fn units_check(
    spec: &samara_spec::Spec,
    name: &str,
    nd: &NetDecl,
    net: &samara_nn::Network,
    warnings: &mut Vec<String>,
) -> R<()> {
    if nd.in_norm.is_some() && net.input_norm.is_some() {
        return value(format!(
            "networks[{name:?}]: units mismatch: the network normalises its own inputs (it has a raw-to-normalised input layer: a raw-unit network such as a `*_denorm` file) but {} declares `normalise {name} input`, i.e. `{name}` takes normalised inputs, so the inputs would be normalised twice; pass the network that takes normalised inputs (e.g. base_model_norm.onnx) or remove the `normalise {name}` lines from the spec",
            spec.file
        ));
    }
    if nd.out_norm.is_some() && net.output_denorm.is_some() {
        return value(format!(
            "networks[{name:?}]: units mismatch: the network denormalises its own output but {} declares `normalise {name} output`, so the output would be converted twice; pass the network with a normalised output or remove the `normalise {name} output` line",
            spec.file
        ));
    }
    if nd.in_norm.is_none() && net.input_norm.is_none() {
        warnings.push(format!(
            "networks[{name:?}]: {} declares `{name}` in raw units (no `normalise {name}` line) and the network carries no normalisation layer: samara cannot check that it takes raw inputs; if it takes normalised ones, add the `normalise {name} input ...` line",
            spec.file
        ));
    }
    Ok(())
}

fn missing_data(l: &Loaded, name: &str) -> Option<String> {
    let p = l.spec.properties.iter().find(|p| p.name == name)?;
    for bnd in &p.binders {
        if let Binder::Data { dataset, .. } = bnd {
            let path = match l.b.datasets.get(dataset) {
                Some(p) => p.clone(),
                None => match l.spec.datasets.get(dataset) {
                    Some(p) if p.is_absolute() => p.clone(),
                    Some(p) => l.spec.dir.join(p),
                    None => continue,
                },
            };
            if !path.is_file() {
                return Some(format!(
                    "property `{name}` quantifies over data set `{dataset}`, whose file {} (the spec's path, relative to the spec file) does not exist; pass datasets={{{dataset:?}: FILE or array}}",
                    path.display()
                ));
            }
        }
    }
    None
}

fn named_point(spec: &samara_spec::Spec, q: &Query, p: &Point) -> Value {
    let mut apps = Vec::new();
    for (ai, app) in q.applications.iter().enumerate() {
        let Some(nd) = spec.networks.iter().find(|n| n.name == app.network) else {
            continue;
        };
        let mut m = serde_json::Map::new();
        for (k, name) in nd.inputs.iter().enumerate() {
            let (c, s) = nd.input_map(k);
            m.insert(name.clone(), json!(c + s * p.inputs[ai][k]));
        }
        for (k, name) in nd.outputs.iter().enumerate() {
            let (c, s) = nd.output_map(k);
            m.insert(name.clone(), json!(c + s * p.outputs[ai][k]));
        }
        apps.push(json!({"network": app.network, "values": m}));
    }
    json!(apps)
}

fn require_networks(l: &Loaded, qs: &[&Instance]) -> R<()> {
    for i in qs {
        for a in &i.query.applications {
            if !l.nets.contains_key(&a.network) {
                return value(format!(
                    "property `{}` uses network `{}`; pass networks={{{:?}: Network}}",
                    i.label, a.network, a.network
                ));
            }
        }
    }
    Ok(())
}

fn reason_json(r: &UnknownReason) -> Value {
    json!({"kind": r.kind(), "message": r.to_string()})
}

fn run_verify(l: &Loaded, property: Option<String>, settings: Settings) -> R<Value> {
    // `timeout` is a deadline for the whole call (as the CLI's --timeout).
    let start = Instant::now();
    let names: Vec<String> = match &property {
        Some(p) => vec![p.clone()],
        None => l
            .spec
            .property_names()
            .iter()
            .map(|s| s.to_string())
            .collect(),
    };
    let mut lowered = Vec::new();
    for n in &names {
        if let Some(m) = missing_data(l, n) {
            return value(m);
        }
        lowered.push(
            l.spec
                .lower_prove(n, &l.b)
                .map_err(|e| Error::Value(e.to_string()))?,
        );
    }
    require_networks(l, &lowered.iter().flatten().collect::<Vec<_>>())?;
    let prep = Prepared::new(&l.nets);
    let mut out = Vec::new();
    for inst in &lowered {
        for i in inst {
            let q = &i.query;
            let ti = Instant::now();
            let left = left_after(&settings, start);
            let verdict = if left.timeout > 0.0 {
                prove(q, &prep, &left).map_err(|e| Error::Samara(e.to_string()))?
            } else {
                Verdict::Unknown(UnknownReason::Timeout { nodes: 0 })
            };
            let isecs = ti.elapsed().as_secs_f64();
            let mut vac = Value::Null;
            let mut reason = Value::Null;
            let (tag, cx) = match &verdict {
                Verdict::Proved => {
                    // Shared with the CLI: an empty input box or an empty premise.
                    let vs = Settings {
                        timeout: left_after(&settings, start).timeout.min(10.0),
                        ..settings
                    };
                    if let Some(why) =
                        vacuity(q, &prep, &vs).map_err(|e| Error::Samara(e.to_string()))?
                    {
                        vac = json!(why);
                    }
                    ("proved", Value::Null)
                }
                Verdict::Violated(c) => (
                    "violated",
                    json!({"point": named_point(l.spec, q, &c.point), "margin": c.margin, "exact_check": c.exact}),
                ),
                Verdict::Unknown(r) => {
                    reason = reason_json(r);
                    ("unknown", json!({"reason": r.to_string()}))
                }
            };
            out.push(json!({"property": i.label, "verdict": tag, "counterexample": cx,
                "seconds": isecs, "vacuous": !vac.is_null(), "vacuity": vac, "unknown_reason": reason}));
        }
    }
    Ok(Value::Array(out))
}

/// As `samara_cli::verify::critical_value`.
fn critical_value(l: &Loaded, property: &str, param: &str, settings: &Settings) -> R<Value> {
    if let Some(m) = missing_data(l, property) {
        return value(m);
    }
    let inst = l
        .spec
        .lower_critical(property, param, &l.b)
        .map_err(|e| Error::Value(e.to_string()))?;
    if inst.len() != 1 {
        return value(format!("critical values are computed for properties without data-set quantifiers; `{property}` has {} instances", inst.len()));
    }
    require_networks(l, &inst.iter().collect::<Vec<_>>())?;
    let prep = Prepared::new(&l.nets);
    let t0 = Instant::now();
    let q_max = inst[0].query.clone();
    let mut q_min = q_max.clone();
    if let Goal::Optimise { sense, .. } = &mut q_min.goal {
        *sense = Sense::Min;
    }
    // `timeout` is a deadline for both searches together (as the CLI).
    let sup = optimise(&q_max, &prep, settings).map_err(|e| Error::Samara(e.to_string()))?;
    let inf = optimise(&q_min, &prep, &left_after(settings, t0))
        .map_err(|e| Error::Samara(e.to_string()))?;
    let Some((lo, hi)) = l.spec.params[param].range else {
        return value(format!("parameter `{param}` has no range"));
    };
    let tol = 1e-9 * (1.0 + hi.abs().max(lo.abs()));
    let unknown = sup.unknown.clone().or(inf.unknown.clone());
    let (holds, chosen) = match (&unknown, inf.value, sup.value) {
        (Some(_), _, _) => ("unknown", None),
        (None, None, _) | (None, _, None) => ("everywhere", None),
        (None, _, Some(s)) if s < hi - tol => ("above", Some(&sup)),
        (None, Some(i), _) if i > lo + tol => ("below", Some(&inf)),
        _ => ("nowhere", Some(&inf)),
    };
    let threshold = match holds {
        "above" | "below" => chosen.map(|c| c.bound),
        _ => None,
    };
    Ok(json!({
        "property": property,
        "parameter": param,
        "holds": holds,
        "critical": chosen.and_then(|c| c.value),
        "bound": chosen.map(|c| c.bound),
        "threshold": threshold,
        "attained": chosen.map(|c| c.attained).unwrap_or(false),
        "vacuous": chosen.map(|c| c.vacuous).unwrap_or(false),
        "domain_extreme": chosen.and_then(|c| c.domain_extreme),
        "counterexample_range": [inf.value, sup.value],
        "witness": chosen.and_then(|c| c.witness.as_ref()).map(|w| named_point(l.spec, &q_max, w)),
        "complete": unknown.is_none(),
        "unknown_reason": unknown.as_ref().map(reason_json),
        "seconds": t0.elapsed().as_secs_f64(),
    }))
}

/// The robustness table of `samara robustness --json` (plus the per-point results):
/// `rows` row-major float64 bytes of `n` rows and `cols` columns (inputs, then the label).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (network, rows, n, cols, eps, lipschitz, reference, form, timeout, max_nodes))]
fn robustness(
    py: Python<'_>,
    network: PyRef<'_, PyNetwork>,
    rows: &[u8],
    n: usize,
    cols: usize,
    eps: Vec<f64>,
    lipschitz: Vec<f64>,
    reference: &str,
    form: &str,
    timeout: f64,
    max_nodes: usize,
) -> PyResult<String> {
    let net = network.net.clone();
    let data = f64s(rows);
    let reference = reference.to_string();
    let form = form.to_string();
    let r = py.allow_threads(move || -> R<String> {
        if data.len() != n * cols {
            return value(format!("data: {} values for {n} rows of {cols}", data.len()));
        }
        let mut es: Vec<f64> = Vec::new();
        for e in eps {
            if !(e > 0.0 && e <= 1e6) {
                return value(format!(
                    "eps {e}: out of range; each value must be a radius > 0 and at most 1e6 (in the network's input units)"
                ));
            }
            if !es.contains(&e) {
                es.push(e);
            }
        }
        let mut ls: Vec<f64> = Vec::new();
        for l in lipschitz {
            if !(l.is_finite() && l >= 0.0) {
                return value(format!(
                    "lipschitz {l}: out of range; each value must be finite and >= 0"
                ));
            }
            if !ls.contains(&l) {
                ls.push(l);
            }
        }
        let reference = match reference.as_str() {
            "label" => Reference::Label,
            "network" => Reference::Network,
            o => return value(format!("reference {o:?}: choose 'label' or 'network'")),
        };
        if !["published", "lipschitz"].contains(&form.as_str()) {
            return value(format!("form {form:?}: choose 'published' or 'lipschitz'"));
        }
        let ni = net.n_inputs();
        let used = if reference == Reference::Label {
            ni + 1
        } else {
            ni
        };
        if cols < used {
            return value(format!(
                "data: {cols} columns but the network has {ni} inputs{}",
                if reference == Reference::Label {
                    " and the label column is needed (or pass reference='network')"
                } else {
                    ""
                }
            ));
        }
        let rows: Vec<Vec<f64>> = (0..n)
            .map(|i| data[i * cols..(i + 1) * cols].to_vec())
            .collect();
        for (i, r) in rows.iter().enumerate() {
            if let Some(j) = r.iter().take(used).position(|v| !v.is_finite()) {
                return value(format!(
                    "data: row {i} column {j} is {}, not a finite number",
                    r[j]
                ));
            }
        }
        let s = settings(timeout, max_nodes, false)?;
        let t0 = Instant::now();
        let points = sweep_with(&net, &rows, &es, reference, None, &s)
            .map_err(|e| Error::Samara(e.to_string()))?;
        let secs = t0.elapsed().as_secs_f64();
        let mut table = Vec::new();
        for e in &es {
            let mut row = Vec::new();
            for l in &ls {
                let c = if form == "published" {
                    published_cell(&points, *e, *l)
                } else {
                    lipschitz_cell(&points, *e, *l)
                };
                row.push(json!({"eps": e, "L": l, "proved": c.proved, "violated": c.violated, "unknown": c.unknown,
                    "success_rate": c.proved as f64 / rows.len().max(1) as f64}));
            }
            table.push(row);
        }
        let pts: Vec<Value> = points
            .iter()
            .map(|p| {
                json!({"index": p.index, "eps": p.eps, "f_min": p.f_min, "f_max": p.f_max,
                    "reference": p.reference, "max_deviation": p.max_deviation,
                    "lipschitz_lower": p.lipschitz_lower, "lipschitz_upper": p.lipschitz_upper})
            })
            .collect();
        Ok(json!({"form": form, "points": rows.len(), "seconds": secs, "table": table, "per_point": pts})
            .to_string())
    })?;
    Ok(r)
}

/// Read a CSV or IDX table as samara does (`samara_nn::data::read_table`): row-major
/// float64 bytes, rows, columns.
#[pyfunction]
fn read_table<'py>(py: Python<'py>, path: &str) -> PyResult<(Bound<'py, PyBytes>, usize, usize)> {
    let p = PathBuf::from(path);
    if !p.exists() {
        return Err(pyo3::exceptions::PyFileNotFoundError::new_err(format!(
            "{path}: no such file"
        )));
    }
    let t = samara_nn::data::read_table(&p).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let n = t.rows();
    let mut v = Vec::with_capacity(n * t.cols);
    for i in 0..n {
        v.extend_from_slice(t.row(i));
    }
    Ok((PyBytes::new(py, &f64_bytes(&v)), n, t.cols))
}

/// One flight for Python: dense rows (bytes), row width, initial state, rhs evaluations.
type FlightRows<'py> = (Bound<'py, PyBytes>, usize, Vec<f64>, usize);

/// Closed-loop flights as `samara simulate` flies them (no files): per start, the dense
/// output rows `t, ex, states...` as float64 bytes, the row width, the initial state and
/// the right-hand-side evaluations. `controller`: "pid", "constant" (with `ex`) or
/// "network" (with `network`, raw units in and out).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (model, controller, ex, network, clip, y0, integrator, horizon, period))]
fn simulate<'py>(
    py: Python<'py>,
    model: &str,
    controller: &str,
    ex: f64,
    network: Option<PyRef<'_, PyNetwork>>,
    clip: bool,
    y0: Option<Vec<f64>>,
    integrator: &str,
    horizon: f64,
    period: f64,
) -> PyResult<Vec<FlightRows<'py>>> {
    use samara_plant::{Model, Plant, EX_RANGE};
    use samara_sim::{
        fly, initial_state, published_starts, ConstantController, Controller, Integrator,
        LoopSettings, NetworkController, PidController,
    };
    let Some(model) = Model::from_name(model) else {
        return Err(PyValueError::new_err(format!(
            "model {model:?}: unknown model; choose one of plate6, reduced, full"
        )));
    };
    let Some(integ) = Integrator::from_name(integrator) else {
        return Err(PyValueError::new_err(format!(
            "integrator {integrator:?}: unknown integrator; choose ode45, tight, dp5 or rk4"
        )));
    };
    check_horizon_period(horizon, period, 1e-3, 100.0, 100_000.0)?;
    let plant = Plant::new(model);
    let mut ctl: Box<dyn Controller + Send> = match controller {
        "pid" => {
            if !model.has_filter() {
                return Err(PyValueError::new_err("controller 'pid' needs the filter state E, which model `reduced` does not have; use model='plate6' or 'full', or another controller"));
            }
            Box::new(PidController::default())
        }
        "constant" => {
            if !(EX_RANGE.0..=EX_RANGE.1).contains(&ex) {
                return Err(PyValueError::new_err(format!(
                    "controller=constant ex = {ex} is outside the allowed range [{}, {}]; choose a value inside it",
                    EX_RANGE.0, EX_RANGE.1
                )));
            }
            Box::new(ConstantController(ex))
        }
        "network" => {
            let Some(n) = network else {
                return Err(PyValueError::new_err("controller: a Network is needed"));
            };
            let net = controller_net(&n.net)?;
            let c = if clip { Some(EX_RANGE) } else { None };
            Box::new(NetworkController::new(net, c, "network"))
        }
        o => {
            return Err(PyValueError::new_err(format!(
                "controller {o:?}: expected 'pid', a number (a constant ex) or a samara.Network"
            )))
        }
    };
    let starts = match y0 {
        Some(v) => {
            if v.is_empty() || v.len() > 100_000 {
                return Err(PyValueError::new_err(format!(
                    "y0: {} starts; give 1 to 100000",
                    v.len()
                )));
            }
            if let Some(y) = v.iter().find(|y| !(y.is_finite() && y.abs() <= 1000.0)) {
                return Err(PyValueError::new_err(format!("y0: the height {y} is outside [-1000, 1000], the range in which the nondimensional model means anything (published starts: 1.43 to 4.29)")));
            }
            v
        }
        None => published_starts(),
    };
    let output_step = if (period / 0.01 - (period / 0.01).round()).abs() < 1e-9 {
        Some(0.01)
    } else {
        Some(period / 50.0)
    };
    let settings = LoopSettings {
        period,
        horizon,
        integrator: integ,
        reset_filter: true,
        output_step,
    };
    settings
        .steps()
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let flights = py.allow_threads(move || -> R<Vec<_>> {
        let mut out = Vec::with_capacity(starts.len());
        for &y in &starts {
            let init = initial_state(&plant, y);
            let f = fly(&plant, ctl.as_mut(), &init, &settings)
                .map_err(|e| Error::Samara(e.to_string()))?;
            out.push(f);
        }
        Ok(out)
    })?;
    Ok(flights
        .into_iter()
        .map(|f| {
            (
                PyBytes::new(py, &f64_bytes(&f.dense.data)),
                f.dense.dim + 2,
                f.initial,
                f.evals,
            )
        })
        .collect())
}

/// Taylor-model reachable sets of a system file's closed loop, as `samara reach --system`
/// computes them (with `--grid`, the cells `cells` of the grid; `samara_reach::grid`):
/// JSON text `{"cells": [start, end] | null, "total_cells": C | null, "reach": result}`.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (system, file, network, grid, cells, order, network_error, lifted_weight, lift_at, max_leaves, samples, seed, timeout))]
fn reach_system(
    py: Python<'_>,
    system: &str,
    file: &str,
    network: PyRef<'_, PyNetwork>,
    grid: HashMap<String, usize>,
    cells: Option<(usize, usize)>,
    order: usize,
    network_error: &str,
    lifted_weight: u32,
    lift_at: f64,
    max_leaves: usize,
    samples: usize,
    seed: u64,
    timeout: Option<f64>,
) -> PyResult<String> {
    use samara_reach::grid as g;
    use samara_reach::system::{end_band_measures, NetworkError, SystemReachSettings};
    let bad = |m: String| -> PyResult<String> { Err(PyValueError::new_err(m)) };
    let sys = samara_system::System::parse(system, file)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let net = network.net.clone();
    if !sys.fits_controller(net.n_inputs(), net.n_outputs()) {
        return bad(format!(
            "network: {} inputs and {} outputs; the system {file} observes {} values and reads {} network outputs: pass the controller made for it",
            net.n_inputs(),
            net.n_outputs(),
            sys.n_observed(),
            sys.n_net_outputs
        ));
    }
    if !(1..=8).contains(&order) {
        return bad(format!("order {order}: give 1 to 8 (3-5 is usual)"));
    }
    if !(1..=order as u32).contains(&lifted_weight) {
        return bad(format!(
            "lifted_weight {lifted_weight}: give 1 to the order ({order})"
        ));
    }
    if !(lift_at.is_finite() && lift_at > 0.0 && lift_at <= 1.0) {
        return bad(format!(
            "lift_at {lift_at}: give a share of the width in (0, 1]"
        ));
    }
    if !(1..=100_000).contains(&max_leaves) {
        return bad(format!("max_leaves {max_leaves}: give 1 to 100000"));
    }
    if !(1..=100_000).contains(&samples) {
        return bad(format!("samples {samples}: give 1 to 100000"));
    }
    if let Some(t) = timeout {
        if !(t.is_finite() && t > 0.0) {
            return bad(format!("timeout {t}: give a positive number of seconds"));
        }
    }
    let mut s = SystemReachSettings {
        order,
        max_boxes: max_leaves,
        samples,
        seed,
        timeout,
        network_error: NetworkError::parse(network_error)
            .map_err(|e| PyValueError::new_err(format!("network_error {network_error:?}: {e}")))?,
        measures: end_band_measures(&sys),
        ..SystemReachSettings::default()
    };
    s.flow.lift_at = lift_at;
    s.flow.lifted_weight = lifted_weight;
    let mut pieces = vec![1usize; sys.dim()];
    for (k, &n) in &grid {
        let Some(i) = sys.states.iter().position(|x| x == k) else {
            return bad(format!(
                "grid[{k:?}]: no such state; the states are {}",
                sys.states.join(", ")
            ));
        };
        pieces[i] = n;
    }
    let gridded = !grid.is_empty() || cells.is_some();
    let total = if gridded {
        Some(
            g::cell_count(&sys, &pieces)
                .map_err(|e| PyValueError::new_err(format!("grid: {e}")))?,
        )
    } else {
        None
    };
    let range = match (total, cells) {
        (Some(c), Some((a, b))) if a < b && b <= c => Some(a..b),
        (Some(c), Some((a, b))) => {
            return bad(format!(
                "cells ({a}, {b}): give start < end <= {c}, the grid's cells"
            ))
        }
        (Some(c), None) => Some(0..c),
        _ => None,
    };
    let r = py.allow_threads(|| match &range {
        None => samara_reach::system::reach_system(&sys, &net, &s),
        Some(r) => g::reach_cells(&sys, &net, &s, &pieces, r.clone()),
    });
    let r = r.map_err(|e| SamaraError::new_err(format!("{file}: {e}")))?;
    Ok(json!({
        "cells": range.map(|r| [r.start, r.end]),
        "total_cells": total,
        "reach": r,
    })
    .to_string())
}

/// Merge the results (JSON of `reach_system`) of consecutive cell ranges, in cell order,
/// into the result of their union (`samara_reach::grid::merge_parts`).
#[pyfunction]
fn merge_reach_system(parts: Vec<String>) -> PyResult<String> {
    use samara_reach::system::SystemReach;
    if parts.is_empty() {
        return Err(PyValueError::new_err("parts: give at least one result"));
    }
    let mut out: Vec<(usize, SystemReach)> = Vec::new();
    let (mut next, mut total) = (None::<usize>, None);
    for (i, text) in parts.iter().enumerate() {
        let v: Value = serde_json::from_str(text)
            .map_err(|e| PyValueError::new_err(format!("parts[{i}]: not a result: {e}")))?;
        let range = v["cells"]
            .as_array()
            .and_then(|a| Some((a.first()?.as_u64()? as usize, a.get(1)?.as_u64()? as usize)));
        let Some((a, b)) = range else {
            return Err(PyValueError::new_err(format!(
                "parts[{i}]: not a grid result (no cells)"
            )));
        };
        if next.is_some_and(|n| n != a)
            || (next.is_none() && a != 0)
            || total.is_some_and(|t| t != v["total_cells"])
        {
            return Err(PyValueError::new_err(format!(
                "parts[{i}]: cells {a}..{b} do not continue the parts before it; give the ranges of one grid in order from cell 0"
            )));
        }
        next = Some(b);
        total = Some(v["total_cells"].clone());
        let r: SystemReach = serde_json::from_value(v["reach"].clone())
            .map_err(|e| PyValueError::new_err(format!("parts[{i}]: not a result: {e}")))?;
        out.push((b - a, r));
    }
    let merged = samara_reach::grid::merge_parts(out);
    Ok(json!({"cells": [0, next], "total_cells": total, "reach": merged}).to_string())
}

/// A 6-input, 1-output controller network with the state names (as the CLI's loader).
fn controller_net(n: &samara_nn::Network) -> PyResult<samara_nn::Network> {
    if n.n_inputs() != 6 || n.n_outputs() != 1 {
        return Err(PyValueError::new_err(format!(
            "the network has {} inputs and {} outputs; a controller needs 6 raw inputs (v_xp, v_yp, omega, theta, x, y) and 1 output (ex)",
            n.n_inputs(),
            n.n_outputs()
        )));
    }
    n.clone()
        .with_names(&samara_nn::STATE_INPUTS, &["ex"])
        .map_err(|e| PyValueError::new_err(e.to_string()))
}

fn check_horizon_period(
    horizon: f64,
    period: f64,
    min_p: f64,
    max_p: f64,
    max_k: f64,
) -> PyResult<()> {
    let bad = |m: String| Err(PyValueError::new_err(m));
    if !(horizon.is_finite() && horizon > 0.0) {
        return bad(format!(
            "horizon {horizon}: the horizon must be positive (e.g. 20)"
        ));
    }
    if !(period.is_finite() && (min_p..=max_p).contains(&period)) {
        return bad(format!(
            "period {period}: the control period must lie in [{min_p}, {max_p}] (e.g. 0.5)"
        ));
    }
    let k = horizon / period;
    if k > max_k + 0.5 {
        return bad(format!(
            "horizon {horizon} / period {period} = {k} control periods; at most {max_k} are allowed"
        ));
    }
    if (k - k.round()).abs() > 1e-9 * k.max(1.0) || k.round() < 1.0 {
        return bad(format!(
            "horizon {horizon} is not a positive multiple of period {period}"
        ));
    }
    Ok(())
}

/// A reachability analysis as `samara reach` runs it (no files): JSON text with the
/// fields of `reach.json` (settings, verdict, final and sampled x + y, leaves with their
/// enclosures per control instant).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (network, model, init, horizon, period, goal_ystar, goal_from, clip, max_leaves, samples, seed))]
fn reach(
    py: Python<'_>,
    network: PyRef<'_, PyNetwork>,
    model: &str,
    init: HashMap<String, (f64, f64)>,
    horizon: f64,
    period: f64,
    goal_ystar: Option<f64>,
    goal_from: Option<f64>,
    clip: bool,
    max_leaves: Option<usize>,
    samples: Option<usize>,
    seed: Option<u64>,
) -> PyResult<String> {
    use samara_plant::{Model, STATE_NAMES};
    use samara_reach::{Goal, ReachSettings, Verdict as RV};
    let Some(m) = Model::from_name(model) else {
        return Err(PyValueError::new_err(format!(
            "model {model:?}: unknown model; choose one of reduced, plate6, full"
        )));
    };
    let mut s = ReachSettings::published(m);
    s.init[5] = (0.1 / 0.07, 0.3 / 0.07);
    let names = &STATE_NAMES[..m.dim()];
    for (k, &(lo, hi)) in &init {
        let Some(i) = names.iter().position(|n| n == k) else {
            return Err(PyValueError::new_err(format!(
                "init[{k:?}]: unknown state; choose one of {}",
                names.join(", ")
            )));
        };
        if !(lo.is_finite() && hi.is_finite() && lo <= hi && lo >= -1000.0 && hi <= 1000.0) {
            return Err(PyValueError::new_err(format!(
                "init[{k:?}] = ({lo}, {hi}): give finite ends lo <= hi in [-1000, 1000]"
            )));
        }
        s.init[i] = (lo, hi);
    }
    check_horizon_period(horizon, period, 1e-3, 10.0, 10_000.0)?;
    s.horizon = horizon;
    s.period = period;
    if !clip {
        s.clip = None;
    }
    match (goal_ystar, goal_from) {
        (None, Some(_)) => {
            return Err(PyValueError::new_err(
                "goal_from: needs a goal; pass goal_ystar too",
            ))
        }
        (Some(y), from) => {
            if !(y.is_finite() && y >= 0.0) {
                return Err(PyValueError::new_err(format!(
                    "goal_ystar {y}: the band half-width must be a finite number >= 0"
                )));
            }
            if let Some(f) = from {
                if !(f.is_finite() && f >= 0.0 && f <= horizon) {
                    return Err(PyValueError::new_err(format!(
                        "goal_from {f}: the window start must lie in [0, horizon = {horizon}]"
                    )));
                }
            }
            s.goal = Some(Goal { ystar: y, from });
        }
        (None, None) => {}
    }
    if let Some(n) = max_leaves {
        if n == 0 || n > 100_000 {
            return Err(PyValueError::new_err(format!(
                "max_leaves {n}: give 1 to 100000 (default 64)"
            )));
        }
        s.max_leaves = n;
    }
    if let Some(n) = samples {
        if n == 0 || n > 100_000 {
            return Err(PyValueError::new_err(format!(
                "samples {n}: give 1 to 100000 (default 200)"
            )));
        }
        s.samples = n;
    }
    if let Some(v) = seed {
        s.seed = v;
    }
    let net = controller_net(&network.net)?;
    s.validate(&net)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    // The checks `samara reach` makes on its inputs and result, from the same library
    // calls: a network in the wrong units, an enclosure lost before the horizon.
    let warnings: Vec<String> = s
        .units_warning(&net)
        .map(|w| format!("network: {w}"))
        .into_iter()
        .collect();
    let r = py.allow_threads(move || -> R<String> {
        let res = samara_reach::reach(&net, &s).map_err(|e| Error::Samara(e.to_string()))?;
        let lost = samara_reach::verdict::lost_enclosure(&res.leaves, &s);
        let num = |v: f64| if v.is_finite() { json!(v) } else { Value::Null };
        let verdict = match &res.verdict {
            RV::Proved => json!({ "verdict": "proved" }),
            RV::NoGoal => json!({ "verdict": "none" }),
            RV::Unknown { reason } => json!({ "verdict": "unknown", "reason": reason }),
            RV::Violated {
                initial,
                t,
                x_plus_y,
            } => json!({
                "verdict": "violated",
                "reason": format!("the simulated trajectory from {initial:?} has x + y = {x_plus_y} at t = {t}, outside the goal band"),
                "counterexample": { "initial": initial, "t": t, "x_plus_y": x_plus_y },
            }),
        };
        let mut init = serde_json::Map::new();
        for (i, (lo, hi)) in s.init.iter().enumerate() {
            init.insert(STATE_NAMES[i].to_string(), json!([lo, hi]));
        }
        Ok(json!({
            "settings": {"model": s.model.name(), "init": init, "horizon": s.horizon,
                "period": s.period, "clip": s.clip.map(|(lo, hi)| [lo, hi]),
                "reset_filter": s.reset_filter, "goal": s.goal.as_ref().map(|g| json!({"ystar": g.ystar, "from": g.from})),
                "max_leaves": s.max_leaves, "initial_splits": s.initial_splits,
                "samples": s.samples, "seed": s.seed},
            "verdict": verdict,
            "final_x_plus_y": [num(res.final_x_plus_y[0]), num(res.final_x_plus_y[1])],
            "sampled_x_plus_y": res.sampled_x_plus_y,
            "width_ratio": num(res.width_ratio()),
            "subproblems": res.subproblems(),
            "seconds": res.seconds,
            "sampled_trajectories": res.samples.len(),
            "state_names": &STATE_NAMES[..s.model.dim()],
            "leaves": serde_json::to_value(&res.leaves).map_err(|e| Error::Samara(e.to_string()))?,
            "warnings": warnings,
            "enclosure_lost": lost,
        })
        .to_string())
    })?;
    Ok(r)
}

/// Train a network as `samara train` does (methods plain, adversarial, lipschitz, dl2,
/// goedel with the built-in P1-P4); returns the network and the report as JSON text
/// (the fields of `samara train --json`, plus the log). `rows`: row-major float64
/// bytes, inputs then the output.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (rows, n, cols, normalisation, method, attack, arch, epochs, batch, lr, seed, eps, lipschitz, weight, ystar, max_restarts, min_r2))]
fn train(
    py: Python<'_>,
    rows: &[u8],
    n: usize,
    cols: usize,
    normalisation: Option<(Vec<f64>, Vec<f64>)>,
    method: &str,
    attack: &str,
    arch: Vec<usize>,
    epochs: usize,
    batch: usize,
    lr: f64,
    seed: u64,
    eps: f64,
    lipschitz: f64,
    weight: Option<f64>,
    ystar: f64,
    max_restarts: Option<usize>,
    min_r2: Option<f64>,
) -> PyResult<(PyNetwork, String)> {
    use samara_train::{Attack, Logic, Method, MinMax, Table, TrainOptions};
    let values = f64s(rows);
    if values.len() != n * cols || cols < 2 {
        return Err(PyValueError::new_err(format!(
            "data: {} values for {n} rows of {cols} columns (inputs, then the output)",
            values.len()
        )));
    }
    let data = Table {
        names: (0..cols).map(|j| format!("c{j}")).collect(),
        cols,
        values,
    };
    let mm = match normalisation {
        Some((min, range)) => {
            if min.len() != cols || range.len() != cols {
                return Err(PyValueError::new_err(format!(
                    "normalisation: {} minima and {} ranges for {cols} columns",
                    min.len(),
                    range.len()
                )));
            }
            MinMax { min, range }
        }
        None => MinMax::of(&data),
    };
    let method_v = match method {
        "plain" => Method::Plain,
        "adversarial" => Method::Adversarial(match attack {
            "fgsm" => Attack::Fgsm,
            "pgd" => Attack::Pgd { steps: 10 },
            other => {
                return Err(PyValueError::new_err(format!(
                    "attack {other:?}: choose 'fgsm' or 'pgd'"
                )))
            }
        }),
        "lipschitz" => Method::Lipschitz {
            l: lipschitz,
            weight: weight.unwrap_or(10.0),
        },
        "dl2" | "goedel" => {
            if cols != 7 || arch.first() != Some(&6) {
                return Err(PyValueError::new_err(format!("method {method:?}: the built-in properties P1-P4 need the case study's 6 inputs and 1 output")));
            }
            // P1-P4 as models/alsomitra/alsomitra.spec states them (compiled into
            // samara-train), lowered in the units of the network being trained, over the
            // box of the data, with ystar bound: what `samara train` does.
            let k = 6;
            let spec = samara_train::case_study_spec();
            let mut b = samara_spec::Bindings::default();
            b.params.insert("ystar".into(), ystar);
            let names: Vec<String> = spec
                .properties
                .iter()
                .filter(|p| p.binders.is_empty())
                .map(|p| p.name.clone())
                .collect();
            let data_mm = MinMax::of(&data);
            let domain: Vec<(f64, f64)> = (0..k)
                .map(|j| (data_mm.min[j], data_mm.min[j] + data_mm.range[j]))
                .collect();
            let props = samara_train::spec_properties(&spec, &names, &b, &mm, Some(domain))
                .map_err(|e| PyValueError::new_err(e.to_string()))?;
            Method::Properties {
                logic: if method == "dl2" {
                    Logic::Dl2
                } else {
                    Logic::Goedel
                },
                props,
                weight: weight.unwrap_or(1.0),
            }
        }
        other => {
            return Err(PyValueError::new_err(format!(
                "method {other:?}: choose plain, adversarial, lipschitz, dl2 or goedel (closed-loop: use the CLI)"
            )))
        }
    };
    let min_r2 = min_r2.unwrap_or(match method_v {
        Method::Plain | Method::Adversarial(_) => 0.9,
        _ => 0.0,
    });
    let mut o = TrainOptions {
        arch,
        epochs,
        batch,
        lr,
        seed,
        eps,
        method: method_v,
        progress: false,
        min_r2,
        ..Default::default()
    };
    if let Some(m) = max_restarts {
        o.max_restarts = m;
    }
    o.validate()
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let method = method.to_string();
    let (net, report) = py.allow_threads(move || -> R<_> {
        let outcome =
            samara_train::train(&data, Some(&mm), &o).map_err(|e| Error::Samara(e.to_string()))?;
        let mut net = outcome.network;
        if net.n_inputs() == 6 && net.n_outputs() == 1 {
            net = net
                .with_names(&samara_nn::STATE_INPUTS, &["ex"])
                .map_err(|e| Error::Samara(e.to_string()))?;
        }
        let m = &outcome.metrics;
        let restarts: Vec<Value> = outcome
            .restarts
            .iter()
            .map(|r| {
                json!({"attempt": r.attempt, "seed": r.seed, "epoch": r.epoch,
                    "reason": r.reason.to_string()})
            })
            .collect();
        let log: Vec<Value> = outcome
            .log
            .iter()
            .map(|r| json!([r.epoch, r.loss, r.test_rmse]))
            .collect();
        let report = json!({
            "method": method, "test_rows": m.n_test, "r2": m.r2, "r2_train": m.r2_train,
            "rmse": m.rmse, "mae": m.mae, "eps": o.eps,
            "attack_worst_deviation": m.attack_worst, "attack_mean_deviation": m.attack_mean,
            "seed": o.seed, "init_seed": outcome.init_seed,
            "restarts": outcome.restarts.len(), "restart_log": restarts, "log": log,
        });
        Ok((net, report.to_string()))
    })?;
    Ok((PyNetwork { net }, report))
}

#[pymodule]
fn _samara(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyNetwork>()?;
    m.add_class::<PySpec>()?;
    m.add_function(wrap_pyfunction!(robustness, m)?)?;
    m.add_function(wrap_pyfunction!(read_table, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(reach, m)?)?;
    m.add_function(wrap_pyfunction!(reach_system, m)?)?;
    m.add_function(wrap_pyfunction!(merge_reach_system, m)?)?;
    m.add_function(wrap_pyfunction!(train, m)?)?;
    m.add("SamaraError", m.py().get_type::<SamaraError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
