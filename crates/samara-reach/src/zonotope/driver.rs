//! The driver: the initial partition, each sub-box flown over the horizon (network
//! enclosure, then validated flow, period by period), refinement of the sub-boxes worth
//! cutting, and the result.
//!
//! [`reach`] is the composition of the steps that [`parts`](crate::parts) runs apart:
//! [`prepare`] (settings, samples, initial pieces), the refinement rounds ([`refine`]
//! over [`Prepared`]'s flights of every piece) and [`finish`] (order and verdict). A
//! sharded run and its merge call the very same functions.

use super::flow::{self, flow_period};
use super::netstep::SetController;
use super::set::Zonotope;
use crate::result::Verdict;
use crate::result::{Flown, Leaf, ReachResult, StepSet};
use crate::sampling::{simulate_samples, Sample};
use crate::settings::{ReachError, ReachSettings};
use crate::verdict::{decide, first_violation, leaf_goal};
use rayon::prelude::*;
use samara_nn::Network;
use samara_num::{Interval, Scalar};
use samara_plant::Plant;
use std::borrow::Borrow;
use std::convert::Infallible;
use std::ops::Range;
use std::time::Instant;

fn iv(x: Interval) -> [f64; 2] {
    [x.lo, x.hi]
}

/// The name of initial piece `i`.
pub fn piece_key(i: usize) -> String {
    format!("{i}:")
}

/// The name of a half of sub-box `key`: `half` 0 the lower, 1 the upper.
pub fn child_key(key: &str, half: u8) -> String {
    format!("{key}{half}")
}

/// A sub-box not flown yet, or in flight: its record, its current set and the flow's
/// step size.
#[derive(Clone)]
struct Node {
    key: String,
    leaf: Leaf,
    z: Zonotope,
    h: f64,
}

/// The sub-box `init_all` (every state's interval), its set at `t = 0`.
fn initial_node(key: String, init_all: &[(f64, f64)]) -> Node {
    // The sets hold the six physical states (E never acts on them).
    let init = &init_all[..6];
    let params: Vec<usize> = (0..init.len()).filter(|&i| init[i].1 > init[i].0).collect();
    let c: Vec<f64> = init.iter().map(|(a, b)| 0.5 * (a + b)).collect();
    let mut gens = Vec::new();
    let mut err = vec![0.0; init.len()];
    for &p in &params {
        let mut g = vec![0.0; init.len()];
        g[p] = 0.5 * (init[p].1 - init[p].0);
        // c +- g covers [a, b] up to rounding; cover that with a tiny box.
        err[p] = ((init[p].0.abs() + init[p].1.abs()) * f64::EPSILON).next_up();
        gens.push(g);
    }
    let mut z = Zonotope {
        c,
        gens,
        n_param: params.len(),
    };
    z.add_box(&err);
    Node {
        key,
        leaf: Leaf {
            init: init_all.iter().map(|&(a, b)| [a, b]).collect(),
            params,
            steps: Vec::new(),
            failure: None,
            flow_steps: (0, 0),
            max_dev: 0.0,
        },
        z,
        h: f64::INFINITY,
    }
}

/// Split a sub-box (current zonotope included) along parameter `j` (index into
/// `params`): the initial partition.
fn split_node(l: &Node, j: usize) -> (Node, Node) {
    let (za, zb) = l.z.split(j);
    let p = l.leaf.params[j];
    let mid = 0.5 * (l.leaf.init[p][0] + l.leaf.init[p][1]);
    let mut a = l.clone();
    let mut b = l.clone();
    a.leaf.init[p][1] = mid;
    b.leaf.init[p][0] = mid;
    a.z = za;
    b.z = zb;
    a.key = child_key(&l.key, 0);
    b.key = child_key(&l.key, 1);
    (a, b)
}

/// The halves of a flown sub-box worth splitting, along its `split` parameter, each
/// flown again from `t = 0`.
fn halves(f: &Flown) -> (Node, Node) {
    let j = f.split.expect("split along a parameter");
    let mut init: Vec<(f64, f64)> = f.leaf.init.iter().map(|r| (r[0], r[1])).collect();
    let p = f.leaf.params[j];
    let mid = 0.5 * (init[p].0 + init[p].1);
    let mut a = init.clone();
    a[p].1 = mid;
    init[p].0 = mid;
    (
        initial_node(child_key(&f.key, 0), &a),
        initial_node(child_key(&f.key, 1), &init),
    )
}

/// What every part of a run computes alike (the settings checked, the simulated
/// samples and what is drawn from them), and its initial pieces.
pub struct Prepared<'a> {
    s: &'a ReachSettings,
    plant: Plant,
    ctrl: SetController,
    min_width: Vec<f64>,
    steps: usize,
    pieces: Vec<Node>,
    /// The simulated trajectories (falsification, the sampled range, the figure).
    pub samples: Vec<Sample>,
    /// The first sampled trajectory that misses the goal, as a verdict.
    pub violation: Option<Verdict>,
    /// Range of `x + y` at the horizon over the samples.
    pub sampled_x_plus_y: [f64; 2],
    /// Noise allowed in a sub-box's final `x + y` before it is worth splitting.
    pub tol_noise: f64,
}

/// Check the settings, simulate the samples (falsification first: it is cheap and gives
/// the figure its trajectories) and cut the initial set into its pieces, named by their
/// place ([`piece_key`]): everything a run does before it flies anything.
pub fn prepare<'a>(net: &Network, s: &'a ReachSettings) -> Result<Prepared<'a>, ReachError> {
    let steps = s.validate(net)?;
    let plant = Plant::new(s.model);
    let samples = simulate_samples(&plant, net, s, s.samples);
    let violation = s
        .goal
        .as_ref()
        .and_then(|g| first_violation(&samples, g, s));
    let min_width = s
        .init
        .iter()
        .map(|(a, b)| (b - a) * s.min_fraction)
        .collect();
    // Initial partition along the widest parameter.
    let root = initial_node(piece_key(0), &s.init);
    let mut leaves = vec![root];
    let pieces = if s.initial_splits > 0 {
        s.initial_splits
    } else {
        let w = s.init[..6]
            .iter()
            .map(|(a, b)| b - a)
            .fold(0.0f64, f64::max);
        // Leave room in the budget for one split of every other parameter.
        let others = s.init[..6]
            .iter()
            .filter(|(a, b)| b > a)
            .count()
            .saturating_sub(1);
        ((w / s.auto_piece).ceil().max(1.0) as usize)
            .next_power_of_two()
            .min((s.max_leaves >> others.min(20)).max(1))
    };
    for _ in 0..pieces.max(1).ilog2() {
        leaves = leaves
            .into_iter()
            .flat_map(|l| {
                let j = (0..l.leaf.params.len()).max_by(|&a, &b| {
                    let w = |j: usize| {
                        l.leaf.init[l.leaf.params[j]][1] - l.leaf.init[l.leaf.params[j]][0]
                    };
                    w(a).total_cmp(&w(b))
                });
                match j {
                    Some(j) => {
                        let (a, b) = split_node(&l, j);
                        vec![a, b]
                    }
                    None => vec![l],
                }
            })
            .collect();
    }
    // The pieces, named by their place.
    for (i, l) in leaves.iter_mut().enumerate() {
        l.key = piece_key(i);
    }
    let sampled = samples.iter().fold(
        Interval {
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
        },
        |acc, smp| {
            let x = smp.states.last().expect("states");
            acc.hull(&Interval::point(x[4] + x[5]))
        },
    );
    // Noise allowed in a sub-box's final x + y: a tenth of the sampled spread, capped.
    let sampled_width = (sampled.hi - sampled.lo).max(0.0);
    let tol_noise = s.max_noise.min(0.1 * sampled_width).max(1e-6);
    Ok(Prepared {
        s,
        plant,
        ctrl: SetController::new(net, s.clip),
        min_width,
        steps,
        pieces: leaves,
        samples,
        violation,
        sampled_x_plus_y: iv(sampled),
        tol_noise,
    })
}

impl Prepared<'_> {
    /// Number of initial pieces.
    pub fn pieces(&self) -> usize {
        self.pieces.len()
    }

    /// The refinement rounds ([`refine`]) over the pieces `range`, the pieces outside
    /// counted as one sub-box each: every round's sub-boxes flown in parallel, `seen`
    /// shown each round's flights in order. Returns the final sub-boxes in the rounds'
    /// order.
    pub(crate) fn refine_pieces(
        &self,
        range: Range<usize>,
        mut seen: impl FnMut(&[Flown]),
    ) -> Vec<Flown> {
        let start: Vec<Node> = self.pieces[range.clone()].to_vec();
        let others = self.pieces.len() - range.len();
        let done = refine(
            start,
            others,
            self.s.max_leaves,
            |round: Vec<Node>| {
                let flown: Vec<Flown> = round.into_par_iter().map(|n| self.run(n)).collect();
                seen(&flown);
                Ok::<_, Infallible>(flown)
            },
            halves,
        );
        match done {
            Ok(done) => done,
            Err(never) => match never {},
        }
    }

    /// Fly one sub-box over the whole horizon and judge it: the goal on it, whether it
    /// is worth splitting and along which parameter.
    fn run(&self, mut n: Node) -> Flown {
        for k in 0..self.steps {
            self.advance(&mut n, k);
            if n.leaf.failure.is_some() {
                break;
            }
        }
        let goal = self
            .s
            .goal
            .as_ref()
            .and_then(|g| leaf_goal(&n.leaf, g, self.s));
        // Worth splitting: it failed, its final x + y carries more than `tol_noise` of
        // noise, or the goal is undecided on it.
        let want = n.leaf.failure.is_some() || {
            let nr = n.z.noise_radius();
            nr[4] + nr[5] > self.tol_noise || self.s.goal.is_some() && goal.is_none()
        };
        let split = self.split_dir(&n);
        Flown {
            key: n.key,
            want,
            split,
            goal,
            leaf: n.leaf,
        }
    }

    fn can_split(&self, l: &Leaf, j: usize) -> bool {
        let p = l.params[j];
        l.init[p][1] - l.init[p][0] > 2.0 * self.min_width[p]
    }

    /// The parameter along which the flown sub-box `n` is most worth splitting.
    fn split_dir(&self, n: &Node) -> Option<usize> {
        (0..n.leaf.params.len())
            .filter(|&j| self.can_split(&n.leaf, j))
            .max_by(|&a, &b| {
                // A sub-box that lost its enclosure splits along the parameter that
                // moves the dynamics' states (v_xp, v_yp, omega, theta) most; otherwise
                // along the one that moves x + y most.
                let w = |j: usize| match n.leaf.failure {
                    Some(_) => n.z.gens[j][..4].iter().map(|v| v.abs()).sum::<f64>(),
                    None => (n.z.gens[j][4] + n.z.gens[j][5]).abs(),
                };
                w(a).total_cmp(&w(b))
            })
    }

    /// Advance `n` by one period from instant `k` (a failure is recorded in its leaf).
    fn advance(&self, n: &mut Node, k: usize) {
        let l = &mut n.leaf;
        let t = k as f64 * self.s.period;
        let u = self.ctrl.over(&n.z);
        l.max_dev = l.max_dev.max(u.dev);
        // The control held over the period starting at t.
        let spread = u.coef.iter().map(|c| c.abs()).sum::<f64>();
        let ex = Some([
            (u.cst - u.dev - spread).max(u.range.lo),
            (u.cst + u.dev + spread).min(u.range.hi),
        ]);
        match l.steps.last_mut() {
            // The record at t was made at the end of the previous period.
            Some(last) if k > 0 => last.ex = ex,
            _ => {
                let xy = iv(n.z.x_plus_y());
                l.steps.push(StepSet {
                    t,
                    bbox: n.z.bbox().iter().map(|x| iv(*x)).collect(),
                    x_plus_y: xy,
                    x_plus_y_period: xy,
                    ex,
                    set: self.s.keep_sets.then(|| n.z.clone()),
                });
            }
        }
        // Augment with the control row.
        let d = n.z.dim();
        let mut za = Zonotope {
            c: n.z.c.clone(),
            gens: Vec::with_capacity(n.z.gens.len() + 1),
            n_param: n.z.n_param,
        };
        za.c.push(u.cst);
        for (g, a) in n.z.gens.iter().zip(&u.coef) {
            let mut ng = g.clone();
            ng.push(*a);
            za.gens.push(ng);
        }
        let mut dg = vec![0.0; d + 1];
        dg[d] = u.dev;
        za.gens.push(dg);
        match flow_period(&self.plant, &za, self.s.period, &self.s.flow, &mut n.h) {
            Ok((nz, xyp, st)) => {
                l.flow_steps.0 += st.taylor_steps;
                l.flow_steps.1 += st.fallback_steps;
                let mut z = Zonotope {
                    c: nz.c[..d].to_vec(),
                    gens: nz.gens.iter().map(|g| g[..d].to_vec()).collect(),
                    n_param: nz.n_param,
                };
                // Drop noise generators that only acted on the control row.
                let np = z.n_param;
                let mut idx = 0;
                z.gens.retain(|g| {
                    idx += 1;
                    idx <= np || g.iter().any(|v| *v != 0.0)
                });
                let bb = z.bbox();
                let xy = z.x_plus_y();
                l.steps.push(StepSet {
                    t: (k + 1) as f64 * self.s.period,
                    bbox: bb.iter().map(|x| iv(*x)).collect(),
                    x_plus_y: iv(xy),
                    x_plus_y_period: iv(xyp.hull(&xy)),
                    ex: None,
                    set: self.s.keep_sets.then(|| z.clone()),
                });
                n.z = z;
            }
            Err(flow::FlowFailure::NoEnclosure { t: tf }) => {
                l.failure = Some(format!(
                    "no validated enclosure at t = {:.4} (set too wide or the flow leaves the model's domain)",
                    t + tf
                ));
            }
        }
    }
}

/// The driver's refinement rounds: fly `start`, then split every flown sub-box that is
/// worth it and can be, while the sub-boxes (`others` more counted outside) number fewer
/// than `max_leaves`, and fly the halves, until none is left. A sub-box that lost its
/// enclosure may still be split when the budget is spent, up to a quarter more: better a
/// few more sub-boxes than an unknown. Returns the final sub-boxes in the rounds' order
/// (sort them with [`finish`]). `fly` flies a round in order (one process or a part: the
/// flight; a merge: the recorded flights, or an error naming a missing one); `children`
/// gives the halves of a sub-box to split.
pub fn refine<U, F: Borrow<Flown>, E>(
    start: Vec<U>,
    others: usize,
    max_leaves: usize,
    mut fly: impl FnMut(Vec<U>) -> Result<Vec<F>, E>,
    mut children: impl FnMut(&Flown) -> (U, U),
) -> Result<Vec<F>, E> {
    let mut done: Vec<F> = Vec::new();
    let mut pending = start;
    while !pending.is_empty() {
        let results = fly(pending)?;
        pending = Vec::new();
        let mut total = others + done.len() + results.len();
        for f in results {
            let l = f.borrow();
            match l.split {
                Some(_)
                    if l.want
                        && (total < max_leaves
                            || l.leaf.failure.is_some() && total < max_leaves + max_leaves / 4) =>
                {
                    let (a, b) = children(l);
                    pending.push(a);
                    pending.push(b);
                    total += 1;
                }
                _ => done.push(f),
            }
        }
    }
    Ok(done)
}

/// The end of a run over the final sub-boxes `done` (as [`refine`] left them): `done`
/// sorted by the lower ends of the sub-boxes, the hull of `x + y` at the horizon (the
/// whole line if a sub-box lost its enclosure) and the verdict (`violation`:
/// [`Prepared::violation`]).
pub fn finish<F: Borrow<Flown>>(
    s: &ReachSettings,
    violation: Option<Verdict>,
    done: &mut [F],
) -> (Verdict, [f64; 2]) {
    let any_failed = done.iter().any(|f| f.borrow().leaf.failure.is_some());
    done.sort_by(|a, b| {
        let lo = |f: &F| {
            f.borrow()
                .leaf
                .init
                .iter()
                .map(|x| x[0])
                .collect::<Vec<_>>()
        };
        lo(a)
            .partial_cmp(&lo(b))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut fin = Interval {
        lo: f64::INFINITY,
        hi: f64::NEG_INFINITY,
    };
    for f in done.iter() {
        let l = &f.borrow().leaf;
        if l.failure.is_none() {
            let r = l.steps.last().expect("final record").x_plus_y;
            fin = fin.hull(&Interval { lo: r[0], hi: r[1] });
        }
    }
    if any_failed {
        fin = Interval::entire();
    }
    (decide(s, violation, done, fin), iv(fin))
}

/// Compute the reachable sets of the closed loop `plant` + `net` from `s.init`, and
/// decide `s.goal`: [`prepare`], every piece refined ([`refine`]) and [`finish`].
pub fn reach(net: &Network, s: &ReachSettings) -> Result<ReachResult, ReachError> {
    let t0 = Instant::now();
    let prep = prepare(net, s)?;
    let mut done = prep.refine_pieces(0..prep.pieces(), |_| {});
    let (verdict, final_x_plus_y) = finish(s, prep.violation.clone(), &mut done);
    Ok(ReachResult {
        verdict,
        final_x_plus_y,
        sampled_x_plus_y: prep.sampled_x_plus_y,
        leaves: done.into_iter().map(|f| f.leaf).collect(),
        seconds: t0.elapsed().as_secs_f64(),
        samples: prep.samples,
    })
}
