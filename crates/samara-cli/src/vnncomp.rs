//! VNN-COMP pieces: loading one (network, property) instance, deciding it with the routed
//! engines ([`samara_verify::route`]), the competition's result-file format, and
//! `samara vnncomp` (a whole benchmark from its instances CSV).

use anyhow::{anyhow, Result};
pub use samara_app::args::VnncompArgs;
use samara_app::benchmark::Tally;
use samara_app::vnncomp::{check_instance, load_network_as, read_property, wants_logits};
pub use samara_app::vnncomp::{decide, timed_out_loading};
use samara_app::vnncomp::{parse_instances, InstanceResult as Part, VnncompRun, VnncompShard};
use samara_nn::Network;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

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
        Some(_) => Some(serde_json::to_value(VnncompRun::of(
            a, &text, &all, &root,
        )?)?),
        None => None,
    };
    // Load everything first: a bad instance is an input error before any computation.
    // A network used by several lines is loaded once (an image-sized one takes seconds
    // and gigabytes); each instance gets a copy when it runs. The load counts against
    // the limit of the instance that needs it first (a generator's lowering takes
    // minutes): it stops there, that instance is a timeout, and the next line that
    // uses the network tries again within its own limit.
    let mut loaded = Vec::new();
    let mut networks: Vec<Network> = Vec::new();
    let mut index: HashMap<(PathBuf, bool), usize> = HashMap::new();
    for l in lines {
        let at = format!("{}:{}", a.instances.display(), l.lineno);
        // Every message gets the CSV line once, here (the labels stay bare, so a
        // network the loader refuses does not read `FILE:LINE: FILE:LINE: onnx ...`).
        let line_err = |e: samara_app::AppError| anyhow!("{at}: {e}");
        let (onnx, vnnlib) = (root.join(&l.onnx), root.join(&l.vnnlib));
        let t = l.timeout * a.timeout_scale;
        let limit = samara_app::bind::timeout_flag(t)?;
        let start = Instant::now();
        let q = read_property(&vnnlib, "vnnlib");
        let key = (onnx.clone(), wants_logits(&onnx, &q));
        let k = match index.get(&key) {
            Some(&k) => Some(k),
            None => match load_network_as(&onnx, "onnx", key.1, limit.deadline_from(start))
                .map_err(line_err)?
            {
                Some((net, _)) => {
                    networks.push(net);
                    index.insert(key, networks.len() - 1);
                    Some(networks.len() - 1)
                }
                None => None,
            },
        };
        let q = q.map_err(line_err)?;
        let inst = match k {
            Some(k) => Some((
                k,
                check_instance(&networks[k], q, &onnx, &vnnlib).map_err(line_err)?,
            )),
            None => None,
        };
        loaded.push((inst, t, limit, start.elapsed()));
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
    let mut tally = Tally::new();
    let mut shard_doc = VnncompShard {
        instances: [range.start, range.end],
        done: 0,
        parts: Vec::new(),
    };
    if let (Some(s), Some(run)) = (a.shard, &run) {
        // At once, so a shard with no instances (N above their number) still leaves its
        // file, and a cut-short shard leaves one that the merge refuses.
        crate::shard::write(&a.out, "vnncomp", s, &run, &shard_doc)?;
    }
    for (l, (inst, t, limit, load)) in lines.iter().zip(loaded) {
        bar.set_message(format!("{} {}", l.onnx, l.vnnlib));
        let start = Instant::now();
        let mut d = match inst {
            // What the load took is taken from the instance's limit and added to its time.
            Some((k, q)) => decide(
                networks[k].clone(),
                &q,
                limit.left_at(start, start + load),
                a.max_nodes,
            )?,
            None => timed_out_loading(0.0),
        };
        d.seconds = load.as_secs_f64() + start.elapsed().as_secs_f64();
        if let Some(n) = &d.note {
            bar.suspend(|| eprintln!("note: {n}"));
        }
        let part = Part::of(l.lineno, &l.onnx, &l.vnnlib, t, &d);
        let progress = part.progress();
        tally.add(&part, a.shard.is_none())?;
        if let (Some(s), Some(run)) = (a.shard, &run) {
            shard_doc.parts.push(part);
            shard_doc.done = shard_doc.parts.len();
            crate::shard::write(&a.out, "vnncomp", s, &run, &shard_doc)?;
        } else {
            samara_report::write_atomic(&a.out, tally.csv.as_bytes())
                .map_err(|e| anyhow!("--out {}: {e}", a.out.display()))?;
        }
        if !a.json {
            bar.suspend(|| println!("{progress}"));
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let total = t0.elapsed().as_secs_f64();
    if let Some(s) = a.shard {
        if a.json {
            let line = samara_app::vnncomp::ShardLine {
                shard: (s.i, s.n),
                instances: (range.start, range.end),
                counts: tally
                    .word_counts()
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
    println!("{}", tally.summary(total, &a.out, a.json)?);
    Ok(ExitCode::SUCCESS)
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
    let mut tally = Tally::new();
    for p in &parts {
        tally.add(p, true)?;
    }
    let total = parts.iter().fold(0.0, |t, p| t + p.seconds);
    samara_report::write_atomic(out, tally.csv.as_bytes())
        .map_err(|e| anyhow!("--out {}: {e}", out.display()))?;
    println!("{}", tally.summary(total, out, json_out)?);
    Ok(ExitCode::SUCCESS)
}
