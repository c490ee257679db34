//! VNN-COMP pieces: loading one (network, property) instance, deciding it with the routed
//! engines ([`samara_verify::route`]), the competition's result-file format, and
//! `samara vnncomp` (a whole benchmark from its instances CSV).
//!
//! **Each instance keeps its own limit.** Every instance of `samara vnncomp` runs in one
//! process (its networks are loaded once and shared), so the backstop of `verify-vnnlib`
//! (which ends the process) cannot serve it. Instead the load of a network and the
//! decision of an instance each run on a worker thread ([`within`]) that the run waits for
//! until [`crate::verify::BACKSTOP_GRACE`] after the instance's limit: past it the instance
//! is `timeout` ([`crate::verify::ended_at_limit`]), its result is written, and the run goes
//! on to the next line while the abandoned step finishes in the background (it looks at
//! the passed deadline at its next clock check and returns, freeing its memory). Why not
//! the alternatives: a child process per instance (`verify-vnnlib` with its backstop)
//! loads every network once per instance, seconds and gigabytes for an image-sized one,
//! where the run's promise is one load per network; fork-after-load cannot be used with
//! the engines' thread pool; and cooperative clock checks alone are a promise about every
//! step of every engine: on a wide convolution (3x32x32 to 128x16x16 to 128x16x16,
//! `tests/conv_time_limits.rs`) main's run overran by 1.3 s in the lowering and by
//! 1.6 s before the first search step (measured on a loaded machine, `--timeout 12` and
//! `5`), each step within its own clock checks. The cost: an abandoned step shares the
//! cores and holds its share of the network (and the network's piecewise-linear form)
//! until it ends.

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
use std::sync::{mpsc, Arc};
use std::time::Instant;

/// The stack of a worker thread ([`within`]): the main thread's 8 MiB, not a spawned
/// thread's default 2 MiB (the engines were written for the main thread's).
const WORKER_STACK: usize = 8 << 20;

/// Run `work` on a worker thread and wait for its result until `until` (for ever when
/// `None`): `None` when it has not returned by then, the thread then left to finish on
/// its own (its result is dropped). A panic of `work` is resumed here, as if it had run
/// on this thread; when no thread can be started, `work` runs here (the limit then rests
/// on its own clock checks).
fn within<T: Send + 'static>(
    until: Option<Instant>,
    work: impl FnOnce() -> T + Send + 'static,
) -> Option<T> {
    let (tx, rx) = mpsc::channel();
    let job = Arc::new(std::sync::Mutex::new(Some(work)));
    let theirs = Arc::clone(&job);
    let spawned = std::thread::Builder::new()
        .name("vnncomp-instance".into())
        .stack_size(WORKER_STACK)
        .spawn(move || {
            let work = theirs.lock().ok().and_then(|mut w| w.take());
            if let Some(work) = work {
                let _ = tx.send(work());
            }
        });
    let handle = match spawned {
        Ok(h) => h,
        Err(e) => {
            eprintln!("warning: no worker thread for the instance ({e}): its limit rests on the engines' clock checks");
            let work = job.lock().ok().and_then(|mut w| w.take())?;
            return Some(work());
        }
    };
    let got = match until {
        None => rx.recv().map_err(|_| mpsc::RecvTimeoutError::Disconnected),
        Some(t) => rx.recv_timeout(t.saturating_duration_since(Instant::now())),
    };
    match got {
        Ok(v) => Some(v),
        Err(mpsc::RecvTimeoutError::Timeout) => None,
        Err(mpsc::RecvTimeoutError::Disconnected) => match handle.join() {
            Err(panic) => std::panic::resume_unwind(panic),
            Ok(()) => None,
        },
    }
}

/// When the run stops waiting for an instance whose limit ends at `deadline`.
fn give_up_at(deadline: Option<Instant>) -> Option<Instant> {
    deadline.map(|d| d + crate::verify::BACKSTOP_GRACE)
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
        Some(_) => Some(serde_json::to_value(VnncompRun::of(
            a, &text, &all, &root,
        )?)?),
        None => None,
    };
    // Load everything first: a bad instance is an input error before any computation.
    // A network used by several lines is loaded once (an image-sized one takes seconds
    // and gigabytes); each instance borrows it (no copy) when it runs. The load counts against
    // the limit of the instance that needs it first (a generator's lowering takes
    // minutes): it stops there, that instance is a timeout, and the next line that
    // uses the network tries again within its own limit.
    // A load runs on a worker ([`within`]) the run waits for until just after the
    // limit; one past it is a timeout, and the network is not kept.
    let mut loaded = Vec::new();
    let mut networks: Vec<Arc<Network>> = Vec::new();
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
            None => {
                let (path, logits) = (onnx.clone(), key.1);
                let deadline = limit.deadline_from(start);
                let net = within(give_up_at(deadline), move || {
                    load_network_as(&path, "onnx", logits, deadline)
                })
                .transpose()
                .map_err(line_err)?
                .flatten();
                net.map(|(net, _)| {
                    networks.push(Arc::new(net));
                    index.insert(key, networks.len() - 1);
                    networks.len() - 1
                })
            }
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
            // The decision (with a share of the network) runs on a worker that the run
            // waits for until just after the limit.
            Some((k, q)) => {
                let net = Arc::clone(&networks[k]);
                let deadline = limit
                    .deadline_from(start)
                    .map(|d| d.checked_sub(load).unwrap_or(start));
                let max_nodes = a.max_nodes;
                let work = move || {
                    let left = match deadline {
                        Some(d) => samara_num::Timeout::from_duration(
                            d.saturating_duration_since(Instant::now()),
                        ),
                        None => samara_num::Timeout::none(),
                    };
                    decide(&net, &q, left, max_nodes)
                };
                match within(give_up_at(deadline), work) {
                    Some(d) => d?,
                    None => crate::verify::ended_at_limit(0.0, "the instance"),
                }
            }
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    /// The run stops waiting at `until` whatever the work does (a step that never looks
    /// at the clock), returns the work's value when it is in time, waits for ever
    /// without a limit, and a panic of the work is the caller's.
    #[test]
    fn within_stops_waiting_at_its_limit() {
        let t = Instant::now();
        let r = within(Some(t + Duration::from_millis(100)), || {
            std::thread::sleep(Duration::from_secs(3));
            1
        });
        assert_eq!(r, None);
        let waited = t.elapsed();
        assert!(
            (Duration::from_millis(100)..Duration::from_secs(1)).contains(&waited),
            "{waited:?}"
        );
        assert_eq!(
            within(Some(Instant::now() + Duration::from_secs(30)), || 2),
            Some(2)
        );
        assert_eq!(
            within(None, || {
                std::thread::sleep(Duration::from_millis(50));
                3
            }),
            Some(3)
        );
        let p = std::panic::catch_unwind(|| within(None, || -> u8 { panic!("in the worker") }));
        assert!(p.is_err());
    }
}
