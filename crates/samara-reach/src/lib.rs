//! Sound reachable sets of the network-controlled Alsomitra glider.
//!
//! The closed loop is the same as in simulation (`samara-sim`): at each control instant
//! the network reads the state, its (clipped) output is held for one period while the
//! plant flies. Here both halves run on sets:
//! - [`netstep`]: the controller output over a zonotope, kept affine in the zonotope's
//!   generators (CROWN over the zonotope);
//! - [`flow`]: validated Taylor integration of the plant (Lohner-style, on zonotopes,
//!   with the plant's own equations run on Taylor series of intervals);
//! - [`settings`]: the run's settings, the goal, and their validation;
//! - [`driver`]: the initial set as a box of parameters, cut into sub-boxes along the
//!   widest parameter, each sub-box flown over the whole horizon (sub-boxes in parallel
//!   with `rayon`); a sub-box that lost its enclosure, carries too much noise in its
//!   final `x + y` or leaves the goal undecided is cut in two along the parameter that
//!   moves the dynamics (lost enclosure) or `x + y` most, and both halves are flown
//!   again from `t = 0`, within the sub-box budget;
//! - [`sampling`]: simulated trajectories (falsification first, figures) and the check
//!   that enclosures contain them;
//! - [`verdict`]: the goal on the final sets and the verdict;
//! - [`figure`](mod@figure): the x-y figure of a run.
//!
//! Verdicts: `Proved` only when every sub-box's enclosure satisfies the goal; `Violated`
//! only with a concrete simulated trajectory; `Unknown` with the reason otherwise.

#![warn(missing_docs)]

pub mod driver;
pub mod figure;
pub mod flow;
pub mod netstep;
pub mod sampling;
pub mod settings;
pub mod system;
pub mod tmflow;
pub mod verdict;
pub mod zonotope;

pub use driver::{reach, Leaf, ReachResult, StepSet};
pub use figure::figure;
pub use sampling::{check_containment, simulate_samples, Sample};
pub use settings::{Goal, ReachError, ReachSettings, MAX_INIT, MAX_PERIODS};
pub use verdict::Verdict;
pub use zonotope::Zonotope;

/// A run cut into parts computed apart and put back together exactly (`samara reach
/// --shard I/N`, `samara merge reach`).
///
/// [`reach`] cuts the initial set into pieces (its initial partition along the widest
/// parameter), flies every sub-box over the horizon and splits the ones worth it, round by
/// round, within one budget of sub-boxes (`max_leaves`) counted over all pieces. A
/// sub-box's flight, and whether it is worth splitting, depend only on the sub-box and on
/// what every part computes alike: the settings and the simulated samples (the
/// falsification, the sampled range and the noise threshold drawn from it). Only the
/// budget ties the pieces together.
///
/// So a part ([`Prepared::fly`]) flies a contiguous range of the pieces and refines them
/// with the driver's rule, counting every piece outside its range as one sub-box (the
/// fewest it can be), and records every sub-box it flew ([`Flown`], named by
/// [`piece_key`] and [`child_key`]). [`refine`] then replays the driver's rounds over all
/// pieces on the recorded flights, and [`finish`] orders the final sub-boxes and decides
/// as the driver does: the result is the one-process result, sub-box for sub-box.
///
/// A part counts at most as many sub-boxes as the whole run at the same point of the
/// rounds (until it makes a split the run does not), so it splits every sub-box the run
/// splits; once the budget runs out during the refinement, a part may go on splitting
/// where the run stops (it cannot see the other parts' sub-boxes), and those extra
/// sub-boxes are recorded but not used. Every sub-box the replay needs was recorded,
/// except in one case: a half that only the part created loses its enclosure and is split
/// on the budget's extra quarter, leaving the part less of that quarter than the run
/// uses. [`refine`] then names the missing sub-box instead of guessing.
///
/// The per-sub-box code mirrors the driver's (which keeps its own, unchanged); the CLI's
/// tests compare merged parts with [`reach`] on the same settings.
pub mod parts {
    use crate::driver::StepSet;
    use crate::flow::{self, flow_period};
    use crate::netstep::SetController;
    use crate::sampling::{simulate_samples, Sample};
    use crate::settings::{Goal, ReachError, ReachSettings};
    use crate::verdict::{first_violation, Verdict};
    use crate::zonotope::Zonotope;
    use rayon::prelude::*;
    use samara_nn::Network;
    use samara_num::{Interval, Scalar};
    use samara_plant::Plant;
    use samara_report::{Curve, TrajectoryFigure};
    use serde::Serialize;
    use std::borrow::Borrow;
    use std::ops::Range;

    /// Largest number of boxes drawn in a figure (as [`figure`](crate::figure)).
    const MAX_FIGURE_BOXES: usize = 20_000;

    /// A sub-box of the initial set and its enclosures: the public fields of
    /// [`Leaf`](crate::Leaf), serialised the same way.
    #[derive(Clone, Debug, Serialize)]
    pub struct LeafRecord {
        /// The sub-box, one interval per state.
        pub init: Vec<[f64; 2]>,
        /// Indices of the states that are parameters.
        pub params: Vec<usize>,
        /// One record per control instant reached.
        pub steps: Vec<StepSet>,
        /// Why the enclosure stopped early, if it did.
        pub failure: Option<String>,
        /// Validated steps taken (Taylor, fallback).
        pub flow_steps: (usize, usize),
        /// Largest deviation of the network enclosure over the flight.
        pub max_dev: f64,
    }

    /// A flown sub-box: one node of a piece's refinement tree.
    #[derive(Clone, Debug)]
    pub struct Flown {
        /// Its name: [`piece_key`] of its piece, then one digit per split (see
        /// [`child_key`]).
        pub key: String,
        /// Whether it is worth splitting: it lost its enclosure, its final `x + y`
        /// carries too much noise, or the goal is undecided on it.
        pub want: bool,
        /// The parameter (index into `leaf.params`) it is split along, if it can be.
        pub split: Option<usize>,
        /// The goal on it: `Some(true)` every enclosure inside the band, `Some(false)`
        /// one entirely outside, `None` undecided or no goal.
        pub goal: Option<bool>,
        /// Its sub-box and enclosures.
        pub leaf: LeafRecord,
    }

    /// The name of initial piece `i`.
    pub fn piece_key(i: usize) -> String {
        format!("{i}:")
    }

    /// The name of a half of sub-box `key`: `half` 0 the lower, 1 the upper.
    pub fn child_key(key: &str, half: u8) -> String {
        format!("{key}{half}")
    }

    /// A sub-box not flown yet.
    #[derive(Clone)]
    struct Node {
        key: String,
        leaf: LeafRecord,
        z: Zonotope,
        h: f64,
    }

    fn iv(x: Interval) -> [f64; 2] {
        [x.lo, x.hi]
    }

    /// As the driver's `initial_leaf`.
    fn initial_node(key: String, init_all: &[(f64, f64)]) -> Node {
        let init = &init_all[..6];
        let params: Vec<usize> = (0..init.len()).filter(|&i| init[i].1 > init[i].0).collect();
        let c: Vec<f64> = init.iter().map(|(a, b)| 0.5 * (a + b)).collect();
        let mut gens = Vec::new();
        let mut err = vec![0.0; init.len()];
        for &p in &params {
            let mut g = vec![0.0; init.len()];
            g[p] = 0.5 * (init[p].1 - init[p].0);
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
            leaf: LeafRecord {
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

    /// As the driver's `split_leaf` (the initial partition).
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

    /// The driver's refinement rounds: fly `start`, then split every flown sub-box that
    /// is worth it and can be, while the sub-boxes (`others` more counted outside) number
    /// fewer than `max_leaves` (a quarter more for one that lost its enclosure), and fly
    /// the halves, until none is left. Returns the final sub-boxes in the rounds' order
    /// (sort them with [`finish`]). `fly` flies a round in order (a part: the flight; a
    /// merge: the recorded flights, or an error naming a missing one); `children` gives
    /// the halves of a sub-box to split.
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
                                || l.leaf.failure.is_some()
                                    && total < max_leaves + max_leaves / 4) =>
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

    /// The driver's end of a run over the final sub-boxes `done` (as [`refine`] left
    /// them): `done` sorted by the lower ends of the sub-boxes, the hull of `x + y` at
    /// the horizon (the whole line if a sub-box lost its enclosure) and the verdict
    /// (`violation`: [`Prepared::violation`]).
    pub fn finish<F: Borrow<Flown>>(
        s: &ReachSettings,
        violation: Option<Verdict>,
        done: &mut [F],
    ) -> (Verdict, [f64; 2]) {
        let any_failed = done.iter().any(|l| l.borrow().leaf.failure.is_some());
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
        // As the driver's `decide`.
        let verdict = match (&s.goal, violation) {
            (None, _) => Verdict::NoGoal,
            (Some(_), Some(v)) => v,
            (Some(_), None) => {
                if let Some(why) = done.iter().find_map(|f| f.borrow().leaf.failure.clone()) {
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
        };
        (verdict, iv(fin))
    }

    /// The goal on one flown sub-box (as the driver's `leaf_goal`).
    fn goal_on(l: &LeafRecord, g: &Goal, s: &ReachSettings) -> Option<bool> {
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

    /// What every part of a run computes alike, and its initial pieces.
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

    /// Check the settings, simulate the samples and cut the initial pieces, as
    /// [`reach`](crate::reach) does before it flies anything.
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
        let root = initial_node(piece_key(0), &s.init);
        let mut leaves = vec![root];
        let pieces = if s.initial_splits > 0 {
            s.initial_splits
        } else {
            let w = s.init[..6]
                .iter()
                .map(|(a, b)| b - a)
                .fold(0.0f64, f64::max);
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
        let sampled_width = samples
            .iter()
            .map(|smp| {
                let x = smp.states.last().expect("states");
                x[4] + x[5]
            })
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        let sampled_width = (sampled_width.1 - sampled_width.0).max(0.0);
        let tol_noise = s.max_noise.min(0.1 * sampled_width).max(1e-6);
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

        /// Fly the pieces `range` and refine them with the driver's rule (the pieces
        /// outside counted as one sub-box each); every sub-box flown, in flight order.
        pub fn fly(&self, range: Range<usize>) -> Vec<Flown> {
            let start: Vec<Node> = self.pieces[range.clone()].to_vec();
            let others = self.pieces.len() - range.len();
            let mut all: Vec<Flown> = Vec::new();
            let r: Result<Vec<Flown>, std::convert::Infallible> = refine(
                start,
                others,
                self.s.max_leaves,
                |batch: Vec<Node>| {
                    let flown: Vec<Flown> = batch.into_par_iter().map(|n| self.run(n)).collect();
                    all.extend(flown.iter().cloned());
                    Ok(flown)
                },
                |f| {
                    let j = f.split.expect("split along a parameter");
                    let mut init: Vec<(f64, f64)> =
                        f.leaf.init.iter().map(|r| (r[0], r[1])).collect();
                    let p = f.leaf.params[j];
                    let mid = 0.5 * (init[p].0 + init[p].1);
                    let mut a = init.clone();
                    a[p].1 = mid;
                    init[p].0 = mid;
                    (
                        initial_node(child_key(&f.key, 0), &a),
                        initial_node(child_key(&f.key, 1), &init),
                    )
                },
            );
            match r {
                Ok(_) => all,
                Err(never) => match never {},
            }
        }

        /// The sampled trajectories drawn in the figure and their legend entry, as
        /// [`figure`](crate::figure) picks them.
        pub fn figure_curves(&self) -> (Vec<Curve>, Option<String>) {
            let stub = crate::ReachResult {
                verdict: Verdict::NoGoal,
                final_x_plus_y: [0.0, 0.0],
                sampled_x_plus_y: self.sampled_x_plus_y,
                leaves: Vec::new(),
                seconds: 0.0,
                samples: self.samples.clone(),
            };
            let fig = crate::figure(&stub, "", None);
            (fig.curves, fig.group_label)
        }

        /// Fly one sub-box over the whole horizon and judge it (the driver's `run`,
        /// `needs_refinement` and `split_dir`).
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
                .and_then(|g| goal_on(&n.leaf, g, self.s));
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

        fn can_split(&self, l: &Node, j: usize) -> bool {
            let p = l.leaf.params[j];
            l.leaf.init[p][1] - l.leaf.init[p][0] > 2.0 * self.min_width[p]
        }

        fn split_dir(&self, l: &Node) -> Option<usize> {
            (0..l.leaf.params.len())
                .filter(|&j| self.can_split(l, j))
                .max_by(|&a, &b| {
                    let w = |j: usize| match l.leaf.failure {
                        Some(_) => l.z.gens[j][..4].iter().map(|v| v.abs()).sum::<f64>(),
                        None => (l.z.gens[j][4] + l.z.gens[j][5]).abs(),
                    };
                    w(a).total_cmp(&w(b))
                })
        }

        /// The driver's `advance`: one period from instant `k`.
        fn advance(&self, n: &mut Node, k: usize) {
            let l = &mut n.leaf;
            let t = k as f64 * self.s.period;
            let u = self.ctrl.over(&n.z);
            l.max_dev = l.max_dev.max(u.dev);
            let spread = u.coef.iter().map(|c| c.abs()).sum::<f64>();
            let ex = Some([
                (u.cst - u.dev - spread).max(u.range.lo),
                (u.cst + u.dev + spread).min(u.range.hi),
            ]);
            match l.steps.last_mut() {
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

    /// The figure of a merged run, as [`figure`](crate::figure) draws the one-process
    /// run: `leaves` the final sub-boxes in order, `curves` and `group_label` from
    /// [`Prepared::figure_curves`].
    pub fn figure(
        title: &str,
        verdict: &Verdict,
        leaves: &[&LeafRecord],
        curves: Vec<Curve>,
        group_label: Option<String>,
        band: Option<f64>,
    ) -> TrajectoryFigure {
        let total: usize = leaves.iter().map(|l| l.steps.len()).sum();
        let group = total.div_ceil(MAX_FIGURE_BOXES).max(1);
        let mut boxes = Vec::new();
        for chunk in leaves.chunks(group) {
            let steps = chunk.iter().map(|l| l.steps.len()).max().unwrap_or(0);
            for k in 0..steps {
                let mut b = (
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                );
                for l in chunk {
                    if let Some(st) = l.steps.get(k) {
                        let (x, y) = (st.bbox[4], st.bbox[5]);
                        b = (b.0.min(x[0]), b.1.max(x[1]), b.2.min(y[0]), b.3.max(y[1]));
                    }
                }
                if b.0.is_finite() && b.1.is_finite() && b.2.is_finite() && b.3.is_finite() {
                    boxes.push(b);
                }
            }
        }
        let mut fig = TrajectoryFigure::new(
            format!(
                "{title}: {} ({} sub-boxes; sets at control instants)",
                verdict.name(),
                leaves.len()
            ),
            curves,
        );
        fig.boxes = boxes;
        fig.band = band;
        fig.legend = false;
        fig.group_label = group_label;
        fig
    }
}
