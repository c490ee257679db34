//! Adaptive splitting's documents (`samara reach ... --target-ratio R`,
//! [`samara_reach::adaptive`]): `reach.json` ([`AdaptiveReport`]: the system run's report
//! plus an `adaptive` object) and the `--json` summary ([`AdaptiveSummary`]), and the
//! human line's adaptive part ([`adaptive_text`]).

use crate::reach::system::{SystemSettingsEcho, SystemSummary, TaylorRun};
use crate::shard::{Exact, Shard};
use crate::{input, AppError};
use samara_reach::adaptive::{
    merge_adaptive, reach_adaptive, AdaptiveCell, AdaptiveReach, AdaptiveSettings, FinishedRoot,
    OnFinished,
};
use samara_reach::system::{SystemLeaf, SystemReach, SystemReachSettings};
use samara_system::System;
use serde::{Deserialize, Serialize};
use std::io::{Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

type Result<T> = std::result::Result<T, AppError>;

/// The settings `reach.json` records of an adaptive run: the Taylor-model settings and
/// the target.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveSettingsEcho {
    /// The Taylor-model run's settings.
    #[serde(flatten)]
    pub run: SystemSettingsEcho,
    /// `--target-ratio`.
    pub target_ratio: f64,
}

/// The `adaptive` object: the target, whether it was met and how the cells came about.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveEcho {
    /// `--target-ratio`.
    pub target_ratio: f64,
    /// Whether the target was met.
    pub met: bool,
    /// The hull's width over the flights' spread, when every cell reached the horizon.
    pub ratio: Option<f64>,
    /// Why the target was not met, if it was not.
    pub reason: Option<String>,
    /// Why the run stopped early (time, budget), if it did.
    pub stopped: Option<String>,
    /// Cells of the final partition.
    pub leaves: usize,
    /// Of those, the cells accepted (sets in the band).
    pub accepted: usize,
    /// Cells flown, parents of cut cells included.
    pub flown: usize,
    /// Rounds.
    pub rounds: usize,
    /// The flights' range of the measure.
    pub sampled: [f64; 2],
    /// The band the cells' enclosures had to lie in.
    pub band: [f64; 2],
    /// The cells (in `reach.json` only: thousands of lines on a large set).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cells: Option<Vec<AdaptiveCell>>,
}

impl AdaptiveEcho {
    /// The echo of `r`, with its cells when `cells`.
    pub fn new(r: &AdaptiveReach, cells: bool) -> Self {
        AdaptiveEcho {
            target_ratio: r.target_ratio,
            met: r.met,
            ratio: r.ratio,
            reason: r.reason.clone(),
            stopped: r.stopped.clone(),
            leaves: r.cells.len(),
            accepted: r.cells.iter().filter(|c| c.accepted).count(),
            flown: r.flown,
            rounds: r.rounds,
            sampled: r.sampled,
            band: r.band,
            cells: cells.then(|| r.cells.clone()),
        }
    }
}

/// `reach.json` of an adaptive run.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveReport {
    /// The system file (or the built-in setting).
    pub system: String,
    /// `--network` as given.
    pub network: String,
    /// The settings.
    pub settings: AdaptiveSettingsEcho,
    /// The Taylor-model result over the final cells.
    pub result: SystemReach,
    /// The adaptive run's record.
    pub adaptive: AdaptiveEcho,
}

/// The `--json` summary of an adaptive run.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveSummary {
    /// The Taylor-model summary.
    #[serde(flatten)]
    pub run: SystemSummary,
    /// The adaptive record, without the cells.
    pub adaptive: AdaptiveEcho,
}

/// `adaptive: N leaves (K cells flown in R rounds); ratio q against the flights
/// (target R): met`.
pub fn adaptive_text(r: &AdaptiveReach) -> String {
    let ratio = r.ratio.map_or_else(
        || "no ratio (not every cell has sets at the horizon)".to_string(),
        |q| format!("ratio {q:.3}"),
    );
    let verdict = match &r.reason {
        None if r.met => "target met".to_string(),
        None => "target not met".to_string(),
        Some(why) => format!("target not met: {why}"),
    };
    format!(
        "adaptive: {} leaves ({} cells flown in {} rounds); {ratio} against the flights (target {}): {verdict}",
        r.cells.len(),
        r.flown,
        r.rounds,
        r.target_ratio
    )
}

/// Whether an adaptive run succeeded (exit 0): the width target met and every goal
/// proved, or no goal.
pub fn adaptive_success(r: &AdaptiveReach) -> bool {
    use samara_reach::system::SystemVerdict;
    r.met
        && matches!(
            r.reach.verdict,
            SystemVerdict::Proved | SystemVerdict::NoGoal
        )
}

impl AdaptiveReport {
    /// `reach.json` of the adaptive run `r` (`system`, `network`: as the command names
    /// them; `s`, `pieces`: the run's settings and `--grid`). The one document of a
    /// one-process run and of a merge of its shards.
    pub fn new(
        system: &str,
        network: &str,
        s: &samara_reach::system::SystemReachSettings,
        pieces: Option<&[usize]>,
        r: &AdaptiveReach,
    ) -> Self {
        AdaptiveReport {
            system: system.to_string(),
            network: network.to_string(),
            settings: AdaptiveSettingsEcho {
                run: SystemSettingsEcho::new(s, pieces),
                target_ratio: r.target_ratio,
            },
            result: r.reach.clone(),
            adaptive: AdaptiveEcho::new(r, true),
        }
    }
}

/// `result` of a shard of an adaptive run (`samara reach ... --target-ratio R --grid ...
/// --shard I/N`): its cells with every number exact, and the system's text, which the
/// merge parses again.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct AdaptiveShard {
    /// The system file as given (or `built-in setting`).
    pub system_name: String,
    /// `--network` as given.
    pub network_name: String,
    /// The system's text (its digest is the run record's `system`).
    pub source: String,
    /// The name it was parsed with (messages, `file`).
    pub file: String,
    /// The shard's result.
    #[serde(with = "adaptive_form")]
    pub adaptive: AdaptiveReach,
}

/// The serde form of [`AdaptiveReach`] with every f64 exact (`crate::shard::Float`).
mod adaptive_form {
    use crate::reach::system::reach_form;
    use crate::shard::Float;
    use samara_reach::adaptive::{AdaptiveCell, AdaptiveReach};
    use samara_reach::system::SystemReach;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    #[derive(Serialize, Deserialize)]
    struct Form {
        #[serde(with = "reach_form")]
        reach: SystemReach,
        cells: Vec<AdaptiveCell>,
        target_ratio: Float,
        sampled: [Float; 2],
        band: [Float; 2],
        ratio: Option<Float>,
        met: bool,
        reason: Option<String>,
        stopped: Option<String>,
        rounds: usize,
        flown: usize,
        unflown: Option<String>,
    }

    pub fn serialize<S: Serializer>(r: &AdaptiveReach, s: S) -> Result<S::Ok, S::Error> {
        // Every field named: a field added to `AdaptiveReach` fails to compile here.
        let AdaptiveReach {
            reach,
            cells,
            target_ratio,
            sampled,
            band,
            ratio,
            met,
            reason,
            stopped,
            rounds,
            flown,
            unflown,
        } = r;
        Form {
            reach: reach.clone(),
            cells: cells.clone(),
            target_ratio: Float(*target_ratio),
            sampled: sampled.map(Float),
            band: band.map(Float),
            ratio: ratio.map(Float),
            met: *met,
            reason: reason.clone(),
            stopped: stopped.clone(),
            rounds: *rounds,
            flown: *flown,
            unflown: unflown.clone(),
        }
        .serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<AdaptiveReach, D::Error> {
        let f = Form::deserialize(d)?;
        Ok(AdaptiveReach {
            reach: f.reach,
            cells: f.cells,
            target_ratio: f.target_ratio.0,
            sampled: f.sampled.map(|x| x.0),
            band: f.band.map(|x| x.0),
            ratio: f.ratio.map(|x| x.0),
            met: f.met,
            reason: f.reason,
            stopped: f.stopped,
            rounds: f.rounds,
            flown: f.flown,
            unflown: f.unflown,
        })
    }
}

/// One line of a checkpoint: a finished starting cell
/// ([`samara_reach::adaptive::FinishedRoot`]) with exact numbers.
#[derive(Serialize, Deserialize)]
struct RootLine {
    root: usize,
    rounds: usize,
    flown: usize,
    cells: Vec<AdaptiveCell>,
    leaves: Vec<crate::reach::system::reach_form::Leaf>,
}

/// The first line of a checkpoint: the run and shard its cells are of.
#[derive(Serialize, Deserialize, PartialEq)]
struct CheckpointHead {
    checkpoint: String,
    shard: (usize, usize),
    run: TaylorRun,
}

// 2: cells lost late are flown again with more symbolic parameters before a cut
// (`samara_reach::adaptive::RETRY_FROM`); a checkpoint of 1 holds cells cut instead.
const CHECKPOINT: &str = "samara adaptive reach checkpoint 2";

/// A shard's checkpoint file (JSON lines: the run, then one finished starting cell a
/// line, appended as they finish), from which a rerun of a killed or timed-out shard
/// resumes.
pub struct Checkpoint {
    path: PathBuf,
    file: Mutex<std::fs::File>,
    error: Mutex<Option<String>>,
}

impl Checkpoint {
    /// Open (or create) the checkpoint `path` of shard `shard` of `run`: the starting
    /// cells it has finished, and the checkpoint to append to. A checkpoint of another
    /// run, or a damaged one, is an input error naming the file; a last line cut short
    /// (the process was killed while writing it) is dropped.
    pub fn open(
        path: &Path,
        run: &TaylorRun,
        shard: Shard,
    ) -> Result<(Vec<FinishedRoot>, Arc<Checkpoint>)> {
        let head = CheckpointHead {
            checkpoint: CHECKPOINT.into(),
            shard: (shard.i, shard.n),
            run: run.clone(),
        };
        let io = |e: std::io::Error| AppError::Input(format!("{}: {e}", path.display()));
        let text = match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => String::new(),
            Err(e) => return Err(io(e)),
        };
        // Only whole lines (ended by a newline) count.
        let whole = text.rfind('\n').map_or(0, |k| k + 1);
        let mut lines = text[..whole].lines();
        let mut done = Vec::new();
        let mut keep = 0;
        if let Some(first) = lines.next() {
            let other = |why: String| {
                AppError::Input(format!(
                    "{}: a checkpoint of another run or shard ({why}); remove it to start this shard afresh, or give the settings it was written with",
                    path.display()
                ))
            };
            let h: CheckpointHead = serde_json::from_str(first)
                .map_err(|e| other(format!("not a checkpoint this samara writes: {e}")))?;
            if h != head {
                let a = serde_json::to_value(&h).unwrap_or_default();
                let b = serde_json::to_value(&head).unwrap_or_default();
                return Err(other(crate::shard::run_differences(&a, &b).join("; ")));
            }
            keep = first.len() + 1;
            for (k, line) in lines.enumerate() {
                let r: RootLine = serde_json::from_str(line).map_err(|e| {
                    AppError::Input(format!(
                        "{}: line {} is damaged ({e}); remove the file to start this shard afresh",
                        path.display(),
                        k + 2
                    ))
                })?;
                keep += line.len() + 1;
                done.push(FinishedRoot {
                    root: r.root,
                    rounds: r.rounds,
                    flown: r.flown,
                    cells: r
                        .cells
                        .into_iter()
                        .zip(r.leaves.into_iter().map(SystemLeaf::from))
                        .collect(),
                });
            }
        }
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(path)
            .map_err(io)?;
        file.set_len(keep as u64).map_err(io)?;
        file.seek(std::io::SeekFrom::End(0)).map_err(io)?;
        if keep == 0 {
            let mut line = serde_json::to_string(&head).expect("the run record serialises");
            line.push('\n');
            file.write_all(line.as_bytes()).map_err(io)?;
        }
        Ok((
            done,
            Arc::new(Checkpoint {
                path: path.to_path_buf(),
                file: Mutex::new(file),
                error: Mutex::new(None),
            }),
        ))
    }

    /// The callback that appends every finished starting cell (one write of a whole
    /// line; the first error is kept for [`Checkpoint::error`]).
    pub fn on_finished(self: &Arc<Self>) -> OnFinished {
        let me = self.clone();
        Arc::new(move |f: &FinishedRoot| {
            let line = RootLine {
                root: f.root,
                rounds: f.rounds,
                flown: f.flown,
                cells: f.cells.iter().map(|(c, _)| c.clone()).collect(),
                leaves: f.cells.iter().map(|(_, l)| l.into()).collect(),
            };
            let mut text = serde_json::to_string(&line).expect("a cell serialises");
            text.push('\n');
            let res = me
                .file
                .lock()
                .map_err(|_| "poisoned".to_string())
                .and_then(|mut w| w.write_all(text.as_bytes()).map_err(|e| e.to_string()));
            if let Err(e) = res {
                let mut slot = me.error.lock().unwrap_or_else(|p| p.into_inner());
                slot.get_or_insert(format!(
                    "{}: cannot append to the checkpoint: {e}",
                    me.path.display()
                ));
            }
        })
    }

    /// The first write error, if one happened (the run's result is unaffected; only a
    /// rerun's resumption is).
    pub fn error(&self) -> Option<String> {
        self.error.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }

    /// Remove the file (the shard's result is written: nothing left to resume).
    pub fn remove(&self) -> Result<()> {
        std::fs::remove_file(&self.path)
            .map_err(|e| AppError::Input(format!("{}: cannot remove: {e}", self.path.display())))
    }
}

/// The checkpoint of a shard file `out`: `out` with `.cells` appended.
pub fn checkpoint_path(out: &Path) -> PathBuf {
    let mut p = out.as_os_str().to_owned();
    p.push(".cells");
    PathBuf::from(p)
}

/// A shard of an adaptive run to fly ([`run_shard`]).
pub struct ShardRun<'a> {
    /// The system.
    pub sys: &'a System,
    /// The controller.
    pub net: &'a samara_nn::Network,
    /// The run's settings (with its measures).
    pub settings: &'a SystemReachSettings,
    /// `--grid`: the starting cells.
    pub pieces: &'a [usize],
    /// `--target-ratio`.
    pub target_ratio: f64,
    /// Which shard.
    pub shard: Shard,
    /// The checkpoint file, if any.
    pub checkpoint: Option<&'a Path>,
    /// The system and network as the command names them.
    pub system_name: String,
    /// The network as the command names it.
    pub network_name: String,
    /// The network's digest (the run record's `network`).
    pub network_digest: String,
    /// Progress lines.
    pub on_round: Option<samara_reach::adaptive::Progress>,
}

/// What [`run_shard`] gives: the run record every shard shares, this shard's result and
/// how many starting cells came from the checkpoint.
pub struct ShardDone {
    /// The run record.
    pub run: TaylorRun,
    /// The shard's result.
    pub result: AdaptiveShard,
    /// Starting cells taken from the checkpoint.
    pub resumed: usize,
    /// A checkpoint write error, if one happened.
    pub checkpoint_error: Option<String>,
}

/// Fly shard `r.shard` of an adaptive run: the grid's starting cells whose number is `I`
/// mod `N`, resuming from (and appending to) the checkpoint. The CLI (`samara reach
/// --target-ratio R --grid ... --shard I/N`) and Python (`samara.distributed`) both call
/// this; [`merge_shards`] joins the shards.
pub fn run_shard(r: ShardRun<'_>) -> Result<ShardDone> {
    let total = samara_reach::grid::cell_count(r.sys, r.pieces)
        .map_err(|e| AppError::Input(format!("grid: {e}")))?;
    if r.shard.n > total {
        return input(format!(
            "shard {}/{}: the grid has {total} starting cells, fewer than the {} shards; use at most {total} shards or a finer grid",
            r.shard.i, r.shard.n, r.shard.n
        ));
    }
    let mut run = TaylorRun::new(r.sys, r.network_digest.clone(), r.settings, r.pieces, total);
    run.target_ratio = Some(Exact(r.target_ratio));
    let (resume, cp) = match r.checkpoint {
        Some(p) => {
            let (done, cp) = Checkpoint::open(p, &run, r.shard)?;
            (done, Some(cp))
        }
        None => (Vec::new(), None),
    };
    let resumed = resume.len();
    let a = AdaptiveSettings {
        target_ratio: r.target_ratio,
        measure: 0,
        pieces: Some(r.pieces.to_vec()),
        on_round: r.on_round.clone(),
        shard: Some((r.shard.i, r.shard.n)),
        resume,
        on_finished: cp.as_ref().map(Checkpoint::on_finished),
        retry_from: AdaptiveSettings::default().retry_from,
    };
    let res = reach_adaptive(r.sys, r.net, r.settings, &a)
        .map_err(|e| AppError::Input(format!("{}: {e}", r.system_name)))?;
    let checkpoint_error = cp.as_ref().and_then(|c| c.error());
    // A shard that finished keeps no checkpoint; one stopped early keeps it to resume.
    if let (Some(c), None) = (&cp, &res.stopped) {
        if checkpoint_error.is_none() {
            c.remove()?;
        }
    }
    Ok(ShardDone {
        run,
        result: AdaptiveShard {
            system_name: r.system_name,
            network_name: r.network_name,
            source: r.sys.source().to_string(),
            file: r.sys.file.clone(),
            adaptive: res,
        },
        resumed,
        checkpoint_error,
    })
}

/// Join the shards of an adaptive run ([`run_shard`]; `shards` in shard order, checked
/// by `crate::shard::read_shards`) into `reach.json` of the one-process run and its
/// result (`samara_reach::adaptive::merge_adaptive`, which refuses a merge that would not
/// be the one-process result).
pub fn merge_shards(
    run: &TaylorRun,
    shards: &[(PathBuf, AdaptiveShard)],
) -> Result<(AdaptiveReport, AdaptiveReach)> {
    let Some((_, first)) = shards.first() else {
        return input("no shards to merge");
    };
    let Some(ratio) = run.target_ratio else {
        return input("not the shards of an adaptive run (no target ratio)");
    };
    for (f, sh) in shards {
        if crate::shard::digest(sh.source.as_bytes()) != run.system {
            return input(format!(
                "{}: the system text it holds is not the one its run record names (digest {}): the file was edited; run that shard again",
                f.display(),
                run.system
            ));
        }
    }
    let params: Vec<(&str, f64)> = run.params.iter().map(|(n, v)| (n.as_str(), v.0)).collect();
    let sys = System::parse_with(&first.source, &first.file, &params)
        .map_err(|e| AppError::Input(format!("the shards' system: {e}")))?;
    let mut s = SystemReachSettings {
        order: run.order,
        max_boxes: run.max_boxes,
        samples: run.samples,
        seed: run.seed,
        precondition: run.precondition,
        network_error: run.network_error,
        measures: run
            .measures
            .iter()
            .map(|m| samara_reach::system::Measure {
                name: m.name.clone(),
                coef: m.coef.iter().map(|c| c.0).collect(),
                offset: m.offset.0,
            })
            .collect(),
        ..SystemReachSettings::default()
    };
    s.flow.lift_at = run.lift_at.0;
    s.flow.lifted_weight = run.lifted_weight;
    s.flow.time_order = run.time_order;
    crate::reach::args::set_step_tol(&mut s.flow, run.step_tol.0);
    let a = AdaptiveSettings {
        target_ratio: ratio.0,
        pieces: Some(run.grid.clone()),
        ..AdaptiveSettings::default()
    };
    let parts = shards.iter().map(|(_, r)| r.adaptive.clone()).collect();
    let res = merge_adaptive(&sys, &s, &a, parts)
        .map_err(|e| AppError::Input(format!("samara merge reach: {e}")))?;
    let report = AdaptiveReport::new(
        &first.system_name,
        &first.network_name,
        &s,
        Some(&run.grid),
        &res,
    );
    Ok((report, res))
}

/// The `--json` line of an adaptive shard.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveShardLine {
    /// `[I, N]`.
    pub shard: (usize, usize),
    /// Its cells.
    pub leaves: usize,
    /// Of those, accepted.
    pub accepted: usize,
    /// Starting cells taken from the checkpoint.
    pub resumed: usize,
    /// Why it stopped early, if it did.
    pub stopped: Option<String>,
    /// The shard file.
    pub out: PathBuf,
}

impl ShardDone {
    /// The `--json` line and the human line of this shard written to `out`.
    pub fn lines(&self, sh: Shard, out: &Path) -> (AdaptiveShardLine, String) {
        let r = &self.result.adaptive;
        let accepted = r.cells.iter().filter(|c| c.accepted).count();
        let line = AdaptiveShardLine {
            shard: (sh.i, sh.n),
            leaves: r.cells.len(),
            accepted,
            resumed: self.resumed,
            stopped: r.stopped.clone(),
            out: out.to_path_buf(),
        };
        let stopped = r.stopped.as_ref().map_or_else(String::new, |w| {
            format!(
                "; stopped early ({w}): rerun the same command to resume from {}",
                checkpoint_path(out).display()
            )
        });
        let human = format!(
            "shard {}/{}: starting cells {} mod {} of {}: {} cells ({accepted} accepted, {} flown in {} rounds, {} starting cells from the checkpoint){stopped}; partial result in {} (merge with `samara merge reach`)",
            sh.i,
            sh.n,
            sh.i,
            sh.n,
            self.run.cells,
            r.cells.len(),
            r.flown,
            r.rounds,
            self.resumed,
            out.display()
        );
        (line, human)
    }
}

/// Merge adaptive shard documents held in memory (Python's `samara.distributed`;
/// `docs[k]` named `shard document k` in messages) into the text of `reach.json` that
/// one process writes.
pub fn merge_documents(docs: Vec<String>) -> Result<String> {
    let texts = docs
        .into_iter()
        .enumerate()
        .map(|(k, t)| (PathBuf::from(format!("shard document {k}")), t))
        .collect();
    let shards = crate::shard::read_shard_texts("reach", texts)?;
    if shards.run["target_ratio"].is_null() {
        return input("not the shards of an adaptive run (no target ratio in their run record)");
    }
    let run: TaylorRun = shards.run_as()?;
    let parts = shards.results_as::<AdaptiveShard>()?;
    let (report, _) = merge_shards(&run, &parts)?;
    crate::json_pretty(&report).map_err(|e| AppError::Input(format!("reach.json: {e}")))
}
