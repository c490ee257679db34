//! `samara._samara`: the native part of the `samara` Python package.
//!
//! The Python layer (`python/samara/__init__.py`) does the numpy and file handling; this
//! module takes plain bytes (float64, row-major), strings and dicts. Every computation
//! and every check of an argument is a call of `samara-app` (mostly its
//! `python_front`), the library the CLI runs too: nothing here is copied from the CLI.
//! Typed results come back as the Python objects of their serde fields ([`topy`]: no
//! JSON text, non-finite floats kept), from which `samara` builds its frozen result
//! classes; [`frompy`] reads them back for a merge. Long computations release the GIL;
//! every call that computes (`verify`, `critical`, `robustness`, `simulate`, `reach`,
//! `reach_system`, `train`) also answers Ctrl-C within a fraction of a second.

mod frompy;
mod topy;

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use samara_app::python_front::{self as front, GridPart, InWords, ReachRequest, TrainReport};
use samara_app::{Front, Loaded};
use samara_verify::Settings;
use std::borrow::Cow;
use std::collections::BTreeMap;
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

impl From<samara_app::AppError> for Error {
    fn from(e: samara_app::AppError) -> Error {
        match e {
            samara_app::AppError::Input(m) => Error::Value(m),
            e => Error::Samara(e.to_string()),
        }
    }
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
    #[pyo3(signature = (networks, params, datasets, property, timeout, max_nodes))]
    fn verify<'py>(
        &self,
        py: Python<'py>,
        networks: HashMap<String, PyRef<'_, PyNetwork>>,
        params: HashMap<String, f64>,
        datasets: HashMap<String, String>,
        property: Option<String>,
        timeout: f64,
        max_nodes: usize,
    ) -> PyResult<(Vec<PyObject>, Vec<String>)> {
        let nets = owned(networks);
        let spec = self.spec.clone();
        let (run, warnings) = interruptible(py, move || {
            let start = Instant::now();
            let l = bind(&spec, nets, &params, None, &datasets)?;
            let s = settings(timeout, max_nodes)?;
            let run = samara_app::run_verify(&l, property.as_deref(), &s, start, false, |_| {})?;
            Ok((run, python_words(l.warnings)))
        })?;
        let rows = run
            .rows()
            .map(|r| topy::to_py(py, &r.clone().in_words(Front::Python)))
            .collect::<PyResult<Vec<_>>>()?;
        Ok((rows, warnings))
    }

    /// The critical value of parameter `param` for `property`: the fields of the typed
    /// `samara_app::CriticalValue` (as `samara critical --json`), and the warnings.
    /// Ctrl-C interrupts it.
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (property, param, networks, params, datasets, timeout, max_nodes))]
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
    ) -> PyResult<(PyObject, Vec<String>)> {
        let nets = owned(networks);
        let spec = self.spec.clone();
        let (c, warnings) = interruptible(py, move || {
            let l = bind(&spec, nets, &params, Some(&param), &datasets)?;
            let s = settings(timeout, max_nodes)?;
            let c = samara_app::critical_value(&l, &property, &param, &s)?;
            Ok((c, python_words(l.warnings)))
        })?;
        Ok((topy::to_py(py, &c.in_words(Front::Python))?, warnings))
    }
}

/// Messages in Python's words ([`Front::words`]).
fn python_words(ms: Vec<String>) -> Vec<String> {
    ms.iter().map(|m| Front::Python.words(m)).collect()
}

/// The networks of a `networks={...}` argument, owned (the computation runs on a
/// thread of its own).
fn owned(networks: HashMap<String, PyRef<'_, PyNetwork>>) -> HashMap<String, samara_nn::Network> {
    networks
        .into_iter()
        .map(|(k, v)| (k, v.net.clone()))
        .collect()
}

/// The verifier's settings ([`front::verify_settings`]).
fn settings(timeout: f64, max_nodes: usize) -> R<Settings> {
    Ok(front::verify_settings(Front::Python, timeout, max_nodes)?)
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
/// runs on in the background until its own time limit or its end; its result is
/// dropped.) The thread gets the 8 MiB stack of a main thread, not a spawned thread's
/// 2 MiB, as the call ran on Python's main thread before.
fn interruptible<T: Send + 'static>(
    py: Python<'_>,
    work: impl FnOnce() -> R<T> + Send + 'static,
) -> PyResult<T> {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::Builder::new()
        .name("samara-call".into())
        .stack_size(8 << 20)
        .spawn(move || {
            let _ = tx.send(work());
        })
        .map_err(|e| SamaraError::new_err(format!("could not start the computation: {e}")))?;
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

/// The robustness table of `samara robustness --json` plus the per-point rows (the
/// typed `samara_app::python_front::RobustnessReport`): `rows` row-major float64 bytes
/// of `n` rows and `cols` columns (inputs, then the label). Ctrl-C interrupts it.
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
    reference: String,
    form: String,
    timeout: f64,
    max_nodes: usize,
) -> PyResult<PyObject> {
    let net = network.net.clone();
    let data = f64s(rows);
    let report = interruptible(py, move || {
        let s = settings(timeout, max_nodes)?;
        let r = front::robustness(
            Front::Python,
            &net,
            &data,
            n,
            cols,
            &eps,
            &lipschitz,
            &reference,
            &form,
            &s,
        )?;
        Ok(r)
    })?;
    topy::to_py(py, &report)
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
    model: String,
    controller: &str,
    ex: f64,
    network: Option<PyRef<'_, PyNetwork>>,
    clip: bool,
    y0: Option<Vec<f64>>,
    integrator: String,
    horizon: f64,
    period: f64,
) -> PyResult<Vec<FlightRows<'py>>> {
    use front::ControllerRequest as C;
    let controller = match (controller, network) {
        ("pid", _) => C::Pid,
        ("constant", _) => C::Constant(ex),
        ("network", Some(n)) => C::Network {
            net: n.net.clone(),
            clip,
        },
        ("network", None) => return Err(PyValueError::new_err("controller: a Network is needed")),
        (o, _) => {
            return Err(PyValueError::new_err(format!(
                "controller {o:?}: expected 'pid', a number (a constant ex) or a samara.Network"
            )))
        }
    };
    let plan = front::SimulateRequest {
        model,
        controller,
        y0,
        integrator,
        horizon,
        period,
    }
    .plan(Front::Python, 100_000.0)
    .map_err(Error::from)?;
    let flights = interruptible(py, move || plan.fly().map_err(Error::Samara))?;
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
/// computes them (with `grid`, the cells `cells` of the grid; `samara_reach::grid`):
/// the typed `samara_app::python_front::GridPart` (`cells`, `total_cells`, `reach`) as
/// Python objects. The arguments are checked by `python_front::SystemRequest`.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (system, file, network, grid, cells, order, network_error, lifted_weight, lift_at, max_leaves, samples, seed, timeout, time_order=None, step_tol=None))]
fn reach_system(
    py: Python<'_>,
    system: &str,
    file: &str,
    network: PyRef<'_, PyNetwork>,
    grid: BTreeMap<String, usize>,
    cells: Option<(usize, usize)>,
    order: usize,
    network_error: String,
    lifted_weight: u32,
    lift_at: f64,
    max_leaves: usize,
    samples: usize,
    seed: u64,
    timeout: Option<f64>,
    time_order: Option<i64>,
    step_tol: Option<f64>,
) -> PyResult<PyObject> {
    let sys = samara_system::System::parse(system, file).map_err(|e| py_value_error(&e))?;
    let net = network.net.clone();
    let req = front::SystemRequest {
        grid,
        cells,
        order,
        network_error,
        lifted_weight,
        lift_at,
        max_leaves,
        samples,
        seed,
        timeout,
        time_order,
        step_tol,
    };
    let plan = req
        .plan(Front::Python, &sys, file, &net)
        .map_err(Error::from)?;
    let file = file.to_string();
    let part = interruptible(py, move || {
        plan.run(&sys, &net)
            .map_err(|e| Error::Samara(format!("{file}: {e}")))
    })?;
    topy::to_py(py, &part.in_words(Front::Python))
}

/// Shard `shard = (i, n)` of an adaptive run (`samara reach --system ... --target-ratio
/// R --grid ... --shard I/N`): the grid's starting cells `i` mod `n` split until their
/// measure meets the target, resuming from (and appending to) `checkpoint` if given
/// (`samara_app::reach::adaptive::run_shard`). Returns the shard document (JSON text),
/// which `merge_adaptive_shards` joins.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (system, file, network, grid, shard, target_ratio, order, network_error, lifted_weight, lift_at, max_leaves, samples, seed, timeout, checkpoint, time_order=None, step_tol=None))]
fn reach_adaptive_shard(
    py: Python<'_>,
    system: &str,
    file: &str,
    network: PyRef<'_, PyNetwork>,
    grid: BTreeMap<String, usize>,
    shard: (usize, usize),
    target_ratio: f64,
    order: usize,
    network_error: String,
    lifted_weight: u32,
    lift_at: f64,
    max_leaves: usize,
    samples: usize,
    seed: u64,
    timeout: Option<f64>,
    checkpoint: Option<PathBuf>,
    time_order: Option<i64>,
    step_tol: Option<f64>,
) -> PyResult<String> {
    let sys = samara_system::System::parse(system, file).map_err(|e| py_value_error(&e))?;
    let net = network.net.clone();
    let (i, n) = shard;
    if n == 0 || i >= n {
        return Err(PyValueError::new_err(format!(
            "shard=({i}, {n}): give 0 <= i < n"
        )));
    }
    if grid.is_empty() {
        return Err(PyValueError::new_err(
            "grid: an adaptive run is sharded by the starting cells of a grid; give grid={state: pieces}",
        ));
    }
    let req = front::SystemRequest {
        grid,
        cells: None,
        order,
        network_error,
        lifted_weight,
        lift_at,
        max_leaves,
        samples,
        seed,
        timeout,
        time_order,
        step_tol,
    };
    let plan = req
        .plan(Front::Python, &sys, file, &net)
        .map_err(Error::from)?;
    let digest = samara_app::shard::digest(&prost_encode(samara_nn::onnx::export(
        &net,
        &samara_nn::onnx::ExportOptions {
            float64: true,
            ..Default::default()
        },
    )));
    let file = file.to_string();
    interruptible(py, move || {
        use samara_app::reach::adaptive::{run_shard, ShardRun};
        let sh = samara_app::shard::Shard { i, n };
        let done = run_shard(ShardRun {
            sys: &sys,
            net: &net,
            settings: &plan.settings,
            pieces: &plan.pieces,
            target_ratio,
            shard: sh,
            checkpoint: checkpoint.as_deref(),
            system_name: file.clone(),
            network_name: "network".into(),
            network_digest: digest,
            on_round: None,
        })
        .map_err(Error::from)?;
        samara_app::shard::document("reach", sh, &done.run, &done.result).map_err(Error::from)
    })
}

/// Join the documents of every shard of one adaptive run into the text of the
/// `reach.json` one process writes (`samara_app::reach::adaptive::merge_documents`;
/// refused where the merge would not be the one-process result).
#[pyfunction]
fn merge_adaptive_shards(docs: Vec<String>) -> PyResult<String> {
    Ok(samara_app::reach::adaptive::merge_documents(docs).map_err(Error::from)?)
}

/// Merge the results of `reach_system` over consecutive cell ranges, in cell order,
/// into the result of their union (`samara_app::python_front::merge_grid_parts`).
#[pyfunction]
fn merge_reach_system(py: Python<'_>, parts: Vec<Bound<'_, PyAny>>) -> PyResult<PyObject> {
    let parts = parts
        .iter()
        .enumerate()
        .map(|(i, p)| frompy::from_py::<GridPart>(p, &format!("parts[{i}]")))
        .collect::<PyResult<Vec<_>>>()?;
    let merged = front::merge_grid_parts(parts, "parts").map_err(Error::from)?;
    let merged = merged.in_words(Front::Python);
    topy::to_py(py, &merged)
}

/// A reachability analysis as `samara reach` runs it (no files): the typed `reach.json`
/// (`samara_app::reach::ReachReport`: settings, verdict, final and sampled x + y, leaves
/// with their enclosures per control instant) as Python objects. The arguments are
/// checked by `samara_app::python_front::ReachRequest`.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (network, model, init, horizon, period, goal_ystar, goal_from, clip, max_leaves, samples, seed, network_name, threads))]
fn reach(
    py: Python<'_>,
    network: PyRef<'_, PyNetwork>,
    model: String,
    init: BTreeMap<String, (f64, f64)>,
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
    front::check_threads(Front::Python, threads).map_err(Error::from)?;
    let s = ReachRequest {
        model,
        init,
        horizon,
        period,
        goal_ystar,
        goal_from,
        clip,
        max_leaves,
        samples,
        seed,
    }
    .settings(Front::Python)
    .map_err(Error::from)?;
    let net = front::glider_controller("network", &network.net).map_err(Error::from)?;
    s.validate(&net).map_err(|e| py_value_error(&e))?;
    // The checks `samara reach` makes on its inputs and result, from the same library
    // calls: a network in the wrong units, an enclosure lost before the horizon.
    let warnings: Vec<String> = s
        .units_warning(&net)
        .map(|w| format!("network: {w}"))
        .into_iter()
        .collect();
    let r = interruptible(py, move || -> R<samara_app::reach::ReachReport> {
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
        Ok(samara_app::reach::ReachReport::new(echo, &s, &o, res.leaves).in_words(Front::Python))
    })?;
    topy::to_py(py, &r)
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
    use samara_train::{MinMax, Table, TrainOptions};
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
    let method_v = front::train_method(
        Front::Python,
        method,
        attack,
        lipschitz,
        weight,
        ystar,
        &data,
        &mm,
        &arch,
    )
    .map_err(Error::from)?;
    let min_r2 = min_r2.unwrap_or_else(|| front::default_min_r2(&method_v));
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
    let (net, report) = interruptible(py, move || -> R<_> {
        let outcome =
            samara_train::train(&data, Some(&mm), &o).map_err(|e| Error::Samara(e.to_string()))?;
        let report = TrainReport::of(&method, &o, &outcome);
        let mut net = outcome.network;
        if net.n_inputs() == 6 && net.n_outputs() == 1 {
            net = net
                .with_names(&samara_nn::STATE_INPUTS, &["ex"])
                .map_err(|e| Error::Samara(e.to_string()))?;
        }
        Ok((net, report))
    })?;
    Ok((PyNetwork { net }, topy::to_py(py, &report)?))
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
    m.add_function(wrap_pyfunction!(reach_adaptive_shard, m)?)?;
    m.add_function(wrap_pyfunction!(merge_adaptive_shards, m)?)?;
    m.add_function(wrap_pyfunction!(merge_reach_system, m)?)?;
    m.add_function(wrap_pyfunction!(train, m)?)?;
    m.add("SamaraError", m.py().get_type::<SamaraError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
