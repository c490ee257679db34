//! Forward symbolic interval propagation with a rigorous floating-point slack.
//!
//! Every neuron carries two linear functions of the network inputs, `L(x)` and `U(x)`,
//! with non-negative slacks `sl`, `su` such that for every input `x` of the box
//! `L(x) - sl <= z(x) <= U(x) + su`, where `L(x)` and `U(x)` are the *exact* real values
//! of the stored f64 coefficients. The slacks absorb every rounding error of the f64
//! arithmetic that produced the coefficients: a dot product of `k` terms computed in f64
//! is within `gamma_k * sum |terms|` of the exact one (Higham, *Accuracy and Stability
//! of Numerical Algorithms*, 2002, eq. 3.5), and `gamma_k = k u / (1 - k u)` is
//! over-approximated here by `(k + 2) * EPSILON` (twice as large). The slacks themselves
//! are sums of non-negative terms; they are inflated by a relative `1e-9` (their own
//! rounding is below `1e-13` relative) and rounded up.
//!
//! ReLU (Neurify, Wang et al., NeurIPS 2018): since ReLU is monotone,
//! `relu(L - sl) <= relu(z) <= relu(U + su)`; `relu(U + su)` is bounded above by the
//! chord over the range of `U + su` and `relu(L - sl)` below by `L - sl` or by 0
//! (whichever loses less area, as DeepPoly chooses). A neuron whose ranges decide its
//! phase is passed exactly.

use crate::rules::relu;
use samara_nn::{ir::Row, Affine};

mod batch;
mod sparse_pull;

/// One linear function of the inputs, `coef . x + cst`, with a slack.
#[derive(Clone, Debug, PartialEq)]
pub struct Linear {
    /// Coefficients over the inputs.
    pub coef: Vec<f64>,
    /// Constant term.
    pub cst: f64,
    /// Non-negative slack (see the module doc: lower functions subtract it, upper ones add it).
    pub slack: f64,
}

impl Linear {
    fn zero(n: usize) -> Self {
        Linear {
            coef: vec![0.0; n],
            cst: 0.0,
            slack: 0.0,
        }
    }

    /// A sound lower bound of `coef . x + cst - slack` over the box `[lo, hi]`.
    pub fn min_over(&self, lo: &[f64], hi: &[f64]) -> f64 {
        let (v, mag) = self.extreme(lo, hi, false);
        let err = gamma(self.coef.len() + 1) * mag;
        (v - inflate(err + self.slack)).next_down()
    }

    /// A sound upper bound of `coef . x + cst + slack` over the box `[lo, hi]`.
    pub fn max_over(&self, lo: &[f64], hi: &[f64]) -> f64 {
        let (v, mag) = self.extreme(lo, hi, true);
        let err = gamma(self.coef.len() + 1) * mag;
        (v + inflate(err + self.slack)).next_up()
    }

    /// The f64 value of `coef . x + cst` at its minimiser (or maximiser) over the box,
    /// and the sum of the magnitudes of its terms.
    fn extreme(&self, lo: &[f64], hi: &[f64], max: bool) -> (f64, f64) {
        let mut v = self.cst;
        let mut mag = self.cst.abs();
        for (t, &c) in self.coef.iter().enumerate() {
            let (a, b) = (c * lo[t], c * hi[t]);
            let pick = if max { a.max(b) } else { a.min(b) };
            v += pick;
            mag += a.abs().max(b.abs());
        }
        (v, mag)
    }

    /// The non-negative combination `a * self + b * other` (`a, b >= 0`), a lower bound
    /// of `a g + b h` when `self` and `other` are lower bounds of `g` and `h`; the
    /// rounding of the combined coefficients over the box `[lo, hi]` joins the slack.
    pub fn combine(&self, a: f64, other: &Linear, b: f64, lo: &[f64], hi: &[f64]) -> Linear {
        debug_assert!(a >= 0.0 && b >= 0.0);
        let xmax = magnitudes(lo, hi);
        let mut err = 0.0;
        let coef: Vec<f64> = self
            .coef
            .iter()
            .zip(&other.coef)
            .zip(&xmax)
            .map(|((p, q), m)| {
                let (u, v) = (a * p, b * q);
                err += (u.abs() + v.abs()) * m;
                u + v
            })
            .collect();
        let (u, v) = (a * self.cst, b * other.cst);
        err += u.abs() + v.abs();
        Linear {
            coef,
            cst: u + v,
            slack: inflate(a * self.slack + b * other.slack + gamma(3) * err),
        }
    }

    /// `-f`: the coefficients and constant negated (exact in floating point), the slack
    /// kept. A lower bound of `h` negated is an upper bound of `-h`, not a lower one:
    /// this is only a lower bound of `-h` where `f` is exact up to its slack, as for a
    /// pull-back that relaxes no neuron (every earlier neuron stable or fixed).
    pub(crate) fn negated(&self) -> Linear {
        Linear {
            coef: self.coef.iter().map(|c| -c).collect(),
            cst: -self.cst,
            slack: self.slack,
        }
    }

    /// The box corner that minimises `coef . x` (ties to the lower end).
    pub fn argmin_corner(&self, lo: &[f64], hi: &[f64]) -> Vec<f64> {
        self.coef
            .iter()
            .enumerate()
            .map(|(t, &c)| if c < 0.0 { hi[t] } else { lo[t] })
            .collect()
    }
}

/// `max(|lo_t|, |hi_t|)` per input: the bound on `|x_t|` that turns a coefficient's
/// rounding error into an error of the function's value.
pub(crate) fn magnitudes(lo: &[f64], hi: &[f64]) -> Vec<f64> {
    lo.iter()
        .zip(hi)
        .map(|(a, b)| a.abs().max(b.abs()))
        .collect()
}

/// `sum_t |c_t| * xmax_t`: with it the rounding bound of a sum of scaled linear
/// functions, `gamma * sum_t (sum_i |w_i c_it|) * xmax_t`, is the same sum regrouped,
/// `gamma * sum_i |w_i| * coef_magnitude(c_i)` (non-negative terms, so the identity is
/// exact; its f64 evaluation is off by a relative `1e-13` at most, far inside
/// [`inflate`]'s `1e-9`), and the inner loop of a layer is a plain multiply-add.
fn coef_magnitude(c: &[f64], xmax: &[f64]) -> f64 {
    c.iter().zip(xmax).map(|(c, x)| c.abs() * x).sum::<f64>()
}

use samara_num::round::{gamma, inflate};

/// Symbolic bounds of one layer's neurons.
#[derive(Clone, Debug)]
pub struct LayerBounds {
    /// Lower functions, one per neuron.
    pub lower: Vec<Linear>,
    /// Upper functions, one per neuron.
    pub upper: Vec<Linear>,
}

impl LayerBounds {
    /// The identity on `n` inputs (exact, zero slack).
    pub fn identity(n: usize) -> Self {
        let f = |i: usize| {
            let mut l = Linear::zero(n);
            l.coef[i] = 1.0;
            l
        };
        LayerBounds {
            lower: (0..n).map(f).collect(),
            upper: (0..n).map(f).collect(),
        }
    }

    /// Sound concrete bounds `[min lower_i, max upper_i]` of each neuron over the box.
    pub fn concretise(&self, lo: &[f64], hi: &[f64]) -> Vec<(f64, f64)> {
        self.lower
            .iter()
            .zip(&self.upper)
            .map(|(l, u)| (l.min_over(lo, hi), u.max_over(lo, hi)))
            .collect()
    }
}

/// The row `sum_i w_i a_i + b` applied to symbolic bounds of `a`: the lower function
/// (takes `a`'s lower function where `w_i > 0`, its upper where `w_i < 0`) or, with
/// `upper`, the upper one. `row_err` is an extra per-weight error bound (`w_i` known only
/// to within `row_err[i]`), `b_err` the same for `b`; `amax[i]` bounds `|a_i|`.
fn affine_row(
    w: &[f64],
    b: f64,
    a: &LayerBounds,
    upper: bool,
    row_err: Option<(&[f64], f64, &[f64])>,
    xmax: &[f64],
) -> Linear {
    let n = xmax.len();
    let mut out = Linear::zero(n);
    let mut mag_c = b.abs();
    let mut wmag = 0.0;
    let mut slack = 0.0;
    out.cst = b;
    for (i, &wi) in w.iter().enumerate() {
        if wi == 0.0 {
            continue;
        }
        let src = if (wi > 0.0) == upper {
            &a.upper[i]
        } else {
            &a.lower[i]
        };
        for (o, &c) in out.coef.iter_mut().zip(&src.coef) {
            *o += wi * c;
        }
        let p = wi * src.cst;
        out.cst += p;
        mag_c += p.abs();
        wmag += wi.abs() * coef_magnitude(&src.coef, xmax);
        slack += wi.abs() * src.slack;
    }
    let k = w.len() + 1;
    let mut err = gamma(k) * mag_c + gamma(k) * wmag;
    if let Some((we, be, amax)) = row_err {
        for i in 0..w.len() {
            err += we[i] * amax[i];
        }
        err += be;
    }
    out.slack = inflate(slack + err);
    out
}

/// Symbolic bounds of `W a + b` from those of `a`.
pub fn affine(m: &Affine, a: &LayerBounds, xmax: &[f64]) -> LayerBounds {
    let rows = |upper: bool| -> Vec<Linear> {
        (0..m.out)
            .map(|i| affine_row(&m.dense_row(i), m.b[i], a, upper, None, xmax))
            .collect()
    };
    LayerBounds {
        lower: rows(false),
        upper: rows(true),
    }
}

/// Symbolic bounds of `relu(z)` from those of `z` over the box (module doc).
///
/// `known` gives concrete bounds of `z` proved elsewhere (e.g. on a box containing this
/// one); a neuron they show stable is passed exactly (identity or zero).
pub fn relu(z: &LayerBounds, lo: &[f64], hi: &[f64], known: Option<&[(f64, f64)]>) -> LayerBounds {
    let n = lo.len();
    let xmax = magnitudes(lo, hi);
    let mut lower = Vec::with_capacity(z.lower.len());
    let mut upper = Vec::with_capacity(z.upper.len());
    for (i, (l, u)) in z.lower.iter().zip(&z.upper).enumerate() {
        match known.map(|k| k[i]) {
            Some((kl, _)) if kl >= 0.0 => {
                lower.push(l.clone());
                upper.push(u.clone());
                continue;
            }
            Some((_, ku)) if ku <= 0.0 => {
                lower.push(Linear::zero(n));
                upper.push(Linear::zero(n));
                continue;
            }
            _ => {}
        }
        // Range of U + su.
        let (ul, uh) = (u.min_over(lo, hi), u.max_over(lo, hi));
        upper.push(if uh <= 0.0 {
            Linear::zero(n)
        } else if ul >= 0.0 {
            u.clone()
        } else {
            // Chord over [ul, uh]: relu(t) <= s (t - ul), s >= uh / (uh - ul).
            let s = relu::chord_slope_up(ul, uh);
            let mut f = Linear::zero(n);
            let mut mag = 0.0;
            for ((fc, uc), xm) in f.coef.iter_mut().zip(&u.coef).zip(&xmax) {
                *fc = s * uc;
                mag += fc.abs() * xm;
            }
            let (sc, sl) = (s * u.cst, s * ul);
            f.cst = sc - sl;
            mag += sc.abs() + sl.abs();
            f.slack = inflate(s * u.slack + gamma(3) * mag);
            f
        });
        // Range of L - sl.
        let (ll, lh) = (l.min_over(lo, hi), l.max_over(lo, hi));
        lower.push(if lh <= 0.0 {
            Linear::zero(n)
        } else if ll >= 0.0 || relu::default_lower_slope(ll, lh) == 1.0 {
            // relu(t) >= t.
            l.clone()
        } else {
            // relu(t) >= 0.
            Linear::zero(n)
        });
    }
    LayerBounds { lower, upper }
}

/// A linear objective `c . y + d` over the network's outputs `y`.
#[derive(Clone, Debug, PartialEq)]
pub struct Objective {
    /// Coefficients over the outputs.
    pub c: Vec<f64>,
    /// Constant.
    pub d: f64,
}

/// Propagate the box `[lo, hi]` through every map but the last; return the symbolic
/// bounds of the last map's input `a`, the last map, and the concrete pre-activation
/// bounds of every map but the last (for [`backward_lower`]), intersected with `known`
/// (bounds proved on a box containing this one, e.g. the parent piece's) when given.
#[allow(clippy::type_complexity)]
pub fn hidden<'a>(
    maps: &'a [(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    known: Option<&[Vec<(f64, f64)>]>,
) -> (LayerBounds, &'a Affine, Vec<Vec<(f64, f64)>>) {
    let xmax = magnitudes(lo, hi);
    let mut a = LayerBounds::identity(lo.len());
    let (last, body) = maps.split_last().expect("a network has at least one map");
    assert!(!last.1, "the last map of a chain carries no ReLU");
    let mut pre = Vec::with_capacity(body.len());
    for (m, r) in body {
        let z = affine(m, &a, &xmax);
        let mut b = z.concretise(lo, hi);
        if let Some(k) = known {
            for (bi, ki) in b.iter_mut().zip(&k[pre.len()]) {
                *bi = (bi.0.max(ki.0), bi.1.min(ki.1));
            }
        }
        a = if *r { relu(&z, lo, hi, Some(&b)) } else { z };
        pre.push(b);
    }
    (a, &last.0, pre)
}

/// Linear functions of one layer stored flat (`coef` row-major, one row of `n` per
/// neuron), for [`hidden_pre`].
struct Flat {
    coef: Vec<f64>,
    cst: Vec<f64>,
    slack: Vec<f64>,
}

impl Flat {
    fn zeros(m: usize, n: usize) -> Self {
        Flat {
            coef: vec![0.0; m * n],
            cst: vec![0.0; m],
            slack: vec![0.0; m],
        }
    }

    /// [`Linear::min_over`] / [`Linear::max_over`] of row `i`, the same operations in
    /// the same order (so the same f64 result).
    fn bound(&self, i: usize, n: usize, lo: &[f64], hi: &[f64], max: bool) -> f64 {
        let c = &self.coef[i * n..(i + 1) * n];
        let mut v = self.cst[i];
        let mut mag = self.cst[i].abs();
        for t in 0..n {
            let (a, b) = (c[t] * lo[t], c[t] * hi[t]);
            v += if max { a.max(b) } else { a.min(b) };
            mag += a.abs().max(b.abs());
        }
        let err = gamma(n + 1) * mag;
        if max {
            (v + inflate(err + self.slack[i])).next_up()
        } else {
            (v - inflate(err + self.slack[i])).next_down()
        }
    }
}

/// The concrete pre-activation bounds of [`hidden`] (its third result), computed with the
/// same operations in the same order but on flat arrays, without a heap allocation per
/// neuron: the forward symbolic pass is the inner loop of every piece of the search.
pub fn hidden_pre(
    maps: &[(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    known: Option<&[Vec<(f64, f64)>]>,
) -> Vec<Vec<(f64, f64)>> {
    hidden_pre_until(maps, lo, hi, known, None)
}

/// [`hidden_pre`] that gives up at `deadline`, returning `known` (bounds of a box
/// containing this one, so sound here) or unbounded ranges: on a wide network with
/// many inputs one pass takes about a second, and a time limit must hold.
pub fn hidden_pre_until(
    maps: &[(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    known: Option<&[Vec<(f64, f64)>]>,
    deadline: Option<std::time::Instant>,
) -> Vec<Vec<(f64, f64)>> {
    let late = || deadline.is_some_and(|d| std::time::Instant::now() >= d);
    let give_up = || match known {
        Some(k) => k.to_vec(),
        None => maps[..maps.len().saturating_sub(1)]
            .iter()
            .map(|(m, _)| vec![(f64::NEG_INFINITY, f64::INFINITY); m.out])
            .collect(),
    };
    let n = lo.len();
    let xmax = magnitudes(lo, hi);
    let (last, body) = maps.split_last().expect("a network has at least one map");
    assert!(!last.1, "the last map of a chain carries no ReLU");
    // The identity, never formed: the first map's rows are its functions (below).
    let mut al = Flat::zeros(0, n);
    let mut au = Flat::zeros(0, n);
    let mut pre = Vec::with_capacity(body.len());
    for (m, r) in body {
        let k = m.inp + 1;
        let mut zl = Flat::zeros(m.out, n);
        let mut zu = Flat::zeros(m.out, n);
        if pre.is_empty() {
            // The first map over the identity: its rows, with the rounding bound of the
            // general step below for identity sources (coefficient magnitude `xmax_i`,
            // constant 0, slack 0). An `n x n` identity times the map would cost
            // `out * n * n` (a quarter of a second per pass at 784 inputs).
            for o in 0..m.out {
                let w = &m.dense_row(o)[..];
                let wmag: f64 = w.iter().zip(&xmax).map(|(wi, x)| wi.abs() * x).sum();
                let err = gamma(k) * m.b[o].abs() + gamma(k) * wmag;
                for z in [&mut zl, &mut zu] {
                    z.coef[o * n..(o + 1) * n].copy_from_slice(w);
                    z.cst[o] = m.b[o];
                    z.slack[o] = inflate(err);
                }
            }
        }
        // On many inputs (images), the columns where each source row's lower or upper
        // function is non-zero: a lowered convolution's neuron depends on a small patch
        // of the image, and skipping the exact zeros of a row (in the same order) leaves
        // every sum's bits as they are, for a fraction of the work.
        let supp: Option<Vec<Vec<u32>>> = (n >= 64 && !pre.is_empty()).then(|| {
            (0..m.inp)
                .map(|i| {
                    let (rl, ru) = (&al.coef[i * n..(i + 1) * n], &au.coef[i * n..(i + 1) * n]);
                    (0..n)
                        .filter(|&t| rl[t] != 0.0 || ru[t] != 0.0)
                        .map(|t| t as u32)
                        .collect()
                })
                .collect()
        });
        // Each source row's `coef_magnitude`, once per layer (see there).
        let cm = |f: &Flat| -> Vec<f64> {
            (0..m.inp)
                .map(|i| {
                    let c = &f.coef[i * n..(i + 1) * n];
                    match &supp {
                        Some(sp) => sp[i]
                            .iter()
                            .map(|&t| c[t as usize].abs() * xmax[t as usize])
                            .sum::<f64>(),
                        None => coef_magnitude(c, &xmax),
                    }
                })
                .collect()
        };
        let (cml, cmu) = match pre.is_empty() {
            true => (Vec::new(), Vec::new()),
            false => (cm(&al), cm(&au)),
        };
        // Output row `o` of the lower (`upper` false) or upper function: its
        // coefficients into `out`, its constant and slack returned.
        let row = |upper: bool, o: usize, out: &mut [f64]| -> (f64, f64) {
            let mut cst = m.b[o];
            let mut mag_c = m.b[o].abs();
            let mut wmag = 0.0;
            let mut slack = 0.0;
            m.row(o).for_each_nonzero(|i, wi| {
                let (src, srcm) = if (wi > 0.0) == upper {
                    (&au, &cmu)
                } else {
                    (&al, &cml)
                };
                let sc = &src.coef[i * n..(i + 1) * n];
                match &supp {
                    Some(sp) => {
                        for &t in &sp[i] {
                            out[t as usize] += wi * sc[t as usize];
                        }
                    }
                    None => {
                        for (ot, &c) in out.iter_mut().zip(sc) {
                            *ot += wi * c;
                        }
                    }
                }
                let p = wi * src.cst[i];
                cst += p;
                mag_c += p.abs();
                wmag += wi.abs() * srcm[i];
                slack += wi.abs() * src.slack[i];
            });
            let err = gamma(k) * mag_c + gamma(k) * wmag;
            (cst, inflate(slack + err))
        };
        for (upper, z) in [(false, &mut zl), (true, &mut zu)] {
            if pre.is_empty() {
                break;
            }
            if supp.is_some() {
                // Rows in parallel (each is its own sum, so the same bits).
                use rayon::prelude::*;
                let gave_up = std::sync::atomic::AtomicBool::new(false);
                let cs: Vec<(f64, f64)> = z
                    .coef
                    .par_chunks_mut(n)
                    .enumerate()
                    .map(|(o, out)| {
                        if o % 16 == 0 && late() {
                            gave_up.store(true, std::sync::atomic::Ordering::Relaxed);
                        }
                        if gave_up.load(std::sync::atomic::Ordering::Relaxed) {
                            return (0.0, 0.0);
                        }
                        row(upper, o, out)
                    })
                    .collect();
                if gave_up.into_inner() {
                    return give_up();
                }
                for (o, (c, sl)) in cs.into_iter().enumerate() {
                    z.cst[o] = c;
                    z.slack[o] = sl;
                }
                continue;
            }
            for o in 0..m.out {
                if o % 16 == 0 && late() {
                    return give_up();
                }
                let (c, sl) = row(upper, o, &mut z.coef[o * n..(o + 1) * n]);
                z.cst[o] = c;
                z.slack[o] = sl;
            }
        }
        let mut b: Vec<(f64, f64)> = (0..m.out)
            .map(|i| (zl.bound(i, n, lo, hi, false), zu.bound(i, n, lo, hi, true)))
            .collect();
        if let Some(kn) = known {
            for (bi, ki) in b.iter_mut().zip(&kn[pre.len()]) {
                *bi = (bi.0.max(ki.0), bi.1.min(ki.1));
            }
        }
        if *r {
            // relu (the same cases as [`relu`]).
            for (i, &(kl, ku)) in b.iter().enumerate() {
                let row = i * n..(i + 1) * n;
                if kl >= 0.0 {
                    continue;
                }
                if ku <= 0.0 {
                    for f in [&mut zl, &mut zu] {
                        f.coef[row.clone()].iter_mut().for_each(|v| *v = 0.0);
                        f.cst[i] = 0.0;
                        f.slack[i] = 0.0;
                    }
                    continue;
                }
                let (ul, uh) = (zu.bound(i, n, lo, hi, false), zu.bound(i, n, lo, hi, true));
                if uh <= 0.0 {
                    zu.coef[row.clone()].iter_mut().for_each(|v| *v = 0.0);
                    zu.cst[i] = 0.0;
                    zu.slack[i] = 0.0;
                } else if ul < 0.0 {
                    let s = relu::chord_slope_up(ul, uh);
                    let mut mg = 0.0;
                    for (fc, xm) in zu.coef[row.clone()].iter_mut().zip(&xmax) {
                        *fc *= s;
                        mg += fc.abs() * xm;
                    }
                    let (sc, sl) = (s * zu.cst[i], s * ul);
                    zu.cst[i] = sc - sl;
                    mg += sc.abs() + sl.abs();
                    zu.slack[i] = inflate(s * zu.slack[i] + gamma(3) * mg);
                }
                let (ll, lh) = (zl.bound(i, n, lo, hi, false), zl.bound(i, n, lo, hi, true));
                if lh <= 0.0 || !(ll >= 0.0 || relu::default_lower_slope(ll, lh) == 1.0) {
                    zl.coef[row].iter_mut().for_each(|v| *v = 0.0);
                    zl.cst[i] = 0.0;
                    zl.slack[i] = 0.0;
                }
            }
        }
        al = zl;
        au = zu;
        pre.push(b);
    }
    pre
}

/// CROWN's backward bound (Zhang et al., NeurIPS 2018) of `c . f(x) + d` over the box:
/// the objective is pulled back through every map, each ReLU replaced by its linear
/// relaxation from the concrete pre-activation bounds `pre` (from [`hidden`]): the chord
/// `a <= s (z - l)` where the coefficient is negative, `a >= alpha z` where it is
/// positive (`alpha` = 1 if `u > -l` else 0). Tighter than the forward bounds on deep
/// networks, since no relaxation is applied twice. Every rounding error of the pull-back
/// is bounded (`gamma` of each dot product times the magnitudes, times a bound on the
/// variable it multiplies) and carried in the slack.
pub fn backward_lower(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    lo: &[f64],
    hi: &[f64],
) -> Linear {
    backward_lower_alpha(maps, pre, obj, lo, hi, None)
}

/// [`backward_lower`] with given lower-relaxation slopes: `alpha[j][t]` in `[0, 1]` is
/// the slope of `a >= alpha z` for unstable neuron `t` of map `j` (any value in `[0, 1]`
/// is sound; `None` takes CROWN's choice, 1 if `u > -l` else 0).
pub fn backward_lower_alpha(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    lo: &[f64],
    hi: &[f64],
    alpha: Option<&[Vec<f64>]>,
) -> Linear {
    backward_lower_beta(maps, pre, obj, lo, hi, alpha, None)
}

/// [`backward_lower_alpha`] with beta-CROWN's split multipliers (Wang et al., NeurIPS
/// 2021): `beta[j][t]` is added to the pull-back's coefficient of the pre-activation
/// `z_t` of map `j`, i.e. the term `beta[j][t] * z_t(x)` joins the objective. That is a
/// lower bound of the objective on every input where `beta[j][t] * z_t(x) <= 0`, so a
/// term is used only where the bounds `pre` (valid on the set bounded) show it: a
/// non-negative multiplier on a neuron with `u <= 0` (inactive, split or not), a
/// non-positive one on a neuron with `l >= 0`; other entries are ignored. With a
/// neuron's phase fixed by clamping its bounds, the multiplier is its split
/// constraint's Lagrange multiplier.
pub fn backward_lower_beta(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    lo: &[f64],
    hi: &[f64],
    alpha: Option<&[Vec<f64>]>,
    beta: Option<&[Vec<f64>]>,
) -> Linear {
    backward_lower_sp(maps, pre, obj, lo, hi, alpha, beta, None)
}

/// [`backward_lower_beta`] over the sparse view `sp` of `maps` (the same bound).
#[allow(clippy::too_many_arguments)]
pub(crate) fn backward_lower_sp(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    lo: &[f64],
    hi: &[f64],
    alpha: Option<&[Vec<f64>]>,
    beta: Option<&[Vec<f64>]>,
    sp: Option<&Sparse>,
) -> Linear {
    let inmax = input_magnitudes(maps, pre, lo, hi, maps.len());
    backward_core(
        maps,
        pre,
        &obj.c,
        obj.d,
        alpha,
        beta,
        Mags::Inputs(&inmax),
        sp,
        None,
    )
}

/// The row magnitudes ([`row_magnitude`]) of every map of the chain for the bounds
/// `pre` (valid on the box or on a set containing the one later bounded): computed once
/// for many pull-backs through the same bounds with [`backward_lower_rows`]. Magnitudes
/// from looser bounds (a parent node's) stay sound for tighter ones: they only bound
/// `|input|` from above.
pub(crate) fn row_magnitudes(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    lo: &[f64],
    hi: &[f64],
) -> Vec<Vec<f64>> {
    input_magnitudes(maps, pre, lo, hi, maps.len())
        .iter()
        .enumerate()
        .map(|(j, im)| row_magnitude(&maps[j].0, None, im))
        .collect()
}

/// [`backward_lower`] with the row magnitudes given ([`row_magnitudes`] of `maps` or of
/// a longer chain starting with them, for bounds containing `pre`), instead of a second,
/// absolute-value pass over the weights at every call.
pub(crate) fn backward_lower_rows(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    rows: &[Vec<f64>],
) -> Linear {
    backward_core(
        maps,
        pre,
        &obj.c,
        obj.d,
        None,
        None,
        Mags::Rows(rows),
        None,
        None,
    )
}

/// Whether the split multiplier `c` on a neuron with bounds `(l, u)` adds a term
/// `c * z <= 0` (see [`backward_lower_beta`]).
fn beta_applies(c: f64, (l, u): (f64, f64)) -> bool {
    (c > 0.0 && u <= 0.0) || (c < 0.0 && l >= 0.0)
}

/// The magnitudes a pull-back's rounding bound needs: the [`row_magnitudes`], when many
/// pull-backs share them (CROWN's intermediate bounds), or the input magnitudes
/// ([`input_magnitudes`]), of which a single pull-back sums only the rows it uses.
#[derive(Clone, Copy)]
enum Mags<'a> {
    Rows(&'a [Vec<f64>]),
    Inputs(&'a [Vec<f64>]),
}

/// One map's row magnitudes `r[i] = sum_t |W[i, t]| * inmax[t]`, for the input bound
/// `inmax` ([`input_magnitudes`]): with them the rounding bound of a pull-back through
/// the map, `gamma * sum_t (sum_i |mu_i W[i, t]|) * inmax[t]`, is the same sum regrouped,
/// `gamma * sum_i |mu_i| * r[i]` (all terms are non-negative, so the identity is exact;
/// the f64 evaluation of `r` and of the sum is off by a relative `1e-13` at most, far
/// inside [`inflate`]'s `1e-9`). Computed once per set of bounds, it spares every
/// pull-back of CROWN's intermediate bounds a second, absolute-value pass over the
/// weights.
fn row_magnitude(m: &Affine, sp: Option<&Rows>, inmax: &[f64]) -> Vec<f64> {
    (0..m.out)
        .map(|i| row_coef_magnitude(m, sp, i, inmax))
        .collect()
}

/// Bounds of `|input of map j|` for `j < upto`: the box's magnitudes for map 0, the
/// (ReLU'd) pre-activation bounds of map `j - 1` after.
pub(crate) fn input_magnitudes(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    lo: &[f64],
    hi: &[f64],
    upto: usize,
) -> Vec<Vec<f64>> {
    (0..upto)
        .map(|j| {
            if j == 0 {
                magnitudes(lo, hi)
            } else {
                let r = maps[j - 1].1;
                pre[j - 1]
                    .iter()
                    .map(|&(l, u)| {
                        if r {
                            l.max(0.0).abs().max(u.max(0.0).abs())
                        } else {
                            l.abs().max(u.abs())
                        }
                    })
                    .collect()
            }
        })
        .collect()
}

/// The non-zero weights of one map by row (compressed sparse rows), for the maps of
/// lowered convolutions, where a row has a kernel's worth of non-zeros among thousands
/// of inputs (oval21's first layer: 48 of 3,072).
struct Rows {
    /// Row `i`'s entries are `start[i]..start[i + 1]`.
    start: Vec<usize>,
    col: Vec<u32>,
    val: Vec<f64>,
}

/// A sparse view of a chain's maps ([`Rows`] where at most a quarter of the weights are
/// non-zero, `None` for the others), built from the dense weights once per group of
/// passes. Passes that iterate only the non-zero entries of a row in column order do
/// the same floating-point operations in the same order as the dense loops minus the
/// additions of exact zeros, so they give the same bits (except where a dense loop
/// would multiply an infinite bound by a zero weight and make a NaN).
pub(crate) struct Sparse {
    rows: Vec<Option<Rows>>,
}

/// Boxes with fewer inputs keep the dense loops ([`Sparse::of`]).
const SPARSE_MIN_INPUTS: usize = 64;

impl Sparse {
    /// The sparse view of `maps`, or `None` when no map is sparse enough to gain or the
    /// box has fewer than 64 inputs (there the dense loops are what the search was
    /// measured with, and a build per call would cost more than it saves).
    pub(crate) fn of(maps: &[(Affine, bool)], inputs: usize) -> Option<Sparse> {
        if inputs < SPARSE_MIN_INPUTS {
            return None;
        }
        let rows: Vec<Option<Rows>> = maps
            .iter()
            .map(|(m, _)| {
                let nnz = m.nonzeros();
                if !Self::gains(m, nnz) {
                    return None;
                }
                let mut start = Vec::with_capacity(m.out + 1);
                let mut col = Vec::with_capacity(nnz);
                let mut val = Vec::with_capacity(nnz);
                start.push(0);
                for i in 0..m.out {
                    m.row(i).for_each_nonzero(|t, w| {
                        col.push(t as u32);
                        val.push(w);
                    });
                    start.push(col.len());
                }
                Some(Rows { start, col, val })
            })
            .collect();
        if rows.iter().all(|r| r.is_none()) {
            return None;
        }
        Some(Sparse { rows })
    }

    /// Whether [`Sparse::of`] gives a view of `maps` (without building it): some map
    /// sparse enough ([`Sparse::gains`]) on a box of at least [`SPARSE_MIN_INPUTS`] inputs.
    pub(crate) fn applies(maps: &[(Affine, bool)], inputs: usize) -> bool {
        inputs >= SPARSE_MIN_INPUTS && maps.iter().any(|(m, _)| Self::gains(m, m.nonzeros()))
    }

    /// Whether map `m`, with `nnz` non-zero weights, gets sparse rows: at most a quarter
    /// of its weights non-zero (and column indices that fit a `u32`).
    fn gains(m: &Affine, nnz: usize) -> bool {
        nnz * 4 <= m.out * m.inp && m.inp <= u32::MAX as usize
    }

    /// The sparse rows of map `j`, when it has them (`self` covers a chain of which
    /// `maps` is a prefix).
    fn map(sp: Option<&Sparse>, j: usize) -> Option<&Rows> {
        sp.and_then(|s| s.rows.get(j)).and_then(|r| r.as_ref())
    }
}

impl Rows {
    /// Row `i`'s columns and weights.
    fn row(&self, i: usize) -> (&[u32], &[f64]) {
        let r = self.start[i]..self.start[i + 1];
        (&self.col[r.clone()], &self.val[r])
    }
}

/// `out += a * W[i, :]` of map `m` (its sparse rows `sp` when given).
#[inline(always)]
fn axpy_row(m: &Affine, sp: Option<&Rows>, i: usize, a: f64, out: &mut [f64]) {
    match sp {
        Some(r) => {
            let (c, v) = r.row(i);
            for (&t, &w) in c.iter().zip(v) {
                out[t as usize] += a * w;
            }
        }
        None => match m.row(i) {
            Row::Dense(w) => {
                for (o, &w) in out.iter_mut().zip(w) {
                    *o += a * w;
                }
            }
            r => r.for_each_nonzero(|t, w| out[t] += a * w),
        },
    }
}

/// `sum_t |W[i, t]| * x[t]` of map `m` ([`coef_magnitude`] of the row).
#[inline(always)]
fn row_coef_magnitude(m: &Affine, sp: Option<&Rows>, i: usize, x: &[f64]) -> f64 {
    match sp {
        Some(r) => {
            let (c, v) = r.row(i);
            c.iter().zip(v).map(|(&t, w)| w.abs() * x[t as usize]).sum()
        }
        None => match m.row(i) {
            Row::Dense(w) => coef_magnitude(w, x),
            r => r.abs_dot(x),
        },
    }
}

/// The pull-back of [`backward_lower_alpha`] with the magnitudes for its rounding bound
/// given ([`Mags`]); the objective is `c . y + d`, with the split multipliers `beta` of
/// [`backward_lower_beta`]. `slopes[j][t]`, when given, is the chord slope
/// ([`relu::chord_slope_up`]) of unstable neuron `t` of `pre[j]`, computed once for the
/// many pull-backs through the same bounds (CROWN's intermediate bounds) instead of a
/// division per neuron in each.
#[allow(clippy::too_many_arguments)]
fn backward_core(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    c: &[f64],
    d: f64,
    alpha: Option<&[Vec<f64>]>,
    beta: Option<&[Vec<f64>]>,
    mags: Mags,
    sp: Option<&Sparse>,
    slopes: Option<&[Vec<f64>]>,
) -> Linear {
    let mut mu = c.to_vec();
    let mut cst = d;
    let mut err = 0.0;
    let mut nu: Vec<f64> = Vec::new();
    for j in (0..maps.len()).rev() {
        let m = &maps[j].0;
        let k = m.out + 1;
        nu.clear();
        nu.resize(m.inp, 0.0);
        // The running constant is the first term of this layer's sum: its magnitude
        // counts in the sum's rounding bound (a large constant carried from later
        // layers makes every addition round at its scale).
        let mut cmag = cst.abs();
        // sum_t (sum_i |mu_i w_it|) |x_t|, regrouped (see `row_magnitudes`).
        let mut wmag = 0.0;
        let rows = Sparse::map(sp, j);
        let given = match mags {
            Mags::Rows(r) => Some(&r[j][..]),
            Mags::Inputs(_) => None,
        };
        for (i, (&mi, &bi)) in mu.iter().zip(&m.b).enumerate() {
            if mi == 0.0 {
                continue;
            }
            let p = mi * bi;
            cst += p;
            cmag += p.abs();
            wmag += mi.abs()
                * match (given, mags) {
                    (Some(r), _) => r[i],
                    (None, Mags::Inputs(x)) => row_coef_magnitude(m, rows, i, &x[j]),
                    (None, Mags::Rows(r)) => r[j][i],
                };
            match (rows, m.row(i)) {
                // The dense row inline (the pull-backs of CROWN's intermediate bounds
                // spend most of their time here): `axpy_row`'s operations, in its order.
                (None, Row::Dense(w)) => {
                    for (o, &wt) in nu.iter_mut().zip(w) {
                        *o += mi * wt;
                    }
                }
                _ => axpy_row(m, rows, i, mi, &mut nu),
            }
        }
        err += gamma(k) * (cmag + wmag);
        if j == 0 || !maps[j - 1].1 {
            std::mem::swap(&mut mu, &mut nu);
            if j == 0 {
                break;
            }
            continue;
        }
        // nu is over the output a of map j - 1.
        mu.clear();
        mu.resize(nu.len(), 0.0);
        let z = &mut mu;
        relax_relu(
            &nu,
            &pre[j - 1],
            slopes.map(|s| &s[j - 1][..]),
            alpha.map(|a| &a[j - 1][..]),
            z,
            &mut cst,
            &mut err,
        );
        if let Some(b) = beta {
            for (t, &c) in b[j - 1].iter().enumerate() {
                let (l, u) = pre[j - 1][t];
                if beta_applies(c, (l, u)) {
                    // The sum's rounding times a bound on |z_t|.
                    z[t] += c;
                    err += 2.0 * f64::EPSILON * z[t].abs() * l.abs().max(u.abs());
                }
            }
        }
    }
    // `mu` ends over the inputs but keeps the capacity of the widest layer it crossed:
    // kept per neuron (CROWN's intermediate bounds keep every neuron's functions), that
    // capacity multiplied memory by the width ratio (a 23,328-neuron convolution over 784
    // inputs: 30x, 11 GB on VNN-COMP 2021 verivital's maxpool network).
    mu.shrink_to_fit();
    Linear {
        coef: mu,
        cst,
        slack: inflate(err),
    }
}

/// One pull-back's step through a ReLU layer (CROWN's relaxation, Zhang et al., NeurIPS
/// 2018): the coefficients `nu` over the layer's outputs become `z` over its inputs
/// (`z` zeroed by the caller), each neuron with bounds `pre` relaxed by the sign of its
/// coefficient: the chord above (slope `slopes[t]` when given, else
/// [`relu::chord_slope_up`]), a lower line below (slope `alpha[t]` when given, else
/// CROWN's default). The chords' intercepts go into `cst`, the products' and sums'
/// rounding into `err`. Shared by [`backward_core`] and the batched pull-backs
/// ([`batch`]), which must give the same bits.
#[inline]
fn relax_relu(
    nu: &[f64],
    pre: &[(f64, f64)],
    slopes: Option<&[f64]>,
    alpha: Option<&[f64]>,
    z: &mut [f64],
    cst: &mut f64,
    err: &mut f64,
) {
    for (t, &v) in nu.iter().enumerate() {
        let (l, u) = pre[t];
        if v == 0.0 || u <= 0.0 {
            continue;
        }
        if l >= 0.0 {
            z[t] = v;
        } else if v < 0.0 {
            let s = match slopes {
                Some(sl) => sl[t],
                None => relu::chord_slope_up(l, u),
            };
            z[t] = v * s;
            let c = -(v * s) * l;
            *cst += c;
            // The products' rounding, and the addition's (at most one ulp of the sum).
            *err += 2.0 * f64::EPSILON * (z[t].abs() * l.abs().max(u.abs()) + c.abs())
                + f64::EPSILON * cst.abs();
        } else if let Some(a) = alpha {
            let al = relu::alpha_range(a[t]);
            z[t] = v * al;
            *err += f64::EPSILON * z[t].abs() * l.abs().max(u.abs());
        } else if relu::default_lower_slope(l, u) == 1.0 {
            z[t] = v;
        }
    }
}

/// CROWN's default slopes (1 if `u > -l` else 0) for every neuron of every ReLU map.
pub fn default_alpha(maps: &[(Affine, bool)], pre: &[Vec<(f64, f64)>]) -> Vec<Vec<f64>> {
    pre.iter()
        .take(maps.len().saturating_sub(1))
        .map(|b| {
            b.iter()
                .map(|&(l, u)| relu::default_lower_slope(l, u))
                .collect()
        })
        .collect()
}

/// The f64 value of the backward bound for slopes `alpha` and its gradient in `alpha`
/// (reverse mode through the pull-back; used only to choose slopes, never as a bound).
fn alpha_value_grad(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    lo: &[f64],
    hi: &[f64],
    alpha: &[Vec<f64>],
    sp: Option<&Sparse>,
) -> (f64, Vec<Vec<f64>>) {
    let g = value_grad(maps, pre, obj, lo, hi, alpha, None, sp);
    (g.value, g.alpha)
}

/// What [`value_grad`] gives: the f64 value of a backward bound, its gradients in the
/// slopes and the split multipliers, and the pull-back's coefficients of every ReLU
/// output (`nu[j]` over the input of map `j`), which the ReLU branching scores.
pub(crate) struct ValueGrad {
    pub(crate) value: f64,
    pub(crate) alpha: Vec<Vec<f64>>,
    pub(crate) beta: Vec<Vec<f64>>,
    pub(crate) nu: Vec<Vec<f64>>,
}

/// `a . b` in f64 with eight partial sums (vectorised; a different rounding from the
/// sequential sum), for the f64 values that only steer an optimisation, never a bound.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            acc[k] += x[k] * y[k];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    acc.iter().sum::<f64>() + tail
}

/// The f64 value of the backward bound with slopes `alpha` and split multipliers `beta`
/// ([`backward_lower_beta`]) and its gradients (reverse mode through the pull-back: the
/// derivative in the coefficient of `z_t` is the value of `z_t` under the relaxation at
/// the minimising corner). Only to choose slopes and multipliers, never as a bound.
#[allow(clippy::too_many_arguments)]
pub(crate) fn value_grad(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    lo: &[f64],
    hi: &[f64],
    alpha: &[Vec<f64>],
    beta: Option<&[Vec<f64>]>,
    sp: Option<&Sparse>,
) -> ValueGrad {
    let nmaps = maps.len();
    let (mu, cst, nus) = pull_f64(maps, pre, obj, alpha, beta, sp, true);
    let mut value = cst;
    let mut g: Vec<f64> = Vec::with_capacity(lo.len());
    for (t, c) in mu.iter().enumerate() {
        let x = if *c >= 0.0 { lo[t] } else { hi[t] };
        value += c * x;
        g.push(x);
    }
    // The vectorised dot product on image-sized inputs only: on few inputs (ACAS Xu)
    // the sequential sum keeps the slopes, and so the search, bit for bit what they were
    // measured with.
    let fast = lo.len() >= 64;
    let mut grad: Vec<Vec<f64>> = alpha.iter().map(|a| vec![0.0; a.len()]).collect();
    let mut gbeta: Vec<Vec<f64>> = alpha.iter().map(|a| vec![0.0; a.len()]).collect();
    // g = dB/d(nu_j) over the inputs of map j; go up the chain.
    for j in 0..nmaps {
        let m = &maps[j].0;
        if j + 1 == nmaps {
            break;
        }
        let mut gm = vec![0.0; m.out];
        let rows = Sparse::map(sp, j);
        for (i, gi) in gm.iter_mut().enumerate() {
            *gi = m.b[i]
                + if let Some(r) = rows {
                    let (c, v) = r.row(i);
                    c.iter()
                        .zip(v)
                        .map(|(&t, w)| w * g[t as usize])
                        .sum::<f64>()
                } else {
                    match m.row(i) {
                        Row::Dense(row) if fast => dot(row, &g),
                        Row::Dense(row) => row.iter().zip(&g).map(|(w, x)| w * x).sum::<f64>(),
                        r => r.nonzeros().map(|(t, w)| w * g[t]).sum::<f64>(),
                    }
                };
        }
        if !maps[j].1 {
            g = gm;
            continue;
        }
        if let Some(gb) = gbeta.get_mut(j) {
            gb.copy_from_slice(&gm);
        }
        let nu = &nus[j + 1];
        for (t, gt) in gm.iter_mut().enumerate() {
            let (l, u) = pre[j][t];
            let v = nu[t];
            if v == 0.0 || u <= 0.0 {
                *gt = 0.0;
            } else if l >= 0.0 {
            } else if v < 0.0 {
                let s = relu::chord_slope(l, u);
                *gt = *gt * s - s * l;
            } else {
                grad[j][t] = *gt * v;
                *gt *= alpha[j][t];
            }
        }
        g = gm;
    }
    ValueGrad {
        value,
        alpha: grad,
        beta: gbeta,
        nu: nus,
    }
}

/// The f64 pull-back of [`value_grad`]: the coefficients over the inputs, the constant,
/// and (when `keep`) the pull-back's coefficients of every ReLU output.
fn pull_f64(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    alpha: &[Vec<f64>],
    beta: Option<&[Vec<f64>]>,
    sp: Option<&Sparse>,
    keep: bool,
) -> (Vec<f64>, f64, Vec<Vec<f64>>) {
    let nmaps = maps.len();
    let mut nus: Vec<Vec<f64>> = vec![Vec::new(); if keep { nmaps } else { 0 }];
    let mut mu = obj.c.clone();
    let mut cst = obj.d;
    for j in (0..nmaps).rev() {
        let m = &maps[j].0;
        let mut nu = vec![0.0; m.inp];
        for (i, &mi) in mu.iter().enumerate() {
            if mi != 0.0 {
                cst += mi * m.b[i];
                axpy_row(m, Sparse::map(sp, j), i, mi, &mut nu);
            }
        }
        if keep {
            nus[j] = nu.clone();
        }
        if j == 0 || !maps[j - 1].1 {
            mu = nu;
            continue;
        }
        for (t, v) in nu.iter_mut().enumerate() {
            let (l, u) = pre[j - 1][t];
            if *v == 0.0 || u <= 0.0 {
                *v = 0.0;
            } else if l >= 0.0 {
            } else if *v < 0.0 {
                let s = relu::chord_slope(l, u);
                cst -= *v * s * l;
                *v *= s;
            } else {
                *v *= alpha[j - 1][t];
            }
        }
        if let Some(b) = beta {
            for (t, &c) in b[j - 1].iter().enumerate() {
                if beta_applies(c, pre[j - 1][t]) {
                    nu[t] += c;
                }
            }
        }
        mu = nu;
    }
    (mu, cst, nus)
}

/// The f64 value of the backward bound with slopes `alpha` and multipliers `beta` (the
/// value of [`value_grad`] without its gradients): to compare branching choices, never
/// as a bound.
#[allow(clippy::too_many_arguments)]
pub(crate) fn value_only(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    lo: &[f64],
    hi: &[f64],
    alpha: &[Vec<f64>],
    beta: Option<&[Vec<f64>]>,
    sp: Option<&Sparse>,
) -> f64 {
    let (mu, cst, _) = pull_f64(maps, pre, obj, alpha, beta, sp, false);
    let mut value = cst;
    for (t, c) in mu.iter().enumerate() {
        value += c * if *c >= 0.0 { lo[t] } else { hi[t] };
    }
    value
}

/// alpha-CROWN (Xu et al., ICLR 2021) for one objective: projected gradient ascent on the
/// lower-relaxation slopes from CROWN's choice, `iters` steps; the returned bound is the
/// rigorous [`backward_lower_alpha`] at the best slopes found, or CROWN's own when that
/// is better.
pub fn alpha_lower(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    lo: &[f64],
    hi: &[f64],
    iters: usize,
) -> Linear {
    alpha_lower_until(maps, pre, obj, lo, hi, iters, None)
}

/// [`alpha_lower`] that stops its gradient steps at `deadline` (any slopes give a sound
/// bound, so stopping early only loosens it): each step is a backward pass through the
/// whole network, which on a wide one takes long enough to overrun a time limit.
pub fn alpha_lower_until(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    lo: &[f64],
    hi: &[f64],
    iters: usize,
    deadline: Option<std::time::Instant>,
) -> Linear {
    let sp = match iters {
        0 => None,
        _ => Sparse::of(maps, lo.len()),
    };
    alpha_lower_sp(
        maps,
        pre,
        obj,
        lo,
        hi,
        iters,
        deadline,
        sp.as_ref(),
        Ascent::Normalised,
    )
}

/// How `alpha_lower_sp` moves the slopes: any slopes in `[0, 1]` give a sound bound,
/// so the choice only decides how tight the bound gets in a given number of backward
/// passes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Ascent {
    /// Steps of size `0.5 / (1 + 0.3 it)` along the gradient scaled by its largest entry:
    /// the slope with the largest gradient moves by the step, the others in proportion.
    Normalised,
    /// Adam (Kingma & Ba, ICLR 2015) with step size `lr` per slope, alpha-CROWN's own
    /// optimiser (Xu et al., ICLR 2021): each slope moves at its own scale, so the
    /// hundreds of slopes with small gradients behind a deep neuron move too. On VNN-COMP
    /// 2022 mnist_fc `256x6` prop_9_0.03, 15 steps per bound left 804 ReLUs unstable
    /// (842 with [`Ascent::Normalised`], 832 with 40 normalised steps) and the last ReLU
    /// layer's mean width at 80 (117).
    Adam(f64),
}

/// [`alpha_lower_until`] over the sparse view `sp` of `maps` (the same bound), the slopes
/// moved by `ascent`.
#[allow(clippy::too_many_arguments)]
fn alpha_lower_sp(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    lo: &[f64],
    hi: &[f64],
    iters: usize,
    deadline: Option<std::time::Instant>,
    sp: Option<&Sparse>,
    ascent: Ascent,
) -> Linear {
    alpha_lower_best(maps, pre, obj, lo, hi, iters, deadline, sp, ascent).0
}

/// [`alpha_lower_sp`] with the slopes of the bound returned, `None` when CROWN's own
/// bound was kept.
#[allow(clippy::too_many_arguments)]
fn alpha_lower_best(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    obj: &Objective,
    lo: &[f64],
    hi: &[f64],
    iters: usize,
    deadline: Option<std::time::Instant>,
    sp: Option<&Sparse>,
    ascent: Ascent,
) -> (Linear, Option<Vec<Vec<f64>>>) {
    let base = backward_lower_sp(maps, pre, obj, lo, hi, None, None, sp);
    let late = || deadline.is_some_and(|d| std::time::Instant::now() >= d);
    if late() {
        return (base, None);
    }
    let mut alpha = default_alpha(maps, pre);
    // Each step's pass gives the value at the slopes before the step, so the first one
    // is CROWN's slopes' value.
    let mut best_v = f64::NEG_INFINITY;
    let mut best_a = alpha.clone();
    let mut adam = crate::adam::Adam::new(&alpha);
    for it in 0..iters {
        if late() {
            break;
        }
        let (v, grad) = alpha_value_grad(maps, pre, obj, lo, hi, &alpha, sp);
        if v > best_v {
            best_v = v;
            best_a = alpha.clone();
        }
        match ascent {
            Ascent::Normalised => {
                let gmax = grad.iter().flatten().fold(0.0f64, |m, g| m.max(g.abs()));
                if gmax == 0.0 {
                    break;
                }
                let eta = 0.5 / (1.0 + it as f64 * 0.3);
                for (a, g) in alpha.iter_mut().zip(&grad) {
                    for (ai, gi) in a.iter_mut().zip(g) {
                        *ai = relu::alpha_range(*ai + eta * gi / gmax);
                    }
                }
            }
            Ascent::Adam(lr) => {
                let lrs = vec![lr; grad.len()];
                adam.step(
                    &mut alpha,
                    &grad,
                    it,
                    &lrs,
                    |_, _| true,
                    |_, _, a| relu::alpha_range(a),
                );
            }
        }
    }
    let (v, _) = alpha_value_grad(maps, pre, obj, lo, hi, &alpha, sp);
    if v > best_v {
        best_a = alpha;
    }
    let opt = backward_lower_sp(maps, pre, obj, lo, hi, Some(&best_a), None, sp);
    if opt.min_over(lo, hi) > base.min_over(lo, hi) {
        (opt, Some(best_a))
    } else {
        (base, None)
    }
}

/// The slopes alpha-CROWN chose for the intermediate bounds ([`alpha_pre_with`]): for
/// map `k`'s neuron `i`, those of its lower bound (`[k][i][0]`) and of its upper bound
/// (`[k][i][1]`), over the ReLU layers before `k`; `None` where CROWN's own bound was kept.
pub type PreSlopes = Vec<Vec<[Option<Vec<Vec<f64>>>; 2]>>;

/// Re-bound the unstable neurons of maps `from..` over tighter bounds `pre` of the
/// layers before them (a node of ReLU splitting, whose fixed phases clamp earlier
/// neurons) with the slopes alpha-CROWN chose at the root ([`PreSlopes`]), one backward
/// pull-back per bound and no optimisation steps: the root's intermediate bounds are
/// tighter than CROWN's, so a node's CROWN re-bound rarely beats them, while the same
/// slopes over the node's tighter bounds do (auto_LiRPA keeps the intermediate slopes of
/// the root for the branches the same way, Xu et al., ICLR 2021). Any slopes in
/// `[0, 1]` give a sound bound over any bounds of the earlier layers, so each bound is
/// rigorous; it only replaces a looser one. Layer by layer, so each layer's pull-backs
/// read the re-bounded layers before it; neurons without slopes, and those stable in
/// `pre`, are left alone; past `deadline` the rest stay.
pub fn rebound_with_slopes(
    maps: &[(Affine, bool)],
    pre: &mut [Vec<(f64, f64)>],
    lo: &[f64],
    hi: &[f64],
    from: usize,
    slopes: &PreSlopes,
    deadline: Option<std::time::Instant>,
) {
    let sp = Sparse::of(maps, lo.len());
    let sp = sp.as_ref();
    for k in from.max(1)..pre.len().min(slopes.len()) {
        if !maps[k].1 {
            continue;
        }
        let out = maps[k].0.out;
        for i in 0..out {
            if deadline.is_some_and(|d| std::time::Instant::now() >= d) {
                return;
            }
            for (side, sign) in [(0usize, 1.0f64), (1, -1.0)] {
                let (l, u) = pre[k][i];
                if !(l < 0.0 && u > 0.0) {
                    break;
                }
                let Some(alpha) = slopes[k].get(i).and_then(|s| s[side].as_ref()) else {
                    continue;
                };
                let mut c = vec![0.0; out];
                c[i] = sign;
                let obj = Objective { c, d: 0.0 };
                let (before, rest) = pre.split_at_mut(k);
                let v = backward_lower_sp(&maps[..=k], before, &obj, lo, hi, Some(alpha), None, sp)
                    .min_over(lo, hi);
                let b = &mut rest[0][i];
                if side == 0 {
                    b.0 = b.0.max(v);
                } else {
                    b.1 = b.1.min(-v);
                }
            }
        }
    }
}

/// Tighten the pre-activation bounds `pre` (sound on the box) of every ReLU map after the
/// first by alpha-CROWN, each unstable neuron's lower and upper bound its own objective
/// with its own slopes ([`alpha_lower_until`] on the chain up to its map, `iters` steps),
/// layer by layer so that each layer's relaxations use the tightened bounds before it
/// (the intermediate-bound optimisation of alpha-CROWN, Xu et al., ICLR 2021). Every
/// bound is rigorous and only replaces a looser one; past `deadline` the rest stay.
/// Neurons of a layer are bounded in parallel. The slopes move by
/// [`Ascent::Normalised`] steps ([`alpha_pre_with`] takes the optimiser).
pub fn alpha_pre_until(
    maps: &[(Affine, bool)],
    pre: &mut [Vec<(f64, f64)>],
    lo: &[f64],
    hi: &[f64],
    iters: usize,
    deadline: Option<std::time::Instant>,
) {
    alpha_pre_with(
        maps,
        pre,
        lo,
        hi,
        iters,
        Ascent::Normalised,
        false,
        deadline,
    );
}

/// [`alpha_pre_until`] with the slopes moved by `ascent`; with `keep_slopes`, returns the
/// slopes of each bound (for [`rebound_with_slopes`]), otherwise `None` everywhere: a
/// bound's slopes span every ReLU before its layer, so keeping them for every neuron
/// of a convolutional network would cost far more memory than the bounds themselves.
#[allow(clippy::too_many_arguments)]
pub fn alpha_pre_with(
    maps: &[(Affine, bool)],
    pre: &mut [Vec<(f64, f64)>],
    lo: &[f64],
    hi: &[f64],
    iters: usize,
    ascent: Ascent,
    keep_slopes: bool,
    deadline: Option<std::time::Instant>,
) -> PreSlopes {
    let all = 1..pre.len();
    alpha_pre_layers(maps, pre, lo, hi, all, iters, ascent, keep_slopes, deadline)
}

/// [`alpha_pre_with`] on the maps `layers` only (those before them are taken as they
/// are): for a caller that refines each layer's bounds in its own way before the next
/// one is bounded ([`crate::refine`]).
#[allow(clippy::too_many_arguments)]
pub fn alpha_pre_layers(
    maps: &[(Affine, bool)],
    pre: &mut [Vec<(f64, f64)>],
    lo: &[f64],
    hi: &[f64],
    layers: std::ops::Range<usize>,
    iters: usize,
    ascent: Ascent,
    keep_slopes: bool,
    deadline: Option<std::time::Instant>,
) -> PreSlopes {
    use rayon::prelude::*;
    let mut slopes: PreSlopes = pre.iter().map(|l| vec![[None, None]; l.len()]).collect();
    let sp = Sparse::of(maps, lo.len());
    let sp = sp.as_ref();
    let profile = std::env::var_os("SAMARA_SEARCH_PROFILE").is_some();
    let t0 = std::time::Instant::now();
    for k in layers.start.max(1)..layers.end.min(pre.len()) {
        if profile {
            let un = pre[k].iter().filter(|b| b.0 < 0.0 && b.1 > 0.0).count();
            eprintln!(
                "alpha pre: layer {k}, {un} unstable, at {:.2} s",
                t0.elapsed().as_secs_f64()
            );
        }
        if deadline.is_some_and(|d| std::time::Instant::now() >= d) {
            return slopes;
        }
        if !maps[k].1 {
            continue;
        }
        let sub = &maps[..=k];
        let before = &pre[..k];
        let out = maps[k].0.out;
        let unstable: Vec<usize> = (0..out)
            .filter(|&i| pre[k][i].0 < 0.0 && pre[k][i].1 > 0.0)
            .collect();
        type Side = (f64, Option<Vec<Vec<f64>>>);
        let new: Vec<(usize, Side, Side)> = unstable
            .par_iter()
            .map(|&i| {
                if deadline.is_some_and(|d| std::time::Instant::now() >= d) {
                    return (i, (f64::NEG_INFINITY, None), (f64::INFINITY, None));
                }
                let mut c = vec![0.0; out];
                c[i] = 1.0;
                let (l, la) = alpha_lower_best(
                    sub,
                    before,
                    &Objective {
                        c: c.clone(),
                        d: 0.0,
                    },
                    lo,
                    hi,
                    iters,
                    deadline,
                    sp,
                    ascent,
                );
                let l = l.min_over(lo, hi);
                c[i] = -1.0;
                let (u, ua) = alpha_lower_best(
                    sub,
                    before,
                    &Objective { c, d: 0.0 },
                    lo,
                    hi,
                    iters,
                    deadline,
                    sp,
                    ascent,
                );
                (i, (l, la), (-u.min_over(lo, hi), ua))
            })
            .collect();
        for (i, (l, la), (u, ua)) in new {
            let b = &mut pre[k][i];
            b.0 = b.0.max(l);
            b.1 = b.1.min(u);
            if keep_slopes {
                slopes[k][i] = [la, ua];
            }
        }
    }
    slopes
}

/// Concrete pre-activation bounds of every map but the last by full CROWN: each
/// neuron's lower and upper bound is its own backward pull-back ([`backward_lower`] with
/// the objectives `z_i` and `-z_i`) through the relaxations of the earlier layers, whose
/// bounds were computed the same way; intersected with the forward bounds `fwd` when
/// given (both are sound, so the intersection is).
pub fn crown_pre(
    maps: &[(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    fwd: Option<&[Vec<(f64, f64)>]>,
) -> Vec<Vec<(f64, f64)>> {
    crown_pre_from(maps, lo, hi, fwd, 0)
}

/// [`crown_pre`] that, past `deadline`, keeps the forward bounds `fwd` (sound, looser)
/// for the neurons not yet tightened: one backward pass per unstable neuron is long on
/// a wide network, and a time limit must hold.
pub fn crown_pre_until(
    maps: &[(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    fwd: &[Vec<(f64, f64)>],
    deadline: Option<std::time::Instant>,
) -> Vec<Vec<(f64, f64)>> {
    crown_pre_core(
        maps,
        lo,
        hi,
        Some(fwd),
        0,
        deadline,
        None,
        Sparse::of(maps, lo.len()).as_ref(),
    )
}

/// The linear bounds behind [`crown_pre_lin_until`]'s concrete ones: for neuron `i` of
/// map `k`, `Some((f, g))` when CROWN bounded it (`f(x) <= z_i(x) <= -g(x)` over the
/// box, so over every box inside it), `None` when its forward bounds were kept.
pub type PreLinear = Vec<LayerLinear>;

/// One layer's entry of [`PreLinear`].
pub type LayerLinear = Vec<Option<(Linear, Linear)>>;

/// [`crown_pre_until`] that also returns the linear functions whose minima are the
/// bounds ([`PreLinear`]): on a sub-box their minima, [`reconcretise`], are sound bounds
/// again, for the cost of a few multiply-adds per neuron instead of a backward pass.
pub fn crown_pre_lin_until(
    maps: &[(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    fwd: &[Vec<(f64, f64)>],
    deadline: Option<std::time::Instant>,
) -> (Vec<Vec<(f64, f64)>>, PreLinear) {
    let mut lins = Vec::new();
    let pre = crown_pre_core(
        maps,
        lo,
        hi,
        Some(fwd),
        0,
        deadline,
        Some(&mut lins),
        Sparse::of(maps, lo.len()).as_ref(),
    );
    (pre, lins)
}

/// Bounds over the sub-box `[lo, hi]` of a box with concrete bounds `pre` and their
/// linear functions `lins` ([`crown_pre_lin_until`]): each neuron's bounds of the box,
/// tightened by the minima of its linear functions over the sub-box. Sound because the
/// functions bound the neuron on the whole box; looser than CROWN on the sub-box itself,
/// whose relaxations of the earlier layers would be tighter too.
pub fn reconcretise(
    pre: &[Vec<(f64, f64)>],
    lins: &PreLinear,
    lo: &[f64],
    hi: &[f64],
) -> Vec<Vec<(f64, f64)>> {
    pre.iter()
        .zip(lins)
        .map(|(layer, ls)| {
            layer
                .iter()
                .zip(ls)
                .map(|(&(l, u), f)| match f {
                    Some((fl, fu)) => (l.max(fl.min_over(lo, hi)), u.min(-fu.min_over(lo, hi))),
                    None => (l, u),
                })
                .collect()
        })
        .collect()
}

/// [`crown_pre`] that takes the bounds of the maps before `from` from `fwd` as they are
/// (they must be given, and sound), and recomputes only the later ones: after a change
/// of the bounds of map `from - 1` (a ReLU's phase fixed), the earlier maps' bounds
/// cannot change.
pub fn crown_pre_from(
    maps: &[(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    fwd: Option<&[Vec<(f64, f64)>]>,
    from: usize,
) -> Vec<Vec<(f64, f64)>> {
    crown_pre_core(
        maps,
        lo,
        hi,
        fwd,
        from,
        None,
        None,
        Sparse::of(maps, lo.len()).as_ref(),
    )
}

/// [`crown_pre_from`] over the sparse view `sp` of `maps` (the same bounds) that keeps
/// the given bounds `fwd` for the neurons not yet re-bounded at `deadline` (they are
/// sound): one re-bound of a wide layer can take seconds, and a time limit must hold.
pub(crate) fn crown_pre_from_sp(
    maps: &[(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    fwd: &[Vec<(f64, f64)>],
    from: usize,
    deadline: Option<std::time::Instant>,
    sp: Option<&Sparse>,
) -> Vec<Vec<(f64, f64)>> {
    crown_pre_core(maps, lo, hi, Some(fwd), from, deadline, None, sp)
}

#[allow(clippy::too_many_arguments)]
fn crown_pre_core(
    maps: &[(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    fwd: Option<&[Vec<(f64, f64)>]>,
    from: usize,
    deadline: Option<std::time::Instant>,
    lins: Option<&mut PreLinear>,
    sp: Option<&Sparse>,
) -> Vec<Vec<(f64, f64)>> {
    crown_pre_core_with(maps, lo, hi, fwd, from, deadline, lins, sp, None, true)
}

/// [`crown_pre_from`] with the row magnitudes of every map given (`rows`, as for
/// [`backward_lower_rows`]: from bounds containing `fwd`'s, or raised by
/// [`rows_with_error`]) instead of computed from the bounds.
pub(crate) fn crown_pre_from_rows(
    maps: &[(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    fwd: &[Vec<(f64, f64)>],
    from: usize,
    rows: &[Vec<f64>],
) -> Vec<Vec<(f64, f64)>> {
    crown_pre_core_with(
        maps,
        lo,
        hi,
        Some(fwd),
        from,
        None,
        None,
        None,
        Some(rows),
        true,
    )
}

/// The row magnitudes of a map `m` applied to the box `[lo, hi]` whose outputs are
/// only known up to an absolute error `err[i]` (a map composed in f64 from several,
/// [`crate::phases`]), for [`backward_lower_rows`] and [`crown_pre_from_rows`]: a
/// pull-back through the map adds `gamma(out + 1) * sum_i |mu_i| * rows[i]` to its slack
/// (see [`backward_core`]), so raising `rows[i]` by `err[i] / gamma(out + 1)` (and a
/// relative `1e-9` for the rounding of this division) adds `sum_i |mu_i| * err[i]`, the
/// most the error can change `mu . z`.
pub(crate) fn rows_with_error(m: &Affine, lo: &[f64], hi: &[f64], err: &[f64]) -> Vec<f64> {
    let g = gamma(m.out + 1);
    row_magnitude(m, None, &magnitudes(lo, hi))
        .iter()
        .zip(err)
        .map(|(r, e)| inflate(r + inflate(e / g)))
        .collect()
}

/// The neurons of one batch of [`crown_layer_batched`]: 16 (32 pull-backs, whose
/// coefficients stay in the first-level cache for a layer of a few hundred neurons),
/// with the clock checked between batches.
const BATCH_NEURONS: usize = 16;

/// One layer's bounds for [`crown_pre_core_with`], every neuron that needs CROWN pulled
/// back in batches of [`BATCH_NEURONS`] ([`batch::pull_units`]): the same bounds and
/// linear functions, bit for bit, as that function's loop of one pull-back per objective.
/// Past the deadline (`late`), checked before each batch, neurons keep `fwd`'s bounds.
#[allow(clippy::too_many_arguments)]
fn crown_layer_batched(
    sub: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    live: &batch::Live,
    lo: &[f64],
    hi: &[f64],
    fwd: Option<&[Vec<(f64, f64)>]>,
    k: usize,
    want_lins: bool,
    rowmag: &[Vec<f64>],
    slopes: &[Vec<f64>],
    late: &dyn Fn() -> bool,
) -> (Vec<(f64, f64)>, LayerLinear) {
    let m = &sub[k].0;
    let lo_hi = |i: usize| {
        fwd.map(|f| f[k][i])
            .unwrap_or((f64::NEG_INFINITY, f64::INFINITY))
    };
    let mut bounds: Vec<(f64, f64)> = (0..m.out).map(lo_hi).collect();
    let mut ls = vec![None; if want_lins { m.out } else { 0 }];
    // Layer 0 is exact under interval arithmetic already (its linear functions, when
    // asked for, are its rows); skip stable neurons.
    let todo: Vec<usize> = (0..m.out)
        .filter(|&i| {
            let (fl, fu) = bounds[i];
            !((k == 0 && !want_lins) || fl >= 0.0 || fu <= 0.0)
        })
        .collect();
    for chunk in todo.chunks(BATCH_NEURONS) {
        if late() {
            break;
        }
        let objs: Vec<(usize, f64)> = chunk.iter().flat_map(|&i| [(i, 1.0), (i, -1.0)]).collect();
        let mut fs = batch::pull_units(sub, pre, live, &objs, rowmag, slopes).into_iter();
        for &i in chunk {
            let (lf, uf) = (fs.next().expect("z_i"), fs.next().expect("-z_i"));
            let (fl, fu) = bounds[i];
            let l = lf.min_over(lo, hi);
            let u = -uf.min_over(lo, hi);
            bounds[i] = (l.max(fl), u.min(fu));
            if want_lins {
                ls[i] = Some((lf, uf));
            }
        }
    }
    (bounds, ls)
}

/// CROWN's intermediate bounds of `maps` over `[lo, hi]` from layer `from` on (the
/// common core of [`crown_pre_from`] and [`crown_pre_from_rows`]): `rows` the maps' row
/// magnitudes when given (else computed from the bounds), and the batched pull-backs
/// ([`crown_layer_batched`]) allowed or not (`batch_ok`; the row-by-row loop is the
/// reference the batches are tested against).
#[allow(clippy::too_many_arguments)]
fn crown_pre_core_with(
    maps: &[(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    fwd: Option<&[Vec<(f64, f64)>]>,
    from: usize,
    deadline: Option<std::time::Instant>,
    mut lins: Option<&mut PreLinear>,
    sp: Option<&Sparse>,
    rows: Option<&[Vec<f64>]>,
    batch_ok: bool,
) -> Vec<Vec<(f64, f64)>> {
    // Past the deadline, neurons keep their forward bounds (only when those are given).
    let late = || fwd.is_some() && deadline.is_some_and(|d| std::time::Instant::now() >= d);
    let body = maps.len() - 1;
    let mut pre: Vec<Vec<(f64, f64)>> = Vec::with_capacity(body);
    let mut c = Vec::new();
    // The chord slopes of every bounded layer's unstable neurons, computed once per layer
    // instead of once per pull-back (the same function of the same bounds, so the same
    // bits; 0 where a neuron is stable, which no pull-back reads).
    let mut slopes: Vec<Vec<f64>> = Vec::with_capacity(body);
    let chords = |b: &[(f64, f64)]| -> Vec<f64> {
        b.iter()
            .map(|&(l, u)| match l < 0.0 && u > 0.0 {
                true => relu::chord_slope_up(l, u),
                false => 0.0,
            })
            .collect()
    };
    // The row magnitudes of every map's input bound up to k (only the last one is new),
    // or all of them given.
    let mut rowmag: Vec<Vec<f64>> = match rows {
        Some(r) => r.to_vec(),
        None => Vec::with_capacity(body),
    };
    // The dense maps' pull-backs go in batches ([`batch`]); sparse ones row by row.
    let batched = batch_ok && sp.is_none() && batch::finite(&maps[..body]);
    let mut live = batch::Live::default();
    let mut scratch = sparse_pull::Scratch::default();
    for k in 0..body {
        if k < from {
            if let Some(f) = fwd {
                slopes.push(chords(&f[k]));
                pre.push(f[k].clone());
                if let Some(v) = lins.as_deref_mut() {
                    v.push(vec![None; f[k].len()]);
                }
                continue;
            }
        }
        let m = &maps[k].0;
        let sub = &maps[..=k];
        if rowmag.len() <= k {
            let inmax = input_magnitudes(sub, &pre, lo, hi, k + 1);
            for (j, im) in inmax.iter().enumerate().skip(rowmag.len()) {
                rowmag.push(row_magnitude(&maps[j].0, Sparse::map(sp, j), im));
            }
        }
        let want = lins.is_some();
        let (mut bounds, mut ls) = match batched {
            true => {
                live.extend(maps, &pre);
                let (p, l) = (&pre, &live);
                crown_layer_batched(sub, p, l, lo, hi, fwd, k, want, &rowmag, &slopes, &late)
            }
            false => (Vec::with_capacity(m.out), Vec::new()),
        };
        // One pull-back per objective (sparse maps, and the batches' reference).
        for i in (0..m.out).filter(|_| !batched) {
            let (fl, fu) = fwd
                .map(|f| f[k][i])
                .unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
            // Layer 0 is exact under interval arithmetic already (its linear functions,
            // when asked for, are its rows); skip stable neurons.
            if (k == 0 && lins.is_none()) || fl >= 0.0 || fu <= 0.0 || late() {
                bounds.push((fl, fu));
                if lins.is_some() {
                    ls.push(None);
                }
                continue;
            }
            let (lf, uf) = if sp.is_none() {
                // The same pull-backs over the coefficients' non-zeros only (sparse maps
                // of few inputs: a neuron reaches few neurons of each earlier layer).
                let (r, sl, sc) = (&rowmag[..], &slopes[..], &mut scratch);
                let lf = sparse_pull::pull_unit(sub, &pre, i, 1.0, r, sl, sc);
                (lf, sparse_pull::pull_unit(sub, &pre, i, -1.0, r, sl, sc))
            } else {
                c.clear();
                c.resize(m.out, 0.0);
                c[i] = 1.0;
                let rm = Mags::Rows(&rowmag);
                let lf = backward_core(sub, &pre, &c, 0.0, None, None, rm, sp, Some(&slopes));
                c[i] = -1.0;
                let uf = backward_core(sub, &pre, &c, 0.0, None, None, rm, sp, Some(&slopes));
                (lf, uf)
            };
            let l = lf.min_over(lo, hi);
            let u = -uf.min_over(lo, hi);
            bounds.push((l.max(fl), u.min(fu)));
            if lins.is_some() {
                ls.push(Some((lf, uf)));
            }
        }
        if let Some(v) = lins.as_deref_mut() {
            v.push(ls);
        }
        slopes.push(chords(&bounds));
        pre.push(bounds);
    }
    pre
}

/// A sound linear lower bound of `c . f(x) + d` over the box, composing the objective
/// with the last map exactly up to a tracked rounding error, so that outputs that share
/// hidden neurons keep their correlation (`y_0 - y_1` is bounded as one function).
pub fn objective_lower(
    a: &LayerBounds,
    last: &Affine,
    obj: &Objective,
    lo: &[f64],
    hi: &[f64],
) -> Linear {
    let xmax = magnitudes(lo, hi);
    // v = c^T W, b' = c . b + d, with per-entry error bounds.
    let m = last.inp;
    let mut v = vec![0.0; m];
    let mut verr = vec![0.0; m];
    let k = last.out + 1;
    for i in 0..m {
        let mut s = 0.0;
        let mut mag = 0.0;
        for o in 0..last.out {
            let p = obj.c[o] * last.weight(o, i);
            s += p;
            mag += p.abs();
        }
        v[i] = s;
        verr[i] = gamma(k) * mag;
    }
    let mut bp = obj.d;
    let mut bmag = obj.d.abs();
    for o in 0..last.out {
        let p = obj.c[o] * last.b[o];
        bp += p;
        bmag += p.abs();
    }
    let berr = gamma(k) * bmag;
    // |a_i| bounds for the composition error.
    let amax: Vec<f64> = a
        .lower
        .iter()
        .zip(&a.upper)
        .map(|(l, u)| l.min_over(lo, hi).abs().max(u.max_over(lo, hi).abs()))
        .collect();
    affine_row(&v, bp, a, false, Some((&verr, berr, &amax)), &xmax)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random chain of `sizes` whose first two maps keep about one weight in six
    /// (a lowered convolution's pattern: most of a row is 0), the last dense.
    fn sparse_chain(sizes: &[usize], seed: u64) -> Vec<(Affine, bool)> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let n = sizes.len() - 1;
        (0..n)
            .map(|j| {
                let (inp, out) = (sizes[j], sizes[j + 1]);
                let keep = if j + 1 < n { 1.0 / 6.0 } else { 1.0 };
                let w = (0..inp * out)
                    .map(|_| match rng.gen_bool(keep) {
                        true => rng.gen_range(-1.0..1.0),
                        false => 0.0,
                    })
                    .collect();
                let b = (0..out).map(|_| rng.gen_range(-0.3..0.3)).collect();
                (Affine::new(inp, out, w, b), j + 1 < n)
            })
            .collect()
    }

    #[test]
    fn batched_crown_pull_backs_give_the_row_loops_bits() {
        // `crown_layer_batched` pulls a layer's objectives back together as matrix
        // products; the row-by-row loop (`batch_ok = false`) is the reference. Bounds and
        // linear functions must be bit for bit the same: chains with widths that are not
        // multiples of the kernel's block (1 to 13 neurons), weights with exact zeros (a
        // zero row, a zero column, a third of the entries), a map without a ReLU in the
        // middle, three weight scales, narrow and wide boxes, from every layer `from`,
        // with and without the linear functions, with the row magnitudes given.
        use rand::{Rng, SeedableRng};
        let mut compared = 0;
        for seed in 0..60u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1000 + seed);
            let depth = rng.gen_range(2..6);
            let mut sizes = vec![rng.gen_range(1..7)];
            sizes.extend((0..depth).map(|_| rng.gen_range(1..14)));
            sizes.push(rng.gen_range(1..4));
            let scale = [0.3, 1.0, 3.0][seed as usize % 3];
            let n = sizes.len() - 1;
            let linear_mid = seed % 5 == 0 && n >= 3;
            let maps: Vec<(Affine, bool)> = (0..n)
                .map(|j| {
                    let (inp, out) = (sizes[j], sizes[j + 1]);
                    let zero_row = rng.gen_range(0..out + 2);
                    let zero_col = rng.gen_range(0..inp + 2);
                    let w = (0..inp * out)
                        .map(|e| {
                            let (i, t) = (e / inp, e % inp);
                            if i == zero_row || t == zero_col || rng.gen_bool(0.3) {
                                0.0
                            } else {
                                scale * rng.gen_range(-1.0..1.0)
                            }
                        })
                        .collect();
                    let b = (0..out).map(|_| rng.gen_range(-0.3..0.3)).collect();
                    let relu = j + 1 < n && !(linear_mid && j == 1);
                    (Affine::new(inp, out, w, b), relu)
                })
                .collect();
            let width = [0.05, 0.5, 2.0][(seed / 3) as usize % 3];
            let lo: Vec<f64> = (0..sizes[0]).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|v| v + width).collect();
            let fwd = hidden_pre(&maps, &lo, &hi, None);
            let bits = |a: &[Vec<(f64, f64)>], b: &[Vec<(f64, f64)>], what: &str| {
                assert_eq!(a.len(), b.len());
                for (k, (x, y)) in a.iter().zip(b).enumerate() {
                    for (i, (p, q)) in x.iter().zip(y).enumerate() {
                        let same = p.0.to_bits() == q.0.to_bits() && p.1.to_bits() == q.1.to_bits();
                        assert!(same, "seed {seed} {what} layer {k} neuron {i}: {p:?} {q:?}");
                    }
                }
            };
            let lin_bits = |a: &Linear, b: &Linear| {
                a.coef.len() == b.coef.len()
                    && a.coef
                        .iter()
                        .zip(&b.coef)
                        .all(|(x, y)| x.to_bits() == y.to_bits())
                    && a.cst.to_bits() == b.cst.to_bits()
                    && a.slack.to_bits() == b.slack.to_bits()
            };
            for from in 0..n {
                let with_lins = from % 2 == 0;
                let run = |batch_ok: bool, given: Option<&[Vec<f64>]>| {
                    let mut lins = Vec::new();
                    let lv = with_lins.then_some(&mut lins);
                    let f = Some(&fwd[..]);
                    let pre = crown_pre_core_with(
                        &maps, &lo, &hi, f, from, None, lv, None, given, batch_ok,
                    );
                    (pre, lins)
                };
                let (a, la) = run(true, None);
                let (b, lb) = run(false, None);
                bits(&a, &b, "bounds");
                assert_eq!(la.len(), lb.len());
                for (x, y) in la.iter().flatten().zip(lb.iter().flatten()) {
                    match (x, y) {
                        (Some((p, q)), Some((r, t))) => {
                            assert!(lin_bits(p, r) && lin_bits(q, t), "seed {seed} linear");
                            compared += 1;
                        }
                        (None, None) => {}
                        _ => panic!("seed {seed}: a neuron bounded by one loop only"),
                    }
                }
                // The row magnitudes given (the phase nodes' composed chains).
                let rm = row_magnitudes(&maps, &fwd, &lo, &hi);
                let (a, _) = run(true, Some(&rm));
                let (b, _) = run(false, Some(&rm));
                bits(&a, &b, "given rows");
            }
        }
        assert!(compared > 300, "only {compared} linear functions compared");
    }

    #[test]
    fn crown_bounds_with_slopes_once_per_layer_equal_slopes_per_pull_back() {
        // `crown_pre_core_with` computes each layer's chord slopes once and passes them
        // to every pull-back; the reference below is the per-neuron loop it replaced,
        // each pull-back computing its slopes itself. Bounds and linear functions must
        // be bit for bit the same, on dense chains at three weight scales, wide and
        // narrow boxes.
        use rand::{Rng, SeedableRng};
        let mut compared = 0;
        for seed in 0..12u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let sizes = [5, 12, 12, 12, 3];
            let scale = [0.3, 1.0, 3.0][seed as usize % 3];
            let maps: Vec<(Affine, bool)> = (0..sizes.len() - 1)
                .map(|j| {
                    let (inp, out) = (sizes[j], sizes[j + 1]);
                    let w = (0..inp * out)
                        .map(|_| scale * rng.gen_range(-1.0..1.0))
                        .collect();
                    let b = (0..out).map(|_| rng.gen_range(-0.3..0.3)).collect();
                    (Affine::new(inp, out, w, b), j + 2 < sizes.len())
                })
                .collect();
            let width = [0.05, 0.5, 2.0][(seed / 3) as usize % 3];
            let lo: Vec<f64> = (0..5).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|v| v + width).collect();
            let fwd = hidden_pre(&maps, &lo, &hi, None);
            let (got, lins) = crown_pre_lin_until(&maps, &lo, &hi, &fwd, None);
            // The reference: the same loop, slopes computed in every pull-back.
            let mut pre: Vec<Vec<(f64, f64)>> = Vec::new();
            let mut rowmag: Vec<Vec<f64>> = Vec::new();
            for k in 0..maps.len() - 1 {
                let sub = &maps[..=k];
                let inmax = input_magnitudes(sub, &pre, &lo, &hi, k + 1);
                for (j, im) in inmax.iter().enumerate().skip(rowmag.len()) {
                    rowmag.push(row_magnitude(&maps[j].0, None, im));
                }
                let mut layer = Vec::new();
                for i in 0..maps[k].0.out {
                    let (fl, fu) = fwd[k][i];
                    if fl >= 0.0 || fu <= 0.0 {
                        layer.push((fl, fu));
                        assert!(lins[k][i].is_none());
                        continue;
                    }
                    let mut c = vec![0.0; maps[k].0.out];
                    c[i] = 1.0;
                    let rm = Mags::Rows(&rowmag);
                    let lf = backward_core(sub, &pre, &c, 0.0, None, None, rm, None, None);
                    c[i] = -1.0;
                    let uf = backward_core(sub, &pre, &c, 0.0, None, None, rm, None, None);
                    let (l, u) = (lf.min_over(&lo, &hi), -uf.min_over(&lo, &hi));
                    let (gl, gu) = lins[k][i].as_ref().expect("an unstable neuron is bounded");
                    assert_eq!((gl, gu), (&lf, &uf), "seed {seed} layer {k} neuron {i}");
                    compared += 1;
                    layer.push((l.max(fl), u.min(fu)));
                }
                for (a, b) in got[k].iter().zip(&layer) {
                    assert_eq!(a.0.to_bits(), b.0.to_bits(), "seed {seed} layer {k}");
                    assert_eq!(a.1.to_bits(), b.1.to_bits(), "seed {seed} layer {k}");
                }
                pre.push(layer);
            }
        }
        assert!(compared > 100, "only {compared} unstable neurons compared");
    }

    #[test]
    fn sparse_passes_give_the_dense_passes_bits() {
        // The sparse rows skip only additions of exact zeros, in the same order: every
        // bound, value and gradient must be bit for bit the dense loops' (the dense
        // loops are the reference; they were measured sound in tests/soundness.rs).
        let maps = sparse_chain(&[96, 60, 40, 3], 7);
        let sp = Sparse::of(&maps, 96).expect("the first maps are sparse");
        assert!(sp.rows[0].is_some() && sp.rows[1].is_some() && sp.rows[2].is_none());
        assert!(
            Sparse::of(&maps, 63).is_none(),
            "no sparse view below 64 inputs"
        );
        // The test without the build says the same.
        assert!(Sparse::applies(&maps, 96) && !Sparse::applies(&maps, 63));
        let dense: Vec<(Affine, bool)> = maps.iter().map(|(m, r)| (m.densified(), *r)).collect();
        assert_eq!(
            Sparse::applies(&dense, 96),
            Sparse::of(&dense, 96).is_some()
        );
        let lo: Vec<f64> = (0..96).map(|t| (t as f64 * 0.37).sin() - 0.1).collect();
        let hi: Vec<f64> = lo.iter().map(|v| v + 0.2).collect();
        let fwd = hidden_pre(&maps, &lo, &hi, None);
        // The forward pass over the rows' supports equals the plain one's bounds.
        assert_eq!(fwd, hidden(&maps, &lo, &hi, None).2);
        let dense = crown_pre_core(&maps, &lo, &hi, Some(&fwd), 0, None, None, None);
        let sparse = crown_pre_core(&maps, &lo, &hi, Some(&fwd), 0, None, None, Some(&sp));
        assert_eq!(dense, sparse);
        let unstable = dense
            .iter()
            .flatten()
            .filter(|b| b.0 < 0.0 && b.1 > 0.0)
            .count();
        assert!(
            unstable > 10,
            "only {unstable} unstable neurons: a weak test"
        );
        let from1 = crown_pre_from_sp(&maps, &lo, &hi, &dense, 1, None, Some(&sp));
        assert_eq!(from1, crown_pre_from(&maps, &lo, &hi, Some(&dense), 1));
        let obj = Objective {
            c: vec![1.0, -1.0, 0.5],
            d: 0.25,
        };
        let alpha: Vec<Vec<f64>> = dense
            .iter()
            .map(|l| (0..l.len()).map(|t| (t % 5) as f64 / 4.0).collect())
            .collect();
        let beta: Vec<Vec<f64>> = dense
            .iter()
            .map(|l| {
                l.iter()
                    .map(|b| if b.1 <= 0.0 { 0.3 } else { 0.0 })
                    .collect()
            })
            .collect();
        let a = backward_lower_sp(
            &maps,
            &dense,
            &obj,
            &lo,
            &hi,
            Some(&alpha),
            Some(&beta),
            None,
        );
        let b = backward_lower_sp(
            &maps,
            &dense,
            &obj,
            &lo,
            &hi,
            Some(&alpha),
            Some(&beta),
            Some(&sp),
        );
        assert_eq!(a, b);
        let g0 = value_grad(&maps, &dense, &obj, &lo, &hi, &alpha, Some(&beta), None);
        let g1 = value_grad(
            &maps,
            &dense,
            &obj,
            &lo,
            &hi,
            &alpha,
            Some(&beta),
            Some(&sp),
        );
        // The forward sums of the gradient differ in order (the dense one is vectorised
        // on 64+ inputs), so equal up to rounding there; the pull-back is exact.
        assert_eq!(g0.nu, g1.nu);
        assert!((g0.value - g1.value).abs() <= 1e-12 * (1.0 + g0.value.abs()));
        for (x, y) in g0.alpha.iter().flatten().zip(g1.alpha.iter().flatten()) {
            assert!((x - y).abs() <= 1e-9 * (1.0 + x.abs()), "{x} {y}");
        }
        let l0 = alpha_lower_sp(
            &maps,
            &dense,
            &obj,
            &lo,
            &hi,
            5,
            None,
            None,
            Ascent::Normalised,
        );
        let l1 = alpha_lower_until(&maps, &dense, &obj, &lo, &hi, 5, None);
        assert!((l0.min_over(&lo, &hi) - l1.min_over(&lo, &hi)).abs() < 1e-9);
    }

    #[test]
    fn chord_and_identity_cases_are_sound_on_a_grid() {
        // z = x0 - x1 over [-1, 2] x [0, 1]; relu bounds must contain relu(z).
        let z = LayerBounds {
            lower: vec![Linear {
                coef: vec![1.0, -1.0],
                cst: 0.0,
                slack: 0.0,
            }],
            upper: vec![Linear {
                coef: vec![1.0, -1.0],
                cst: 0.0,
                slack: 0.0,
            }],
        };
        let (lo, hi) = ([-1.0, 0.0], [2.0, 1.0]);
        let r = relu(&z, &lo, &hi, None);
        for i in 0..=30 {
            for j in 0..=30 {
                let x = [-1.0 + 3.0 * i as f64 / 30.0, j as f64 / 30.0];
                let a = (x[0] - x[1]).max(0.0);
                let l = r.lower[0].coef[0] * x[0] + r.lower[0].coef[1] * x[1] + r.lower[0].cst
                    - r.lower[0].slack;
                let u = r.upper[0].coef[0] * x[0]
                    + r.upper[0].coef[1] * x[1]
                    + r.upper[0].cst
                    + r.upper[0].slack;
                assert!(l <= a + 1e-15 && a <= u + 1e-15, "{x:?}: {l} {a} {u}");
            }
        }
    }
}
