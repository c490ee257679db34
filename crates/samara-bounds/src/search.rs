//! Input-domain branch and bound for box queries: is there an input `x` in a box whose
//! outputs satisfy every constraint of a conjunction (the VNN-LIB counterexample shape)?
//!
//! Per case (one input box, one conjunction over the outputs): a projected-gradient
//! attack (Madry et al., ICLR 2018) with seeded random restarts looks for a point first
//! (all cases in parallel; short bursts recur during the search). Then the box is split,
//! depth first and in parallel batches; cases with the same box (a disjunction over the
//! outputs) share its pieces, so each piece's CROWN intermediate bounds and look-ahead
//! serve all of them. Each piece gets full CROWN intermediate bounds (Zhang et al.,
//! NeurIPS 2018) and alpha-CROWN bounds (Xu et al., ICLR 2021) of every constraint; a
//! conjunction is closed when one constraint's bound shows it cannot hold, or when a
//! non-negative combination of the constraints is positive on the piece: the weights come
//! from the exact min-max LP over the linear bounds ([`crate::lp`]), and the combination
//! is also bounded as one objective (its own alpha-CROWN slopes). The split is chosen by
//! look-ahead (every input halved, both halves bounded cheaply by the piece's own CROWN
//! functions minimised over each half, the best [`Settings::look_refine`] splits bounded
//! again by full CROWN; the split that leaves the least to prove for the most promising
//! case wins; with one input, the only split, its halves bounded by the forward symbolic
//! pass instead of CROWN), by smear `|coefficient| *
//! width` (ReluVal, Wang et al., USENIX Security 2018) when the look-ahead stalls. A
//! piece that at most [`Settings::phase_max_unstable`] ReLUs cross is first handed to
//! ReLU-phase splitting ([`crate::phases`]), which decides it exactly unless its node
//! budget runs out. Every bound is sound in floating point ([`crate::symbolic`]). A candidate point (the
//! piece's centre, the LP's minimiser, the minimising corner of each linear bound, a
//! short local attack) is reported only when its f64 evaluation satisfies every
//! constraint with a margin above the evaluation's own rounding error. Anything cut short
//! (time, piece budget) is [`Outcome::Unknown`] with its reason.
//!
//! On 64 or more inputs (images) halving one input hardly moves a bound: a box left open
//! by those same checks is decided by ReLU splitting with beta-CROWN bounds instead
//! (`crate::relusplit`), one tree per open case, after the intermediate bounds are
//! tightened once by alpha-CROWN ([`symbolic::alpha_pre_with`]); on deep dense networks
//! whose tree stays open, they are refined layer by layer by proving neurons stable with
//! small trees of their own ([`crate::refine`]) and the tree starts again (after a few
//! batches when every case's bound at the whole box is far below 0).

use crate::query::{combination_certifies, forward};
pub use crate::query::{satisfies, Case, OutputConstraint};
use crate::symbolic::{self, Objective};
use rayon::prelude::*;
use samara_nn::Affine;
use samara_num::Timeout;
use std::sync::atomic::{AtomicU64, Ordering as AtOrd};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Profile counters (nanoseconds / counts), printed to stderr at the end of [`solve`]
/// when the environment variable `SAMARA_SEARCH_PROFILE` is set.
static PROF: [AtomicU64; 11] = [
    AtomicU64::new(0),
    AtomicU64::new(0),
    AtomicU64::new(0),
    AtomicU64::new(0),
    AtomicU64::new(0),
    AtomicU64::new(0),
    AtomicU64::new(0),
    AtomicU64::new(0),
    AtomicU64::new(0),
    AtomicU64::new(0),
    AtomicU64::new(0),
];
const P_ATTACK: usize = 0;
const P_OWNB: usize = 1;
const P_ALPHA: usize = 2;
const P_LOOK: usize = 3;
const P_PGD: usize = 4;
const P_MAXDEPTH: usize = 5;
const P_COMB: usize = 6;
const P_CLOSED: usize = 7;
const P_PHASE: usize = 8;
const P_PHASE_CLOSED: usize = 9;
const P_PHASE_NODES: usize = 10;
/// Which route found the point (1 first attack, 2 a burst, 3 a piece's candidates, 4 a
/// piece's local attack, 5 phase splitting, 6 constant fates).
static FOUND_BY: AtomicU64 = AtomicU64::new(0);

fn prof_add(k: usize, t0: Instant) {
    PROF[k].fetch_add(t0.elapsed().as_nanos() as u64, AtOrd::Relaxed);
}

/// Concrete pre-activation bounds of every map but the last.
type Bounds = Vec<Vec<(f64, f64)>>;

/// Limits and choices of the search.
#[derive(Clone, Debug)]
pub struct Settings {
    /// Wall-clock limit ([`Timeout::none`]: none).
    pub timeout: Timeout,
    /// Most pieces examined over all cases (`0`: no limit).
    pub max_pieces: u64,
    /// Pieces per parallel batch.
    pub batch: usize,
    /// Random restarts of the attack per case.
    pub restarts: usize,
    /// Gradient steps per restart (a restart whose gradient vanishes, e.g. in a region
    /// where every ReLU of a layer is off, ends early: restarts are then cheap samples).
    pub steps: usize,
    /// Wall-clock budget of the attack per case, before the search (seconds). The
    /// search repeats bursts with fresh starts, every `max(0.5, t / 4)` seconds at time
    /// `t`, each 15% of that interval long but at most four times this budget (shared
    /// by the cases), so bursts stay a small share of a long proof. The first burst gets
    /// ten times this budget when fewer than one piece in ten has closed by then (a
    /// search that makes no headway, typical of a query with points), later bursts half
    /// of it when at least every second piece examined has closed. A point found for
    /// one case ends the other cases' attacks. On fewer than 64 inputs the first attack
    /// takes at most 0.02 s per case (see `FEW_INPUTS_FIRST_ATTACK`).
    pub attack_seconds: f64,
    /// alpha-CROWN gradient steps for each piece's own constraint bounds (0: CROWN's
    /// slopes; the look-ahead always uses CROWN's, for speed).
    pub alpha_iters: usize,
    /// A piece that at most this many ReLUs cross (after its bounds, its constraint
    /// bounds, its candidate points and its local attack failed) is decided by splitting
    /// those ReLUs' phases instead of its inputs, with LP bounds over each phase set
    /// ([`crate::phases`]; 0: never).
    pub phase_max_unstable: usize,
    /// Most nodes of one piece's phase splitting, before the piece goes back to input
    /// splitting.
    pub phase_budget: usize,
    /// How many of the look-ahead's splits, the best by their cheap score (this piece's
    /// CROWN functions minimised over each half), are scored again with full CROWN bounds
    /// of both halves, which then decide (0: the cheap score decides). On ACAS Xu
    /// properties 1 and 2, 1 took about half the CPU time of 2 and a third of 5 (every
    /// input), with 5-20% more pieces.
    pub look_refine: usize,
    /// Seed of the attack's random starts.
    pub seed: u64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            timeout: Timeout::from_duration(Duration::from_secs(60)),
            max_pieces: 0,
            batch: 32,
            restarts: 1_000_000,
            attack_seconds: 0.05,
            alpha_iters: 10,
            steps: 60,
            phase_max_unstable: 40,
            phase_budget: 5000,
            look_refine: 1,
            seed: 0,
        }
    }
}

/// Why a search stopped without an answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// The time limit was reached.
    Timeout,
    /// The piece budget was spent.
    PieceLimit,
    /// A piece became too small to split in floating point and was neither closed nor
    /// refuted (a boundary case the f64 bounds cannot decide).
    Unsplittable,
    /// A piece's region is thin: with every ReLU phase fixed the network is affine and
    /// the case's constraints leave room for points only at the rounding level
    /// (`phases::PhaseResult::Thin`); reported as soon as the rest of the
    /// search is done, not after splitting that piece to the time limit.
    ThinRegion,
}

/// A point of case `case`, with the network's f64 outputs there: the witness of a
/// violated query.
#[derive(Clone, Debug, PartialEq)]
pub struct CasePoint {
    /// Index of the case.
    pub case: usize,
    /// The input.
    pub x: Vec<f64>,
    /// The outputs.
    pub y: Vec<f64>,
}

/// The answer, in the one answer vocabulary ([`samara_num::Outcome`]): `Proved` (no
/// case has a point: the property holds), `Violated` with a [`CasePoint`], or `Unknown`
/// when the search is cut short.
pub type Outcome = samara_num::Outcome<CasePoint, StopReason>;

/// Statistics of a search.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    /// Pieces whose bounds were computed.
    pub pieces: u64,
    /// Attack gradient steps taken.
    pub attack_steps: u64,
}

/// From this many inputs on (images), the attack steps by the gradient's sign and
/// attacks the cases over one box together.
const SIGN_STEP_INPUTS: usize = 64;

/// Projected gradient descent from `x` on the summed violation
/// `sum_k max(0, g_k(f(x)) + margin)` of the conjunction (the gradient of every violated
/// constraint, not only the worst, so the steps do not oscillate between constraints),
/// with a step that shrinks over `steps`. Returns a point that satisfies every constraint.
fn pgd(
    maps: &[(Affine, bool)],
    cs: &[OutputConstraint],
    lo: &[f64],
    hi: &[f64],
    x: Vec<f64>,
    steps: usize,
    deadline: Option<Instant>,
) -> Option<Vec<f64>> {
    pgd_any(maps, &[cs], lo, hi, x, steps, 0.0, deadline).map(|(_, x)| x)
}

/// [`pgd`] on a disjunction of conjunctions over one box (the cases of a VNN-LIB
/// property that share their input region: an image property's "class j wins" for every
/// j): each step descends on the conjunction nearest to holding (least summed
/// violation), the untargeted margin attack of Carlini and Wagner, instead of one attack
/// per case. `leak` is the backward slope of an inactive ReLU (0: the exact gradient;
/// [`crate::attack::LEAK`] on the leaky restarts of [`attack`]). Returns the index of a
/// conjunction that holds and the point.
#[allow(clippy::too_many_arguments)]
fn pgd_any(
    maps: &[(Affine, bool)],
    group: &[&[OutputConstraint]],
    lo: &[f64],
    hi: &[f64],
    x: Vec<f64>,
    steps: usize,
    leak: f64,
    deadline: Option<Instant>,
) -> Option<(usize, Vec<f64>)> {
    // Steepest descent for the box, the gradient's sign, on many inputs; on few (ACAS
    // Xu's five) the step scaled by the gradient, which converges there in fewer steps.
    let rule = if lo.len() >= SIGN_STEP_INPUTS {
        crate::attack::Step::Sign(1.0)
    } else {
        crate::attack::Step::Scaled
    };
    let mut chain = crate::attack::Chain {
        maps,
        masks: Vec::new(),
        leak,
    };
    crate::attack::descend(
        &mut chain, group, lo, hi, x, steps, rule, deadline, satisfies,
    )
}

/// The cases grouped by their box (indices in order; groups in order of their first
/// case): the search's pieces and, on many inputs, the attack are shared by a group.
pub(crate) fn box_groups(cases: &[Case]) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, c) in cases.iter().enumerate() {
        match groups
            .iter_mut()
            .find(|g| cases[g[0]].lo == c.lo && cases[g[0]].hi == c.hi)
        {
            Some(g) => g.push(i),
            None => groups.push(vec![i]),
        }
    }
    groups
}

/// What one attack found (the case and the point) and the gradient steps it took.
type Attacked = (Option<(usize, Vec<f64>)>, u64);

/// The attack: [`pgd_any`] on the cases `group` (indices into `cases`, all over one box)
/// from the centre and from seeded random starts (on many inputs, two restarts of every
/// 4 on the surrogate gradient of [`crate::attack::LEAK`]), `steps` gradient steps each, until
/// `s.restarts` starts or `seconds` are spent (the first start runs its steps in full),
/// and never past `deadline`. `round` varies the seed. Returns the case and point found
/// and the gradient steps taken.
#[allow(clippy::too_many_arguments)]
fn attack(
    maps: &[(Affine, bool)],
    cases: &[Case],
    group: &[usize],
    s: &Settings,
    round: u64,
    seconds: f64,
    steps_per_start: usize,
    stop: &std::sync::atomic::AtomicBool,
    deadline: Option<Instant>,
) -> Attacked {
    let _guard = ProfGuard(Instant::now());
    let mut rng = crate::attack::starts(s.seed, round);
    let case = &cases[group[0]];
    let conj: Vec<&[OutputConstraint]> =
        group.iter().map(|ci| &cases[*ci].constraints[..]).collect();
    let mut steps = 0u64;
    let found = crate::attack::restarts(s.restarts.max(1), seconds, stop, deadline, |r| {
        let x = crate::attack::start(&mut rng, &case.lo, &case.hi, r == 0 && round == 0);
        steps += steps_per_start as u64;
        // Even restarts descend on whichever case is nearest (image properties: one
        // class beats the label, whichever it is); odd ones on one case at a time in
        // turn (ACAS Xu properties 7 and 8, whose nearest case is often a trap).
        let one = (r % 2 == 1 && conj.len() > 1).then(|| (r / 2) % conj.len());
        let target = match one {
            Some(k) => &conj[k..k + 1],
            None => &conj[..],
        };
        // Two restarts of every 4 (one of each kind above) descend on a leaky ReLU's
        // surrogate gradient (`attack::LEAK`): where the exact gradient ends on a plateau
        // of switched-off units (mnist_fc 256x6 prop_1 at 0.05, whose point the exact
        // descent misses from every start) it still sees the units a step could turn on.
        // The cycle is offset by `round` (the worker's salt), so that the first start of
        // the second worker is leaky: the first attack on an image often has time for one
        // start a worker (mnist_fc 256x6: 60 steps took 0.07 s of its 0.05).
        // On few inputs (ACAS Xu) the exact descent alone: its properties 7 and 8 points
        // (1_9, 2_9) come from the bursts' exact restarts in their order, and were lost
        // with half of them leaky (unknown at 60 s).
        let leak = if case.lo.len() >= SIGN_STEP_INPUTS && matches!((r as u64 + round) % 4, 1 | 2) {
            crate::attack::LEAK
        } else {
            0.0
        };
        pgd_any(
            maps,
            target,
            &case.lo,
            &case.hi,
            x,
            steps_per_start,
            leak,
            deadline,
        )
        .map(|(k, x)| (group[one.unwrap_or(k)], x))
    });
    (found, steps)
}

/// [`attack`] on every case, in parallel, `seconds` each and `steps` gradient steps per
/// start; the point of the first case (in order) that has one, and the wall seconds a
/// gradient step of one job took (the wall time over the steps per job; `None` when no
/// step was taken). On many inputs (images)
/// cases over the same box are attacked together, and a box gets as many workers
/// (seeds) as there are threads per box, so that a single image property keeps every
/// core on its one joint attack.
#[allow(clippy::too_many_arguments)]
fn attack_all(
    maps: &[(Affine, bool)],
    cases: &[Case],
    s: &Settings,
    round: u64,
    seconds: f64,
    steps: usize,
    stats: &mut Stats,
    deadline: Option<Instant>,
) -> (Option<(usize, Vec<f64>)>, Option<f64>) {
    let t0 = Instant::now();
    // On few inputs (ACAS Xu) a separate attack per case is cheap and finds points a
    // joint one can miss (property 8): cases are grouped on many inputs only.
    let joint = cases
        .first()
        .is_some_and(|c| c.lo.len() >= SIGN_STEP_INPUTS);
    let groups = if joint {
        box_groups(cases)
    } else {
        (0..cases.len()).map(|i| vec![i]).collect()
    };
    let workers = rayon::current_num_threads()
        .max(1)
        .div_ceil(groups.len().max(1)) as u64;
    let jobs: Vec<(usize, u64)> = (0..groups.len())
        .flat_map(|g| (0..workers).map(move |w| (g, w)))
        .collect();
    // A point of one case ends the other cases' attacks.
    let stop = std::sync::atomic::AtomicBool::new(false);
    let res: Vec<Attacked> = jobs
        .par_iter()
        .map(|(g, w)| {
            let salt = round * workers + w;
            attack(
                maps,
                cases,
                &groups[*g],
                s,
                salt,
                seconds,
                steps,
                &stop,
                deadline,
            )
        })
        .collect();
    let taken = res.iter().map(|r| r.1).sum::<u64>();
    stats.attack_steps += taken;
    let wall = t0.elapsed().as_secs_f64();
    // The jobs that ran side by side: all of them on many inputs (a box's workers are one
    // per thread); on few inputs (one job per case, often more cases than threads) at
    // most one per thread, so the cost is a step's own, whatever the number of cases.
    let side_by_side = match joint {
        true => jobs.len(),
        false => jobs.len().min(rayon::current_num_threads().max(1)),
    };
    let cost = (taken > 0).then(|| wall * side_by_side as f64 / taken as f64);
    if std::env::var_os("SAMARA_SEARCH_PROFILE").is_some() {
        eprintln!(
            "attack {round}: {} jobs, {steps} steps a start, {seconds:.3} s each, {taken} steps in {:.3} s{}",
            jobs.len(),
            wall,
            if stop.load(AtOrd::Relaxed) { ", found" } else { "" }
        );
    }
    let found = res
        .into_iter()
        .filter_map(|r| r.0)
        .min_by_key(|(ci, _)| *ci);
    (found, cost)
}

struct ProfGuard(Instant);
impl Drop for ProfGuard {
    fn drop(&mut self) {
        prof_add(P_ATTACK, self.0);
    }
}

/// A piece of the box shared by one or more cases, with intermediate bounds proved on it
/// (`fin`) or on a box containing it (to be tightened).
struct Work {
    lo: Vec<f64>,
    hi: Vec<f64>,
    bounds: Option<Arc<Bounds>>,
    fin: bool,
    /// CROWN's linear functions behind `bounds` when `fin` (for the look-ahead).
    lins: Option<Arc<symbolic::PreLinear>>,
    /// The best constraint bound known for the piece: among pieces of the same depth
    /// the lowest goes first (closest to holding a point).
    key: f64,
    /// Number of splits from the case's box: the deepest pieces go first (depth first,
    /// so the frontier stays small and pieces get cheap quickly).
    depth: u32,
    /// The cases (indices into the query's cases, all with this piece's box) not yet
    /// closed on the piece. Cases that share their box (a disjunction over the outputs,
    /// e.g. "some output is below `y_0`") share its pieces: the intermediate bounds and
    /// the look-ahead are computed once for all of them.
    open: Vec<usize>,
}

crate::work::deepest_then_least_key!(Work);

/// One look-ahead trial: its score (higher is better), the halves left open, the input
/// split, and whether the halves' bounds are full CROWN (else the cheap ones).
type Try = (f64, Vec<Work>, usize, bool);

/// What one piece came to.
enum Piece {
    Closed,
    /// A point of the given case.
    Found(usize, Vec<f64>),
    /// The pieces left open (a half closed by the look-ahead is dropped).
    Split(Vec<Work>),
    Stuck,
    /// The piece's region is thin (see [`StopReason::ThinRegion`]); not split further.
    Thin,
    /// Past the deadline before the piece was done.
    Late,
}

/// Full CROWN intermediate bounds of a piece, starting from bounds of a containing box.
/// Past `deadline` the forward bounds are kept for the neurons CROWN has not reached.
pub(crate) fn piece_bounds(
    maps: &[(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    known: Option<&Bounds>,
    deadline: Option<Instant>,
) -> Bounds {
    let fwd = symbolic::hidden_pre_until(maps, lo, hi, known.map(|v| &v[..]), deadline);
    symbolic::crown_pre_until(maps, lo, hi, &fwd, deadline)
}

/// [`piece_bounds`] with CROWN's linear functions ([`symbolic::crown_pre_lin_until`]),
/// for the look-ahead's cheap bounds of the halves.
fn piece_bounds_lin(
    maps: &[(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    known: Option<&Bounds>,
    deadline: Option<Instant>,
) -> (Bounds, symbolic::PreLinear) {
    // Bounds known on the piece (a half's, from its parent's CROWN functions) stand in
    // for the forward pass: CROWN re-bounds every neuron they leave unstable anyway.
    match known {
        Some(k) => symbolic::crown_pre_lin_until(maps, lo, hi, k, deadline),
        None => {
            let fwd = symbolic::hidden_pre_until(maps, lo, hi, None, deadline);
            symbolic::crown_pre_lin_until(maps, lo, hi, &fwd, deadline)
        }
    }
}

/// A conjunction's bounds on one piece.
struct ConjBound {
    /// The best lower bound over the conjunction's constraints (or of a certified
    /// combination of them).
    lb: f64,
    /// Whether the conjunction is shown to have no point on the piece.
    closed: bool,
    /// The linear lower bound of the constraint with the best bound.
    f: Option<symbolic::Linear>,
    /// The point of the piece where every linear lower bound is smallest together (the
    /// min-max LP's minimiser), a candidate for a point of the conjunction.
    x: Option<Vec<f64>>,
}

/// The best lower bound over the conjunction's constraints (the piece is closed when it
/// is positive, or non-negative for a strict constraint), or failing that a non-negative
/// combination of the constraints' linear bounds positive on the whole piece.
fn best_bound(
    maps: &[(Affine, bool)],
    cs: &[OutputConstraint],
    pre: &Bounds,
    lo: &[f64],
    hi: &[f64],
    alpha_iters: usize,
    deadline: Option<Instant>,
) -> ConjBound {
    let mut best = ConjBound {
        lb: f64::NEG_INFINITY,
        closed: false,
        f: None,
        x: None,
    };
    let mut fs = Vec::with_capacity(cs.len());
    for k in cs {
        let f = if alpha_iters > 0 {
            symbolic::alpha_lower_until(maps, pre, &k.obj, lo, hi, alpha_iters, deadline)
        } else {
            symbolic::backward_lower(maps, pre, &k.obj, lo, hi)
        };
        let lb = f.min_over(lo, hi);
        let closed = if k.strict { lb >= 0.0 } else { lb > 0.0 };
        if closed {
            return ConjBound {
                lb,
                closed: true,
                f: Some(f),
                x: None,
            };
        }
        if best.f.is_none() || lb > best.lb {
            best.lb = lb;
            best.f = Some(f.clone());
        }
        fs.push(f);
    }
    // No single constraint is excluded: a non-negative combination `sum_k l_k g_k > 0`
    // everywhere still shows that the `g_k <= 0` never hold together.
    if fs.len() >= 2 {
        let tc = Instant::now();
        let (ok, mm) = combination_certifies(&fs, lo, hi);
        prof_add(P_COMB, tc);
        if ok {
            best.closed = true;
        } else if let Some(mm) = mm {
            best.x = Some(mm.x.clone());
            // One bound of the LP's combination as a single objective: its backward pass
            // relaxes every neuron once for the combination (by the sign of the combined
            // coefficient) instead of summing relaxations chosen for each constraint alone,
            // and alpha-CROWN optimises the slopes for it (the conjunction's weights and the
            // slopes together, as in the joint optimisation of Xu et al. 2021).
            if let Some(lb) =
                combined_bound(maps, cs, pre, lo, hi, &mm.lambda, alpha_iters, deadline)
            {
                // Only the proof is taken: steering the look-ahead by the LP's value or
                // by this bound (instead of the best single constraint's) did not help
                // on ACAS Xu property 2.
                if lb > 0.0 {
                    best.closed = true;
                }
            }
        }
    }
    best
}

/// A sound lower bound, over the piece, of `sum_k lam_k g_k(f(x))` for the constraints
/// `g_k` (so a positive one shows that the conjunction has no point): the combined
/// objective `c' = fl(sum_k lam_k c_k)`, `d' = fl(sum_k lam_k d_k)` is bounded by
/// ([`symbolic::alpha_lower`] or [`symbolic::backward_lower`]), and the rounding of the
/// combination is subtracted: `|c'_o - sum_k lam_k c_ko| <= gamma * sum_k |lam_k c_ko|`
/// (Higham's bound, as in [`crate::symbolic`]), times a sound bound on `|y_o|` from the
/// last hidden layer's bounds by interval arithmetic. `None` when the output bounds are
/// not finite.
#[allow(clippy::too_many_arguments)]
fn combined_bound(
    maps: &[(Affine, bool)],
    cs: &[OutputConstraint],
    pre: &Bounds,
    lo: &[f64],
    hi: &[f64],
    lam: &[f64],
    alpha_iters: usize,
    deadline: Option<Instant>,
) -> Option<f64> {
    let (last, _) = maps.last()?;
    // The argument needs non-negative weights (a negative one flips its constraint).
    if lam.len() != cs.len() || lam.iter().any(|l| !(l.is_finite() && *l >= 0.0)) {
        return None;
    }
    let no = last.out;
    let k = cs.len();
    let gam = (k as f64 + 3.0) * f64::EPSILON;
    let mut c = vec![0.0; no];
    let mut cerr = vec![0.0; no];
    for o in 0..no {
        let mut mag = 0.0;
        for (kc, l) in cs.iter().zip(lam) {
            let p = l * kc.obj.c[o];
            c[o] += p;
            mag += p.abs();
        }
        cerr[o] = gam * mag;
    }
    let mut d = 0.0;
    let mut dmag = 0.0;
    for (kc, l) in cs.iter().zip(lam) {
        let p = l * kc.obj.d;
        d += p;
        dmag += p.abs();
    }
    // |y_o| <= |b_o| + sum_i |w_oi| * max|a_i|, a = the last map's input.
    let amax = symbolic::input_magnitudes(maps, pre, lo, hi, maps.len()).pop()?;
    let mut err = gam * dmag;
    for (o, ce) in cerr.iter().enumerate() {
        let ymax =
            (last.b[o].abs() + last.row(o).abs_dot(&amax)) * (1.0 + gam * (last.inp as f64 + 2.0));
        err += ce * ymax;
    }
    if !err.is_finite() {
        return None;
    }
    let obj = Objective { c, d };
    let f = if alpha_iters > 0 {
        symbolic::alpha_lower_until(maps, pre, &obj, lo, hi, alpha_iters, deadline)
    } else {
        symbolic::backward_lower(maps, pre, &obj, lo, hi)
    };
    let v = f.min_over(lo, hi) - (err * (1.0 + 1e-9)).next_up();
    Some(v.next_down())
}

/// The open cases' bounds on one piece: the cases still open, with their bounds.
#[allow(clippy::too_many_arguments)]
fn open_bounds(
    maps: &[(Affine, bool)],
    cases: &[Case],
    open: &[usize],
    pre: &Bounds,
    lo: &[f64],
    hi: &[f64],
    alpha_iters: usize,
    deadline: Option<Instant>,
) -> Vec<(usize, ConjBound)> {
    open.iter()
        .map(|&ci| {
            let b = best_bound(
                maps,
                &cases[ci].constraints,
                pre,
                lo,
                hi,
                alpha_iters,
                deadline,
            );
            (ci, b)
        })
        .filter(|(_, b)| !b.closed)
        .collect()
}

/// Whether the constant fates ([`crate::constant`]) could decide one of the open cases
/// `left` on the piece `[lo, hi]`: some case's best constraint bound is within rounding
/// of 0 (`1e-6` of the magnitudes summed in it: a constraint exactly at 0 there, which
/// the widened bounds never close), or some case nearly holds at the piece's centre
/// (within `1e-9` relative: a case that holds at every point of the piece, perhaps with
/// margin 0, which the margin of [`satisfies`] rejects). A `false` only skips a shortcut.
fn constant_fates_may_decide(
    maps: &[(Affine, bool)],
    cases: &[Case],
    left: &[(usize, ConjBound)],
    lo: &[f64],
    hi: &[f64],
) -> bool {
    let near_zero = left.iter().any(|(_, b)| match &b.f {
        Some(f) => {
            let scale = f.cst.abs()
                + f.slack
                + f.coef
                    .iter()
                    .zip(lo.iter().zip(hi))
                    .map(|(c, (a, h))| c.abs() * a.abs().max(h.abs()))
                    .sum::<f64>();
            b.lb >= -1e-6 * (1.0 + scale)
        }
        None => true,
    });
    if near_zero {
        return true;
    }
    let centre: Vec<f64> = lo.iter().zip(hi).map(|(a, b)| 0.5 * (a + b)).collect();
    let y = forward(maps, &centre, None);
    left.iter().any(|(ci, _)| {
        cases[*ci].constraints.iter().all(|k| {
            let mut v = k.obj.d;
            let mut mag = k.obj.d.abs();
            for (c, yo) in k.obj.c.iter().zip(&y) {
                v += c * yo;
                mag += (c * yo).abs();
            }
            v <= 1e-9 * (1.0 + mag)
        })
    })
}

/// What [`settle`] left of a piece: its bounds and the cases still open with theirs.
struct Settled {
    lo: Vec<f64>,
    hi: Vec<f64>,
    depth: u32,
    pre: Arc<Bounds>,
    lins: Arc<symbolic::PreLinear>,
    left: Vec<(usize, ConjBound)>,
}

/// The checks every piece gets before it is split: its intermediate bounds, each open
/// case's constraint bounds (alpha-CROWN and the combination LP), the constant fates,
/// the candidate points (centre, LP minimiser, minimising corners) and a short local
/// attack. `Err` with what decided the piece (closed, a point, late), else what is left.
fn settle(
    maps: &[(Affine, bool)],
    cases: &[Case],
    w: Work,
    s: &Settings,
    deadline: Option<Instant>,
) -> Result<Settled, Piece> {
    let alpha_iters = s.alpha_iters;
    let late = || deadline.is_some_and(|d| Instant::now() >= d);
    if late() {
        return Err(Piece::Late);
    }
    let Work {
        lo,
        hi,
        bounds,
        fin,
        lins,
        open,
        depth,
        ..
    } = w;
    PROF[P_MAXDEPTH].fetch_max(depth as u64, AtOrd::Relaxed);
    let tp = Instant::now();
    let (pre, lins) = match (bounds, fin, lins) {
        (Some(b), true, Some(l)) => (b, l),
        (b, _, _) => {
            let (p, l) = piece_bounds_lin(maps, &lo, &hi, b.as_deref(), deadline);
            (Arc::new(p), Arc::new(l))
        }
    };
    prof_add(P_OWNB, tp);
    let tp = Instant::now();
    let mut left = open_bounds(maps, cases, &open, &pre, &lo, &hi, alpha_iters, deadline);
    prof_add(P_ALPHA, tp);
    // Constraints whose bound is exactly at 0 on the piece (an output exactly 0 there
    // against a strict inequality, two identical outputs compared): the bounds above
    // always widen by a possible rounding and never close them; bounds rounded only
    // where inexact ([`crate::constant`]) decide them.
    // One interval pass for all the piece's cases, given up past the deadline (then the
    // cases stay open; the caller sees the time limit).
    // The pass costs about as much as the piece's CROWN bounds, and decides something
    // only in two situations, which are checked first: a constraint whose bound is within
    // rounding of 0 (`Never` possible), or a case that every point of the piece
    // satisfies (`Always`), which then nearly holds at the centre.
    let settled = match left.is_empty() || !constant_fates_may_decide(maps, cases, &left, &lo, &hi)
    {
        true => None,
        false => crate::constant::layer_intervals_until(maps, &lo, &hi, deadline),
    };
    if let Some(iv) = settled {
        let centre: Vec<f64> = lo.iter().zip(&hi).map(|(a, b)| 0.5 * (a + b)).collect();
        let mut everywhere = None;
        left.retain(|(ci, _)| {
            let f = crate::constant::fates_given(maps, &cases[*ci].constraints, &iv);
            if f.iter().all(|f| *f == crate::constant::Fate::Always) {
                everywhere.get_or_insert(*ci);
            }
            !f.contains(&crate::constant::Fate::Never)
        });
        if let Some(ci) = everywhere {
            // Every point of the piece satisfies the case: its centre is one (the caller
            // re-checks it exactly).
            FOUND_BY.store(6, AtOrd::Relaxed);
            return Err(Piece::Found(ci, centre));
        }
    }
    if left.is_empty() {
        PROF[P_CLOSED].fetch_add(1, AtOrd::Relaxed);
        return Err(Piece::Closed);
    }
    let tp = Instant::now();
    let centre: Vec<f64> = lo.iter().zip(&hi).map(|(a, b)| 0.5 * (a + b)).collect();
    let mut candidates = vec![centre.clone()];
    for (_, b) in &left {
        candidates.extend(b.x.iter().cloned());
        if let Some(f) = &b.f {
            candidates.push(f.argmin_corner(&lo, &hi));
        }
    }
    for x in &candidates {
        let y = forward(maps, x, None);
        if let Some((ci, _)) = left
            .iter()
            .find(|(ci, _)| satisfies(&cases[*ci].constraints, &y))
        {
            FOUND_BY.store(3, AtOrd::Relaxed);
            return Err(Piece::Found(*ci, x.clone()));
        }
    }
    // The most promising case: the lowest bound (closest to holding a point).
    let (pci, pb) = left
        .iter()
        .min_by(|a, b| a.1.lb.total_cmp(&b.1.lb))
        .expect("some case is open");
    let Some(pf) = &pb.f else {
        // An empty conjunction holds at the centre: found above.
        return Err(Piece::Stuck);
    };
    // A short local attack from where the most promising bounds point.
    let start = pb.x.clone().unwrap_or_else(|| pf.argmin_corner(&lo, &hi));
    if let Some(x) = pgd(
        maps,
        &cases[*pci].constraints,
        &lo,
        &hi,
        start,
        10,
        deadline,
    ) {
        FOUND_BY.store(4, AtOrd::Relaxed);
        return Err(Piece::Found(*pci, x));
    }
    prof_add(P_PGD, tp);
    if late() {
        return Err(Piece::Late);
    }
    Ok(Settled {
        lo,
        hi,
        depth,
        pre,
        lins,
        left,
    })
}

fn examine(
    maps: &[(Affine, bool)],
    cases: &[Case],
    w: Work,
    s: &Settings,
    deadline: Option<Instant>,
) -> Piece {
    let late = || deadline.is_some_and(|d| Instant::now() >= d);
    let Settled {
        lo,
        hi,
        depth,
        pre,
        lins,
        left,
    } = match settle(maps, cases, w, s, deadline) {
        Ok(st) => st,
        Err(p) => return p,
    };
    let (pci, pb) = left
        .iter()
        .min_by(|a, b| a.1.lb.total_cmp(&b.1.lb))
        .expect("some case is open");
    let Some(pf) = &pb.f else {
        return Piece::Stuck;
    };
    let open: Vec<usize> = left.iter().map(|l| l.0).collect();
    let nu = crate::phases::unstable(maps, &pre).len();
    if nu <= s.phase_max_unstable {
        let tp = Instant::now();
        let mut nodes = 0;
        let r = crate::phases::split_phases(
            maps,
            cases,
            &open,
            &pre,
            &lo,
            &hi,
            s.phase_budget,
            deadline,
            &mut nodes,
        );
        prof_add(P_PHASE, tp);
        PROF[P_PHASE_NODES].fetch_add(nodes, AtOrd::Relaxed);
        match r {
            crate::phases::PhaseResult::Closed => {
                PROF[P_PHASE_CLOSED].fetch_add(1, AtOrd::Relaxed);
                return Piece::Closed;
            }
            crate::phases::PhaseResult::Found(ci, x) => {
                FOUND_BY.store(5, AtOrd::Relaxed);
                return Piece::Found(ci, x);
            }
            crate::phases::PhaseResult::Thin => return Piece::Thin,
            crate::phases::PhaseResult::GaveUp => {}
        }
    }
    // The look-ahead scores the splits by one case, the most promising one (the others
    // close along the way or take over once it is closed): scoring by the sum over the
    // open cases favours splits that help the case with the largest scale, and on ACAS
    // Xu property 5 took fifteen times the pieces of separate searches.
    let driver = *pci;
    let deficit = (-pb.lb).max(0.0);
    let refine = s.look_refine;
    let tp = Instant::now();
    // Branching by look-ahead: split every input at its midpoint and score the split by
    // what is left to prove in its two halves. First cheaply, for every input: the halves'
    // bounds are this piece's CROWN functions minimised over each half
    // ([`symbolic::reconcretise`]), then the open cases' CROWN bounds over those. Then the
    // `refine` best of those splits again with full CROWN bounds of both halves (their
    // earlier layers' relaxations tightened too), which decide among them; the chosen
    // halves keep their bounds, so they are not computed again.
    let only_full = refine > 0 && lo.len() == 1;
    let trial = |t: usize, full: bool| -> Option<Try> {
        // One trial bounds two halves by full CROWN: on a wide network with many
        // inputs the whole look-ahead takes minutes, so each trial checks the clock.
        if late() {
            return None;
        }
        let mid = 0.5 * (lo[t] + hi[t]);
        if !(mid > lo[t] && mid < hi[t]) {
            return None;
        }
        let (mut h1, mut l2) = (hi.clone(), lo.clone());
        h1[t] = mid;
        l2[t] = mid;
        let mut halves = Vec::with_capacity(2);
        let mut total = 0.0;
        // The two halves in parallel (the search's batches are small when most halves
        // close, so this is where the second core finds work); in order after.
        let bounded: Vec<_> = vec![(&lo, &h1), (&l2, &hi)]
            .into_par_iter()
            .map(|(a, b)| {
                // The cheap bounds are sound on the half: full CROWN starts from them.
                let cheap = symbolic::reconcretise(&pre, &lins, a, b);
                if full {
                    // A half the cheap bounds already close needs no full ones (on ACAS
                    // Xu property 1 most refined splits close one half that way).
                    let hl = open_bounds(maps, cases, &open, &cheap, a, b, 0, deadline);
                    if hl.is_empty() {
                        return (a, b, cheap, None, hl);
                    }
                    let (p, l) = match only_full {
                        // With one input a half's box is an interval: the forward
                        // symbolic pass (linear functions of the one input, ReluVal's
                        // symbolic intervals, Wang et al. 2018) within the parent's bounds
                        // costs two forward passes, against one backward pass per
                        // unstable neuron for CROWN. On nn4sys's normal_1000 (row 61) it
                        // split the same 73 pieces to the same depth 23 with a tenth of
                        // the look-ahead's time. No linear functions are kept: the next
                        // look-ahead starts from these bounds as they are.
                        true => {
                            let p = symbolic::hidden_pre_until(maps, a, b, Some(&cheap), deadline);
                            let l: symbolic::PreLinear =
                                p.iter().map(|layer| vec![None; layer.len()]).collect();
                            (p, l)
                        }
                        false => piece_bounds_lin(maps, a, b, Some(&cheap), deadline),
                    };
                    let hl = open_bounds(maps, cases, &open, &p, a, b, 0, deadline);
                    (a, b, p, Some(Arc::new(l)), hl)
                } else {
                    let hl = open_bounds(maps, cases, &open, &cheap, a, b, 0, deadline);
                    (a, b, cheap, None, hl)
                }
            })
            .collect();
        for (a, b, bd, bl, hl) in bounded {
            total += hl
                .iter()
                .find(|h| h.0 == driver)
                .map(|h| (-h.1.lb).max(0.0))
                .unwrap_or(0.0);
            if hl.is_empty() {
                continue;
            }
            halves.push(Work {
                lo: a.clone(),
                hi: b.clone(),
                bounds: Some(Arc::new(bd)),
                fin: full,
                lins: bl,
                key: hl.iter().map(|h| h.1.lb).fold(f64::INFINITY, f64::min),
                depth: depth + 1,
                open: hl.into_iter().map(|h| h.0).collect(),
            });
        }
        // What is left to prove in each half (0 once closed); the split that leaves
        // the least in total wins, so closing one half outright counts fully.
        Some((-total + 1e-12 * (hi[t] - lo[t]), halves, t, full))
    };
    // With one input (nn4sys) there is one split: its cheap score would only rank it
    // against itself before the full bounds replace it, so it goes straight to the full
    // bounds (the same choice and halves, one cheap pass over the open cases fewer).
    let mut tries: Vec<Try> = (0..lo.len())
        .into_par_iter()
        .filter_map(|t| trial(t, only_full))
        .collect();
    if refine > 0 && !only_full && !tries.is_empty() {
        tries.sort_by(|a, b| b.0.total_cmp(&a.0));
        let k = refine.min(tries.len());
        let refined: Vec<Option<Try>> = tries[..k].par_iter().map(|tr| trial(tr.2, true)).collect();
        for (slot, r) in tries.iter_mut().zip(refined) {
            if let Some(r) = r {
                *slot = r;
            }
        }
    }
    prof_add(P_LOOK, tp);
    if late() {
        return Piece::Late;
    }
    // When no split makes real progress (less than 1% of the piece's own deficit, counted
    // for both halves), the look-ahead only sees rounding noise and would keep cutting
    // already thin sides: split by smear instead (|coefficient| * width of the most
    // promising constraint's bound), so every side keeps shrinking.
    let parent_deficit = 2.0 * deficit;
    // Refined and cheap scores are not comparable: only the refined ones compete when
    // there are any.
    let any_full = tries.iter().any(|t| t.3);
    let competes = |t: &Try| t.3 || !any_full;
    let best = tries
        .iter()
        .filter(|t| competes(t))
        .map(|t| t.0)
        .fold(f64::NEG_INFINITY, f64::max);
    let stalled = best + parent_deficit <= 0.01 * parent_deficit;
    let pick = if stalled {
        let sm = |t: usize| pf.coef[t].abs() * (hi[t] - lo[t]) + 1e-300;
        tries
            .iter()
            .enumerate()
            .max_by(|a, b| sm(a.1 .2).total_cmp(&sm(b.1 .2)))
            .map(|(i, _)| i)
    } else {
        tries
            .iter()
            .enumerate()
            .filter(|t| competes(t.1))
            .max_by(|a, b| a.1 .0.total_cmp(&b.1 .0))
            .map(|(i, _)| i)
    };
    match pick {
        Some(i) => Piece::Split(tries.swap_remove(i).1),
        None => Piece::Stuck,
    }
}

/// Decide the query: is there a case with a point? Cases are searched in order.
pub fn solve(maps: &[(Affine, bool)], cases: &[Case], s: &Settings) -> (Outcome, Stats) {
    let t0 = Instant::now();
    let profile = std::env::var_os("SAMARA_SEARCH_PROFILE").is_some();
    if profile {
        PROF.iter().for_each(|p| p.store(0, AtOrd::Relaxed));
        FOUND_BY.store(0, AtOrd::Relaxed);
    }
    let (o, st) = solve_inner(maps, cases, s);
    if profile {
        let ms = |k: usize| PROF[k].load(AtOrd::Relaxed) as f64 * 1e-6;
        eprintln!(
            "profile: {:.0} ms wall, {} cases, {} pieces, {} closed, max depth {}; \
             cpu ms: attack {:.0}, own bounds {:.0}, alpha+comb {:.0} (comb {:.0}), \
             pgd {:.0}, look-ahead {:.0}, phases {:.0} ({} closed, {} nodes); outcome {:?} (found by {})",
            t0.elapsed().as_secs_f64() * 1e3,
            cases.len(),
            st.pieces,
            PROF[P_CLOSED].load(AtOrd::Relaxed),
            PROF[P_MAXDEPTH].load(AtOrd::Relaxed),
            ms(P_ATTACK),
            ms(P_OWNB),
            ms(P_ALPHA),
            ms(P_COMB),
            ms(P_PGD),
            ms(P_LOOK),
            ms(P_PHASE),
            PROF[P_PHASE_CLOSED].load(AtOrd::Relaxed),
            PROF[P_PHASE_NODES].load(AtOrd::Relaxed),
            match &o {
                Outcome::Violated(CasePoint { .. }) => "point".to_string(),
                o => format!("{o:?}"),
            },
            FOUND_BY.load(AtOrd::Relaxed)
        );
    }
    (o, st)
}

/// Fewest gradient steps of a start of an attack burst on many inputs
/// ([`Bursts::steps`]).
const BURST_MIN_STEPS: usize = 10;

/// The attack bursts during a search (see [`Settings::attack_seconds`]).
struct Bursts {
    last: Instant,
    count: u64,
    /// Wall seconds of one gradient step of one attack job in the last burst.
    step_cost: Option<f64>,
    /// The first case of the next burst when a burst attacks only some of the cases.
    next: usize,
}

/// Cases per thread up to which the long first burst (ten times
/// [`Settings::attack_seconds`] a case) is not shared among the cases ([`Bursts::run`]).
const BURST_FULL_CASES: f64 = 4.0;

impl Bursts {
    fn new() -> Self {
        Bursts {
            last: Instant::now(),
            count: 0,
            step_cost: None,
            next: 0,
        }
    }

    /// Gradient steps of each start of a burst of `per_case` seconds. On many inputs
    /// (images, [`SIGN_STEP_INPUTS`]) what the budget buys at the wall time of a step that
    /// the last burst took, between [`BURST_MIN_STEPS`] and `s.steps`: a start runs its
    /// steps in full whatever the budget ([`attack`]), so on a CIFAR convolution
    /// (oval21's deep network, 2-6 ms a step on a loaded machine) every burst's 60 steps
    /// took 5-7 times its 0.044 s. The first burst, and every burst on small networks
    /// (microseconds a step: collins_rul_cnn's `if_then` point is found by the first
    /// burst's 8,000 steps) keep `s.steps`, as does the first attack on many inputs
    /// before the search, which finds the points of the `sat` instances of verivital and
    /// oval21 (on few inputs the first burst is sized by the first attack's cost, below). PGD given fewer steps takes longer ones (its step shrinks over the steps
    /// given; Madry et al., ICLR 2018).
    ///
    /// On few inputs the same rule, from the last burst's (or the first attack's) cost of
    /// a step of one job: a step of ACAS Xu's networks takes microseconds, so a burst's
    /// budget buys `s.steps` and nothing changes; on nn4sys's large networks (37 million
    /// weights) a step took 3.9 ms, and each of the 50 cases' one start of 60 steps made
    /// every burst 10-12 s on one core whatever its budget (0.002 s a case).
    fn steps(&self, cases: &[Case], s: &Settings, per_case: f64) -> usize {
        match (cases.first(), self.step_cost) {
            (Some(_), Some(cost)) if cost > 0.0 => {
                let buys = (per_case / cost).min(s.steps as f64) as usize;
                buys.clamp(BURST_MIN_STEPS.min(s.steps), s.steps.max(1))
            }
            _ => s.steps,
        }
    }

    /// A fresh attack burst when one is due, shared by all cases so bursts stay a small
    /// share of the search however many cases there are; the violation when it finds a
    /// point. `closed` counts the pieces closed so far.
    #[allow(clippy::too_many_arguments)]
    fn run(
        &mut self,
        maps: &[(Affine, bool)],
        cases: &[Case],
        s: &Settings,
        t0: Instant,
        round: u64,
        closed: u64,
        stats: &mut Stats,
        deadline: Option<Instant>,
    ) -> Option<Outcome> {
        let interval = (0.25 * t0.elapsed().as_secs_f64()).max(0.5);
        if self.last.elapsed().as_secs_f64() < interval {
            return None;
        }
        let share = rayon::current_num_threads().max(1) as f64 / cases.len().max(1) as f64;
        let mut per_case = (0.15 * interval).min(4.0 * s.attack_seconds) * share.min(1.0);
        // The first burst is long when hardly any piece has closed yet (fewer than 1 in
        // 10, halves closed by the look-ahead included): the search is then making no
        // headway, which is typical of a query with points (ACAS Xu properties 7 and 8),
        // where the attack is the faster way to one.
        // On few inputs, beyond `BURST_FULL_CASES` cases per thread its budget is shared
        // like the others' (ACAS Xu's properties have at most 4 cases; nn4sys's 50 made
        // it 25 s of one core). Cases over one box (images) are attacked together.
        let few = cases.first().is_some_and(|c| c.lo.len() < SIGN_STEP_INPUTS);
        if self.count == 0 && closed * 10 < stats.pieces {
            let shared = if few { BURST_FULL_CASES * share } else { 1.0 };
            per_case = 10.0 * s.attack_seconds * shared.min(1.0);
        } else if closed * 2 >= stats.pieces {
            // A search that closes at least every second piece examined is on its way to
            // a proof or to its point (the pieces' candidates and local attacks find
            // those): its bursts are halved, 7.5% of the interval instead of 15%.
            per_case *= 0.5;
        }
        self.count += 1;
        let steps = self.steps(cases, s, per_case);
        // Every attacked case runs one start in full, so a burst takes at least its cases'
        // share of a thread times one start: when that exceeds the burst's budget (the
        // wall time its cases' `per_case` seconds take on the threads), only as many cases
        // as the budget buys are attacked (at least one per thread), the next burst going
        // on from there, so that bursts stay their share of the search.
        let threads = rayon::current_num_threads().max(1);
        let n = cases.len();
        let take = match self.step_cost {
            Some(cost) if few && cost > 0.0 && n > threads => {
                let wall = per_case * n.div_ceil(threads) as f64;
                let rounds = (wall / (cost * steps as f64)).floor().max(1.0);
                ((rounds as usize).saturating_mul(threads)).min(n)
            }
            _ => n,
        };
        let from = if take < n { self.next % n } else { 0 };
        let to = (from + take).min(n);
        self.next = to % n.max(1);
        let (found, cost) = attack_all(
            maps,
            &cases[from..to],
            s,
            round,
            per_case,
            steps,
            stats,
            deadline,
        );
        let found = found.map(|(ci, x)| (from + ci, x));
        self.step_cost = cost.or(self.step_cost);
        self.last = Instant::now();
        found.map(|(ci, x)| {
            let y = forward(maps, &x, None);
            FOUND_BY.store(2, AtOrd::Relaxed);
            Outcome::Violated(CasePoint { case: ci, x, y })
        })
    }
}

/// From this many inputs on (images), a box left open by its own bounds is decided by
/// ReLU splitting ([`crate::relusplit`]) instead of input splitting: halving one input
/// of hundreds hardly tightens a bound, and the look-ahead's trial of every input costs
/// more than the whole bound.
const RELU_SPLIT_INPUTS: usize = SIGN_STEP_INPUTS;

/// From this many inputs on, a network with a single ReLU layer is decided by ReLU
/// splitting, with the phases as LP constraints ([`crate::relusplit::Tree::lp_bounds`]).
/// On VNN-COMP 2024 safenlp (30 inputs, 128 ReLUs), input splitting left 9 of 54
/// instances (every 20th) open at 20 s, halving boxes to depth 50; ReLU splitting with
/// LP bounds proves all 9 in 0.4-7 CPU seconds each (bench/vnncomp/results_safenlp_2024_x1.md).
/// Below 16 inputs input splitting keeps them (not measured there).
const ONE_LAYER_RELU_INPUTS: usize = 16;

/// Whether [`solve_inner`] decides the boxes of `cases` by ReLU splitting
/// ([`solve_relu`]) rather than input splitting: on [`RELU_SPLIT_INPUTS`] inputs or
/// more, and on [`ONE_LAYER_RELU_INPUTS`] or more when the network has a single ReLU
/// layer (there every pre-activation bound over a box is exact, and what is left to
/// gain is in the output layer's relaxation, which ReLU splitting removes).
fn relu_split_route(maps: &[(Affine, bool)], cases: &[Case]) -> bool {
    let n = cases.first().map_or(0, |c| c.lo.len());
    let one_layer = maps.iter().filter(|m| m.1).count() == 1;
    n >= RELU_SPLIT_INPUTS || (one_layer && n >= ONE_LAYER_RELU_INPUTS)
}

/// The search of [`solve_inner`] for boxes with many inputs: per box, the checks of
/// [`settle`] on the whole box, then ReLU splitting of the cases left open, in parallel
/// batches, with the same attack bursts.
fn solve_relu(
    maps: &[(Affine, bool)],
    cases: &[Case],
    s: &Settings,
    t0: Instant,
    mut stats: Stats,
) -> (Outcome, Stats) {
    use crate::relusplit::{self, NodeOut};
    let deadline = s.timeout.deadline_from(t0);
    let out_of_time = || s.timeout.expired(t0, Instant::now());
    let mut bursts = Bursts::new();
    let mut stuck = false;
    let mut batches = 0u64;
    let mut closed = 0u64;
    let violated = |ci: usize, x: Vec<f64>| {
        let y = forward(maps, &x, None);
        Outcome::Violated(CasePoint { case: ci, x, y })
    };
    for group in box_groups(cases) {
        let c0 = &cases[group[0]];
        let w = Work {
            lo: c0.lo.clone(),
            hi: c0.hi.clone(),
            bounds: None,
            fin: false,
            lins: None,
            key: f64::NEG_INFINITY,
            depth: 0,
            open: group,
        };
        stats.pieces += 1;
        let st = match settle(maps, cases, w, s, deadline) {
            Ok(st) => st,
            Err(Piece::Closed) => {
                closed += 1;
                continue;
            }
            Err(Piece::Found(ci, x)) => return (violated(ci, x), stats),
            Err(Piece::Late) => return (Outcome::Unknown(StopReason::Timeout), stats),
            Err(_) => {
                stuck = true;
                continue;
            }
        };
        // The intermediate bounds are shared by every node below: optimise them once
        // (alpha-CROWN per neuron), within a quarter of the time left.
        let mut pre = st.pre.to_vec();
        let left_s = deadline.map(|d| d.saturating_duration_since(Instant::now()));
        let pre_deadline = left_s.map(|l| Instant::now() + l / 4);
        let deep = deep_split(maps, st.lo.len());
        // Dense deep networks only: their early-layer branching gains through the
        // later layers' re-bounds ([`crate::relusplit::Deep`]).
        let node_slopes = RELU_NODE_SLOPES && deep.is_some();
        let far = deep.is_some() && st.left.iter().all(|l| l.1.lb < REFINE_FAR_BOUND);
        let ascent = if far { FAR_PRE_ASCENT } else { RELU_PRE_ASCENT };
        let mut slopes = symbolic::alpha_pre_with(
            maps,
            &mut pre,
            &st.lo,
            &st.hi,
            RELU_PRE_ITERS,
            ascent,
            node_slopes,
            pre_deadline,
        );
        let open: Vec<usize> = st.left.iter().map(|l| l.0).collect();
        if std::env::var_os("SAMARA_SEARCH_PROFILE").is_some() {
            let un = crate::phases::unstable(maps, &st.pre).len();
            let un2 = crate::phases::unstable(maps, &pre).len();
            let lbs: Vec<String> = st
                .left
                .iter()
                .map(|l| format!("{}:{:.3}", l.0, l.1.lb))
                .collect();
            for (k, (a, b)) in st.pre.iter().zip(&pre).enumerate() {
                let cnt = |v: &Vec<(f64, f64)>| v.iter().filter(|x| x.0 < 0.0 && x.1 > 0.0).count();
                let wid =
                    |v: &Vec<(f64, f64)>| v.iter().map(|x| x.1 - x.0).sum::<f64>() / v.len() as f64;
                eprintln!(
                    "layer {k}: crown {} unstable, width {:.3}; alpha {} width {:.3}",
                    cnt(a),
                    wid(a),
                    cnt(b),
                    wid(b)
                );
            }
            eprintln!(
                "relu split: {un} unstable, {un2} after alpha, open {lbs:?} after {:.2} s",
                t0.elapsed().as_secs_f64()
            );
        }
        // A tree per case: its splits are chosen for its own bound (a joint tree
        // branches for the worst case and bounds every case at every node).
        let mut heap: std::collections::BinaryHeap<_> =
            open.iter().map(|&ci| relusplit::root(vec![ci])).collect();
        let batch = (2 * rayon::current_num_threads()).max(2);
        // Deep dense networks: a tree that does not close within [`REFINE_AFTER_BATCHES`]
        // batches (and [`REFINE_AFTER_SHARE`] of the time) starts again over refined
        // bounds ([`refine_root`]; the nodes it closed are counted once more); within
        // [`REFINE_FAR_AFTER_BATCHES`] when every open case's bound at the whole box is
        // below [`REFINE_FAR_BOUND`].
        let mut refined = deep.is_none();
        loop {
            let tree = relusplit::Tree {
                maps,
                cases,
                pre: &pre,
                lo: &st.lo,
                hi: &st.hi,
                root_iters: RELU_ROOT_ITERS,
                iters: RELU_NODE_ITERS,
                lp_bounds: st.lo.len() < RELU_SPLIT_INPUTS,
                intercept: symbolic::Sparse::applies(maps, st.lo.len()),
                deep,
                pre_slopes: node_slopes.then_some(&slopes),
                lp_depth: deep
                    .filter(|_| st.lo.len() <= relusplit::EXACT_LP_INPUTS)
                    .map(|_| DEEP_LP_DEPTH),
                closed_share: std::sync::Mutex::new(0.0),
            };
            // The plain tree stops for the refinement after REFINE_AFTER_BATCHES
            // batches and REFINE_AFTER_SHARE of the time left at its start (far:
            // REFINE_FAR_AFTER_BATCHES batches).
            let start = Instant::now();
            let refine_at = deadline.filter(|_| !far).map(|d| {
                start
                    + d.saturating_duration_since(start)
                        .mul_f64(REFINE_AFTER_SHARE)
            });
            let after = if far {
                REFINE_FAR_AFTER_BATCHES
            } else {
                REFINE_AFTER_BATCHES
            };
            let go_on =
                |b: u64| refined || b < after || refine_at.is_some_and(|t| Instant::now() < t);
            let mut phase_batches = 0u64;
            while !heap.is_empty() && go_on(phase_batches) {
                if out_of_time() {
                    PROF[P_CLOSED].fetch_add(closed, AtOrd::Relaxed);
                    return (Outcome::Unknown(StopReason::Timeout), stats);
                }
                if s.max_pieces > 0 && stats.pieces >= s.max_pieces {
                    return (Outcome::Unknown(StopReason::PieceLimit), stats);
                }
                batches += 1;
                phase_batches += 1;
                if let Some(found) =
                    bursts.run(maps, cases, s, t0, batches, closed, &mut stats, deadline)
                {
                    return (found, stats);
                }
                let take = batch.min(heap.len());
                let nodes: Vec<_> = (0..take).filter_map(|_| heap.pop()).collect();
                stats.pieces += nodes.len() as u64;
                for r in relusplit::examine_batch(&tree, nodes, deadline) {
                    match r {
                        NodeOut::Closed => closed += 1,
                        NodeOut::Found(ci, x) => {
                            FOUND_BY.store(7, AtOrd::Relaxed);
                            return (violated(ci, x), stats);
                        }
                        NodeOut::Split(ch) => {
                            PROF[P_MAXDEPTH].fetch_max(ch[0].depth() as u64, AtOrd::Relaxed);
                            heap.extend(ch)
                        }
                        NodeOut::Stuck => stuck = true,
                        NodeOut::Late => return (Outcome::Unknown(StopReason::Timeout), stats),
                    }
                }
            }
            if heap.is_empty() || refined {
                break;
            }
            refined = true;
            let share = if far {
                REFINE_FAR_SHARE
            } else {
                REFINE_LATE_SHARE
            };
            slopes = refine_root(
                maps,
                &mut pre,
                &st.lo,
                &st.hi,
                node_slopes,
                ascent,
                share,
                deadline,
            );
            heap = open.iter().map(|&ci| relusplit::root(vec![ci])).collect();
        }
    }
    PROF[P_CLOSED].fetch_add(closed, AtOrd::Relaxed);
    if stuck {
        (Outcome::Unknown(StopReason::Unsplittable), stats)
    } else {
        (Outcome::Proved, stats)
    }
}

/// The early-layer branching of ReLU splitting ([`crate::relusplit::Deep`]) on dense
/// networks (no map sparse enough for [`symbolic::Sparse`]) with at least
/// [`DEEP_RELU_LAYERS`] ReLU layers: the first half of them are the early ones, and the
/// earliest of those with unstable neurons is split first.
fn deep_split(maps: &[(Affine, bool)], inputs: usize) -> Option<crate::relusplit::Deep> {
    let relus = maps.iter().filter(|m| m.1).count();
    if relus < DEEP_RELU_LAYERS || symbolic::Sparse::applies(maps, inputs) {
        return None;
    }
    Some(crate::relusplit::Deep {
        depth: DEEP_EARLY_DEPTH,
        layers: relus / 2,
    })
}

/// Batches of a deep dense network's tree over alpha-CROWN's root bounds at least before
/// [`refine_root`] refines them and the tree starts again: the refinement costs 10-30
/// CPU-s on mnist_fc's 256x4 and 256x6, while `256x4` prop_3_0.05 closes in 19 batches
/// (1.1 CPU-s) without it (13.9 s wall with it first, 2026-11-28, i52-m).
const REFINE_AFTER_BATCHES: u64 = 50;
/// And the share of the time left at the tree's start it has spent first: on VNN-COMP
/// 2021 mnistfc `256x4` at x0.1 (30 s), prop_13_0.03 and prop_0_0.03 close in 10.1 s and
/// 6.4 s of main's plain tree, and took 29.1 s and 14.2 s with the refinement after 50
/// batches alone (2026-11-28, i52-m).
const REFINE_AFTER_SHARE: f64 = 0.4;
/// The share of the time left that [`refine_root`]'s trees may spend when the tree
/// stopped for them.
const REFINE_LATE_SHARE: f64 = 1.0 / 3.0;

/// Deep dense networks whose open cases are all bounded below this at the whole box
/// (alpha-CROWN) refine the root bounds after [`REFINE_FAR_AFTER_BATCHES`] batches,
/// within [`REFINE_FAR_SHARE`] of the time left: the rows the plain tree closes start
/// near 0 (VNN-COMP 2021 mnistfc `256x4` prop_13_0.03 -3.2..-4.3, prop_0_0.03
/// -3.6..-4.5, prop_5_0.03 -1.1..-1.5; 2022 mnist_fc `256x4` prop_3_0.05 -0.6..-1.0),
/// while `256x6` prop_3_0.05, which only the refinement closes, starts at -242..-292
/// (and the open `256x4` prop_0_0.05 at -17..-21, `256x6` prop_9_0.03 near -1000),
/// 2026-11-28, i53-m.
const REFINE_FAR_BOUND: f64 = -10.0;
/// Batches of the plain tree before the refinement of such rows: its first nodes' points
/// (2021 mnistfc `256x6` prop_3_0.05 is sat at the tree's ninth node, 9.1 s at load 8;
/// 25.1 s when the refinement came first, of its 30 s at x0.1).
const REFINE_FAR_AFTER_BATCHES: u64 = 5;
/// The share of the time left that [`refine_root`]'s trees may spend on such rows: their
/// plain tree gains nothing meanwhile.
const REFINE_FAR_SHARE: f64 = 0.75;

/// Nodes of each neuron's tree in [`refine_root`] ([`crate::refine::stabilise`]). On
/// mnist_fc `256x6` prop_3_0.05 (VeriNet unsat in 23 s; a timeout at 300 s here before)
/// 200 nodes proved 112 of the 142 neurons tried stable (7,734 nodes in all), the six
/// layers' unstable neurons went from 698 to 143, and the tree closed at its root: unsat
/// in 20.7 CPU-s, 30.6 s wall. With 50 nodes `256x4` prop_3_0.05's last layer kept 24
/// neurons unstable instead of 10 (2026-11-28, i52-m).
const REFINE_NODES: u64 = 200;
/// The most nodes of each neuron's tree, when [`refine_root`] has
/// [`REFINE_NODES_MAX_SECONDS`] or more: at the full VNN-COMP limits (300 s) the
/// refinement with 200 nodes ended after 18-42 s of the 225 it may spend, and the
/// trees it left open were the ones 1,000 nodes close. On VNN-COMP 2022 mnist_fc
/// (`verify-vnnlib --timeout 300 --threads 1`, 2026-11-28, i54-x) `256x4` prop_13_0.05's
/// last ReLU layer kept 210 of 236 neurons unstable with 200 nodes and 30 with 1,000,
/// and the row was proved in 135.8 s (a timeout at 300 s with 200; VeriNet 20 s);
/// prop_5_0.05, 39 -> 12 unstable, proved in 57.9 s (VeriNet 43 s).
const REFINE_NODES_MAX: u64 = 1000;
/// The refinement time from which each tree gets [`REFINE_NODES_MAX`] nodes; below it
/// the limit shrinks in proportion, to [`REFINE_NODES`] at the least (the x0.1 limits'
/// 20 s or so keep 200: `256x6` prop_3_0.05 closes in 17.5 s with them).
const REFINE_NODES_MAX_SECONDS: f64 = 120.0;

/// Nodes of each tree of [`crate::refine::tighten`], which moves the bounds of the neurons
/// a layer's [`crate::refine::stabilise`] left unstable halfway to an attack's extremes,
/// before the next layer is bounded. Narrower first layers stabilise the later ones: on
/// VNN-COMP 2022 mnist_fc `256x6` prop_8_0.05 (VeriNet unsat in 80 s) the sixth ReLU
/// layer kept 244 of 250 neurons unstable without it and 3 of 153 with it, and the row was
/// proved in 96.1 s; prop_9_0.03 (VeriNet 51 s) 256 -> 12 unstable, proved in 128.4 s
/// (both timeouts at 300 s before; `verify-vnnlib --timeout 300 --threads 1`,
/// 2026-11-28, i54-x).
const TIGHTEN_NODES: u64 = 30;

/// Nodes of each neuron's tree in a refinement that may take `budget` (none: no
/// limit): [`REFINE_NODES`] to [`REFINE_NODES_MAX`] in proportion to the time.
fn refine_nodes(budget: Option<std::time::Duration>) -> u64 {
    let Some(b) = budget else {
        return REFINE_NODES_MAX;
    };
    let share = (b.as_secs_f64() / REFINE_NODES_MAX_SECONDS).min(1.0);
    ((REFINE_NODES_MAX as f64 * share) as u64).clamp(REFINE_NODES, REFINE_NODES_MAX)
}

/// The root bounds of ReLU splitting on deep dense networks, refined: layer by layer,
/// alpha-CROWN's bounds of the layer (within a quarter of the time left, the slopes
/// moved by `ascent`), then the neurons no attack sees change sign proved stable by small
/// trees of their own ([`crate::refine::stabilise`], [`refine_nodes`] nodes each) and the
/// others' bounds tightened ([`crate::refine::tighten`]) before the next layer is
/// bounded over them; the trees within `share` of the time left. Returns the slopes of
/// the bounds (with `keep_slopes`, see [`symbolic::alpha_pre_with`]).
#[allow(clippy::too_many_arguments)]
fn refine_root(
    maps: &[(Affine, bool)],
    pre: &mut [Vec<(f64, f64)>],
    lo: &[f64],
    hi: &[f64],
    keep_slopes: bool,
    ascent: symbolic::Ascent,
    share: f64,
    deadline: Option<Instant>,
) -> symbolic::PreSlopes {
    let t = Instant::now();
    let budget = deadline.map(|d| d.saturating_duration_since(t).mul_f64(share));
    let refine_deadline = budget.map(|b| t + b);
    let nodes = refine_nodes(budget);
    let mut slopes: symbolic::PreSlopes = pre.iter().map(|l| vec![[None, None]; l.len()]).collect();
    let mut rs = Vec::new();
    for k in 1..pre.len() {
        let now = Instant::now();
        let alpha_deadline = deadline.map(|d| now + d.saturating_duration_since(now) / 4);
        let got = symbolic::alpha_pre_layers(
            maps,
            pre,
            lo,
            hi,
            k..k + 1,
            RELU_PRE_ITERS,
            ascent,
            keep_slopes,
            alpha_deadline,
        );
        slopes[k] = got[k].clone();
        // Each layer but the last within half the refinement's time left: the later
        // layers, nearly stable once bounded over the earlier ones' proofs, are cheap
        // and decisive.
        let now = Instant::now();
        let layer_deadline = refine_deadline.map(|d| {
            if k + 1 < pre.len() {
                now + d.saturating_duration_since(now) / 2
            } else {
                d
            }
        });
        rs.push(crate::refine::stabilise(
            maps,
            pre,
            lo,
            hi,
            k..=k,
            nodes,
            layer_deadline,
        ));
        let tg = crate::refine::tighten(maps, pre, lo, hi, k, TIGHTEN_NODES, layer_deadline);
        if std::env::var_os("SAMARA_SEARCH_PROFILE").is_some() {
            eprintln!("tighten layer {k}: {:?}", tg.layer);
            eprintln!(
                "refine layer {k}: {:?} after {:.2} s",
                rs.last().map(|r| &r.layers),
                t.elapsed().as_secs_f64()
            );
        }
    }
    if std::env::var_os("SAMARA_SEARCH_PROFILE").is_some() {
        eprintln!(
            "refine: {:?} in {:.2} s, then {:?} unstable",
            rs,
            t.elapsed().as_secs_f64(),
            pre.iter()
                .map(|l| l.iter().filter(|b| b.0 < 0.0 && b.1 > 0.0).count())
                .collect::<Vec<_>>()
        );
    }
    slopes
}

/// ReLU layers from which [`deep_split`] applies (mnistfc's 256x4 and 256x6; 256x2's
/// trees, solved within seconds, keep the output-bound branching; conv networks,
/// sparse, too).
const DEEP_RELU_LAYERS: usize = 3;
/// Nodes of ReLU splitting with fewer phases fixed branch in the early layers (on
/// mnist_fc `256x4` prop_3_0.05 depth 6 proves it in 1.1 CPU-s; 10, with alpha-CROWN
/// re-bounds of the later layers per node, in 5.7, and those re-bounds alone cost 5x).
/// With the root's slopes at the nodes ([`RELU_NODE_SLOPES`]) and the earliest layer
/// first, on `256x6` prop_9_0.03 (2026-11-28, branch i53-d, load 9, 300 s, about 99
/// CPU-s each) the map-0 splits took the first path's bound to about -3 by depth 12 and
/// left it there: depth 12 had closed 7e-9 of the tree over the refined root at the
/// end, depth 20 2e-5 (closed nodes from depth 17 on; 2e-5 at 90 s already, 5e-16 with
/// depth 12).
const DEEP_EARLY_DEPTH: u32 = 20;

/// Nodes of ReLU splitting on deep dense networks with at least this many phases fixed
/// also bound each open constraint by the LP over their phases' rows and hand its
/// multipliers to their children ([`crate::relusplit::Tree::lp_depth`]). On VNN-COMP
/// 2021 mnistfc `256x4` prop_5_0.03 (VeriNet unsat in 6 s; a timeout here before, 13,833
/// nodes in 90 s, 32.7 CPU-s) the tree closed in 4,356 nodes, 18.4 CPU-s; at depth 10
/// the LPs start below the early-layer branching of [`DEEP_EARLY_DEPTH`] (2026-11-28,
/// branch i51-m).
const DEEP_LP_DEPTH: u32 = 10;

/// Slope and multiplier optimisation steps of ReLU splitting's root node (from CROWN's
/// slopes) and of every later node (warm-started from its parent's).
const RELU_ROOT_ITERS: usize = 30;
const RELU_NODE_ITERS: usize = 10;
/// alpha-CROWN steps of each intermediate bound at the root of ReLU splitting (on
/// mnistfc 256x4 prop_0_0.03, 15 steps left 198 of 309 ReLUs unstable in 4 s, 30 steps
/// 184).
const RELU_PRE_ITERS: usize = 15;
/// Their optimiser. Adam (`Ascent::Adam(0.3)`, alpha-CROWN's own) gives much tighter
/// bounds for the same 15 passes: on mnist_fc (VNN-COMP 2022) `256x6` prop_3_0.05, 547
/// ReLUs left unstable instead of 698, the last ReLU layer's mean width 8.9 instead of
/// 93, and the root's case bounds about -14.7 instead of -78. It is not the default:
/// on `256x4` prop_3_0.05 (unsat in 74 nodes, 1.2 CPU-s, with these steps) the tree over
/// Adam's tighter bounds grew past 3,000 nodes and timed out at 40 s, as the early
/// splits of [`crate::relusplit::Deep`] stopped gaining (the nodes' CROWN re-bounds no
/// longer beat the root's bounds), and no undecided row was decided within 60 s
/// (2026-11-28, branch i50-m). Round 51 (i51-m) re-measured it with the LPs of
/// [`DEEP_LP_DEPTH`]: with Adam's root (with or without [`RELU_NODE_SLOPES`]), `256x4`
/// prop_3_0.05 was still open at 90 s (about 2,000 nodes, 17 CPU-s each), and the
/// three rows' deep nodes had 100-250 unstable neurons left, none with every one fixed
/// (so the exact LP of [`crate::exact`] was never reached): both stay off, but for the
/// rows far from holding ([`FAR_PRE_ASCENT`]).
const RELU_PRE_ASCENT: symbolic::Ascent = symbolic::Ascent::Normalised;
/// The optimiser of the intermediate bounds, at the root and in [`refine_root`], of deep
/// dense rows far from holding ([`REFINE_FAR_BOUND`]): Adam's tighter bounds, which cost
/// the near rows their early splits' gains (see [`RELU_PRE_ASCENT`]), help the far ones,
/// whose plain tree gains nothing anyway. On VNN-COMP 2022 mnist_fc (`verify-vnnlib
/// --threads 1`, 2026-11-28, i54-x), at 30 s the share of the trees closed went 3.7e-9 ->
/// 1.1e-3 on `256x4` prop_0_0.05 and 4.6e-6 -> 6.9e-5 on `256x6` prop_9_0.03; at 300 s
/// with 1,000-node refinement trees ([`REFINE_NODES_MAX`]) `256x4` prop_5_0.05 was proved
/// in 57.9 s instead of 67.1 s (prop_13_0.05: 135.8 s, 136.4 s).
const FAR_PRE_ASCENT: symbolic::Ascent = symbolic::Ascent::Adam(0.3);
/// Whether nodes of deep dense networks re-bound their later layers with the root's
/// intermediate slopes too ([`symbolic::rebound_with_slopes`]), after CROWN: the root's
/// alpha-CROWN bounds are far tighter than a node's CROWN re-bound (on mnist_fc `256x6`
/// prop_9_0.03 the last ReLU layer's mean width is 117 against CROWN's 477), so without
/// the slopes an early split reaches the later layers only where CROWN happens to beat
/// them. On that row (2026-11-28, branch i53-d, load 9, 90 s, no root refinement), with
/// the early splits in map 0 ([`deep_split`]), the first path's bound went from -298 to
/// -83..-134 at depth 12 with CROWN alone and to -17..-0.2 with the slopes, for 0.15-0.3
/// CPU-s a node more. Round 50 had it off: with the early splits chosen among the first
/// half of the layers by the output bound's score, it lost `256x4` prop_3_0.05 (over
/// 2,800 nodes at 40 s; 74 without); with the map-0 splits that row is proved in 1.8
/// CPU-s.
const RELU_NODE_SLOPES: bool = true;

/// The first attack's budget per case on boxes of fewer than [`SIGN_STEP_INPUTS`] inputs
/// (ACAS Xu), at most (seconds). Measured on the 47 `sat` instances of VNN-COMP 2021
/// ACAS Xu (`box_bench`, budget 2 s, load 10, so about 2.5 times slower than a quiet
/// machine): it found 39 points within 32 ms, five after 0.23-1.1 s (the search or a
/// later burst finds those too) and three not at all (the pieces' local attacks find
/// them). Every unsat instance (139 of 186) spends the whole budget, so the 0.05 s of
/// [`Settings::attack_seconds`] cost about 7 s of the benchmark's sum. The bursts, the
/// long first one included, keep the full budget.
const FEW_INPUTS_FIRST_ATTACK: f64 = 0.02;

fn solve_inner(maps: &[(Affine, bool)], cases: &[Case], s: &Settings) -> (Outcome, Stats) {
    let t0 = Instant::now();
    let mut stats = Stats::default();
    let out_of_time = |t0: &Instant| s.timeout.expired(*t0, Instant::now());
    // Attack every case first (in parallel): a cheap refutation beats any proof.
    let deadline = s.timeout.deadline_from(t0);
    let few_inputs = cases.first().is_some_and(|c| c.lo.len() < SIGN_STEP_INPUTS);
    let first = match few_inputs {
        true => s.attack_seconds.min(FEW_INPUTS_FIRST_ATTACK),
        false => s.attack_seconds,
    };
    // On few inputs a start runs `s.steps` in full however short the budget, so the
    // steps are what the budget buys at the cost of a step, three forward passes (the
    // fastest of three timed), between `BURST_MIN_STEPS` and `s.steps`: on ACAS Xu a
    // pass takes microseconds and nothing changes; on nn4sys's large networks (37
    // million weights) the 50 cases' 60 steps each took 11.6 s of one core at 12 s limits.
    let steps = match (few_inputs, cases.first()) {
        (true, Some(c)) => {
            let centre: Vec<f64> = c.lo.iter().zip(&c.hi).map(|(a, b)| 0.5 * (a + b)).collect();
            let pass = (0..3)
                .map(|_| {
                    let t = Instant::now();
                    std::hint::black_box(forward(maps, &centre, None));
                    t.elapsed().as_secs_f64()
                })
                .fold(f64::INFINITY, f64::min);
            let buys = first / (3.0 * pass).max(1e-12);
            (buys.min(s.steps as f64) as usize).clamp(BURST_MIN_STEPS.min(s.steps), s.steps.max(1))
        }
        _ => s.steps,
    };
    let (found, first_cost) = attack_all(maps, cases, s, 0, first, steps, &mut stats, deadline);
    if let Some((ci, x)) = found {
        let y = forward(maps, &x, None);
        FOUND_BY.store(1, AtOrd::Relaxed);
        return (Outcome::Violated(CasePoint { case: ci, x, y }), stats);
    }
    if out_of_time(&t0) {
        return (Outcome::Unknown(StopReason::Timeout), stats);
    }
    if relu_split_route(maps, cases) {
        return solve_relu(maps, cases, s, t0, stats);
    }
    // Cases with the same box share its pieces.
    let groups: Vec<(usize, Vec<usize>)> =
        box_groups(cases).into_iter().map(|g| (g[0], g)).collect();
    // Depth first over the pieces of every box together, the most promising first.
    let mut stuck = false;
    let mut thin = false;
    let mut heap: std::collections::BinaryHeap<Work> = groups
        .into_iter()
        .map(|(first, open)| Work {
            lo: cases[first].lo.clone(),
            hi: cases[first].hi.clone(),
            bounds: None,
            fin: false,
            lins: None,
            key: f64::NEG_INFINITY,
            depth: 0,
            open,
        })
        .collect();
    let deadline = s.timeout.deadline_from(t0);
    let mut batches = 0u64;
    let mut bursts = Bursts::new();
    // The bursts on few inputs are sized by the first attack's cost of a step
    // ([`Bursts::steps`]).
    bursts.step_cost = first_cost.filter(|_| few_inputs);
    let mut closed = 0u64;
    while !heap.is_empty() {
        if out_of_time(&t0) {
            return (Outcome::Unknown(StopReason::Timeout), stats);
        }
        if s.max_pieces > 0 && stats.pieces >= s.max_pieces {
            return (Outcome::Unknown(StopReason::PieceLimit), stats);
        }
        batches += 1;
        if let Some(found) = bursts.run(maps, cases, s, t0, batches, closed, &mut stats, deadline) {
            return (found, stats);
        }
        let take = s.batch.max(1).min(heap.len());
        let batch: Vec<Work> = (0..take).filter_map(|_| heap.pop()).collect();
        stats.pieces += batch.len() as u64;
        let results: Vec<Piece> = batch
            .into_par_iter()
            .map(|w| examine(maps, cases, w, s, deadline))
            .collect();
        for r in results {
            match r {
                Piece::Closed => closed += 1,
                Piece::Found(ci, x) => {
                    let y = forward(maps, &x, None);
                    return (Outcome::Violated(CasePoint { case: ci, x, y }), stats);
                }
                Piece::Split(ws) => {
                    // A half the look-ahead closed counts as closed: on ACAS Xu property
                    // 1 almost every piece closes that way, and counting only examined
                    // pieces made the first burst long (half a second on one core) on
                    // queries that were making headway.
                    closed += 2u64.saturating_sub(ws.len() as u64);
                    heap.extend(ws);
                }
                Piece::Stuck => stuck = true,
                Piece::Thin => thin = true,
                Piece::Late => return (Outcome::Unknown(StopReason::Timeout), stats),
            }
        }
    }
    if thin {
        (Outcome::Unknown(StopReason::ThinRegion), stats)
    } else if stuck {
        (Outcome::Unknown(StopReason::Unsplittable), stats)
    } else {
        (Outcome::Proved, stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    /// The refinement's trees keep [`REFINE_NODES`] at the x0.1 limits (about 20 s of
    /// refinement, where `256x6` prop_3_0.05 closes with them), get [`REFINE_NODES_MAX`]
    /// at the full ones (over two minutes) and without a limit, and never shrink as the
    /// budget grows.
    #[test]
    fn refinement_trees_grow_with_the_budget() {
        assert_eq!(refine_nodes(Some(Duration::from_secs(20))), REFINE_NODES);
        assert_eq!(
            refine_nodes(Some(Duration::from_secs(225))),
            REFINE_NODES_MAX
        );
        assert_eq!(refine_nodes(None), REFINE_NODES_MAX);
        let mut last = 0;
        for s in 0..400 {
            let n = refine_nodes(Some(Duration::from_secs(s)));
            assert!((REFINE_NODES..=REFINE_NODES_MAX).contains(&n) && n >= last);
            last = n;
        }
    }
}
