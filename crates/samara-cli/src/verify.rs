//! `samara check | verify | critical | robustness | export-vnnlib | verify-vnnlib`, and
//! (in `vnncomp.rs`) `samara vnncomp`.

use anyhow::{anyhow, bail, Result};
pub use samara_app::args::{
    CheckArgs, CriticalArgs, ExportArgs, RobustnessArgs, SpecArgs, VerifyArgs, VerifyVnnlibArgs,
};
use samara_app::bind::timeout_flag;
use samara_app::robustness::{self, SweepDone};
use samara_app::vnncomp::{
    decide, load_instance_logits, result_text, softmax, timed_out_loading, Decided, InstanceVerdict,
};
use samara_app::{Holds, VerdictRow};
use samara_verify::{Settings, Verdict};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// A spec with its networks, parameters and data sets bound (owned by the run).
pub type Loaded = samara_app::Loaded<'static>;

/// Load a spec and its bindings ([`SpecArgs::load`]); a units warning is printed as soon
/// as its network is bound.
pub fn load(a: &SpecArgs, free_params: bool) -> Result<Loaded> {
    Ok(a.load(free_params, |w| eprintln!("warning: {w}"))?)
}

/// Run `samara check`: exit 2 on a bad flag or spec, 1 if a property cannot be lowered
/// (e.g. its data set is missing), 0 otherwise.
pub fn run_check(a: &CheckArgs) -> Result<ExitCode> {
    let l = load(&a.s, false)?;
    let r = samara_app::check::check(&l, &a.s.spec.display().to_string());
    for line in &r.lines {
        println!("{line}");
    }
    if let Some(m) = r.failure() {
        eprintln!("{m}");
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

/// Run `samara verify`: the library's [`samara_app::run_verify`], one line per property
/// (or the rows as JSON).
pub fn run_verify(a: &VerifyArgs) -> Result<ExitCode> {
    let timeout = timeout_flag(a.timeout)?;
    // `--timeout` is a deadline for the whole command: every instance gets what is left.
    let start = Instant::now();
    let l = load(&a.s, false)?;
    let settings = Settings {
        timeout,
        max_nodes: a.search.max_nodes,
        ..Default::default()
    };
    let json_out = a.search.json;
    let run = samara_app::run_verify(&l, a.property.as_deref(), &settings, start, true, |p| {
        if !json_out {
            println!("{}", p.human_line());
        }
        if let Some(w) = p.vacuity_warning() {
            eprintln!("{w}");
        }
    })?;
    if a.search.json {
        let rows: Vec<&VerdictRow> = run.rows().collect();
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::to_value(rows)?)?
        );
    }
    if !run.skipped.is_empty() {
        for m in &run.skipped {
            eprintln!("error: {m}");
        }
        return Ok(ExitCode::from(2));
    }
    Ok(if run.all_proved() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// Run `samara critical`: exit 0 with a result from complete searches, 1 when a
/// search was cut short (`unknown`). The decision is the library's
/// ([`samara_app::critical_value`]).
pub fn run_critical(a: &CriticalArgs) -> Result<ExitCode> {
    let timeout = timeout_flag(a.timeout)?;
    let l = load(&a.s, true)?;
    let free: Vec<&String> = a.s.params.iter().filter(|s| !s.contains('=')).collect();
    let [of] = free.as_slice() else {
        bail!("samara critical: name exactly one parameter to search with --param NAME (e.g. --param ystar); got {}", free.len());
    };
    let of = of.trim().to_string();
    let v = samara_app::critical_value(
        &l,
        &a.property,
        &of,
        &Settings {
            timeout,
            max_nodes: a.search.max_nodes,
            ..Default::default()
        },
    )?;
    if a.search.json {
        println!("{}", crate::json_text(&v, true)?);
    } else {
        println!("{}", v.human_line(&a.property, &of));
    }
    Ok(if v.holds == Holds::Unknown {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

/// Run `samara robustness`.
pub fn run_robustness(a: &RobustnessArgs) -> Result<ExitCode> {
    let timeout = timeout_flag(a.timeout)?;
    // `--timeout` is a deadline for the whole command (each search also stops at it).
    let start = Instant::now();
    let deadline = timeout.deadline_from(start);
    let settings = Settings {
        timeout,
        max_nodes: a.max_nodes,
        ..Default::default()
    };
    match robustness::run(a, &settings, deadline, |n| eprintln!("{n}"))? {
        SweepDone::Shard { line, .. } if a.json => {
            println!("{}", crate::json_text(&line, false)?)
        }
        SweepDone::Shard { human, .. } => println!("{human}"),
        SweepDone::Table(r) => print_table(&r, a.json)?,
    }
    Ok(ExitCode::SUCCESS)
}

/// `samara merge robustness`: the shards' points in order
/// (`samara_app::robustness::merge`), then the one-process report.
pub(crate) fn merge_robustness(
    shards: &samara_app::shard::Shards,
    out: Option<&Path>,
    json_out: bool,
) -> Result<ExitCode> {
    print_table(&robustness::merge(shards, out)?, json_out)?;
    Ok(ExitCode::SUCCESS)
}

/// The robustness table on stdout: `--json` or the text table.
fn print_table(r: &robustness::SweepReport, json: bool) -> Result<()> {
    if json {
        println!("{}", crate::json_text(&r.table, true)?);
    } else {
        print!("{}", r.human);
    }
    Ok(())
}

/// Run `samara verify-vnnlib`: prints `unsat` (proved), `sat` (violated, with the
/// counterexample) or `unknown`, as VNN-COMP tools do. Box-shaped properties go to the
/// input-split engine, the rest to the exact optimiser ([`samara_verify::route`]).
///
/// `--timeout` is a promise: the load and the search look at the clock between steps,
/// and a backstop ([`start_backstop`]) reports `unknown` and ends the process
/// [`BACKSTOP_GRACE`] after the limit if they have not returned by then (a step of a
/// search on an image-sized network, or freeing its gigabytes, can outlast the limit).
pub fn run_verify_vnnlib(a: &VerifyVnnlibArgs) -> Result<ExitCode> {
    let start = std::time::Instant::now();
    let timeout = timeout_flag(a.timeout)?;
    if let Some(r) = &a.result {
        samara_report::guard::check_output_file(
            "--result",
            r,
            &[("--network", &a.network), ("--property", &a.property)],
        )?;
    }
    if let Some(deadline) = timeout.deadline_from(start) {
        start_backstop(deadline, start, a.json, a.result.clone());
    }
    // `--timeout` counts from the start: loading a wide network (a CIFAR convolution
    // lowered to dense maps) takes seconds of it, minutes for an image-sized generator,
    // so the load itself stops at the deadline.
    let loaded = load_instance_logits(
        &a.network,
        &a.property,
        "--network",
        "--property",
        timeout.deadline_from(start),
    )?;
    let mut d = match loaded {
        Some((net, q, logits)) => {
            let mut d = decide(&net, &q, timeout.left(start), a.max_nodes)?;
            samara_app::vnncomp::free_apart(net);
            if logits {
                // The file's network ends in the softmax that was left out: show its
                // outputs.
                d.outputs = d.outputs.map(|y| softmax(&y));
            }
            d
        }
        None => timed_out_loading(start.elapsed().as_secs_f64()),
    };
    d.seconds = start.elapsed().as_secs_f64();
    if !take_report() {
        // The backstop is reporting the timeout and ends the process.
        loop {
            std::thread::park();
        }
    }
    report_vnnlib(&d, a.json, a.result.as_deref())
}

/// How long after `--timeout` the backstop of `verify-vnnlib` ([`start_backstop`])
/// reports `unknown (timeout)` and ends the process, when the run has not reported by
/// then: a quarter of the second the limit promises; the rest is for the process's
/// exit, which returns its memory to the kernel (a gigabyte takes 0.1-0.2 CPU seconds,
/// most of a second of wall time on a loaded machine).
pub const BACKSTOP_GRACE: Duration = Duration::from_millis(250);

/// Set by the first of the run and its backstop to report a verdict ([`take_report`]).
static REPORTED: AtomicBool = AtomicBool::new(false);

/// Whether the caller is the first to report (the run or its backstop): only one of
/// them prints and writes `--result`.
fn take_report() -> bool {
    !REPORTED.swap(true, Ordering::SeqCst)
}

/// The backstop of `verify-vnnlib --timeout`: a thread that sleeps until
/// [`BACKSTOP_GRACE`] after `deadline` and then, unless the run has reported, reports
/// `unknown (timeout)` (stdout, `--json`, `--result` as the run would) and ends the
/// process with exit 1, without waiting for the step the run is in or for its memory to
/// be freed. `unknown` is never wrong, so ending the search this way is sound.
fn start_backstop(deadline: Instant, start: Instant, json: bool, result: Option<PathBuf>) {
    let at = deadline + BACKSTOP_GRACE;
    let spawned = std::thread::Builder::new()
        .name("timeout-backstop".into())
        .spawn(move || {
            loop {
                let now = Instant::now();
                if now >= at {
                    break;
                }
                std::thread::sleep(at - now);
            }
            if !take_report() {
                return;
            }
            let d = ended_at_limit(start.elapsed().as_secs_f64(), "the run");
            let code = match report_vnnlib(&d, json, result.as_deref()) {
                Ok(_) => 1,
                Err(e) => {
                    eprintln!("error: {}", samara_app::error_text(&e));
                    2
                }
            };
            use std::io::Write;
            let _ = std::io::stdout().flush();
            std::process::exit(code);
        });
    if let Err(e) = spawned {
        // Without the thread the limit rests on the run's own clock checks.
        eprintln!("warning: no time-limit backstop thread: {e}");
    }
}

/// The verdict of a run (`what`) that had not stopped [`BACKSTOP_GRACE`] after its time
/// limit and was ended there, after `seconds`: `unknown (timeout)`, no engine having
/// answered (the engine named is the router's first). The backstop of `verify-vnnlib` and
/// the per-instance limit of `samara vnncomp` report it.
pub(crate) fn ended_at_limit(seconds: f64, what: &str) -> Decided {
    Decided::timed_out(
        seconds,
        format!(
            "{what} had not stopped {} s after the time limit: ended there",
            BACKSTOP_GRACE.as_secs_f64()
        ),
    )
}

/// Print a `verify-vnnlib` verdict (text or `--json`), its note and reason on stderr,
/// and write `--result`; the exit code (0 for `unsat`, 1 otherwise).
fn report_vnnlib(d: &Decided, json: bool, result: Option<&Path>) -> Result<ExitCode> {
    if let Some(n) = &d.note {
        eprintln!("note: {n}");
    }
    if let Some(r) = result {
        samara_report::write_atomic(r, result_text(d).as_bytes())
            .map_err(|e| anyhow!("--result {}: {e}", r.display()))?;
    }
    let doc = InstanceVerdict::of(d);
    if json {
        println!("{}", serde_json::to_value(&doc)?);
    } else {
        match &d.verdict {
            Verdict::Violated(_) => print!("{}", result_text(d)),
            _ => println!("{}", doc.result),
        }
        if let Verdict::Unknown(r) = &d.verdict {
            eprintln!("unknown ({}): {r}", r.kind());
        }
    }
    let tag = doc.result;
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
    let done = samara_app::export::export_vnnlib(&l, a)?;
    if done.written == 0 {
        for m in &done.skipped {
            eprintln!("skipped {m}");
        }
        bail!("no property could be written as VNN-LIB (see the messages above)");
    }
    for line in done.lines(&a.out) {
        eprintln!("{line}");
    }
    Ok(if done.skipped.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
