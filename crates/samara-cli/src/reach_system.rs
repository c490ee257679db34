//! `samara reach --system FILE --network NET`: sound reachable sets of any closed loop
//! written as a system file (docs/system.md), with Taylor-model sets
//! (`samara_reach::system`). Writes `DIR/reach.json` (settings, verdict, the hull of the
//! state at each control instant and over each period, the sub-boxes) and prints one
//! line, or the JSON summary with `--json`.

use crate::json_text;
use crate::reach::ReachArgs;
use crate::verify::shard::{self, Shard};
use anyhow::{anyhow, bail, Context, Result};
use samara_app::reach::system::{
    human_line, merge_taylor, percent, success, SystemReport, SystemSettingsEcho, SystemSummary,
    TaylorRun, TaylorShard, TaylorShardLine,
};
use samara_app::shard::Shards;
use samara_reach::grid;
use samara_reach::system::{reach_system, Measure, NetworkError, SystemReachSettings};
use samara_report::write_atomic;
use std::path::Path;
use std::process::ExitCode;

/// Files `reach --system` writes.
const WRITES: [&str; 1] = ["reach.json"];

/// Flags of the built-in glider setting that do not apply to a system file (which
/// states its own initial set, period, horizon, clip and goals).
fn refuse_builtin_flags(a: &ReachArgs) -> Result<()> {
    let given: Vec<&str> = [
        (a.y0.is_some(), "--y0"),
        (!a.init.is_empty(), "--init"),
        (a.goal_ystar.is_some(), "--goal-ystar"),
        (a.goal_from.is_some(), "--goal-from"),
        (a.no_clip, "--no-clip"),
        (a.model != "reduced", "--model"),
    ]
    .iter()
    .filter(|(on, _)| *on)
    .map(|(_, n)| *n)
    .collect();
    if !given.is_empty() {
        bail!(
            "{} do(es) not apply with --system: the system file states its model, initial set (`init`), goals (`goal`), clip and period; edit the file",
            given.join(", ")
        );
    }
    Ok(())
}

/// Run `samara reach --system`.
pub fn run(a: &ReachArgs, path: &Path) -> Result<ExitCode> {
    refuse_builtin_flags(a)?;
    if a.sets != "zonotope" {
        bail!("--sets does not apply with --system: system files always use Taylor-model sets");
    }
    let sys = samara_system::System::from_file(path).map_err(|e| anyhow!("{e}"))?;
    let net = samara_nn::load(&a.network)
        .with_context(|| format!("--network {}", a.network.display()))?;
    let measures = samara_reach::system::end_band_measures(&sys);
    run_system(a, &sys, path, &net, measures)
}

/// Reachability of a checked system under a loaded controller; `path` names the
/// system in messages and the report. With --grid the cells are flown as separate runs
/// (`samara_reach::grid`); with --shard only this shard's range of them, written as a
/// shard file for `samara merge reach`.
pub fn run_system(
    a: &ReachArgs,
    sys: &samara_system::System,
    path: &Path,
    net: &samara_nn::Network,
    measures: Vec<Measure>,
) -> Result<ExitCode> {
    crate::simulate::check_fits("--network", &a.network, net, sys, path)?;
    let mut s = taylor_settings(a)?;
    s.measures = measures;
    crate::reach::check_budget(a, s.max_boxes)?;
    if let Some(n) = a.max_leaves {
        s.max_boxes = n;
    }
    if let Some(n) = a.samples {
        s.samples = n;
    }
    let pieces = grid_pieces(a, sys)?;
    if let Some(r) = a.target_ratio {
        return crate::reach_adaptive::run(a, r, sys, path, net, s, pieces);
    }
    let inputs = if path.is_file() {
        vec![("--system", path), ("--network", a.network.as_path())]
    } else {
        vec![("--network", a.network.as_path())]
    };
    if let Some(sh) = a.shard {
        let Some(pieces) = pieces else {
            bail!("--shard with Taylor-model sets needs --grid NAME=K (the grid's cells are what the shards divide), e.g. --grid theta=3 --grid y=8");
        };
        return run_shard(a, sh, sys, path, net, &s, &pieces, &inputs);
    }
    crate::reach::start_threads(a)?;
    samara_report::guard::check_output_dir("--out", &a.out, &WRITES, &inputs)?;
    let out = samara_report::guard::OutDir::prepare(&a.out)?;
    let res = match &pieces {
        None => reach_system(sys, net, &s),
        Some(p) => {
            let total = grid::cell_count(sys, p).map_err(|e| anyhow!("--grid: {e}"))?;
            grid::reach_cells(sys, net, &s, p, 0..total)
        }
    }
    .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let report = SystemReport {
        system: path.display().to_string(),
        network: a.network.display().to_string(),
        settings: SystemSettingsEcho::new(&s, pieces.as_deref()),
        result: res,
    };
    let code = write_report(&a.out, a.json, &report)?;
    out.keep();
    Ok(code)
}

/// Write `out/reach.json` and print the human line (or the JSON summary); the exit code
/// of the verdict. Shared by runs and `samara merge reach` of Taylor-model shards.
fn write_report(out: &Path, json: bool, report: &SystemReport) -> Result<ExitCode> {
    write_atomic(&out.join("reach.json"), json_text(report, true)?.as_bytes())?;
    let res = &report.result;
    if json {
        println!("{}", json_text(&SystemSummary::new(res), true)?);
    } else {
        println!("{}", human_line(&report.system, res));
        eprintln!("wrote {}", out.display());
    }
    Ok(if success(res) {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// `--grid NAME=K ...` as pieces per state (`None` without the flag), checked against
/// the system's states and initial set.
fn grid_pieces(a: &ReachArgs, sys: &samara_system::System) -> Result<Option<Vec<usize>>> {
    if a.grid.is_empty() {
        return Ok(None);
    }
    let mut pieces = vec![1usize; sys.dim()];
    let mut seen = vec![false; sys.dim()];
    for g in &a.grid {
        let (name, k) = g.split_once('=').ok_or_else(|| {
            anyhow!("--grid {g:?}: expected NAME=K, a state and its number of pieces (e.g. --grid theta=3)")
        })?;
        let i = sys
            .states
            .iter()
            .position(|n| n == name.trim())
            .ok_or_else(|| {
                anyhow!(
                    "--grid {g:?}: no state `{}`; the states are {}",
                    name.trim(),
                    sys.states.join(", ")
                )
            })?;
        let k: usize = k.trim().parse().ok().filter(|k| *k >= 1).ok_or_else(|| {
            anyhow!("--grid {g:?}: K must be a whole number of pieces, at least 1")
        })?;
        if seen[i] {
            bail!(
                "--grid {g:?}: state `{}` is cut twice; give each state once",
                sys.states[i]
            );
        }
        seen[i] = true;
        pieces[i] = k;
    }
    grid::cell_count(sys, &pieces).map_err(|e| anyhow!("--grid: {e}"))?;
    Ok(Some(pieces))
}

/// `--shard I/N` of a Taylor-model grid run: cells `Shard::range` of the grid's, written
/// as a shard file.
#[allow(clippy::too_many_arguments)]
fn run_shard(
    a: &ReachArgs,
    sh: Shard,
    sys: &samara_system::System,
    path: &Path,
    net: &samara_nn::Network,
    s: &SystemReachSettings,
    pieces: &[usize],
    inputs: &[(&str, &Path)],
) -> Result<ExitCode> {
    samara_report::guard::check_output_file("--out", &a.out, inputs)?;
    let total = grid::cell_count(sys, pieces).map_err(|e| anyhow!("--grid: {e}"))?;
    let range = sh.range(total);
    if range.is_empty() {
        bail!(
            "--shard {}/{}: the grid has {total} cells, fewer than the {} shards; use at most {total} shards or a finer --grid",
            sh.i,
            sh.n,
            sh.n
        );
    }
    let network = shard::digest_inputs([(
        "--network".to_string(),
        a.network.as_path(),
        "--network".to_string(),
    )])?;
    let run = TaylorRun::new(sys, network["--network"].clone(), s, pieces, total);
    crate::reach::start_threads(a)?;
    let res = grid::reach_cells(sys, net, s, pieces, range.clone())
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let result = TaylorShard {
        cells: (range.start, range.end),
        system_name: path.display().to_string(),
        network_name: a.network.display().to_string(),
        reach: res,
    };
    shard::write(&a.out, "reach", sh, &run, &result)?;
    let res = &result.reach;
    if a.json {
        let line = TaylorShardLine {
            shard: (sh.i, sh.n),
            cells: (range.start, range.end),
            verdict: res.verdict.clone(),
            covered: res.covered,
            out: a.out.clone(),
        };
        println!("{}", json_text(&line, false)?);
    } else {
        println!(
            "shard {}/{}: cells {}..{} of {total}: {} ({} sub-boxes, {:.2} s, sets to the horizon for {} of these cells); partial result in {} (merge with `samara merge reach`)",
            sh.i,
            sh.n,
            range.start,
            range.end,
            res.verdict.name(),
            res.boxes,
            res.seconds,
            percent(res.covered),
            a.out.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// `samara merge reach` of Taylor-model grid shards
/// (`samara_app::reach::system::merge_taylor`), written as the one-process run writes
/// them.
pub fn merge_shards(shards: &Shards, out: &Path, json: bool) -> Result<ExitCode> {
    let run: TaylorRun = shards.run_as()?;
    let report = merge_taylor(&run, &shards.results_as::<TaylorShard>()?)?;
    let dir = samara_report::guard::OutDir::prepare(out)?;
    let code = write_report(out, json, &report)?;
    dir.keep();
    Ok(code)
}

/// `--network-error`: `interval`, `symbolic`, `symbolic:N` or `auto`.
fn parse_network_error(v: &str) -> Result<Option<NetworkError>> {
    NetworkError::parse(v).map_err(|e| anyhow!("--network-error {v:?}: {e}"))
}

/// The built-in glider setting (`--model`, `--y0`, `--init`, `--period`, `--horizon`,
/// clip, goal) as a system: the shipped `examples/archcomp/alsomitra_<model>.sys`
/// (embedded; bit-identical to the built-in right-hand sides, see docs/system.md) with
/// its period, horizon, actuation, initial set and goal lines replaced by the flags'.
pub fn builtin_system(s: &samara_reach::ReachSettings) -> Result<samara_system::System> {
    use samara_plant::Model;
    let (file, text) = match s.model {
        Model::Reduced => (
            "alsomitra_reduced.sys",
            include_str!("../../../examples/archcomp/alsomitra_reduced.sys"),
        ),
        Model::Plate6 => (
            "alsomitra_plate6.sys",
            include_str!("../../../examples/archcomp/alsomitra_plate6.sys"),
        ),
        Model::Full => (
            "alsomitra_full.sys",
            include_str!("../../../examples/archcomp/alsomitra_full.sys"),
        ),
    };
    let replaced = ["period", "horizon", "actuate", "init", "goal", "reset"];
    let mut src: String = text
        .lines()
        .filter(|l| {
            let w = l.split_whitespace().next().unwrap_or("");
            !replaced.contains(&w)
        })
        .map(|l| format!("{l}\n"))
        .collect();
    let names = ["v_xp", "v_yp", "omega", "theta", "x", "y", "E"];
    src.push_str(&format!("period {:?}\nhorizon {:?}\n", s.period, s.horizon));
    match s.clip {
        Some((lo, hi)) => src.push_str(&format!("actuate ex = net[0] clip [{lo:?}, {hi:?}]\n")),
        None => src.push_str("actuate ex = net[0]\n"),
    }
    if s.init.len() == 7 && s.reset_filter {
        src.push_str("reset E = 0\n");
    }
    for (n, (lo, hi)) in names.iter().zip(&s.init) {
        if lo == hi {
            src.push_str(&format!("init {n} = {lo:?}\n"));
        } else {
            src.push_str(&format!("init {n} in [{lo:?}, {hi:?}]\n"));
        }
    }
    if let Some(g) = &s.goal {
        match g.from {
            None => src.push_str(&format!("goal band |x + y| <= {:?} at end\n", g.ystar)),
            Some(f) => src.push_str(&format!(
                "goal band |x + y| <= {:?} always [{f:?}, {:?}]\n",
                g.ystar, s.horizon
            )),
        }
    }
    samara_system::System::parse(&src, &format!("{file} (built-in setting)"))
        .map_err(|e| anyhow!("the built-in setting as a system file: {e}"))
}

/// The Taylor-model settings the flags give (`--order`, `--timeout`, `--network-error`),
/// checked; `--sets auto` checks them before its zonotope run.
pub(crate) fn taylor_settings(a: &ReachArgs) -> Result<SystemReachSettings> {
    let mut s = SystemReachSettings::default();
    if let Some(k) = a.order {
        if !(1..=8).contains(&k) {
            bail!("--order {k}: give 1 to 8 (3-5 is usual; higher orders cost more per step)");
        }
        s.order = k;
    }
    if let Some(t) = a.timeout {
        if !(t.is_finite() && t > 0.0 && t <= 1e7) {
            bail!("--timeout {t}: give a number of seconds, positive and at most 1e7");
        }
        s.timeout = Some(t);
    }
    if let Some(v) = a.lift_at {
        if !(v.is_finite() && v > 0.0 && v <= 1.0) {
            bail!("--lift-at {v}: give a share of the width in (0, 1], such as 0.05 or 0.001");
        }
        s.flow.lift_at = v;
    }
    if let Some(v) = &a.network_error {
        s.network_error = parse_network_error(v)?;
        // Symbolic remainders go with order 3 unless --order says otherwise (as in
        // the automatic choice, samara_reach::system::NETWORK_ERROR_LADDER).
        if a.order.is_none() && matches!(s.network_error, Some(NetworkError::Symbolic { .. })) {
            s.order = 3;
        }
    }
    if let Some(v) = a.lifted_weight {
        if !(1..=s.order as i64).contains(&v) {
            bail!(
                "--lifted-weight {v}: give 1 to the order ({}): 1 weighs lifted parameters as initial ones, the order makes them linear",
                s.order
            );
        }
        s.flow.lifted_weight = v as u32;
    }
    Ok(s)
}
