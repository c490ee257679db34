//! `samara check | verify | critical | robustness | export-vnnlib | verify-vnnlib`, and
//! (in `vnncomp.rs`) `samara vnncomp`.

use crate::shard;
use anyhow::{anyhow, bail, Result};
pub use samara_app::args::{
    CheckArgs, CriticalArgs, ExportArgs, RobustnessArgs, SpecArgs, VerifyArgs, VerifyVnnlibArgs,
};
use samara_app::bind::{load_network, read_data, timeout_flag};
use samara_app::robustness::{
    merge_sweep, Form, PointText, SweepRun, SweepShard, SweepShardLine, Table,
};
use samara_app::shard::Exact;
use samara_app::verify::{PropertyRun, RowCounterexample, VerdictTag};
use samara_app::vnncomp::{decide, load_instance, result_text, InstanceVerdict};
use samara_app::{Holds, VerdictRow};
use samara_spec::vnnlib;
use samara_verify::robustness::sweep_until;
use samara_verify::{LpTighten, Settings, Verdict};
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

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
        if let Some(m) = l.missing_data(name) {
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
        lp_tighten: tighten_mode(a.search.lp_tighten),
        ..Default::default()
    };
    let json_out = a.search.json;
    let run = samara_app::run_verify(&l, a.property.as_deref(), &settings, start, true, |p| {
        if !json_out {
            print_property(p);
        }
        if !p.vacuous.is_empty() {
            eprintln!(
                    "warning: {}: {} instance(s) proved only vacuously ({}): no point of the input domain meets the premise there (or a data point outside the declared domain has its ball clipped away), so the network was never checked; `samara robustness` evaluates the whole ball of a data point",
                    p.name,
                    p.vacuous.len(),
                    p.vacuous.iter().take(5).cloned().collect::<Vec<_>>().join(", ")
                );
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

/// The human line of one property's verdicts.
fn print_property(p: &PropertyRun) {
    let (name, secs) = (&p.name, p.seconds);
    if let [last] = p.rows.as_slice() {
        let extra = match (&last.counterexample, &last.unknown_reason, &last.vacuity) {
            (Some(RowCounterexample::Point { point, .. }), _, _) => {
                format!(
                    " counterexample {}",
                    serde_json::to_string(point).unwrap_or_default()
                )
            }
            (_, Some(r), _) => format!(" ({}: {})", r.kind, r.message),
            (_, _, Some(why)) => format!(" VACUOUS: {why}"),
            _ => String::new(),
        };
        println!("{name:<16} {:<9} {secs:>8.3} s{extra}", last.verdict.text());
    } else {
        let kinds: Vec<String> = p
            .unknown_kinds
            .iter()
            .map(|(k, n)| format!("{k}: {n}"))
            .collect();
        println!(
            "{name:<16} {} instances: {} proved{}, {} violated, {} unknown{}  {secs:>8.3} s",
            p.rows.len(),
            p.count(VerdictTag::Proved),
            if p.vacuous.is_empty() {
                String::new()
            } else {
                format!(" ({} vacuously)", p.vacuous.len())
            },
            p.count(VerdictTag::Violated),
            p.count(VerdictTag::Unknown),
            if kinds.is_empty() {
                String::new()
            } else {
                format!(" ({})", kinds.join(", "))
            }
        );
    }
}

fn tighten_mode(on: bool) -> LpTighten {
    if on {
        LpTighten::Root
    } else {
        LpTighten::Off
    }
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
            lp_tighten: tighten_mode(a.search.lp_tighten),
            ..Default::default()
        },
    )?;
    if a.search.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::to_value(&v)?)?
        );
    } else {
        match (v.holds, v.critical) {
            (Holds::Unknown, _) => {
                let r = v.unknown_reason.clone().unwrap_or(samara_app::Reason {
                    kind: String::new(),
                    message: String::new(),
                });
                println!(
                    "{}: unknown ({}: {}); no claim about {of}",
                    a.property, r.kind, r.message
                )
            }
            (Holds::Everywhere, _) => {
                println!("{}: holds for every {} in its range", a.property, of)
            }
            (Holds::Nowhere, Some(c)) => println!(
                "{}: fails for every {of} in its declared range (counterexamples from {of} = {c:.3e} up){}",
                a.property,
                if v.vacuous {
                    "; VACUOUS: it holds only where the precondition is empty"
                } else {
                    ""
                }
            ),
            (h @ (Holds::Above | Holds::Below), Some(c)) => {
                let t = v.threshold.unwrap_or(c);
                println!(
                    "{}: holds for {} {} {:.9}{}{}  ({:.3} s)",
                    a.property,
                    of,
                    if h == Holds::Above { ">" } else { "<" },
                    t,
                    if v.attained {
                        String::new()
                    } else {
                        format!(" (sound bound; the critical value lies between {c:.9} and it, not attained)")
                    },
                    if v.vacuous { "  VACUOUS: the precondition is empty there" } else { "" },
                    v.seconds
                )
            }
            _ => println!("{}: {}", a.property, serde_json::to_value(&v)?),
        }
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
    let checked = a.validate()?;
    for n in &checked.notes {
        eprintln!("{n}");
    }
    let (eps, ls, reference) = (checked.eps, checked.lipschitz, checked.reference);
    let net = load_network(&a.network, "--network")?;
    let t = read_data(&a.data, "--data")?;
    let rows = a.data_rows(net.n_inputs(), &t, reference)?;
    let t0 = Instant::now();
    let settings = Settings {
        timeout,
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
        let run = SweepRun {
            inputs: shard::digest_inputs([
                (
                    "--network".to_string(),
                    a.network.as_path(),
                    "--network".to_string(),
                ),
                ("--data".to_string(), a.data.as_path(), "--data".to_string()),
            ])?,
            points: rows.len(),
            eps: eps.iter().map(|e| Exact(*e)).collect(),
            lipschitz: ls.iter().map(|l| Exact(*l)).collect(),
            reference: a.reference.clone(),
            form: a.form.clone(),
            timeout: Exact(a.timeout),
            max_nodes: a.max_nodes,
        };
        let result = SweepShard {
            rows: (range.start, range.end),
            seconds: secs,
            points: points.iter().map(PointText::from).collect(),
        };
        shard::write(out, "robustness", s, &run, &result)?;
        if a.json {
            let line = SweepShardLine {
                shard: (s.i, s.n),
                rows: (range.start, range.end),
                out: out.clone(),
            };
            println!("{}", crate::json_text(&line, false)?);
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

/// `samara merge robustness`: the shards' points in order
/// (`samara_app::robustness::merge_sweep`), then the one-process report.
pub(crate) fn merge_robustness(
    shards: &samara_app::shard::Shards,
    out: Option<&Path>,
    json_out: bool,
) -> Result<ExitCode> {
    let run: SweepRun = shards.run_as()?;
    let m = merge_sweep(&run, &shards.results_as::<SweepShard>()?)?;
    report_robustness(&Sweep {
        form: &m.form,
        eps: &m.eps,
        ls: &m.ls,
        n_rows: m.n_rows,
        secs: m.seconds,
        points: &m.points,
        out,
        json: json_out,
    })
}

/// The robustness table (stdout) and the per-point CSV (`out`).
fn report_robustness(w: &Sweep) -> Result<ExitCode> {
    let (eps, ls, points, secs) = (w.eps, w.ls, w.points, w.secs);
    let form = Form::parse(w.form).ok_or_else(|| {
        anyhow!(
            "form {:?}: not a robustness form (published or lipschitz)",
            w.form
        )
    })?;
    let t = Table::of(form, eps, ls, w.n_rows, secs, points);
    if let Some(p) = w.out {
        let csv = samara_app::robustness::points_csv(points);
        samara_report::write_atomic(p, csv.as_bytes())
            .map_err(|e| anyhow!("--out {}: {e}", p.display()))?;
    }
    if w.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::to_value(&t)?)?
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
        for (e, row) in eps.iter().zip(&t.table) {
            print!("{e:>10.0e}");
            for c in row {
                print!("{:>9.1}%", 100.0 * c.success_rate);
            }
            println!();
        }
        if t.any_unknown() {
            println!("(some points are unknown, neither proved nor violated: see --json)");
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Run `samara verify-vnnlib`: prints `unsat` (proved), `sat` (violated, with the
/// counterexample) or `unknown`, as VNN-COMP tools do. Box-shaped properties go to the
/// input-split engine, the rest to the ReLU-phase engine ([`samara_verify::route`]).
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
    let (net, q) = load_instance(&a.network, &a.property, "--network", "--property")?;
    // `--timeout` counts from the start: loading a wide network (a CIFAR convolution
    // lowered to dense maps) takes seconds of it.
    let d = decide(net, &q, timeout.left(start), a.max_nodes)?;
    if let Some(n) = &d.note {
        eprintln!("note: {n}");
    }
    if let Some(r) = &a.result {
        samara_report::write_atomic(r, result_text(&d).as_bytes())
            .map_err(|e| anyhow!("--result {}: {e}", r.display()))?;
    }
    let doc = InstanceVerdict::of(&d);
    if a.json {
        println!("{}", serde_json::to_value(&doc)?);
    } else {
        match &d.verdict {
            Verdict::Violated(_) => print!("{}", result_text(&d)),
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
    if let Some(p) = &a.property {
        if !l.spec.property_names().contains(&p.as_str()) {
            bail!(
                "--property {p}: the spec {} declares no property `{p}`; {}",
                a.s.spec.display(),
                samara_app::suggest(p, l.spec.property_names())
            );
        }
    }
    let names = l.selected(a.property.as_deref());
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
        if let Some(m) = l.missing_data(name) {
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
