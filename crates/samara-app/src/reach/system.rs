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
    /// `--time-order` (records from before the flag: the default, 6).
    #[serde(default = "default_time_order")]
    pub time_order: usize,
    /// `--step-tol`, the flow's relative step tolerance (records from before the flag:
    /// the default, 1e-7).
    #[serde(default = "default_step_tol")]
    pub step_tol: Exact,
    /// Whether sets are re-parameterised.
    pub precondition: bool,
    /// The measures.
    pub measures: Vec<MeasureText>,
    /// `--target-ratio` of an adaptive run (`samara_reach::adaptive`), whose shards
    /// divide the grid's starting cells by their number mod N; none for a grid run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_ratio: Option<Exact>,
}

/// [`TaylorRun::time_order`] of a record without it: the flow's default.
fn default_time_order() -> usize {
    samara_reach::tmflow::TmFlowSettings::default().time_order
}

/// [`TaylorRun::step_tol`] of a record without it: the flow's default.
fn default_step_tol() -> Exact {
    Exact(samara_reach::tmflow::TmFlowSettings::default().rem_rel)
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
            time_order: s.flow.time_order,
            step_tol: Exact(s.flow.rem_rel),
            precondition: s.precondition,
            measures: s.measures.iter().map(measure_text_of).collect(),
            target_ratio: None,
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
    /// The cells' merged result, every number kept exactly (`reach_form`: an
    /// infinite bound of a lost enclosure stays infinite), so that the merge gives
    /// what one process gives.
    #[serde(with = "reach_form")]
    pub reach: SystemReach,
}

/// The serde form of [`TaylorShard::reach`]: [`SystemReach`] field for field with every
/// f64 a [`Float`] (finite numbers keep their bytes; `inf`, `-inf` and `NaN` are
/// written as text where `reach.json`'s plain f64s give `null`, which reads back as
/// nothing). A leaf's `decided` is kept too (a merge's verdict needs it: a leaf read
/// back without it would count as proved); `flights`, which `SystemReach` does not
/// serialise, is left out (empty when read back).
pub(crate) mod reach_form {
    use crate::shard::Float;
    use samara_reach::system::{
        MeasureRange, NetworkError, SystemLeaf, SystemReach, SystemVerdict, SystemViolation,
    };
    use samara_reach::ReachVerdict;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    type Rows = Vec<Vec<[Float; 2]>>;

    fn rows(r: &[Vec<[f64; 2]>]) -> Rows {
        r.iter().map(|row| boxes(row)).collect()
    }

    fn boxes(b: &[[f64; 2]]) -> Vec<[Float; 2]> {
        b.iter().map(|iv| iv.map(Float)).collect()
    }

    fn unrows(r: Rows) -> Vec<Vec<[f64; 2]>> {
        r.into_iter().map(unboxes).collect()
    }

    fn unboxes(b: Vec<[Float; 2]>) -> Vec<[f64; 2]> {
        b.into_iter().map(|iv| iv.map(|x| x.0)).collect()
    }

    #[derive(Serialize, Deserialize)]
    struct Violation {
        initial: Vec<Float>,
        goal: String,
    }

    /// A [`SystemLeaf`] with exact numbers.
    #[derive(Serialize, Deserialize)]
    pub(crate) struct Leaf {
        init: Vec<[Float; 2]>,
        instants: Rows,
        periods: Rows,
        failure: Option<String>,
        stopped_at: Option<Float>,
        end_measures: Vec<[Float; 2]>,
        /// Shard files written before it was kept have none: read as "undecided" by
        /// nothing, as before (only the adaptive merge, which came with it, needs it).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        decided: Vec<Option<bool>>,
    }

    impl From<&SystemLeaf> for Leaf {
        fn from(l: &SystemLeaf) -> Leaf {
            let SystemLeaf {
                init,
                instants,
                periods,
                failure,
                decided,
                stopped_at,
                end_measures,
            } = l;
            Leaf {
                init: boxes(init),
                instants: rows(instants),
                periods: rows(periods),
                failure: failure.clone(),
                stopped_at: stopped_at.map(Float),
                end_measures: boxes(end_measures),
                decided: decided.clone(),
            }
        }
    }

    impl From<Leaf> for SystemLeaf {
        fn from(l: Leaf) -> SystemLeaf {
            SystemLeaf {
                init: unboxes(l.init),
                instants: unrows(l.instants),
                periods: unrows(l.periods),
                failure: l.failure,
                decided: l.decided,
                stopped_at: l.stopped_at.map(|x| x.0),
                end_measures: unboxes(l.end_measures),
            }
        }
    }

    #[derive(Serialize, Deserialize)]
    struct Measure {
        name: String,
        enclosure: Option<[Float; 2]>,
        sampled: Option<[Float; 2]>,
        ratio: Option<Float>,
    }

    #[derive(Serialize, Deserialize)]
    struct Reach {
        system: String,
        verdict: ReachVerdict<Violation>,
        instants: Rows,
        periods: Rows,
        boxes: usize,
        covered: Float,
        order: usize,
        network_error: NetworkError,
        seconds: Float,
        leaves: Vec<Leaf>,
        measures: Vec<Measure>,
    }

    pub fn serialize<S: Serializer>(r: &SystemReach, s: S) -> Result<S::Ok, S::Error> {
        // Every field named, so that a field added to `SystemReach` fails to compile
        // here until the form has it too.
        let SystemReach {
            system,
            verdict,
            instants,
            periods,
            boxes: n_boxes,
            covered,
            order,
            network_error,
            seconds,
            leaves,
            measures,
            flights: _,
        } = r;
        Reach {
            system: system.clone(),
            verdict: match verdict {
                ReachVerdict::Proved => ReachVerdict::Proved,
                ReachVerdict::Violated(v) => ReachVerdict::Violated(Violation {
                    initial: v.initial.iter().map(|x| Float(*x)).collect(),
                    goal: v.goal.clone(),
                }),
                ReachVerdict::Unknown { reason } => ReachVerdict::Unknown {
                    reason: reason.clone(),
                },
                ReachVerdict::NoGoal => ReachVerdict::NoGoal,
            },
            instants: rows(instants),
            periods: rows(periods),
            boxes: *n_boxes,
            covered: Float(*covered),
            order: *order,
            network_error: *network_error,
            seconds: Float(*seconds),
            leaves: leaves.iter().map(Leaf::from).collect(),
            measures: measures
                .iter()
                .map(|m| {
                    let MeasureRange {
                        name,
                        enclosure,
                        sampled,
                        ratio,
                    } = m;
                    Measure {
                        name: name.clone(),
                        enclosure: enclosure.map(|e| e.map(Float)),
                        sampled: sampled.map(|e| e.map(Float)),
                        ratio: ratio.map(Float),
                    }
                })
                .collect(),
        }
        .serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<SystemReach, D::Error> {
        let r = Reach::deserialize(d)?;
        let verdict: SystemVerdict = match r.verdict {
            ReachVerdict::Proved => ReachVerdict::Proved,
            ReachVerdict::Violated(v) => ReachVerdict::Violated(SystemViolation {
                initial: v.initial.into_iter().map(|x| x.0).collect(),
                goal: v.goal,
            }),
            ReachVerdict::Unknown { reason } => ReachVerdict::Unknown { reason },
            ReachVerdict::NoGoal => ReachVerdict::NoGoal,
        };
        Ok(SystemReach {
            system: r.system,
            verdict,
            instants: unrows(r.instants),
            periods: unrows(r.periods),
            boxes: r.boxes,
            covered: r.covered.0,
            order: r.order,
            network_error: r.network_error,
            seconds: r.seconds.0,
            leaves: r.leaves.into_iter().map(SystemLeaf::from).collect(),
            measures: r
                .measures
                .into_iter()
                .map(|m| MeasureRange {
                    name: m.name,
                    enclosure: m.enclosure.map(|e| e.map(|x| x.0)),
                    sampled: m.sampled.map(|e| e.map(|x| x.0)),
                    ratio: m.ratio.map(|x| x.0),
                })
                .collect(),
            flights: Vec::new(),
        })
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shard::{document, read_shards};
    use samara_reach::system::SystemLeaf;

    /// A cell's result; `lost`: its enclosure was lost after the first instant (an
    /// infinite hull, as the driver leaves it), with an infinite measure ratio.
    fn part(lost: bool) -> SystemReach {
        let (last, verdict) = if lost {
            (
                [f64::NEG_INFINITY, f64::INFINITY],
                SystemVerdict::Unknown {
                    reason: "the enclosure was lost at t = 0.5".into(),
                },
            )
        } else {
            ([0.25, 0.75], SystemVerdict::Proved)
        };
        let instants = vec![vec![[0.0, 0.5], [1.0, 1.5]], vec![last, [1.0, 2.0]]];
        SystemReach {
            system: "toy".into(),
            verdict,
            instants: instants.clone(),
            periods: vec![vec![[0.0, last[1]], [1.0, 2.0]]],
            boxes: 1,
            covered: if lost { 0.0 } else { 1.0 },
            order: 3,
            network_error: NetworkError::Interval,
            seconds: 0.125,
            leaves: vec![SystemLeaf {
                init: vec![[0.0, 0.5], [1.0, 1.5]],
                instants,
                periods: vec![vec![[0.0, last[1]], [1.0, 2.0]]],
                failure: lost.then(|| "the enclosure was lost at t = 0.5".into()),
                decided: Vec::new(),
                stopped_at: lost.then_some(0.5),
                end_measures: vec![last],
            }],
            measures: vec![MeasureRange {
                name: "x".into(),
                enclosure: Some(last),
                sampled: Some([0.3, 0.6]),
                ratio: Some((last[1] - last[0]) / 0.3),
            }],
            flights: Vec::new(),
        }
    }

    #[test]
    fn a_merge_of_shards_with_infinite_bounds_is_the_merge_of_their_results() {
        let run = TaylorRun {
            sets: "taylor".into(),
            system: "0123456789abcdef".into(),
            params: Vec::new(),
            init: vec![pair([0.0, 1.0]), pair([1.0, 1.5])],
            network: "fedcba9876543210".into(),
            grid: vec![2, 1],
            cells: 2,
            order: 3,
            max_boxes: 8,
            samples: 10,
            seed: 1,
            network_error: None,
            lift_at: Exact(0.5),
            lifted_weight: 1,
            time_order: 6,
            step_tol: Exact(1e-7),
            precondition: true,
            measures: Vec::new(),
            target_ratio: None,
        };
        let parts = [part(true), part(false)];
        let dir = std::env::temp_dir().join(format!("samara-taylor-merge-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut files = Vec::new();
        for (i, p) in parts.iter().enumerate() {
            let result = TaylorShard {
                cells: (i, i + 1),
                system_name: "toy.sys".into(),
                network_name: "toy.onnx".into(),
                reach: p.clone(),
            };
            let text = document("reach", Shard { i, n: 2 }, &run, &result).unwrap();
            if i == 0 {
                assert!(
                    text.contains("\"-inf\"") && text.contains("\"inf\""),
                    "{text}"
                );
            }
            let f = dir.join(format!("shard{i}.json"));
            std::fs::write(&f, text).unwrap();
            files.push(f);
        }
        let shards = read_shards("reach", &files).unwrap();
        let merged = merge_taylor(
            &shards.run_as::<TaylorRun>().unwrap(),
            &shards.results_as::<TaylorShard>().unwrap(),
        )
        .unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        // What one process gives: the same parts merged without a file between.
        let direct = grid::merge_parts(parts.iter().map(|p| (1, p.clone())).collect());
        assert_eq!(
            merged.result.instants[1][0],
            [f64::NEG_INFINITY, f64::INFINITY]
        );
        assert_eq!(
            merged.result.measures[0].enclosure,
            Some([f64::NEG_INFINITY, f64::INFINITY])
        );
        // Debug text shows every f64 exactly (shortest round trip, `inf`, `NaN`).
        assert_eq!(format!("{:?}", merged.result), format!("{direct:?}"));
        // And reach.json of the merge is the one-process document, byte for byte.
        assert_eq!(
            serde_json::to_string(&merged.result).unwrap(),
            serde_json::to_string(&direct).unwrap()
        );
    }
}
