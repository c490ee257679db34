//! The driver: the initial partition, each sub-box flown over the horizon (network
//! enclosure, then validated flow, period by period), refinement of the sub-boxes worth
//! cutting, and the result.

use crate::flow::{self, flow_period};
use crate::netstep::SetController;
use crate::sampling::{simulate_samples, Sample};
use crate::settings::{ReachError, ReachSettings};
use crate::verdict::{decide, first_violation, leaf_goal, Verdict};
use crate::zonotope::Zonotope;
use rayon::prelude::*;
use samara_nn::Network;
use samara_num::{Interval, Scalar};
use samara_plant::Plant;
use serde::Serialize;
use std::time::Instant;

/// The enclosure of one sub-box at one control instant.
#[derive(Clone, Debug, Serialize)]
pub struct StepSet {
    /// Time.
    pub t: f64,
    /// Interval hull of the six physical states (v_xp, v_yp, omega, theta, x, y).
    pub bbox: Vec<[f64; 2]>,
    /// Enclosure of `x + y` at `t`.
    pub x_plus_y: [f64; 2],
    /// Enclosure of `x + y` over the period ending at `t` (at `t = 0`: the start).
    pub x_plus_y_period: [f64; 2],
    /// Control held over the period starting at `t` (absent at the horizon).
    pub ex: Option<[f64; 2]>,
    /// The zonotope (only with `keep_sets`).
    #[serde(skip)]
    pub set: Option<Zonotope>,
}

/// A sub-box of the initial set and its enclosures.
#[derive(Clone, Debug, Serialize)]
pub struct Leaf {
    /// The sub-box, one interval per state.
    pub init: Vec<[f64; 2]>,
    /// Indices of the states that are parameters (the first generators, in order).
    pub params: Vec<usize>,
    /// One record per control instant reached (all of them unless `failure`).
    pub steps: Vec<StepSet>,
    /// Why the enclosure stopped early, if it did.
    pub failure: Option<String>,
    /// Validated steps taken (Taylor, fallback).
    pub flow_steps: (usize, usize),
    /// Largest deviation of the network enclosure over the flight.
    pub max_dev: f64,
    #[serde(skip)]
    z: Zonotope,
    #[serde(skip)]
    h: f64,
}

/// The result of a run.
#[derive(Clone, Debug, Serialize)]
pub struct ReachResult {
    /// The verdict on the goal.
    pub verdict: Verdict,
    /// Enclosure of `x + y` at the horizon (hull over sub-boxes).
    pub final_x_plus_y: [f64; 2],
    /// Range of `x + y` at the horizon over the simulated samples.
    pub sampled_x_plus_y: [f64; 2],
    /// Sub-boxes.
    pub leaves: Vec<Leaf>,
    /// Wall time in seconds.
    pub seconds: f64,
    /// Simulated trajectories (falsification and figures).
    #[serde(skip)]
    pub samples: Vec<Sample>,
}

impl ReachResult {
    /// Number of sub-problems (sub-boxes) in the final partition.
    pub fn subproblems(&self) -> usize {
        self.leaves.len()
    }

    /// Width ratio of the enclosure of `x + y` at the horizon to the sampled range.
    pub fn width_ratio(&self) -> f64 {
        (self.final_x_plus_y[1] - self.final_x_plus_y[0])
            / (self.sampled_x_plus_y[1] - self.sampled_x_plus_y[0])
    }
}

fn iv(x: Interval) -> [f64; 2] {
    [x.lo, x.hi]
}

fn initial_leaf(init_all: &[(f64, f64)]) -> Leaf {
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
    Leaf {
        init: init_all.iter().map(|&(a, b)| [a, b]).collect(),
        params,
        steps: Vec::new(),
        failure: None,
        flow_steps: (0, 0),
        max_dev: 0.0,
        z,
        h: f64::INFINITY,
    }
}

/// Split a leaf (current zonotope included) along parameter `j` (index into `params`).
fn split_leaf(l: &Leaf, j: usize) -> (Leaf, Leaf) {
    let (za, zb) = l.z.split(j);
    let p = l.params[j];
    let mid = 0.5 * (l.init[p][0] + l.init[p][1]);
    let mut a = l.clone();
    let mut b = l.clone();
    a.init[p][1] = mid;
    b.init[p][0] = mid;
    a.z = za;
    b.z = zb;
    (a, b)
}

struct Ctx<'a> {
    plant: &'a Plant,
    ctrl: SetController,
    s: &'a ReachSettings,
    min_width: Vec<f64>,
}

impl Ctx<'_> {
    fn can_split(&self, l: &Leaf, j: usize) -> bool {
        let p = l.params[j];
        l.init[p][1] - l.init[p][0] > 2.0 * self.min_width[p]
    }

    /// The parameter along which the flown sub-box `l` is most worth splitting.
    fn split_dir(&self, l: &Leaf) -> Option<usize> {
        (0..l.params.len())
            .filter(|&j| self.can_split(l, j))
            .max_by(|&a, &b| {
                // A sub-box that lost its enclosure splits along the parameter that
                // moves the dynamics' states (v_xp, v_yp, omega, theta) most; otherwise
                // along the one that moves x + y most.
                let w = |j: usize| match l.failure {
                    Some(_) => l.z.gens[j][..4].iter().map(|v| v.abs()).sum::<f64>(),
                    None => (l.z.gens[j][4] + l.z.gens[j][5]).abs(),
                };
                w(a).total_cmp(&w(b))
            })
    }

    /// Advance `l` by one period from instant `k` (a failure is recorded in the leaf).
    fn advance(&self, l: &mut Leaf, k: usize) {
        let t = k as f64 * self.s.period;
        let u = self.ctrl.over(&l.z);
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
                let xy = iv(l.z.x_plus_y());
                l.steps.push(StepSet {
                    t,
                    bbox: l.z.bbox().iter().map(|x| iv(*x)).collect(),
                    x_plus_y: xy,
                    x_plus_y_period: xy,
                    ex,
                    set: self.s.keep_sets.then(|| l.z.clone()),
                });
            }
        }
        // Augment with the control row.
        let d = l.z.dim();
        let mut za = Zonotope {
            c: l.z.c.clone(),
            gens: Vec::with_capacity(l.z.gens.len() + 1),
            n_param: l.z.n_param,
        };
        za.c.push(u.cst);
        for (g, a) in l.z.gens.iter().zip(&u.coef) {
            let mut ng = g.clone();
            ng.push(*a);
            za.gens.push(ng);
        }
        let mut dg = vec![0.0; d + 1];
        dg[d] = u.dev;
        za.gens.push(dg);
        match flow_period(self.plant, &za, self.s.period, &self.s.flow, &mut l.h) {
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
                l.z = z;
            }
            Err(flow::FlowFailure::NoEnclosure { t: tf }) => {
                l.failure = Some(format!(
                    "no validated enclosure at t = {:.4} (set too wide or the flow leaves the model's domain)",
                    t + tf
                ));
            }
        }
    }

    /// Whether a flown sub-box is worth splitting: it failed, its final `x + y` carries
    /// more than `tol_noise` of noise, or the goal is undecided on it.
    fn needs_refinement(&self, l: &Leaf, tol_noise: f64) -> bool {
        if l.failure.is_some() {
            return true;
        }
        let nr = l.z.noise_radius();
        if nr[4] + nr[5] > tol_noise {
            return true;
        }
        match &self.s.goal {
            Some(g) => leaf_goal(l, g, self.s).is_none(),
            None => false,
        }
    }

    /// Fly one sub-box over the whole horizon.
    fn run(&self, mut l: Leaf, steps: usize) -> Leaf {
        for k in 0..steps {
            self.advance(&mut l, k);
            if l.failure.is_some() {
                break;
            }
        }
        l
    }
}

/// Compute the reachable sets of the closed loop `plant` + `net` from `s.init`, and
/// decide `s.goal`.
pub fn reach(net: &Network, s: &ReachSettings) -> Result<ReachResult, ReachError> {
    let t0 = Instant::now();
    let steps = s.validate(net)?;
    let plant = Plant::new(s.model);
    // Falsification first: it is cheap and gives the figure its trajectories.
    let samples = simulate_samples(&plant, net, s, s.samples);
    let violation = s
        .goal
        .as_ref()
        .and_then(|g| first_violation(&samples, g, s));
    let ctx = Ctx {
        plant: &plant,
        ctrl: SetController::new(net, s.clip),
        s,
        min_width: s
            .init
            .iter()
            .map(|(a, b)| (b - a) * s.min_fraction)
            .collect(),
    };
    // Initial partition along the widest parameter.
    let root = initial_leaf(&s.init);
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
                let j = (0..l.params.len()).max_by(|&a, &b| {
                    let w = |j: usize| l.init[l.params[j]][1] - l.init[l.params[j]][0];
                    w(a).total_cmp(&w(b))
                });
                match j {
                    Some(j) => {
                        let (a, b) = split_leaf(&l, j);
                        vec![a, b]
                    }
                    None => vec![l],
                }
            })
            .collect();
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
    // Noise allowed in a sub-box's final x + y: a tenth of the sampled spread, capped.
    let tol_noise = s.max_noise.min(0.1 * sampled_width).max(1e-6);
    let mut done: Vec<Leaf> = Vec::new();
    let mut pending = leaves;
    while !pending.is_empty() {
        let results: Vec<Leaf> = pending.into_par_iter().map(|l| ctx.run(l, steps)).collect();
        pending = Vec::new();
        let mut total = done.len() + results.len();
        for l in results {
            let want = ctx.needs_refinement(&l, tol_noise);
            match ctx.split_dir(&l) {
                // A sub-box that lost its enclosure may still be split when the budget
                // is spent, up to a quarter more: better a few more sub-boxes than an
                // unknown.
                Some(j)
                    if want
                        && (total < s.max_leaves
                            || l.failure.is_some() && total < s.max_leaves + s.max_leaves / 4) =>
                {
                    let mut init: Vec<(f64, f64)> = l.init.iter().map(|r| (r[0], r[1])).collect();
                    let p = l.params[j];
                    let mid = 0.5 * (init[p].0 + init[p].1);
                    let mut a = init.clone();
                    a[p].1 = mid;
                    init[p].0 = mid;
                    pending.push(initial_leaf(&a));
                    pending.push(initial_leaf(&init));
                    total += 1;
                }
                _ => done.push(l),
            }
        }
    }
    let any_failed = done.iter().any(|l| l.failure.is_some());
    done.sort_by(|a, b| {
        a.init
            .iter()
            .map(|x| x[0])
            .collect::<Vec<_>>()
            .partial_cmp(&b.init.iter().map(|x| x[0]).collect::<Vec<_>>())
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut fin = Interval {
        lo: f64::INFINITY,
        hi: f64::NEG_INFINITY,
    };
    for l in &done {
        if l.failure.is_none() {
            let r = l.steps.last().expect("final record").x_plus_y;
            fin = fin.hull(&Interval { lo: r[0], hi: r[1] });
        }
    }
    if any_failed {
        fin = Interval::entire();
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
    let verdict = decide(s, violation, &done, fin);
    Ok(ReachResult {
        verdict,
        final_x_plus_y: iv(fin),
        sampled_x_plus_y: iv(sampled),
        leaves: done,
        seconds: t0.elapsed().as_secs_f64(),
        samples,
    })
}
