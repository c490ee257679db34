//! Validated integration of the plant over one control period with the control held
//! constant: an interval Taylor method in the style of Lohner (1987) on zonotopes.
//!
//! One step of size `h` from the zonotope `Z = c + G xi` (the control `ex` is the last
//! row, with zero derivative, so its dependence on the parameters is kept):
//! 1. a-priori enclosure `B` of every trajectory over `[0, h]`: the first-order Picard
//!    test `box(Z) + [0, h] f(B) ⊆ B` (Nedialkov, Jackson & Corliss 1999, §3);
//! 2. Taylor map `T(s) = sum_{i<=p} x_i(s) h^i` by Taylor-mode AD of the plant's own
//!    equations ([`samara_num::Series`]), the Lagrange remainder `h^{p+1} x_{p+1}(B)`;
//! 3. mean-value form `T(Z) ⊆ T(c) + DT(box Z) G xi`, with `DT` enclosed by
//!    `Series<IDual>`; the midpoint matrix maps the generators exactly (no wrapping),
//!    the radius matrix and the remainder become new axis-aligned generators.
//!
//! Where the right-hand side is not analytic over `B` (the full model's `|omega|` and
//! quadrant masks), the step falls back to the zeroth-order enclosure
//! `phi_h(s) ∈ s + h f(B)`, which only needs `f` bounded on `B`.

// Numeric kernels index several arrays by one index; the explicit forms mirror the formulas.
#![allow(clippy::assign_op_pattern, clippy::needless_range_loop)]

use super::set::{gamma, Zonotope};
use crate::taylor_step::{apriori_by, finite, lagrange_remainder, series_in, subset};
use samara_num::{IDual, Interval, Scalar, Series};
use samara_plant::Plant;
use samara_system::taylor::{SeriesPair, SeriesScratch};
use samara_system::Graph;
use std::cell::RefCell;
use std::rc::Rc;

thread_local! {
    /// The series expansions' tables, per worker thread: allocated once, not three
    /// times per step (malloc and free took about a tenth of the published setting's
    /// time before).
    static SCRATCH_I: RefCell<SeriesScratch<Interval>> = RefCell::new(SeriesScratch::default());
    static SCRATCH_D: RefCell<SeriesScratch<IDual<ND>>> = RefCell::new(SeriesScratch::default());
    /// The right-hand side's graph where it holds at every box ([`record_rhs`]), with
    /// the plant and the number of states it was recorded for.
    static GRAPH: RefCell<Option<(Plant, usize, Rc<Graph>)>> = const { RefCell::new(None) };
}

/// Taylor order of the validated steps.
pub const ORDER: usize = 7;
/// Orders of the Taylor map whose Jacobian is enclosed by interval duals (the
/// expensive part); orders `JAC_ORDER + 1 ..= ORDER` contribute `h^i` times their
/// interval spread over the set instead, a small first-order term.
pub const JAC_ORDER: usize = 5;
const KK: usize = ORDER + 2;
/// Safety factor of the step-size suggestion `h s (tol / rem)^(1 / (p + 1))` (Hairer,
/// Norsett & Wanner, *Solving ODEs I*, sec. II.4). 0.8 rather than 0.9: the remainder
/// over the a-priori box grows faster than `h^(p+1)` (the box grows with `h`), and at
/// 0.9 a step after a long one was rejected often enough that rejected attempts were
/// 17 % of the published setting's and a third of the full model's (2026-11-28,
/// bench/reach/published_speed.md); at 0.8 about 1 % and 8 %, with slightly fewer accepted steps.
const STEP_SAFETY: f64 = 0.8;
/// Dual directions: v_xp, v_yp, omega, theta and ex (the right-hand side never reads
/// x or y, so their Jacobian columns are unit vectors).
const ND: usize = 5;
/// Rows of the integrated state: the six physical states and the held control. The
/// filter state E of plate6/full never acts on the others (it only fed the PID) and is
/// left out of the sets.
pub const ROWS: usize = 7;

/// The plant's right-hand side on the six states (E = 0 supplied when the model has it).
fn rhs6<S: Scalar>(plant: &Plant, x: &[S], out: &mut [S]) {
    if plant.dim() == 7 {
        let mut st: Vec<S> = x[..6].to_vec();
        st.push(S::cst(0.0));
        let mut o = vec![S::cst(0.0); 7];
        plant.rhs(&st, &x[6], &mut o);
        out[..6].clone_from_slice(&o[..6]);
    } else {
        plant.rhs(&x[..6], &x[6], &mut out[..6]);
    }
}

/// Why a period could not be enclosed.
#[derive(Clone, Debug, PartialEq)]
pub enum FlowFailure {
    /// The a-priori enclosure could not be validated even for tiny steps (the set is
    /// too large, or the flow leaves the model's domain: `v_xp` reaching 0, ...).
    NoEnclosure {
        /// Time within the period.
        t: f64,
    },
}

/// Settings of the validated integrator.
#[derive(Clone, Debug)]
pub struct FlowSettings {
    /// Nominal step (0.5 / 8).
    pub h: f64,
    /// Smallest Taylor step before the zeroth-order fallback (1e-3).
    pub h_min_taylor: f64,
    /// Smallest step at all (1e-7).
    pub h_min: f64,
    /// Largest remainder width accepted per step before the step is shortened (1e-8).
    pub rem_tol: f64,
    /// Noise generators kept by the reduction (24 per dimension: with 4, Girard's
    /// reduction merged away the correlation between x and y that makes x + y
    /// contract, and a sub-box's final x + y came out 15x its flights' spread).
    pub max_noise_per_dim: usize,
    /// Largest first-order step where the right-hand side is not analytic (1e-3).
    pub h_lohner1: f64,
    /// Remainder accepted relative to the set's width in that row (1e-4).
    pub rem_rel: f64,
    /// Attempted steps per period before giving up (the set is then too wide to
    /// integrate efficiently and the caller splits it): 400.
    pub max_attempts: usize,
}

impl Default for FlowSettings {
    fn default() -> Self {
        FlowSettings {
            h: 0.0625,
            h_min_taylor: 1e-3,
            h_min: 1e-7,
            rem_tol: 1e-8,
            max_noise_per_dim: 24,
            max_attempts: 400,
            rem_rel: 1e-4,
            h_lohner1: 1e-3,
        }
    }
}

/// Statistics of one period.
#[derive(Clone, Debug, Default)]
pub struct FlowStats {
    /// Taylor steps taken.
    pub taylor_steps: usize,
    /// Zeroth-order fallback steps taken.
    pub fallback_steps: usize,
    /// Rejected attempts.
    pub rejected: usize,
}

/// Dual direction of each row: v_xp, v_yp, omega, theta -> 0..4, ex (row 6) -> 4;
/// x and y carry none (the right-hand side never reads them).
fn dual_dir(i: usize) -> Option<usize> {
    match i {
        0..=3 => Some(i),
        6 => Some(4),
        _ => None,
    }
}

/// Interval duals seeded over the box `b` along [`dual_dir`].
fn dual_seeds(b: &[Interval]) -> Vec<IDual<ND>> {
    b.iter()
        .enumerate()
        .map(|(i, v)| match dual_dir(i) {
            Some(k) => IDual::var(*v, k),
            None => IDual::constant(*v),
        })
        .collect()
}

fn rhs_interval(plant: &Plant, x: &[Interval]) -> Vec<Interval> {
    let mut out = vec![Interval::point(0.0); ROWS];
    rhs6(plant, x, &mut out);
    out
}

/// The plant's right-hand side recorded as a graph at the box `b` (last entry: ex),
/// with the branches `b` decides ([`samara_system::taylor::record`]); `None` where one
/// is undecided over `b`. Branches are decided on strict signs, which hold on every
/// subset of `b`, so one recording over a step's a-priori box serves every expansion of
/// the step (over the set's box, at its centre, with duals over the box): the graph a
/// recording at any of those would give.
///
/// A plant whose right-hand side decides no branch on values (the reduced model: no
/// sign is asked, [`samara_system::taylor::record_checked`]) records the same graph at
/// every box: it is recorded once per thread and plant, with its common subexpressions
/// merged ([`samara_system::taylor::merge_common`]: the same numbers, `alpha^2`,
/// `omega^2` and `cos theta` computed once).
fn record_rhs(plant: &Plant, b: &[Interval]) -> Option<Rc<Graph>> {
    let n = b.len() - 1;
    if let Some(g) = GRAPH.with_borrow(|c| {
        c.as_ref()
            .filter(|(p, rows, _)| p == plant && *rows == n)
            .map(|(_, _, g)| Rc::clone(g))
    }) {
        return Some(g);
    }
    let (g, everywhere) =
        samara_system::taylor::record_checked(&b[..n], &b[n..], n, |x, u, out| {
            let mut full = x.to_vec();
            full.push(u[0].clone());
            rhs6(plant, &full, out);
        })?;
    if !everywhere {
        return Some(Rc::new(g));
    }
    let g = Rc::new(samara_system::taylor::merge_common(&g));
    GRAPH.set(Some((plant.clone(), n, Rc::clone(&g))));
    Some(g)
}

/// Taylor coefficients `0..=upto` of the solution from `x0` (last entry: ex, constant),
/// inside the box `g` was recorded at ([`record_rhs`]).
fn taylor<S: Scalar + Copy, const K: usize>(
    plant: &Plant,
    g: Option<&Graph>,
    x0: &[S],
    upto: usize,
    scratch: &mut SeriesScratch<S>,
) -> Vec<Series<S, K>> {
    let d = x0.len();
    let n = d - 1;
    // Expanded by the shared step's series on the recording (O(K^2) where re-running
    // the plant on series per order is O(K^3); the same recurrences, so the same
    // enclosures); the plant's own equations on series below where there is no recording
    // or its series is `bad` (an undecided branch: then `bad` here too).
    if let Some(mut s) =
        g.and_then(|g| series_in::<S, K>(g, &x0[..n], &x0[n..], upto, &|_, v| v, scratch))
    {
        s.push(Series::constant(x0[n]));
        return s;
    }
    let mut x: Vec<Series<S, K>> = x0.iter().map(|v| Series::var(*v)).collect();
    x[n] = Series::constant(x0[n]);
    let mut out = vec![Series::<S, K>::cst(0.0); d];
    for i in 0..upto {
        for xj in x.iter_mut().take(n) {
            xj.n = i + 1;
        }
        rhs6(plant, &x, &mut out);
        for j in 0..n {
            x[j].c[i + 1] = out[j].c[i] / (i as f64 + 1.0);
            x[j].bad |= out[j].bad;
        }
    }
    for xj in x.iter_mut().take(n) {
        xj.n = upto + 1;
    }
    x
}

/// The two expansions over the set's box `bz`: Taylor coefficients `0..=JAC_ORDER` on
/// interval duals seeded over `bz` ([`dual_seeds`]), and `0..=ORDER` on intervals.
/// With a recording, one expansion
/// ([`samara_system::taylor::solution_series_pair_in`]): the duals' orders, then the
/// interval orders above them continued from the duals' value parts, which are the
/// interval expansion's own lower orders (a dual's value is computed by the same
/// interval operations), so the interval series are those of a separate expansion;
/// two separate expansions ([`taylor`]) otherwise.
fn over_box(
    plant: &Plant,
    g: Option<&Graph>,
    bz: &[Interval],
) -> SeriesPair<IDual<ND>, Interval, { JAC_ORDER + 1 }, KK> {
    let n = bz.len() - 1;
    let seeds = dual_seeds(bz);
    let pair = g.and_then(|g| {
        SCRATCH_D.with_borrow_mut(|sd| {
            SCRATCH_I.with_borrow_mut(|si| {
                samara_system::taylor::solution_series_pair_in::<
                    IDual<ND>,
                    Interval,
                    { JAC_ORDER + 1 },
                    KK,
                >(
                    g,
                    &seeds[..n],
                    &seeds[n..],
                    JAC_ORDER,
                    ORDER,
                    &|d| d.v,
                    sd,
                    si,
                )
            })
        })
    });
    if let Some((mut tj, mut tz)) = pair {
        if !tj.iter().any(|x| x.bad) && !tz.iter().any(|x| x.bad) {
            tj.push(Series::constant(seeds[n]));
            tz.push(Series::constant(bz[n]));
            return (tj, tz);
        }
    }
    let tz = SCRATCH_I.with_borrow_mut(|sc| taylor::<Interval, KK>(plant, g, bz, ORDER, sc));
    let tj = SCRATCH_D.with_borrow_mut(|sc| {
        taylor::<IDual<ND>, { JAC_ORDER + 1 }>(plant, g, &seeds, JAC_ORDER, sc)
    });
    (tj, tz)
}

/// A-priori enclosure of all trajectories from `bz` over `[0, h]`.
fn apriori(plant: &Plant, bz: &[Interval], h: f64) -> Option<Vec<Interval>> {
    apriori_by(|x| rhs_interval(plant, x), bz, h)
}

/// One Taylor step, `z` replaced by its image; `None` (and `z` unchanged) if it cannot
/// be validated at this `h`. Returns the a-priori box.
fn taylor_step(
    plant: &Plant,
    z: &mut Zonotope,
    h: f64,
    s: &FlowSettings,
    hint: &mut f64,
) -> Option<Vec<Interval>> {
    let d = z.dim();
    let n = d - 1;
    let bz = z.bbox();
    let b = apriori(plant, &bz, h)?;
    // Remainder h^{p+1} x_{p+1}(B).
    let rec = record_rhs(plant, &b);
    let tb = SCRATCH_I
        .with_borrow_mut(|sc| taylor::<Interval, KK>(plant, rec.as_deref(), &b, ORDER + 1, sc));
    if tb[..n].iter().any(|x| x.bad) {
        *hint = f64::NAN;
        return None;
    }
    let rem = lagrange_remainder(&tb, n, ORDER, h);
    // Step-size suggestion from the remainder's scaling, rem ~ h^{p+1}.
    // Worst ratio of the remainder's width to what is accepted in its row: the absolute
    // tolerance, or a fraction of the set's own width (a wide set cannot do better).
    let worst = rem
        .iter()
        .zip(&bz)
        .map(|(r, b)| (r.hi - r.lo) / s.rem_tol.max(s.rem_rel * (b.hi - b.lo)))
        .fold(0.0f64, f64::max)
        * s.rem_tol;
    *hint = if worst.is_finite() && worst > 0.0 {
        h * STEP_SAFETY * (s.rem_tol / worst).powf(1.0 / (ORDER as f64 + 1.0))
    } else if worst == 0.0 {
        2.0 * h
    } else {
        0.5 * h
    };
    if !finite(&rem) || worst > s.rem_tol && h > s.h_min_taylor {
        return None;
    }
    // T(c).
    let cpt: Vec<Interval> = z.c.iter().map(|&v| Interval::point(v)).collect();
    let tc = SCRATCH_I
        .with_borrow_mut(|sc| taylor::<Interval, KK>(plant, rec.as_deref(), &cpt, ORDER, sc));
    if tc[..n].iter().any(|x| x.bad) {
        *hint = f64::NAN;
        return None;
    }
    let horner = |co: &[Interval]| -> Interval {
        let mut acc = co[ORDER];
        for i in (0..ORDER).rev() {
            acc = acc * h + co[i];
        }
        acc
    };
    // DT(box Z) by interval duals, and the orders above JAC_ORDER by intervals over
    // box(Z): h^i (x_i(s) - x_i(c)) ∈ h^i (x_i(box Z) - x_i(c)).
    let (tj, tz) = over_box(plant, rec.as_deref(), &bz);
    if tz[..n].iter().any(|x| x.bad) || tj[..n].iter().any(|x| x.bad) {
        *hint = f64::NAN;
        return None;
    }
    let centre: Vec<Interval> = (0..n)
        .map(|j| {
            let mut hi_orders = Interval::point(0.0);
            for i in (JAC_ORDER + 1..=ORDER).rev() {
                hi_orders = (hi_orders + (tz[j].c[i] - tc[j].c[i])) * h;
            }
            for _ in 0..JAC_ORDER {
                hi_orders = hi_orders * h;
            }
            horner(&tc[j].c) + rem[j] + hi_orders
        })
        .collect();
    // jac[j][k] enclosure of d T_j / d s_k.
    let mut jac = vec![vec![Interval::point(0.0); d]; d];
    for j in 0..n {
        for (k, jk) in jac[j].iter_mut().enumerate() {
            *jk = match dual_dir(k) {
                Some(q) => {
                    let mut acc = tj[j].c[JAC_ORDER].d[q];
                    for i in (0..JAC_ORDER).rev() {
                        acc = acc * h + tj[j].c[i].d[q];
                    }
                    acc
                }
                None => Interval::point(if j == k { 1.0 } else { 0.0 }),
            };
        }
    }
    jac[n][n] = Interval::point(1.0);
    if jac.iter().any(|r| !finite(r)) || !finite(&centre) {
        return None;
    }
    compose(z, &centre, &jac, s);
    Some(b)
}

/// The zonotope `centre + jac G xi`, in place of `z = c + G xi`: `mid(jac)` maps the
/// generators exactly; the radius of `jac` times `|G|`, the centre's width and the
/// rounding of the products become new axis-aligned generators (then Girard
/// reduction). `centre` covers the first rows (the states); the control row is carried
/// unchanged.
///
/// Each generator's image is summed over the columns `k` in increasing order, one
/// accumulator per row: the rows' sums are independent (they vectorise, and no sum
/// waits on the previous one's rounding), each the same floats as a row-by-row loop.
fn compose(z: &mut Zonotope, centre: &[Interval], jac: &[Vec<Interval>], s: &FlowSettings) {
    const D: usize = ROWS;
    let d = z.dim();
    debug_assert_eq!(d, D, "the flow's sets have ROWS rows");
    // Column-major midpoint and radius matrices of `jac`: `mid_t[k][j]` = mid(jac[j][k]).
    let mut mid_t = [[0.0f64; D]; D];
    let mut rad_t = [[0.0f64; D]; D];
    for j in 0..D {
        for k in 0..D {
            let x = jac[j][k];
            let mm = 0.5 * (x.lo + x.hi);
            mid_t[k][j] = mm;
            rad_t[k][j] = (x.hi - mm).max(mm - x.lo).next_up();
        }
    }
    let gd = gamma(d);
    let mut noise = [0.0f64; D];
    for j in 0..centre.len() {
        let m = 0.5 * (centre[j].lo + centre[j].hi);
        z.c[j] = m;
        noise[j] = (centre[j].hi - m).max(m - centre[j].lo).next_up();
    }
    for g in z.gens.iter_mut() {
        let g: &mut [f64; D] = (&mut g[..D]).try_into().expect("D rows");
        let mut acc = [0.0f64; D];
        let mut mag = [0.0f64; D];
        let mut radterm = [0.0f64; D];
        for k in 0..D {
            let (gk, ak) = (g[k], g[k].abs());
            for j in 0..D {
                let p = mid_t[k][j] * gk;
                acc[j] += p;
                mag[j] += p.abs();
                radterm[j] += rad_t[k][j] * ak;
            }
        }
        for j in 0..D {
            noise[j] += (radterm[j] + mag[j] * gd) * (1.0 + gd);
        }
        *g = acc;
    }
    for x in noise.iter_mut() {
        *x = x.next_up();
    }
    z.add_box(&noise);
    z.reduce(s.max_noise_per_dim * d);
}

/// Enclosure of the right-hand side's Jacobian (rows and columns: the 6 states and ex)
/// over the box `b`, by interval duals.
fn jacobian(plant: &Plant, b: &[Interval]) -> Option<Vec<Vec<Interval>>> {
    let d = b.len();
    let n = d - 1;
    let mut out = vec![IDual::<ND>::cst(0.0); d];
    rhs6(plant, &dual_seeds(b), &mut out);
    let mut jf = vec![vec![Interval::point(0.0); d]; d];
    for j in 0..n {
        for k in 0..d {
            if let Some(q) = dual_dir(k) {
                jf[j][k] = out[j].d[q];
            }
        }
    }
    if jf.iter().any(|r| !finite(r)) {
        return None;
    }
    Some(jf)
}

fn imat_mul(a: &[Vec<Interval>], b: &[Vec<Interval>]) -> Vec<Vec<Interval>> {
    let d = a.len();
    (0..d)
        .map(|i| {
            (0..d)
                .map(|j| {
                    let mut acc = Interval::point(0.0);
                    for k in 0..d {
                        if a[i][k] != Interval::point(0.0) && b[k][j] != Interval::point(0.0) {
                            acc = acc + a[i][k] * b[k][j];
                        }
                    }
                    acc
                })
                .collect()
        })
        .collect()
}

fn identity(d: usize) -> Vec<Vec<Interval>> {
    (0..d)
        .map(|i| {
            (0..d)
                .map(|j| Interval::point(if i == j { 1.0 } else { 0.0 }))
                .collect()
        })
        .collect()
}

/// First-order (C^1) Lohner step for right-hand sides that are only Lipschitz (the full
/// model's `omega |omega|` and quadrant masks): the Jacobian `J(B)` is enclosed with
/// interval duals (Clarke's generalised Jacobian where a branch is undecided: the hull
/// of both pieces' derivatives), the flow's Jacobian over `[0, h]` by the fixed point
/// `W ⊇ I + [0, h] J(B) W`, and `phi_h(Z) ⊆ phi_h(c) + (I + h J + h²/2 J J W) G xi` by the
/// mean-value theorem (Clarke's version for Lipschitz maps), with
/// `phi_h(c) ∈ c + h f(B_c)`. As [`taylor_step`]: `z` replaced by its image, or unchanged.
fn lohner1_step(
    plant: &Plant,
    z: &mut Zonotope,
    h: f64,
    s: &FlowSettings,
) -> Option<Vec<Interval>> {
    let d = z.dim();
    let n = d - 1;
    let bz = z.bbox();
    let b = apriori(plant, &bz, h)?;
    let jf = jacobian(plant, &b)?;
    let t = Interval::new(0.0, h);
    let tj: Vec<Vec<Interval>> = jf
        .iter()
        .map(|r| r.iter().map(|x| *x * t).collect())
        .collect();
    let id = identity(d);
    let add = |a: &[Vec<Interval>], b: &[Vec<Interval>]| -> Vec<Vec<Interval>> {
        a.iter()
            .zip(b)
            .map(|(x, y)| x.iter().zip(y).map(|(p, q)| *p + *q).collect())
            .collect()
    };
    let mut w = add(&id, &imat_mul(&tj, &add(&id, &tj)));
    let mut found = None;
    for _ in 0..10 {
        let inf: Vec<Vec<Interval>> = w
            .iter()
            .map(|r| {
                r.iter()
                    .map(|x| {
                        let e = 0.1 * (x.hi - x.lo) + 1e-12;
                        Interval::new(x.lo - e, x.hi + e)
                    })
                    .collect()
            })
            .collect();
        let nw = add(&id, &imat_mul(&tj, &inf));
        if nw.iter().zip(&inf).all(|(a, b)| subset(a, b)) {
            found = Some(nw);
            break;
        }
        w = nw;
    }
    let w = found?;
    let hj: Vec<Vec<Interval>> = jf
        .iter()
        .map(|r| r.iter().map(|x| *x * h).collect())
        .collect();
    // D phi_h = I + int_0^h J (D phi_tau) dtau with D phi_tau - I ∈ [0, tau] J W, so
    // D phi_h ∈ I + h J(B) + h^2/2 J(B) J(B) W: the [0, h] spread of W enters at
    // second order only.
    let h2j: Vec<Vec<Interval>> = jf
        .iter()
        .map(|r| {
            r.iter()
                .map(|x| *x * (Interval::point(h) * h * 0.5))
                .collect()
        })
        .collect();
    let wh = add(&add(&id, &hj), &imat_mul(&h2j, &imat_mul(&jf, &w)));
    // Centre, second order: phi_h(c) ∈ c + h f(c) + h^2/2 co(J(B_c) f(B_c)).
    let cpt: Vec<Interval> = z.c.iter().map(|&v| Interval::point(v)).collect();
    let bc = apriori(plant, &cpt, h)?;
    let f0 = rhs_interval(plant, &cpt);
    let fbc = rhs_interval(plant, &bc);
    let jbc = jacobian(plant, &bc)?;
    let h2 = Interval::point(h) * h * 0.5;
    let centre: Vec<Interval> = (0..n)
        .map(|j| {
            let mut jf = Interval::point(0.0);
            for k in 0..d {
                jf = jf + jbc[j][k] * fbc[k];
            }
            cpt[j] + f0[j] * h + jf * h2
        })
        .collect();
    if !finite(&centre) || wh.iter().any(|r| !finite(r)) {
        return None;
    }
    compose(z, &centre, &wh, s);
    Some(b)
}

/// The zeroth-order step `phi_h(Z) ⊆ Z ⊕ h f(B)`. As [`taylor_step`]: `z` replaced by
/// its image, or unchanged.
fn fallback_step(
    plant: &Plant,
    z: &mut Zonotope,
    h: f64,
    s: &FlowSettings,
) -> Option<Vec<Interval>> {
    let bz = z.bbox();
    let b = apriori(plant, &bz, h)?;
    let fb = rhs_interval(plant, &b);
    let mut r = vec![0.0; z.dim()];
    for j in 0..z.dim() - 1 {
        let inc = fb[j] * h;
        let m = 0.5 * (inc.lo + inc.hi);
        let e = (z.c[j].abs() + m.abs()) * f64::EPSILON;
        z.c[j] += m;
        r[j] = ((inc.hi - m).max(m - inc.lo) + e).next_up();
    }
    z.add_box(&r);
    z.reduce(s.max_noise_per_dim * z.dim());
    Some(b)
}

/// Enclose the flow of `z` (last row: the held control) over `[0, period]`. Returns
/// the final zonotope, the hull of `x + y` over the whole period, and statistics.
pub fn flow_period(
    plant: &Plant,
    z: &Zonotope,
    period: f64,
    s: &FlowSettings,
    h_start: &mut f64,
) -> Result<(Zonotope, Interval, FlowStats), FlowFailure> {
    let mut t = 0.0;
    let mut z = z.clone();
    let mut h = h_start.min(s.h).min(period);
    let mut st = FlowStats::default();
    let mut xy = z.x_plus_y();
    while t < period {
        let rest = period - t;
        let hh = if h >= rest * (1.0 - 1e-12) { rest } else { h };
        let mut hint = 0.5 * hh;
        // Each step replaces `z` by its image only where it succeeds.
        let mut res = taylor_step(plant, &mut z, hh, s, &mut hint);
        if res.is_some() {
            st.taylor_steps += 1;
        } else if hh <= s.h_min_taylor * 1.0001 || hint.is_nan() && hh <= s.h_lohner1 {
            // Not analytic here (hint NaN), or Taylor cannot be validated: first order.
            res =
                lohner1_step(plant, &mut z, hh, s).or_else(|| fallback_step(plant, &mut z, hh, s));
            if res.is_some() {
                st.fallback_steps += 1;
            }
        }
        match res {
            Some(b) => {
                xy = xy.hull(&(b[4] + b[5]));
                t = if hh == rest { period } else { t + hh };
                if hh < rest {
                    h = hint.clamp(0.5 * hh, 4.0 * hh).max(s.h_min_taylor).min(s.h);
                }
            }
            None => {
                st.rejected += 1;
                if hh <= s.h_min
                    || st.rejected + st.taylor_steps + st.fallback_steps > s.max_attempts
                {
                    return Err(FlowFailure::NoEnclosure { t });
                }
                h = if hint.is_nan() {
                    (0.5 * hh).min(s.h_lohner1)
                } else {
                    hint.clamp(0.1 * hh, 0.5 * hh)
                };
            }
        }
    }
    *h_start = h;
    Ok((z, xy, st))
}
