//! The refinement: sub-boxes whose enclosure is lost or whose goal is undecided are
//! cut in two and flown again from `t = 0`, in parallel, within the budget.

use super::flight::{empty_leaf, fly_box, past};
use super::network::controller;
use super::result::SystemLeaf;
use super::settings::{NetworkError, SystemReachSettings};

use samara_nn::Network;
use samara_num::Interval;
use samara_system::sim::fly;
use samara_system::System;
use std::time::Instant;

/// Where the refinement starts: a flight of the whole set already made (the ladder's
/// best), or boxes still to fly.
pub(crate) enum Frontier {
    Flown(SystemLeaf),
    Boxes(Vec<Vec<Interval>>),
}

/// The state [`refine`] shares between its tasks and ends with: every sub-box flown
/// (sorted by their initial boxes at the end), how many of them are not settled,
/// whether the deadline stopped the splitting, and a goal some sub-box's sets lie
/// entirely outside of (its text and the sub-box's centre).
pub(crate) struct RefineState {
    pub(crate) leaves: Vec<SystemLeaf>,
    pub(crate) unsettled: usize,
    pub(crate) timed_out: bool,
    pub(crate) refuted: Option<(String, Vec<f64>)>,
    /// Sub-boxes made so far (flown or waiting), against the budget.
    pub(crate) boxes: usize,
}

/// Fly the frontier's boxes and split every sub-box that is neither settled (reaches
/// the horizon with every goal proved) nor refuted, as long as the budget and the
/// deadline allow. Asynchronous: a sub-box's halves are flown as soon as it ends, on
/// whichever worker is free, not after the whole round (one slow sub-box no longer holds
/// the others' halves back). A goal refuted by some sub-box's sets stops the splitting;
/// boxes not started by then are not flown.
pub(crate) fn refine(
    sys: &System,
    net: &Network,
    init: &[Interval],
    s: &SystemReachSettings,
    mode: NetworkError,
    deadline: Option<Instant>,
    frontier: Frontier,
) -> RefineState {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Mutex;
    let stop = AtomicBool::new(false);
    let state = Mutex::new(RefineState {
        leaves: Vec::new(),
        unsettled: 0,
        timed_out: false,
        refuted: None,
        boxes: match &frontier {
            Frontier::Flown(_) => 1,
            Frontier::Boxes(b) => b.len(),
        },
    });
    /// What every task of the scope shares.
    #[derive(Clone, Copy)]
    struct Ctx<'s> {
        sys: &'s System,
        net: &'s Network,
        init: &'s [Interval],
        s: &'s SystemReachSettings,
        mode: NetworkError,
        deadline: Option<Instant>,
        stop: &'s AtomicBool,
        state: &'s Mutex<RefineState>,
    }
    // A flown sub-box: keep it, or split it and fly the halves.
    fn handle<'s>(l: SystemLeaf, scope: &rayon::Scope<'s>, ctx: &'s Ctx<'s>) {
        let Ctx {
            sys,
            init,
            s,
            deadline,
            stop,
            state,
            ..
        } = *ctx;
        let mut st = state.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(gi) = l.decided.iter().position(|d| *d == Some(false)) {
            if st.refuted.is_none() {
                let centre: Vec<f64> = l.init.iter().map(|v| 0.5 * (v[0] + v[1])).collect();
                st.refuted = Some((sys.goals[gi].text.clone(), centre));
            }
            stop.store(true, Ordering::SeqCst);
        }
        if l.settled() {
            st.leaves.push(l);
            return;
        }
        let timed_out = past(deadline);
        if stop.load(Ordering::SeqCst) || timed_out || st.boxes + 1 > s.max_boxes {
            st.timed_out |= timed_out;
            st.unsettled += 1;
            st.leaves.push(l);
            return;
        }
        st.boxes += 1;
        drop(st);
        let b: Vec<Interval> = l
            .init
            .iter()
            .map(|v| Interval { lo: v[0], hi: v[1] })
            .collect();
        let k = l.instants.len().saturating_sub(1);
        let (a, c) = bisect_sensitive(sys, ctx.net, &b, init, k);
        for half in [a, c] {
            scope.spawn(move |sc| fly_and_handle(half, sc, ctx));
        }
    }
    fn fly_and_handle<'s>(b: Vec<Interval>, scope: &rayon::Scope<'s>, ctx: &'s Ctx<'s>) {
        if ctx.stop.load(Ordering::SeqCst) {
            // Kept as a leaf without sets, so that the leaves still tile the initial
            // set and the hulls over them (which end where the shortest leaf ends) claim
            // nothing for the part of the set never flown.
            let mut st = ctx.state.lock().unwrap_or_else(|e| e.into_inner());
            st.unsettled += 1;
            st.leaves.push(empty_leaf(
                ctx.sys,
                &b,
                Some("not flown: a goal was refuted on another sub-box first".into()),
            ));
            return;
        }
        let l = fly_box(ctx.sys, ctx.net, &b, ctx.s, ctx.mode, ctx.deadline);
        handle(l, scope, ctx);
    }
    let ctx = Ctx {
        sys,
        net,
        init,
        s,
        mode,
        deadline,
        stop: &stop,
        state: &state,
    };
    let ctx = &ctx;
    rayon::scope(|sc| match frontier {
        Frontier::Flown(l) => handle(l, sc, ctx),
        Frontier::Boxes(boxes) => {
            for b in boxes {
                sc.spawn(move |sc| fly_and_handle(b, sc, ctx));
            }
        }
    });
    let mut st = state.into_inner().unwrap_or_else(|e| e.into_inner());
    st.leaves.sort_by(|p, q| {
        p.init
            .iter()
            .flatten()
            .zip(q.init.iter().flatten())
            .map(|(a, b)| a.total_cmp(b))
            .find(|o| o.is_ne())
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    st
}

/// How far a sub-box's flight got, in control instants: where its goals became
/// undecidable or its enclosure was lost, else the whole horizon.
pub(crate) fn progress(l: &SystemLeaf, sys: &System) -> usize {
    match (l.stopped_at, &l.failure) {
        (_, Some(_)) => l.instants.len().saturating_sub(1),
        (Some(t), None) => (t / sys.period).round() as usize,
        (None, None) => sys.steps(),
    }
}

/// Cut `b` in two along the parameter whose range moves the state most at control
/// instant `k` (where a sub-box's sets ended; the horizon for the first cut): per
/// parameter of nonzero width, two flights from the box's centre with that parameter at
/// its ends; the effect of a parameter is the sum over the states of its flights'
/// difference, each state scaled by the spread of all these flights in it (so units
/// cancel). A parameter that barely matters (a height interval of 1e-4 beside an
/// angular rate of 0.02) is then not cut only because its relative width ties. Falls
/// back to [`bisect`] where a flight fails or nothing moves.
pub(crate) fn bisect_sensitive(
    sys: &System,
    net: &Network,
    b: &[Interval],
    init: &[Interval],
    k: usize,
) -> (Vec<Interval>, Vec<Interval>) {
    let eval = controller(net);
    let k = k.clamp(1, sys.steps().max(1));
    let centre: Vec<f64> = b.iter().map(|v| 0.5 * (v.lo + v.hi)).collect();
    let row = |x0: &[f64]| -> Option<Vec<f64>> {
        let f = fly(sys, &eval, x0, 1).ok()?;
        f.states.get(k).cloned()
    };
    let mut pairs: Vec<(usize, Vec<f64>, Vec<f64>)> = Vec::new();
    for j in 0..b.len() {
        if b[j].hi <= b[j].lo {
            continue;
        }
        let (mut lo, mut hi) = (centre.clone(), centre.clone());
        lo[j] = b[j].lo;
        hi[j] = b[j].hi;
        match (row(&lo), row(&hi)) {
            (Some(p), Some(q)) => pairs.push((j, p, q)),
            _ => return bisect(b, init),
        }
    }
    let spread: Vec<f64> = (0..sys.dim())
        .map(|i| {
            let (mn, mx) = pairs
                .iter()
                .flat_map(|(_, p, q)| [p[i], q[i]])
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, c), v| {
                    (a.min(v), c.max(v))
                });
            mx - mn
        })
        .collect();
    let mut best: Option<(f64, usize)> = None;
    for (j, p, q) in &pairs {
        let effect: f64 = (0..sys.dim())
            .filter(|&i| spread[i] > 0.0 && spread[i].is_finite())
            .map(|i| (p[i] - q[i]).abs() / spread[i])
            .sum();
        if effect.is_finite() && best.is_none_or(|(e, _)| effect > e) {
            best = Some((effect, *j));
        }
    }
    match best {
        Some((e, j)) if e > 0.0 => cut_at(b, j),
        _ => bisect(b, init),
    }
}

/// Cut `b` in two along the parameter widest relative to the initial set `init`.
fn bisect(b: &[Interval], init: &[Interval]) -> (Vec<Interval>, Vec<Interval>) {
    let rel = |i: usize| {
        let w0 = init[i].hi - init[i].lo;
        if w0 > 0.0 {
            (b[i].hi - b[i].lo) / w0
        } else {
            0.0
        }
    };
    let j = (0..b.len())
        .max_by(|&p, &q| rel(p).total_cmp(&rel(q)))
        .unwrap_or(0);
    cut_at(b, j)
}

/// `b` cut in two at the midpoint of parameter `j`.
pub(crate) fn cut_at(b: &[Interval], j: usize) -> (Vec<Interval>, Vec<Interval>) {
    let m = 0.5 * (b[j].lo + b[j].hi);
    let mut lo = b.to_vec();
    let mut hi = b.to_vec();
    lo[j].hi = m;
    hi[j].lo = m;
    (lo, hi)
}
