//! VNN-COMP pieces: loading one (network, property) instance, deciding it with the routed
//! engines ([`samara_verify::route`]), the competition's result-file format, and
//! `samara vnncomp` (a whole benchmark from its instances CSV).

use anyhow::{anyhow, bail, Result};
pub use samara_app::vnncomp::{decide, load_instance, recheck, Recheck};
use samara_app::vnncomp::{InstanceResult as Part, Word};
use samara_verify::route::Engine;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;
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
    #[command(flatten)]
    /// Worker threads.
    pub threads: crate::threads::ThreadsArg,
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
    #[arg(long, value_name = "I/N", allow_hyphen_values = true, value_parser = crate::shard::parse_shard)]
    pub shard: Option<crate::shard::Shard>,
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

/// What every shard of one `samara vnncomp` run shares (`run` of the shard file).
#[derive(Serialize, Deserialize)]
struct VnncompRun {
    /// The instances CSV: its content digest and its resolved path (the merge reads it
    /// back to check every part against its line).
    instances: String,
    instances_file: String,
    n_instances: usize,
    /// The folder the CSV's paths were resolved against.
    root: String,
    /// The content digest of every network and property file of the whole benchmark,
    /// keyed by the CSV's path text.
    inputs: Value,
    timeout_scale: String,
    max_nodes: usize,
}

/// A vnncomp shard's `result`.
#[derive(Serialize, Deserialize)]
struct VnncompShard {
    /// The instance indices `[start, end)` of this shard.
    instances: [usize; 2],
    /// How many of them are done (the file is rewritten after each).
    done: usize,
    parts: Vec<Part>,
}

/// The `run` record of a vnncomp run: every input's content digest and the settings.
fn vnncomp_run(a: &VnncompArgs, text: &str, all: &[Line], root: &Path) -> Result<VnncompRun> {
    let files = all.iter().flat_map(|l| {
        let at = format!("{}:{}:", a.instances.display(), l.lineno);
        [
            (l.onnx.clone(), root.join(&l.onnx), format!("{at} onnx")),
            (
                l.vnnlib.clone(),
                root.join(&l.vnnlib),
                format!("{at} vnnlib"),
            ),
        ]
    });
    let files: Vec<(String, PathBuf, String)> = files.collect();
    Ok(VnncompRun {
        instances: crate::shard::digest(text.as_bytes()),
        instances_file: crate::shard::resolved(&a.instances),
        n_instances: all.len(),
        root: crate::shard::resolved(root),
        inputs: serde_json::to_value(crate::shard::digest_inputs(
            files
                .iter()
                .map(|(n, p, f)| (n.clone(), p.as_path(), f.clone())),
        )?)?,
        timeout_scale: format!("{:?}", a.timeout_scale),
        max_nodes: a.max_nodes,
    })
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
    // A shard seals every input of the whole run (not only its own lines), so the merge
    // sees a file edited between two shards' runs.
    let run = match a.shard {
        Some(_) => Some(serde_json::to_value(vnncomp_run(a, &text, &all, &root)?)?),
        None => None,
    };
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
        samara_app::bind::timeout_flag(t)?;
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
    let mut shard_doc = VnncompShard {
        instances: [range.start, range.end],
        done: 0,
        parts: Vec::new(),
    };
    let mut rows = Vec::new();
    let mut counts: BTreeMap<Word, usize> = Default::default();
    if let (Some(s), Some(run)) = (a.shard, &run) {
        // At once, so a shard with no instances (N above their number) still leaves its
        // file, and a cut-short shard leaves one that the merge refuses.
        crate::shard::write(&a.out, "vnncomp", s, &run, &shard_doc)?;
    }
    for (l, (net, q, t)) in lines.iter().zip(loaded) {
        bar.set_message(format!("{} {}", l.onnx, l.vnnlib));
        let d = decide(net, &q, t, a.max_nodes)?;
        if let Some(n) = &d.note {
            bar.suspend(|| eprintln!("note: {n}"));
        }
        let part = Part::of(l.lineno, &l.onnx, &l.vnnlib, t, &d);
        *counts.entry(part.result).or_default() += 1;
        let row = serde_json::to_string(&serde_json::to_value(part.row())?)?;
        let progress = part.progress();
        if let (Some(s), Some(run)) = (a.shard, &run) {
            shard_doc.parts.push(part);
            shard_doc.done = shard_doc.parts.len();
            crate::shard::write(&a.out, "vnncomp", s, &run, &shard_doc)?;
        } else {
            csv.push_str(&part.csv_line());
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
            let line = samara_app::vnncomp::ShardLine {
                shard: (s.i, s.n),
                instances: (range.start, range.end),
                counts: word_counts(&counts)
                    .into_iter()
                    .map(|(w, n)| (w.to_string(), n))
                    .collect(),
                total_seconds: total,
                out: a.out.clone(),
            };
            println!("{}", crate::json_text(&line, false)?);
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
    summary(lines.len(), &counts, &rows, total, &a.out, a.json)?;
    Ok(ExitCode::SUCCESS)
}

/// The results CSV's header.
const HEADER: &str = "onnx,vnnlib,timeout,result,seconds,engine,detail\n";

/// The counts by result word, keyed by the word's text.
fn word_counts(counts: &BTreeMap<Word, usize>) -> BTreeMap<&'static str, usize> {
    counts.iter().map(|(w, n)| (w.text(), *n)).collect()
}

/// The closing summary on stdout: `--json` (every instance's row, as serialised, and the
/// counts) or one line.
fn summary(
    n: usize,
    counts: &BTreeMap<Word, usize>,
    rows: &[String],
    total: f64,
    out: &Path,
    json_out: bool,
) -> Result<()> {
    let summary: Vec<String> = [Word::Unsat, Word::Sat, Word::Timeout, Word::Unknown]
        .iter()
        .map(|w| format!("{} {}", w.text(), counts.get(w).copied().unwrap_or(0)))
        .collect();
    if json_out {
        // By hand, in serde_json's (sorted-key, compact) form: the rows are kept as they
        // were serialised, so merged shards print the same numbers digit for digit.
        println!(
            "{{\"counts\":{},\"instances\":[{}],\"out\":{},\"total_seconds\":{}}}",
            serde_json::to_string(&word_counts(counts))?,
            rows.join(","),
            serde_json::to_string(out)?,
            serde_json::to_string(&total)?
        );
    } else {
        println!(
            "{n} instances: {}; {total:.1} s in all; results in {}",
            summary.join(", "),
            out.display()
        );
    }
    Ok(())
}

/// Check one part of a shard against the run: it is the instance of its line (the same
/// files and timeout), its fields agree with its result word, and a `sat` part's
/// counterexample holds when the network is evaluated concretely ([`recheck`]; the
/// network and property are read back and must be the files the shards digested).
/// Returns the part with the re-computed outputs.
fn check_part(file: &Path, run: &VnncompRun, l: &Line, scale: f64, mut p: Part) -> Result<Part> {
    let at = format!(
        "{}: line {} ({}, {})",
        file.display(),
        l.lineno,
        l.onnx,
        l.vnnlib
    );
    let t = l.timeout * scale;
    if p.line != l.lineno || p.onnx != l.onnx || p.vnnlib != l.vnnlib || p.timeout != t {
        bail!(
            "{}: the part for line {} is line {} ({}, {}, timeout {}), not the instances CSV's ({}, {}, timeout {t}): the shard does not belong to these instances; run it again",
            file.display(),
            l.lineno,
            p.line,
            p.onnx,
            p.vnnlib,
            p.timeout,
            l.onnx,
            l.vnnlib
        );
    }
    if !(p.seconds.is_finite() && p.seconds >= 0.0) {
        bail!("{at}: `seconds` {} is not a wall time", p.seconds);
    }
    if ![
        Engine::InputSplit,
        Engine::Phase,
        Engine::InputSplitThenPhase,
    ]
    .iter()
    .any(|e| e.tag() == p.engine)
    {
        bail!("{at}: unknown engine `{}`", p.engine);
    }
    match (p.result, &p.counterexample, &p.unknown_reason) {
        (Word::Unsat, None, None) => {}
        (Word::Timeout, None, Some(r)) if r.kind == "timeout" => {}
        (Word::Unknown, None, Some(r)) if r.kind != "timeout" => {}
        (Word::Sat, None, _) => {
            bail!("{at}: `sat` without a counterexample; a `sat` part must carry its point (run the shard again)")
        }
        (Word::Sat, Some(c), None) => {
            let root = Path::new(&run.root);
            let (onnx, vnnlib) = (root.join(&l.onnx), root.join(&l.vnnlib));
            for (name, path) in [(&l.onnx, &onnx), (&l.vnnlib, &vnnlib)] {
                let now = crate::shard::digest_file(path, &format!("{at}: re-checking the counterexample needs"))?;
                if run.inputs[name.as_str()] != now.as_str() {
                    bail!(
                        "{at}: input `{name}` ({}) changed since the shards ran (content digest {} then, {now} now); run every shard again",
                        path.display(),
                        run.inputs[name.as_str()]
                    );
                }
            }
            let (net, q) = load_instance(&onnx, &vnnlib, "onnx", "vnnlib")
                .map_err(|e| anyhow!("{at}: {e}"))?;
            let y = match recheck(&net, &q, &c.inputs, c.disjunct)
                .map_err(|e| anyhow!("{at}: the `sat` counterexample is malformed: {e}"))?
            {
                Recheck::Holds(y) | Recheck::ExactOnly(y, _) => y,
                Recheck::Fails(margin) => bail!(
                    "{at}: the `sat` counterexample does not hold: the network's outputs there miss the property's region (margin {margin:e}); the shard is damaged or tampered with, run it again"
                ),
            };
            if y.iter().map(|v| v.to_bits()).ne(c.outputs.iter().map(|v| v.to_bits())) {
                bail!(
                    "{at}: the `sat` counterexample's outputs {:?} are not the network's {:?} at its inputs; the shard is damaged or tampered with, run it again",
                    c.outputs,
                    y
                );
            }
            if let Some(c) = &mut p.counterexample {
                c.outputs = y;
            }
        }
        _ => bail!(
            "{at}: result `{}` with {} counterexample and {} unknown reason: the fields contradict each other; the shard is damaged or tampered with, run it again",
            p.result.text(),
            if p.counterexample.is_some() { "a" } else { "no" },
            p.unknown_reason
                .as_ref()
                .map_or("no".to_string(), |r| format!("a `{}`", r.kind))
        ),
    }
    Ok(p)
}

/// `samara merge vnncomp`: the shards' instances in order, each checked against the run's
/// instances CSV (read back from where the shards resolved it: every instance exactly
/// once) and rebuilt from its typed result, every `sat` counterexample re-checked on the
/// network; then the results CSV and the summary, as one process writes them.
pub fn merge_vnncomp(
    run: &Value,
    shards: &[(PathBuf, Value)],
    out: &Path,
    json_out: bool,
) -> Result<ExitCode> {
    let (file0, _) = &shards[0];
    let run: VnncompRun = serde_json::from_value(run.clone())
        .map_err(|e| anyhow!("{}: not a vnncomp run record: {e}", file0.display()))?;
    let csv_path = PathBuf::from(&run.instances_file);
    let text = std::fs::read_to_string(&csv_path).map_err(|e| {
        anyhow!(
            "{}: the run's instances CSV {}: cannot read: {e} (the merge reads the run's inputs back to check the shards)",
            file0.display(),
            csv_path.display()
        )
    })?;
    if crate::shard::digest(text.as_bytes()) != run.instances {
        bail!(
            "input `{}` changed since the shards ran (content digest {} then, {} now); run every shard again",
            csv_path.display(),
            run.instances,
            crate::shard::digest(text.as_bytes())
        );
    }
    let all = parse_instances(&csv_path, &text)?;
    if all.len() != run.n_instances {
        bail!(
            "{}: {} instances recorded, the CSV {} has {}",
            file0.display(),
            run.n_instances,
            csv_path.display(),
            all.len()
        );
    }
    let scale: f64 = run
        .timeout_scale
        .parse()
        .map_err(|_| anyhow!("{}: bad `run.timeout_scale`", file0.display()))?;
    let mut csv = String::from(HEADER);
    let mut rows = Vec::new();
    let mut counts: BTreeMap<Word, usize> = Default::default();
    let mut total = 0.0;
    let mut next = 0usize;
    let mut n = 0;
    let n_shards = shards.len();
    for (i, (file, r)) in shards.iter().enumerate() {
        let r: VnncompShard = serde_json::from_value(r.clone())
            .map_err(|e| anyhow!("{}: not a vnncomp shard result: {e}", file.display()))?;
        let want = crate::shard::Shard { i, n: n_shards }.range(all.len());
        if r.instances != [want.start, want.end] || want.start != next {
            bail!(
                "{}: instances {}..{}, expected {}..{} for shard {i}/{n_shards} (the shards do not tile the instances)",
                file.display(),
                r.instances[0],
                r.instances[1],
                want.start,
                want.end
            );
        }
        if r.parts.len() > want.len() {
            bail!(
                "{}: {} instance parts for its {} instances {}..{}: an instance appears more than once (the shard is damaged or tampered with); run it again",
                file.display(),
                r.parts.len(),
                want.len(),
                want.start,
                want.end
            );
        }
        if r.parts.len() != want.len() || r.done != r.parts.len() {
            bail!(
                "{}: {} of its {} instances done (the shard was cut short); run it again",
                file.display(),
                r.parts.len().min(r.done),
                want.len()
            );
        }
        next = want.end;
        for (l, p) in all[want].iter().zip(r.parts) {
            let p = check_part(file, &run, l, scale, p)?;
            *counts.entry(p.result).or_default() += 1;
            csv.push_str(&p.csv_line());
            rows.push(serde_json::to_string(&serde_json::to_value(p.row())?)?);
            total += p.seconds;
            if !json_out {
                println!("{}", p.progress());
            }
            n += 1;
        }
    }
    samara_report::write_atomic(out, csv.as_bytes())
        .map_err(|e| anyhow!("--out {}: {e}", out.display()))?;
    summary(n, &counts, &rows, total, out, json_out)?;
    Ok(ExitCode::SUCCESS)
}
