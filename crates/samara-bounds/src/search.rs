//! Input-domain branch and bound for box queries: is there an input `x` in a box whose
//! outputs satisfy every constraint of a conjunction (the VNN-LIB counterexample shape)?
//!
//! Per case (one input box, one conjunction over the outputs): a projected-gradient
//! attack (Madry et al., ICLR 2018) with seeded random restarts looks for a point first;
//! then the box is split, depth first and in parallel batches, along the input with the
//! largest smear `|coefficient| * width` of the objective's linear lower bound (ReluVal,
//! Wang et al., USENIX Security 2018). A piece is closed when the symbolic lower bound of
//! one constraint shows it cannot hold there ([`crate::symbolic`], sound in floating
//! point). A candidate point (the piece's centre, the minimising corner of each linear
//! bound) is reported only when its f64 evaluation satisfies every constraint with a
//! margin above the evaluation's own rounding error. Anything cut short (time, piece
//! budget) is [`Outcome::Unknown`] with its reason.

use crate::symbolic::{self, Objective};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use samara_nn::Affine;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Concrete pre-activation bounds of every map but the last.
type Bounds = Vec<Vec<(f64, f64)>>;

/// One output constraint `c . y + d <= 0` (or `< 0` when `strict`).
#[derive(Clone, Debug, PartialEq)]
pub struct OutputConstraint {
    /// The linear function.
    pub obj: Objective,
    /// Strict inequality.
    pub strict: bool,
}

/// One case of a query: an input box and a conjunction over the outputs. The query asks
/// whether some case has a point.
#[derive(Clone, Debug, PartialEq)]
pub struct Case {
    /// Lower ends of the input box.
    pub lo: Vec<f64>,
    /// Upper ends of the input box.
    pub hi: Vec<f64>,
    /// The conjunction (an empty one holds everywhere).
    pub constraints: Vec<OutputConstraint>,
}

/// Limits and choices of the search.
#[derive(Clone, Debug)]
pub struct Settings {
    /// Wall-clock limit (`None`: none).
    pub timeout: Option<Duration>,
    /// Most pieces examined over all cases (`0`: no limit).
    pub max_pieces: u64,
    /// Pieces per parallel batch.
    pub batch: usize,
    /// Random restarts of the attack per case.
    pub restarts: usize,
    /// Gradient steps per restart (a restart whose gradient vanishes, e.g. in a region
    /// where every ReLU of a layer is off, ends early: restarts are then cheap samples).
    pub steps: usize,
    /// Wall-clock budget of the attack per case, before the search (seconds); the
    /// search repeats a burst of the same length, with fresh starts, every 2 seconds.
    pub attack_seconds: f64,
    /// alpha-CROWN gradient steps for each piece's own constraint bounds (0: CROWN's
    /// slopes; the look-ahead always uses CROWN's, for speed).
    pub alpha_iters: usize,
    /// Seed of the attack's random starts.
    pub seed: u64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            timeout: Some(Duration::from_secs(60)),
            max_pieces: 0,
            batch: 32,
            restarts: 1_000_000,
            attack_seconds: 0.2,
            alpha_iters: 10,
            steps: 60,
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
}

/// The answer.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// No case has a point: the property holds.
    Empty,
    /// A point of case `case`, with the network's f64 outputs there.
    Point {
        /// Index of the case.
        case: usize,
        /// The input.
        x: Vec<f64>,
        /// The outputs.
        y: Vec<f64>,
    },
    /// Cut short.
    Unknown(StopReason),
}

/// Statistics of a search.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    /// Pieces whose bounds were computed.
    pub pieces: u64,
    /// Attack gradient steps taken.
    pub attack_steps: u64,
}

/// Evaluate the chain in f64, keeping each ReLU map's activation mask.
fn forward(maps: &[(Affine, bool)], x: &[f64], masks: Option<&mut Vec<Vec<bool>>>) -> Vec<f64> {
    let mut a = x.to_vec();
    let mut ms = Vec::new();
    for (m, r) in maps {
        let mut z = vec![0.0; m.out];
        m.apply_f64(&a, &mut z);
        if *r {
            ms.push(z.iter().map(|v| *v > 0.0).collect::<Vec<_>>());
            z.iter_mut().for_each(|v| *v = v.max(0.0));
        }
        a = z;
    }
    if let Some(out) = masks {
        *out = ms;
    }
    a
}

/// Gradient of `c . f(x)` at `x` (the active linear piece).
fn gradient(maps: &[(Affine, bool)], x: &[f64], c: &[f64]) -> Vec<f64> {
    let mut masks = Vec::new();
    forward(maps, x, Some(&mut masks));
    let mut g = c.to_vec();
    let mut mi = masks.len();
    for (m, r) in maps.iter().rev() {
        if *r {
            mi -= 1;
            for (gi, on) in g.iter_mut().zip(&masks[mi]) {
                if !on {
                    *gi = 0.0;
                }
            }
        }
        let mut next = vec![0.0; m.inp];
        for (i, gi) in g.iter().enumerate() {
            if *gi != 0.0 {
                for (j, nx) in next.iter_mut().enumerate() {
                    *nx += gi * m.w[i * m.inp + j];
                }
            }
        }
        g = next;
    }
    g
}

/// Whether `y` satisfies every constraint with a margin larger than the rounding error
/// of its f64 evaluation (`1e-9` relative to the magnitudes involved, far above the
/// error of the network's few thousand operations).
pub fn satisfies(cs: &[OutputConstraint], y: &[f64]) -> bool {
    cs.iter().all(|k| {
        let mut v = k.obj.d;
        let mut mag = k.obj.d.abs();
        for (c, yo) in k.obj.c.iter().zip(y) {
            v += c * yo;
            mag += (c * yo).abs();
        }
        v < -1e-9 * (1.0 + mag)
    })
}

/// Projected gradient descent from `x` on the summed violation
/// `sum_k max(0, g_k(f(x)) + margin)` of the conjunction (the gradient of every violated
/// constraint, not only the worst, so the steps do not oscillate between constraints),
/// with a step that shrinks over `steps`. Returns a point that satisfies every constraint.
fn pgd(
    maps: &[(Affine, bool)],
    cs: &[OutputConstraint],
    lo: &[f64],
    hi: &[f64],
    mut x: Vec<f64>,
    steps: usize,
) -> Option<Vec<f64>> {
    let n = lo.len();
    let no = cs.first().map(|k| k.obj.c.len()).unwrap_or(0);
    for step in 0..=steps {
        let y = forward(maps, &x, None);
        if satisfies(cs, &y) {
            return Some(x);
        }
        if step == steps {
            break;
        }
        let mut c = vec![0.0; no];
        for k in cs {
            let g = k.obj.d + k.obj.c.iter().zip(&y).map(|(c, v)| c * v).sum::<f64>();
            if g >= -1e-7 * (1.0 + g.abs()) {
                for (ci, kc) in c.iter_mut().zip(&k.obj.c) {
                    *ci += kc;
                }
            }
        }
        let g = gradient(maps, &x, &c);
        let gmax = g
            .iter()
            .zip(lo.iter().zip(hi))
            .map(|(gi, (a, b))| (gi * (b - a)).abs())
            .fold(0.0, f64::max);
        if gmax == 0.0 {
            break;
        }
        let eta = 0.5 * (1.0 - step as f64 / steps as f64) + 0.02;
        for t in 0..n {
            let w = hi[t] - lo[t];
            x[t] = (x[t] - eta * w * (g[t] * w / gmax)).clamp(lo[t], hi[t]);
        }
    }
    None
}

/// The attack: [`pgd`] from the centre and from seeded random starts, until
/// `s.restarts` starts or `s.attack_seconds` are spent. `round` varies the seed.
fn attack(
    maps: &[(Affine, bool)],
    case: &Case,
    s: &Settings,
    round: u64,
    stats: &mut Stats,
) -> Option<Vec<f64>> {
    let t0 = Instant::now();
    let mut rng =
        rand_chacha::ChaCha8Rng::seed_from_u64(s.seed ^ round.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let n = case.lo.len();
    for r in 0..s.restarts.max(1) {
        if r > 0 && t0.elapsed().as_secs_f64() > s.attack_seconds {
            break;
        }
        let x: Vec<f64> = (0..n)
            .map(|t| {
                if r == 0 && round == 0 {
                    0.5 * (case.lo[t] + case.hi[t])
                } else {
                    rng.gen_range(case.lo[t]..=case.hi[t])
                }
            })
            .collect();
        stats.attack_steps += s.steps as u64;
        if let Some(x) = pgd(maps, &case.constraints, &case.lo, &case.hi, x, s.steps) {
            return Some(x);
        }
    }
    None
}

/// A piece of a case's box, with intermediate bounds proved on it (`final`) or on a box
/// containing it (to be tightened).
struct Work {
    lo: Vec<f64>,
    hi: Vec<f64>,
    bounds: Option<Arc<Bounds>>,
    fin: bool,
    /// The best constraint bound known for the piece: among pieces of the same depth
    /// the lowest goes first (closest to holding a point).
    key: f64,
    /// Number of splits from the case's box: the deepest pieces go first (depth first,
    /// so the frontier stays small and pieces get cheap quickly).
    depth: u32,
    /// The case the piece belongs to.
    case: usize,
}

impl PartialEq for Work {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o).is_eq()
    }
}
impl Eq for Work {}
impl PartialOrd for Work {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Work {
    /// The max-heap pops the deepest piece, and of those the lowest key.
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.depth.cmp(&o.depth).then(o.key.total_cmp(&self.key))
    }
}

/// What one piece came to.
enum Piece {
    Closed,
    Found(Vec<f64>),
    Split(Work, Work),
    Stuck,
    /// Past the deadline before the piece was done.
    Late,
}

/// Full CROWN intermediate bounds of a piece, starting from bounds of a containing box.
fn piece_bounds(maps: &[(Affine, bool)], lo: &[f64], hi: &[f64], known: Option<&Bounds>) -> Bounds {
    let (_, _, fwd) = symbolic::hidden(maps, lo, hi, known.map(|v| &v[..]));
    symbolic::crown_pre(maps, lo, hi, Some(&fwd))
}

/// The best lower bound over the conjunction's constraints (the piece is closed when it
/// is positive, or non-negative for a strict constraint) and the constraint's bound.
fn best_bound(
    maps: &[(Affine, bool)],
    cs: &[OutputConstraint],
    pre: &Bounds,
    lo: &[f64],
    hi: &[f64],
    alpha_iters: usize,
) -> (f64, bool, Option<symbolic::Linear>) {
    let mut best: (f64, bool, Option<symbolic::Linear>) = (f64::NEG_INFINITY, false, None);
    let mut fs = Vec::with_capacity(cs.len());
    for k in cs {
        let f = if alpha_iters > 0 {
            symbolic::alpha_lower(maps, pre, &k.obj, lo, hi, alpha_iters)
        } else {
            symbolic::backward_lower(maps, pre, &k.obj, lo, hi)
        };
        let lb = f.min_over(lo, hi);
        let closed = if k.strict { lb >= 0.0 } else { lb > 0.0 };
        if closed {
            return (lb, true, Some(f));
        }
        if best.2.is_none() || lb > best.0 {
            best = (lb, false, Some(f.clone()));
        }
        fs.push(f);
    }
    // No single constraint is excluded: a non-negative combination `sum_k l_k g_k > 0`
    // everywhere still shows that the `g_k <= 0` never hold together.
    if fs.len() >= 2 && combination_certifies(&fs, lo, hi) {
        return (best.0, true, best.2);
    }
    best
}

/// Look for weights `l >= 0` with `min_x sum_k l_k f_k(x) > 0` over the box (a matrix
/// game between the weights and the box corners, played by multiplicative weights against
/// the best-response corner; Freund and Schapire, 1999), and certify the averaged weights
/// with the rigorous combination [`symbolic::Linear::combine`].
fn combination_certifies(fs: &[symbolic::Linear], lo: &[f64], hi: &[f64]) -> bool {
    let k = fs.len();
    let mut lam = vec![1.0 / k as f64; k];
    let mut avg = vec![0.0; k];
    let n = lo.len();
    for it in 1..=120 {
        let mut coef = vec![0.0; n];
        for (f, l) in fs.iter().zip(&lam) {
            for (c, fc) in coef.iter_mut().zip(&f.coef) {
                *c += l * fc;
            }
        }
        let corner: Vec<f64> = (0..n)
            .map(|t| if coef[t] < 0.0 { hi[t] } else { lo[t] })
            .collect();
        let vals: Vec<f64> = fs
            .iter()
            .map(|f| f.cst + f.coef.iter().zip(&corner).map(|(c, x)| c * x).sum::<f64>())
            .collect();
        let scale = vals.iter().fold(1e-300, |m: f64, v| m.max(v.abs()));
        let mut tot = 0.0;
        for (l, v) in lam.iter_mut().zip(&vals) {
            *l *= (0.5 * v / scale).exp();
            tot += *l;
        }
        for (a, l) in avg.iter_mut().zip(lam.iter_mut()) {
            *l /= tot;
            *a += *l;
        }
        if it % 20 == 0 {
            let mut h = fs[0].combine(avg[0], &fs[1], avg[1], lo, hi);
            for j in 2..k {
                h = h.combine(1.0, &fs[j], avg[j], lo, hi);
            }
            if h.min_over(lo, hi) > 0.0 {
                return true;
            }
        }
    }
    false
}

fn examine(
    maps: &[(Affine, bool)],
    cs: &[OutputConstraint],
    w: Work,
    alpha_iters: usize,
    deadline: Option<Instant>,
) -> Piece {
    let late = || deadline.is_some_and(|d| Instant::now() >= d);
    if late() {
        return Piece::Late;
    }
    let Work {
        lo,
        hi,
        bounds,
        fin,
        case,
        depth,
        ..
    } = w;
    let pre = match (bounds, fin) {
        (Some(b), true) => b,
        (b, _) => Arc::new(piece_bounds(maps, &lo, &hi, b.as_deref())),
    };
    let (lbv, closed, f) = best_bound(maps, cs, &pre, &lo, &hi, alpha_iters);
    if closed {
        return Piece::Closed;
    }
    let centre: Vec<f64> = lo.iter().zip(&hi).map(|(a, b)| 0.5 * (a + b)).collect();
    let mut candidates = vec![centre];
    if let Some(f) = &f {
        candidates.push(f.argmin_corner(&lo, &hi));
    }
    for x in &candidates {
        if satisfies(cs, &forward(maps, x, None)) {
            return Piece::Found(x.clone());
        }
    }
    // A short local attack from the corner that the most promising bound points at.
    if let Some(x) = pgd(maps, cs, &lo, &hi, candidates.pop().unwrap_or_default(), 10) {
        return Piece::Found(x);
    }
    if f.is_none() {
        // An empty conjunction holds at the centre: found above.
        return Piece::Stuck;
    }
    if late() {
        return Piece::Late;
    }
    // Branching by look-ahead: split every input at its midpoint, bound both halves with
    // full CROWN, keep the split that leaves the least to prove (ties: the widest input). The
    // chosen halves keep their bounds, so they are not computed again.
    let mut tries: Vec<(f64, Work, Work, usize)> = (0..lo.len())
        .into_par_iter()
        .filter_map(|t| {
            let mid = 0.5 * (lo[t] + hi[t]);
            if !(mid > lo[t] && mid < hi[t]) {
                return None;
            }
            let (mut h1, mut l2) = (hi.clone(), lo.clone());
            h1[t] = mid;
            l2[t] = mid;
            let b1 = piece_bounds(maps, &lo, &h1, Some(&pre));
            let b2 = piece_bounds(maps, &l2, &hi, Some(&pre));
            let s1 = best_bound(maps, cs, &b1, &lo, &h1, 0);
            let s2 = best_bound(maps, cs, &b2, &l2, &hi, 0);
            // What is left to prove in each half (0 once closed); the split that leaves
            // the least in total wins, so closing one half outright counts fully.
            let deficit = |b: &(f64, bool, Option<symbolic::Linear>)| {
                if b.1 {
                    0.0
                } else {
                    (-b.0).max(0.0)
                }
            };
            let sc = -(deficit(&s1) + deficit(&s2)) + 1e-12 * (hi[t] - lo[t]);
            Some((
                sc,
                Work {
                    lo: lo.clone(),
                    hi: h1,
                    bounds: Some(Arc::new(b1)),
                    fin: true,
                    key: if s1.1 { f64::INFINITY } else { s1.0 },
                    depth: depth + 1,
                    case,
                },
                Work {
                    lo: l2,
                    hi: hi.clone(),
                    bounds: Some(Arc::new(b2)),
                    fin: true,
                    key: if s2.1 { f64::INFINITY } else { s2.0 },
                    depth: depth + 1,
                    case,
                },
                t,
            ))
        })
        .collect();
    // When no split makes real progress (less than 1% of the piece's own deficit, counted
    // for both halves), the look-ahead only sees rounding noise and would keep cutting
    // already thin sides: split by smear instead (|coefficient| * width of the most
    // promising constraint's bound), so every side keeps shrinking.
    let parent_deficit = 2.0 * (-lbv).max(0.0);
    let best = tries.iter().map(|t| t.0).fold(f64::NEG_INFINITY, f64::max);
    let stalled = best + parent_deficit <= 0.01 * parent_deficit;
    let smear_pick = f.as_ref().and_then(|f| {
        let sm = |t: usize| f.coef[t].abs() * (hi[t] - lo[t]) + 1e-300;
        tries
            .iter()
            .enumerate()
            .max_by(|a, b| sm(a.1 .3).total_cmp(&sm(b.1 .3)))
            .map(|(i, _)| i)
    });
    let pick = if stalled {
        smear_pick
    } else {
        tries
            .iter()
            .enumerate()
            .max_by(|a, b| a.1 .0.total_cmp(&b.1 .0))
            .map(|(i, _)| i)
    };
    match pick {
        Some(i) => {
            let (_, w1, w2, _) = tries.swap_remove(i);
            Piece::Split(w1, w2)
        }
        None => Piece::Stuck,
    }
}

/// Decide the query: is there a case with a point? Cases are searched in order.
pub fn solve(maps: &[(Affine, bool)], cases: &[Case], s: &Settings) -> (Outcome, Stats) {
    let t0 = Instant::now();
    let mut stats = Stats::default();
    let out_of_time = |t0: &Instant| s.timeout.is_some_and(|d| t0.elapsed() >= d);
    // Attack every case first: a cheap refutation beats any proof.
    for (ci, case) in cases.iter().enumerate() {
        if let Some(x) = attack(maps, case, s, 0, &mut stats) {
            let y = forward(maps, &x, None);
            return (Outcome::Point { case: ci, x, y }, stats);
        }
        if out_of_time(&t0) {
            return (Outcome::Unknown(StopReason::Timeout), stats);
        }
    }
    // Depth first over the pieces of every case together, the most promising first.
    let mut stuck = false;
    let mut heap: std::collections::BinaryHeap<Work> = cases
        .iter()
        .enumerate()
        .map(|(ci, case)| Work {
            lo: case.lo.clone(),
            hi: case.hi.clone(),
            bounds: None,
            fin: false,
            key: f64::NEG_INFINITY,
            depth: 0,
            case: ci,
        })
        .collect();
    let deadline = s.timeout.map(|d| t0 + d);
    let mut batches = 0u64;
    let mut last_burst = Instant::now();
    while !heap.is_empty() {
        if out_of_time(&t0) {
            return (Outcome::Unknown(StopReason::Timeout), stats);
        }
        if s.max_pieces > 0 && stats.pieces >= s.max_pieces {
            return (Outcome::Unknown(StopReason::PieceLimit), stats);
        }
        batches += 1;
        if last_burst.elapsed().as_secs_f64() >= 2.0 {
            last_burst = Instant::now();
            for (ci, case) in cases.iter().enumerate() {
                if let Some(x) = attack(maps, case, s, batches, &mut stats) {
                    let y = forward(maps, &x, None);
                    return (Outcome::Point { case: ci, x, y }, stats);
                }
            }
        }
        let take = s.batch.max(1).min(heap.len());
        let batch: Vec<Work> = (0..take).filter_map(|_| heap.pop()).collect();
        stats.pieces += batch.len() as u64;
        let results: Vec<(usize, Piece)> = batch
            .into_par_iter()
            .map(|w| {
                (
                    w.case,
                    examine(maps, &cases[w.case].constraints, w, s.alpha_iters, deadline),
                )
            })
            .collect();
        for (ci, r) in results {
            match r {
                Piece::Closed => {}
                Piece::Found(x) => {
                    let y = forward(maps, &x, None);
                    return (Outcome::Point { case: ci, x, y }, stats);
                }
                Piece::Split(w1, w2) => {
                    heap.push(w1);
                    heap.push(w2);
                }
                Piece::Stuck => stuck = true,
                Piece::Late => return (Outcome::Unknown(StopReason::Timeout), stats),
            }
        }
    }
    if stuck {
        (Outcome::Unknown(StopReason::Unsplittable), stats)
    } else {
        (Outcome::Empty, stats)
    }
}
