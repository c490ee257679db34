//! Adaptive splitting toward a width target: the cells of the initial set are found by
//! the run, not by hand (issue 39, item 1).
//!
//! A covering run of a large initial set (the glider's six-state set) needs hundreds of
//! Taylor-model cells, but most of them can be large: of a hand-chosen grid of 1,296
//! cells, 1,278 met their band on the first try. Here the run starts coarse and cuts
//! only the cells that need it:
//!
//! 1. Flights first: `samples` simulated flights over the whole initial set (its centre,
//!    corners and random starts, [`crate::system::starts`]) give the range `[lo, hi]` of
//!    the target's measure at the horizon (`x + y` for the glider) and look for a goal
//!    they miss.
//! 2. The band: the hull of the cells' enclosures of the measure has width at most
//!    `target_ratio * (hi - lo)` when every cell's enclosure lies in
//!    `mid +- target_ratio * (hi - lo) / 2`, `mid` the flights' midpoint. That is each
//!    cell's share of the target: a cell is tight enough when its own enclosure lies in
//!    the band, however wide it is on its own.
//! 3. Rounds: every cell of the frontier is flown by `crate::system::fly_box` in
//!    parallel (the rayon pool of the caller, `--threads`). A cell is **accepted** when
//!    its sets reach the horizon, its measure lies in the band and (unless a flight
//!    already refuted them) its goals are proved. Every other cell is cut in two:
//!    - lost (or stopped where a goal became undecidable): along the parameter that moves
//!      the state most at the control instant where its sets ended
//!      (`crate::system::bisect_sensitive`, flights from the cell's centre with one
//!      parameter at its ends);
//!    - too wide: along the parameter that moves the measure at the horizon most (the
//!      same flights, the measure's difference): the dependence that cutting halves.
//! 4. The budget `max_boxes` bounds the cells of the final partition. When a round's cuts
//!    would pass it, the cells lost earliest are cut first, then the widest, ties by cell
//!    id; the rest stay as they are (unaccepted).
//!
//! Determinism: a cell's result depends only on its box (no wall-clock budget), the
//! rounds are synchronous and every choice is made in cell-id order, so the partition,
//! the sets and the verdict do not depend on the number of threads
//! (`tests/adaptive.rs`). A `timeout` ends the run where it is (`unknown (timeout)`).
//!
//! Cell ids: the starting cell's number (row-major over `pieces`, 0 without a grid)
//! followed by the halves taken, `0` the lower and `1` the upper (`"17.0110"`).
//!
//! Shards and checkpoints: `AdaptiveSettings::shard` flies the starting cells of one
//! residue, and [`merge_adaptive`] joins the shards into the one-process result, or
//! refuses where it would differ (a shard stopped early, cells past the budget).
//! `AdaptiveSettings::on_finished` reports each starting cell whose cells are final and
//! depend on its own box only ([`FinishedRoot`]); given back as
//! `AdaptiveSettings::resume`, they are not flown again, so a killed run resumes
//! (`tests/adaptive.rs`; the file form is `samara_app::reach::adaptive::Checkpoint`).

use crate::taylor::driver::{
    checked_settings, coverage, covered_volume, falsify, leaf_hull, measure_ranges, Falsified,
};
use crate::taylor::flight::{empty_leaf, fly_box, past};
use crate::taylor::network::controller;
use crate::taylor::refine::{bisect_sensitive, cut_at};
use crate::taylor::SystemViolation;
use crate::taylor::{
    NetworkError, SystemLeaf, SystemReach, SystemReachError, SystemReachSettings, SystemVerdict,
};
use rayon::prelude::*;
use samara_nn::Network;
use samara_num::Interval;
use samara_system::sim::{fly, goals_hold};
use samara_system::System;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;
use std::time::Instant;

/// A progress callback: one line per round.
pub type Progress = Arc<dyn Fn(&str) + Send + Sync>;

/// A checkpoint callback: called with every starting cell whose cells are all final
/// (see [`FinishedRoot`]), in the run's thread, as soon as its round ends.
pub type OnFinished = Arc<dyn Fn(&FinishedRoot) + Send + Sync>;

/// A starting cell whose splitting is over, with every cell cut from it: what a
/// checkpoint keeps so that a rerun of a killed or timed-out run skips it
/// ([`AdaptiveSettings::resume`]).
///
/// Only cells whose result depends on their own box are reported: a starting cell with
/// a cell left uncut by the leaf budget, the time budget or a goal refuted elsewhere,
/// or with a goal refuted on its own sets, is not (a rerun flies it again), so a resumed
/// run gives what an uninterrupted one gives wherever the budget does not bind.
#[derive(Clone, Debug)]
pub struct FinishedRoot {
    /// The starting cell's number (row-major over `pieces`).
    pub root: usize,
    /// Rounds its splitting took (the round its last cell was accepted in).
    pub rounds: usize,
    /// Cells flown for it, parents of cut cells included.
    pub flown: usize,
    /// Its final cells, in the order the run found them.
    pub cells: Vec<(AdaptiveCell, SystemLeaf)>,
}

/// Settings of the adaptive splitting (on top of the run's [`SystemReachSettings`], whose
/// `max_boxes` is the leaf budget, `samples` the flights that set the band and
/// `measures` the functions a target can be on).
#[derive(Clone)]
pub struct AdaptiveSettings {
    /// The target: the hull of the measure's enclosures at the horizon at most this
    /// many times the flights' spread (at least 1).
    pub target_ratio: f64,
    /// Which of the run's measures the target is on.
    pub measure: usize,
    /// The starting cells: `pieces[i]` equal pieces along state `i`
    /// ([`crate::grid::cell_box`]); `None`: the whole initial set.
    pub pieces: Option<Vec<usize>>,
    /// Called with one line of progress after every round (the CLI prints it).
    pub on_round: Option<Progress>,
    /// `Some((i, n))`: fly only the starting cells whose number is `i` mod `n` (shard `i`
    /// of `n`; each shard flies all the flights, so every shard has the same band), and
    /// `max_boxes` bounds this shard's cells. [`merge_adaptive`] joins the shards.
    pub shard: Option<(usize, usize)>,
    /// Starting cells finished by an earlier run of the same settings (a checkpoint):
    /// not flown again, their cells taken as they are. Each must be one of this run's
    /// (shard's) starting cells.
    pub resume: Vec<FinishedRoot>,
    /// Called with every starting cell as it finishes (to write a checkpoint).
    pub on_finished: Option<OnFinished>,
    /// `Some(f)`: a cell lost after reaching the share `f` of the horizon's control
    /// steps is flown once more with more symbolic parameters ([`retry_mode`]) before
    /// it is cut, once per cell (default [`RETRY_FROM`]); `None`: lost cells are cut.
    pub retry_from: Option<f64>,
}

impl Default for AdaptiveSettings {
    fn default() -> Self {
        AdaptiveSettings {
            target_ratio: 2.0,
            measure: 0,
            pieces: None,
            on_round: None,
            shard: None,
            resume: Vec::new(),
            on_finished: None,
            retry_from: Some(RETRY_FROM),
        }
    }
}

/// One cell of the final partition: its id and whether it met its share of the target.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AdaptiveCell {
    /// The cell's id (module doc).
    pub id: String,
    /// Sets to the horizon, the measure in the band, goals proved (or refuted by a
    /// flight).
    pub accepted: bool,
    /// Its sets are those of its second flight, with [`retry_mode`]'s network error
    /// (its first was lost late).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub retried: bool,
}

/// The result of an adaptive run.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveReach {
    /// The run's sets and verdict on the goals (`leaves`: the final cells, in id order).
    pub reach: SystemReach,
    /// Per leaf of `reach.leaves`: its id and whether it was accepted.
    pub cells: Vec<AdaptiveCell>,
    /// The target ratio asked for.
    pub target_ratio: f64,
    /// The measure's range over the flights.
    pub sampled: [f64; 2],
    /// The band every cell's enclosure must lie in.
    pub band: [f64; 2],
    /// The hull of the cells' enclosures over the flights' spread, when every cell has
    /// sets at the horizon.
    pub ratio: Option<f64>,
    /// Whether the target is met (every cell reaches the horizon and the hull's ratio is
    /// at most the target).
    pub met: bool,
    /// Why not, when not.
    pub reason: Option<String>,
    /// Why the splitting stopped before every cell was accepted (time, budget, a goal
    /// refuted on the sets), if it did.
    pub stopped: Option<String>,
    /// Rounds of flights.
    pub rounds: usize,
    /// Cells flown in all (the cut ones included).
    pub flown: usize,
    /// A falsification flight that could not be finished, if one could not (the same
    /// flights in every shard: kept so that a merge words an `unknown` as one run does).
    pub unflown: Option<String>,
}

/// A cell: its starting cell's number and the halves taken since.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct CellId {
    root: usize,
    path: Vec<u8>,
}

impl CellId {
    fn label(&self) -> String {
        if self.path.is_empty() {
            self.root.to_string()
        } else {
            let bits: String = self.path.iter().map(|b| char::from(b'0' + b)).collect();
            format!("{}.{bits}", self.root)
        }
    }

    /// The id of a label ([`CellId::label`]'s form), if it is one.
    fn parse(label: &str) -> Option<CellId> {
        let (root, bits) = label.split_once('.').unwrap_or((label, ""));
        let path = bits
            .bytes()
            .map(|b| match b {
                b'0' | b'1' => Some(b - b'0'),
                _ => None,
            })
            .collect::<Option<Vec<u8>>>()?;
        if label.contains('.') && path.is_empty() {
            return None;
        }
        Some(CellId {
            root: root.parse().ok()?,
            path,
        })
    }

    fn child(&self, half: u8) -> CellId {
        let mut path = self.path.clone();
        path.push(half);
        CellId {
            root: self.root,
            path,
        }
    }
}

/// The share of the horizon's control steps a lost cell must have reached to be flown
/// once more with [`retry_mode`] before it is cut. On the glider's six-state cells
/// (bench/reach/cell_cost.md, "i51-r"), cells lost in the periods from t = 18 and 19
/// of 20 reach the horizon with `symbolic:60` where they were lost with `symbolic:40`,
/// at about 1.5x a cell's cost where their two halves cost 2x; a cell lost from t = 16
/// is lost again (at t = 19.5), and so are coarser cells lost earlier: those are cut.
pub const RETRY_FROM: f64 = 0.85;

/// The network error a cell lost late is flown again with: half as many symbolic
/// parameters again (`symbolic:40` -> `symbolic:60`, at most 256: more symbolic
/// remainders keep more of the network's error correlated, the lifted parameters of
/// Makino and Berz's symbolic remainders), symbolic remainders after interval ones.
pub fn retry_mode(mode: NetworkError) -> NetworkError {
    match mode {
        NetworkError::Interval => NetworkError::Symbolic { extra: 20 },
        NetworkError::Symbolic { extra } => NetworkError::Symbolic {
            extra: (extra + extra.div_ceil(2)).min(256),
        },
    }
}

/// `interval` or `symbolic:N`, as `--network-error` names a mode.
fn mode_name(m: NetworkError) -> String {
    match m {
        NetworkError::Interval => "interval".into(),
        NetworkError::Symbolic { extra } => format!("symbolic:{extra}"),
    }
}

/// What a flown cell needs: nothing, a cut (with its urgency), or nothing more can be
/// done (a goal refuted by its sets).
enum Need {
    Accepted,
    /// Sort key: lost or stopped cells first by the instant reached, then wide ones by
    /// how far they leave the band (negated, so that the widest come first).
    Cut(u8, f64),
    Refuted(usize),
}

/// Sound reachable sets of `sys` under `net`, the initial set split adaptively until the
/// measure `a.measure` meets `a.target_ratio` (module doc).
pub fn reach_adaptive(
    sys: &System,
    net: &Network,
    s: &SystemReachSettings,
    a: &AdaptiveSettings,
) -> Result<AdaptiveReach, SystemReachError> {
    let t0 = Instant::now();
    let setting = |m: String| Err(SystemReachError::Setting(m));
    if !(a.target_ratio.is_finite() && a.target_ratio >= 1.0) {
        return setting(format!(
            "the target ratio must be a number of at least 1 (got {}): the enclosure's hull holds every flight, so it is never narrower than their spread",
            a.target_ratio
        ));
    }
    let Some(measure) = s.measures.get(a.measure) else {
        return setting(
            "a width target needs a measure at the horizon (the glider's x + y, or a system file's `goal band ... at end`)".into(),
        );
    };
    let (s, deadline) = checked_settings(sys, net, s, t0)?;
    let s = &s;
    let init: Vec<Interval> = sys
        .init
        .iter()
        .map(|&(l, h)| Interval { lo: l, hi: h })
        .collect();
    let mut frontier: Vec<(CellId, Vec<Interval>)> = match &a.pieces {
        None => vec![(
            CellId {
                root: 0,
                path: Vec::new(),
            },
            init.clone(),
        )],
        Some(p) => {
            let n = crate::grid::cell_count(sys, p)?;
            (0..n)
                .map(|c| {
                    let b = crate::grid::cell_box(&sys.init, p, c)
                        .into_iter()
                        .map(|(lo, hi)| Interval { lo, hi })
                        .collect();
                    (
                        CellId {
                            root: c,
                            path: Vec::new(),
                        },
                        b,
                    )
                })
                .collect()
        }
    };
    if let Some((i, n)) = a.shard {
        if n == 0 || i >= n {
            return setting(format!("shard {i} of {n}: give 0 <= i < n"));
        }
        frontier.retain(|(id, _)| id.root % n == i);
        if frontier.is_empty() {
            return setting(format!(
                "shard {i} of {n} has no starting cell: use at most as many shards as starting cells (--grid)"
            ));
        }
    }
    if frontier.len() > s.max_boxes {
        return setting(format!(
            "the starting grid has {} cells, more than the budget of {} leaves: raise the budget or start coarser",
            frontier.len(),
            s.max_boxes
        ));
    }
    // Starting cells a checkpoint finished: their cells as they are, not flown again.
    let mut done: Vec<(CellId, SystemLeaf, bool)> = Vec::new();
    // Cells flown with `retry_mode` (their second flight), and those of the next round.
    let mut retried: BTreeSet<CellId> = BTreeSet::new();
    let mut retrying: BTreeSet<CellId> = BTreeSet::new();
    let (mut resumed_rounds, mut resumed_flown) = (0, 0);
    if !a.resume.is_empty() {
        let mut resumed = std::collections::BTreeSet::new();
        for f in &a.resume {
            if !frontier.iter().any(|(id, _)| id.root == f.root) || !resumed.insert(f.root) {
                return setting(format!(
                    "the checkpoint has starting cell {} twice or one this run does not fly: it is of another run (--grid, --shard); remove it",
                    f.root
                ));
            }
            resumed_rounds = resumed_rounds.max(f.rounds);
            resumed_flown += f.flown;
            for (c, l) in &f.cells {
                match CellId::parse(&c.id) {
                    Some(id) if id.root == f.root => {
                        if c.retried {
                            retried.insert(id.clone());
                        }
                        done.push((id, l.clone(), c.accepted))
                    }
                    _ => {
                        return setting(format!(
                            "the checkpoint's cell `{}` is not a cell of starting cell {}: the file is damaged; remove it",
                            c.id, f.root
                        ))
                    }
                }
            }
        }
        frontier.retain(|(id, _)| !resumed.contains(&id.root));
    }
    // 1. The flights: the band, and a goal they miss.
    let Falsified {
        flights,
        violation,
        unflown,
    } = falsify(sys, net, s, deadline)?;
    let ends: Vec<f64> = flights
        .iter()
        .filter_map(|(_, f)| f.states.last().map(|x| measure.at(x)))
        .collect();
    let lo = ends.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = ends.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return setting(format!(
            "the {} flights spread `{}` at the horizon over [{lo}, {hi}]: a width target needs a spread; give more samples or a wider initial set",
            ends.len(),
            measure.name
        ));
    }
    let mid = 0.5 * (lo + hi);
    let half = 0.5 * a.target_ratio * (hi - lo);
    let band = [mid - half, mid + half];
    // With a goal already missed by a flight the verdict is decided; the cells are then
    // cut for the width target only.
    let goals_count = violation.is_none();
    let mode = s
        .network_error
        .unwrap_or(NetworkError::Symbolic { extra: 20 });
    let steps = sys.steps();
    let again = retry_mode(mode);
    let need = |l: &SystemLeaf| -> Need {
        if goals_count {
            if let Some(gi) = l.decided.iter().position(|d| *d == Some(false)) {
                return Need::Refuted(gi);
            }
        }
        let reached = l.failure.is_none() && l.stopped_at.is_none() && l.instants.len() > steps;
        let Some(e) = l.end_measures.get(a.measure).filter(|_| reached) else {
            return Need::Cut(0, l.instants.len() as f64);
        };
        let excess = (band[0] - e[0]).max(e[1] - band[1]);
        let goals_ok = !goals_count || l.decided.iter().all(|d| *d == Some(true));
        if excess <= 0.0 && goals_ok {
            Need::Accepted
        } else {
            Need::Cut(1, -excess)
        }
    };
    let mut refuted: Option<(usize, Vec<f64>)> = None;
    let mut leaves = frontier.len() + done.len();
    // Per starting cell still being split: its cells in the frontier, its cells flown,
    // and whether one of its cells was left uncut for a reason outside its own box.
    let mut roots: BTreeMap<usize, Root> = BTreeMap::new();
    for (id, _) in &frontier {
        roots.entry(id.root).or_default().pending += 1;
    }
    let (mut rounds, mut flown, mut timed_out, mut budget_bound) = (0, 0, false, false);
    while !frontier.is_empty() {
        if past(deadline) {
            timed_out = true;
            for (id, b) in frontier.drain(..) {
                roots.entry(id.root).or_default().tainted = true;
                let why = "not flown: the time budget was spent".to_string();
                done.push((id, empty_leaf(sys, &b, Some(why)), false));
            }
            break;
        }
        rounds += 1;
        let results: Vec<(CellId, SystemLeaf)> = frontier
            .par_iter()
            .map(|(id, b)| {
                let m = if retrying.contains(id) { again } else { mode };
                (id.clone(), fly_box(sys, net, b, s, m, deadline))
            })
            .collect();
        flown += results.len();
        retried.append(&mut retrying);
        let mut cuts: Vec<(u8, f64, CellId, SystemLeaf)> = Vec::new();
        let mut again_next: Vec<(CellId, SystemLeaf)> = Vec::new();
        let (mut accepted, mut lost, mut wide) = (0usize, 0usize, 0usize);
        let mut touched = std::collections::BTreeSet::new();
        for (id, _) in &results {
            let r = roots.entry(id.root).or_default();
            r.pending -= 1;
            r.flown += 1;
            touched.insert(id.root);
        }
        for (id, l) in results {
            match need(&l) {
                Need::Accepted => {
                    accepted += 1;
                    done.push((id, l, true));
                }
                Need::Refuted(gi) => {
                    roots.entry(id.root).or_default().tainted = true;
                    if refuted.is_none() {
                        let centre = l.init.iter().map(|v| 0.5 * (v[0] + v[1])).collect();
                        refuted = Some((gi, centre));
                    }
                    done.push((id, l, false));
                }
                Need::Cut(class, key) => {
                    lost += usize::from(class == 0);
                    wide += usize::from(class == 1);
                    let late = a.retry_from.is_some_and(|f| {
                        l.failure.is_some()
                            && l.instants.len().saturating_sub(1) as f64 >= f * steps as f64
                    });
                    if class == 0 && late && again != mode && !retried.contains(&id) {
                        again_next.push((id, l));
                    } else {
                        cuts.push((class, key, id, l));
                    }
                }
            }
        }
        cuts.sort_by(|p, q| {
            p.0.cmp(&q.0)
                .then(p.1.total_cmp(&q.1))
                .then_with(|| p.2.cmp(&q.2))
        });
        let room = s.max_boxes - leaves;
        let n_cut = if refuted.is_some() || past(deadline) {
            timed_out |= past(deadline);
            0
        } else {
            cuts.len().min(room)
        };
        budget_bound |= n_cut < cuts.len() && refuted.is_none() && !timed_out;
        leaves += n_cut;
        let rest = cuts.split_off(n_cut);
        for (_, _, id, l) in rest {
            roots.entry(id.root).or_default().tainted = true;
            done.push((id, l, false));
        }
        // Lost late: flown once more (it stays one leaf), unless the run is ending.
        let n_again = again_next.len();
        let mut again_cells = Vec::new();
        for (id, l) in again_next {
            if refuted.is_some() || timed_out {
                roots.entry(id.root).or_default().tainted = true;
                done.push((id, l, false));
                continue;
            }
            roots.entry(id.root).or_default().pending += 1;
            let b: Vec<Interval> = l
                .init
                .iter()
                .map(|v| Interval { lo: v[0], hi: v[1] })
                .collect();
            retrying.insert(id.clone());
            again_cells.push((id, b));
        }
        for (_, _, id, _) in &cuts {
            roots.entry(id.root).or_default().pending += 2;
        }
        let halves: Vec<Vec<(CellId, Vec<Interval>)>> = cuts
            .into_par_iter()
            .map(|(class, _, id, l)| {
                let b: Vec<Interval> = l
                    .init
                    .iter()
                    .map(|v| Interval { lo: v[0], hi: v[1] })
                    .collect();
                let (p, q) = if class == 0 {
                    let k = l.instants.len().saturating_sub(1);
                    bisect_sensitive(sys, net, &b, &init, k)
                } else {
                    cut_at(
                        &b,
                        measure_split(sys, net, &b, measure).unwrap_or_else(|| {
                            let (p, _) = bisect_sensitive(sys, net, &b, &init, steps);
                            // The parameter the fallback cut: where the halves differ.
                            (0..b.len()).find(|&j| p[j].hi != b[j].hi).unwrap_or(0)
                        }),
                    )
                };
                vec![(id.child(0), p), (id.child(1), q)]
            })
            .collect();
        frontier = again_cells;
        frontier.extend(halves.into_iter().flatten());
        for root in touched {
            let finished = roots.get(&root).is_some_and(|r| r.pending == 0);
            if !finished {
                continue;
            }
            let r = roots.remove(&root).unwrap_or_default();
            if let (Some(f), false) = (&a.on_finished, r.tainted) {
                f(&FinishedRoot {
                    root,
                    rounds,
                    flown: r.flown,
                    cells: done
                        .iter()
                        .filter(|d| d.0.root == root)
                        .map(|(id, l, ok)| {
                            (
                                AdaptiveCell {
                                    id: id.label(),
                                    accepted: *ok,
                                    retried: retried.contains(id),
                                },
                                l.clone(),
                            )
                        })
                        .collect(),
                });
            }
        }
        if let Some(f) = &a.on_round {
            f(&format!(
                "round {rounds}: {accepted} cells accepted, {lost} lost ({n_again} lost late, to fly again with {}), {wide} too wide or undecided; {} to fly next; {} leaves of {}, {} accepted so far; {:.0} s",
                mode_name(again),
                frontier.len(),
                leaves,
                s.max_boxes,
                done.iter().filter(|d| d.2).count(),
                t0.elapsed().as_secs_f64()
            ));
        }
    }
    let (rounds, flown) = (rounds.max(resumed_rounds), flown + resumed_flown);
    let stopped = if timed_out {
        Some(format!("timeout after {:.1} s", t0.elapsed().as_secs_f64()))
    } else if budget_bound {
        Some(format!("the budget of {} leaves ran out", s.max_boxes))
    } else {
        refuted
            .is_some()
            .then(|| "a goal was refuted on the sets first".to_string())
    };
    // The verdict on the goals where the cells alone do not give it, as `reach_system`.
    let goal_verdict = if let Some(v) = violation {
        Some(v)
    } else if let Some((gi, centre)) = refuted {
        let eval = controller(net);
        Some(match fly(sys, &eval, &centre, 10) {
            Ok(f) if goals_hold(sys, &f).iter().any(|h| !h) => SystemVerdict::Violated(SystemViolation {
                initial: centre,
                goal: sys.goals[gi].text.clone(),
            }),
            _ => SystemVerdict::Unknown {
                reason: format!(
                    "the enclosure of a cell lies outside the goal `{}`, but no simulated flight from the starts tried missed it",
                    sys.goals[gi].text
                ),
            },
        })
    } else {
        None
    };
    let cells = done
        .into_iter()
        .map(|(id, l, ok)| {
            (
                AdaptiveCell {
                    retried: retried.contains(&id),
                    id: id.label(),
                    accepted: ok,
                },
                l,
            )
        })
        .collect();
    let sampled = measure_ranges(&s.measures, &[], &flights, 0.0)
        .into_iter()
        .map(|m| m.sampled)
        .collect();
    let mut r = assemble(
        sys,
        s,
        a,
        Joined {
            cells,
            sampled,
            range: [lo, hi],
            band,
            goal_verdict,
            stopped,
            unflown,
            rounds,
            flown,
            mode,
        },
    );
    r.reach.flights = flights;
    r.reach.seconds = t0.elapsed().as_secs_f64();
    Ok(r)
}

/// A starting cell being split ([`reach_adaptive`]'s bookkeeping for checkpoints).
#[derive(Default)]
struct Root {
    pending: usize,
    flown: usize,
    tainted: bool,
}

/// What a run or a merge of shards has at the end, for [`assemble`].
struct Joined {
    cells: Vec<(AdaptiveCell, SystemLeaf)>,
    /// Each measure's range over the flights.
    sampled: Vec<Option<[f64; 2]>>,
    range: [f64; 2],
    band: [f64; 2],
    goal_verdict: Option<SystemVerdict>,
    stopped: Option<String>,
    unflown: Option<String>,
    rounds: usize,
    flown: usize,
    mode: NetworkError,
}

/// The sort key of a cell id: its starting cell, then its halves (a parent before its
/// children, the lower half first).
fn id_key(id: &str) -> (usize, &str) {
    let (root, path) = id.split_once('.').unwrap_or((id, ""));
    (root.parse().unwrap_or(usize::MAX), path)
}

/// The result of the final cells (sorted here by id): the hulls, the coverage, the
/// measures, the ratio and the verdicts. No flights, `seconds` 0: the caller's.
fn assemble(
    sys: &System,
    s: &SystemReachSettings,
    a: &AdaptiveSettings,
    j: Joined,
) -> AdaptiveReach {
    let Joined {
        mut cells,
        sampled,
        range: [lo, hi],
        band,
        goal_verdict,
        stopped,
        unflown,
        rounds,
        flown,
        mode,
    } = j;
    cells.sort_by(|p, q| id_key(&p.0.id).cmp(&id_key(&q.0.id)));
    let (cells, leaves): (Vec<AdaptiveCell>, Vec<SystemLeaf>) = cells.into_iter().unzip();
    let init: Vec<Interval> = sys
        .init
        .iter()
        .map(|&(l, h)| Interval { lo: l, hi: h })
        .collect();
    // A shard's cells are part of the set: their share, never 1.
    let covered = match a.shard {
        Some((_, n)) if n > 1 => {
            covered_volume(&init, &leaves, sys.steps()).min(1.0 - f64::EPSILON)
        }
        _ => coverage(&init, &leaves, sys.steps()),
    };
    let mut measures = measure_ranges(&s.measures, &leaves, &[], covered);
    for (m, smp) in measures.iter_mut().zip(sampled) {
        m.sampled = smp;
        m.ratio = match (m.enclosure, smp) {
            (Some(e), Some(v)) if v[1] > v[0] => Some((e[1] - e[0]) / (v[1] - v[0])),
            _ => None,
        };
    }
    let enclosure = measures[a.measure].enclosure;
    let ratio = enclosure.map(|e| (e[1] - e[0]) / (hi - lo));
    let met = ratio.is_some_and(|r| r <= a.target_ratio);
    let not_accepted = cells.iter().filter(|c| !c.accepted).count();
    let unflown_note = unflown.clone();
    let reason = (!met).then(|| {
        let lost = leaves.iter().filter(|l| l.failure.is_some()).count();
        format!(
            "{}: {not_accepted} of {} cells short of the target ({lost} without sets to the horizon)",
            stopped.as_deref().unwrap_or("the splitting stopped"),
            cells.len()
        )
    });
    let verdict = if let Some(v) = goal_verdict {
        v
    } else if sys.goals.is_empty() {
        SystemVerdict::NoGoal
    } else if leaves
        .iter()
        .all(|l| l.failure.is_none() && l.decided.iter().all(|d| *d == Some(true)))
    {
        SystemVerdict::Proved
    } else {
        let r = reason
            .clone()
            .unwrap_or_else(|| format!("{not_accepted} cells leave a goal undecided"));
        SystemVerdict::Unknown {
            reason: match &unflown {
                Some(u) => format!("{r}; {u}"),
                None => r,
            },
        }
    };
    let reach = SystemReach {
        system: sys.name.clone(),
        verdict,
        instants: leaf_hull(&leaves, sys.dim(), |l| &l.instants),
        periods: leaf_hull(&leaves, sys.dim(), |l| &l.periods),
        boxes: leaves.len(),
        covered,
        order: s.order,
        network_error: mode,
        seconds: 0.0,
        leaves,
        measures,
        flights: Vec::new(),
    };
    AdaptiveReach {
        reach,
        cells,
        target_ratio: a.target_ratio,
        sampled: [lo, hi],
        band,
        ratio,
        met,
        reason,
        stopped,
        rounds,
        flown,
        unflown: unflown_note,
    }
}

/// Join the results of the shards `0..n` of one adaptive run (`AdaptiveSettings::shard`,
/// the same system, settings and flights) into the result of the unsharded run: the
/// cells of every shard in id order, and the hulls, ratio and verdicts over them.
/// `rounds` is the most of any shard, `flown` and `seconds` their sums, a goal missed by
/// a flight the first shard's.
///
/// The result is the one-process run's (but `seconds`) or an error: each shard's cells
/// depend on their own boxes only as long as nothing outside them stopped the
/// splitting, so a shard that stopped early (its deadline, its budget, a goal refuted on
/// the sets) is refused, and so are shards whose cells together pass the leaf budget
/// (one process would have stopped cutting at it).
pub fn merge_adaptive(
    sys: &System,
    s: &SystemReachSettings,
    a: &AdaptiveSettings,
    parts: Vec<AdaptiveReach>,
) -> Result<AdaptiveReach, SystemReachError> {
    let Some(first) = parts.first() else {
        return Err(SystemReachError::Setting("no shards to merge".into()));
    };
    let (range, band) = (first.sampled, first.band);
    if let Some(k) = parts
        .iter()
        .position(|p| p.sampled != range || p.band != band)
    {
        return Err(SystemReachError::Setting(format!(
            "shard {k} has the band {:?} from flights over {:?}, shard 0 {band:?} from {range:?}: the shards are of different runs",
            parts[k].band, parts[k].sampled
        )));
    }
    if let Some((k, why)) = parts
        .iter()
        .enumerate()
        .find_map(|(k, p)| p.stopped.as_ref().map(|w| (k, w)))
    {
        return Err(SystemReachError::Setting(format!(
            "shard {k} stopped splitting early ({why}): one process would have cut other cells, so the merge would not be its result; rerun that shard with a longer --timeout or a larger --max-leaves (it resumes from its checkpoint), or run the set in one process"
        )));
    }
    let total: usize = parts.iter().map(|p| p.cells.len()).sum();
    if total > s.max_boxes {
        return Err(SystemReachError::Setting(format!(
            "the shards have {total} cells together, more than the budget of {} leaves: one process would have stopped cutting at the budget; run every shard again with --max-leaves {total} or more",
            s.max_boxes
        )));
    }
    let mut ids: Vec<&str> = parts
        .iter()
        .flat_map(|p| p.cells.iter().map(|c| c.id.as_str()))
        .collect();
    ids.sort_unstable();
    if let Some(w) = ids.windows(2).find(|w| w[0] == w[1]) {
        return Err(SystemReachError::Setting(format!(
            "cell {} is in two shards: the shards are of different runs",
            w[0]
        )));
    }
    let sampled = first.reach.measures.iter().map(|m| m.sampled).collect();
    let mode = first.reach.network_error;
    let unflown = first.unflown.clone();
    let goal_verdict = parts
        .iter()
        .map(|p| &p.reach.verdict)
        .find(|v| matches!(v, SystemVerdict::Violated(SystemViolation { .. })))
        .cloned();
    let stopped = parts.iter().find_map(|p| p.stopped.clone());
    let rounds = parts.iter().map(|p| p.rounds).max().unwrap_or(0);
    let flown = parts.iter().map(|p| p.flown).sum();
    let seconds = parts.iter().map(|p| p.reach.seconds).sum();
    let cells = parts
        .into_iter()
        .flat_map(|p| p.cells.into_iter().zip(p.reach.leaves))
        .collect();
    let mut r = assemble(
        sys,
        s,
        a,
        Joined {
            cells,
            sampled,
            range,
            band,
            goal_verdict,
            stopped,
            unflown,
            rounds,
            flown,
            mode,
        },
    );
    r.reach.seconds = seconds;
    Ok(r)
}

/// The parameter whose range moves `m` at the horizon most over the box `b`: per
/// parameter of nonzero width, two flights from the box's centre with that parameter at
/// its ends, `|m(upper) - m(lower)|`. `None` when a flight fails or nothing moves.
fn measure_split(
    sys: &System,
    net: &Network,
    b: &[Interval],
    m: &crate::taylor::Measure,
) -> Option<usize> {
    let eval = controller(net);
    let centre: Vec<f64> = b.iter().map(|v| 0.5 * (v.lo + v.hi)).collect();
    let at = |x0: &[f64]| -> Option<f64> {
        let f = fly(sys, &eval, x0, 1).ok()?;
        f.states.last().map(|x| m.at(x))
    };
    let mut best: Option<(f64, usize)> = None;
    for j in (0..b.len()).filter(|&j| b[j].hi > b[j].lo) {
        let (mut p, mut q) = (centre.clone(), centre.clone());
        p[j] = b[j].lo;
        q[j] = b[j].hi;
        let effect = (at(&q)? - at(&p)?).abs();
        if effect.is_finite() && best.is_none_or(|(e, _)| effect > e) {
            best = Some((effect, j));
        }
    }
    best.filter(|(e, _)| *e > 0.0).map(|(_, j)| j)
}
