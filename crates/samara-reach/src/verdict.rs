//! The goal on the final sets, falsification by simulated trajectories, and the verdict.

use crate::result::GliderViolation;
pub use crate::result::Verdict;
use crate::result::{Flown, Leaf};
use crate::sampling::Sample;
use crate::settings::{Goal, ReachSettings};
use samara_num::Interval;
use std::borrow::Borrow;

/// The goal on one sub-box: `Some(true)` every enclosure inside the band, `Some(false)`
/// some enclosure entirely outside it, `None` undecided.
pub(crate) fn leaf_goal(l: &Leaf, g: &Goal, s: &ReachSettings) -> Option<bool> {
    let mut all_in = true;
    for st in &l.steps {
        let r = match g.from {
            None if st.t >= s.horizon - 1e-9 => st.x_plus_y,
            None => continue,
            Some(f) if st.t >= f + s.period - 1e-9 => st.x_plus_y_period,
            Some(f) if st.t >= f - 1e-9 => st.x_plus_y,
            Some(_) => continue,
        };
        if r[0] > g.ystar || r[1] < -g.ystar {
            return Some(false);
        }
        if !(-g.ystar <= r[0] && r[1] <= g.ystar) {
            all_in = false;
        }
    }
    if l.failure.is_some() {
        return None;
    }
    if all_in {
        Some(true)
    } else {
        None
    }
}

/// Falsification: the first simulated trajectory that misses the goal `g`, as a
/// `Violated` verdict.
pub(crate) fn first_violation(samples: &[Sample], g: &Goal, s: &ReachSettings) -> Option<Verdict> {
    for smp in samples {
        let bad = match g.from {
            None => {
                let x = smp.states.last().expect("states");
                ((x[4] + x[5]).abs() > g.ystar).then_some((s.horizon, x[4] + x[5]))
            }
            Some(f) => smp
                .txy
                .iter()
                .find(|(t, v)| *t >= f - 1e-12 && v.abs() > g.ystar)
                .map(|&(t, v)| (t, v)),
        };
        if let Some((t, v)) = bad {
            return Some(Verdict::Violated(GliderViolation {
                initial: smp.initial.clone(),
                t,
                x_plus_y: v,
            }));
        }
    }
    None
}

/// Re-check a `Violated` verdict concretely: the trajectory from its initial state (a
/// point of the initial set) is flown again exactly as the run's samples are
/// ([`simulate_one`](crate::sampling::simulate_one)) and must miss the goal where and
/// as the verdict says, bit for bit (`first_violation`, the run's own test). Used by
/// `samara merge reach` on the counterexample its shards carry.
pub fn recheck_violation(
    net: &samara_nn::Network,
    s: &ReachSettings,
    v: &Verdict,
) -> Result<(), String> {
    let Verdict::Violated(GliderViolation { initial, .. }) = v else {
        return Err(format!("a `{}` verdict is not a counterexample", v.name()));
    };
    let Some(g) = &s.goal else {
        return Err("the run has no goal to violate".into());
    };
    if initial.len() != s.init.len()
        || !initial
            .iter()
            .zip(&s.init)
            .all(|(x, (lo, hi))| lo <= x && x <= hi)
    {
        return Err(format!(
            "its initial state {initial:?} is not a point of the initial set"
        ));
    }
    let plant = samara_plant::Plant::new(s.model);
    let smp = crate::sampling::simulate_one(&plant, net, s, initial)
        .ok_or_else(|| format!("the flight from {initial:?} fails"))?;
    match first_violation(&[smp], g, s) {
        Some(w) if &w == v => Ok(()),
        Some(w) => Err(format!(
            "the flight from it misses the goal elsewhere ({})",
            w.reason()
        )),
        None => Err(format!("the flight from {initial:?} meets the goal")),
    }
}

/// Where a run lost its enclosure, in words, if a sub-box did: how many sub-boxes lost
/// theirs, and for the first (in the final partition's order) which one (its number and
/// initial box), in which control period (the last instant it reached and the next) and
/// why. `None` when every sub-box is enclosed up to the horizon. A run without a goal
/// that lost its enclosure has no result over the horizon: the CLI exits 1 with this.
pub fn lost_enclosure<'a>(
    leaves: impl IntoIterator<Item = &'a Leaf>,
    s: &ReachSettings,
) -> Option<String> {
    let leaves: Vec<&Leaf> = leaves.into_iter().collect();
    let lost: Vec<usize> = (0..leaves.len())
        .filter(|&i| leaves[i].failure.is_some())
        .collect();
    let &first = lost.first()?;
    let l = leaves[first];
    let names = samara_plant::STATE_NAMES;
    let bounds: Vec<String> = l
        .params
        .iter()
        .map(|&j| {
            format!(
                "{} in [{}, {}]",
                names.get(j).copied().unwrap_or("?"),
                l.init[j][0],
                l.init[j][1]
            )
        })
        .collect();
    let reached = l.steps.last().map_or(0.0, |st| st.t);
    let period = (reached / s.period).round() as usize + 1;
    Some(format!(
        "the enclosure was lost before the horizon t = {} in {} of {} sub-boxes; the first, sub-box {} of {} ({}), in control period {period} (t in [{reached}, {}]): {}",
        s.horizon,
        lost.len(),
        leaves.len(),
        first + 1,
        leaves.len(),
        if bounds.is_empty() {
            "the initial point".to_string()
        } else {
            bounds.join(", ")
        },
        reached + s.period,
        l.failure.as_deref().unwrap_or("")
    ))
}

/// The verdict of a run: no goal, the falsifying trajectory if there is one, unknown if
/// a sub-box lost its enclosure, proved if every sub-box's enclosures lie in the band
/// (the goal [`leaf_goal`] found on each flown sub-box; `fin`: the hull of `x + y` at the
/// horizon, for the message), unknown otherwise.
pub(crate) fn decide<F: Borrow<Flown>>(
    s: &ReachSettings,
    violation: Option<Verdict>,
    done: &[F],
    fin: Interval,
) -> Verdict {
    match (&s.goal, violation) {
        (None, _) => Verdict::NoGoal,
        (Some(_), Some(v)) => v,
        (Some(_), None) => {
            if let Some(why) = lost_enclosure(done.iter().map(|f| &f.borrow().leaf), s) {
                Verdict::Unknown { reason: why }
            } else if done.iter().all(|f| f.borrow().goal == Some(true)) {
                Verdict::Proved
            } else {
                Verdict::Unknown {
                    reason: format!(
                        "the enclosure of x + y ({:.4}, {:.4}) is not inside the goal band and no simulated trajectory violates it; refine with more sub-boxes (--max-leaves) or smaller thresholds",
                        fin.lo, fin.hi
                    ),
                }
            }
        }
    }
}
