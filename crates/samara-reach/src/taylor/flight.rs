//! One sub-box of the initial set flown over the horizon: the network step, the
//! inputs, the flowpipe over each period, the re-parameterisation and the goals decided
//! on the sets.

use super::network::{lift_remainders, monomials, network_over};
use super::result::{undecidable, SystemLeaf};
use super::settings::{affine_on, NetworkError, SystemReachSettings};
use samara_num::tm_reduce::{mid_rad, needs_precondition, precondition, reduce};

use super::flow::{tm_period_parts, TmFlowSettings};
use samara_nn::Network;
use samara_num::{Interval, Scalar, Tm};
use samara_system::{band_decision, GoalKind, System, When};
use std::time::Instant;

pub(crate) fn to_pairs(v: &[Interval]) -> Vec<[f64; 2]> {
    v.iter().map(|i| [i.lo, i.hi]).collect()
}

/// The Taylor models of a box: `x_i = mid_i + rad_i xi_k` for the `k`-th state of
/// non-zero width, constants otherwise; [`mid_rad`] makes the model's range contain the
/// box.
/// With `lifted_weight > 1` the models are mixed-degree ([`Tm::with_lifted_weight`]):
/// every parameter lifted later weighs that much toward the order.
fn box_models(b: &[Interval], order: u32, lifted_weight: u32) -> Vec<Tm> {
    let free: Vec<usize> = (0..b.len()).filter(|&i| b[i].hi > b[i].lo).collect();
    let n = free.len();
    b.iter()
        .enumerate()
        .map(|(i, v)| match free.iter().position(|&j| j == i) {
            None => Tm::constant(v.lo, n, order),
            Some(k) => {
                let (mid, rad) = mid_rad(*v);
                Tm::var(k, n, order) * rad + mid
            }
        })
        .map(|m| {
            if lifted_weight > 1 {
                m.with_lifted_weight(lifted_weight)
            } else {
                m
            }
        })
        .collect()
}

/// How many times its initial magnitude (`1 + max |x_i|` over the sub-box) a state's
/// enclosure may grow before the sub-box is given up as lost (and split).
const EXPLODED: f64 = 1e3;

/// Most polynomial terms a symbolic remainder may grow the models to (the number of
/// monomials of the order in the parameters kept).
const TERM_BUDGET: usize = 30_000;

/// Number of monomials of a mixed-degree table ([`Tm::with_lifted_weight`]): `full`
/// parameters of weight 1 and `lifted` of weight `lw`, weighted degree at most `order`
/// (the classic count `monomials(full + lifted, order)` when `lw <= 1`): the lifted
/// monomials of degree `d` times the full ones of degree up to `order - lw d`.
fn mixed_monomials(full: usize, lifted: usize, order: usize, lw: u32) -> usize {
    let lw = (lw as usize).min(order.max(1));
    if lw <= 1 {
        return monomials(full + lifted, order);
    }
    (0..=order / lw)
        .map(|d| {
            // Monomials of degree exactly d in `lifted` variables: C(lifted + d - 1, d).
            let exact = if d == 0 {
                1
            } else if lifted == 0 {
                0
            } else {
                monomials(lifted - 1, d)
            };
            exact.saturating_mul(monomials(full, order - lw * d))
        })
        .fold(0usize, |a, v| a.saturating_add(v))
}

/// Whether the run's time budget (its deadline, if any) is spent.
pub(crate) fn past(deadline: Option<Instant>) -> bool {
    deadline.is_some_and(|d| Instant::now() > d)
}

/// A sub-box `b` without sets (yet): every goal undecided, `failure` saying why, if it
/// stays so.
pub(crate) fn empty_leaf(sys: &System, b: &[Interval], failure: Option<String>) -> SystemLeaf {
    SystemLeaf {
        init: to_pairs(b),
        instants: Vec::new(),
        periods: Vec::new(),
        failure,
        decided: vec![None; sys.goals.len()],
        stopped_at: None,
        end_measures: Vec::new(),
    }
}

/// Fly one sub-box over the horizon and decide the goals on its sets.
pub(crate) fn fly_box(
    sys: &System,
    net: &Network,
    b: &[Interval],
    s: &SystemReachSettings,
    mode: NetworkError,
    deadline: Option<Instant>,
) -> SystemLeaf {
    let mut x = box_models(b, s.order as u32, s.flow.lifted_weight);
    // Most parameters the models may carry before the set is re-parameterised (0: the
    // network's error stays an interval).
    let max_params = match mode {
        NetworkError::Symbolic { extra } if s.precondition => {
            let base = sys.dim();
            let m = net.n_outputs();
            let mut e = extra;
            while e > 0 && mixed_monomials(base, e + m, s.order, s.flow.lifted_weight) > TERM_BUDGET
            {
                e -= 1;
            }
            if e == 0 {
                0
            } else {
                base + e
            }
        }
        _ => 0,
    };
    // A set this much wider than the initial box's magnitude is lost: stop the
    // sub-box (its flow would crawl on) so that it is split.
    let scale: Vec<f64> = b.iter().map(|v| 1.0 + v.lo.abs().max(v.hi.abs())).collect();
    // With symbolic remainders, the flow's own remainders become parameters too.
    let flow = TmFlowSettings {
        max_params,
        deadline,
        ..s.flow.clone()
    };
    let mut leaf = empty_leaf(sys, b, None);
    // Per goal: proved so far over the instants and periods seen (Always, End), or
    // met at some instant (Eventually).
    let mut ok: Vec<bool> = vec![true; sys.goals.len()];
    let mut met: Vec<bool> = vec![false; sys.goals.len()];
    let mut refuted: Vec<bool> = vec![false; sys.goals.len()];
    let steps = sys.steps();
    let mut obs = vec![Tm::cst(0.0); sys.n_observed()];
    let mut u = vec![Tm::cst(0.0); sys.n_inputs()];
    // The plant's semantics from samara-system, as the simulator takes them: the resets
    // act on the initial set, then at the start of every period but at the horizon; the
    // set recorded and checked at an instant k >= 1 is the previous period's flow at its
    // end, before the resets.
    sys.initial_state(&mut x);
    for k in 0..=steps {
        let t = k as f64 * sys.period;
        let hull: Vec<Interval> = x.iter().map(|v| v.bound()).collect();
        leaf.instants.push(to_pairs(&hull));
        check_goals(sys, &x, &hull, t, t, &mut ok, &mut met, &mut refuted);
        if k == steps {
            leaf.end_measures = s
                .measures
                .iter()
                .map(|m| {
                    let r = m.over(&x, &hull);
                    [r.lo, r.hi]
                })
                .collect();
            break;
        }
        if hull
            .iter()
            .zip(&scale)
            .any(|(h, sc)| h.width().is_nan() || h.width() > EXPLODED * sc)
        {
            leaf.failure = Some(format!(
                "the enclosure grew past {EXPLODED} times the initial set's magnitude by t = {t}"
            ));
            break;
        }
        if undecidable(sys, &ok) {
            leaf.stopped_at = Some(t);
            break;
        }
        if past(deadline) {
            leaf.failure = Some(format!(
                "time budget spent before the period starting at t = {t}"
            ));
            break;
        }
        let hull = if sys.resets.is_empty() {
            hull
        } else {
            sys.begin_period(k, &mut x);
            x.iter().map(|v| v.bound()).collect()
        };
        // Room for this period's symbolic remainders (one per input at most).
        let crowded =
            max_params > 0 && x.iter().map(|v| v.n_vars()).max().unwrap_or(0) > max_params;
        if s.precondition && (crowded || needs_precondition(&x, &hull)) {
            if max_params > 0 {
                // Symbolic remainders: order reduction, leaving room for one period's
                // new parameters (one per network output).
                x = reduce(
                    &x,
                    max_params.saturating_sub(net.n_outputs()),
                    s.order as u32,
                );
            } else {
                x = precondition(&x, s.order as u32);
            }
        }
        sys.observe(&x, &mut obs);
        let mut y = network_over(net, &obs, s.order as u32);
        if max_params > 0 {
            let n = x.iter().map(|v| v.n_vars()).max().unwrap_or(0);
            y = lift_remainders(y, n, s.order as u32);
        }
        sys.actuate(&y, &mut u);
        match tm_period_parts(sys, &x, &u, sys.period, &flow) {
            Ok((next, parts)) => {
                let mut ph = parts
                    .first()
                    .map_or_else(|| hull.clone(), |p| p.bounds.clone());
                for part in &parts {
                    for (a, v) in ph.iter_mut().zip(&part.bounds) {
                        *a = Scalar::hull(a, v);
                    }
                }
                leaf.periods.push(to_pairs(&ph));
                // Each part on its own (they cover the period together): an
                // obstacle the flight passes diagonally misses the parts but not
                // their hull; a band is decided on the part's Taylor models too.
                let empty: Vec<Tm> = Vec::new();
                for part in &parts {
                    check_goals(
                        sys,
                        part.models.as_deref().unwrap_or(&empty),
                        &part.bounds,
                        t,
                        t + sys.period,
                        &mut ok,
                        &mut met,
                        &mut refuted,
                    );
                }
                x = next;
                if undecidable(sys, &ok) {
                    leaf.stopped_at = Some(t + sys.period);
                    break;
                }
            }
            Err(e) => {
                leaf.failure = Some(format!("{e} (period starting at t = {t})"));
                break;
            }
        }
    }
    for (gi, g) in sys.goals.iter().enumerate() {
        leaf.decided[gi] = if refuted[gi] {
            Some(false)
        } else if leaf.failure.is_some() {
            None
        } else {
            match g.when {
                When::Eventually(..) => met[gi].then_some(true),
                _ => ok[gi].then_some(true),
            }
        };
    }
    leaf
}

/// Update the per-goal state with the set over `[t1, t2]` (an instant when equal):
/// `x` the Taylor models at an instant (empty over a period: then only the hull).
#[allow(clippy::too_many_arguments)]
fn check_goals(
    sys: &System,
    x: &[Tm],
    hull: &[Interval],
    t1: f64,
    t2: f64,
    ok: &mut [bool],
    met: &mut [bool],
    refuted: &mut [bool],
) {
    let eps = 1e-9 * sys.horizon.max(1.0);
    for (gi, g) in sys.goals.iter().enumerate() {
        // Does [t1, t2] meet the goal's window?
        let (w1, w2) = match g.when {
            When::End => (sys.horizon, sys.horizon),
            When::Always(a, b) | When::Eventually(a, b) => (a, b),
        };
        if t2 < w1 - eps || t1 > w2 + eps {
            continue;
        }
        let instant = t1 == t2;
        // A period that meets the window only at one of its ends: that instant's set
        // is checked on its own (sharper than the period's hull), nothing else to check.
        if !instant && (t2 <= w1 + eps || t1 >= w2 - eps) {
            continue;
        }
        // An instant's set inside the window decides an "eventually" goal; a period's
        // hull only counts for "always" (it covers times inside and outside the window,
        // which is conservative for "always").
        let d = decide_on(g, x, hull);
        match g.when {
            When::End | When::Always(..) => {
                if d != Some(true) {
                    ok[gi] = false;
                }
                if d == Some(false) && instant {
                    refuted[gi] = true;
                }
            }
            When::Eventually(..) => {
                if instant && d == Some(true) {
                    met[gi] = true;
                }
            }
        }
    }
}

/// A goal on a set: by the Taylor models for an affine band (the dependence kept); a
/// band of any other expression by the expression evaluated on the Taylor models and on
/// the interval hull, whichever decides (both enclose it); boxes by the hull.
fn decide_on(g: &samara_system::Goal, x: &[Tm], hull: &[Interval]) -> Option<bool> {
    if let (
        GoalKind::Band {
            graph,
            lo,
            hi,
            linear: None,
            ..
        },
        false,
    ) = (&g.kind, x.is_empty())
    {
        let by_hull = g.decide(hull);
        if by_hull.is_some() {
            return by_hull;
        }
        let mut o = [Tm::cst(0.0)];
        graph.eval(x, &[], &mut o);
        return band_decision(o[0].bound(), *lo, *hi);
    }
    if let (
        GoalKind::Band {
            lo,
            hi,
            linear: Some((a, b)),
            ..
        },
        false,
    ) = (&g.kind, x.is_empty())
    {
        return band_decision(affine_on(a, *b, x).bound(), *lo, *hi);
    }
    g.decide(hull)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A band of a non-affine expression is decided on the Taylor models where the
    /// interval hull cannot: on the diagonal set `x = y = xi`, `(x - y)^2 + x^2` ranges
    /// over `[0, 1]` while the hull gives `[0, 5]`; a band `<= 1.5` is proved, a band
    /// `>= 2` refuted, and the hull alone decides neither. Sampling the set agrees.
    #[test]
    fn nonlinear_bands_are_decided_on_the_taylor_models() {
        let src = |band: &str| {
            format!(
                "state x, y\ninput u\nx' = u\ny' = u\nperiod 1\nhorizon 1\n\
                 actuate u = net[0]\ninit x in [-1, 1]\ninit y in [-1, 1]\n\
                 goal band {band} always\n"
            )
        };
        let x = vec![Tm::var(0, 1, 4), Tm::var(0, 1, 4)];
        let hull = vec![Interval::new(-1.0, 1.0); 2];
        for (band, want) in [
            ("(x - y)^2 + x^2 <= 1.5", Some(true)),
            ("(x - y)^2 + x^2 >= 2", Some(false)),
        ] {
            let sys = System::parse(&src(band), "t.sys").unwrap();
            let g = &sys.goals[0];
            assert_eq!(g.decide(&hull), None, "{band}: the hull decides nothing");
            assert_eq!(decide_on(g, &x, &hull), want, "{band}");
            for k in 0..=100 {
                let v = -1.0 + 0.02 * k as f64;
                assert_eq!(g.holds(&[v, v]), want == Some(true), "{band} at {v}");
            }
        }
    }

    #[test]
    fn monomial_counts_are_binomials() {
        assert_eq!(monomials(4, 4), 70);
        assert_eq!(monomials(27, 4), 31_465);
        assert_eq!(monomials(24, 3), 2_925);
        assert_eq!(monomials(0, 5), 1);
        // Mixed degree: the classic count at weight 1; at order 3 with 6 full and 20
        // lifted parameters of weight 3, C(9, 3) + 20 = 104; of weight 2,
        // 84 + 20 * 7 = 224 (each lifted one alone or times one full one).
        assert_eq!(mixed_monomials(6, 20, 3, 1), monomials(26, 3));
        assert_eq!(mixed_monomials(6, 20, 3, 3), 104);
        assert_eq!(mixed_monomials(6, 20, 3, 2), 224);
        // Order 4, weight 2: 210 + 41 * 28 + C(42, 2) = 2,219.
        assert_eq!(mixed_monomials(6, 41, 4, 2), 2_219);
        assert_eq!(mixed_monomials(6, 0, 4, 2), 210);
    }
}
