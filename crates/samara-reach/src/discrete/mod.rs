//! Discrete-time systems (`next` updates, a mode set by `argmax` of the network's
//! outputs, networks chosen by the mode, per-mode tables of input values;
//! docs/system.md, "Discrete-time systems") on boxes.
//!
//! A *set* is a box of states with one mode value and the input choices that led to
//! it. At every step each set's network (the one of its current mode) is bounded over
//! the box by CROWN (`samara_bounds::symbolic`). The **sound argmax**: output `i` can be
//! the largest unless some output `j` has a positive lower bound of `o_j - o_i` over
//! the box, a bound on the *difference* (one backward pass of the objective
//! `e_j - e_i`), which keeps the outputs' shared hidden neurons correlated. Where more
//! than one output can win, the box is halved (along the state whose width weighs most
//! in the ambiguous differences) up to [`DiscreteSettings::max_depth`] times; a piece
//! still ambiguous branches into every possible new mode. Each new mode then branches
//! into the table values the [`Choice`] admits (all of them, or one). The states'
//! update is evaluated on intervals (outward rounded), so each new box contains the
//! image of its set.
//!
//! Verdicts: `Proved` when every set satisfies every goal at every checked instant;
//! `Violated` only with a concrete trajectory, simulated in f64 with the real networks
//! ([`simulate`]) and re-checked; `Unknown` with the reason otherwise (a set that meets
//! the unsafe region with no simulated trajectory that does, the set budget, the time
//! limit).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_bounds::pwl::PwlNet;
use samara_bounds::symbolic::{self, Objective};
use samara_nn::Network;
use samara_num::{Interval, Timeout};
use samara_system::{System, When};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Which of a table's listed values an input takes (ARCH-COMP's VerticalCAS strategies).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Choice {
    /// Every listed value (a branch per value): the sound quantification over the
    /// pilot's choices, which covers every strategy.
    All,
    /// The middle entry of the list (the first of the two middle ones for an even
    /// count): ARCH-COMP's "middle" strategy.
    Middle,
    /// The smallest value (VerticalCAS's worst case while the intruder is below, h < 0).
    Min,
    /// The largest value (the worst case while the intruder is above).
    Max,
}

impl Choice {
    /// Parse `all`, `middle`, `min` or `max`.
    pub fn parse(s: &str) -> Option<Choice> {
        Some(match s {
            "all" => Choice::All,
            "middle" => Choice::Middle,
            "min" => Choice::Min,
            "max" => Choice::Max,
            _ => return None,
        })
    }

    /// The indices of `row` this choice admits.
    pub fn indices(self, row: &[f64]) -> Vec<usize> {
        let by = |better: fn(f64, f64) -> bool| {
            let mut k = 0;
            for (i, v) in row.iter().enumerate() {
                if better(*v, row[k]) {
                    k = i;
                }
            }
            vec![k]
        };
        match self {
            Choice::All => (0..row.len()).collect(),
            Choice::Middle => vec![(row.len() - 1) / 2],
            Choice::Min => by(|a, b| a < b),
            Choice::Max => by(|a, b| a > b),
        }
    }
}

/// Settings of a discrete-time reachability run.
#[derive(Clone, Debug)]
pub struct DiscreteSettings {
    /// Which table values the inputs take.
    pub choice: Choice,
    /// Halvings of a set whose argmax is ambiguous, per step (default 12).
    pub max_depth: u32,
    /// Largest number of sets at one instant (default 20,000): beyond it, `Unknown`.
    pub max_sets: usize,
    /// Above this many sets at an instant (default 1,000), the sets of each mode are
    /// sorted by their centres and merged in consecutive groups into their hulls, down
    /// to half as many (sound: a hull contains its sets; the choices kept are the first
    /// set's).
    pub merge_at: usize,
    /// Simulated trajectories for falsification (default 200; 10 times as many are
    /// tried before a set that meets the unsafe region is reported `Unknown`).
    pub samples: usize,
    /// Seed of the samples.
    pub seed: u64,
    /// Time limit.
    pub timeout: Timeout,
}

impl Default for DiscreteSettings {
    fn default() -> Self {
        DiscreteSettings {
            choice: Choice::All,
            max_depth: 12,
            max_sets: 20_000,
            merge_at: 1_000,
            samples: 200,
            seed: 1,
            timeout: Timeout::default(),
        }
    }
}

/// Why a run could not start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DiscreteError {
    /// The system is continuous-time.
    #[error("the system is continuous-time (`x' = ...`); this engine takes `next` updates")]
    NotDiscrete,
    /// Wrong number of networks.
    #[error("the system needs {expected} network(s) ({why}), got {found}")]
    NetworkCount {
        /// Networks needed.
        expected: usize,
        /// Networks given.
        found: usize,
        /// Why that many.
        why: String,
    },
    /// A network's shape does not fit the system.
    #[error("network {index}: {found_in} inputs and {found_out} outputs; the system observes {want_in} values and reads {want_out} outputs")]
    Shape {
        /// Which network (0-based).
        index: usize,
        /// Its inputs.
        found_in: usize,
        /// Its outputs.
        found_out: usize,
        /// Inputs needed.
        want_in: usize,
        /// Outputs needed.
        want_out: usize,
    },
    /// A network is not piecewise linear.
    #[error("network {index}: {message}")]
    Unsupported {
        /// Which network.
        index: usize,
        /// Why.
        message: String,
    },
    /// A goal this engine does not check.
    #[error("goal `{0}`: discrete-time systems check `always` and `at end` goals only")]
    Goal(String),
}

/// The controllers of a discrete system: one network, or one per mode value.
pub struct Controllers {
    nets: Vec<Network>,
    pwl: Vec<PwlNet>,
}

impl Controllers {
    /// Check the networks against the system (count, shapes, piecewise linearity).
    pub fn new(sys: &System, nets: Vec<Network>) -> Result<Controllers, DiscreteError> {
        let Some(d) = &sys.discrete else {
            return Err(DiscreteError::NotDiscrete);
        };
        let (expected, why) = match &d.mode {
            Some(m) if m.networks_by => (
                m.values.len(),
                format!("one per value of the mode `{}`", m.name),
            ),
            _ => (1, "no `networks by`".into()),
        };
        if nets.len() != expected {
            return Err(DiscreteError::NetworkCount {
                expected,
                found: nets.len(),
                why,
            });
        }
        let mut pwl = Vec::new();
        for (index, n) in nets.iter().enumerate() {
            if !sys.fits_controller(n.n_inputs(), n.n_outputs()) {
                return Err(DiscreteError::Shape {
                    index,
                    found_in: n.n_inputs(),
                    found_out: n.n_outputs(),
                    want_in: sys.n_observed(),
                    want_out: sys.n_net_outputs,
                });
            }
            pwl.push(
                PwlNet::from_network(n).map_err(|e| DiscreteError::Unsupported {
                    index,
                    message: e.to_string(),
                })?,
            );
        }
        Ok(Controllers { nets, pwl })
    }

    fn index(&self, mode: Option<usize>) -> usize {
        if self.nets.len() > 1 {
            mode.unwrap_or(0)
        } else {
            0
        }
    }

    /// The network used in mode `mode`.
    pub fn network(&self, mode: Option<usize>) -> &Network {
        &self.nets[self.index(mode)]
    }
}

/// A box of states at one instant with its mode value and the input choices taken.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BoxSet {
    /// Lower corner.
    pub lo: Vec<f64>,
    /// Upper corner.
    pub hi: Vec<f64>,
    /// The mode's value (index), if the system has a mode.
    pub mode: Option<usize>,
    /// Per step so far, the index into each table input's row that was taken.
    pub choices: Vec<Vec<usize>>,
}

impl BoxSet {
    /// Whether a state (and mode) lies in the set (closed box).
    pub fn contains(&self, x: &[f64], mode: Option<usize>) -> bool {
        self.mode == mode
            && x.iter()
                .zip(self.lo.iter().zip(&self.hi))
                .all(|(v, (l, h))| l <= v && v <= h)
    }

    fn intervals(&self) -> Vec<Interval> {
        self.lo
            .iter()
            .zip(&self.hi)
            .map(|(l, h)| Interval::new(*l, *h))
            .collect()
    }
}

/// A simulated trajectory: the states, modes and inputs at instants `0..=N`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Trajectory {
    /// States at each instant.
    pub states: Vec<Vec<f64>>,
    /// Mode values at each instant.
    pub modes: Vec<Option<usize>>,
    /// Inputs applied over step `k` (one row fewer than the states).
    pub inputs: Vec<Vec<f64>>,
}

/// A simulated trajectory that breaks a goal of a discrete run (re-simulated in f64 with
/// the real networks).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DiscreteViolation {
    /// The trajectory.
    pub trajectory: Trajectory,
    /// The goal's text.
    pub goal: String,
    /// The first instant where it fails.
    pub step: usize,
}

/// The verdict of a discrete run: samara's one reach verdict ([`crate::ReachVerdict`]:
/// proved when every set satisfies every goal, violated with a trajectory, unknown with
/// the reason), so discrete, glider and system runs answer in one vocabulary.
pub type DiscreteVerdict = crate::result::ReachVerdict<DiscreteViolation>;

/// What a discrete run returns.
#[derive(Clone, Debug, Serialize)]
pub struct DiscreteResult {
    /// The verdict.
    pub verdict: DiscreteVerdict,
    /// The sets at each instant `0..=N` reached (fewer rows if the run stopped).
    pub sets: Vec<Vec<BoxSet>>,
    /// The hull of the states at each instant.
    pub hull: Vec<Vec<(f64, f64)>>,
    /// Halvings of ambiguous sets.
    pub splits: usize,
    /// Sets that branched into more than one new mode.
    pub mode_branches: usize,
    /// Wall time in seconds.
    pub elapsed_s: f64,
}

/// The index of the largest value, the lowest index on ties (the `argmax` of the
/// system language, as numpy's and MATLAB's `max`).
pub fn argmax(v: &[f64]) -> usize {
    let mut k = 0;
    for (i, x) in v.iter().enumerate() {
        if *x > v[k] {
            k = i;
        }
    }
    k
}

/// The table inputs' rows for a new mode value: `(input index, values)`.
fn rows(sys: &System, mode: Option<usize>) -> Vec<(usize, &[f64])> {
    match (&sys.discrete.as_ref().and_then(|d| d.mode.as_ref()), mode) {
        (Some(m), Some(v)) => m
            .tables
            .iter()
            .map(|t| (t.input, t.values[v].as_slice()))
            .collect(),
        _ => Vec::new(),
    }
}

/// Every combination of admitted indices, one index per row.
fn combinations(rows: &[(usize, &[f64])], choice: Choice) -> Vec<Vec<usize>> {
    let mut out = vec![Vec::new()];
    for (_, r) in rows {
        let idx = choice.indices(r);
        out = out
            .into_iter()
            .flat_map(|c| {
                idx.iter().map(move |&i| {
                    let mut c = c.clone();
                    c.push(i);
                    c
                })
            })
            .collect();
    }
    out
}

/// One f64 step of the closed loop from `x` in mode `mode`: the new mode (argmax of
/// the mode's network at `observe(x)`), the inputs (the tables' entries picked by
/// `pick`, which gets each row and returns an index; other inputs by `actuate`), and
/// the next state.
pub fn step_f64(
    sys: &System,
    ctrl: &Controllers,
    x: &[f64],
    mode: Option<usize>,
    pick: &mut dyn FnMut(&[f64]) -> usize,
) -> (Vec<f64>, Option<usize>, Vec<f64>) {
    let mut obs = vec![0.0; sys.n_observed()];
    sys.observe(x, &mut obs);
    let out = ctrl.network(mode).eval_f64(&obs);
    let has_mode = sys.discrete.as_ref().is_some_and(|d| d.mode.is_some());
    let new_mode = has_mode.then(|| argmax(&out));
    let mut u = vec![0.0; sys.n_inputs()];
    sys.actuate(&out, &mut u);
    for (i, r) in rows(sys, new_mode) {
        u[i] = r[pick(r).min(r.len() - 1)];
    }
    let mut nx = vec![0.0; sys.dim()];
    sys.next_state(x, &u, &mut nx);
    (nx, new_mode, u)
}

/// Simulate from `x0` over the horizon, the table entries picked by `pick(step, row)`.
pub fn simulate(
    sys: &System,
    ctrl: &Controllers,
    x0: &[f64],
    pick: &mut dyn FnMut(usize, &[f64]) -> usize,
) -> Trajectory {
    let mode0 = sys
        .discrete
        .as_ref()
        .and_then(|d| d.mode.as_ref())
        .map(|m| m.init);
    let mut t = Trajectory {
        states: vec![x0.to_vec()],
        modes: vec![mode0],
        inputs: Vec::new(),
    };
    for k in 0..sys.steps() {
        let (x, m) = (t.states[k].clone(), t.modes[k]);
        let (nx, nm, u) = step_f64(sys, ctrl, &x, m, &mut |r| pick(k, r));
        t.states.push(nx);
        t.modes.push(nm);
        t.inputs.push(u);
    }
    t
}

/// Whether instant `k` is inside a goal's window (instants at `k * period`).
fn checked_at(sys: &System, when: &When, k: usize) -> bool {
    let t = k as f64 * sys.period;
    let eps = 1e-9 * sys.period;
    match when {
        When::End => k == sys.steps(),
        When::Always(a, b) | When::Eventually(a, b) => t >= a - eps && t <= b + eps,
    }
}

/// The first goal a trajectory breaks: (goal index, instant).
pub fn first_violation(sys: &System, t: &Trajectory) -> Option<(usize, usize)> {
    for (k, x) in t.states.iter().enumerate() {
        for (g, goal) in sys.goals.iter().enumerate() {
            if checked_at(sys, &goal.when, k) && !goal.holds(x) {
                return Some((g, k));
            }
        }
    }
    None
}

/// Starting points: the box's corners (up to 64), its centre, then seeded uniform points.
fn starts(init: &[(f64, f64)], n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    let d = init.len();
    let mut v = Vec::with_capacity(n);
    v.push(init.iter().map(|(l, h)| 0.5 * (l + h)).collect());
    for c in 0..(1usize << d.min(6)) {
        v.push(
            init.iter()
                .enumerate()
                .map(|(i, (l, h))| if c >> i.min(63) & 1 == 1 { *h } else { *l })
                .collect(),
        );
    }
    while v.len() < n {
        v.push(
            init.iter()
                .map(|(l, h)| if l < h { rng.gen_range(*l..=*h) } else { *l })
                .collect(),
        );
    }
    v.truncate(n.max(1));
    v
}

/// Look for a violating trajectory from `n` starts: each start is flown with the
/// choice's own picks, and with `Choice::All` also with the smallest, middle and
/// largest entries throughout, with every choice sequence in `replays` (those of sets
/// that met the unsafe region) and with one random sequence.
fn falsify(
    sys: &System,
    ctrl: &Controllers,
    s: &DiscreteSettings,
    n: usize,
    replays: &[Vec<Vec<usize>>],
    rng: &mut ChaCha8Rng,
) -> Option<(Trajectory, usize, usize)> {
    let pts = starts(&sys.init, n, rng);
    let fixed: Vec<Choice> = match s.choice {
        Choice::All => vec![Choice::Min, Choice::Middle, Choice::Max],
        c => vec![c],
    };
    for x0 in &pts {
        for c in &fixed {
            let t = simulate(sys, ctrl, x0, &mut |_, r| c.indices(r)[0]);
            if let Some((g, k)) = first_violation(sys, &t) {
                return Some((t, g, k));
            }
        }
        if s.choice == Choice::All {
            for seq in replays {
                // Table inputs are picked in the order of `rows`: one index per row.
                let mut col = 0usize;
                let mut last_k = usize::MAX;
                let t = simulate(sys, ctrl, x0, &mut |k, _| {
                    if k != last_k {
                        last_k = k;
                        col = 0;
                    }
                    let i = seq.get(k).and_then(|c| c.get(col)).copied().unwrap_or(0);
                    col += 1;
                    i
                });
                if let Some((g, k)) = first_violation(sys, &t) {
                    return Some((t, g, k));
                }
            }
            let seed: u64 = rng.gen();
            let mut r2 = ChaCha8Rng::seed_from_u64(seed);
            let t = simulate(sys, ctrl, x0, &mut |_, r| r2.gen_range(0..r.len()));
            if let Some((g, k)) = first_violation(sys, &t) {
                return Some((t, g, k));
            }
        }
    }
    None
}

/// The possible argmax outputs of `net` over the input box `[lo, hi]`, and per
/// network input how much its width weighs in the ambiguous differences.
fn candidates(net: &PwlNet, lo: &[f64], hi: &[f64]) -> (Vec<usize>, Vec<f64>) {
    let (_, _, fwd) = symbolic::hidden(&net.maps, lo, hi, None);
    let pre = symbolic::crown_pre(&net.maps, lo, hi, Some(&fwd));
    let n = net.n_outputs();
    let mut weight = vec![0.0; lo.len()];
    let mut out = Vec::new();
    for i in 0..n {
        let mut beaten = false;
        let mut amb = Vec::new();
        for j in (0..n).filter(|&j| j != i) {
            let mut c = vec![0.0; n];
            c[j] = 1.0;
            c[i] = -1.0;
            let f = symbolic::backward_lower(&net.maps, &pre, &Objective { c, d: 0.0 }, lo, hi);
            if f.min_over(lo, hi) > 0.0 {
                beaten = true;
                break;
            }
            amb.push(f.coef);
        }
        if !beaten {
            out.push(i);
            for c in amb {
                for (w, (k, l, h)) in weight
                    .iter_mut()
                    .zip(c.iter().zip(lo.iter().zip(hi)).map(|(k, (l, h))| (k, l, h)))
                {
                    *w += k.abs() * (h - l);
                }
            }
        }
    }
    (out, weight)
}

/// Sound bounds of every output of `net` over `[lo, hi]`.
fn output_bounds(net: &PwlNet, lo: &[f64], hi: &[f64]) -> Vec<Interval> {
    let (_, _, fwd) = symbolic::hidden(&net.maps, lo, hi, None);
    let pre = symbolic::crown_pre(&net.maps, lo, hi, Some(&fwd));
    let n = net.n_outputs();
    (0..n)
        .map(|i| {
            let b = |s: f64| {
                let mut c = vec![0.0; n];
                c[i] = s;
                symbolic::backward_lower(&net.maps, &pre, &Objective { c, d: 0.0 }, lo, hi)
                    .min_over(lo, hi)
            };
            Interval::new(b(1.0), -b(-1.0))
        })
        .collect()
}

/// The state whose width weighs most, through the (affine) observation, in the
/// ambiguous differences; the widest state when the observation is not affine.
fn split_dim(sys: &System, set: &BoxSet, weight: &[f64], olo: &[f64], ohi: &[f64]) -> usize {
    let w: Vec<f64> = set.lo.iter().zip(&set.hi).map(|(l, h)| h - l).collect();
    let widest = (0..w.len())
        .max_by(|a, b| w[*a].total_cmp(&w[*b]))
        .unwrap_or(0);
    let Some(a) = sys.observe_affine() else {
        return widest;
    };
    let mut score = vec![0.0; w.len()];
    for (t, row) in a.state.iter().enumerate() {
        let ow = ohi[t] - olo[t];
        if ow <= 0.0 {
            continue;
        }
        for (s, c) in row.iter().enumerate() {
            score[s] += weight[t] / ow * (c * w[s]).abs();
        }
    }
    let best = (0..w.len())
        .max_by(|a, b| score[*a].total_cmp(&score[*b]))
        .unwrap_or(widest);
    if score[best] > 0.0 {
        best
    } else {
        widest
    }
}

/// Sound reachable sets of a discrete-time system under its controllers, with the
/// verdict on its goals (see the module documentation).
pub fn reach_discrete(
    sys: &System,
    ctrl: &Controllers,
    s: &DiscreteSettings,
) -> Result<DiscreteResult, DiscreteError> {
    let start = Instant::now();
    let deadline = s.timeout.deadline_from(start);
    if !sys.is_discrete() {
        return Err(DiscreteError::NotDiscrete);
    }
    if let Some(g) = sys
        .goals
        .iter()
        .find(|g| matches!(g.when, When::Eventually(..)))
    {
        return Err(DiscreteError::Goal(g.text.clone()));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
    let finish = |verdict, sets: Vec<Vec<BoxSet>>, splits, mode_branches| {
        let hull = sets
            .iter()
            .filter(|v: &&Vec<BoxSet>| !v.is_empty())
            .map(|v| {
                (0..sys.dim())
                    .map(|i| {
                        v.iter()
                            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), b| {
                                (l.min(b.lo[i]), h.max(b.hi[i]))
                            })
                    })
                    .collect()
            })
            .collect();
        Ok(DiscreteResult {
            verdict,
            sets,
            hull,
            splits,
            mode_branches,
            elapsed_s: start.elapsed().as_secs_f64(),
        })
    };
    // Falsification first.
    if let Some((trajectory, g, step)) = falsify(sys, ctrl, s, s.samples, &[], &mut rng) {
        let verdict = DiscreteVerdict::Violated(DiscreteViolation {
            trajectory,
            goal: sys.goals[g].text.clone(),
            step,
        });
        return finish(verdict, Vec::new(), 0, 0);
    }
    let mode0 = sys
        .discrete
        .as_ref()
        .and_then(|d| d.mode.as_ref())
        .map(|m| m.init);
    let init = BoxSet {
        lo: sys.init.iter().map(|r| r.0).collect(),
        hi: sys.init.iter().map(|r| r.1).collect(),
        mode: mode0,
        choices: Vec::new(),
    };
    let mut sets = vec![vec![init]];
    let (mut splits, mut mode_branches) = (0usize, 0usize);
    // Sets that meet the unsafe region: (instant, goal text, the set).
    let mut failed: Option<(usize, String, BoxSet)> = None;
    let check = |k: usize, b: &BoxSet| -> Option<String> {
        let x = b.intervals();
        sys.goals
            .iter()
            .filter(|g| checked_at(sys, &g.when, k))
            .find(|g| g.decide(&x) != Some(true))
            .map(|g| g.text.clone())
    };
    if let Some(g) = check(0, &sets[0][0]) {
        failed = Some((0, g, sets[0][0].clone()));
    }
    let needs_bounds = sys.n_inputs() > rows(sys, mode0.map(|_| 0)).len();
    let mut k = 0;
    while failed.is_none() && k < sys.steps() {
        let mut next: Vec<BoxSet> = Vec::new();
        for set in &sets[k] {
            let mut queue = vec![(set.clone(), 0u32)];
            while let Some((b, depth)) = queue.pop() {
                if deadline.is_some_and(|d| Instant::now() >= d) {
                    let reason = format!(
                        "unknown (timeout): the time limit of {} s was reached at step {} of {}",
                        s.timeout.secs(),
                        k,
                        sys.steps()
                    );
                    sets.push(next);
                    return finish(
                        DiscreteVerdict::Unknown { reason },
                        sets,
                        splits,
                        mode_branches,
                    );
                }
                let x = b.intervals();
                let mut obs = vec![Interval::point(0.0); sys.n_observed()];
                sys.observe(&x, &mut obs);
                let olo: Vec<f64> = obs.iter().map(|v| v.lo).collect();
                let ohi: Vec<f64> = obs.iter().map(|v| v.hi).collect();
                let net = &ctrl.pwl[ctrl.index(b.mode)];
                let (cands, weight) = if mode0.is_some() {
                    candidates(net, &olo, &ohi)
                } else {
                    (vec![usize::MAX], vec![])
                };
                if cands.len() > 1 && depth < s.max_depth {
                    let d = split_dim(sys, &b, &weight, &olo, &ohi);
                    if b.hi[d] > b.lo[d] {
                        let mid = 0.5 * (b.lo[d] + b.hi[d]);
                        let (mut l, mut h) = (b.clone(), b);
                        l.hi[d] = mid;
                        h.lo[d] = mid;
                        splits += 1;
                        queue.push((l, depth + 1));
                        queue.push((h, depth + 1));
                        continue;
                    }
                }
                if cands.len() > 1 {
                    mode_branches += 1;
                }
                let mut u = vec![Interval::point(0.0); sys.n_inputs()];
                if needs_bounds {
                    sys.actuate(&output_bounds(net, &olo, &ohi), &mut u);
                }
                for c in cands {
                    let nm = (c != usize::MAX).then_some(c);
                    let r = rows(sys, nm);
                    for combo in combinations(&r, s.choice) {
                        for ((i, row), j) in r.iter().zip(&combo) {
                            u[*i] = Interval::point(row[*j]);
                        }
                        let mut nx = vec![Interval::point(0.0); sys.dim()];
                        sys.next_state(&x, &u, &mut nx);
                        let mut choices = b.choices.clone();
                        choices.push(combo);
                        next.push(BoxSet {
                            lo: nx.iter().map(|v| v.lo).collect(),
                            hi: nx.iter().map(|v| v.hi).collect(),
                            mode: nm,
                            choices,
                        });
                    }
                }
                if next.len() > s.max_sets {
                    let reason = format!(
                        "more than {} sets at step {} of {} (raise --max-leaves)",
                        s.max_sets,
                        k + 1,
                        sys.steps()
                    );
                    sets.push(next);
                    return finish(
                        DiscreteVerdict::Unknown { reason },
                        sets,
                        splits,
                        mode_branches,
                    );
                }
            }
        }
        k += 1;
        if next.len() > s.merge_at {
            next = merge(next, s.merge_at / 2);
        }
        if let Some((g, b)) = next.iter().find_map(|b| check(k, b).map(|g| (g, b))) {
            failed = Some((k, g, b.clone()));
        }
        sets.push(next);
    }
    let Some((k, goal, b)) = failed else {
        return finish(DiscreteVerdict::Proved, sets, splits, mode_branches);
    };
    // A set meets the unsafe region: look harder for a trajectory, replaying the
    // choices of every set that fails at that instant.
    let replays: Vec<Vec<Vec<usize>>> = sets[k]
        .iter()
        .filter(|c| check(k, c).is_some())
        .take(64)
        .map(|c| c.choices.clone())
        .collect();
    if let Some((trajectory, g, step)) = falsify(sys, ctrl, s, 10 * s.samples, &replays, &mut rng) {
        let verdict = DiscreteVerdict::Violated(DiscreteViolation {
            trajectory,
            goal: sys.goals[g].text.clone(),
            step,
        });
        return finish(verdict, sets, splits, mode_branches);
    }
    let reason = format!(
        "at step {k} a set (mode {}, {}) does not satisfy `{goal}`, and none of {} simulated trajectories breaks it",
        mode_name(sys, b.mode),
        b.lo.iter()
            .zip(&b.hi)
            .zip(&sys.states)
            .map(|((l, h), n)| format!("{n} in [{l}, {h}]"))
            .collect::<Vec<_>>()
            .join(", "),
        10 * s.samples
    );
    finish(
        DiscreteVerdict::Unknown { reason },
        sets,
        splits,
        mode_branches,
    )
}

/// Merge sets into about `target` hulls: per mode, sorted by centre, consecutive groups.
fn merge(sets: Vec<BoxSet>, target: usize) -> Vec<BoxSet> {
    let total = sets.len();
    let mut by_mode: Vec<(Option<usize>, Vec<BoxSet>)> = Vec::new();
    for b in sets {
        match by_mode.iter_mut().find(|(m, _)| *m == b.mode) {
            Some((_, v)) => v.push(b),
            None => by_mode.push((b.mode, vec![b])),
        }
    }
    let mut out = Vec::new();
    for (_, mut v) in by_mode {
        let centre = |b: &BoxSet| -> Vec<f64> {
            b.lo.iter().zip(&b.hi).map(|(l, h)| 0.5 * (l + h)).collect()
        };
        v.sort_by(|a, b| {
            centre(a)
                .iter()
                .zip(centre(b).iter())
                .map(|(x, y)| x.total_cmp(y))
                .find(|o| o.is_ne())
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        let groups = (v.len() * target.max(1)).div_ceil(total).max(1);
        let size = v.len().div_ceil(groups);
        for chunk in v.chunks(size) {
            let mut h = chunk[0].clone();
            for b in &chunk[1..] {
                for i in 0..h.lo.len() {
                    h.lo[i] = h.lo[i].min(b.lo[i]);
                    h.hi[i] = h.hi[i].max(b.hi[i]);
                }
            }
            out.push(h);
        }
    }
    out
}

/// A mode value's name (`-` without a mode).
pub fn mode_name(sys: &System, mode: Option<usize>) -> String {
    match (sys.discrete.as_ref().and_then(|d| d.mode.as_ref()), mode) {
        (Some(m), Some(v)) => m.values[v].clone(),
        _ => "-".into(),
    }
}
