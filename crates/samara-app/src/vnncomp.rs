//! VNN-COMP instances: deciding one with the routed engines and the verdict policy
//! (every counterexample re-checked concretely before it is reported, downgraded to
//! `unknown` (rounding) when neither f64 nor exact arithmetic confirms it), the
//! competition's result words and result file, and the typed per-instance result that
//! results CSVs, `--json` rows and shard files are made from.

use crate::{input, AppError, Reason};
use samara_nn::Network;
use samara_spec::normal::{Query, Var};
use samara_spec::vnnlib;
use samara_verify::point::Point;
use samara_verify::route::{prove_routed, Engine};
use samara_verify::{Prepared, Settings, Timeout, UnknownReason, Verdict};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Load and check one instance: the network and the property (exit 2 on a bad one,
/// naming the flag or file, the line or the operator).
pub fn load_instance(
    network: &Path,
    property: &Path,
    net_flag: &str,
    prop_flag: &str,
) -> Result<(Network, Query), AppError> {
    load_instance_logits(network, property, net_flag, prop_flag, None)?
        .map(|(net, q, _)| (net, q))
        .ok_or_else(|| {
            AppError::Input(format!(
                "{net_flag} {}: {}",
                network.display(),
                samara_nn::limits::TIMED_OUT
            ))
        })
}

/// [`load_instance`] within a time limit (`Ok(None)` when `deadline` passed while the
/// network was read or lowered: an instance's limit counts its load, and lowering an
/// image-sized convolutional network takes minutes), leaving out a final `Softmax`
/// over all the outputs when the property only compares outputs with each other
/// ([`compares_outputs_only`]: the answer is the same on the logits, softmax being
/// strictly increasing in each logit against any other). The third value is `true`
/// when the softmax was left out: the network then computes the logits, and outputs
/// shown as the file's (a counterexample's `Y_j`) are [`softmax`] of the network's.
pub fn load_instance_logits(
    network: &Path,
    property: &Path,
    net_flag: &str,
    prop_flag: &str,
    deadline: Option<Instant>,
) -> Result<Option<(Network, Query, bool)>, AppError> {
    // The property is read first to choose how to load the network, but a bad network
    // is reported before a bad property, as always (and a bad property before a load
    // that ran out of time).
    let q = read_property(property, prop_flag);
    let logits = wants_logits(network, &q);
    let Some((net, logits)) = load_network_as(network, net_flag, logits, deadline)? else {
        q?;
        return Ok(None);
    };
    let q = check_instance(&net, q?, network, property)?;
    Ok(Some((net, q, logits)))
}

/// The property file as a query (exit 2 naming the flag or the file's line).
pub fn read_property(property: &Path, prop_flag: &str) -> Result<Query, AppError> {
    let file = property.display().to_string();
    let text = std::fs::read_to_string(property)
        .map_err(|e| AppError::Input(format!("{prop_flag} {file}: cannot read: {e}")))?;
    vnnlib::import(&text, &file, "f", "property").map_err(|e| AppError::Input(e.to_string()))
}

/// Whether an ONNX network for this property may be loaded without a final softmax
/// ([`compares_outputs_only`]).
pub fn wants_logits(network: &Path, q: &Result<Query, AppError>) -> bool {
    let nnet = network
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("nnet"));
    matches!(q, Ok(q) if !nnet && compares_outputs_only(q))
}

/// Load the network, without a final softmax over all outputs when `logits` (then the
/// flag says whether one was left out); `Ok(None)` when `deadline` passed during the
/// load ([`samara_nn::load_until`]).
pub fn load_network_as(
    network: &Path,
    net_flag: &str,
    logits: bool,
    deadline: Option<Instant>,
) -> Result<Option<(Network, bool)>, AppError> {
    if logits {
        match samara_nn::onnx::load_logits_until(network, deadline) {
            Ok(n) => Ok(Some(n)),
            Err(samara_nn::onnx::OnnxError::Timeout { .. }) => Ok(None),
            Err(e) => Err(AppError::Input(format!(
                "{}{e}",
                crate::bind::flag_prefix(net_flag)
            ))),
        }
    } else {
        Ok(crate::bind::load_network_until(network, net_flag, deadline)?.map(|n| (n, false)))
    }
}

/// Check a property against its network: dimensions, the variables it uses, finite
/// input bounds (exit 2 naming the file and the fix).
pub fn check_instance(
    net: &Network,
    q: Query,
    network: &Path,
    property: &Path,
) -> Result<Query, AppError> {
    let file = property.display().to_string();
    let Some(app) = q.applications.first() else {
        return crate::input(format!("{file}: the property calls no network"));
    };
    if app.n_inputs != net.n_inputs() || app.n_outputs != net.n_outputs() {
        return crate::input(format!(
            "dimension mismatch: {file} declares {} inputs and {} outputs, the network {} has {} and {}",
            app.n_inputs,
            app.n_outputs,
            network.display(),
            net.n_inputs(),
            net.n_outputs()
        ));
    }
    // Every variable used must be declared and exist in the network.
    for e in q.region.iter().flatten().map(|c| &c.expr) {
        for (v, _) in &e.terms {
            let (used, declared, have, what) = match *v {
                Var::Input { index, .. } => (index, app.n_inputs, net.n_inputs(), "inputs"),
                Var::Output { index, .. } => (index, app.n_outputs, net.n_outputs(), "outputs"),
                Var::Free(_) => {
                    return crate::input(format!(
                        "{file}: uses {}, which is not an X_i or Y_j",
                        vnn_name(*v)
                    ))
                }
            };
            if used >= declared.min(have) {
                return crate::input(format!(
                    "{file}: the property uses {}, which it does not declare (it declares {declared} {what}; the network {} has {have}): use only the declared variables, {} to {}",
                    vnn_name(*v),
                    network.display(),
                    vnn_name(var_at(*v, 0)),
                    vnn_name(var_at(*v, declared.min(have).saturating_sub(1)))
                ));
            }
        }
    }
    if app.input_box.len() != net.n_inputs() {
        return crate::input(format!(
            "{file}: bounds for {} inputs but the network has {}",
            app.input_box.len(),
            net.n_inputs()
        ));
    }
    if let Some((i, (l, h))) = app
        .input_box
        .iter()
        .enumerate()
        .find(|(_, (l, h))| !l.is_finite() || !h.is_finite())
    {
        return crate::input(format!(
            "{file}: input X_{i} is bounded by [{l}, {h}]; give it finite bounds with top-level asserts, e.g. (assert (>= X_{i} 0.0)) and (assert (<= X_{i} 1.0))"
        ));
    }
    Ok(q)
}

/// Whether every constraint of the property's region leaves the outputs alone or
/// compares two distinct outputs of its one network with each other,
/// `a Y_i - a Y_j cmp 0` (VNN-COMP's classification properties): then the answer is
/// the same on the logits as on their softmax (`s_i >= s_j` iff `x_i >= x_j`).
pub fn compares_outputs_only(q: &Query) -> bool {
    q.applications.len() == 1
        && q.free_vars.is_empty()
        && q.region.iter().flatten().all(|c| {
            let outs: Vec<(usize, f64)> = c
                .expr
                .terms
                .iter()
                .filter_map(|&(v, k)| match v {
                    Var::Output { index, .. } => Some((index, k)),
                    _ => None,
                })
                .collect();
            match outs.as_slice() {
                [] => true,
                [(i, a), (j, b)] => {
                    outs.len() == c.expr.terms.len()
                        && c.expr.constant == 0.0
                        && i != j
                        && *a == -*b
                        && *a != 0.0
                }
                _ => false,
            }
        })
}

/// Softmax of logits in f64 (shifted by the largest, so no overflow): the outputs of a
/// network whose final softmax [`load_instance_logits`] left out.
pub fn softmax(x: &[f64]) -> Vec<f64> {
    let m = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let e: Vec<f64> = x.iter().map(|v| (v - m).exp()).collect();
    let s: f64 = e.iter().sum();
    e.iter().map(|v| v / s).collect()
}

/// The name of a VNN-LIB variable.
fn vnn_name(v: Var) -> String {
    match v {
        Var::Input { index, .. } => format!("X_{index}"),
        Var::Output { index, .. } => format!("Y_{index}"),
        Var::Free(k) => format!("P_{k}"),
    }
}

/// The same kind of variable at another index.
fn var_at(v: Var, index: usize) -> Var {
    match v {
        Var::Input { app, .. } => Var::Input { app, index },
        Var::Output { app, .. } => Var::Output { app, index },
        Var::Free(_) => Var::Free(index),
    }
}

/// A decided instance.
pub struct Decided {
    /// The verdict (a `Violated` one re-checked, see [`decide`]).
    pub verdict: Verdict,
    /// The engine that decided.
    pub engine: Engine,
    /// Wall time of the decision.
    pub seconds: f64,
    /// For `Violated`: the outputs at the counterexample by the network's own f64
    /// evaluator (`Network::eval_f64`), written to the result file.
    pub outputs: Option<Vec<f64>>,
    /// A note for the user (the counterexample holds in exact arithmetic only).
    pub note: Option<String>,
}

impl Decided {
    /// `unknown (timeout)` after `seconds` with no engine having answered (the engine
    /// named is the router's first, the input-split one), and `note` saying where the
    /// limit struck: the load ([`timed_out_loading`]) or a step that overran it (the
    /// backstops of `verify-vnnlib` and `samara vnncomp`).
    pub fn timed_out(seconds: f64, note: String) -> Decided {
        Decided {
            verdict: Verdict::Unknown(UnknownReason::Timeout { nodes: 0 }),
            engine: Engine::InputSplit,
            seconds,
            outputs: None,
            note: Some(note),
        }
    }
}

/// A counterexample re-checked concretely ([`recheck`]).
pub enum Recheck {
    /// The network's f64 outputs at the point satisfy the disjunct.
    Holds(Vec<f64>),
    /// f64 rounding puts the point outside the disjunct by `margin`, but exact rational
    /// arithmetic confirms it (a `sat` still; the f64 outputs are the ones written).
    ExactOnly(Vec<f64>, f64),
    /// Neither f64 nor exact arithmetic confirms the point (`margin`: by how much the
    /// f64 outputs miss the disjunct).
    Fails(f64),
}

/// Re-check a counterexample `x` of disjunct `disjunct` of `q` by evaluating the network
/// concretely: its plain f64 evaluator (`Network::eval_f64`), then, if that misses the
/// region by rounding, exact rational arithmetic. The one check of deciding an instance
/// and of merging shards' `sat` parts.
pub fn recheck(net: &Network, q: &Query, x: &[f64], disjunct: usize) -> Result<Recheck, AppError> {
    let Some(cs) = q.region.get(disjunct) else {
        return crate::input(format!(
            "disjunct {disjunct} does not exist (the property has {})",
            q.region.len()
        ));
    };
    if x.len() != net.n_inputs() {
        return crate::input(format!(
            "{} input values for a network of {} inputs",
            x.len(),
            net.n_inputs()
        ));
    }
    let y = net.eval_f64(x);
    let again = Point {
        inputs: vec![x.to_vec()],
        outputs: vec![y.clone()],
        free: vec![],
    };
    if again.satisfies(cs) {
        return Ok(Recheck::Holds(y));
    }
    let margin = again.margin(cs);
    let exact = samara_verify::net::PwlNet::from_network(net)
        .ok()
        .and_then(|pwl| samara_verify::exact::exact_satisfies(&[&pwl], &again, cs));
    Ok(if exact == Some(true) {
        Recheck::ExactOnly(y, margin)
    } else {
        Recheck::Fails(margin)
    })
}

/// Decide one instance (network `f` of `q`) within `timeout`. The network is borrowed:
/// `samara vnncomp` shares one load among the lines that use it, and a copy of an
/// image-sized network costs seconds and gigabytes. A counterexample
/// is re-checked ([`recheck`]) before it is reported: a point that the f64
/// re-evaluation or exact rational arithmetic confirms stays `sat` (its f64 outputs are
/// the ones written; a disagreement is said in [`Decided::note`]); any other becomes
/// `unknown` (rounding).
pub fn decide(
    net: &Network,
    q: &Query,
    timeout: Timeout,
    max_nodes: usize,
) -> Result<Decided, AppError> {
    let t0 = Instant::now();
    let nets = HashMap::from([("f".to_string(), net)]);
    // Preparing the network (its piecewise-linear form) counts against the time limit,
    // and stops at it (a copy of a lowered generator's layers takes many seconds).
    let Some(prep) = Prepared::borrowing_until(nets, timeout.deadline_from(t0)) else {
        let mut d = timed_out_loading(t0.elapsed().as_secs_f64());
        d.note = Some(
            "the time limit ran out while the network's piecewise-linear form was prepared: no verification was started".into(),
        );
        return Ok(d);
    };
    let (mut verdict, engine) = prove_routed(
        q,
        &prep,
        &Settings {
            timeout: timeout.left(t0),
            max_nodes,
            ..Default::default()
        },
    )?;
    let mut outputs = None;
    let mut note = None;
    if let Verdict::Violated(c) = &verdict {
        match recheck(net, q, &c.point.inputs[0], c.disjunct)? {
            Recheck::Holds(y) => outputs = Some(y),
            Recheck::ExactOnly(y, margin) => {
                note = Some(format!(
                    "the counterexample holds in exact arithmetic but the f64 re-evaluation puts it outside the region by rounding (margin {margin:e})"
                ));
                outputs = Some(y);
            }
            Recheck::Fails(margin) => {
                verdict = Verdict::Unknown(UnknownReason::Rounding {
                    margin,
                    tolerance: 0.0,
                });
            }
        }
    }
    drop(prep);
    Ok(Decided {
        verdict,
        engine,
        seconds: t0.elapsed().as_secs_f64(),
        outputs,
        note,
    })
}

/// Drop a network, on a thread of its own when it is large
/// ([`samara_verify::FREE_APART_WEIGHTS`]): freeing a lowered generator's gigabytes
/// took seconds past the instance's time limit.
pub fn free_apart(net: Network) {
    let weights: usize = net
        .layers
        .iter()
        .map(|l| match l {
            samara_nn::Layer::Affine(a) => a.stored(),
            samara_nn::Layer::Act(_) => 0,
        })
        .sum();
    if weights > samara_verify::FREE_APART_WEIGHTS {
        std::thread::spawn(move || drop(net));
    }
}

/// The instance whose time limit ran out while its network was loaded
/// (`load_instance_until`): `unknown (timeout)` after `seconds`, no engine having run
/// (the engine named is the router's first, the input-split one).
pub fn timed_out_loading(seconds: f64) -> Decided {
    Decided::timed_out(
        seconds,
        format!(
            "{}: no verification was started",
            samara_nn::limits::TIMED_OUT
        ),
    )
}

/// A result word of the competition, typed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Word {
    /// Proved (the property's counterexample region is empty).
    Unsat,
    /// A re-checked counterexample.
    Sat,
    /// The time limit ran out.
    Timeout,
    /// Any other reason for no verdict.
    Unknown,
}

impl Word {
    /// The word of a verdict.
    pub fn of(v: &Verdict) -> Word {
        match v {
            Verdict::Proved => Word::Unsat,
            Verdict::Violated(_) => Word::Sat,
            Verdict::Unknown(UnknownReason::Timeout { .. }) => Word::Timeout,
            Verdict::Unknown(_) => Word::Unknown,
        }
    }

    /// `unsat`, `sat`, `timeout` or `unknown`.
    pub fn text(self) -> &'static str {
        match self {
            Word::Unsat => "unsat",
            Word::Sat => "sat",
            Word::Timeout => "timeout",
            Word::Unknown => "unknown",
        }
    }
}

/// The result file's text (VNN-COMP 2021-2024): the word on the first line; after `sat`
/// the assignment `((X_0 v)`, ` (X_1 v)`, ..., ` (Y_m v))`, one variable per line,
/// values in the shortest decimal form that reads back to the same f64.
pub fn result_text(d: &Decided) -> String {
    let mut s = format!("{}\n", Word::of(&d.verdict).text());
    if let (Verdict::Violated(c), Some(y)) = (&d.verdict, &d.outputs) {
        let x = &c.point.inputs[0];
        let vars: Vec<(String, f64)> = x
            .iter()
            .enumerate()
            .map(|(i, v)| (format!("X_{i}"), *v))
            .chain(y.iter().enumerate().map(|(j, v)| (format!("Y_{j}"), *v)))
            .collect();
        for (k, (name, v)) in vars.iter().enumerate() {
            let open = if k == 0 { "((" } else { " (" };
            let close = if k + 1 == vars.len() { "))" } else { ")" };
            let _ = writeln!(s, "{open}{name} {v}{close}");
        }
    }
    s
}

/// The `counterexample` field of a VNN-COMP `--json` row: the point of a `sat`
/// instance, or the reason text of any other.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum JsonCounterexample {
    /// A `sat` instance's point.
    Point {
        /// The inputs.
        inputs: Vec<f64>,
        /// The network's f64 outputs there.
        outputs: Option<Vec<f64>>,
        /// The engine's margin (`null` when not finite).
        margin: Option<f64>,
        /// Whether exact arithmetic confirmed it.
        exact_check: Option<bool>,
    },
    /// An unknown instance's reason text.
    Message(String),
}

/// The counterexample and unknown reason of a decided instance, as `--json` shows them.
pub fn verdict_fields(d: &Decided) -> (Option<JsonCounterexample>, Option<Reason>) {
    match &d.verdict {
        Verdict::Proved => (None, None),
        Verdict::Violated(c) => (
            Some(JsonCounterexample::Point {
                inputs: c.point.inputs[0].clone(),
                outputs: d.outputs.clone(),
                margin: Some(c.margin).filter(|m| m.is_finite()),
                exact_check: c.exact,
            }),
            None,
        ),
        Verdict::Unknown(r) => (
            Some(JsonCounterexample::Message(r.to_string())),
            Some(r.into()),
        ),
    }
}

/// One decided instance as `samara verify-vnnlib --json` shows it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InstanceVerdict {
    /// `unsat`, `sat` or `unknown` (a timeout is `unknown` here; its reason says so).
    pub result: String,
    /// The point (`sat`) or the reason text.
    pub counterexample: Option<JsonCounterexample>,
    /// Wall time.
    pub seconds: f64,
    /// Why it is unknown.
    pub unknown_reason: Option<Reason>,
    /// The engine's tag.
    pub engine: String,
}

impl InstanceVerdict {
    /// The verdict of a decided instance.
    pub fn of(d: &Decided) -> Self {
        let (counterexample, unknown_reason) = verdict_fields(d);
        let result = match &d.verdict {
            Verdict::Proved => "unsat",
            Verdict::Violated(_) => "sat",
            Verdict::Unknown(_) => "unknown",
        };
        InstanceVerdict {
            result: result.to_string(),
            counterexample,
            seconds: d.seconds,
            unknown_reason,
            engine: d.engine.tag().to_string(),
        }
    }
}

/// A `sat` instance's counterexample as a shard stores it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Cex {
    /// The input point.
    pub inputs: Vec<f64>,
    /// The network's f64 outputs there (re-computed by the merge).
    pub outputs: Vec<f64>,
    /// The engine's margin (null when not finite).
    pub margin: Option<f64>,
    /// Whether exact arithmetic confirmed it (`exact_check`).
    pub exact_check: Option<bool>,
    /// Which disjunct of the property's region the point lies in.
    pub disjunct: usize,
}

/// One decided instance of a benchmark, typed, with its counterexample in form `C`:
/// [`InstanceResult`] (what a shard stores and what both the one-process run and the
/// merge format the results-CSV line, the `--json` row and the progress line from) and
/// [`JsonRow`] (the `--json` row).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Instance<C> {
    /// The instances CSV's line number.
    pub line: usize,
    /// The network file as the CSV names it.
    pub onnx: String,
    /// The property file as the CSV names it.
    pub vnnlib: String,
    /// The instance's timeout (scaled).
    pub timeout: f64,
    /// The result word.
    pub result: Word,
    /// Wall time.
    pub seconds: f64,
    /// The engine's tag (`route::Engine::tag`).
    pub engine: String,
    /// For `sat` only (the `--json` row: the reason text for `timeout`/`unknown`).
    pub counterexample: Option<C>,
    /// For `timeout` and `unknown` only.
    pub unknown_reason: Option<Reason>,
}

/// A decided instance as a shard stores it.
pub type InstanceResult = Instance<Cex>;

/// The `--json` row of an instance (the `verify-vnnlib --json` fields and where it is).
pub type JsonRow = Instance<JsonCounterexample>;

impl InstanceResult {
    /// The result of a decided instance of CSV line `line`.
    pub fn of(line: usize, onnx: &str, vnnlib: &str, timeout: f64, d: &Decided) -> Self {
        let counterexample = match (&d.verdict, &d.outputs) {
            (Verdict::Violated(c), Some(y)) => Some(Cex {
                inputs: c.point.inputs[0].clone(),
                outputs: y.clone(),
                margin: Some(c.margin).filter(|m| m.is_finite()),
                exact_check: c.exact,
                disjunct: c.disjunct,
            }),
            _ => None,
        };
        InstanceResult {
            line,
            onnx: onnx.to_string(),
            vnnlib: vnnlib.to_string(),
            timeout,
            result: Word::of(&d.verdict),
            seconds: d.seconds,
            engine: d.engine.tag().to_string(),
            counterexample,
            unknown_reason: match &d.verdict {
                Verdict::Unknown(r) => Some(r.into()),
                _ => None,
            },
        }
    }

    /// The results CSV's line.
    pub fn csv_line(&self) -> String {
        let detail = match (&self.unknown_reason, &self.counterexample) {
            (Some(r), _) => r.kind.clone(),
            (None, Some(c)) => format!(
                "exact_check={}",
                c.exact_check.map_or("none".into(), |b| b.to_string())
            ),
            (None, None) => String::new(),
        };
        format!(
            "{},{},{},{},{:.3},{},{}\n",
            csv_field(&self.onnx),
            csv_field(&self.vnnlib),
            self.timeout,
            self.result.text(),
            self.seconds,
            self.engine,
            csv_field(&detail)
        )
    }

    /// The `--json` row.
    pub fn row(&self) -> JsonRow {
        let counterexample = match (&self.counterexample, &self.unknown_reason) {
            (Some(c), _) => Some(JsonCounterexample::Point {
                inputs: c.inputs.clone(),
                outputs: Some(c.outputs.clone()),
                margin: c.margin,
                exact_check: c.exact_check,
            }),
            (None, Some(r)) => Some(JsonCounterexample::Message(r.message.clone())),
            (None, None) => None,
        };
        JsonRow {
            line: self.line,
            onnx: self.onnx.clone(),
            vnnlib: self.vnnlib.clone(),
            timeout: self.timeout,
            result: self.result,
            seconds: self.seconds,
            engine: self.engine.clone(),
            counterexample,
            unknown_reason: self.unknown_reason.clone(),
        }
    }

    /// The progress line.
    pub fn progress(&self) -> String {
        format!(
            "{} {} {} {:.2}s",
            self.onnx,
            self.vnnlib,
            self.result.text(),
            self.seconds
        )
    }
}

/// A field of a CSV line, quoted when it needs to be.
pub fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The `--json` line of a VNN-COMP shard.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShardLine {
    /// `[I, N]`.
    pub shard: (usize, usize),
    /// The shard's range of instances.
    pub instances: (usize, usize),
    /// Its counts by result word.
    pub counts: std::collections::BTreeMap<String, usize>,
    /// Wall time.
    pub total_seconds: f64,
    /// The shard file.
    pub out: std::path::PathBuf,
}

/// One line of an instances CSV.
#[derive(Clone, Debug, PartialEq)]
pub struct Line {
    /// The network's path as the CSV writes it.
    pub onnx: String,
    /// The property's path as the CSV writes it.
    pub vnnlib: String,
    /// The instance's time limit in seconds.
    pub timeout: f64,
    /// Its line number (from 1).
    pub lineno: usize,
}

/// The instances of a VNN-COMP instances CSV (`onnx,vnnlib,timeout` lines; blank lines
/// and `#` comments skipped), each checked; `path` names the file in messages.
pub fn parse_instances(path: &Path, text: &str) -> Result<Vec<Line>, AppError> {
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let l = raw.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let f: Vec<&str> = l.split(',').map(str::trim).collect();
        let bad = |why: &str| {
            AppError::Input(format!(
                "{}:{}: {why}; expected `onnx,vnnlib,timeout` (e.g. net.onnx,prop.vnnlib,116)",
                path.display(),
                i + 1
            ))
        };
        if f.len() != 3 || f[0].is_empty() || f[1].is_empty() {
            return Err(bad(&format!("{} fields", f.len())));
        }
        let timeout: f64 = f[2]
            .parse()
            .map_err(|_| bad(&format!("timeout `{}` is not a number", f[2])))?;
        if timeout.is_nan() || timeout < 0.0 {
            return Err(bad(&format!("timeout `{}` must be >= 0", f[2])));
        }
        out.push(Line {
            onnx: f[0].to_string(),
            vnnlib: f[1].to_string(),
            timeout,
            lineno: i + 1,
        });
    }
    if out.is_empty() {
        return input(format!(
            "{}: no instances (expected lines `onnx,vnnlib,timeout`)",
            path.display()
        ));
    }
    Ok(out)
}

/// What every shard of one `samara vnncomp` run shares (`run` of the shard file).
#[derive(Serialize, Deserialize)]
pub struct VnncompRun {
    /// The instances CSV: its content digest and its resolved path (the merge reads it
    /// back to check every part against its line).
    pub instances: String,
    /// The instances CSV's resolved path.
    pub instances_file: String,
    /// How many instances the CSV has.
    pub n_instances: usize,
    /// The folder the CSV's paths were resolved against.
    pub root: String,
    /// The content digest of every network and property file of the whole benchmark,
    /// keyed by the CSV's path text.
    pub inputs: BTreeMap<String, String>,
    /// `--timeout-scale`, as Rust's `{:?}` writes it (exact).
    pub timeout_scale: String,
    /// `--max-nodes`.
    pub max_nodes: usize,
}

/// A vnncomp shard's `result`.
#[derive(Serialize, Deserialize)]
pub struct VnncompShard {
    /// The instance indices `[start, end)` of this shard.
    pub instances: [usize; 2],
    /// How many of them are done (the file is rewritten after each).
    pub done: usize,
    /// The done instances' results.
    pub parts: Vec<InstanceResult>,
}

/// Check one part of a shard against the run: it is the instance of its line (the same
/// files and timeout), its fields agree with its result word, and a `sat` part's
/// counterexample holds when the network is evaluated concretely ([`recheck`]; the
/// network and property are read back and must be the files the shards digested).
/// Returns the part with the re-computed outputs.
pub fn check_part(
    file: &Path,
    run: &VnncompRun,
    l: &Line,
    scale: f64,
    mut p: InstanceResult,
) -> Result<InstanceResult, AppError> {
    let at = format!(
        "{}: line {} ({}, {})",
        file.display(),
        l.lineno,
        l.onnx,
        l.vnnlib
    );
    let t = l.timeout * scale;
    if p.line != l.lineno || p.onnx != l.onnx || p.vnnlib != l.vnnlib || p.timeout != t {
        return input(format!(
            "{}: the part for line {} is line {} ({}, {}, timeout {}), not the instances CSV's ({}, {}, timeout {t}): the shard does not belong to these instances; run it again",
            file.display(),
            l.lineno,
            p.line,
            p.onnx,
            p.vnnlib,
            p.timeout,
            l.onnx,
            l.vnnlib
        ));
    }
    if !(p.seconds.is_finite() && p.seconds >= 0.0) {
        return input(format!("{at}: `seconds` {} is not a wall time", p.seconds));
    }
    if ![
        Engine::InputSplit,
        Engine::Phase,
        Engine::InputSplitThenPhase,
    ]
    .iter()
    .any(|e| e.tag() == p.engine)
    {
        return input(format!("{at}: unknown engine `{}`", p.engine));
    }
    match (p.result, &p.counterexample, &p.unknown_reason) {
        (Word::Unsat, None, None) => {}
        (Word::Timeout, None, Some(r)) if r.kind == "timeout" => {}
        (Word::Unknown, None, Some(r)) if r.kind != "timeout" => {}
        (Word::Sat, None, _) => {
            return input(format!("{at}: `sat` without a counterexample; a `sat` part must carry its point (run the shard again)"))
        }
        (Word::Sat, Some(c), None) => {
            let root = Path::new(&run.root);
            let (onnx, vnnlib) = (root.join(&l.onnx), root.join(&l.vnnlib));
            for (name, path) in [(&l.onnx, &onnx), (&l.vnnlib, &vnnlib)] {
                let now = crate::shard::digest_file(path, &format!("{at}: re-checking the counterexample needs"))?;
                let then = run.inputs.get(name.as_str()).map_or("none", String::as_str);
                if then != now.as_str() {
                    return input(format!(
                        "{at}: input `{name}` ({}) changed since the shards ran (content digest {} then, {now} now); run every shard again",
                        path.display(),
                        then
                    ));
                }
            }
            let (net, q) = load_instance(&onnx, &vnnlib, "onnx", "vnnlib")
                .map_err(|e| AppError::Input(format!("{at}: {e}")))?;
            let y = match recheck(&net, &q, &c.inputs, c.disjunct)
                .map_err(|e| AppError::Input(format!("{at}: the `sat` counterexample is malformed: {e}")))?
            {
                Recheck::Holds(y) | Recheck::ExactOnly(y, _) => y,
                Recheck::Fails(margin) => return input(format!(
                    "{at}: the `sat` counterexample does not hold: the network's outputs there miss the property's region (margin {margin:e}); the shard is damaged or tampered with, run it again"
                )),
            };
            if y.iter().map(|v| v.to_bits()).ne(c.outputs.iter().map(|v| v.to_bits())) {
                return input(format!(
                    "{at}: the `sat` counterexample's outputs {:?} are not the network's {:?} at its inputs; the shard is damaged or tampered with, run it again",
                    c.outputs,
                    y
                ));
            }
            if let Some(c) = &mut p.counterexample {
                c.outputs = y;
            }
        }
        _ => return input(format!(
            "{at}: result `{}` with {} counterexample and {} unknown reason: the fields contradict each other; the shard is damaged or tampered with, run it again",
            p.result.text(),
            if p.counterexample.is_some() { "a" } else { "no" },
            p.unknown_reason
                .as_ref()
                .map_or("no".to_string(), |r| format!("a `{}`", r.kind))
        )),
    }
    Ok(p)
}

/// `samara merge vnncomp`: the shards' instances in order, each checked against the run's
/// instances CSV (read back from where the shards resolved it: every instance exactly
/// once) and rebuilt from its typed result, every `sat` counterexample re-checked on the
/// network (`on_part` sees each, in order, as it is checked). The caller writes the
/// results CSV and the summary, as one process writes them.
pub fn merge_vnncomp(
    shards: &crate::shard::Shards,
    mut on_part: impl FnMut(&InstanceResult),
) -> Result<Vec<InstanceResult>, AppError> {
    let (file0, _) = &shards.results[0];
    let run: VnncompRun = serde_json::from_value(shards.run.clone()).map_err(|e| {
        AppError::Input(format!(
            "{}: not a vnncomp run record: {e}",
            file0.display()
        ))
    })?;
    let csv_path = PathBuf::from(&run.instances_file);
    let text = std::fs::read_to_string(&csv_path).map_err(|e| {
        AppError::Input(format!(
            "{}: the run's instances CSV {}: cannot read: {e} (the merge reads the run's inputs back to check the shards)",
            file0.display(),
            csv_path.display()
        ))
    })?;
    if crate::shard::digest(text.as_bytes()) != run.instances {
        return input(format!(
            "input `{}` changed since the shards ran (content digest {} then, {} now); run every shard again",
            csv_path.display(),
            run.instances,
            crate::shard::digest(text.as_bytes())
        ));
    }
    let all = parse_instances(&csv_path, &text)?;
    if all.len() != run.n_instances {
        return input(format!(
            "{}: {} instances recorded, the CSV {} has {}",
            file0.display(),
            run.n_instances,
            csv_path.display(),
            all.len()
        ));
    }
    let scale: f64 = run
        .timeout_scale
        .parse()
        .map_err(|_| AppError::Input(format!("{}: bad `run.timeout_scale`", file0.display())))?;
    let mut parts = Vec::new();
    let mut next = 0usize;
    let n_shards = shards.results.len();
    for (i, (file, r)) in shards.results.iter().enumerate() {
        let r: VnncompShard = serde_json::from_value(r.clone()).map_err(|e| {
            AppError::Input(format!(
                "{}: not a vnncomp shard result: {e}",
                file.display()
            ))
        })?;
        let want = crate::shard::Shard { i, n: n_shards }.range(all.len());
        if r.instances != [want.start, want.end] || want.start != next {
            return input(format!(
                "{}: instances {}..{}, expected {}..{} for shard {i}/{n_shards} (the shards do not tile the instances)",
                file.display(),
                r.instances[0],
                r.instances[1],
                want.start,
                want.end
            ));
        }
        if r.parts.len() > want.len() {
            return input(format!(
                "{}: {} instance parts for its {} instances {}..{}: an instance appears more than once (the shard is damaged or tampered with); run it again",
                file.display(),
                r.parts.len(),
                want.len(),
                want.start,
                want.end
            ));
        }
        if r.parts.len() != want.len() || r.done != r.parts.len() {
            return input(format!(
                "{}: {} of its {} instances done (the shard was cut short); run it again",
                file.display(),
                r.parts.len().min(r.done),
                want.len()
            ));
        }
        next = want.end;
        for (l, p) in all[want].iter().zip(r.parts) {
            let p = check_part(file, &run, l, scale, p)?;
            on_part(&p);
            parts.push(p);
        }
    }
    Ok(parts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_run_record_is_typed_and_reads_back() {
        let run = VnncompRun {
            instances: "d1".into(),
            instances_file: "/b/instances.csv".into(),
            n_instances: 2,
            root: "/b".into(),
            inputs: [("n.onnx".to_string(), "d2".to_string())].into(),
            timeout_scale: format!("{:?}", 0.5),
            max_nodes: 7,
        };
        let v = serde_json::to_value(&run).unwrap();
        assert_eq!(v["inputs"]["n.onnx"], "d2");
        let back: VnncompRun = serde_json::from_value(v.clone()).unwrap();
        assert_eq!(back.inputs, run.inputs);
        assert_eq!(back.timeout_scale.parse::<f64>().unwrap(), 0.5);
        // A digest that is not text is not a run record this samara writes.
        let mut bad = v;
        bad["inputs"]["n.onnx"] = serde_json::json!(3);
        assert!(serde_json::from_value::<VnncompRun>(bad).is_err());
    }

    #[test]
    fn instance_lines_are_checked_with_file_and_line() {
        let p = Path::new("i.csv");
        let l = parse_instances(p, "# c\n\na.onnx, b.vnnlib, 116\n").unwrap();
        assert_eq!((l.len(), l[0].lineno, l[0].timeout), (1, 3, 116.0));
        let e = parse_instances(p, "a.onnx,b.vnnlib,-1\n").unwrap_err();
        assert!(
            e.to_string()
                .starts_with("i.csv:1: timeout `-1` must be >= 0"),
            "{e}"
        );
        let e = parse_instances(p, "a.onnx,b.vnnlib\n").unwrap_err();
        assert!(e.to_string().starts_with("i.csv:1: 2 fields"), "{e}");
        assert!(parse_instances(p, "# only a comment\n").is_err());
    }

    /// Only properties whose every output constraint is `a Y_i - a Y_j cmp 0` keep
    /// their answer when a final softmax is left out; a constant, a third output, an
    /// input term beside outputs or unequal weights make the softmax matter.
    #[test]
    fn only_pairwise_output_comparisons_ignore_a_softmax() {
        let head = "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n(declare-const Y_1 Real)\n(declare-const Y_2 Real)\n(assert (>= X_0 0.0))\n(assert (<= X_0 1.0))\n";
        let q =
            |body: &str| vnnlib::import(&format!("{head}{body}"), "p", "f", "property").unwrap();
        assert!(compares_outputs_only(&q(
            "(assert (or (and (>= Y_0 Y_1)) (and (>= Y_2 Y_1))))"
        )));
        assert!(compares_outputs_only(&q("(assert (<= Y_0 Y_2))")));
        assert!(!compares_outputs_only(&q("(assert (>= Y_0 0.5))")));
        assert!(!compares_outputs_only(&q(
            "(assert (>= (+ Y_0 Y_1) (* 2.0 Y_2)))"
        )));
        assert!(!compares_outputs_only(&q("(assert (>= Y_0 (+ Y_1 X_0)))")));
        assert!(!compares_outputs_only(&q("(assert (>= Y_0 (* 2.0 Y_1)))")));
        // Softmax of logits, as onnxruntime's output is (sums to 1, order kept).
        let s = softmax(&[1.0, 3.0, -2.0]);
        assert!((s.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!(s[1] > s[0] && s[0] > s[2]);
        assert!((s[1] - 3f64.exp() / (1f64.exp() + 3f64.exp() + (-2f64).exp())).abs() < 1e-15);
    }
}
