//! Reachability of a system file on Taylor-model sets as typed documents (`samara reach
//! --system`, `--sets taylor`): `reach.json` ([`SystemReport`]), the `--json` summary
//! ([`SystemSummary`]), the human line, and the grid shards ([`TaylorRun`],
//! [`TaylorShard`]) with their merge ([`merge_taylor`]).

use crate::shard::{digest, pair, Exact, ExactPair, Shard};
use crate::AppError;
use samara_reach::grid;
use samara_reach::system::SystemViolation;
use samara_reach::system::{
    Measure, MeasureRange, NetworkError, SystemReach, SystemReachSettings, SystemVerdict,
};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

type Result<T> = std::result::Result<T, AppError>;

/// The settings `reach.json` records of a Taylor-model run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SystemSettingsEcho {
    /// Taylor-model order.
    pub order: usize,
    /// Sub-box budget.
    pub max_boxes: usize,
    /// Simulated flights.
    pub samples: usize,
    /// The `--grid` pieces per state, if the run was cut into a grid.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grid: Option<Vec<usize>>,
}

impl SystemSettingsEcho {
    /// The echo of `s` (`grid`: the `--grid` pieces per state).
    pub fn new(s: &SystemReachSettings, grid: Option<&[usize]>) -> Self {
        SystemSettingsEcho {
            order: s.order,
            max_boxes: s.max_boxes,
            samples: s.samples,
            grid: grid.map(<[usize]>::to_vec),
        }
    }
}

/// `reach.json` of a Taylor-model run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SystemReport {
    /// The system file (or `built-in setting`).
    pub system: String,
    /// `--network` as given.
    pub network: String,
    /// The settings.
    pub settings: SystemSettingsEcho,
    /// The result.
    pub result: SystemReach,
}

/// The `--json` summary of a Taylor-model run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SystemSummary {
    /// The system's name.
    pub system: String,
    /// The verdict.
    pub verdict: SystemVerdict,
    /// Sub-boxes of the final partition.
    pub boxes: usize,
    /// Share of the initial set with sets to the horizon.
    pub covered: f64,
    /// Taylor-model order used.
    pub order: usize,
    /// How the network's error entered the sets.
    pub network_error: NetworkError,
    /// Wall time.
    pub seconds: f64,
    /// The hull at the horizon, only when every sub-box has sets there (else the last
    /// row of `instants` is an earlier instant).
    #[serde(rename = "final")]
    pub final_hull: Option<Vec<[f64; 2]>>,
    /// Why a sub-box's sets stop before the horizon, if one's do.
    pub lost: Option<String>,
    /// The measures at the horizon.
    pub measures: Vec<MeasureRange>,
}

impl SystemSummary {
    /// The summary of `r`.
    pub fn new(r: &SystemReach) -> Self {
        SystemSummary {
            system: r.system.clone(),
            verdict: r.verdict.clone(),
            boxes: r.boxes,
            covered: r.covered,
            order: r.order,
            network_error: r.network_error,
            seconds: r.seconds,
            final_hull: if r.covered == 1.0 {
                r.instants.last().cloned()
            } else {
                None
            },
            lost: lost(r),
            measures: r.measures.clone(),
        }
    }
}

/// Why a sub-box's sets stop before the horizon (enclosure lost, time budget spent), if
/// one's do.
pub fn lost(r: &SystemReach) -> Option<String> {
    r.leaves.iter().find_map(|l| l.failure.clone())
}

/// Whether the run succeeded (the CLI's exit 0): proved, or no goal and sets to the
/// horizon.
pub fn success(r: &SystemReach) -> bool {
    match r.verdict {
        SystemVerdict::Proved => true,
        SystemVerdict::NoGoal => lost(r).is_none(),
        _ => false,
    }
}

/// The one-line result the CLI prints (`system`: the file's name).
pub fn human_line(system: &str, r: &SystemReach) -> String {
    let what = match &r.verdict {
        SystemVerdict::Proved => "proved: every goal holds on the sound enclosure".to_string(),
        SystemVerdict::Violated(SystemViolation { initial, goal }) => {
            format!("violated: the flight from {initial:?} misses `{goal}`")
        }
        SystemVerdict::Unknown { reason } => format!("unknown: {reason}"),
        SystemVerdict::NoGoal => match lost(r) {
            None => "no goal in the file; sets computed to the horizon".to_string(),
            Some(f) => format!(
                "no goal in the file; the sets stop before the horizon: {f} (reach.json has the instants reached)"
            ),
        },
    };
    let ne = match r.network_error {
        NetworkError::Interval => "interval".to_string(),
        NetworkError::Symbolic { extra } => format!("symbolic:{extra}"),
    };
    // A count of enclosed sub-boxes says little when they are the small ones: the
    // share of the initial set they cover does.
    let cover = if r.covered < 1.0
        && !matches!(r.verdict, SystemVerdict::Violated(SystemViolation { .. }))
    {
        format!(
            "; sets to the horizon for {} of the initial set",
            percent(r.covered)
        )
    } else {
        String::new()
    };
    let mut line = format!(
        "{system}: {what} ({} sub-boxes, Taylor models of order {}, network error {ne}, {:.2} s{cover})",
        r.boxes,
        r.order,
        r.seconds
    );
    for m in &r.measures {
        line.push_str(&measure_text(m));
    }
    line
}

/// `; NAME at the horizon in [a, b] (width w); flights [c, d] (width v); ratio q`.
fn measure_text(m: &MeasureRange) -> String {
    let range = |v: [f64; 2]| format!("[{:.6}, {:.6}] (width {:.6})", v[0], v[1], v[1] - v[0]);
    // The enclosure printed outward (6 decimals), so that the line never shows it
    // narrower than it is.
    let outward = |e: [f64; 2]| [(e[0] * 1e6).floor() / 1e6, (e[1] * 1e6).ceil() / 1e6];
    let sets = m.enclosure.map_or_else(
        || "not enclosed by every sub-box".to_string(),
        |e| format!("in {}", range(outward(e))),
    );
    let flights = m
        .sampled
        .map_or_else(String::new, |v| format!("; flights {}", range(v)));
    let ratio = m
        .ratio
        .map_or_else(String::new, |q| format!("; ratio {q:.3}"));
    format!("; {} at the horizon {sets}{flights}{ratio}", m.name)
}

/// A fraction as a percentage that never rounds a part to 0 % or 100 %.
pub fn percent(f: f64) -> String {
    let p = 100.0 * f;
    if p > 0.0 && p < 0.01 {
        format!("{p:.1e} %")
    } else if p > 99.99 && p < 100.0 {
        "99.99+ %".to_string()
    } else {
        format!("{p:.2} %")
    }
}

/// A measure in a [`TaylorRun`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeasureText {
    /// Its name.
    pub name: String,
    /// Coefficients per state.
    pub coef: Vec<Exact>,
    /// Offset.
    pub offset: Exact,
}

/// `run` of a Taylor-model grid shard: what every shard of one grid run shares (the
/// system's text digest and parameter values, the network's digest, the grid and the
/// settings that change results). The wall-clock budget is not part of it (each shard
/// has its own).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TaylorRun {
    /// Always `taylor` (what tells the merge the two kinds of reach shard apart).
    pub sets: String,
    /// Digest of the system's text.
    pub system: String,
    /// The system's parameter values.
    pub params: Vec<(String, Exact)>,
    /// Its initial box.
    pub init: Vec<ExactPair>,
    /// Digest of the network file.
    pub network: String,
    /// Pieces per state.
    pub grid: Vec<usize>,
    /// Cells of the grid.
    pub cells: usize,
    /// Taylor-model order.
    pub order: usize,
    /// Sub-box budget.
    pub max_boxes: usize,
    /// Simulated flights.
    pub samples: usize,
    /// Sampling seed.
    pub seed: u64,
    /// `--network-error` (`None`: chosen per run).
    pub network_error: Option<NetworkError>,
    /// `--lift-at`.
    pub lift_at: Exact,
    /// `--lifted-weight`.
    pub lifted_weight: u32,
    /// Whether sets are re-parameterised.
    pub precondition: bool,
    /// The measures.
    pub measures: Vec<MeasureText>,
}

impl TaylorRun {
    /// The record of a grid run of `sys` (`network_digest`: the network file's).
    pub fn new(
        sys: &samara_system::System,
        network_digest: String,
        s: &SystemReachSettings,
        pieces: &[usize],
        cells: usize,
    ) -> Self {
        TaylorRun {
            sets: "taylor".into(),
            system: digest(sys.source().as_bytes()),
            params: sys
                .params
                .iter()
                .map(|(n, v)| (n.clone(), Exact(*v)))
                .collect(),
            init: sys.init.iter().map(|(l, h)| pair([*l, *h])).collect(),
            network: network_digest,
            grid: pieces.to_vec(),
            cells,
            order: s.order,
            max_boxes: s.max_boxes,
            samples: s.samples,
            seed: s.seed,
            network_error: s.network_error,
            lift_at: Exact(s.flow.lift_at),
            lifted_weight: s.flow.lifted_weight,
            precondition: s.precondition,
            measures: s.measures.iter().map(measure_text_of).collect(),
        }
    }
}

fn measure_text_of(m: &Measure) -> MeasureText {
    MeasureText {
        name: m.name.clone(),
        coef: m.coef.iter().map(|c| Exact(*c)).collect(),
        offset: Exact(m.offset),
    }
}

/// `result` of a Taylor-model grid shard.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TaylorShard {
    /// The shard's range of cells.
    pub cells: (usize, usize),
    /// The system file as given.
    pub system_name: String,
    /// `--network` as given.
    pub network_name: String,
    /// The cells' merged result.
    pub reach: SystemReach,
}

/// The `--json` line of a Taylor-model grid shard.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TaylorShardLine {
    /// `[I, N]`.
    pub shard: (usize, usize),
    /// The shard's range of cells.
    pub cells: (usize, usize),
    /// Its verdict.
    pub verdict: SystemVerdict,
    /// Share of its cells with sets to the horizon.
    pub covered: f64,
    /// The shard file.
    pub out: PathBuf,
}

/// `samara merge reach` of Taylor-model grid shards: the shards' cells checked to be the
/// grid's ranges in order, their results merged (`samara_reach::grid::merge_parts`),
/// and `reach.json` as the one-process run writes it.
pub fn merge_taylor(run: &TaylorRun, shards: &[(PathBuf, TaylorShard)]) -> Result<SystemReport> {
    let total = run.cells;
    let n = shards.len();
    let mut parts = Vec::with_capacity(n);
    for (i, (file, r)) in shards.iter().enumerate() {
        let range = Shard { i, n }.range(total);
        if r.cells != (range.start, range.end) {
            return Err(AppError::Input(format!(
                "{}: cells [{},{}], expected {}..{} of {total} for shard {i}/{n}",
                file.display(),
                r.cells.0,
                r.cells.1,
                range.start,
                range.end
            )));
        }
        parts.push((range.len(), r.reach.clone()));
    }
    let r0 = &shards[0].1;
    Ok(SystemReport {
        system: r0.system_name.clone(),
        network: r0.network_name.clone(),
        settings: SystemSettingsEcho {
            order: run.order,
            max_boxes: run.max_boxes,
            samples: run.samples,
            grid: Some(run.grid.clone()),
        },
        result: grid::merge_parts(parts),
    })
}

/// Whether a shard `run` record is of a Taylor-model grid run (`"sets": "taylor"`).
pub fn is_taylor(run: &serde_json::Value) -> bool {
    run["sets"] == "taylor"
}

impl TaylorShard {
    /// Write this shard (`sh` of the grid run `run`) as the shard file `out`; its
    /// `--json` line and its human line.
    pub fn write(
        self,
        out: &std::path::Path,
        sh: crate::shard::Shard,
        run: &TaylorRun,
    ) -> anyhow::Result<(TaylorShardLine, String)> {
        crate::shard::write(out, "reach", sh, run, &self)?;
        let res = &self.reach;
        let (a, b) = self.cells;
        let line = TaylorShardLine {
            shard: (sh.i, sh.n),
            cells: (a, b),
            verdict: res.verdict.clone(),
            covered: res.covered,
            out: out.to_path_buf(),
        };
        let human = format!(
            "shard {}/{}: cells {a}..{b} of {}: {} ({} sub-boxes, {:.2} s, sets to the horizon for {} of these cells); partial result in {} (merge with `samara merge reach`)",
            sh.i,
            sh.n,
            run.cells,
            res.verdict.name(),
            res.boxes,
            res.seconds,
            percent(res.covered),
            out.display()
        );
        Ok((line, human))
    }
}
