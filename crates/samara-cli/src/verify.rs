//! `samara check | verify | critical | robustness | export-vnnlib`.

use anyhow::{anyhow, bail, Context, Result};
use samara_spec::lower::NetDecl;
use samara_spec::normal::{Goal, Query, Sense};
use samara_spec::{vnnlib, Bindings, Instance, Spec};
use samara_verify::engine::Point;
use samara_verify::robustness::{lipschitz_cell, published_cell, sweep, Reference};
use samara_verify::{optimise, prove, LpTighten, Prepared, Settings, Verdict};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::path::PathBuf;
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
    /// Bind a data set (repeatable): --dataset train=data.csv.
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
    /// Time limit per query in seconds.
    #[arg(long, default_value_t = 60.0)]
    pub timeout: f64,
    /// Tighten unstable neurons' bounds with LPs at the root of each search
    /// (`samara_verify::tighten`; off by default).
    #[arg(long)]
    pub lp_tighten: bool,
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
    /// Time limit in seconds.
    #[arg(long, default_value_t = 60.0)]
    pub timeout: f64,
    /// Tighten unstable neurons' bounds with LPs at the root of each search
    /// (`samara_verify::tighten`; off by default).
    #[arg(long)]
    pub lp_tighten: bool,
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
    /// Radii (comma-separated).
    #[arg(long, default_value = "1e-5,1e-4,1e-3,1e-2")]
    pub eps: String,
    /// Bounds L (comma-separated).
    #[arg(long, default_value = "1e-5,1e-4,1e-3,1e-2")]
    pub lipschitz: String,
    /// Reference of the published form: label or network.
    #[arg(long, default_value = "label")]
    pub reference: String,
    /// published (|f(x') - ref| <= L / eps) or lipschitz (|f(x') - f(x)| <= L ||x' - x||).
    #[arg(long, default_value = "published")]
    pub form: String,
    /// Per-point results CSV.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// JSON output.
    #[arg(long)]
    pub json: bool,
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
    /// Time limit in seconds.
    #[arg(long, default_value_t = 60.0)]
    pub timeout: f64,
    /// JSON output.
    #[arg(long)]
    pub json: bool,
}

/// Run `samara verify-vnnlib`: prints `unsat` (proved), `sat` (violated, with the
/// counterexample) or `unknown`, as VNN-COMP tools do.
pub fn run_verify_vnnlib(a: &VerifyVnnlibArgs) -> Result<ExitCode> {
    let net = samara_nn::onnx::load(&a.network)?;
    let text = std::fs::read_to_string(&a.property)
        .with_context(|| format!("cannot read {}", a.property.display()))?;
    let q = vnnlib::import(&text, &a.property.display().to_string(), "f", "property")?;
    let app = &q.applications[0];
    if app.n_inputs != net.n_inputs() || app.n_outputs != net.n_outputs() {
        bail!(
            "dimension mismatch: {} declares {} inputs and {} outputs, the network has {} and {}",
            a.property.display(),
            app.n_inputs,
            app.n_outputs,
            net.n_inputs(),
            net.n_outputs()
        );
    }
    let mut nets = HashMap::new();
    nets.insert("f".to_string(), net);
    let prep = Prepared::new(&nets);
    let t0 = Instant::now();
    let v = prove(
        &q,
        &prep,
        &Settings {
            timeout: a.timeout,
            ..Default::default()
        },
    )?;
    let secs = t0.elapsed().as_secs_f64();
    let (tag, cx) = match &v {
        Verdict::Proved => ("unsat", Value::Null),
        Verdict::Violated(c) => (
            "sat",
            json!({"inputs": c.point.inputs[0], "outputs": c.point.outputs[0], "margin": c.margin, "exact_check": c.exact}),
        ),
        Verdict::Unknown(r) => ("unknown", json!(r)),
    };
    if a.json {
        println!(
            "{}",
            json!({"result": tag, "counterexample": cx, "seconds": secs})
        );
    } else {
        println!("{tag}");
    }
    Ok(if tag == "unsat" {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// Flags of `samara export-vnnlib`.
#[derive(clap::Args, Debug)]
pub struct ExportArgs {
    #[command(flatten)]
    /// Spec and bindings.
    pub s: SpecArgs,
    /// Output directory (one .vnnlib per property instance).
    #[arg(long)]
    pub out: PathBuf,
    /// One file per disjunct of the counterexample region (for tools that cannot read `or`).
    #[arg(long)]
    pub split_disjuncts: bool,
}

fn kv(s: &str, flag: &str) -> Result<(String, String)> {
    let (k, v) = s
        .split_once('=')
        .ok_or_else(|| anyhow!("--{flag} {s:?}: expected NAME=VALUE"))?;
    Ok((k.trim().to_string(), v.trim().to_string()))
}

/// Loaded spec, networks and bindings.
pub struct Loaded {
    /// The spec.
    pub spec: Spec,
    /// Networks by name.
    pub nets: HashMap<String, samara_nn::Network>,
    /// Bindings.
    pub b: Bindings,
}

/// Load a spec and its bindings.
pub fn load(a: &SpecArgs) -> Result<Loaded> {
    let spec = Spec::read(&a.spec).map_err(|e| anyhow!("{e}"))?;
    let mut b = Bindings::default();
    let mut nets = HashMap::new();
    for s in &a.networks {
        let (k, v) = kv(s, "network")?;
        if !spec.networks.iter().any(|n| n.name == k) {
            bail!(
                "--network {k}=...: the spec declares no network `{k}` (it declares {})",
                spec.networks
                    .iter()
                    .map(|n| n.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        let net = samara_nn::onnx::load(&v)?;
        b.network_dims
            .insert(k.clone(), (net.n_inputs(), net.n_outputs()));
        nets.insert(k, net);
    }
    for s in a.params.iter().filter(|s| s.contains('=')) {
        let (k, v) = kv(s, "param")?;
        let x: f64 = v
            .parse()
            .map_err(|_| anyhow!("--param {k}={v}: not a number"))?;
        if !spec.params.contains_key(&k) {
            bail!("--param {k}: the spec declares no parameter `{k}`");
        }
        b.params.insert(k, x);
    }
    for s in &a.datasets {
        let (k, v) = kv(s, "dataset")?;
        b.datasets.insert(k, PathBuf::from(v));
    }
    Ok(Loaded { spec, nets, b })
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

/// Run `samara check`.
pub fn run_check(a: &CheckArgs) -> Result<ExitCode> {
    let l = load(&a.s)?;
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
    for name in l.spec.property_names() {
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
            Err(e) => println!("  property {name}: not lowered yet ({})", e.message),
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Run `samara verify`.
pub fn run_verify(a: &VerifyArgs) -> Result<ExitCode> {
    let l = load(&a.s)?;
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
    for n in &names {
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
        lp_tighten: tighten_mode(a.lp_tighten),
        ..Default::default()
    };
    let mut all_proved = true;
    let mut out = Vec::new();
    for (name, inst) in &lowered {
        let t0 = Instant::now();
        let verdicts: Vec<(String, Verdict)> = inst
            .iter()
            .map(|i| prove(&i.query, &prep, &settings).map(|v| (i.label.clone(), v)))
            .collect::<Result<_, _>>()?;
        let secs = t0.elapsed().as_secs_f64();
        let (mut p, mut v, mut u) = (0, 0, 0);
        for (label, verdict) in &verdicts {
            let q = &inst
                .iter()
                .find(|i| &i.label == label)
                .expect("instance")
                .query;
            let (tag, cx) = match verdict {
                Verdict::Proved => {
                    p += 1;
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
                    ("unknown", json!({"reason": r}))
                }
            };
            out.push(json!({"property": label, "verdict": tag, "counterexample": cx, "seconds": secs / verdicts.len() as f64}));
        }
        all_proved &= v == 0 && u == 0;
        if !a.json {
            if verdicts.len() == 1 {
                let last = out.last().expect("one");
                let extra = match &verdicts[0].1 {
                    Verdict::Violated(_) => {
                        format!(" counterexample {}", last["counterexample"]["point"])
                    }
                    Verdict::Unknown(r) => format!(" ({r})"),
                    Verdict::Proved => String::new(),
                };
                println!(
                    "{name:<16} {:<9} {secs:>8.3} s{extra}",
                    last["verdict"].as_str().unwrap_or("")
                );
            } else {
                println!(
                    "{name:<16} {} instances: {p} proved, {v} violated, {u} unknown  {secs:>8.3} s",
                    verdicts.len()
                );
            }
        }
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
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

/// The critical value of a parameter, both ends of the counterexample set.
pub fn critical_value(
    l: &Loaded,
    property: &str,
    param: &str,
    settings: &Settings,
) -> Result<Value> {
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
    let sup = optimise(&q_max, &prep, settings)?;
    let inf = optimise(&q_min, &prep, settings)?;
    let (lo, hi) = l.spec.params[param]
        .range
        .expect("checked by lower_critical");
    let tol = 1e-9 * (1.0 + hi.abs().max(lo.abs()));
    // Counterexamples exist for parameter values in [inf, sup] (within [lo, hi]); the
    // property holds above sup if sup is inside the range, else below inf if inf is,
    // else nowhere in the range.
    let (holds, chosen) = match (inf.value, sup.value) {
        (None, _) | (_, None) => ("everywhere", None),
        (_, Some(s)) if s < hi - tol => ("above", Some(&sup)),
        (Some(i), _) if i > lo + tol => ("below", Some(&inf)),
        _ => ("nowhere", Some(&inf)),
    };
    Ok(json!({
        "property": property,
        "parameter": param,
        "holds": holds,
        "critical": chosen.and_then(|c| c.value),
        "bound": chosen.map(|c| c.bound),
        "attained": chosen.map(|c| c.attained).unwrap_or(false),
        "vacuous": chosen.map(|c| c.vacuous).unwrap_or(false),
        "domain_extreme": chosen.and_then(|c| c.domain_extreme),
        "counterexample_range": [inf.value, sup.value],
        "witness": chosen.and_then(|c| c.witness.as_ref()).map(|w| named_point(&l.spec, &q_max, w)),
        "complete": sup.complete && inf.complete,
        "seconds": t0.elapsed().as_secs_f64(),
    }))
}

/// Run `samara critical`.
pub fn run_critical(a: &CriticalArgs) -> Result<ExitCode> {
    let l = load(&a.s)?;
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
            lp_tighten: tighten_mode(a.lp_tighten),
            ..Default::default()
        },
    )?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        let c = v["critical"].as_f64();
        match (v["holds"].as_str(), c) {
            (Some("everywhere"), _) => println!("{}: holds for every {} in its range", a.property, of),
            (Some("nowhere"), Some(c)) => println!(
                "{}: fails for every {of} in its declared range (counterexamples from {of} = {c:.3e} up); VACUOUS: it holds only where the precondition is empty",
                a.property
            ),
            (Some(h), Some(c)) => println!(
                "{}: holds for {} {} {:.9}{}{}  ({:.3} s)",
                a.property,
                of,
                if h == "above" { ">" } else { "<" },
                c,
                if v["attained"].as_bool() == Some(true) { "" } else { " (supremum, not attained)" },
                if v["vacuous"].as_bool() == Some(true) { "  VACUOUS: the precondition is empty there" } else { "" },
                v["seconds"].as_f64().unwrap_or(0.0)
            ),
            _ => println!("{}: {v}", a.property),
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn list(s: &str, flag: &str) -> Result<Vec<f64>> {
    s.split(',')
        .map(|x| {
            x.trim()
                .parse::<f64>()
                .map_err(|_| anyhow!("--{flag} {s:?}: expected comma-separated numbers"))
        })
        .collect()
}

/// Run `samara robustness`.
pub fn run_robustness(a: &RobustnessArgs) -> Result<ExitCode> {
    let net = samara_nn::onnx::load(&a.network)?;
    let t = samara_nn::data::read_table(&a.data)?;
    let n = net.n_inputs();
    if t.cols < n {
        bail!(
            "{}: {} columns but the network has {n} inputs",
            a.data.display(),
            t.cols
        );
    }
    let eps = list(&a.eps, "eps")?;
    let ls = list(&a.lipschitz, "lipschitz")?;
    let reference = match a.reference.as_str() {
        "label" => Reference::Label,
        "network" => Reference::Network,
        o => bail!("--reference {o:?}: choose label or network"),
    };
    if !["published", "lipschitz"].contains(&a.form.as_str()) {
        bail!("--form {:?}: choose published or lipschitz", a.form);
    }
    let rows: Vec<Vec<f64>> = (0..t.rows()).map(|i| t.row(i).to_vec()).collect();
    let t0 = Instant::now();
    let points = sweep(&net, &rows, &eps, reference, None).map_err(|e| anyhow!("{e}"))?;
    let secs = t0.elapsed().as_secs_f64();
    let mut table = Vec::new();
    for e in &eps {
        let mut row = Vec::new();
        for l in &ls {
            let c = if a.form == "published" {
                published_cell(&points, *e, *l)
            } else {
                lipschitz_cell(&points, *e, *l)
            };
            row.push(json!({"eps": e, "L": l, "proved": c.proved, "violated": c.violated, "unknown": c.unknown,
                "success_rate": c.proved as f64 / rows.len() as f64}));
        }
        table.push(row);
    }
    if let Some(p) = &a.out {
        let mut csv = String::from(
            "index,eps,f_min,f_max,reference,max_deviation,lipschitz_lower,lipschitz_upper\n",
        );
        for p in &points {
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
            .with_context(|| format!("writing {}", p.display()))?;
    }
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(
                &json!({"form": a.form, "points": rows.len(), "seconds": secs, "table": table})
            )?
        );
    } else {
        println!(
            "{} form, {} points, {:.3} s; success rate (rows eps, columns L):",
            a.form,
            rows.len(),
            secs
        );
        print!("{:>10}", "eps \\ L");
        for l in &ls {
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
    }
    Ok(ExitCode::SUCCESS)
}

/// Run `samara export-vnnlib`.
pub fn run_export(a: &ExportArgs) -> Result<ExitCode> {
    let l = load(&a.s)?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let mut n = 0;
    for name in l.spec.property_names() {
        let inst = match l.spec.lower_prove(name, &l.b) {
            Ok(i) => i,
            Err(e) => {
                eprintln!("skipped property {name}: {}", e.message);
                continue;
            }
        };
        for i in inst {
            // Relational instances: rewrite over the stacked network and write its ONNX.
            let mut q = i.query.clone();
            if q.applications.len() > 1 {
                let Some((sq, k)) = vnnlib::stack_applications(&q) else {
                    eprintln!("skipped {}: it calls different networks", i.label);
                    continue;
                };
                let base = &i.query.applications[0].network;
                let Some(net) = l.nets.get(base) else {
                    eprintln!("skipped {}: relational; pass --network {base}=FILE to write the {k}-fold stacked ONNX it needs", i.label);
                    continue;
                };
                let onnx_path = a.out.join(format!("{}.onnx", sq.applications[0].network));
                if !onnx_path.exists() {
                    samara_nn::onnx::save(&net.stacked(k), &onnx_path, &Default::default())
                        .with_context(|| format!("writing {}", onnx_path.display()))?;
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
                        samara_report::write_atomic(&file, text.as_bytes())?;
                        n += 1;
                    }
                    Err(e) => eprintln!("skipped: {e}"),
                }
            }
        }
    }
    if n == 0 {
        bail!("no property could be written as VNN-LIB (see the messages above)");
    }
    eprintln!("wrote {n} VNN-LIB file(s) to {}", a.out.display());
    Ok(ExitCode::SUCCESS)
}
