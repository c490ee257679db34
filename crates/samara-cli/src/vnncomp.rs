//! VNN-COMP pieces: loading one (network, property) instance, deciding it with the routed
//! engines ([`samara_verify::route`]), the competition's result-file format, and
//! `samara vnncomp` (a whole benchmark from its instances CSV).

use anyhow::{anyhow, Result};
pub use samara_app::args::VnncompArgs;
pub use samara_app::vnncomp::{decide, load_instance};
use samara_app::vnncomp::{
    parse_instances, InstanceResult as Part, Line, VnncompRun, VnncompShard, Word,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

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
        inputs: crate::shard::digest_inputs(
            files
                .iter()
                .map(|(n, p, f)| (n.clone(), p.as_path(), f.clone())),
        )?,
        timeout_scale: format!("{:?}", a.timeout_scale),
        max_nodes: a.max_nodes,
    })
}

/// Run `samara vnncomp`: exit 0 when the benchmark ran (verdicts are data), 2 on bad
/// input (every instance is loaded and checked before the first is run).
pub fn run_vnncomp(a: &VnncompArgs) -> Result<ExitCode> {
    a.validate()?;
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
        let limit = samara_app::bind::timeout_flag(t)?;
        loaded.push((net, q, t, limit));
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
    for (l, (net, q, t, limit)) in lines.iter().zip(loaded) {
        bar.set_message(format!("{} {}", l.onnx, l.vnnlib));
        let d = decide(net, &q, limit, a.max_nodes)?;
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

/// `samara merge vnncomp`: the shards' instances in order, each checked against the run's
/// instances CSV and every `sat` counterexample re-checked on the network
/// (`samara_app::vnncomp::merge_vnncomp`); then the results CSV and the summary, as one
/// process writes them.
pub fn merge_vnncomp(
    shards: &samara_app::shard::Shards,
    out: &Path,
    json_out: bool,
) -> Result<ExitCode> {
    let parts = samara_app::vnncomp::merge_vnncomp(shards, |p| {
        if !json_out {
            println!("{}", p.progress());
        }
    })?;
    let mut csv = String::from(HEADER);
    let mut rows = Vec::new();
    let mut counts: BTreeMap<Word, usize> = Default::default();
    let mut total = 0.0;
    for p in &parts {
        *counts.entry(p.result).or_default() += 1;
        csv.push_str(&p.csv_line());
        rows.push(serde_json::to_string(&serde_json::to_value(p.row())?)?);
        total += p.seconds;
    }
    samara_report::write_atomic(out, csv.as_bytes())
        .map_err(|e| anyhow!("--out {}: {e}", out.display()))?;
    summary(parts.len(), &counts, &rows, total, out, json_out)?;
    Ok(ExitCode::SUCCESS)
}
