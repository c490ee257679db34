//! `samara check | verify | critical | robustness | export-vnnlib | verify-vnnlib`, and
//! (in `vnncomp.rs`) `samara vnncomp`.

#[path = "vnncomp.rs"]
pub mod vnncomp;
pub use vnncomp::{run_vnncomp, VnncompArgs};
#[path = "shard.rs"]
pub mod shard;

use anyhow::{anyhow, bail, Result};
use samara_spec::lower::nearest;
use samara_spec::lower::NetDecl;
use samara_spec::normal::{Goal, Query, Sense, Var};
use samara_spec::syntax::Binder;
use samara_spec::{vnnlib, Bindings, Instance, Spec};
use samara_verify::engine::Point;
use samara_verify::robustness::{lipschitz_cell, published_cell, sweep_until, Reference};
use samara_verify::{
    left_after, optimise, prove, vacuity, LpTighten, Prepared, Settings, UnknownReason, Verdict,
};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Flags shared by the spec commands.
#[derive(clap::Args, Debug, Clone)]
pub struct SpecArgs {
    /// The specification file.
    pub spec: PathBuf,
    /// Bind a network name to an ONNX file (repeatable): --network f=net.onnx.
    #[arg(long = "network", value_name = "NAME=FILE")]
    pub networks: Vec<String>,
    /// Bind a parameter (repeatable): --param ystar=2.
    #[arg(long = "param", value_name = "NAME=VALUE")]
    pub params: Vec<String>,
    /// Bind a data set (repeatable): --dataset train=data.csv. Only the properties that
    /// quantify over a data set (`for p in data NAME`) need it; without this flag the
    /// spec's `dataset` path is used, relative to the spec file. The published training
    /// points are `../shared/reference/Training_Data_Normalised.csv`.
    #[arg(long = "dataset", value_name = "NAME=FILE")]
    pub datasets: Vec<String>,
}

/// Flags of `samara check`.
#[derive(clap::Args, Debug)]
pub struct CheckArgs {
    #[command(flatten)]
    /// Spec and bindings.
    pub s: SpecArgs,
}

/// Flags of `samara verify`.
#[derive(clap::Args, Debug)]
pub struct VerifyArgs {
    #[command(flatten)]
    /// Spec and bindings.
    pub s: SpecArgs,
    /// Only this property (default: all).
    #[arg(long)]
    pub property: Option<String>,
    /// Time limit of the whole command in seconds (>= 0; `inf` for none): every query
    /// gets what is left of it. A query cut short is `unknown` with its reason, never
    /// proved or violated.
    #[arg(long, default_value_t = 60.0)]
    pub timeout: f64,
    /// Tighten unstable neurons' bounds with LPs at the root of each search
    /// (`samara_verify::tighten`; off by default).
    #[arg(long)]
    pub lp_tighten: bool,
    /// Node limit per search (branch-and-bound nodes per disjunct); a search that reaches
    /// it is `unknown` (node_limit).
    #[arg(long, default_value_t = 200_000)]
    pub max_nodes: usize,
    /// JSON output.
    #[arg(long)]
    pub json: bool,
}

/// Flags of `samara critical`.
#[derive(clap::Args, Debug)]
pub struct CriticalArgs {
    #[command(flatten)]
    /// Spec and bindings; `--param NAME` without a value names the parameter whose
    /// critical value is computed (it must be declared with a range).
    pub s: SpecArgs,
    /// The property.
    #[arg(long)]
    pub property: String,
    /// Time limit of the whole command in seconds (>= 0; `inf` for none), shared by its
    /// two searches (the supremum's, then the infimum's). A search cut short reports
    /// `unknown` with its reason (exit 1), never a critical value.
    #[arg(long, default_value_t = 60.0)]
    pub timeout: f64,
    /// Tighten unstable neurons' bounds with LPs at the root of each search
    /// (`samara_verify::tighten`; off by default).
    #[arg(long)]
    pub lp_tighten: bool,
    /// Node limit per search (branch-and-bound nodes per disjunct); a search that reaches
    /// it is `unknown` (node_limit).
    #[arg(long, default_value_t = 200_000)]
    pub max_nodes: usize,
    /// JSON output.
    #[arg(long)]
    pub json: bool,
}

/// Flags of `samara robustness`.
#[derive(clap::Args, Debug)]
pub struct RobustnessArgs {
    /// The network (ONNX). Data and eps are in the units the network takes.
    #[arg(long)]
    pub network: PathBuf,
    /// Data set (CSV or IDX): inputs, then the label.
    #[arg(long)]
    pub data: PathBuf,
    /// Radii (comma-separated; each positive, finite and at most 1e6; repeated values
    /// count once).
    #[arg(long, default_value = "1e-5,1e-4,1e-3,1e-2")]
    pub eps: String,
    /// Bounds L (comma-separated; each finite and >= 0; repeated values count once).
    #[arg(long, default_value = "1e-5,1e-4,1e-3,1e-2")]
    pub lipschitz: String,
    /// Reference of the published form: label or network.
    #[arg(long, default_value = "label")]
    pub reference: String,
    /// published (|f(x') - ref| <= L / eps) or lipschitz (|f(x') - f(x)| <= L ||x' - x||).
    #[arg(long, default_value = "published")]
    pub form: String,
    /// Time limit of the whole command in seconds (>= 0; `inf` for none): every point's
    /// search stops at it; a point whose search is cut short counts as unknown unless
    /// its bounds already settle it.
    #[arg(long, default_value_t = 30.0)]
    pub timeout: f64,
    /// Node limit of each point's search; a point whose search reaches it counts as
    /// unknown unless its bounds already settle it.
    #[arg(long, default_value_t = 200_000)]
    pub max_nodes: usize,
    /// Per-point results CSV (refused if it is the --data or --network file). With
    /// --shard: this shard's partial result (JSON, for `samara merge robustness`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// JSON output.
    #[arg(long)]
    pub json: bool,
    /// Compute only shard I of N (0-based): the data set's points split into N
    /// contiguous parts. Needs --out; `samara merge robustness` puts the N files together.
    #[arg(long, value_name = "I/N", allow_hyphen_values = true, value_parser = shard::parse_shard)]
    pub shard: Option<shard::Shard>,
}

/// Flags of `samara verify-vnnlib`.
#[derive(clap::Args, Debug)]
pub struct VerifyVnnlibArgs {
    /// The network (ONNX).
    #[arg(long)]
    pub network: PathBuf,
    /// The property (VNN-LIB 1.0): a satisfying point is a counterexample.
    #[arg(long)]
    pub property: PathBuf,
    /// Time limit in seconds (>= 0; `inf` for none).
    #[arg(long, default_value_t = 60.0)]
    pub timeout: f64,
    /// Node limit per search (branch-and-bound nodes per disjunct); a search that reaches
    /// it is `unknown` (node_limit).
    #[arg(long, default_value_t = 200_000)]
    pub max_nodes: usize,
    /// Also write the verdict to FILE in the competition's result format (atomically):
    /// `unsat`, `timeout`, `unknown`, or `sat` followed by the counterexample
    /// `((X_0 v)` ... ` (Y_m v))`, one variable per line, outputs by the network's own f64
    /// evaluator.
    #[arg(long, value_name = "FILE")]
    pub result: Option<PathBuf>,
    /// JSON output.
    #[arg(long)]
    pub json: bool,
}

/// Flags of `samara export-vnnlib`.
#[derive(clap::Args, Debug)]
pub struct ExportArgs {
    #[command(flatten)]
    /// Spec and bindings.
    pub s: SpecArgs,
    /// Output directory (one .vnnlib per property instance). It must be empty or not
    /// exist yet: a folder that holds files is refused (old and new files would mix);
    /// a folder this run created is removed again if the export fails.
    #[arg(long)]
    pub out: PathBuf,
    /// One file per disjunct of the counterexample region (for tools that cannot read `or`).
    #[arg(long)]
    pub split_disjuncts: bool,
    /// Only this property (default: all). The command exits 1 if any instance of the
    /// selected properties could not be written.
    #[arg(long)]
    pub property: Option<String>,
}

/// Where the published training points live (relative to a samara checkout).
const PUBLISHED_DATA: &str = "../shared/reference/Training_Data_Normalised.csv";

fn kv(s: &str, flag: &str) -> Result<(String, String)> {
    let (k, v) = s
        .split_once('=')
        .ok_or_else(|| anyhow!("--{flag} {s:?}: expected NAME=VALUE (e.g. --{flag} NAME=VALUE)"))?;
    Ok((k.trim().to_string(), v.trim().to_string()))
}

/// `did you mean` for a name among candidates, else the list.
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

/// Load an ONNX network, naming the flag on failure (the error's own text only: its
/// source is already part of it).
/// (`flag` ends with `=` for a `NAME=FILE` flag. The loaders' errors start with the
/// file's path, so the message reads `--flag FILE: what`.)
pub fn load_network(path: &Path, flag: &str) -> Result<samara_nn::Network> {
    samara_nn::onnx::load(path).map_err(|e| anyhow!("{}{e}", flag_prefix(flag)))
}

fn read_data(path: &Path, flag: &str) -> Result<samara_nn::data::Table> {
    samara_nn::data::read_table(path).map_err(|e| anyhow!("{}{e}", flag_prefix(flag)))
}

fn flag_prefix(flag: &str) -> String {
    if flag.ends_with('=') {
        flag.to_string()
    } else {
        format!("{flag} ")
    }
}

/// `--timeout`: a number >= 0 (`inf` allowed: no limit).
fn check_timeout(t: f64) -> Result<()> {
    if t.is_nan() || t < 0.0 {
        bail!(
            "--timeout {t}: must be a number of seconds >= 0 (e.g. --timeout 60; inf for no limit)"
        );
    }
    Ok(())
}

/// Loaded spec, networks and bindings.
pub struct Loaded {
    /// The spec.
    pub spec: Spec,
    /// Networks by name.
    pub nets: HashMap<String, samara_nn::Network>,
    /// Bindings.
    pub b: Bindings,
    /// The network files by name (for output guards).
    pub net_files: Vec<PathBuf>,
}

/// Load a spec and its bindings; every flag is checked here (exit 2 on a bad one).
/// `free_params`: whether a bare `--param NAME` (no value) is allowed (`critical`).
pub fn load(a: &SpecArgs, free_params: bool) -> Result<Loaded> {
    let spec = Spec::read(&a.spec).map_err(|e| anyhow!("{e}"))?;
    let mut b = Bindings::default();
    let mut nets = HashMap::new();
    let mut net_files = Vec::new();
    for s in &a.networks {
        let (k, v) = kv(s, "network")?;
        let Some(nd) = spec.networks.iter().find(|n| n.name == k) else {
            bail!(
                "--network {k}=...: the spec {} declares no network `{k}`; {}",
                a.spec.display(),
                suggest(&k, spec.networks.iter().map(|n| n.name.as_str()))
            );
        };
        if nets.contains_key(&k) {
            bail!("--network {k}=...: given twice; bind each network once");
        }
        let file = PathBuf::from(&v);
        let net = load_network(&file, &format!("--network {k}="))?;
        if net.n_inputs() != nd.inputs.len() || net.n_outputs() != nd.outputs.len() {
            bail!(
                "--network {k}={v}: dimension mismatch: the file has {} inputs and {} outputs but {} declares `{k}({})` with {} inputs and {} outputs; pass a network of that signature",
                net.n_inputs(),
                net.n_outputs(),
                a.spec.display(),
                nd.inputs.join(", "),
                nd.inputs.len(),
                nd.outputs.len()
            );
        }
        units_check(&a.spec, &k, &v, nd, &net)?;
        b.network_dims
            .insert(k.clone(), (net.n_inputs(), net.n_outputs()));
        nets.insert(k, net);
        net_files.push(file);
    }
    for s in &a.params {
        if !s.contains('=') {
            let k = s.trim();
            if !free_params {
                bail!(
                    "--param {k}: no value; pass --param {k}=VALUE (only `samara critical` takes a bare --param NAME: the parameter to search)"
                );
            }
            if !spec.params.contains_key(k) {
                bail!(
                    "--param {k}: the spec {} declares no parameter `{k}`; {}",
                    a.spec.display(),
                    suggest(k, spec.params.keys().map(String::as_str))
                );
            }
            continue;
        }
        let (k, v) = kv(s, "param")?;
        if !spec.params.contains_key(&k) {
            bail!(
                "--param {k}={v}: the spec {} declares no parameter `{k}`; {}",
                a.spec.display(),
                suggest(&k, spec.params.keys().map(String::as_str))
            );
        }
        if b.params.contains_key(&k) {
            bail!("--param {k}: given twice; bind each parameter once");
        }
        let x: f64 = v
            .parse()
            .map_err(|_| anyhow!("--param {k}={v}: not a number; pass e.g. --param {k}=2"))?;
        if !x.is_finite() {
            bail!("--param {k}={v}: not a finite number; pass a finite value, e.g. --param {k}=2");
        }
        if a.params.iter().any(|p| p.trim() == k) {
            bail!(
                "--param {k}={v}: `{k}` is also the parameter to search (--param {k}); drop one of them"
            );
        }
        b.params.insert(k, x);
    }
    // Values outside a declared `param NAME in [lo, hi]` are refused here (exit 2).
    spec.check_bindings(&b)
        .map_err(|e| anyhow!("--param: {e}"))?;
    for s in &a.datasets {
        let (k, v) = kv(s, "dataset")?;
        if !spec.datasets.contains_key(&k) {
            bail!(
                "--dataset {k}={v}: the spec {} declares no data set `{k}`; {}",
                a.spec.display(),
                suggest(&k, spec.datasets.keys().map(String::as_str))
            );
        }
        if b.datasets.contains_key(&k) {
            bail!("--dataset {k}=...: given twice; bind each data set once");
        }
        let p = PathBuf::from(&v);
        if !p.is_file() {
            bail!(
                "--dataset {k}={v}: no such file; pass the CSV or IDX file of data set `{k}` (the published training points are {PUBLISHED_DATA})"
            );
        }
        b.datasets.insert(k, p);
    }
    Ok(Loaded {
        spec,
        nets,
        b,
        net_files,
    })
}

/// A network whose file carries its own normalisation, bound to a network the spec
/// declares with normalised units (or the reverse where the file says so) would have
/// its units converted twice: refuse. Where the file carries no information, warn.
fn units_check(
    spec_file: &Path,
    name: &str,
    file: &str,
    nd: &NetDecl,
    net: &samara_nn::Network,
) -> Result<()> {
    if nd.in_norm.is_some() && net.input_norm.is_some() {
        bail!(
            "--network {name}={file}: units mismatch: the file normalises its own inputs (it has a raw-to-normalised input layer: a raw-unit network such as a `*_denorm` file) but {} declares `normalise {name} input`, i.e. `{name}` takes normalised inputs, so the inputs would be normalised twice; pass the network that takes normalised inputs (e.g. base_model_norm.onnx) or remove the `normalise {name}` lines from the spec",
            spec_file.display()
        );
    }
    if nd.out_norm.is_some() && net.output_denorm.is_some() {
        bail!(
            "--network {name}={file}: units mismatch: the file denormalises its own output but {} declares `normalise {name} output`, so the output would be converted twice; pass the network with a normalised output or remove the `normalise {name} output` line",
            spec_file.display()
        );
    }
    if nd.in_norm.is_none() && net.input_norm.is_none() {
        eprintln!(
            "warning: --network {name}={file}: {} declares `{name}` in raw units (no `normalise {name}` line) and the file carries no normalisation layer: samara cannot check that it takes raw inputs; if it takes normalised ones, add the `normalise {name} input ...` line",
            spec_file.display()
        );
    }
    Ok(())
}

/// The data sets property `name` quantifies over whose file is missing, as a message
/// naming the flag to pass; `None` if it needs none or they exist.
fn missing_data(l: &Loaded, name: &str) -> Option<String> {
    let p = l.spec.properties.iter().find(|p| p.name == name)?;
    for bnd in &p.binders {
        if let Binder::Data { dataset, .. } = bnd {
            let path = match l.b.datasets.get(dataset) {
                Some(p) => p.clone(),
                None => match l.spec.datasets.get(dataset) {
                    Some(p) if p.is_absolute() => p.clone(),
                    Some(p) => l.spec.dir.join(p),
                    None => continue, // the lowering names it
                },
            };
            if !path.is_file() {
                return Some(format!(
                    "property `{name}` quantifies over data set `{dataset}`, whose file {} (the spec's path, relative to the spec file) does not exist; pass --dataset {dataset}=FILE (the published training points are {PUBLISHED_DATA})",
                    path.display()
                ));
            }
        }
    }
    None
}

fn named_point(spec: &Spec, q: &Query, p: &Point) -> Value {
    let mut apps = Vec::new();
    for (ai, app) in q.applications.iter().enumerate() {
        let Some(nd): Option<&NetDecl> = spec.networks.iter().find(|n| n.name == app.network)
        else {
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

fn require_networks(l: &Loaded, qs: &[&Instance]) -> Result<()> {
    for i in qs {
        for a in &i.query.applications {
            if !l.nets.contains_key(&a.network) {
                bail!(
                    "property `{}` uses network `{}`; pass --network {}=FILE.onnx",
                    i.label,
                    a.network,
                    a.network
                );
            }
        }
    }
    Ok(())
}

fn reason_json(r: &UnknownReason) -> Value {
    json!({"kind": r.kind(), "message": r.to_string()})
}

/// Run `samara check`: exit 2 on a bad flag or spec, 1 if a property cannot be lowered
/// (e.g. its data set is missing), 0 otherwise.
pub fn run_check(a: &CheckArgs) -> Result<ExitCode> {
    let l = load(&a.s, false)?;
    println!(
        "{}: {} network(s), {} parameter(s), {} propert(ies)",
        a.s.spec.display(),
        l.spec.networks.len(),
        l.spec.params.len(),
        l.spec.properties.len()
    );
    for n in &l.spec.networks {
        println!(
            "  network {}({}) -> ({})",
            n.name,
            n.inputs.join(", "),
            n.outputs.join(", ")
        );
    }
    let mut failed = 0;
    for name in l.spec.property_names() {
        if let Some(m) = missing_data(&l, name) {
            println!("  property {name}: FAILED: {m}");
            failed += 1;
            continue;
        }
        match l.spec.lower_prove(name, &l.b) {
            Ok(inst) => {
                let q = &inst[0].query;
                println!(
                    "  property {name}: {} instance(s), {} network call(s), counterexample region of {} disjunct(s)",
                    inst.len(),
                    q.applications.len(),
                    q.region.len()
                );
            }
            Err(e) => {
                println!("  property {name}: FAILED: {} ({})", e.message, e.hint);
                failed += 1;
            }
        }
    }
    if failed > 0 {
        eprintln!("check failed: {failed} propert(ies) could not be lowered (see above)");
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

/// Run `samara verify`.
pub fn run_verify(a: &VerifyArgs) -> Result<ExitCode> {
    check_timeout(a.timeout)?;
    // `--timeout` is a deadline for the whole command: every instance gets what is left.
    let start = Instant::now();
    let l = load(&a.s, false)?;
    let names: Vec<String> = match &a.property {
        Some(p) => vec![p.clone()],
        None => l
            .spec
            .property_names()
            .iter()
            .map(|s| s.to_string())
            .collect(),
    };
    let mut lowered = Vec::new();
    let mut skipped = Vec::new();
    for n in &names {
        if let Some(m) = missing_data(&l, n) {
            if a.property.is_some() {
                bail!("{m}");
            }
            // The other properties still run; the missing data set is reported at the
            // end (exit 2).
            skipped.push(m);
            continue;
        }
        lowered.push((
            n.clone(),
            l.spec.lower_prove(n, &l.b).map_err(|e| anyhow!("{e}"))?,
        ));
    }
    require_networks(
        &l,
        &lowered
            .iter()
            .flat_map(|(_, v)| v.iter())
            .collect::<Vec<_>>(),
    )?;
    let prep = Prepared::new(&l.nets);
    let settings = Settings {
        timeout: a.timeout,
        max_nodes: a.max_nodes,
        lp_tighten: tighten_mode(a.lp_tighten),
        ..Default::default()
    };
    // Deciding vacuity (is the premise empty over the domain?) is one root LP in
    // practice; it gets at most 10 s of what the deadline leaves (undecided: not called
    // vacuous).
    let vacuity_settings = || Settings {
        timeout: left_after(&settings, start).timeout.min(10.0),
        ..settings
    };
    let mut all_proved = true;
    let mut out = Vec::new();
    for (name, inst) in &lowered {
        let t0 = Instant::now();
        let mut verdicts: Vec<(&Instance, Verdict, f64)> = Vec::new();
        for i in inst {
            let ti = Instant::now();
            let left = left_after(&settings, start);
            let v = if left.timeout > 0.0 {
                prove(&i.query, &prep, &left)?
            } else {
                Verdict::Unknown(UnknownReason::Timeout { nodes: 0 })
            };
            verdicts.push((i, v, ti.elapsed().as_secs_f64()));
        }
        let secs = t0.elapsed().as_secs_f64();
        let (mut p, mut v, mut u) = (0, 0, 0);
        let mut vacuous = Vec::new();
        let mut kinds: Vec<(&'static str, usize)> = Vec::new();
        for (i, verdict, isecs) in &verdicts {
            let q = &i.query;
            let mut vac = Value::Null;
            let mut reason = Value::Null;
            let (tag, cx) = match verdict {
                Verdict::Proved => {
                    p += 1;
                    if let Some(why) = vacuity(q, &prep, &vacuity_settings())? {
                        vacuous.push(i.label.clone());
                        vac = json!(why);
                    }
                    ("proved", Value::Null)
                }
                Verdict::Violated(c) => {
                    v += 1;
                    (
                        "violated",
                        json!({"point": named_point(&l.spec, q, &c.point), "margin": c.margin, "exact_check": c.exact}),
                    )
                }
                Verdict::Unknown(r) => {
                    u += 1;
                    match kinds.iter_mut().find(|k| k.0 == r.kind()) {
                        Some(k) => k.1 += 1,
                        None => kinds.push((r.kind(), 1)),
                    }
                    reason = reason_json(r);
                    ("unknown", json!({"reason": r.to_string()}))
                }
            };
            out.push(json!({"property": i.label, "verdict": tag, "counterexample": cx,
                "seconds": isecs, "vacuous": !vac.is_null(), "vacuity": vac, "unknown_reason": reason}));
        }
        all_proved &= v == 0 && u == 0;
        if !a.json {
            if verdicts.len() == 1 {
                let last = out.last().expect("one");
                let extra = match &verdicts[0].1 {
                    Verdict::Violated(_) => {
                        format!(" counterexample {}", last["counterexample"]["point"])
                    }
                    Verdict::Unknown(r) => format!(" ({}: {r})", r.kind()),
                    Verdict::Proved if !vacuous.is_empty() => {
                        format!(" VACUOUS: {}", last["vacuity"].as_str().unwrap_or(""))
                    }
                    Verdict::Proved => String::new(),
                };
                println!(
                    "{name:<16} {:<9} {secs:>8.3} s{extra}",
                    last["verdict"].as_str().unwrap_or("")
                );
            } else {
                let kinds: Vec<String> = kinds.iter().map(|(k, n)| format!("{k}: {n}")).collect();
                println!(
                    "{name:<16} {} instances: {p} proved{}, {v} violated, {u} unknown{}  {secs:>8.3} s",
                    verdicts.len(),
                    if vacuous.is_empty() {
                        String::new()
                    } else {
                        format!(" ({} vacuously)", vacuous.len())
                    },
                    if kinds.is_empty() {
                        String::new()
                    } else {
                        format!(" ({})", kinds.join(", "))
                    }
                );
            }
        }
        if !vacuous.is_empty() {
            eprintln!(
                "warning: {name}: {} instance(s) proved only vacuously ({}): no point of the input domain meets the premise there (or a data point outside the declared domain has its ball clipped away), so the network was never checked; `samara robustness` evaluates the whole ball of a data point",
                vacuous.len(),
                vacuous.iter().take(5).cloned().collect::<Vec<_>>().join(", ")
            );
        }
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    }
    if !skipped.is_empty() {
        for m in &skipped {
            eprintln!("error: {m}");
        }
        return Ok(ExitCode::from(2));
    }
    Ok(if all_proved {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

fn tighten_mode(on: bool) -> LpTighten {
    if on {
        LpTighten::Root
    } else {
        LpTighten::Off
    }
}

/// The critical value of a parameter, both ends of the counterexample set. `holds` is
/// `unknown` (with `unknown_reason`) when either search was cut short: no claim is made
/// from an incomplete search.
pub fn critical_value(
    l: &Loaded,
    property: &str,
    param: &str,
    settings: &Settings,
) -> Result<Value> {
    if let Some(m) = missing_data(l, property) {
        bail!("{m}");
    }
    let inst = l
        .spec
        .lower_critical(property, param, &l.b)
        .map_err(|e| anyhow!("{e}"))?;
    if inst.len() != 1 {
        bail!("critical values are computed for properties without data-set quantifiers; `{property}` has {} instances", inst.len());
    }
    require_networks(l, &inst.iter().collect::<Vec<_>>())?;
    let prep = Prepared::new(&l.nets);
    let t0 = Instant::now();
    let q_max = inst[0].query.clone();
    let mut q_min = q_max.clone();
    if let Goal::Optimise { sense, .. } = &mut q_min.goal {
        *sense = Sense::Min;
    }
    // `--timeout` is a deadline for both searches together (the second gets what the
    // first left).
    let sup = optimise(&q_max, &prep, settings)?;
    let inf = optimise(&q_min, &prep, &left_after(settings, t0))?;
    let (lo, hi) = l.spec.params[param]
        .range
        .ok_or_else(|| anyhow!("parameter `{param}` has no range"))?;
    let tol = 1e-9 * (1.0 + hi.abs().max(lo.abs()));
    let unknown = sup.unknown.clone().or(inf.unknown.clone());
    // Counterexamples exist for parameter values in [inf, sup] (within [lo, hi]); the
    // property holds above sup if sup is inside the range, else below inf if inf is,
    // else nowhere in the range. Only from complete searches.
    let (holds, chosen) = match (&unknown, inf.value, sup.value) {
        (Some(_), _, _) => ("unknown", None),
        (None, None, _) | (None, _, None) => ("everywhere", None),
        (None, _, Some(s)) if s < hi - tol => ("above", Some(&sup)),
        (None, Some(i), _) if i > lo + tol => ("below", Some(&inf)),
        _ => ("nowhere", Some(&inf)),
    };
    // The sound threshold: the property is proved beyond the search's bound (the
    // critical value lies between the witness value and it).
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
        "witness": chosen.and_then(|c| c.witness.as_ref()).map(|w| named_point(&l.spec, &q_max, w)),
        "complete": unknown.is_none(),
        "unknown_reason": unknown.as_ref().map(reason_json),
        "seconds": t0.elapsed().as_secs_f64(),
    }))
}

/// Run `samara critical`: exit 0 with a result from complete searches, 1 when a
/// search was cut short (`unknown`).
pub fn run_critical(a: &CriticalArgs) -> Result<ExitCode> {
    check_timeout(a.timeout)?;
    let l = load(&a.s, true)?;
    let free: Vec<&String> = a.s.params.iter().filter(|s| !s.contains('=')).collect();
    let [of] = free.as_slice() else {
        bail!("samara critical: name exactly one parameter to search with --param NAME (e.g. --param ystar); got {}", free.len());
    };
    let of = of.trim().to_string();
    let v = critical_value(
        &l,
        &a.property,
        &of,
        &Settings {
            timeout: a.timeout,
            max_nodes: a.max_nodes,
            lp_tighten: tighten_mode(a.lp_tighten),
            ..Default::default()
        },
    )?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        let c = v["critical"].as_f64();
        match (v["holds"].as_str(), c) {
            (Some("unknown"), _) => println!(
                "{}: unknown ({}: {}); no claim about {of}",
                a.property,
                v["unknown_reason"]["kind"].as_str().unwrap_or(""),
                v["unknown_reason"]["message"].as_str().unwrap_or("")
            ),
            (Some("everywhere"), _) => println!("{}: holds for every {} in its range", a.property, of),
            (Some("nowhere"), Some(c)) => println!(
                "{}: fails for every {of} in its declared range (counterexamples from {of} = {c:.3e} up){}",
                a.property,
                if v["vacuous"].as_bool() == Some(true) {
                    "; VACUOUS: it holds only where the precondition is empty"
                } else {
                    ""
                }
            ),
            (Some(h), Some(c)) => {
                let t = v["threshold"].as_f64().unwrap_or(c);
                let attained = v["attained"].as_bool() == Some(true);
                println!(
                    "{}: holds for {} {} {:.9}{}{}  ({:.3} s)",
                    a.property,
                    of,
                    if h == "above" { ">" } else { "<" },
                    t,
                    if attained {
                        String::new()
                    } else {
                        format!(" (sound bound; the critical value lies between {c:.9} and it, not attained)")
                    },
                    if v["vacuous"].as_bool() == Some(true) { "  VACUOUS: the precondition is empty there" } else { "" },
                    v["seconds"].as_f64().unwrap_or(0.0)
                )
            }
            _ => println!("{}: {v}", a.property),
        }
    }
    Ok(if v["holds"] == "unknown" {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

/// A comma-separated list of numbers, each checked by `ok` (whose text says what is
/// allowed), repeated values dropped (a note says so).
fn list(s: &str, flag: &str, ok: fn(f64) -> bool, allowed: &str) -> Result<Vec<f64>> {
    let mut out: Vec<f64> = Vec::new();
    for x in s.split(',') {
        let v = x.trim().parse::<f64>().map_err(|_| {
            anyhow!("--{flag} {s:?}: {:?} is not a number; expected comma-separated numbers, e.g. --{flag} 1e-3,1e-2", x.trim())
        })?;
        if !ok(v) {
            bail!(
                "--{flag} {s:?}: {} is out of range; each value must be {allowed}",
                x.trim()
            );
        }
        if out.contains(&v) {
            eprintln!("note: --{flag} repeats {v:e}; it is counted once");
            continue;
        }
        out.push(v);
    }
    Ok(out)
}

/// Run `samara robustness`.
pub fn run_robustness(a: &RobustnessArgs) -> Result<ExitCode> {
    check_timeout(a.timeout)?;
    // `--timeout` is a deadline for the whole command (each search also stops at it).
    let start = Instant::now();
    let deadline = a
        .timeout
        .is_finite()
        .then(|| start + std::time::Duration::from_secs_f64(a.timeout.min(1e9)));
    if a.shard.is_some() && a.out.is_none() {
        bail!(
            "--shard needs --out FILE (the shard's partial result, for `samara merge robustness`)"
        );
    }
    if let Some(o) = &a.out {
        samara_report::guard::check_output_file(
            "--out",
            o,
            &[("--data", &a.data), ("--network", &a.network)],
        )?;
    }
    let eps = list(
        &a.eps,
        "eps",
        |e| e > 0.0 && e <= 1e6,
        "a radius > 0 and at most 1e6 (in the network's input units)",
    )?;
    let ls = list(
        &a.lipschitz,
        "lipschitz",
        |l| l.is_finite() && l >= 0.0,
        "finite and >= 0",
    )?;
    let reference = match a.reference.as_str() {
        "label" => Reference::Label,
        "network" => Reference::Network,
        o => bail!("--reference {o:?}: choose label or network"),
    };
    if !["published", "lipschitz"].contains(&a.form.as_str()) {
        bail!("--form {:?}: choose published or lipschitz", a.form);
    }
    let net = load_network(&a.network, "--network")?;
    let t = read_data(&a.data, "--data")?;
    let n = net.n_inputs();
    if t.cols < n {
        bail!(
            "--data {}: {} columns but the network has {n} inputs",
            a.data.display(),
            t.cols
        );
    }
    if reference == Reference::Label && t.cols < n + 1 {
        bail!(
            "--data {}: {} columns, the network's {n} inputs and no label column; add the label column (the reference of --reference label) or pass --reference network",
            a.data.display(),
            t.cols
        );
    }
    let rows: Vec<Vec<f64>> = (0..t.rows()).map(|i| t.row(i).to_vec()).collect();
    let used = if reference == Reference::Label {
        n + 1
    } else {
        n
    };
    for (i, r) in rows.iter().enumerate() {
        if let Some(j) = r.iter().take(used).position(|v| !v.is_finite()) {
            bail!(
                "--data {}: row {} column {} is {}, not a finite number; fix or drop the row",
                a.data.display(),
                i + 1,
                j + 1,
                r[j]
            );
        }
    }
    let t0 = Instant::now();
    let settings = Settings {
        timeout: a.timeout,
        max_nodes: a.max_nodes,
        ..Default::default()
    };
    let range = a.shard.map_or(0..rows.len(), |s| s.range(rows.len()));
    let mut points = sweep_until(
        &net,
        &rows[range.clone()],
        &eps,
        reference,
        None,
        &settings,
        deadline,
    )
    .map_err(|e| anyhow!("{e}"))?;
    for p in &mut points {
        p.index += range.start;
    }
    let secs = t0.elapsed().as_secs_f64();
    if let (Some(s), Some(out)) = (a.shard, &a.out) {
        let run = json!({
            "inputs": shard::digest_inputs([
                ("--network".to_string(), a.network.as_path(), "--network".to_string()),
                ("--data".to_string(), a.data.as_path(), "--data".to_string()),
            ])?,
            "points": rows.len(),
            "eps": eps.iter().map(|e| shard::f(*e)).collect::<Vec<_>>(),
            "lipschitz": ls.iter().map(|l| shard::f(*l)).collect::<Vec<_>>(),
            "reference": a.reference, "form": a.form,
            "timeout": shard::f(a.timeout), "max_nodes": a.max_nodes,
        });
        let pts: Vec<Value> = points
            .iter()
            .map(|p| {
                json!({"index": p.index, "eps": shard::f(p.eps), "f_min": shard::f(p.f_min),
                "f_max": shard::f(p.f_max), "reference": shard::f(p.reference),
                "max_deviation": shard::f(p.max_deviation),
                "witnessed_deviation": shard::f(p.witnessed_deviation),
                "lipschitz_lower": shard::f(p.lipschitz_lower),
                "lipschitz_upper": shard::f(p.lipschitz_upper),
                "unknown": p.unknown.as_ref().map(|r| r.kind().to_string())})
            })
            .collect();
        shard::write(
            out,
            "robustness",
            s,
            run,
            json!({"rows": [range.start, range.end], "seconds": secs, "points": pts}),
        )?;
        if a.json {
            println!(
                "{}",
                json!({"shard": [s.i, s.n], "rows": [range.start, range.end], "out": out})
            );
        } else {
            println!(
                "shard {}/{}: rows {}..{} of {} ({} points x {} radii), {secs:.3} s; partial result in {} (merge with `samara merge robustness`)",
                s.i,
                s.n,
                range.start,
                range.end,
                rows.len(),
                range.len(),
                eps.len(),
                out.display()
            );
        }
        return Ok(ExitCode::SUCCESS);
    }
    report_robustness(&Sweep {
        form: &a.form,
        eps: &eps,
        ls: &ls,
        n_rows: rows.len(),
        secs,
        points: &points,
        out: a.out.as_deref(),
        json: a.json,
    })
}

/// A finished robustness sweep (one process, or merged shards).
struct Sweep<'a> {
    form: &'a str,
    eps: &'a [f64],
    ls: &'a [f64],
    n_rows: usize,
    secs: f64,
    points: &'a [samara_verify::robustness::PointBall],
    out: Option<&'a Path>,
    json: bool,
}

/// `samara merge robustness`: the shards' points in order, then the one-process report.
fn merge_robustness(
    run: &Value,
    shards: &[(PathBuf, Value)],
    out: Option<&Path>,
    json_out: bool,
) -> Result<ExitCode> {
    let nums = |key: &str| -> Result<Vec<f64>> {
        run[key]
            .as_array()
            .ok_or_else(|| anyhow!("shard files: no `{key}` list"))?
            .iter()
            .map(|v| {
                v.as_str()
                    .and_then(|s| s.parse().ok())
                    .ok_or_else(|| anyhow!("shard files: bad `{key}` value {v}"))
            })
            .collect()
    };
    let eps = nums("eps")?;
    let ls = nums("lipschitz")?;
    let n_rows = run["points"].as_u64().unwrap_or(0) as usize;
    let form = run["form"].as_str().unwrap_or("published").to_string();
    let mut points = Vec::new();
    let mut secs = 0.0;
    let mut next = 0usize;
    for (file, r) in shards {
        let rows = (r["rows"][0].as_u64(), r["rows"][1].as_u64());
        if rows.0 != Some(next as u64) {
            bail!(
                "{}: rows {}..{}, expected to start at {next} (the shards do not tile the data set)",
                file.display(),
                r["rows"][0],
                r["rows"][1]
            );
        }
        let end = rows.1.unwrap_or(0) as usize;
        if end < next || end > n_rows {
            bail!(
                "{}: rows {}..{} of a {n_rows}-row data set",
                file.display(),
                r["rows"][0],
                r["rows"][1]
            );
        }
        let range = next..end;
        next = end;
        secs += r["seconds"].as_f64().unwrap_or(0.0);
        // Every (row, radius) of the shard's rows exactly once.
        let mut seen = std::collections::HashSet::new();
        let first = points.len();
        for p in r["points"].as_array().into_iter().flatten() {
            let g = |k: &str| shard::get_f(p, k, file);
            points.push(samara_verify::robustness::PointBall {
                index: p["index"]
                    .as_u64()
                    .ok_or_else(|| anyhow!("{}: a point without index", file.display()))?
                    as usize,
                eps: g("eps")?,
                f_min: g("f_min")?,
                f_max: g("f_max")?,
                reference: g("reference")?,
                max_deviation: g("max_deviation")?,
                witnessed_deviation: g("witnessed_deviation")?,
                unknown: None,
                lipschitz_upper: g("lipschitz_upper")?,
                lipschitz_lower: g("lipschitz_lower")?,
            });
            let q = points.last().expect("pushed");
            if !range.contains(&q.index) || !eps.contains(&q.eps) {
                bail!(
                    "{}: a point of row {} radius {} is not of this shard's rows {}..{} and the run's radii",
                    file.display(),
                    q.index,
                    q.eps,
                    range.start,
                    range.end
                );
            }
            if !seen.insert((q.index, q.eps.to_bits())) {
                bail!(
                    "{}: row {} radius {} appears more than once (the shard is damaged or tampered with); run it again",
                    file.display(),
                    q.index,
                    q.eps
                );
            }
            // Sound bounds and witnesses cannot cross (NaN fails too).
            if !(q.f_min <= q.f_max
                && q.witnessed_deviation <= q.max_deviation
                && q.lipschitz_lower <= q.lipschitz_upper)
            {
                bail!(
                    "{}: row {} radius {}: its bounds contradict each other (f_min {} > f_max {}, a witnessed deviation above the bound, or a Lipschitz lower bound above the upper); the shard is damaged or tampered with, run it again",
                    file.display(),
                    q.index,
                    q.eps,
                    q.f_min,
                    q.f_max
                );
            }
        }
        if points.len() - first != range.len() * eps.len() {
            bail!(
                "{}: {} points for rows {}..{} and {} radii (expected {}): the shard was cut short or damaged; run it again",
                file.display(),
                points.len() - first,
                range.start,
                range.end,
                eps.len(),
                range.len() * eps.len()
            );
        }
    }
    if next != n_rows {
        bail!("the shards cover rows 0..{next} of {n_rows}");
    }
    report_robustness(&Sweep {
        form: &form,
        eps: &eps,
        ls: &ls,
        n_rows,
        secs,
        points: &points,
        out,
        json: json_out,
    })
}

/// The robustness table (stdout) and the per-point CSV (`out`).
fn report_robustness(w: &Sweep) -> Result<ExitCode> {
    let (eps, ls, points, secs) = (w.eps, w.ls, w.points, w.secs);
    let mut table = Vec::new();
    let mut any_unknown = false;
    for e in eps {
        let mut row = Vec::new();
        for l in ls {
            let c = if w.form == "published" {
                published_cell(points, *e, *l)
            } else {
                lipschitz_cell(points, *e, *l)
            };
            any_unknown |= c.unknown > 0;
            row.push(json!({"eps": e, "L": l, "proved": c.proved, "violated": c.violated, "unknown": c.unknown,
                "success_rate": c.proved as f64 / w.n_rows.max(1) as f64}));
        }
        table.push(row);
    }
    if let Some(p) = w.out {
        let mut csv = String::from(
            "index,eps,f_min,f_max,reference,max_deviation,lipschitz_lower,lipschitz_upper\n",
        );
        for p in points {
            csv.push_str(&format!(
                "{},{:?},{:?},{:?},{:?},{:?},{:?},{:?}\n",
                p.index,
                p.eps,
                p.f_min,
                p.f_max,
                p.reference,
                p.max_deviation,
                p.lipschitz_lower,
                p.lipschitz_upper
            ));
        }
        samara_report::write_atomic(p, csv.as_bytes())
            .map_err(|e| anyhow!("--out {}: {e}", p.display()))?;
    }
    if w.json {
        println!(
            "{}",
            serde_json::to_string_pretty(
                &json!({"form": w.form, "points": w.n_rows, "seconds": secs, "table": table})
            )?
        );
    } else {
        println!(
            "{} form, {} points, {:.3} s; success rate (rows eps, columns L):",
            w.form, w.n_rows, secs
        );
        print!("{:>10}", "eps \\ L");
        for l in ls {
            print!("{l:>10.0e}");
        }
        println!();
        for (e, row) in eps.iter().zip(&table) {
            print!("{e:>10.0e}");
            for c in row {
                print!(
                    "{:>9.1}%",
                    100.0 * c["success_rate"].as_f64().unwrap_or(0.0)
                );
            }
            println!();
        }
        if any_unknown {
            println!("(some points are unknown, neither proved nor violated: see --json)");
        }
    }
    Ok(ExitCode::SUCCESS)
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

/// Run `samara verify-vnnlib`: prints `unsat` (proved), `sat` (violated, with the
/// counterexample) or `unknown`, as VNN-COMP tools do. Box-shaped properties go to the
/// input-split engine, the rest to the ReLU-phase engine ([`samara_verify::route`]).
pub fn run_verify_vnnlib(a: &VerifyVnnlibArgs) -> Result<ExitCode> {
    check_timeout(a.timeout)?;
    if let Some(r) = &a.result {
        samara_report::guard::check_output_file(
            "--result",
            r,
            &[("--network", &a.network), ("--property", &a.property)],
        )?;
    }
    let (net, q) = vnncomp::load_instance(&a.network, &a.property, "--network", "--property")?;
    let d = vnncomp::decide(net, &q, a.timeout, a.max_nodes)?;
    if let Some(r) = &a.result {
        samara_report::write_atomic(r, vnncomp::result_text(&d).as_bytes())
            .map_err(|e| anyhow!("--result {}: {e}", r.display()))?;
    }
    let tag = match &d.verdict {
        Verdict::Proved => "unsat",
        Verdict::Violated(_) => "sat",
        Verdict::Unknown(_) => "unknown",
    };
    let (cx, reason) = vnncomp::verdict_json(&d);
    if a.json {
        println!(
            "{}",
            json!({"result": tag, "counterexample": cx, "seconds": d.seconds, "unknown_reason": reason, "engine": d.engine.tag()})
        );
    } else {
        match &d.verdict {
            Verdict::Violated(_) => print!("{}", vnncomp::result_text(&d)),
            _ => println!("{tag}"),
        }
        if let Verdict::Unknown(r) = &d.verdict {
            eprintln!("unknown ({}): {r}", r.kind());
        }
    }
    Ok(if tag == "unsat" {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// Run `samara export-vnnlib`: exit 0 when every selected instance was written, 1 when
/// some were skipped (each named on stderr), 2 on bad input.
pub fn run_export(a: &ExportArgs) -> Result<ExitCode> {
    let l = load(&a.s, false)?;
    let names: Vec<String> = match &a.property {
        Some(p) => {
            if !l.spec.property_names().contains(&p.as_str()) {
                bail!(
                    "--property {p}: the spec {} declares no property `{p}`; {}",
                    a.s.spec.display(),
                    suggest(p, l.spec.property_names())
                );
            }
            vec![p.clone()]
        }
        None => l
            .spec
            .property_names()
            .iter()
            .map(|s| s.to_string())
            .collect(),
    };
    // Output protection: never into (or over) an input, never mixed with old files.
    let mut inputs: Vec<(&str, &Path)> = vec![("the spec", a.s.spec.as_path())];
    for f in &l.net_files {
        inputs.push(("--network", f.as_path()));
    }
    for f in l.b.datasets.values() {
        inputs.push(("--dataset", f.as_path()));
    }
    samara_report::guard::check_output_dir("--out", &a.out, &[], &inputs)?;
    if a.out.is_dir() {
        let used = std::fs::read_dir(&a.out)
            .map_err(|e| anyhow!("--out {}: {e}", a.out.display()))?
            .next()
            .is_some();
        if used {
            bail!(
                "--out {}: the folder is not empty; export-vnnlib writes only into an empty or new folder (old and new .vnnlib files would mix): choose a new --out or empty it",
                a.out.display()
            );
        }
    }
    let dir = samara_report::guard::OutDir::prepare(&a.out)?;
    let mut n = 0;
    let mut skipped: Vec<String> = Vec::new();
    for name in &names {
        if let Some(m) = missing_data(&l, name) {
            skipped.push(m);
            continue;
        }
        let inst = match l.spec.lower_prove(name, &l.b) {
            Ok(i) => i,
            Err(e) => {
                skipped.push(format!("property {name}: {} ({})", e.message, e.hint));
                continue;
            }
        };
        for i in inst {
            // Relational instances: rewrite over the stacked network and write its ONNX.
            let mut q = i.query.clone();
            if q.applications.len() > 1 {
                let Some((sq, k)) = vnnlib::stack_applications(&q) else {
                    skipped.push(format!("{}: it calls different networks", i.label));
                    continue;
                };
                let base = &i.query.applications[0].network;
                let Some(net) = l.nets.get(base) else {
                    skipped.push(format!("{}: relational; pass --network {base}=FILE to write the {k}-fold stacked ONNX it needs", i.label));
                    continue;
                };
                let onnx_path = a.out.join(format!("{}.onnx", sq.applications[0].network));
                if !onnx_path.exists() {
                    samara_nn::onnx::save(&net.stacked(k), &onnx_path, &Default::default())
                        .map_err(|e| anyhow!("--out: writing {}: {e}", onnx_path.display()))?;
                }
                q = sq;
            }
            let parts = if a.split_disjuncts {
                vnnlib::split_disjuncts(&q)
            } else {
                vec![q]
            };
            for part in parts {
                match vnnlib::export(&part) {
                    Ok(text) => {
                        let file = a
                            .out
                            .join(format!("{}.vnnlib", part.name.replace(['[', ']'], "_")));
                        samara_report::write_atomic(&file, text.as_bytes())
                            .map_err(|e| anyhow!("--out: writing {}: {e}", file.display()))?;
                        n += 1;
                    }
                    Err(e) => skipped.push(e.to_string()),
                }
            }
        }
    }
    if n == 0 {
        for m in &skipped {
            eprintln!("skipped {m}");
        }
        bail!("no property could be written as VNN-LIB (see the messages above)");
    }
    dir.keep();
    eprintln!("wrote {n} VNN-LIB file(s) to {}", a.out.display());
    if !skipped.is_empty() {
        for m in skipped.iter().take(10) {
            eprintln!("skipped {m}");
        }
        if skipped.len() > 10 {
            eprintln!("... and {} more", skipped.len() - 10);
        }
        eprintln!(
            "error: {} instance(s) or propert(ies) were NOT written (see above); select properties with --property",
            skipped.len()
        );
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}
