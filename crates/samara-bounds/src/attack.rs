//! The falsification attack shared by the input-split searches ([`crate::search`] on
//! ReLU chains, [`crate::smooth`] on networks with any activation): projected gradient
//! descent (Madry et al., ICLR 2018) from seeded starts on the conjunction nearest to
//! holding, the untargeted margin attack of Carlini and Wagner (S&P 2017) when several
//! conjunctions share a box, and restarts whose backward pass lets a little gradient
//! through the inactive ReLUs ([`Chain::leak`]) past the plateaus of the exact gradient.
//! A model only has to give its outputs at a point and the
//! gradient of a weighted sum of them ([`Model`]); every point is judged on the model's
//! own f64 outputs ([`satisfies`]), and callers re-check what they report.

#[cfg(doc)]
use crate::query::satisfies;
use crate::query::{forward, OutputConstraint};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_nn::Affine;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// What the descent needs of a network.
pub(crate) trait Model {
    /// The outputs `f(x)` and, when `pick(f(x))` gives weights `c`, the gradient of
    /// `c . f(x)` in `x` (none when it gives none: the point already holds).
    fn outputs_and_gradient(
        &mut self,
        x: &[f64],
        pick: impl FnOnce(&[f64]) -> Option<Vec<f64>>,
    ) -> (Vec<f64>, Option<Vec<f64>>);
}

/// A ReLU chain ([`crate::search`]'s maps): the gradient of the active linear piece,
/// from the activation pattern of the forward pass (kept between the two).
pub(crate) struct Chain<'a> {
    /// The maps, each with whether a ReLU follows it.
    pub maps: &'a [(Affine, bool)],
    /// The activation pattern of the last forward pass.
    pub masks: Vec<Vec<bool>>,
    /// The slope the backward pass gives an inactive ReLU: 0 for the exact gradient of
    /// the active piece; a small one ([`LEAK`]) for the surrogate gradient of a leaky
    /// ReLU, which sees the units a step could turn on where the exact one is masked
    /// (Athalye, Carlini and Wagner's backward-pass approximation, ICML 2018).
    pub leak: f64,
}

/// The backward slope of an inactive ReLU on the attack's leaky restarts
/// ([`Chain::leak`]). On VNN-COMP 2022 mnist_fc's 256x6 network, prop_1 at eps 0.05 (a
/// `sat` row), the fifth layer has one active unit anywhere near the box's centre: the
/// exact descent switches it off and stops on a flat margin of -0.81 from every start
/// (centre, uniform, corners, each class targeted, 60 to 1,000 steps), while the point
/// needs another unit of that layer (pre-activation -4.4 at the centre) on. With slopes
/// 0.001 to 0.02 the sign descent reaches a point in 2 to 5 steps from the centre and
/// from random starts, each class targeted or not; from 0.03 on the inactive units'
/// paths drown the active ones and it stalls (-0.66 to -0.89).
pub(crate) const LEAK: f64 = 0.01;

impl Model for Chain<'_> {
    fn outputs_and_gradient(
        &mut self,
        x: &[f64],
        pick: impl FnOnce(&[f64]) -> Option<Vec<f64>>,
    ) -> (Vec<f64>, Option<Vec<f64>>) {
        let y = forward(self.maps, x, Some(&mut self.masks));
        let g = pick(&y).map(|c| gradient_masked(self.maps, &self.masks, &c, self.leak));
        (y, g)
    }
}

/// Gradient of `c . f(x)` at `x` (the active linear piece).
pub(crate) fn gradient(maps: &[(Affine, bool)], x: &[f64], c: &[f64]) -> Vec<f64> {
    let mut masks = Vec::new();
    forward(maps, x, Some(&mut masks));
    gradient_masked(maps, &masks, c, 0.0)
}

/// [`gradient`] with the activation masks of the point given ([`forward`]'s), so a
/// caller that has just evaluated the point does not evaluate it again; an inactive
/// ReLU passes `leak` times its gradient (0: the exact gradient, [`Chain::leak`]).
pub(crate) fn gradient_masked(
    maps: &[(Affine, bool)],
    masks: &[Vec<bool>],
    c: &[f64],
    leak: f64,
) -> Vec<f64> {
    let mut g = c.to_vec();
    let mut mi = masks.len();
    for (m, r) in maps.iter().rev() {
        if *r {
            mi -= 1;
            for (gi, on) in g.iter_mut().zip(&masks[mi]) {
                if !on {
                    *gi = if leak == 0.0 { 0.0 } else { *gi * leak };
                }
            }
        }
        let mut next = vec![0.0; m.inp];
        for (i, gi) in g.iter().enumerate() {
            if *gi != 0.0 {
                match m.row(i) {
                    samara_nn::ir::Row::Dense(w) => {
                        for (nx, w) in next.iter_mut().zip(w) {
                            *nx += gi * w;
                        }
                    }
                    r => r.for_each_nonzero(|j, w| next[j] += gi * w),
                }
            }
        }
        g = next;
    }
    g
}

/// How a descent step moves each input `t` of width `w_t`, `eta` shrinking from 0.52 to
/// 0.02 over the steps.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Step {
    /// `eta * scale * w_t * sign(g_t)`: steepest descent for a box (an L-infinity ball),
    /// Madry et al.'s step, for many inputs and for gradients that only point (a
    /// straight-through `Sign`).
    Sign(f64),
    /// `eta * w_t * g_t w_t / max_s |g_s w_s|`: the gradient scaled to the box, which
    /// converges in fewer steps on few inputs (ACAS Xu's five).
    Scaled,
}

/// The value of constraint `k` at outputs `y` (at most 0 where it holds).
fn value(k: &OutputConstraint, y: &[f64]) -> f64 {
    k.obj.d + k.obj.c.iter().zip(y).map(|(c, v)| c * v).sum::<f64>()
}

/// Whether constraint `k` is violated at `y`, or holds by less than its rounding.
fn violated(k: &OutputConstraint, y: &[f64]) -> bool {
    let g = value(k, y);
    g >= -1e-7 * (1.0 + g.abs())
}

/// Projected gradient descent from `x` over the box `[lo, hi]` on a disjunction of
/// conjunctions: each step descends the summed violation `sum_k max(0, g_k(f(x)))` of
/// the conjunction nearest to holding (the least summed violation; the gradient of
/// every violated constraint, not only the worst, so the steps do not oscillate between
/// constraints), by `rule` with a step that shrinks over `steps`. Stops where no input
/// can move, and at `deadline` (checked at every step: a step of a wide network takes
/// tens of milliseconds). Returns the index of a conjunction that holds at the point
/// by `holds` ([`satisfies`], or the smooth engine's [`crate::smooth::holds`]) and the
/// point.
#[allow(clippy::too_many_arguments)]
pub(crate) fn descend(
    model: &mut impl Model,
    group: &[&[OutputConstraint]],
    lo: &[f64],
    hi: &[f64],
    mut x: Vec<f64>,
    steps: usize,
    rule: Step,
    deadline: Option<Instant>,
    holds: impl Fn(&[OutputConstraint], &[f64]) -> bool,
) -> Option<(usize, Vec<f64>)> {
    for step in 0..=steps {
        if deadline.is_some_and(|d| Instant::now() >= d) {
            return None;
        }
        let mut found = None;
        let (_, g) = model.outputs_and_gradient(&x, |y| {
            if let Some(k) = group.iter().position(|cs| holds(cs, y)) {
                found = Some(k);
                return None;
            }
            if step == steps {
                return None;
            }
            let near = group
                .iter()
                .map(|cs| {
                    cs.iter()
                        .filter(|k| violated(k, y))
                        .map(|k| value(k, y).max(0.0))
                        .sum::<f64>()
                })
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map_or(0, |(i, _)| i);
            let mut c = vec![0.0; y.len()];
            for k in group[near].iter().filter(|k| violated(k, y)) {
                for (ci, kc) in c.iter_mut().zip(&k.obj.c) {
                    *ci += kc;
                }
            }
            Some(c)
        });
        if let Some(k) = found {
            return Some((k, x));
        }
        let g = g?;
        let gmax = g
            .iter()
            .zip(lo.iter().zip(hi))
            .map(|(gi, (a, b))| (gi * (b - a)).abs())
            .fold(0.0, f64::max);
        if gmax == 0.0 {
            break;
        }
        let eta = 0.5 * (1.0 - step as f64 / steps as f64) + 0.02;
        for t in 0..x.len() {
            let w = hi[t] - lo[t];
            let (scale, d) = match rule {
                Step::Sign(scale) => (scale, g[t].signum() * f64::from(u8::from(g[t] != 0.0))),
                Step::Scaled => (1.0, g[t] * w / gmax),
            };
            x[t] = (x[t] - eta * scale * w * d).clamp(lo[t], hi[t]);
        }
    }
    None
}

/// The generator of the starts of one attack worker: `seed` varied by `salt` (the round
/// and the worker), so that every round and worker starts elsewhere, the same on every
/// run.
pub(crate) fn starts(seed: u64, salt: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed ^ salt.wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// A start in the box `[lo, hi]`: its centre when `centre`, else uniform.
pub(crate) fn start(rng: &mut ChaCha8Rng, lo: &[f64], hi: &[f64], centre: bool) -> Vec<f64> {
    lo.iter()
        .zip(hi)
        .map(|(&l, &h)| {
            if centre {
                0.5 * (l + h)
            } else {
                rng.gen_range(l..=h)
            }
        })
        .collect()
}

/// Restarts `run(r)` for `r = 0, 1, ...` up to `max` until it gives something; after
/// the first, only while `seconds` have not passed since the call and no other worker
/// raised `stop`; never at or past `deadline`. Raises `stop` when `run` gives.
pub(crate) fn restarts<T>(
    max: usize,
    seconds: f64,
    stop: &AtomicBool,
    deadline: Option<Instant>,
    mut run: impl FnMut(usize) -> Option<T>,
) -> Option<T> {
    let t0 = Instant::now();
    for r in 0..max {
        if r > 0 && (t0.elapsed().as_secs_f64() > seconds || stop.load(Ordering::Relaxed)) {
            break;
        }
        if deadline.is_some_and(|d| Instant::now() >= d) {
            break;
        }
        if let Some(found) = run(r) {
            stop.store(true, Ordering::Relaxed);
            return Some(found);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::symbolic::Objective;

    /// `u = relu(x)` on `x` in [0, 1], then `a = relu(0.5 - u)`, `b = relu(u - 0.9)`,
    /// outputs `y0 = 0.5` and `y1 = 0.3 - a + 10 b`; the constraint `y0 - y1 < 0` holds
    /// exactly for `x > 0.92` (by hand: `y1 = 0.3 + 10 (x - 0.9)` there, and `y1 <= 0.3`
    /// for `x <= 0.9`). At the centre both units of the second layer are off: the exact
    /// gradient is zero, the plateau of mnist_fc 256x6 prop_1 in one dimension.
    fn plateau() -> (Vec<(Affine, bool)>, Vec<OutputConstraint>) {
        let maps = vec![
            (Affine::new(1, 1, vec![1.0], vec![0.0]), true),
            (Affine::new(1, 2, vec![-1.0, 1.0], vec![0.5, -0.9]), true),
            (
                Affine::new(2, 2, vec![0.0, 0.0, -1.0, 10.0], vec![0.5, 0.3]),
                false,
            ),
        ];
        let cs = vec![OutputConstraint {
            obj: Objective {
                c: vec![1.0, -1.0],
                d: 0.0,
            },
            strict: true,
        }];
        (maps, cs)
    }

    fn run(leak: f64) -> Option<(usize, Vec<f64>)> {
        let (maps, cs) = plateau();
        let mut chain = Chain {
            maps: &maps,
            masks: Vec::new(),
            leak,
        };
        descend(
            &mut chain,
            &[&cs[..]],
            &[0.0],
            &[1.0],
            vec![0.5],
            60,
            Step::Sign(1.0),
            None,
            crate::query::satisfies,
        )
    }

    #[test]
    fn exact_gradient_stops_on_the_plateau() {
        assert!(run(0.0).is_none());
    }

    #[test]
    fn leaky_gradient_crosses_the_plateau() {
        let (k, x) = run(LEAK).expect("the leaky descent reaches x > 0.92");
        assert_eq!(k, 0);
        // The point, judged by the hand-derived outputs, not by the chain's forward pass.
        assert!(x[0] > 0.92 && x[0] <= 1.0, "x = {}", x[0]);
        let y1 = 0.3 + 10.0 * (x[0] - 0.9);
        assert!(y1 > 0.5);
    }
}
