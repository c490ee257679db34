//! The system-file reachability run: settings checked, falsification by simulated
//! flights, the network-error ladder on the whole set, the refinement, the verdict.

use super::flight::{fly_box, past};
use super::network::controller;
use super::refine::{bisect_sensitive, progress, refine, Frontier};
use super::result::{SystemLeaf, SystemReach, SystemVerdict};
use super::settings::{
    Measure, MeasureRange, NetworkError, SystemReachError, SystemReachSettings,
    NETWORK_ERROR_LADDER,
};
use crate::taylor::SystemViolation;

use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use samara_nn::Network;
use samara_num::Interval;
use samara_system::sim::{fly, fly_until, goals_hold, SimError, SystemFlight};
use samara_system::System;
use std::time::Instant;

/// The starts of the falsification flights: the initial box's centre, its corners (up
/// to 64 of them) and random points.
pub fn starts(sys: &System, n: usize, seed: u64) -> Vec<Vec<f64>> {
    let init = &sys.init;
    let mut out = vec![init.iter().map(|(l, h)| 0.5 * (l + h)).collect::<Vec<_>>()];
    let free: Vec<usize> = (0..init.len()).filter(|&i| init[i].0 < init[i].1).collect();
    let corners = if free.len() <= 6 {
        1usize << free.len()
    } else {
        64
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    for c in 0..corners {
        let mut x: Vec<f64> = init.iter().map(|(l, _)| *l).collect();
        for (b, &i) in free.iter().enumerate() {
            let hi = if free.len() <= 6 {
                (c >> b) & 1 == 1
            } else {
                rng.gen_bool(0.5)
            };
            x[i] = if hi { init[i].1 } else { init[i].0 };
        }
        out.push(x);
    }
    while out.len() < n {
        out.push(init.iter().map(|(l, h)| rng.gen_range(*l..=*h)).collect());
    }
    out
}

/// Sound reachable sets of `sys` under the controller `net`, and the verdict on the
/// file's goals.
pub fn reach_system(
    sys: &System,
    net: &Network,
    s: &SystemReachSettings,
) -> Result<SystemReach, SystemReachError> {
    let t0 = Instant::now();
    let (s, deadline) = checked_settings(sys, net, s, t0)?;
    let s = &s;
    // Falsification first.
    let eval = controller(net);
    let Falsified {
        flights: ok_flights,
        violation,
        unflown,
    } = falsify(sys, net, s, deadline)?;
    let init: Vec<Interval> = sys
        .init
        .iter()
        .map(|&(l, h)| Interval { lo: l, hi: h })
        .collect();
    let mut leaves: Vec<SystemLeaf> = Vec::new();
    let mut mode = s.network_error.unwrap_or(NetworkError::Interval);
    let mut run_s = s.clone();
    let mut verdict = if let Some(v) = violation {
        // The sets are still computed once (for the figure), without refinement.
        let leaf = fly_box(sys, net, &init, s, mode, deadline);
        leaves.push(leaf);
        v
    } else {
        // The whole initial set first, in each mode of the ladder until one decides
        // (without goals: until one keeps its enclosure to the horizon); else the
        // sub-boxes are flown in the mode that got furthest.
        let mut root: Option<SystemLeaf> = None;
        if s.network_error.is_none() {
            let mut best: Option<(usize, NetworkError, SystemReachSettings, SystemLeaf)> = None;
            for (m, cap) in NETWORK_ERROR_LADDER {
                let mut rs = s.clone();
                if let Some(k) = cap {
                    rs.order = rs.order.min(k);
                    rs.flow.order = rs.order as u32;
                }
                let l = fly_box(sys, net, &init, &rs, m, deadline);
                let done = l.decided.contains(&Some(false)) || l.settled();
                let p = progress(&l, sys);
                if done {
                    best = Some((usize::MAX, m, rs, l));
                    break;
                }
                if best.as_ref().is_none_or(|(bp, ..)| p >= *bp) {
                    best = Some((p, m, rs, l));
                }
                if past(deadline) {
                    break;
                }
            }
            if let Some((_, m, rs, l)) = best {
                mode = m;
                run_s = rs;
                root = Some(l);
            }
        }
        // Without a root flight (a fixed network-error mode), the whole set is cut into
        // as many sub-boxes as there are worker threads at once, so that no core idles
        // while one flies the whole set.
        let frontier = match root.take() {
            Some(l) => Frontier::Flown(l),
            None => {
                let k = rayon::current_num_threads().clamp(1, s.max_boxes);
                let mut boxes = vec![init.clone()];
                while boxes.len() < k {
                    let b = boxes.remove(0);
                    let (a, c) = bisect_sensitive(sys, net, &b, &init, sys.steps());
                    boxes.push(a);
                    boxes.push(c);
                }
                Frontier::Boxes(boxes)
            }
        };
        let r = refine(sys, net, &init, &run_s, mode, deadline, frontier);
        leaves = r.leaves;
        let mut reason = None;
        let mut violation_from_sets = None;
        if let Some((g, centre)) = r.refuted {
            // The sets show a sub-box missing the goal entirely at some instant:
            // every flight from it misses it; its centre's flight is the witness.
            match fly(sys, &eval, &centre, 10) {
                Ok(f) if goals_hold(sys, &f).iter().any(|h| !h) => {
                    violation_from_sets = Some(SystemVerdict::Violated(SystemViolation {
                        initial: centre,
                        goal: g,
                    }));
                }
                _ => {
                    reason = Some(format!(
                        "the enclosure of a sub-box lies outside the goal `{g}`, but no simulated flight from the starts tried missed it"
                    ));
                }
            }
        } else if r.unsettled > 0 {
            let lost = leaves.iter().filter(|l| l.failure.is_some()).count();
            reason = Some(if r.timed_out {
                format!(
                    "timeout after {:.1} s with {} sub-boxes undecided",
                    t0.elapsed().as_secs_f64(),
                    r.unsettled
                )
            } else if lost > 0 {
                format!(
                    "{lost} of {} sub-boxes lost their enclosure ({}) within the budget of {} sub-boxes (raise --max-leaves)",
                    leaves.len(),
                    leaves.iter().find_map(|l| l.failure.clone()).unwrap_or_default(),
                    s.max_boxes
                )
            } else {
                format!(
                    "{} of {} sub-boxes leave a goal undecided within the budget of {} sub-boxes (raise --max-leaves)",
                    r.unsettled,
                    leaves.len(),
                    s.max_boxes
                )
            });
        }
        match (violation_from_sets, reason) {
            (Some(v), _) => v,
            // Without goals the sets are the result; a sub-box that stops early says so
            // in its `failure`.
            _ if sys.goals.is_empty() => SystemVerdict::NoGoal,
            (None, Some(r)) => SystemVerdict::Unknown {
                reason: match &unflown {
                    Some(u) => format!("{r}; {u}"),
                    None => r,
                },
            },
            (None, None) => SystemVerdict::Proved,
        }
    };
    if matches!(verdict, SystemVerdict::Proved) && leaves.iter().any(|l| l.failure.is_some()) {
        verdict = SystemVerdict::Unknown {
            reason: "an enclosure was lost".into(),
        };
    }
    let instants = leaf_hull(&leaves, sys.dim(), |l| &l.instants);
    let covered = coverage(&init, &leaves, sys.steps());
    let periods = leaf_hull(&leaves, sys.dim(), |l| &l.periods);
    let measures = measure_ranges(&s.measures, &leaves, &ok_flights, covered);
    Ok(SystemReach {
        system: sys.name.clone(),
        verdict,
        instants,
        periods,
        boxes: leaves.len(),
        covered,
        order: run_s.order,
        network_error: mode,
        seconds: t0.elapsed().as_secs_f64(),
        leaves,
        measures,
        flights: ok_flights,
    })
}

/// The checks every run makes before flying anything (the network fits the system, the
/// order, the budget), the settings with the flow's order set, and the deadline of
/// `s.timeout` counted from `t0`.
pub(crate) fn checked_settings(
    sys: &System,
    net: &Network,
    s: &SystemReachSettings,
    t0: Instant,
) -> Result<(SystemReachSettings, Option<Instant>), SystemReachError> {
    if !sys.fits_controller(net.n_inputs(), net.n_outputs()) {
        return Err(SystemReachError::Shape {
            n_in: net.n_inputs(),
            n_out: net.n_outputs(),
            obs: sys.n_observed(),
            reads: sys.n_net_outputs,
        });
    }
    if !(1..=8).contains(&s.order) {
        return Err(SystemReachError::Setting(format!(
            "the Taylor-model order must be 1 to 8 (got {}); 3-5 is usual",
            s.order
        )));
    }
    if s.max_boxes == 0 {
        return Err(SystemReachError::Setting(
            "the sub-box budget must be at least 1".into(),
        ));
    }
    let mut s = s.clone();
    s.flow.order = s.order as u32;
    // The budget also bounds each sub-box's flight (one wide network can take minutes
    // per box), not only the splitting rounds.
    let deadline = s.timeout.deadline_from(t0);
    Ok((s, deadline))
}

/// The falsification flights of a run: the flights that finished, the first that
/// misses a goal (as the verdict), and why a flight could not be finished (the first).
pub(crate) struct Falsified {
    pub(crate) flights: Vec<(Vec<f64>, SystemFlight)>,
    pub(crate) violation: Option<SystemVerdict>,
    pub(crate) unflown: Option<String>,
}

/// Fly the falsification starts ([`starts`]: `s.samples` of them, seeded by `s.seed`)
/// in parallel and look for a goal they miss.
pub(crate) fn falsify(
    sys: &System,
    net: &Network,
    s: &SystemReachSettings,
    deadline: Option<Instant>,
) -> Result<Falsified, SystemReachError> {
    let eval = controller(net);
    let flights: Vec<(Vec<f64>, Result<SystemFlight, SimError>)> = starts(sys, s.samples, s.seed)
        .into_par_iter()
        .map(|x0| {
            let f = fly_until(sys, &eval, &x0, 10, deadline);
            (x0, f)
        })
        .collect();
    let mut ok_flights = Vec::with_capacity(flights.len());
    let mut violation = None;
    // A flight the simulator cannot finish (its step collapsed on a switch, or the
    // budget ran out) witnesses nothing; the sets do not need it.
    let mut unflown: Option<String> = None;
    for (x0, f) in flights {
        let f = match f {
            Ok(f) => f,
            Err(e @ (SimError::StepCollapse { .. } | SimError::Timeout { .. })) => {
                unflown.get_or_insert_with(|| format!("the flight from {x0:?} stopped: {e}"));
                continue;
            }
            Err(e) => return Err(SystemReachError::Simulation(e.to_string())),
        };
        if violation.is_none() {
            if let Some(gi) = goals_hold(sys, &f).iter().position(|h| !h) {
                violation = Some(SystemVerdict::Violated(SystemViolation {
                    initial: x0.clone(),
                    goal: sys.goals[gi].text.clone(),
                }));
            }
        }
        ok_flights.push((x0, f));
    }
    Ok(Falsified {
        flights: ok_flights,
        violation,
        unflown,
    })
}

/// The hull over `leaves` of one of their rows of boxes (`instants` or `periods`), up to
/// the shortest leaf's rows.
pub(crate) fn leaf_hull(
    leaves: &[SystemLeaf],
    dim: usize,
    rows: impl Fn(&SystemLeaf) -> &Vec<Vec<[f64; 2]>>,
) -> Vec<Vec<[f64; 2]>> {
    let n = leaves.iter().map(|l| rows(l).len()).min().unwrap_or(0);
    (0..n)
        .map(|k| {
            (0..dim)
                .map(|i| {
                    leaves
                        .iter()
                        .fold([f64::INFINITY, f64::NEG_INFINITY], |a, l| {
                            let v = rows(l)[k][i];
                            [a[0].min(v[0]), a[1].max(v[1])]
                        })
                })
                .collect()
        })
        .collect()
}

/// Each measure over the sets at the horizon (hull over the sub-boxes, when every
/// sub-box has sets there) and over the flights' final states.
pub(crate) fn measure_ranges(
    measures: &[Measure],
    leaves: &[SystemLeaf],
    flights: &[(Vec<f64>, SystemFlight)],
    covered: f64,
) -> Vec<MeasureRange> {
    let span = |it: &mut dyn Iterator<Item = [f64; 2]>| {
        it.fold(None, |a: Option<[f64; 2]>, v| {
            Some(a.map_or(v, |a| [a[0].min(v[0]), a[1].max(v[1])]))
        })
    };
    measures
        .iter()
        .enumerate()
        .map(|(j, m)| {
            let all = covered == 1.0 && leaves.iter().all(|l| l.end_measures.len() > j);
            let enclosure = if all {
                span(&mut leaves.iter().map(|l| l.end_measures[j]))
            } else {
                None
            };
            let sampled = span(&mut flights.iter().filter_map(|(_, f)| {
                f.states.last().map(|x| {
                    let v = m.at(x);
                    [v, v]
                })
            }));
            let ratio = match (enclosure, sampled) {
                (Some(e), Some(s)) if s[1] > s[0] => Some((e[1] - e[0]) / (s[1] - s[0])),
                _ => None,
            };
            MeasureRange {
                name: m.name.clone(),
                enclosure,
                sampled,
                ratio,
            }
        })
        .collect()
}

/// The fraction of `init` (by volume over its parameters of nonzero width) whose
/// leaves have sets at all `steps + 1` control instants.
/// Exactly 1 when every leaf does (then `instants` runs to the horizon).
pub(crate) fn coverage(init: &[Interval], leaves: &[SystemLeaf], steps: usize) -> f64 {
    let whole =
        |l: &SystemLeaf| l.failure.is_none() && l.stopped_at.is_none() && l.instants.len() > steps;
    if leaves.iter().all(whole) {
        return 1.0;
    }
    covered_volume(init, leaves, steps).min(1.0)
}

/// The volume share of `init` (over its parameters of nonzero width) of the `leaves`
/// with sets at all `steps + 1` control instants, summed: [`coverage`] for leaves that
/// need not tile the whole set (a shard's).
pub(crate) fn covered_volume(init: &[Interval], leaves: &[SystemLeaf], steps: usize) -> f64 {
    let whole =
        |l: &&SystemLeaf| l.failure.is_none() && l.stopped_at.is_none() && l.instants.len() > steps;
    leaves
        .iter()
        .filter(whole)
        .map(|l| {
            l.init
                .iter()
                .zip(init)
                .filter(|(_, b)| b.hi > b.lo)
                .map(|(v, b)| (v[1] - v[0]) / (b.hi - b.lo))
                .product::<f64>()
        })
        .fold(0.0, |a, v| a + v)
}
