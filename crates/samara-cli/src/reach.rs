//! `samara reach`: sound reachable sets of the network-controlled glider (issue 6).
//!
//! Parses the flags into `samara_reach::ReachSettings`, checks everything (including
//! the network against the settings) before writing anything, runs
//! `samara_reach::reach`, then writes `DIR/reach.json`, `DIR/reach.png` and
//! `DIR/reach.svg` and prints the verdict.
//!
//! With `--shard I/N` it computes only part I of N of the run (`samara_reach::parts`: a
//! contiguous range of the initial pieces, each refined on its own) and writes it to the
//! shard file `--out`; `samara merge reach` replays the run's refinement over the N parts
//! and writes what one process writes (see [`merge_reach`]).

use anyhow::{anyhow, bail, Context, Result};
pub use samara_app::reach::args::ReachArgs;
use samara_app::reach::args::{builtin_system, spec_controller, spec_settings, x_plus_y};
use samara_app::reach::{
    merge_zonotope, Outcome, ReachReport, ReachSummary, SettingsEcho, ShardLine, ShardSource,
    ZonotopeRun, ZonotopeShard,
};
use samara_reach::parts;
use samara_reach::ReachSettings;
use samara_report::write_atomic;
use samara_spec::lower::NetDecl;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use crate::json_text;
use crate::shard::{self, Shard};

/// Start the global worker pool with `--threads` workers (all cores without it).
pub(crate) fn start_threads(a: &ReachArgs) -> Result<()> {
    crate::threads::start(a.threads)
}

/// Validated inputs of a run.
struct Plan {
    settings: ReachSettings,
    net: samara_nn::Network,
}

/// The files a run (and `samara merge reach`) writes into `--out`.
pub(crate) const WRITES: [&str; 3] = ["reach.json", "reach.png", "reach.svg"];

/// `as_file`: --out is a shard file (--shard), not the output folder.
fn plan(a: &ReachArgs, as_file: bool) -> Result<Plan> {
    let (settings, decl) = match &a.spec {
        Some(p) => {
            let (s, d) = spec_settings(p, a.loop_name.as_deref())?;
            (s, Some(d))
        }
        None => (a.builtin_settings()?, None),
    };
    // Never write over the network file (an input), before anything is computed.
    let inputs = [("--network", a.network.as_path())];
    if as_file {
        samara_report::guard::check_output_file("--out", &a.out, &inputs)?;
    } else {
        samara_report::guard::check_output_dir("--out", &a.out, &WRITES, &inputs)?;
    }
    // The flags are checked; now the network, then the library's own check of the
    // settings against it.
    let net = controller(&a.network, decl.as_ref())?;
    settings.validate(&net).map_err(|e| match e {
        samara_reach::ReachError::NetworkShape { .. } => {
            anyhow!("--network {}: {e}", a.network.display())
        }
        samara_reach::ReachError::Horizon { .. } => anyhow!("--horizon/--period: {e}"),
        samara_reach::ReachError::BadInterval { .. } => anyhow!("--y0/--init: {e}"),
        _ => anyhow!("{e}"),
    })?;
    Ok(Plan { settings, net })
}

/// A network in the wrong units (`ReachSettings::units_warning`: its outputs at the
/// initial set's corners far outside the actuator range), as a warning naming the flag.
fn units_warnings(a: &ReachArgs, plan: &Plan) -> Vec<String> {
    plan.settings
        .units_warning(&plan.net)
        .map(|w| format!("--network {}: {w}", a.network.display()))
        .into_iter()
        .collect()
}

/// The controller a run flies: the `--network` file, with the normalisation of `--spec`'s
/// network declaration composed (`decl`).
fn controller(network: &Path, decl: Option<&NetDecl>) -> Result<samara_nn::Network> {
    if !network.exists() {
        bail!(
            "--network {}: no such file; give the path of an .onnx controller with 6 raw inputs and 1 output (e.g. base_model_denorm.onnx)",
            network.display()
        );
    }
    let net = crate::simulate::glider_network(network).with_context(|| {
        format!(
            "--network {}: cannot load the network; give an ONNX file samara can read",
            network.display()
        )
    })?;
    match decl {
        Some(d) => Ok(spec_controller(net, d, network)?),
        None => Ok(net),
    }
}

/// Run `samara reach`.
pub fn run(a: &ReachArgs) -> Result<ExitCode> {
    // Taylor-model runs shard by their --grid (crate::reach_system); zonotope runs by
    // their initial pieces.
    let taylor = a.taylor();
    if let Some(sh) = a.shard.filter(|_| !taylor) {
        return run_shard(a, sh);
    }
    if !a.grid.is_empty() && !taylor {
        bail!("--grid applies to Taylor-model sets (--sets taylor or --system); the zonotope sets are cut by --max-leaves (and sharded by their initial pieces)");
    }
    if let Some(sys) = &a.system {
        return crate::reach_system::run(a, sys);
    }
    if a.target_ratio.is_some() {
        return run_taylor(a);
    }
    match a.sets.as_str() {
        "zonotope" => {
            a.check_zonotope_flags()?;
            Ok(run_zonotope(a, false)?.0)
        }
        "taylor" => run_taylor(a),
        "auto" => {
            // The Taylor-model flags are checked now, not after the zonotope run.
            a.taylor_settings()?;
            // On to Taylor-model sets when the zonotopes leave the goal unknown, or lose
            // the enclosure with no goal (no result over the horizon either way).
            let (code, unknown) = run_zonotope(a, true)?;
            if !unknown {
                return Ok(code);
            }
            let mut t = a.clone();
            t.sets = "taylor".into();
            t.out = a.out.join("taylor");
            // The zonotope run started the thread pool already.
            t.threads = None;
            eprintln!(
                "--sets auto: the zonotope sets left the goal unknown or lost the enclosure (reach.json in {}); now Taylor-model sets, written to {}",
                a.out.display(),
                t.out.display()
            );
            run_taylor(&t)
        }
        other => bail!("--sets {other}: give zonotope, taylor or auto"),
    }
}

/// The built-in glider setting on Taylor-model sets: the shipped system file of the
/// model with the flags' initial set, period, horizon, clip and goal, and the glider's
/// tuning for the flags left out ([`ReachArgs::glider_tuned`]).
fn run_taylor(a: &ReachArgs) -> Result<ExitCode> {
    let a = &a.glider_tuned();
    let plan = plan(a, a.shard.is_some())?;
    for w in units_warnings(a, &plan) {
        eprintln!("warning: {w}");
    }
    let sys = builtin_system(&plan.settings)?;
    let xy = x_plus_y(&sys);
    crate::reach_system::run_system(a, &sys, Path::new("built-in setting"), &plan.net, vec![xy])
}

/// The built-in glider setting on zonotope sets; also whether the run has no result
/// (the verdict is `unknown`, or there is no goal and a sub-box lost its enclosure). With
/// `quiet_unknown` such a run is reported on stderr only (files written), leaving stdout
/// to the run that follows (`--sets auto`).
fn run_zonotope(a: &ReachArgs, quiet_unknown: bool) -> Result<(ExitCode, bool)> {
    let plan = plan(a, false)?;
    let warnings = units_warnings(a, &plan);
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    start_threads(a)?;
    // Output directory: create and probe before the (possibly long) analysis; a failed
    // run removes the folders it created.
    let out = samara_report::guard::OutDir::prepare(&a.out)?;

    let spinner = progress(&plan.settings);
    let res = samara_reach::reach(&plan.net, &plan.settings);
    if let Some(p) = spinner {
        p.finish_and_clear();
    }
    let res = res.map_err(|e| anyhow!("{e}"))?;

    let o = Outcome::of(&res, &plan.settings, warnings);
    let settings = SettingsEcho::new(
        &a.network.display().to_string(),
        a.threads.unwrap_or_else(rayon::current_num_threads),
        &plan.settings,
    );
    let report = ReachReport::new(settings, &plan.settings, &o, res.leaves.clone());
    write_atomic(
        &a.out.join("reach.json"),
        json_text(&report, true)?.as_bytes(),
    )?;
    samara_report::reach::figure(
        &figure_title(&a.network, &plan.settings),
        res.verdict.name(),
        &samara_app::reach::figure_sets(&res.leaves),
        &samara_app::reach::figure_samples(&res.samples),
        plan.settings.goal.as_ref().map(|g| g.ystar),
    )
    .render(&a.out.join("reach.png"), &a.out.join("reach.svg"))?;
    let unknown = o.no_result();
    if unknown && quiet_unknown {
        eprintln!("{}", o.human_line(&plan.settings));
        out.keep();
        return Ok((ExitCode::from(1), true));
    }
    Ok((finish(&o, &plan.settings, &a.out, a.json, out)?, unknown))
}

/// Print the verdict (or the JSON summary), keep the output folder, and the exit code.
fn finish(
    o: &Outcome,
    s: &ReachSettings,
    dir: &Path,
    json_out: bool,
    out: samara_report::guard::OutDir,
) -> Result<ExitCode> {
    if json_out {
        println!("{}", json_text(&ReachSummary::new(o, dir), true)?);
    } else {
        println!("{}", o.human_line(s));
        eprintln!("wrote {}", dir.display());
    }
    out.keep();
    Ok(if o.success() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// A spinner on stderr (only drawn when stderr is a terminal).
fn progress(s: &ReachSettings) -> Option<indicatif::ProgressBar> {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return None;
    }
    let p = indicatif::ProgressBar::new_spinner();
    p.set_message(format!(
        "reachable sets of the {} model over [0, {}] ...",
        s.model.name(),
        s.horizon
    ));
    p.enable_steady_tick(std::time::Duration::from_millis(120));
    Some(p)
}

/// The figure's title: the network's name and the model.
fn figure_title(network: &Path, s: &ReachSettings) -> String {
    let name = network
        .file_stem()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "network".into());
    format!("{name}, {} model", s.model.name())
}

/// `samara reach --shard I/N --out FILE`: part I of N of the run (the initial pieces
/// `Shard::range` of their number, each refined on its own) as a shard file.
fn run_shard(a: &ReachArgs, sh: Shard) -> Result<ExitCode> {
    match a.sets.as_str() {
        "zonotope" => a.check_zonotope_flags()?,
        "auto" => bail!("--shard with --sets auto: the two kinds of set are sharded differently; shard the zonotope run (--sets zonotope) or the Taylor-model run (--sets taylor with --grid)"),
        other => bail!("--sets {other}: give zonotope, taylor or auto"),
    }
    let plan = plan(a, true)?;
    let s = &plan.settings;
    let warnings = units_warnings(a, &plan);
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    start_threads(a)?;
    let t0 = Instant::now();
    let spinner = progress(s);
    let done = parts::prepare(&plan.net, s).map(|prep| {
        let range = sh.range(prep.pieces());
        let flown = prep.fly(range.clone());
        (prep, range, flown)
    });
    if let Some(p) = spinner {
        p.finish_and_clear();
    }
    let (prep, range, flown) = done.map_err(|e| anyhow!("{e}"))?;
    let secs = t0.elapsed().as_secs_f64();
    let mut inputs = vec![(
        "--network".to_string(),
        a.network.as_path(),
        "--network".to_string(),
    )];
    if let Some(p) = &a.spec {
        inputs.push(("--spec".to_string(), p.as_path(), "--spec".to_string()));
    }
    let run = ZonotopeRun::new(s, shard::digest_inputs(inputs)?, prep.pieces());
    let src = ShardSource {
        network: a.network.display().to_string(),
        network_file: shard::resolved(&a.network),
        spec_file: a.spec.as_deref().map(shard::resolved),
        loop_name: a.loop_name.clone(),
        warnings,
        threads: a.threads.unwrap_or_else(rayon::current_num_threads),
    };
    let result = ZonotopeShard::new(sh, &prep, range.clone(), &flown, secs, src);
    shard::write(&a.out, "reach", sh, &run, &result)?;
    if a.json {
        let line = ShardLine {
            shard: (sh.i, sh.n),
            pieces: (range.start, range.end),
            subboxes: flown.len(),
            out: a.out.clone(),
        };
        println!("{}", json_text(&line, false)?);
    } else {
        println!(
            "shard {}/{}: pieces {}..{} of {} ({} sub-boxes flown), {secs:.3} s; partial result in {} (merge with `samara merge reach`)",
            sh.i,
            sh.n,
            range.start,
            range.end,
            prep.pieces(),
            flown.len(),
            a.out.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// `samara merge reach` of zonotope shards (`samara_app::reach::merge_zonotope`), then
/// `DIR/reach.json` and the figures as one process writes them. The counterexample is
/// re-checked under the controller read back from where shard 0 found it (with its
/// --spec).
pub fn merge_reach(
    shards: &samara_app::shard::Shards,
    out: &Path,
    json_out: bool,
) -> Result<ExitCode> {
    let run: ZonotopeRun = shards.run_as()?;
    let results = shards.results_as::<ZonotopeShard>()?;
    let merged = merge_zonotope(&run, &results, |r| {
        r.run(&run, |network, spec, loop_name| {
            let decl = match spec {
                Some(p) => Some(spec_settings(p, loop_name)?.1),
                None => None,
            };
            controller(network, decl.as_ref()).map_err(app_input)
        })
    })?;
    for w in &merged.outcome.warnings {
        eprintln!("warning: {w}");
    }
    let s = &merged.settings;
    let dir = samara_report::guard::OutDir::prepare(out)?;
    write_atomic(
        &out.join("reach.json"),
        json_text(&merged.report(), true)?.as_bytes(),
    )?;
    samara_report::reach::draw(
        &figure_title(Path::new(&merged.network), s),
        merged.outcome.verdict.name(),
        &samara_app::reach::figure_sets(&merged.leaves),
        merged.curves.clone(),
        merged.group_label.clone(),
        s.goal.as_ref().map(|g| g.ystar),
    )
    .render(&out.join("reach.png"), &out.join("reach.svg"))?;
    finish(&merged.outcome, s, out, json_out, dir)
}

/// A CLI error as the library's input error (its message, causes included).
fn app_input(e: anyhow::Error) -> samara_app::AppError {
    samara_app::AppError::Input(crate::error_chain(&e))
}
