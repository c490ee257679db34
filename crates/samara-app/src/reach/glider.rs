//! `samara reach` on the built-in glider with zonotope sets: the run's plan (settings
//! and controller, checked before anything is written), the files of a run
//! (`reach.json` and the figure), and a shard's file.

use crate::reach::args::{spec_controller, spec_settings, ReachArgs};
use crate::reach::{
    figure_samples, figure_sets, Outcome, ReachReport, SettingsEcho, ShardLine, ShardSource,
    ZonotopeRun, ZonotopeShard,
};
use crate::shard::Shard;
use anyhow::{anyhow, bail, Context, Result};
use samara_reach::parts::{Flown, Prepared};
use samara_reach::{ReachResult, ReachSettings};
use samara_spec::lower::NetDecl;
use std::path::Path;

/// The files a run (and `samara merge reach`) writes into `--out`.
pub const WRITES: [&str; 3] = ["reach.json", "reach.png", "reach.svg"];

/// A glider controller file (`samara_nn::load`: ONNX or `.nnet`); a 6-input, 1-output
/// network gets the case study's state names (v_xp, v_yp, omega, theta, x, y) and `ex`.
pub fn glider_network(path: &Path) -> Result<samara_nn::Network> {
    let net = samara_nn::load(path)?;
    if net.n_inputs() == 6 && net.n_outputs() == 1 {
        return Ok(net.with_names(&samara_nn::STATE_INPUTS, &["ex"])?);
    }
    Ok(net)
}

/// The controller a run flies: the `--network` file, with the normalisation of `--spec`'s
/// network declaration composed (`decl`).
pub fn controller(network: &Path, decl: Option<&NetDecl>) -> Result<samara_nn::Network> {
    if !network.exists() {
        bail!(
            "--network {}: no such file; give the path of an .onnx controller with 6 raw inputs and 1 output (e.g. base_model_denorm.onnx)",
            network.display()
        );
    }
    let net = glider_network(network).with_context(|| {
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

/// The checked inputs of a glider run.
#[derive(Clone, Debug)]
pub struct ReachPlan {
    /// The run's settings.
    pub settings: ReachSettings,
    /// The controller.
    pub net: samara_nn::Network,
}

impl ReachArgs {
    /// The settings (`--spec`'s loop or the flags') and the controller, checked against
    /// each other, after the output is checked never to overwrite the network file
    /// (`as_file`: `--out` is a shard file, else the output folder).
    pub fn plan(&self, as_file: bool) -> Result<ReachPlan> {
        let a = self;
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
        Ok(ReachPlan { settings, net })
    }

    /// A network in the wrong units (`ReachSettings::units_warning`: its outputs at the
    /// initial set's corners far outside the actuator range), as a warning naming the
    /// flag.
    pub fn units_warnings(&self, plan: &ReachPlan) -> Vec<String> {
        plan.settings
            .units_warning(&plan.net)
            .map(|w| format!("--network {}: {w}", self.network.display()))
            .into_iter()
            .collect()
    }
}

/// The figure's title: the network's name and the model.
pub fn figure_title(network: &Path, s: &ReachSettings) -> String {
    let name = network
        .file_stem()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "network".into());
    format!("{name}, {} model", s.model.name())
}

/// Write a finished glider run's `reach.json` and figure into `--out`; its outcome.
/// `threads`: the worker threads it ran on.
pub fn write_run(
    a: &ReachArgs,
    plan: &ReachPlan,
    res: &ReachResult,
    warnings: Vec<String>,
    threads: usize,
) -> Result<Outcome> {
    let o = Outcome::of(res, &plan.settings, warnings);
    let settings = SettingsEcho::new(&a.network.display().to_string(), threads, &plan.settings);
    let report = ReachReport::new(settings, &plan.settings, &o, res.leaves.clone());
    samara_report::write_atomic(
        &a.out.join("reach.json"),
        crate::json_pretty(&report)?.as_bytes(),
    )?;
    samara_report::reach::figure(
        &figure_title(&a.network, &plan.settings),
        res.verdict.name(),
        &figure_sets(&res.leaves),
        &figure_samples(&res.samples),
        plan.settings.goal.as_ref().map(|g| g.ystar),
    )
    .render(&a.out.join("reach.png"), &a.out.join("reach.svg"))?;
    Ok(o)
}

/// Write shard `sh` of a glider run: the initial pieces `range` of `prep`, flown
/// (`flown`) in `secs` on `threads` workers; its `--json` line and human line.
#[allow(clippy::too_many_arguments)]
pub fn write_shard(
    a: &ReachArgs,
    sh: Shard,
    settings: &ReachSettings,
    prep: &Prepared,
    range: std::ops::Range<usize>,
    flown: &[Flown],
    secs: f64,
    warnings: Vec<String>,
    threads: usize,
) -> Result<(ShardLine, String)> {
    let mut inputs = vec![(
        "--network".to_string(),
        a.network.as_path(),
        "--network".to_string(),
    )];
    if let Some(p) = &a.spec {
        inputs.push(("--spec".to_string(), p.as_path(), "--spec".to_string()));
    }
    let run = ZonotopeRun::new(
        settings,
        crate::shard::digest_inputs(inputs)?,
        prep.pieces(),
    );
    let src = ShardSource {
        network: a.network.display().to_string(),
        network_file: crate::shard::resolved(&a.network),
        spec_file: a.spec.as_deref().map(crate::shard::resolved),
        loop_name: a.loop_name.clone(),
        warnings,
        threads,
    };
    let result = ZonotopeShard::new(sh, prep, range.clone(), flown, secs, src);
    crate::shard::write(&a.out, "reach", sh, &run, &result)?;
    let line = ShardLine {
        shard: (sh.i, sh.n),
        pieces: (range.start, range.end),
        subboxes: flown.len(),
        out: a.out.clone(),
    };
    let human = format!(
        "shard {}/{}: pieces {}..{} of {} ({} sub-boxes flown), {secs:.3} s; partial result in {} (merge with `samara merge reach`)",
        sh.i,
        sh.n,
        range.start,
        range.end,
        prep.pieces(),
        flown.len(),
        a.out.display()
    );
    Ok((line, human))
}

/// `samara merge reach` of zonotope shards ([`crate::reach::merge_zonotope`], the
/// counterexample re-checked under the controller read back from where shard 0 found
/// it, with its `--spec`).
pub fn merge(shards: &crate::shard::Shards) -> Result<crate::reach::Merged> {
    let run: ZonotopeRun = shards.run_as()?;
    let results = shards.results_as::<ZonotopeShard>()?;
    let merged = crate::reach::merge_zonotope(&run, &results, |r| {
        r.run(&run, |network, spec, loop_name| {
            let decl = match spec {
                Some(p) => Some(spec_settings(p, loop_name)?.1),
                None => None,
            };
            controller(network, decl.as_ref())
                .map_err(|e| crate::AppError::Input(crate::error_text(&e)))
        })
    })?;
    Ok(merged)
}

/// Write a merged run into `out` as one process writes it: `reach.json` and the figure.
pub fn write_merged(merged: &crate::reach::Merged, out: &Path) -> Result<()> {
    let s = &merged.settings;
    samara_report::write_atomic(
        &out.join("reach.json"),
        crate::json_pretty(&merged.report())?.as_bytes(),
    )?;
    samara_report::reach::draw(
        &figure_title(Path::new(&merged.network), s),
        merged.outcome.verdict.name(),
        &figure_sets(&merged.leaves),
        merged.curves.clone(),
        merged.group_label.clone(),
        s.goal.as_ref().map(|g| g.ystar),
    )
    .render(&out.join("reach.png"), &out.join("reach.svg"))?;
    Ok(())
}
