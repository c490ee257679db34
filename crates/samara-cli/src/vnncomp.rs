//! VNN-COMP pieces: loading one (network, property) instance, deciding it with the routed
//! engines ([`samara_verify::route`]), the competition's result-file format, and
//! `samara vnncomp` (a whole benchmark from its instances CSV).

use super::{check_timeout, load_network, reason_json, var_at, vnn_name};
use anyhow::{anyhow, bail, Result};
use samara_nn::Network;
use samara_spec::normal::{Query, Var};
use samara_spec::vnnlib;
use samara_verify::engine::Point;
use samara_verify::route::{prove_routed, Engine};
use samara_verify::{Prepared, Settings, UnknownReason, Verdict};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Run a VNN-COMP benchmark (its instances CSV): sat/unsat/timeout/unknown and seconds
/// per instance, a results CSV and a summary.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  samara vnncomp benchmarks/acasxu/acasxu_instances.csv --out results.csv\n  samara vnncomp instances.csv --root benchmarks/acasxu --timeout-scale 0.5 --out r.csv --json\n\nExit codes: 0 the benchmark ran (its verdicts are data, in --out), 2 a usage or input error (the message names the CSV line, the file, the flag)."
)]
pub struct VnncompArgs {
    /// The benchmark's instances CSV: lines `onnx,vnnlib,timeout` (paths relative to the
    /// CSV's folder, or to --root).
    pub instances: PathBuf,
    /// Folder the CSV's paths are relative to (default: the CSV's folder).
    #[arg(long)]
    pub root: Option<PathBuf>,
    /// Results CSV (one line per instance: onnx,vnnlib,timeout,result,seconds,engine,
    /// detail); rewritten atomically after each instance.
    #[arg(long)]
    pub out: PathBuf,
    /// Multiply every instance's timeout by this (> 0).
    #[arg(long, default_value_t = 1.0)]
    pub timeout_scale: f64,
    /// Node limit per search of the ReLU-phase engine (used for queries that are not
    /// box-shaped).
    #[arg(long, default_value_t = 200_000)]
    pub max_nodes: usize,
    /// JSON output (every instance and the summary) on stdout.
    #[arg(long)]
    pub json: bool,
    /// Run only shard I of N (0-based): the instance lines split into N contiguous
    /// parts. --out is then this shard's partial result (JSON); `samara merge vnncomp
    /// FILES --out results.csv` puts the N files together.
    #[arg(long, value_name = "I/N", allow_hyphen_values = true, value_parser = super::shard::parse_shard)]
    pub shard: Option<super::shard::Shard>,
}

/// Load and check one instance: the network and the property (exit 2 on a bad one,
/// naming the flag or file, the line or the operator).
pub fn load_instance(
    network: &Path,
    property: &Path,
    net_flag: &str,
    prop_flag: &str,
) -> Result<(Network, Query)> {
    let net = load_network(network, net_flag)?;
    let text = std::fs::read_to_string(property)
        .map_err(|e| anyhow!("{prop_flag} {}: cannot read: {e}", property.display()))?;
    let file = property.display().to_string();
    let q = vnnlib::import(&text, &file, "f", "property").map_err(|e| anyhow!("{e}"))?;
    let Some(app) = q.applications.first() else {
        bail!("{file}: the property calls no network");
    };
    if app.n_inputs != net.n_inputs() || app.n_outputs != net.n_outputs() {
        bail!(
            "dimension mismatch: {file} declares {} inputs and {} outputs, the network {} has {} and {}",
            app.n_inputs,
            app.n_outputs,
            network.display(),
            net.n_inputs(),
            net.n_outputs()
        );
    }
    // Every variable used must be declared and exist in the network.
    for e in q.region.iter().flatten().map(|c| &c.expr) {
        for (v, _) in &e.terms {
            let (used, declared, have, what) = match *v {
                Var::Input { index, .. } => (index, app.n_inputs, net.n_inputs(), "inputs"),
                Var::Output { index, .. } => (index, app.n_outputs, net.n_outputs(), "outputs"),
                Var::Free(_) => {
                    bail!("{file}: uses {}, which is not an X_i or Y_j", vnn_name(*v))
                }
            };
            if used >= declared.min(have) {
                bail!(
                    "{file}: the property uses {}, which it does not declare (it declares {declared} {what}; the network {} has {have}): use only the declared variables, {} to {}",
                    vnn_name(*v),
                    network.display(),
                    vnn_name(var_at(*v, 0)),
                    vnn_name(var_at(*v, declared.min(have).saturating_sub(1)))
                );
            }
        }
    }
    if app.input_box.len() != net.n_inputs() {
        bail!(
            "{file}: bounds for {} inputs but the network has {}",
            app.input_box.len(),
            net.n_inputs()
        );
    }
    if let Some((i, (l, h))) = app
        .input_box
        .iter()
        .enumerate()
        .find(|(_, (l, h))| !l.is_finite() || !h.is_finite())
    {
        bail!(
            "{file}: input X_{i} is bounded by [{l}, {h}]; give it finite bounds with top-level asserts, e.g. (assert (>= X_{i} 0.0)) and (assert (<= X_{i} 1.0))"
        );
    }
    Ok((net, q))
}

/// A decided instance.
pub struct Decided {
    /// The verdict (a `Violated` one re-evaluated, see [`decide`]).
    pub verdict: Verdict,
    /// The engine that decided.
    pub engine: Engine,
    /// Wall time of the decision.
    pub seconds: f64,
    /// For `Violated`: the outputs at the counterexample by the network's own f64
    /// evaluator (`Network::eval_f64`), written to the result file.
    pub outputs: Option<Vec<f64>>,
}

/// Decide one instance within `timeout` seconds. A counterexample is re-evaluated by the
/// network's plain f64 evaluator before it is reported: a point the engines confirmed in
/// exact rational arithmetic stays `sat` (its f64 outputs are the ones written; a
/// disagreement is said on stderr); a point neither exact arithmetic confirmed nor the
/// f64 re-evaluation satisfies becomes `unknown` (rounding).
pub fn decide(net: Network, q: &Query, timeout: f64, max_nodes: usize) -> Result<Decided> {
    let mut nets = HashMap::new();
    nets.insert("f".to_string(), net);
    let prep = Prepared::new(&nets);
    let t0 = Instant::now();
    let (mut verdict, engine) = prove_routed(
        q,
        &prep,
        &Settings {
            timeout,
            max_nodes,
            ..Default::default()
        },
    )?;
    let mut outputs = None;
    if let Verdict::Violated(c) = &verdict {
        let x = &c.point.inputs[0];
        let y = nets["f"].eval_f64(x);
        let again = Point {
            inputs: vec![x.clone()],
            outputs: vec![y.clone()],
            free: vec![],
        };
        let cs = &q.region[c.disjunct];
        if !again.satisfies(cs) {
            if c.exact == Some(true) {
                eprintln!(
                    "note: the counterexample holds in exact arithmetic but the f64 re-evaluation puts it outside the region by rounding (margin {:e})",
                    again.margin(cs)
                );
            } else {
                verdict = Verdict::Unknown(UnknownReason::Rounding {
                    margin: again.margin(cs),
                    tolerance: 0.0,
                });
            }
        }
        if matches!(verdict, Verdict::Violated(_)) {
            outputs = Some(y);
        }
    }
    Ok(Decided {
        verdict,
        engine,
        seconds: t0.elapsed().as_secs_f64(),
        outputs,
    })
}

/// The competition's result word: `sat`, `unsat`, `timeout` (the time limit ran out) or
/// `unknown` (any other reason).
pub fn result_word(v: &Verdict) -> &'static str {
    match v {
        Verdict::Proved => "unsat",
        Verdict::Violated(_) => "sat",
        Verdict::Unknown(UnknownReason::Timeout { .. }) => "timeout",
        Verdict::Unknown(_) => "unknown",
    }
}

/// The result file's text (VNN-COMP 2021-2024): the word on the first line; after `sat`
/// the assignment `((X_0 v)`, ` (X_1 v)`, ..., ` (Y_m v))`, one variable per line,
/// values in the shortest decimal form that reads back to the same f64.
pub fn result_text(d: &Decided) -> String {
    let mut s = format!("{}\n", result_word(&d.verdict));
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

/// The JSON of a decided instance's verdict (the `verify-vnnlib --json` fields).
pub fn verdict_json(d: &Decided) -> (Value, Value) {
    match &d.verdict {
        Verdict::Proved => (Value::Null, Value::Null),
        Verdict::Violated(c) => (
            json!({"inputs": c.point.inputs[0], "outputs": d.outputs, "margin": c.margin, "exact_check": c.exact}),
            Value::Null,
        ),
        Verdict::Unknown(r) => (json!(r.to_string()), reason_json(r)),
    }
}

/// One line of an instances CSV.
struct Line {
    onnx: String,
    vnnlib: String,
    timeout: f64,
    lineno: usize,
}

fn parse_instances(path: &Path, text: &str) -> Result<Vec<Line>> {
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let l = raw.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let f: Vec<&str> = l.split(',').map(str::trim).collect();
        let bad = |why: &str| {
            anyhow!(
                "{}:{}: {why}; expected `onnx,vnnlib,timeout` (e.g. net.onnx,prop.vnnlib,116)",
                path.display(),
                i + 1
            )
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
        bail!(
            "{}: no instances (expected lines `onnx,vnnlib,timeout`)",
            path.display()
        );
    }
    Ok(out)
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Run `samara vnncomp`: exit 0 when the benchmark ran (verdicts are data), 2 on bad
/// input (every instance is loaded and checked before the first is run).
pub fn run_vnncomp(a: &VnncompArgs) -> Result<ExitCode> {
    if !(a.timeout_scale > 0.0 && a.timeout_scale.is_finite()) {
        bail!(
            "--timeout-scale {}: must be a finite number > 0 (e.g. --timeout-scale 0.5)",
            a.timeout_scale
        );
    }
    let text = std::fs::read_to_string(&a.instances)
        .map_err(|e| anyhow!("{}: cannot read: {e}", a.instances.display()))?;
    let all = parse_instances(&a.instances, &text)?;
    let range = a.shard.map_or(0..all.len(), |s| s.range(all.len()));
    let lines = &all[range.clone()];
    let run = json!({"instances": super::shard::digest(text.as_bytes()), "n_instances": all.len(),
        "timeout_scale": super::shard::f(a.timeout_scale), "max_nodes": a.max_nodes});
    let root = match &a.root {
        Some(r) => r.clone(),
        None => a
            .instances
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default(),
    };
    let mut inputs: Vec<(String, PathBuf)> = vec![("INSTANCES".into(), a.instances.clone())];
    for l in lines {
        inputs.push((format!("line {} onnx", l.lineno), root.join(&l.onnx)));
        inputs.push((format!("line {} vnnlib", l.lineno), root.join(&l.vnnlib)));
    }
    let refs: Vec<(&str, &Path)> = inputs
        .iter()
        .map(|(f, p)| (f.as_str(), p.as_path()))
        .collect();
    samara_report::guard::check_output_file("--out", &a.out, &refs)?;
    // Load everything first: a bad instance is an input error before any computation.
    let mut loaded = Vec::new();
    for l in lines {
        let at = format!("{}:{}", a.instances.display(), l.lineno);
        let (net, q) = load_instance(
            &root.join(&l.onnx),
            &root.join(&l.vnnlib),
            &format!("{at}: onnx"),
            &format!("{at}: vnnlib"),
        )
        .map_err(|e| anyhow!("{at}: {e}"))?;
        let t = l.timeout * a.timeout_scale;
        check_timeout(t)?;
        loaded.push((net, q, t));
    }
    let bar = {
        use std::io::IsTerminal;
        let p = indicatif::ProgressBar::new(lines.len() as u64);
        if !std::io::stderr().is_terminal() {
            p.set_draw_target(indicatif::ProgressDrawTarget::hidden());
        }
        p.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:30} {pos}/{len} [{elapsed_precise}] {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        p
    };
    let t0 = Instant::now();
    let mut csv = String::from(HEADER);
    let mut parts = Vec::new();
    let mut rows = Vec::new();
    let mut counts: std::collections::BTreeMap<&str, usize> = Default::default();
    if let Some(s) = a.shard {
        // At once, so a shard with no instances (N above their number) still leaves its
        // file, and a cut-short shard leaves one that the merge refuses.
        super::shard::write(
            &a.out,
            "vnncomp",
            s,
            run.clone(),
            json!({"instances": [range.start, range.end], "done": 0, "parts": []}),
        )?;
    }
    for (l, (net, q, t)) in lines.iter().zip(loaded) {
        bar.set_message(format!("{} {}", l.onnx, l.vnnlib));
        let d = decide(net, &q, t, a.max_nodes)?;
        let word = result_word(&d.verdict);
        *counts.entry(word).or_default() += 1;
        let detail = match &d.verdict {
            Verdict::Unknown(r) => r.kind().to_string(),
            Verdict::Violated(c) => format!(
                "exact_check={}",
                c.exact.map_or("none".into(), |b| b.to_string())
            ),
            Verdict::Proved => String::new(),
        };
        let csv_line = format!(
            "{},{},{},{word},{:.3},{},{}\n",
            csv_field(&l.onnx),
            csv_field(&l.vnnlib),
            t,
            d.seconds,
            d.engine.tag(),
            csv_field(&detail)
        );
        let progress = format!("{} {} {word} {:.2}s", l.onnx, l.vnnlib, d.seconds);
        let (cx, reason) = verdict_json(&d);
        let row = serde_json::to_string(
            &json!({"line": l.lineno, "onnx": l.onnx, "vnnlib": l.vnnlib, "timeout": t,
            "result": word, "seconds": d.seconds, "engine": d.engine.tag(),
            "counterexample": cx, "unknown_reason": reason}),
        )?;
        if let Some(s) = a.shard {
            parts.push(json!({"csv": csv_line, "row": row, "result": word,
                "seconds": d.seconds, "progress": progress}));
            super::shard::write(
                &a.out,
                "vnncomp",
                s,
                run.clone(),
                json!({"instances": [range.start, range.end], "done": parts.len(), "parts": parts}),
            )?;
        } else {
            csv.push_str(&csv_line);
            samara_report::write_atomic(&a.out, csv.as_bytes())
                .map_err(|e| anyhow!("--out {}: {e}", a.out.display()))?;
        }
        if !a.json {
            bar.suspend(|| println!("{progress}"));
        }
        rows.push(row);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let total = t0.elapsed().as_secs_f64();
    if let Some(s) = a.shard {
        if a.json {
            println!(
                "{}",
                json!({"shard": [s.i, s.n], "instances": [range.start, range.end], "counts": counts,
                    "total_seconds": total, "out": a.out})
            );
        } else {
            println!(
                "shard {}/{}: instances {}..{} of {}; {total:.1} s; partial result in {} (merge with `samara merge vnncomp`)",
                s.i,
                s.n,
                range.start,
                range.end,
                all.len(),
                a.out.display()
            );
        }
        return Ok(ExitCode::SUCCESS);
    }
    summary(lines.len(), &counts, &rows, total, &a.out, a.json);
    Ok(ExitCode::SUCCESS)
}

/// The results CSV's header.
const HEADER: &str = "onnx,vnnlib,timeout,result,seconds,engine,detail\n";

/// The closing summary on stdout: `--json` (every instance's row, as serialised, and the
/// counts) or one line.
fn summary(
    n: usize,
    counts: &std::collections::BTreeMap<&str, usize>,
    rows: &[String],
    total: f64,
    out: &Path,
    json_out: bool,
) {
    let summary: Vec<String> = ["unsat", "sat", "timeout", "unknown"]
        .iter()
        .map(|w| format!("{w} {}", counts.get(w).copied().unwrap_or(0)))
        .collect();
    if json_out {
        // By hand, in serde_json's (sorted-key, compact) form: the rows are kept as they
        // were serialised, so merged shards print the same numbers digit for digit.
        println!(
            "{{\"counts\":{},\"instances\":[{}],\"out\":{},\"total_seconds\":{}}}",
            json!(counts),
            rows.join(","),
            json!(out),
            json!(total)
        );
    } else {
        println!(
            "{n} instances: {}; {total:.1} s in all; results in {}",
            summary.join(", "),
            out.display()
        );
    }
}

/// `samara merge vnncomp`: the shards' rows in instance order, the results CSV and the
/// summary, as one process writes them.
pub fn merge_vnncomp(shards: &[(PathBuf, Value)], out: &Path, json_out: bool) -> Result<ExitCode> {
    let mut csv = String::from(HEADER);
    let mut rows = Vec::new();
    let mut counts: std::collections::BTreeMap<&str, usize> = Default::default();
    let mut total = 0.0;
    let mut next = 0u64;
    let mut n = 0;
    for (file, r) in shards {
        let (lo, hi) = (r["instances"][0].as_u64(), r["instances"][1].as_u64());
        let parts = r["parts"].as_array().cloned().unwrap_or_default();
        if lo != Some(next) {
            bail!(
                "{}: instances {}..{}, expected to start at {next} (the shards do not tile the instances)",
                file.display(),
                r["instances"][0],
                r["instances"][1]
            );
        }
        let hi = hi.unwrap_or(0);
        if parts.len() as u64 != hi - next {
            bail!(
                "{}: {} of its {} instances done (the shard was cut short); run it again",
                file.display(),
                parts.len(),
                hi - next
            );
        }
        next = hi;
        for p in &parts {
            let (Some(c), Some(row), Some(word)) =
                (p["csv"].as_str(), p["row"].as_str(), p["result"].as_str())
            else {
                bail!("{}: a malformed instance entry", file.display());
            };
            let word = ["unsat", "sat", "timeout", "unknown"]
                .into_iter()
                .find(|w| *w == word)
                .ok_or_else(|| anyhow!("{}: result `{word}`", file.display()))?;
            *counts.entry(word).or_default() += 1;
            csv.push_str(c);
            rows.push(row.to_string());
            total += p["seconds"].as_f64().unwrap_or(0.0);
            if !json_out {
                println!("{}", p["progress"].as_str().unwrap_or_default());
            }
            n += 1;
        }
    }
    samara_report::write_atomic(out, csv.as_bytes())
        .map_err(|e| anyhow!("--out {}: {e}", out.display()))?;
    summary(n, &counts, &rows, total, out, json_out);
    Ok(ExitCode::SUCCESS)
}
