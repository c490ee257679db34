//! `samara._samara`: the native part of the `samara` Python package.
//!
//! The Python layer (`python/samara/__init__.py`) does the numpy and file handling; this
//! module takes plain bytes (float64, row-major), strings and dicts. Verification runs
//! through `samara-app`, the library the CLI runs too (no logic is copied): its typed
//! results come back as dicts of their fields, from which `samara` builds frozen
//! dataclasses. Long computations release the GIL; `verify` and `critical` also answer
//! Ctrl-C within a fraction of a second.

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use pyo3::BoundObject;
use samara_app::verify::{NamedValues, RowCounterexample};
use samara_app::{CriticalValue, Front, Loaded, VerdictRow};
use samara_verify::robustness::{sweep_with, Reference};
use samara_verify::{LpTighten, Settings};
use serde_json::Value;
use std::borrow::Cow;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

create_exception!(
    samara,
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
    /// The message in Python's words ([`Front::words`]: the keyword arguments where a
    /// library names the CLI's flags).
    fn from(e: Error) -> PyErr {
        match e {
            Error::Value(m) => PyValueError::new_err(Front::Python.words(&m)),
            Error::Samara(m) => SamaraError::new_err(Front::Python.words(&m)),
        }
    }
}

/// A library error as Python's `ValueError`, in Python's words ([`Front::words`]).
fn py_value_error(e: &impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(Front::Python.words(&e.to_string()))
}

/// A typed result as Python objects (dicts, lists, numbers, strings), built from its
/// serde tree with no JSON text in between; non-finite numbers (which serde writes as
/// `null`) become None.
fn typed_py<T: serde::Serialize>(py: Python<'_>, v: &T) -> PyResult<PyObject> {
    let v = serde_json::to_value(v).map_err(|e| SamaraError::new_err(e.to_string()))?;
    value_py(py, &v)
}

/// Python objects (what [`typed_py`] gives) back as a serde tree, to read a typed result
/// from; `where_` names the argument in messages.
fn py_value(o: &Bound<'_, PyAny>, where_: &str) -> PyResult<Value> {
    use pyo3::types::{PyBool, PyFloat, PyInt, PyString, PyTuple};
    Ok(if o.is_none() {
        Value::Null
    } else if let Ok(b) = o.downcast::<PyBool>() {
        Value::Bool(b.is_true())
    } else if let Ok(i) = o.downcast::<PyInt>() {
        match i.extract::<u64>() {
            Ok(u) => Value::from(u),
            Err(_) => Value::from(i.extract::<i64>()?),
        }
    } else if let Ok(x) = o.downcast::<PyFloat>() {
        serde_json::Number::from_f64(x.value()).map_or(Value::Null, Value::Number)
    } else if let Ok(t) = o.downcast::<PyString>() {
        Value::String(t.extract::<String>()?)
    } else if let Ok(d) = o.downcast::<PyDict>() {
        let mut m = serde_json::Map::new();
        for (k, v) in d.iter() {
            let k: String = k.extract()?;
            let at = format!("{where_}[{k:?}]");
            m.insert(k, py_value(&v, &at)?);
        }
        Value::Object(m)
    } else if let Ok(l) = o.downcast::<PyList>() {
        let items = l
            .iter()
            .enumerate()
            .map(|(i, v)| py_value(&v, &format!("{where_}[{i}]")));
        Value::Array(items.collect::<PyResult<_>>()?)
    } else if let Ok(t) = o.downcast::<PyTuple>() {
        let items = t
            .iter()
            .enumerate()
            .map(|(i, v)| py_value(&v, &format!("{where_}[{i}]")));
        Value::Array(items.collect::<PyResult<_>>()?)
    } else {
        return Err(PyValueError::new_err(format!(
            "{where_}: a {} is not part of a samara result",
            o.get_type().name()?
        )));
    })
}

/// A result of `reach_system`: the cells `[start, end)` of a grid run (`None` without a
/// grid), the grid's cell count and the cells' merged result.
#[derive(serde::Serialize, serde::Deserialize)]
struct GridPart {
    cells: Option<(usize, usize)>,
    total_cells: Option<usize>,
    reach: samara_reach::system::SystemReach,
}

fn value_py(py: Python<'_>, v: &Value) -> PyResult<PyObject> {
    Ok(match v {
        Value::Null => py.None(),
        Value::Bool(b) => obj(py, *b)?,
        Value::Number(n) => match (n.as_u64(), n.as_i64()) {
            (Some(u), _) => obj(py, u)?,
            (None, Some(i)) => obj(py, i)?,
            _ => obj(py, n.as_f64().unwrap_or(f64::NAN))?,
        },
        Value::String(t) => obj(py, t.as_str())?,
        Value::Array(a) => {
            let items = a
                .iter()
                .map(|x| value_py(py, x))
                .collect::<PyResult<Vec<_>>>()?;
            PyList::new(py, items)?.into_any().unbind()
        }
        Value::Object(m) => {
            let d = PyDict::new(py);
            for (k, x) in m {
                d.set_item(k, value_py(py, x)?)?;
            }
            d.into_any().unbind()
        }
    })
}

impl From<samara_app::AppError> for Error {
    fn from(e: samara_app::AppError) -> Error {
        match e {
            samara_app::AppError::Input(m) => Error::Value(m),
            e => Error::Samara(e.to_string()),
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
            .map_err(|e| py_value_error(&e))?;
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
        let spec =
            samara_spec::Spec::parse(text, file, Path::new(dir)).map_err(|e| py_value_error(&e))?;
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

    /// Verify properties (all, or `property`): one dict of a verdict row's fields per
    /// instance (the typed rows of `samara_app::run_verify`, the fields of
    /// `samara verify --json`), and the warnings. Ctrl-C interrupts it.
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (networks, params, datasets, property, timeout, max_nodes, lp_tighten))]
    fn verify<'py>(
        &self,
        py: Python<'py>,
        networks: HashMap<String, PyRef<'_, PyNetwork>>,
        params: HashMap<String, f64>,
        datasets: HashMap<String, String>,
        property: Option<String>,
        timeout: f64,
        max_nodes: usize,
        lp_tighten: bool,
    ) -> PyResult<(Vec<Bound<'py, PyDict>>, Vec<String>)> {
        let nets: HashMap<String, samara_nn::Network> = networks
            .into_iter()
            .map(|(k, v)| (k, v.net.clone()))
            .collect();
        let spec = self.spec.clone();
        let (run, warnings) = interruptible(py, move || {
            let start = Instant::now();
            let l = bind(&spec, nets, &params, None, &datasets)?;
            let s = settings(timeout, max_nodes, lp_tighten)?;
            let run = samara_app::run_verify(&l, property.as_deref(), &s, start, false, |_| {})?;
            Ok((run, l.warnings))
        })?;
        let rows = run
            .rows()
            .map(|r| row_py(py, r))
            .collect::<PyResult<Vec<_>>>()?;
        Ok((rows, warnings))
    }

    /// The critical value of parameter `param` for `property`: the fields of the typed
    /// `samara_app::CriticalValue` (as `samara critical --json`), and the warnings.
    /// Ctrl-C interrupts it.
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (property, param, networks, params, datasets, timeout, max_nodes, lp_tighten))]
    fn critical<'py>(
        &self,
        py: Python<'py>,
        property: String,
        param: String,
        networks: HashMap<String, PyRef<'_, PyNetwork>>,
        params: HashMap<String, f64>,
        datasets: HashMap<String, String>,
        timeout: f64,
        max_nodes: usize,
        lp_tighten: bool,
    ) -> PyResult<(Bound<'py, PyDict>, Vec<String>)> {
        let nets: HashMap<String, samara_nn::Network> = networks
            .into_iter()
            .map(|(k, v)| (k, v.net.clone()))
            .collect();
        let spec = self.spec.clone();
        let (c, warnings) = interruptible(py, move || {
            let l = bind(&spec, nets, &params, Some(&param), &datasets)?;
            let s = settings(timeout, max_nodes, lp_tighten)?;
            let c = samara_app::critical_value(&l, &property, &param, &s)?;
            Ok((c, l.warnings))
        })?;
        Ok((critical_py(py, &c)?, warnings))
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

/// Bind a spec's networks, parameters and data sets with the library's checks
/// ([`samara_app::Loaded`]), each named as the Python argument (`networks["f"]`,
/// `params["ystar"]`, `datasets["train"]`). `free`: the parameter to search.
fn bind<'a>(
    spec: &'a samara_spec::Spec,
    nets: HashMap<String, samara_nn::Network>,
    params: &HashMap<String, f64>,
    free: Option<&str>,
    datasets: &HashMap<String, String>,
) -> R<Loaded<'a>> {
    let mut l = Loaded::new(Cow::Borrowed(spec), spec.file.clone(), Front::Python);
    let mut names: Vec<(String, samara_nn::Network)> = nets.into_iter().collect();
    names.sort_by(|a, b| a.0.cmp(&b.0));
    for (k, net) in names {
        l.bind_network(&k, net, &format!("networks[{k:?}]"), None)?;
    }
    if let Some(k) = free {
        l.declared_param(k, &format!("param {k:?}"))?;
    }
    let mut ps: Vec<(&String, &f64)> = params.iter().collect();
    ps.sort_by(|a, b| a.0.cmp(b.0));
    for (k, &x) in ps {
        l.bind_param(k, x, &format!("params[{k:?}]"), free)?;
    }
    let mut l = l.finish("params")?;
    let mut ds: Vec<(&String, &String)> = datasets.iter().collect();
    ds.sort();
    for (k, v) in ds {
        l.bind_dataset(k, Path::new(v), &format!("datasets[{k:?}] = {v:?}"))?;
    }
    Ok(l)
}

/// Run `work` on a thread of its own while this one waits with the GIL released,
/// checking for signals every 50 ms: Ctrl-C raises `KeyboardInterrupt` within a
/// fraction of a second instead of after the computation. (The abandoned computation
/// runs on until its own time limit; its result is dropped.)
fn interruptible<T: Send + 'static>(
    py: Python<'_>,
    work: impl FnOnce() -> R<T> + Send + 'static,
) -> PyResult<T> {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(work());
    });
    let rx = std::sync::Mutex::new(rx);
    let wait = || {
        rx.lock()
            .expect("only this thread locks it")
            .recv_timeout(std::time::Duration::from_millis(50))
    };
    loop {
        match py.allow_threads(wait) {
            Ok(r) => return r.map_err(PyErr::from),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => py.check_signals()?,
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                return Err(SamaraError::new_err(
                    "the computation's thread ended without a result (a panic: please report it)",
                ))
            }
        }
    }
}

/// A Python object of a Rust value.
fn obj<'py, T>(py: Python<'py>, v: T) -> PyResult<PyObject>
where
    T: IntoPyObject<'py>,
    T::Error: Into<PyErr>,
{
    Ok(v.into_pyobject(py)
        .map_err(Into::into)?
        .into_bound()
        .into_any()
        .unbind())
}

/// A dict of `(key, value)` pairs.
fn dict<'py>(py: Python<'py>, items: Vec<(&str, PyObject)>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, v) in items {
        d.set_item(k, v)?;
    }
    Ok(d)
}

/// A reason as `{'kind', 'message'}`.
fn reason_py(py: Python<'_>, r: &Option<samara_app::Reason>) -> PyResult<PyObject> {
    match r {
        None => Ok(py.None()),
        Some(r) => Ok(dict(
            py,
            vec![
                ("kind", obj(py, r.kind.clone())?),
                ("message", obj(py, r.message.clone())?),
            ],
        )?
        .into_any()
        .unbind()),
    }
}

/// A named point as a list of `{'network', 'values': {name: value}}`.
fn point_py(py: Python<'_>, p: &[NamedValues]) -> PyResult<PyObject> {
    let mut out = Vec::new();
    for a in p {
        let values = PyDict::new(py);
        for (k, v) in &a.values {
            values.set_item(k, v)?;
        }
        out.push(dict(
            py,
            vec![
                ("network", obj(py, a.network.clone())?),
                ("values", values.into_any().unbind()),
            ],
        )?);
    }
    Ok(PyList::new(py, out)?.into_any().unbind())
}

/// The fields of a verdict row (the typed [`VerdictRow`]), for `samara.VerifyResult`.
fn row_py<'py>(py: Python<'py>, r: &VerdictRow) -> PyResult<Bound<'py, PyDict>> {
    let cx = match &r.counterexample {
        None => py.None(),
        Some(RowCounterexample::Point {
            point,
            margin,
            exact_check,
        }) => dict(
            py,
            vec![
                ("point", point_py(py, point)?),
                ("margin", obj(py, *margin)?),
                ("exact_check", obj(py, *exact_check)?),
            ],
        )?
        .into_any()
        .unbind(),
        Some(RowCounterexample::Reason { reason }) => {
            dict(py, vec![("reason", obj(py, reason.clone())?)])?
                .into_any()
                .unbind()
        }
    };
    dict(
        py,
        vec![
            ("property", obj(py, r.property.clone())?),
            ("verdict", obj(py, r.verdict.text())?),
            ("counterexample", cx),
            ("seconds", obj(py, r.seconds)?),
            ("vacuous", obj(py, r.vacuous)?),
            ("vacuity", obj(py, r.vacuity.clone())?),
            ("unknown_reason", reason_py(py, &r.unknown_reason)?),
        ],
    )
}

/// The fields of a critical value (the typed [`CriticalValue`]), for
/// `samara.CriticalResult`.
fn critical_py<'py>(py: Python<'py>, c: &CriticalValue) -> PyResult<Bound<'py, PyDict>> {
    let witness = match &c.witness {
        Some(w) => point_py(py, w)?,
        None => py.None(),
    };
    dict(
        py,
        vec![
            ("property", obj(py, c.property.clone())?),
            ("parameter", obj(py, c.parameter.clone())?),
            ("holds", obj(py, c.holds.text())?),
            ("critical", obj(py, c.critical)?),
            ("bound", obj(py, c.bound)?),
            ("threshold", obj(py, c.threshold)?),
            ("attained", obj(py, c.attained)?),
            ("vacuous", obj(py, c.vacuous)?),
            ("domain_extreme", obj(py, c.domain_extreme)?),
            (
                "counterexample_range",
                obj(py, (c.counterexample_range[0], c.counterexample_range[1]))?,
            ),
            ("witness", witness),
            ("complete", obj(py, c.complete)?),
            ("unknown_reason", reason_py(py, &c.unknown_reason)?),
            ("seconds", obj(py, c.seconds)?),
        ],
    )
}

/// The robustness table of `samara robustness --json` (plus the per-point results):
/// `rows` row-major float64 bytes of `n` rows and `cols` columns (inputs, then the label).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (network, rows, n, cols, eps, lipschitz, reference, form, timeout, max_nodes))]
fn robustness<'py>(
    py: Python<'py>,
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
) -> PyResult<Bound<'py, PyDict>> {
    let net = network.net.clone();
    let data = f64s(rows);
    let reference = reference.to_string();
    let form = form.to_string();
    let (table, points) = interruptible(py, move || {
        if data.len() != n * cols {
            return value(format!(
                "data: {} values for {n} rows of {cols}",
                data.len()
            ));
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
        let form = samara_app::robustness::Form::parse(&form).expect("checked above");
        let table = samara_app::robustness::Table::of(form, &es, &ls, rows.len(), secs, &points);
        Ok((table, points))
    })?;
    robustness_py(py, &table, &points)
}

/// The fields of a robustness table (the typed [`samara_app::robustness::Table`]) and
/// the per-point results, for `samara.RobustnessResult`.
fn robustness_py<'py>(
    py: Python<'py>,
    t: &samara_app::robustness::Table,
    points: &[samara_verify::robustness::PointBall],
) -> PyResult<Bound<'py, PyDict>> {
    let mut rows = Vec::new();
    for row in &t.table {
        let mut cells = Vec::new();
        for c in row {
            cells.push(dict(
                py,
                vec![
                    ("eps", obj(py, c.eps)?),
                    ("L", obj(py, c.l)?),
                    ("proved", obj(py, c.proved)?),
                    ("violated", obj(py, c.violated)?),
                    ("unknown", obj(py, c.unknown)?),
                    ("success_rate", obj(py, c.success_rate)?),
                ],
            )?);
        }
        rows.push(PyList::new(py, cells)?);
    }
    let mut pts = Vec::new();
    for p in points {
        pts.push(dict(
            py,
            vec![
                ("index", obj(py, p.index)?),
                ("eps", obj(py, p.eps)?),
                ("f_min", obj(py, p.f_min)?),
                ("f_max", obj(py, p.f_max)?),
                ("reference", obj(py, p.reference)?),
                ("max_deviation", obj(py, p.max_deviation)?),
                ("lipschitz_lower", obj(py, p.lipschitz_lower)?),
                ("lipschitz_upper", obj(py, p.lipschitz_upper)?),
            ],
        )?);
    }
    dict(
        py,
        vec![
            ("form", obj(py, t.form.text())?),
            ("points", obj(py, t.points)?),
            ("seconds", obj(py, t.seconds)?),
            ("table", obj(py, PyList::new(py, rows)?)?),
            ("per_point", obj(py, PyList::new(py, pts)?)?),
        ],
    )
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
    let t = samara_nn::data::read_table(&p).map_err(|e| py_value_error(&e))?;
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
    check_horizon_period(horizon, period, samara_app::bind::MAX_PERIOD, 100_000.0)?;
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
    settings.steps().map_err(|e| py_value_error(&e))?;
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
/// `{"cells": (start, end) | None, "total_cells": C | None, "reach": result}` (a typed
/// [`GridPart`] as Python objects).
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
) -> PyResult<PyObject> {
    use samara_reach::grid as g;
    use samara_reach::system::{end_band_measures, NetworkError, SystemReachSettings};
    let bad = |m: String| -> PyResult<PyObject> { Err(PyValueError::new_err(m)) };
    let sys = samara_system::System::parse(system, file).map_err(|e| py_value_error(&e))?;
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
    let part = GridPart {
        cells: range.map(|r| (r.start, r.end)),
        total_cells: total,
        reach: r,
    };
    typed_py(py, &part)
}

/// Merge the results of `reach_system` over consecutive cell ranges, in cell order,
/// into the result of their union (`samara_reach::grid::merge_parts`).
#[pyfunction]
fn merge_reach_system(py: Python<'_>, parts: Vec<Bound<'_, PyAny>>) -> PyResult<PyObject> {
    if parts.is_empty() {
        return Err(PyValueError::new_err("parts: give at least one result"));
    }
    let mut out: Vec<(usize, samara_reach::system::SystemReach)> = Vec::new();
    let (mut next, mut total) = (None::<usize>, None);
    for (i, p) in parts.iter().enumerate() {
        let at = format!("parts[{i}]");
        let v: GridPart = serde_json::from_value(py_value(p, &at)?)
            .map_err(|e| PyValueError::new_err(format!("{at}: not a result: {e}")))?;
        let Some((a, b)) = v.cells else {
            return Err(PyValueError::new_err(format!(
                "{at}: not a grid result (no cells)"
            )));
        };
        if next.is_some_and(|n| n != a)
            || (next.is_none() && a != 0)
            || total.is_some_and(|t| t != v.total_cells)
        {
            return Err(PyValueError::new_err(format!(
                "{at}: cells {a}..{b} do not continue the parts before it; give the ranges of one grid in order from cell 0"
            )));
        }
        next = Some(b);
        total = Some(v.total_cells);
        out.push((b - a, v.reach));
    }
    let merged = GridPart {
        cells: next.map(|n| (0, n)),
        total_cells: total.flatten(),
        reach: samara_reach::grid::merge_parts(out),
    };
    typed_py(py, &merged)
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
        .map_err(|e| py_value_error(&e))
}

/// The horizon and period of a closed-loop run: the library's checks
/// ([`samara_app::check_horizon_period`], at most `max_k` periods), a period of at most
/// `max_p` (reach: 10, simulate: the library's 100) and a whole number of periods.
fn check_horizon_period(horizon: f64, period: f64, max_p: f64, max_k: f64) -> PyResult<()> {
    samara_app::check_horizon_period(Front::Python, horizon, period).map_err(Error::from)?;
    if period > max_p {
        return Err(PyValueError::new_err(format!(
            "period {period}: the control period must lie in [{}, {max_p}] (e.g. period=0.5)",
            samara_app::bind::MIN_PERIOD
        )));
    }
    samara_app::bind::check_period_count(Front::Python, horizon, period, max_k)
        .map_err(Error::from)?;
    let k = horizon / period;
    if (k - k.round()).abs() > 1e-9 * k.max(1.0) || k.round() < 1.0 {
        return Err(PyValueError::new_err(format!(
            "horizon {horizon} is not a positive multiple of period {period}"
        )));
    }
    Ok(())
}

/// A reachability analysis as `samara reach` runs it (no files): the typed `reach.json`
/// (`samara_app::reach::ReachReport`: settings, verdict, final and sampled x + y, leaves
/// with their enclosures per control instant) as Python objects.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (network, model, init, horizon, period, goal_ystar, goal_from, clip, max_leaves, samples, seed, network_name, threads))]
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
    network_name: String,
    threads: Option<usize>,
) -> PyResult<PyObject> {
    use samara_plant::{Model, STATE_NAMES};
    if threads.is_some_and(|t| !(1..=1024).contains(&t)) {
        return Err(PyValueError::new_err(format!(
            "threads={}: give 1 to 1024 worker threads (None: all cores)",
            threads.unwrap_or(0)
        )));
    }
    use samara_reach::{Goal, ReachSettings};
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
    check_horizon_period(horizon, period, 10.0, 10_000.0)?;
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
    s.validate(&net).map_err(|e| py_value_error(&e))?;
    // The checks `samara reach` makes on its inputs and result, from the same library
    // calls: a network in the wrong units, an enclosure lost before the horizon.
    let warnings: Vec<String> = s
        .units_warning(&net)
        .map(|w| format!("network: {w}"))
        .into_iter()
        .collect();
    let r = py.allow_threads(move || -> R<samara_app::reach::ReachReport> {
        // A pool of `threads` workers (as `samara reach --threads`), else the global one.
        let pool = match threads {
            Some(t) => Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(t)
                    .build()
                    .map_err(|e| Error::Samara(format!("threads={t}: {e}")))?,
            ),
            None => None,
        };
        let n_threads = threads.unwrap_or_else(rayon::current_num_threads);
        let run = || samara_reach::reach(&net, &s);
        let res = match &pool {
            Some(p) => p.install(run),
            None => run(),
        }
        .map_err(|e| Error::Samara(e.to_string()))?;
        let o = samara_app::reach::Outcome::of(&res, &s, warnings);
        let echo = samara_app::reach::SettingsEcho::new(&network_name, n_threads, &s);
        Ok(samara_app::reach::ReachReport::new(
            echo, &s, &o, res.leaves,
        ))
    })?;
    typed_py(py, &r)
}

/// Train a network as `samara train` does (methods plain, adversarial, lipschitz, dl2,
/// goedel with the built-in P1-P4); returns the network and the typed report
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
) -> PyResult<(PyNetwork, PyObject)> {
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
                .map_err(|e| py_value_error(&e))?;
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
    o.validate().map_err(|e| py_value_error(&e))?;
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
        let report = TrainReport {
            method,
            test_rows: m.n_test,
            r2: m.r2,
            r2_train: m.r2_train,
            rmse: m.rmse,
            mae: m.mae,
            eps: o.eps,
            attack_worst_deviation: m.attack_worst,
            attack_mean_deviation: m.attack_mean,
            seed: o.seed,
            init_seed: outcome.init_seed,
            restarts: outcome.restarts.len(),
            restart_log: outcome
                .restarts
                .iter()
                .map(samara_app::train::RestartEntry::from)
                .collect(),
            log: outcome
                .log
                .iter()
                .map(|r| (r.epoch, r.loss, r.test_rmse))
                .collect(),
        };
        Ok((net, report))
    })?;
    Ok((PyNetwork { net }, typed_py(py, &report)?))
}

/// The report of [`train`]: the fields of `samara train --json` (without the file
/// paths), the training R^2, and the log as (epoch, loss, test RMSE) rows.
#[derive(serde::Serialize)]
struct TrainReport {
    method: String,
    test_rows: usize,
    r2: f64,
    r2_train: f64,
    rmse: f64,
    mae: f64,
    eps: f64,
    attack_worst_deviation: f64,
    attack_mean_deviation: f64,
    seed: u64,
    init_seed: u64,
    restarts: usize,
    restart_log: Vec<samara_app::train::RestartEntry>,
    log: Vec<(usize, f64, f64)>,
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
