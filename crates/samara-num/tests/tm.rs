//! Soundness and usefulness of the Taylor-model number type [`Tm`].
//!
//! Arithmetic is checked against exact rational arithmetic (`num-rational`): random
//! expression trees over random polynomial leaves are evaluated once as Taylor models
//! and once exactly at random parameter points, and the exact value must lie in both
//! `eval_at` and `bound`. Elementary functions are checked against `f64` libm values of
//! `f(g(xi))` (with `g(xi)` exact), with a slack of a few ulps: the reference interval
//! contains the true value, so it must meet the model's enclosure.

use num_bigint::BigInt;
use num_rational::BigRational;
use num_traits::{ToPrimitive, Zero};
use samara_num::{Interval, Scalar, Series, Sign, Tm};
use std::time::Instant;

use crate::support::Rng;

/// Coefficients and parameter points on top of the shared generator.
impl Rng {
    fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    /// A coefficient: zero, a small integer, or a full-mantissa number of magnitude
    /// 2^-40 .. 2^12.
    fn coef(&mut self) -> f64 {
        match self.below(10) {
            0 => 0.0,
            1 => self.below(7) as f64 - 3.0,
            _ => {
                let m = self.range(-1.0, 1.0);
                let e = self.below(53) as i32 - 40;
                m * 2f64.powi(e)
            }
        }
    }
    /// A parameter point in [-1, 1] (sometimes an end point).
    fn param(&mut self) -> f64 {
        match self.below(8) {
            0 => 1.0,
            1 => -1.0,
            2 => 0.0,
            _ => self.range(-1.0, 1.0),
        }
    }
    /// A point of `n` parameters ([`Rng::param`] each), as floats and as exact rationals.
    fn point(&mut self, n: usize) -> (Vec<f64>, Vec<BigRational>) {
        let xi: Vec<f64> = (0..n).map(|_| self.param()).collect();
        let xq = xi.iter().map(|&x| q(x)).collect();
        (xi, xq)
    }
}

fn q(x: f64) -> BigRational {
    BigRational::from_float(x).expect("finite")
}

/// Whether the exact `v` lies in `i` (infinite ends are open-ended).
fn contains_exact(i: &Interval, v: &BigRational) -> bool {
    let lo_ok = i.lo == f64::NEG_INFINITY || (i.lo.is_finite() && q(i.lo) <= *v);
    let hi_ok = i.hi == f64::INFINITY || (i.hi.is_finite() && *v <= q(i.hi));
    lo_ok && hi_ok
}

/// Expression trees evaluated both as Taylor models and exactly.
#[derive(Clone, Debug)]
enum Expr {
    /// `c + sum coef[k] xi_k` with the given order.
    Affine(f64, Vec<f64>, u32),
    /// `Scalar::cst`.
    Cst(f64),
    /// `Tm::from_interval(i)`; the function is the constant `delta in i`.
    FromInterval(Interval, f64),
    /// `Tm::var(k, n, order)`.
    Var(usize, usize, u32),
    /// `e.with_lifted_weight(w)`: the same function on a mixed-degree table.
    Lifted(Box<Expr>, u32),
    /// `e.param(k, n)`: the function `xi_k` on `e`'s kind of table.
    Param(Box<Expr>, usize, usize),
    /// `e.with_rem(r)`; the function is `e + delta`, `delta in r`.
    WithRem(Box<Expr>, Interval, f64),
    Add(Box<Expr>, Box<Expr>),
    Sub(Box<Expr>, Box<Expr>),
    Mul(Box<Expr>, Box<Expr>),
    /// Divisor is bounded away from 0 (checked when generated).
    Div(Box<Expr>, Box<Expr>),
    Sqr(Box<Expr>),
    Powi(Box<Expr>, u32),
    Neg(Box<Expr>),
    AddF(Box<Expr>, f64),
    SubF(Box<Expr>, f64),
    MulF(Box<Expr>, f64),
    DivF(Box<Expr>, f64),
}

impl Expr {
    fn tm(&self) -> Tm {
        match self {
            Expr::Affine(c, coef, o) => Tm::affine(*c, coef, *o),
            Expr::Cst(c) => Tm::cst(*c),
            Expr::FromInterval(i, _) => Tm::from_interval(*i),
            Expr::Var(k, n, o) => Tm::var(*k, *n, *o),
            Expr::Lifted(e, w) => e.tm().with_lifted_weight(*w),
            Expr::Param(e, k, n) => e.tm().param(*k, *n),
            Expr::WithRem(e, r, _) => e.tm().with_rem(*r),
            Expr::Add(a, b) => a.tm() + b.tm(),
            Expr::Sub(a, b) => a.tm() - b.tm(),
            Expr::Mul(a, b) => a.tm() * b.tm(),
            Expr::Div(a, b) => a.tm() / b.tm(),
            Expr::Sqr(a) => a.tm().sqr(),
            Expr::Powi(a, k) => a.tm().powi(*k),
            Expr::Neg(a) => -a.tm(),
            Expr::AddF(a, f) => a.tm() + *f,
            Expr::SubF(a, f) => a.tm() - *f,
            Expr::MulF(a, f) => a.tm() * *f,
            Expr::DivF(a, f) => a.tm() / *f,
        }
    }

    fn exact(&self, xi: &[BigRational]) -> BigRational {
        match self {
            Expr::Affine(c, coef, _) => {
                let mut s = q(*c);
                for (k, &a) in coef.iter().enumerate() {
                    s += q(a) * &xi[k];
                }
                s
            }
            Expr::Cst(c) => q(*c),
            Expr::FromInterval(_, d) => q(*d),
            Expr::Var(k, _, _) => xi[*k].clone(),
            Expr::Lifted(e, _) => e.exact(xi),
            Expr::Param(_, k, _) => xi[*k].clone(),
            Expr::WithRem(e, _, d) => e.exact(xi) + q(*d),
            Expr::Add(a, b) => a.exact(xi) + b.exact(xi),
            Expr::Sub(a, b) => a.exact(xi) - b.exact(xi),
            Expr::Mul(a, b) => a.exact(xi) * b.exact(xi),
            Expr::Div(a, b) => {
                let d = b.exact(xi);
                assert!(
                    !d.is_zero(),
                    "divisor enclosure excluded 0 but the exact value is 0"
                );
                a.exact(xi) / d
            }
            Expr::Sqr(a) => {
                let v = a.exact(xi);
                &v * &v
            }
            Expr::Powi(a, k) => {
                let v = a.exact(xi);
                let mut r = BigRational::from_integer(BigInt::from(1));
                for _ in 0..*k {
                    r *= &v;
                }
                r
            }
            Expr::Neg(a) => -a.exact(xi),
            Expr::AddF(a, f) => a.exact(xi) + q(*f),
            Expr::SubF(a, f) => a.exact(xi) - q(*f),
            Expr::MulF(a, f) => a.exact(xi) * q(*f),
            Expr::DivF(a, f) => a.exact(xi) / q(*f),
        }
    }
}

/// A point of a finite interval, chosen at random (an end sometimes).
fn point_in(rng: &mut Rng, i: &Interval) -> f64 {
    match rng.below(4) {
        0 => i.lo,
        1 => i.hi,
        _ => (i.lo + (i.hi - i.lo) * rng.unit()).clamp(i.lo, i.hi),
    }
}

fn rand_leaf(rng: &mut Rng, n: usize, order: u32) -> Expr {
    match rng.below(10) {
        0 => Expr::Cst(rng.coef()),
        1 => {
            let c = rng.coef();
            let w = rng.coef().abs() * 1e-3;
            let i = Interval::new(c - w, c + w);
            let d = point_in(rng, &i);
            Expr::FromInterval(i, d)
        }
        2 => Expr::Var(rng.below(n as u64) as usize, n, order),
        _ => {
            // Fewer parameters sometimes (mixed n), another order sometimes.
            let nl = if rng.below(4) == 0 {
                1 + rng.below(n as u64) as usize
            } else {
                n
            };
            let ol = if rng.below(6) == 0 {
                1 + rng.below(6) as u32
            } else {
                order
            };
            let coef = (0..nl).map(|_| rng.coef()).collect();
            let e = Expr::Affine(rng.coef(), coef, ol);
            if rng.below(4) == 0 {
                let a = rng.coef().abs() * 1e-6;
                let r = Interval::new(-a * rng.unit(), a * rng.unit());
                let d = point_in(rng, &r);
                Expr::WithRem(Box::new(e), r, d)
            } else {
                e
            }
        }
    }
}

fn rand_expr(rng: &mut Rng, n: usize, order: u32, depth: u32) -> Expr {
    if depth == 0 || rng.below(5) == 0 {
        return rand_leaf(rng, n, order);
    }
    let sub = |rng: &mut Rng| Box::new(rand_expr(rng, n, order, depth - 1));
    match rng.below(13) {
        0 | 1 => Expr::Add(sub(rng), sub(rng)),
        2 | 3 => Expr::Sub(sub(rng), sub(rng)),
        4..=6 => Expr::Mul(sub(rng), sub(rng)),
        7 => {
            let num = sub(rng);
            // A divisor whose enclosure excludes 0; else an affine one dominated by its
            // constant.
            let den = sub(rng);
            let b = den.tm().bound();
            let ok = b.lo.is_finite() && b.hi.is_finite() && (b.lo > 1e-3 || b.hi < -1e-3);
            let den = if ok {
                den
            } else {
                let coef: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
                let s: f64 = coef.iter().map(|c| c.abs()).sum();
                let c0 = (s + rng.range(0.1, 3.0)) * if rng.below(2) == 0 { 1.0 } else { -1.0 };
                Box::new(Expr::Affine(c0, coef, order))
            };
            Expr::Div(num, den)
        }
        8 => Expr::Sqr(sub(rng)),
        9 => Expr::Powi(sub(rng), rng.below(5) as u32),
        10 => Expr::Neg(sub(rng)),
        11 => match rng.below(4) {
            0 => Expr::AddF(sub(rng), rng.coef()),
            1 => Expr::SubF(sub(rng), rng.coef()),
            2 => Expr::MulF(sub(rng), rng.coef()),
            _ => {
                let f = rng.coef();
                let f = if f == 0.0 { 3.0 } else { f };
                Expr::DivF(sub(rng), f)
            }
        },
        _ => rand_leaf(rng, n, order),
    }
}

/// The exact value of `e` at 6 random points lies in both `t.eval_at` and `t.bound()`
/// (never NaN); returns whether the bound is finite.
fn encloses_at_points(e: &Expr, t: &Tm, rng: &mut Rng, n: usize, case: usize) -> bool {
    let b = t.bound();
    assert!(!b.lo.is_nan() && !b.hi.is_nan(), "NaN bound: {e:?}");
    for _ in 0..6 {
        let (xi, xq) = rng.point(n);
        let v = e.exact(&xq);
        let at = t.eval_at(&xi);
        assert!(
            contains_exact(&at, &v),
            "case {case}: exact {} not in eval_at {at:?}\n{e:?}\n{t:?}",
            v.to_f64().unwrap_or(f64::NAN)
        );
        assert!(
            contains_exact(&b, &v),
            "case {case}: exact {} not in bound {b:?}\n{e:?}\n{t:?}",
            v.to_f64().unwrap_or(f64::NAN)
        );
    }
    b.lo.is_finite() && b.hi.is_finite()
}

#[test]
fn arithmetic_encloses_exact_rational_values() {
    let mut rng = Rng(0x5EED_0001);
    let (mut checked, mut finite_results) = (0usize, 0usize);
    let start = Instant::now();
    for case in 0..3000 {
        let n = 1 + rng.below(4) as usize;
        let order = 1 + rng.below(6) as u32;
        let depth = 1 + rng.below(4) as u32;
        let e = rand_expr(&mut rng, n, order, depth);
        let t = e.tm();
        assert!(t.n_vars() <= n);
        finite_results += usize::from(encloses_at_points(&e, &t, &mut rng, n, case));
        checked += 6;
    }
    // The models must be informative, not the whole line.
    assert!(
        finite_results > 2700,
        "only {finite_results} finite results"
    );
    eprintln!(
        "arithmetic: {checked} point checks, {finite_results}/3000 finite, {:?}",
        start.elapsed()
    );
}

/// The tree with some leaves on mixed-degree tables: an affine leaf in fewer
/// parameters made mixed (the parameters it lacks weigh `2..=order` when it meets the
/// others), or a parameter of such a leaf's kind.
fn mixed(e: Expr, rng: &mut Rng, n: usize) -> Expr {
    let b = |e: Box<Expr>, rng: &mut Rng| Box::new(mixed(*e, rng, n));
    match e {
        Expr::Affine(c, coef, o) if o >= 2 && rng.below(2) == 0 => {
            let nl = 1 + rng.below(coef.len() as u64) as usize;
            let w = 2 + rng.below(o as u64 - 1) as u32;
            let leaf = Expr::Lifted(Box::new(Expr::Affine(c, coef[..nl].to_vec(), o)), w);
            if rng.below(4) == 0 {
                Expr::Param(Box::new(leaf), rng.below(n as u64) as usize, n)
            } else {
                leaf
            }
        }
        Expr::WithRem(e, r, d) => Expr::WithRem(b(e, rng), r, d),
        Expr::Add(x, y) => Expr::Add(b(x, rng), b(y, rng)),
        Expr::Sub(x, y) => Expr::Sub(b(x, rng), b(y, rng)),
        Expr::Mul(x, y) => Expr::Mul(b(x, rng), b(y, rng)),
        Expr::Div(x, y) => Expr::Div(b(x, rng), y),
        Expr::Sqr(x) => Expr::Sqr(b(x, rng)),
        Expr::Powi(x, k) => Expr::Powi(b(x, rng), k),
        Expr::Neg(x) => Expr::Neg(b(x, rng)),
        Expr::AddF(x, f) => Expr::AddF(b(x, rng), f),
        Expr::SubF(x, f) => Expr::SubF(b(x, rng), f),
        Expr::MulF(x, f) => Expr::MulF(b(x, rng), f),
        Expr::DivF(x, f) => Expr::DivF(b(x, rng), f),
        other => other,
    }
}

/// Mixed-degree models (`Tm::with_lifted_weight`: parameters past the first ones weigh
/// more toward the order, so their high-degree terms are truncated into the remainder)
/// enclose the exact rational values of random expressions, as classic ones do; and
/// they are smaller: with the weight equal to the order, 6 full and 20 lifted
/// parameters at order 3 make 104 monomials (84 in the 6, plus 20), not 3,654.
#[test]
fn mixed_degree_arithmetic_encloses_exact_rational_values() {
    let mut rng = Rng(0x5EED_0A1F);
    let (mut checked, mut mixed_results, mut finite) = (0usize, 0usize, 0usize);
    for case in 0..3000 {
        let n = 2 + rng.below(4) as usize;
        let order = 2 + rng.below(4) as u32;
        let depth = 1 + rng.below(4) as u32;
        let e = rand_expr(&mut rng, n, order, depth);
        let e = mixed(e, &mut rng, n);
        let t = e.tm();
        if t.full_params().is_some() {
            mixed_results += 1;
        }
        finite += usize::from(encloses_at_points(&e, &t, &mut rng, n, case));
        checked += 6;
        // Reparameterised (some parameters dropped or moved) they still hold every value.
        let nv = t.n_vars();
        let map: Vec<Option<usize>> = (0..nv)
            .map(|k| (rng.below(4) != 0).then_some(nv - 1 - k))
            .collect();
        let r = t.reparam(&map, nv);
        let (xi, xq) = rng.point(n);
        let mut yi = vec![0.0; nv];
        for (k, m) in map.iter().enumerate() {
            if let Some(j) = m {
                yi[*j] = xi[k];
            }
        }
        let v = e.exact(&xq);
        let at = r.eval_at(&yi);
        assert!(
            contains_exact(&at, &v),
            "case {case}: exact {} not in {at:?} after reparam {map:?}\n{t:?}\n{r:?}",
            v.to_f64().unwrap_or(f64::NAN)
        );
    }
    assert!(mixed_results > 1000, "only {mixed_results} mixed results");
    assert!(finite > 2500, "only {finite} finite results");
    eprintln!("mixed degree: {checked} point checks, {mixed_results} mixed, {finite} finite");
    // The table sizes (C(6 + 3, 3) = 84 monomials in the full parameters, one per lifted
    // one) and the product's truncation: a lifted parameter squared is not a term.
    let a = (0..6).fold(Tm::constant(0.5, 6, 3), |s, k| s + Tm::var(k, 6, 3) * 0.1);
    let m = a.clone().with_lifted_weight(3);
    let lifted = (6..26).fold(m.clone(), |s, k| s + m.param(k, 26) * 0.01);
    assert_eq!(lifted.n_terms(), 104);
    assert_eq!(lifted.full_params(), Some(6));
    let classic = (6..26).fold(a, |s, k| s + Tm::var(k, 26, 3) * 0.01);
    assert_eq!(classic.n_terms(), 3654);
    let sq = m.param(7, 26).sqr();
    assert_eq!(sq.value(), 0.0);
    let r = sq.rem();
    assert!(
        r.lo <= 0.0 && r.hi >= 1.0 && r.width() < 2.0 + 1e-12,
        "{r:?}"
    );
}

/// Exact polynomial identities hold with tiny remainders: `(x + y)^2 = x^2 + 2xy + y^2`.
/// `Tm::reparam` (order reduction: parameters renumbered, some dropped) keeps every
/// value: for random models and random maps, the exact rational value of the original
/// expression at a random point lies in the reduced model's enclosure at the point's
/// kept coordinates, whatever the dropped coordinates were. `param_weights` is checked
/// against the coefficients' absolute sum read off the model's bound when only one
/// parameter varies.
#[test]
fn reparameterised_models_keep_every_value() {
    let mut rng = Rng(0x5EED_00A7);
    let mut checked = 0usize;
    for case in 0..1500 {
        let n = 2 + rng.below(4) as usize;
        let order = 1 + rng.below(5) as u32;
        let depth = 1 + rng.below(3) as u32;
        let e = rand_expr(&mut rng, n, order, depth);
        let t = e.tm();
        let nv = t.n_vars();
        // A random injective map: each parameter kept (to a shuffled new index among
        // `n_new`) or dropped.
        let n_new = nv + rng.below(3) as usize;
        let mut free: Vec<usize> = (0..n_new).collect();
        let map: Vec<Option<usize>> = (0..nv)
            .map(|_| {
                if rng.below(3) == 0 || free.is_empty() {
                    None
                } else {
                    let k = rng.below(free.len() as u64) as usize;
                    Some(free.swap_remove(k))
                }
            })
            .collect();
        let r = t.reparam(&map, n_new);
        assert_eq!(r.n_vars(), n_new);
        let w = t.param_weights();
        assert_eq!(w.len(), nv);
        assert!(w.iter().all(|v| *v >= 0.0), "case {case}: weights {w:?}");
        for _ in 0..6 {
            let (xi, xq) = rng.point(n);
            let v = e.exact(&xq);
            let mut yi = vec![0.0; n_new];
            for (k, m) in map.iter().enumerate() {
                if let Some(j) = m {
                    yi[*j] = xi[k];
                }
            }
            let at = r.eval_at(&yi);
            assert!(
                contains_exact(&at, &v),
                "case {case}: exact {} not in {at:?} after reparam {map:?}\n{t:?}\n{r:?}",
                v.to_f64().unwrap_or(f64::NAN)
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 9000);
    // Weights: x0 + 2 x1^2 - 3 x0 x1 puts |1| + |3| on x0 and |2| + |3| on x1.
    let x0 = Tm::var(0, 2, 3);
    let x1 = Tm::var(1, 2, 3);
    let t = x0.clone() + x1.sqr() * 2.0 - x0 * x1 * 3.0;
    assert_eq!(t.param_weights(), vec![4.0, 5.0]);
    // Dropping x1 bounds 2 x1^2 by [0, 2] and 3 x0 x1 by [-3, 3]: x0 + [-3, 5].
    let r = t.reparam(&[Some(0), None], 1);
    let b = r.eval_at(&[0.5]);
    assert!(
        b.lo <= 0.5 - 3.0 && b.hi >= 0.5 + 5.0 && b.hi - b.lo < 8.0 + 1e-12,
        "{b:?}"
    );
}

/// An affine model `c + g . xi` (`|c| < centre`, `|g_k| < slope`, `n` parameters, order
/// `o`), half the time plus a random multiple of its square.
fn rand_quadratic(rng: &mut Rng, n: usize, o: u32, centre: f64, slope: f64) -> Tm {
    let coef: Vec<f64> = (0..n).map(|_| rng.range(-slope, slope)).collect();
    let a = Tm::affine(rng.range(-centre, centre), &coef, o);
    if rng.below(2) == 0 {
        a.clone() + a.sqr() * rng.range(-0.5, 0.5)
    } else {
        a
    }
}

/// `relu` of a model whose sign is undecided is the chord of the triangle relaxation,
/// `lam x + [0, gap]`: at every point the image of the argument's enclosure lies in the
/// result's (up to 1e-15: the chord touches relu at the enclosure's top, where the
/// argument's own outward rounding can exceed the true value), and the gap is the
/// relaxation's `u |l| / (u - l)` (1/2 for `xi` over `[-1, 1]`, where the interval
/// `[0, u]` would keep no dependence).
#[test]
fn relu_of_undecided_models_is_the_triangle_chord() {
    let mut rng = Rng(0x5EED_0C0D);
    let mut mixed = 0;
    for _ in 0..2000 {
        let n = 1 + rng.below(3) as usize;
        let o = 1 + rng.below(4) as u32;
        let a = rand_quadratic(&mut rng, n, o, 0.8, 1.0);
        if a.sign() != Sign::Mixed {
            continue;
        }
        mixed += 1;
        let r = a.relu();
        for _ in 0..10 {
            let xi: Vec<f64> = (0..n).map(|_| rng.param()).collect();
            let u = a.eval_at(&xi);
            let got = r.eval_at(&xi);
            let tol = 1e-15 * (1.0 + u.hi.abs());
            assert!(
                got.lo <= u.lo.max(0.0) + tol && u.hi.max(0.0) <= got.hi + tol,
                "relu image [{}, {}] not in {got:?}",
                u.lo.max(0.0),
                u.hi.max(0.0)
            );
        }
    }
    assert!(mixed > 1000, "only {mixed} undecided models");
    let x = Tm::var(0, 1, 3);
    let r = x.relu();
    for p in [-1.0, -0.5, 0.0, 0.5, 1.0] {
        let e = r.eval_at(&[p]);
        assert!(e.hi - e.lo <= 0.5 + 1e-12, "{e:?} at {p}");
    }
}

/// Squares carry the lower bound 0 (`Tm`'s `lo`), through sums and positive scalings,
/// so `sqrt(x^2 + eps)` keeps its domain where `x` straddles 0 and the monomial-wise
/// bound of `x^2 + eps` dips below 0 (the glider's `sqrt(omega^2 + 1e-5)`). Checked at
/// random points against the range of `sqrt(2 x^2 + eps)` over `x`'s enclosure there
/// (libm, 1e-13 relative slack), for one and several parameters; on `Series<Tm>` the square's
/// constant term keeps the bound too, so the series' square root stays finite.
#[test]
fn squares_keep_their_lower_bound() {
    let mut rng = Rng(0x5EED_F100);
    let eps = 1e-5;
    let mut dipped = 0;
    for case in 0..2000 {
        let n = 1 + rng.below(3) as usize;
        let o = 1 + rng.below(4) as u32;
        // Centre small against the slopes: the set straddles 0.
        let x = rand_quadratic(&mut rng, n, o, 0.004, 0.01);
        let u = x.sqr() * 2.0 + eps;
        // What the polynomial alone would say.
        let (c0, lin) = x.linear_part();
        let naive = c0 * c0 - 2.0 * c0.abs() * lin.iter().map(|v| v.abs()).sum::<f64>();
        if naive + eps < 0.0 {
            dipped += 1;
        }
        let b = u.bound();
        assert!(b.lo >= eps * (1.0 - 1e-12), "case {case}: bound {b:?}");
        let r = u.sqrt();
        let rb = r.bound();
        assert!(
            rb.lo.is_finite() && rb.hi.is_finite() && rb.lo > 0.0,
            "case {case}: {rb:?}"
        );
        let inv = Tm::cst(1.0) / r.clone();
        assert!(inv.bound().hi.is_finite(), "case {case}: 1/sqrt unbounded");
        for _ in 0..5 {
            let xi: Vec<f64> = (0..n).map(|_| rng.param()).collect();
            let xv = x.eval_at(&xi);
            // The exact argument lies in 2 [min x^2, max x^2] + eps.
            let lo_sq = if xv.lo <= 0.0 && xv.hi >= 0.0 {
                0.0
            } else {
                xv.lo.abs().min(xv.hi.abs()).powi(2)
            };
            let hi_sq = xv.lo.abs().max(xv.hi.abs()).powi(2);
            let (want_lo, want_hi) = ((2.0 * lo_sq + eps).sqrt(), (2.0 * hi_sq + eps).sqrt());
            let got = r.eval_at(&xi);
            // The reference comes from x's outward-rounded enclosure: a hair wide.
            let tol = 1e-13 * want_hi;
            assert!(
                got.lo <= want_lo + tol && want_hi <= got.hi + tol,
                "case {case}: [{want_lo}, {want_hi}] not in {got:?}"
            );
        }
    }
    assert!(
        dipped > 200,
        "only {dipped} cases where the plain bound dips below 0"
    );
    // On series: sqrt(x(t)^2 + eps) with x(t) = x0 + t, x0 a model straddling 0.
    let x0 = Tm::affine(0.001, &[0.01, 0.004], 3);
    let xs = Series::<Tm, 6>::var(x0);
    let s = (xs.sqr() + Series::cst(eps)).sqrt();
    assert!(s.c[0].bound().lo > 0.0);
    for k in 0..6 {
        let b = s.c[k].bound();
        assert!(
            b.lo.is_finite() && b.hi.is_finite(),
            "coefficient {k}: {b:?}"
        );
    }
}

#[test]
fn products_are_exact_up_to_rounding_when_the_order_suffices() {
    let x = Tm::affine(0.5, &[0.25, 0.0], 4);
    let y = Tm::affine(-0.125, &[0.0, 0.75], 4);
    let lhs = (x.clone() + y.clone()).sqr();
    let rhs = x.sqr() + x.clone() * y.clone() * 2.0 + y.sqr();
    let d = lhs - rhs;
    let b = d.bound();
    assert!(b.lo <= 0.0 && b.hi >= 0.0 && b.width() < 1e-14, "{b:?}");
    // Dyadic coefficients: the product is exact; only the a-priori rounding bound
    // (gamma_m sum |a_i b_j|) enters the remainder.
    let p = x.clone() * y.clone();
    assert!(p.rem().width() < 1e-14, "{p:?}");
    // Truncation: x^3 at order 2 moves the cubic term into the remainder.
    let z = Tm::var(0, 1, 2);
    let c = z.clone() * z.clone() * z;
    assert!(c.rem().lo <= -1.0 && c.rem().hi >= 1.0);
}

type Fun = (&'static str, fn(&Tm) -> Tm, fn(f64) -> f64);

fn funs() -> Vec<(Fun, f64, f64)> {
    // (function, range of the argument's constant term)
    vec![
        (("exp", |t| t.exp(), f64::exp), -3.0, 3.0),
        (("sin", |t| t.sin(), f64::sin), -4.0, 4.0),
        (("cos", |t| t.cos(), f64::cos), -4.0, 4.0),
        (("tanh", |t| t.tanh(), f64::tanh), -3.0, 3.0),
        (("atan", |t| t.atan(), f64::atan), -3.0, 3.0),
        (("sqrt", |t| t.sqrt(), f64::sqrt), 1.0, 5.0),
        (("ln", |t| t.ln(), f64::ln), 1.0, 5.0),
        (("tan", |t| t.tan(), f64::tan), -0.9, 0.9),
        (
            ("sigmoid", |t| t.sigmoid(), |x| 1.0 / (1.0 + (-x).exp())),
            -4.0,
            4.0,
        ),
        (
            ("recip", |t| Tm::cst(1.0) / t.clone(), |x| 1.0 / x),
            1.0,
            4.0,
        ),
    ]
}

/// Reference enclosure of `f(y)` for the exact `y`: `f` at `y`'s neighbours (the
/// conversion to f64 is within 1 ulp), widened by 4 ulps plus an absolute 1e-300.
fn reference(f: fn(f64) -> f64, y: &BigRational) -> Interval {
    let yf = y.to_f64().unwrap();
    let pts = [yf.next_down().next_down(), yf, yf.next_up().next_up()];
    let vals = pts.map(f);
    let mut lo = vals.iter().cloned().fold(f64::INFINITY, f64::min);
    let mut hi = vals.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    for _ in 0..4 {
        lo = lo.next_down();
        hi = hi.next_up();
    }
    Interval::new(lo - 1e-300, hi + 1e-300)
}

fn meets(a: &Interval, b: &Interval) -> bool {
    a.lo <= b.hi && b.lo <= a.hi
}

#[test]
fn elementary_functions_enclose_libm_values() {
    let mut rng = Rng(0x5EED_0002);
    let mut checks = 0usize;
    for case in 0..1500 {
        for ((name, ft, ff), lo, hi) in funs() {
            let n = 1 + rng.below(4) as usize;
            let order = 1 + rng.below(6) as u32;
            // g = c + small random polynomial (+ remainder sometimes), range radius <= 0.6.
            let scale = [0.6, 0.1, 0.01][rng.below(3) as usize];
            let c = rng.range(lo, hi);
            let coef: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
            let s: f64 = coef.iter().map(|v| v.abs()).sum();
            let lin = Expr::Affine(
                0.0,
                coef.iter().map(|v| v * scale / (2.0 * s)).collect(),
                order,
            );
            let quad = Expr::MulF(
                Box::new(Expr::Mul(Box::new(lin.clone()), Box::new(lin.clone()))),
                rng.range(-1.0, 1.0),
            );
            let mut g = Expr::AddF(Box::new(Expr::Add(Box::new(lin), Box::new(quad))), c);
            if rng.below(3) == 0 {
                let r = Interval::new(-1e-4 * scale * rng.unit(), 1e-4 * scale * rng.unit());
                let d = point_in(&mut rng, &r);
                g = Expr::WithRem(Box::new(g), r, d);
            }
            let gt = g.tm();
            let ftm = ft(&gt);
            let b = ftm.bound();
            assert!(
                b.lo.is_finite() && b.hi.is_finite(),
                "{name} case {case}: not finite {ftm:?} of {gt:?}"
            );
            for _ in 0..4 {
                let (xi, xq) = rng.point(n);
                let y = g.exact(&xq);
                let r = reference(ff, &y);
                let at = ftm.eval_at(&xi);
                assert!(
                    meets(&at, &r),
                    "{name} case {case}: f(g) in {r:?}, eval_at {at:?}\n{ftm:?}\n{gt:?}"
                );
                assert!(
                    meets(&b, &r),
                    "{name} case {case}: bound {b:?} misses {r:?}"
                );
                checks += 1;
            }
        }
    }
    eprintln!("elementary: {checks} point checks");
}

/// Compositions (f of an arithmetic expression of Taylor models) stay sound too.
#[test]
fn compositions_enclose_libm_values() {
    let mut rng = Rng(0x5EED_0003);
    for case in 0..400 {
        let n = 1 + rng.below(3) as usize;
        let order = 2 + rng.below(4) as u32;
        let x = Tm::affine(rng.range(-1.0, 1.0), &vec![0.2; n], order);
        let y = x.sin() * x.exp() + x.atan().sqr();
        let z = (y.clone() * 0.1).tanh() / (x.cos() + 2.0);
        for _ in 0..4 {
            let xi: Vec<f64> = (0..n).map(|_| rng.param()).collect();
            // Independent: interval evaluation at the point (Interval is separate code).
            let xv = x.eval_at(&xi);
            let yv = xv.sin() * xv.exp() + xv.atan().sqr();
            let zv = (yv * 0.1).tanh() / (xv.cos() + 2.0);
            assert!(meets(&y.eval_at(&xi), &yv), "case {case}: {y:?} vs {yv:?}");
            assert!(meets(&z.eval_at(&xi), &zv), "case {case}: {z:?} vs {zv:?}");
            assert!(meets(&z.bound(), &zv));
        }
    }
}

/// The remainders stay small enough for the type to be useful.
#[test]
fn remainders_are_small() {
    // |H| <= 0.1, order 5: Lagrange term ~ e^0.4 0.1^6 / 720.
    let g = Tm::affine(0.3, &[0.05, 0.03, 0.02], 5) + Tm::var(0, 3, 5) * Tm::var(1, 3, 5) * 0.0;
    for (name, f) in [
        ("exp", (|t: &Tm| t.exp()) as fn(&Tm) -> Tm),
        ("sin", |t| t.sin()),
        ("cos", |t| t.cos()),
        ("tanh", |t| t.tanh()),
        ("atan", |t| t.atan()),
        ("sigmoid", |t| t.sigmoid()),
        ("sqrt", |t| (t.clone() + 1.0).sqrt()),
        ("ln", |t| (t.clone() + 1.0).ln()),
        ("tan", |t| t.tan()),
        ("recip", |t| Tm::cst(1.0) / (t.clone() + 1.0)),
    ] {
        let r = f(&g);
        assert!(r.rem().width() < 1e-6, "{name}: remainder {:?}", r.rem());
        assert_eq!(r.order(), 5);
        assert_eq!(r.n_vars(), 3);
    }
    // The remainder shrinks with the order (order 8, |H| <= 0.1: ~1e-12).
    let g8 = Tm::affine(0.3, &[0.05, 0.03, 0.02], 8);
    assert!(g8.exp().rem().width() < 1e-10, "{:?}", g8.exp().rem());
    // The linear part of exp(c + h) is exp(c) (1 + h).
    let (c0, lin) = g.exp().linear_part();
    let e = 0.3f64.exp();
    assert!((c0 - e).abs() < 1e-12 && (lin[0] - 0.05 * e).abs() < 1e-12);
    assert!(g.exp().nonlinear_bound().width() < 0.02);
}

/// Out-of-domain arguments give non-finite (never wrong finite) enclosures.
#[test]
fn domain_violations_are_not_finite() {
    let x = Tm::affine(0.0, &[1.0], 3); // [-1, 1]
    let s = x.sqrt(); // Interval convention: sqrt of the non-negative part, [0, 1]
    assert!(s.bound().lo <= 0.0 && s.bound().hi >= 1.0);
    assert_eq!(x.ln().bound().lo, f64::NEG_INFINITY);
    let neg = Tm::affine(-3.0, &[1.0], 3);
    assert_eq!(neg.sqrt().bound(), Interval::entire());
    assert_eq!(neg.ln().bound(), Interval::entire());
    assert_eq!((Tm::cst(1.0) / x.clone()).bound(), Interval::entire());
    let pole = Tm::affine(1.5, &[0.2], 3);
    assert_eq!(pole.tan().bound(), Interval::entire());
    let big = Tm::affine(800.0, &[1.0], 3);
    assert!(big.exp().bound().hi == f64::INFINITY);
    assert!((x.clone() / 0.0).bound() == Interval::entire());
    // Overflowing coefficients make the entire model, never NaN.
    let huge = Tm::affine(1e300, &[1e300], 3);
    let p = huge.clone() * huge;
    assert_eq!(p.bound(), Interval::entire());
    assert_eq!(p.eval_at(&[0.5]), Interval::entire());
}

#[test]
fn constructors_accessors_and_mixing() {
    let a = Tm::affine(1.0, &[2.0, -3.0], 3);
    assert_eq!(a.n_vars(), 2);
    assert_eq!(a.order(), 3);
    assert_eq!(a.linear_part(), (1.0, vec![2.0, -3.0]));
    assert_eq!(a.bound(), Interval::new(-4.0, 6.0));
    assert_eq!(a.nonlinear_bound(), Interval::point(0.0));
    assert_eq!(a.value(), 1.0);
    // x^2 over [-1, 1] is [0, 1]: the all-even bound.
    let x = Tm::var(0, 1, 2);
    let close =
        |a: Interval, b: Interval| (a.lo - b.lo).abs() < 1e-15 && (a.hi - b.hi).abs() < 1e-15;
    assert!(
        close(x.sqr().bound(), Interval::new(0.0, 1.0)),
        "{:?}",
        x.sqr()
    );
    assert!(close(x.sqr().nonlinear_bound(), Interval::new(0.0, 1.0)));
    // cst and from_interval adopt the other operand's n and order.
    let c = Tm::cst(2.0) * a.clone();
    assert_eq!((c.n_vars(), c.order()), (2, 3));
    let i = Tm::from_interval(Interval::new(1.0, 2.0)) + a.clone();
    assert_eq!((i.n_vars(), i.order()), (2, 3));
    assert!(i.bound().lo <= -3.0 && i.bound().hi >= 8.0);
    // Different n: result n = max; different explicit orders: the minimum.
    let b = Tm::var(0, 1, 5) * Tm::var(0, 3, 2);
    assert_eq!((b.n_vars(), b.order()), (3, 2));
    let e = Tm::var(0, 1, 5).powi(4) + Tm::constant(0.0, 3, 2);
    assert_eq!((e.n_vars(), e.order()), (3, 2));
    assert!(
        e.rem().lo <= 0.0 && e.rem().hi >= 1.0,
        "x^4 at order 2: {e:?}"
    );
    // with_rem, eval_at, order 0.
    let w = a.clone().with_rem(Interval::new(-0.5, 0.25));
    assert_eq!(w.rem(), Interval::new(-0.5, 0.25));
    let v = w.eval_at(&[0.5, 0.5]);
    assert!(v.contains(0.5 - 0.5) && v.contains(0.5 + 0.25));
    let z = Tm::affine(1.0, &[0.5], 0);
    assert_eq!(z.linear_part(), (1.0, vec![0.0]));
    assert!(z.bound().contains(0.5) && z.bound().contains(1.5));
    assert_eq!(Tm::constant(3.0, 2, 4).bound(), Interval::point(3.0));
    assert_eq!(
        Tm::from_interval(Interval::new(1.0, 3.0)).bound(),
        Interval::new(1.0, 3.0)
    );
}

/// The point function a set operation must enclose.
type PointFn = Box<dyn Fn(f64, f64) -> f64>;

#[test]
fn sign_hull_abs_relu_clamp_are_sound() {
    let mut rng = Rng(0x5EED_0004);
    let x = Tm::affine(0.0, &[1.0], 3);
    assert_eq!(x.sign(), Sign::Mixed);
    assert_eq!(
        Tm::from_interval(Interval::new(0.0, 1.0)).sign(),
        Sign::NonNegative
    );
    // relu of a square whose bound dips below 0 by rounding stays tight.
    let r = x.sqr().relu();
    assert!(
        r.bound().lo >= -1e-15 && r.bound().hi <= 1.0 + 1e-15,
        "{r:?}"
    );
    assert_eq!((x.clone() + 2.0).sign(), Sign::Positive);
    assert_eq!((x.clone() - 2.0).sign(), Sign::Negative);
    assert_eq!(Tm::cst(0.0).sign(), Sign::Zero);
    for _ in 0..300 {
        let n = 1 + rng.below(3) as usize;
        let o = 1 + rng.below(4) as u32;
        let coef: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
        let coef2: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
        let a = Tm::affine(rng.range(-1.0, 1.0), &coef, o);
        let a = a.clone() * a.clone() - 0.3;
        let b = Tm::affine(rng.range(-1.0, 1.0), &coef2, o);
        let (lo, hi) = (rng.range(-0.5, 0.0), rng.range(0.0, 0.5));
        let ops: Vec<(Tm, PointFn)> = vec![
            (a.abs(), Box::new(|u, _| u.abs())),
            (a.relu(), Box::new(|u, _| u.max(0.0))),
            (a.smin(&b), Box::new(|u, v| u.min(v))),
            (a.smax(&b), Box::new(|u, v| u.max(v))),
            (a.clamp_to(lo, hi), Box::new(move |u, _| u.clamp(lo, hi))),
            (a.hull(&b), Box::new(|u, v| 0.5 * (u + v))),
        ];
        for _ in 0..5 {
            let xi: Vec<f64> = (0..n).map(|_| rng.param()).collect();
            let (u, v) = (a.eval_at(&xi), b.eval_at(&xi));
            for (t, f) in &ops {
                // f is monotone or 1-Lipschitz: its value at the enclosures' mid points
                // lies within the enclosure widths of the true value.
                let want = f(u.value(), v.value());
                let slack = u.width() + v.width() + 1e-12;
                let got = t.eval_at(&xi);
                assert!(
                    got.lo <= want + slack && want - slack <= got.hi,
                    "{got:?} vs {want}"
                );
            }
        }
    }
}

#[test]
fn series_of_taylor_models_gives_exp_coefficients() {
    // exp(t) about t0 = 0: coefficients 1/k!.
    let seed = Tm::constant(0.0, 2, 4);
    let mut t = Series::<Tm, 8>::var(seed);
    t.c[1] = Tm::cst(1.0);
    t.n = 8;
    let e = t.exp();
    let mut fact = BigRational::from_integer(BigInt::from(1));
    for k in 0..8 {
        if k > 0 {
            fact *= BigRational::from_integer(BigInt::from(k));
        }
        let want = BigRational::from_integer(BigInt::from(1)) / &fact;
        let got = e.c[k].eval_at(&[0.3, -0.7]);
        assert!(contains_exact(&got, &want), "k={k}: {got:?}");
        assert!(e.c[k].bound().width() < 1e-14, "k={k}: {:?}", e.c[k]);
        assert_eq!(e.c[k].n_vars(), 2);
    }
    // About a Taylor model x0(xi) = 0.2 + 0.1 xi_0: coefficient k is exp(x0(xi)) / k!.
    let x0 = Tm::affine(0.2, &[0.1], 5);
    let mut t = Series::<Tm, 6>::var(x0);
    t.c[1] = Tm::cst(1.0);
    t.n = 6;
    let e = t.exp();
    let mut rng = Rng(7);
    for _ in 0..50 {
        let xi = [rng.param()];
        let y = q(0.2) + q(0.1) * q(xi[0]);
        let mut f = 1.0;
        for k in 0..6 {
            if k > 0 {
                f *= k as f64;
            }
            let r = reference(|v| v.exp(), &y);
            let r = Interval::new((r.lo / f).next_down(), (r.hi / f).next_up());
            assert!(
                meets(&e.c[k].eval_at(&xi), &r),
                "k={k}: {:?} vs {r:?}",
                e.c[k]
            );
            assert!(e.c[k].rem().width() < 1e-6);
        }
    }
    // Series<Interval> is still Copy (the relaxed bound keeps it).
    fn is_copy<T: Copy>() {}
    is_copy::<Series<Interval, 4>>();
}

#[test]
fn tm_is_send_and_sync() {
    fn check<T: Send + Sync>() {}
    check::<Tm>();
    let h = std::thread::spawn(|| (Tm::var(0, 4, 4) * Tm::var(1, 4, 4)).bound());
    let b = h.join().unwrap();
    assert!(b.lo <= -1.0 && b.hi >= 1.0 && b.width() < 2.0 + 1e-14);
}

/// Timing of the product of two dense n = 4, order 4 models (70 terms); printed, and
/// checked loosely so that the test is not flaky on a loaded machine.
#[test]
fn product_timing() {
    let mut rng = Rng(0x5EED_0005);
    let mk = |rng: &mut Rng| {
        let coef: Vec<f64> = (0..4).map(|_| rng.range(-0.3, 0.3)).collect();
        let a = Tm::affine(rng.range(-1.0, 1.0), &coef, 4);
        (a.clone() * a.clone() * a.clone() * a.clone() + a).with_rem(Interval::new(-1e-9, 1e-9))
    };
    let (a, b) = (mk(&mut rng), mk(&mut rng));
    let reps = 20_000;
    let start = Instant::now();
    let mut acc = 0.0;
    for _ in 0..reps {
        let p = std::hint::black_box(&a) * std::hint::black_box(&b);
        acc += p.value();
    }
    let per = start.elapsed().as_secs_f64() / reps as f64;
    eprintln!("product n=4 order=4: {:.3} us ({acc})", per * 1e6);
    assert!(per < 1e-4, "product takes {per} s");
}

/// A model rebuilt from its own terms (`coef`, `from_terms`, its remainder) is the same
/// model: exact rational values of 400 random expressions lie in the rebuilt model's
/// enclosure; each `term` is its monomial (`x0^2 x1` at a point is the product), with
/// `[0, 1]` as the range of even monomials.
#[test]
fn models_rebuilt_from_their_terms_keep_every_value() {
    let mut rng = Rng(0x7E_4A5);
    for case in 0..400 {
        let n = 1 + rng.below(4) as usize;
        let order = 1 + rng.below(4) as u32;
        let depth = 1 + rng.below(3) as u32;
        let e = rand_expr(&mut rng, n, order, depth);
        let t = e.tm();
        let terms: Vec<(usize, f64)> = (1..t.n_terms())
            .filter(|&i| t.coef(i) != 0.0)
            .map(|i| (i, t.coef(i)))
            .collect();
        let r = t.from_terms(t.coef(0), &terms).with_rem(t.rem());
        assert!(r.same_basis(&t));
        for _ in 0..5 {
            let (xi, xq) = rng.point(t.n_vars().max(n));
            let v = e.exact(&xq);
            assert!(
                contains_exact(&r.eval_at(&xi), &v),
                "case {case}: rebuilt model misses the exact value"
            );
        }
    }
    let x0 = Tm::var(0, 2, 3);
    let x1 = Tm::var(1, 2, 3);
    let m = x0.sqr() * x1.clone();
    let i = (1..m.n_terms()).find(|&i| m.coef(i) != 0.0).unwrap();
    assert_eq!(m.term_degree(i), 3);
    assert!(!m.term_even(i));
    let at = m.term(i).eval_at(&[0.5, -0.25]);
    assert!(at.lo <= -0.0625 && at.hi >= -0.0625 && at.hi - at.lo < 1e-15);
    let s = x1.sqr();
    let j = (1..s.n_terms()).find(|&j| s.coef(j) != 0.0).unwrap();
    assert!(s.term_even(j));
    let b = s.term(j).bound();
    assert!(b.lo >= 0.0 && b.hi >= 1.0, "{b:?}");
}

/// The range bound sums coefficient magnitudes in round-to-nearest and adds the
/// additions' errors back (TwoSum, raised by the a-priori summation bound): 1 plus a
/// thousand terms of 1e-16, each below half an ulp of 1 so that every float addition
/// drops it, must still reach 1 + 1000e-16 (a plain float sum stays at exactly 1), and
/// exact sums stay exact.
#[test]
fn range_bound_keeps_the_additions_rounding_errors() {
    let x = 1e-16;
    let mut coef = vec![1.0];
    coef.extend(std::iter::repeat_n(x, 1000));
    let b = Tm::affine(0.0, &coef, 1).bound();
    assert!(
        b.hi - 1.0 >= 1000.0 * x * (1.0 - 1e-12),
        "upper end {} misses the dropped terms",
        b.hi
    );
    assert!(
        b.lo - -1.0 <= -1000.0 * x * (1.0 - 1e-12),
        "lower end {}",
        b.lo
    );
    // Not loose either: within a few ulps of 1 of the exact 1 + 1e-13.
    assert!(
        b.hi - 1.0 <= 1000.0 * x + 4.0 * f64::EPSILON,
        "upper end {}",
        b.hi
    );
    let e = Tm::affine(0.5, &[0.25, -0.125, 2.0], 1).bound();
    assert_eq!(e, Interval::new(0.5 - 2.375, 0.5 + 2.375));
}

/// Order changes keep every value: `Tm::with_order` (terms past a lower order bounded
/// into the remainder, as the joint-degree truncation of a flow's time coefficients
/// does), `Tm::raised_to` (a low-order model put on a higher-order table before a sum),
/// `Tm::share_table` (states and inputs put on one table), and quotients whose
/// numerator has the lower order (the denominator is lowered before its reciprocal).
/// Checked on random classic and mixed-degree expressions against exact rationals; a
/// raise onto a table that holds every monomial is exact (same remainder).
#[test]
fn order_changes_keep_every_value() {
    let mut rng = Rng(0x5EED_0D3C);
    let (mut checked, mut lowered, mut finite) = (0usize, 0usize, 0usize);
    for case in 0..2000 {
        let n = 2 + rng.below(4) as usize;
        let order = 2 + rng.below(4) as u32;
        let depth = 1 + rng.below(4) as u32;
        let mut e = rand_expr(&mut rng, n, order, depth);
        if rng.below(2) == 0 {
            e = mixed(e, &mut rng, n);
        }
        let t = e.tm();
        let low_order = rng.below(order as u64) as u32;
        let low = t.clone().with_order(low_order);
        if low.order() < t.order() {
            lowered += 1;
        }
        finite += usize::from(encloses_at_points(&e, &low, &mut rng, n, case));
        // Back onto the original table: exact, so the remainder does not move.
        let back = low.clone().raised_to(&t);
        assert_eq!(
            back.rem(),
            low.rem(),
            "case {case}: raise changed the remainder"
        );
        encloses_at_points(&e, &back, &mut rng, n, case);
        // A quotient of the lowered model by a higher-order divisor bounded away from 0.
        let coef: Vec<f64> = (0..n).map(|_| rng.range(-0.2, 0.2)).collect();
        let den = Expr::Affine(1.5 + rng.unit(), coef, order);
        let quot = low.clone() / den.tm();
        let (xi, xq) = rng.point(n);
        let v = e.exact(&xq) / den.exact(&xq);
        let at = quot.eval_at(&xi);
        assert!(
            contains_exact(&at, &v),
            "case {case}: exact quotient {} not in {at:?}",
            v.to_f64().unwrap_or(f64::NAN)
        );
        // One table for a model and a parameter past its own.
        let mut two = vec![t.clone(), t.param(n - 1, n)];
        Tm::share_table(&mut two);
        // (Models without an order of their own, constants, keep theirs.)
        if t.order() > 0 {
            assert!(two[0].same_basis(&two[1]), "case {case}: tables differ");
        }
        // Exact: the remainder is the model's own.
        assert_eq!(
            two[0].rem(),
            t.rem(),
            "case {case}: share_table changed the model"
        );
        encloses_at_points(&e, &two[0], &mut rng, n, case);
        // A model of a higher order keeps its terms (left on its own table).
        let mut mixed_orders = vec![t.clone(), low.clone()];
        Tm::share_table(&mut mixed_orders);
        assert_eq!(
            mixed_orders[0].rem(),
            t.rem(),
            "case {case}: a higher order was cut"
        );
        encloses_at_points(&e, &mixed_orders[1], &mut rng, n, case);
        checked += 25;
    }
    assert!(lowered > 1000, "only {lowered} lowered");
    assert!(finite > 1500, "only {finite} finite");
    eprintln!("order changes: {checked} point checks, {lowered} lowered, {finite} finite");
}

/// The model rebuilt from its coefficients and remainder: the same numbers, with
/// nothing kept from earlier operations (no kept ranges).
fn fresh(t: &Tm) -> Tm {
    if t.trunc_order() == u32::MAX {
        // No order of its own (a constant): nothing kept, and `from_terms` would fix one.
        return t.clone();
    }
    let terms: Vec<(usize, f64)> = (1..t.n_terms())
        .filter(|&i| t.coef(i) != 0.0)
        .map(|i| (i, t.coef(i)))
        .collect();
    t.from_terms(t.value(), &terms).with_rem(t.rem())
}

/// The same numbers: table, coefficients and remainder (as floats: bit for bit but for
/// the sign of a zero, which a negation gives and a rebuilt model does not keep).
fn same_bits(a: &Tm, b: &Tm) -> bool {
    a.same_basis(b)
        && a.rem().lo == b.rem().lo
        && a.rem().hi == b.rem().hi
        && (0..a.n_terms()).all(|i| a.coef(i) == b.coef(i))
}

/// Products truncated at a lower order (`Scalar::mul_capped`, what the series
/// convolutions use under the joint degree) enclose the exact rational product at
/// random points and end at that order; and the dropped-term bounds a model keeps
/// from its lowerings (`Tm`'s `drops`) give bit for bit the products of a model rebuilt
/// from its coefficients, also after the operations that change the coefficients of a
/// model that had kept them (sums, differences, scalings, quotients by a float,
/// negation), so a stale kept bound would show here.
#[test]
fn capped_products_and_kept_lowerings_hold() {
    let mut rng = Rng(0x5EED_CA9D);
    let (mut capped, mut finite) = (0usize, 0usize);
    for case in 0..1500 {
        let n = 2 + rng.below(4) as usize;
        let order = 2 + rng.below(4) as u32;
        let (da, db) = (1 + rng.below(3) as u32, 1 + rng.below(3) as u32);
        let mut ea = rand_expr(&mut rng, n, order, da);
        let mut eb = rand_expr(&mut rng, n, order, db);
        if rng.below(2) == 0 {
            ea = mixed(ea, &mut rng, n);
            eb = mixed(eb, &mut rng, n);
        }
        let (a, b) = (ea.tm(), eb.tm());
        let cap = rng.below(order as u64 + 1) as u32;
        let p = a.mul_capped(&b, cap);
        if a.trunc_order() != u32::MAX || b.trunc_order() != u32::MAX {
            assert!(
                p.order() <= cap,
                "case {case}: order {} past {cap}",
                p.order()
            );
            capped += usize::from(p.order() < a.order().max(b.order()));
        }
        let prod = Expr::Mul(Box::new(ea.clone()), Box::new(eb.clone()));
        finite += usize::from(encloses_at_points(&prod, &p, &mut rng, n, case));
        // Again (the kept bounds now used): the same numbers, and those of fresh copies.
        let again = a.mul_capped(&b, cap);
        assert!(
            same_bits(&p, &again),
            "case {case}: a kept lowering changed a product"
        );
        let cold = fresh(&a).mul_capped(&fresh(&b), cap);
        assert!(same_bits(&p, &cold), "case {case}: kept against fresh");
        // Operations that change the coefficients of a model with kept bounds.
        let f = 1.0 + rng.unit();
        let changed = [
            a.clone() + b.clone(),
            a.clone() - b.clone(),
            a.clone() * f,
            a.clone() / f,
            -a.clone(),
            {
                let mut s = a.clone();
                s += b.clone();
                s
            },
        ];
        for (k, m) in changed.iter().enumerate() {
            let warm = m.mul_capped(&b, cap);
            let cold = fresh(m).mul_capped(&fresh(&b), cap);
            assert!(
                same_bits(&warm, &cold),
                "case {case}: operation {k} left a stale bound"
            );
            let low = cap.min(m.order());
            let kept = m.clone().with_order(low);
            assert!(
                same_bits(&kept, &fresh(m).with_order(low)),
                "case {case}: lowering {k}"
            );
        }
    }
    assert!(capped > 300, "only {capped} capped products");
    assert!(finite > 1000, "only {finite} finite");
    eprintln!("capped products: {capped} capped, {finite} finite");
}

/// The exponents of monomial `i` of `t`'s table, read through the public interface:
/// monomial `i` at the point with `xi_k = 1/2` and every other parameter 1 is
/// `2^-e_k`, which its (outward-rounded) evaluation encloses.
fn exponents(t: &Tm, i: usize) -> Vec<u32> {
    let m = t.term(i);
    (0..t.n_vars())
        .map(|k| {
            let mut xi = vec![1.0; t.n_vars()];
            xi[k] = 0.5;
            let v = m.eval_at(&xi);
            let e = (-(0.5 * (v.lo + v.hi)).log2()).round();
            assert!(v.contains(2f64.powf(-e)), "monomial {i} at a power of two");
            e as u32
        })
        .collect()
}

/// The exponents of every monomial of `t`'s table ([`exponents`]), by index.
fn all_exponents(t: &Tm) -> Vec<Vec<u32>> {
    (0..t.n_terms()).map(|i| exponents(t, i)).collect()
}

/// The tables of the dense-model tests: a mixed-degree one as the six-state cell's (3
/// weight-1 and 4 lifted parameters of weight 2 at order 4), one with 2 and 3 of
/// weight 3, and classic ones in 4 parameters at order 3 and 2 at order 5.
fn dense_tables() -> [Tm; 4] {
    [
        Tm::var(0, 3, 4).with_lifted_weight(2).param(0, 7),
        Tm::var(0, 2, 4).with_lifted_weight(3).param(0, 5),
        Tm::var(0, 4, 3),
        Tm::var(0, 2, 5),
    ]
}

/// A model with every monomial of `base`'s table set (mixed magnitudes, some zero)
/// and a random remainder, and its exact function: the coefficients, the exponents
/// and the remainder's chosen point.
fn dense_model(rng: &mut Rng, base: &Tm, exps: &[Vec<u32>]) -> (Tm, Vec<f64>, Interval) {
    let decay = rng.range(0.05, 1.0);
    let c: Vec<f64> = (0..base.n_terms())
        .map(|i| match rng.below(8) {
            0 => 0.0,
            _ => rng.coef() * decay.powi(exps[i].iter().sum::<u32>() as i32),
        })
        .collect();
    let terms: Vec<(usize, f64)> = (1..c.len()).map(|i| (i, c[i])).collect();
    let rem = match rng.below(3) {
        0 => Interval::point(0.0),
        _ => {
            let a = rng.coef().abs() * 1e-6;
            Interval::new(-a * rng.unit(), a * rng.unit())
        }
    };
    (base.from_terms(c[0], &terms).with_rem(rem), c, rem)
}

/// The exact function a dense model ([`dense_model`]) encloses at the point `xq`: its
/// polynomial (coefficients `c`, exponents `exps`) plus a point of its remainder `rem`
/// chosen at random.
fn exact_at(
    rng: &mut Rng,
    c: &[f64],
    exps: &[Vec<u32>],
    xq: &[BigRational],
    rem: &Interval,
) -> BigRational {
    exact_poly(c, exps, xq) + q(point_in(rng, rem))
}

fn exact_poly(c: &[f64], exps: &[Vec<u32>], xq: &[BigRational]) -> BigRational {
    let mut s = BigRational::zero();
    for (ci, e) in c.iter().zip(exps) {
        if *ci == 0.0 {
            continue;
        }
        let mut m = q(*ci);
        for (k, &ek) in e.iter().enumerate() {
            for _ in 0..ek {
                m *= &xq[k];
            }
        }
        s += m;
    }
    s
}

/// Products of dense models (every monomial of the table nonzero but a few, as the
/// time coefficients of a lifted flow are) on mixed-degree tables (3 weight-1 and 4
/// lifted parameters of weight 2 at order 4, as the six-state cell's 6 and 36; 2 and 3
/// of weight 3) and classic ones, at the full order and capped at every lower one
/// (`Scalar::mul_capped`), enclose the exact rational product at random points with
/// any point of the operands' remainders. What the product's bounds by weighted degree
/// (the rounding errors and truncated terms summed per degree, not per row) must hold.
#[test]
fn dense_products_enclose_exact_values() {
    let mut rng = Rng(0x5EED_DE45);
    let tables = dense_tables();
    let mut checked = 0usize;
    for (tk, base) in tables.iter().enumerate() {
        let exps = all_exponents(base);
        let n = base.n_vars();
        for case in 0..60 {
            let (a, ca, ra) = dense_model(&mut rng, base, &exps);
            let (b, cb, rb) = dense_model(&mut rng, base, &exps);
            let cap = if case % 3 == 0 {
                base.order()
            } else {
                rng.below(base.order() as u64 + 1) as u32
            };
            let p = a.mul_capped(&b, cap);
            assert!(p.order() <= cap);
            let bound = p.bound();
            for _ in 0..4 {
                let (xi, xq) = rng.point(n);
                let va = exact_at(&mut rng, &ca, &exps, &xq, &ra);
                let vb = exact_at(&mut rng, &cb, &exps, &xq, &rb);
                let v = va * vb;
                let at = p.eval_at(&xi);
                assert!(
                    contains_exact(&at, &v),
                    "table {tk}, case {case}, cap {cap}: exact {} not in {at:?}",
                    v.to_f64().unwrap_or(f64::NAN)
                );
                assert!(contains_exact(&bound, &v), "table {tk}, case {case}: bound");
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 4 * 60 * 4);
}

/// Sums of products of dense models as a series' convolution takes them
/// (`Scalar::conv_capped`: `sum_j a_j b_{i-j}` at the smallest order of its operands,
/// the later coefficients at lower orders as under the joint degree, every product
/// added into one vector with one rounding-error bound) enclose the exact rational sum
/// at random points with any point of the remainders, on the tables of
/// `dense_products_enclose_exact_values`; and their remainders are not wider than
/// those of the products summed one by one, but for rounding terms.
#[test]
fn dense_convolutions_enclose_exact_values() {
    let mut rng = Rng(0x5EED_C0A7);
    let tables = dense_tables();
    let mut checked = 0usize;
    for (tk, base) in tables.iter().enumerate() {
        let exps = all_exponents(base);
        let n = base.n_vars();
        for case in 0..24 {
            let i = 1 + rng.below(5) as usize;
            // Coefficient k at order max(2, order + 1 - k) (or the full order).
            let joint = rng.below(2) == 0;
            let series = |rng: &mut Rng| {
                (0..=i)
                    .map(|k| {
                        let (m, c, r) = dense_model(rng, base, &exps);
                        let o = if joint && k >= 1 {
                            (base.order() + 1).saturating_sub(k as u32).max(2)
                        } else {
                            base.order()
                        };
                        (m.with_order(o), c, r)
                    })
                    .collect::<Vec<_>>()
            };
            let sa = series(&mut rng);
            let sb = series(&mut rng);
            let a: Vec<Tm> = sa.iter().map(|x| x.0.clone()).collect();
            let b: Vec<Tm> = sb.iter().map(|x| x.0.clone()).collect();
            let cap = (0..=i)
                .map(|j| a[j].trunc_order().min(b[i - j].trunc_order()))
                .min()
                .unwrap();
            let p = Tm::conv_capped(&a, &b, 0, i, cap);
            assert!(p.order() <= cap);
            let mut one = a[0].mul_capped(&b[i], cap);
            for j in 1..=i {
                one += a[j].mul_capped(&b[i - j], cap);
            }
            let (w, w1) = (p.rem().width(), one.rem().width());
            assert!(
                w <= w1 * (1.0 + 1e-9)
                    + 1e-12 * {
                        let b = p.bound();
                        b.lo.abs().max(b.hi.abs()).max(1.0)
                    },
                "table {tk}, case {case}: remainder {w} against {w1} one by one"
            );
            let bound = p.bound();
            for _ in 0..4 {
                let (xi, xq) = rng.point(n);
                let mut v = BigRational::zero();
                for j in 0..=i {
                    // The exact functions the models enclose: the dense polynomials
                    // and a point of their remainders (lowering keeps the function).
                    let (_, ca, ra) = &sa[j];
                    let (_, cb, rb) = &sb[i - j];
                    let va = exact_at(&mut rng, ca, &exps, &xq, ra);
                    let vb = exact_at(&mut rng, cb, &exps, &xq, rb);
                    v += va * vb;
                }
                let at = p.eval_at(&xi);
                assert!(
                    contains_exact(&at, &v),
                    "table {tk}, case {case}, i {i}, cap {cap}: exact {} not in {at:?}",
                    v.to_f64().unwrap_or(f64::NAN)
                );
                assert!(contains_exact(&bound, &v), "table {tk}, case {case}: bound");
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 4 * 24 * 4);
}

/// Elementary functions of dense models on mixed-degree tables (the six-state cell's
/// kind, 3 weight-1 and 4 lifted parameters of weight 2 at order 4) and classic ones
/// meet the libm values at random points: their Horner products run at the order each
/// step's result is left with (`order - k` for the `k`-th from the end), which must
/// keep every value.
#[test]
fn elementary_functions_of_dense_models_meet_libm_values() {
    let mut rng = Rng(0x5EED_E1E4);
    let tables = [
        Tm::var(0, 3, 4).with_lifted_weight(2).param(0, 7),
        Tm::var(0, 2, 5).with_lifted_weight(3).param(0, 4),
        Tm::var(0, 3, 4),
        Tm::var(0, 2, 2),
    ];
    let mut checks = 0usize;
    for (tk, base) in tables.iter().enumerate() {
        let exps = all_exponents(base);
        let n = base.n_vars();
        for case in 0..40 {
            for ((name, ft, ff), lo, hi) in funs() {
                // g = c + a dense polynomial of range radius <= `scale` (+ a remainder).
                let (d, mut cd, rd) = dense_model(&mut rng, base, &exps);
                let s: f64 = cd.iter().skip(1).map(|v| v.abs()).sum();
                let scale = [0.5, 0.1, 0.01][rng.below(3) as usize];
                let f = if s > 0.0 { scale / s } else { 1.0 };
                cd[0] = rng.range(lo, hi);
                for v in cd.iter_mut().skip(1) {
                    *v *= f;
                }
                let terms: Vec<(usize, f64)> = (1..cd.len()).map(|i| (i, cd[i])).collect();
                let r = Interval::new(rd.lo * 1e-3, rd.hi * 1e-3);
                let g = d.from_terms(cd[0], &terms).with_rem(r);
                let dr = point_in(&mut rng, &r);
                let fg = ft(&g);
                let b = fg.bound();
                assert!(
                    b.lo.is_finite() && b.hi.is_finite(),
                    "table {tk}, {name} case {case}: not finite"
                );
                for _ in 0..4 {
                    let (xi, xq) = rng.point(n);
                    let y = exact_poly(&cd, &exps, &xq) + q(dr);
                    let want = reference(ff, &y);
                    let at = fg.eval_at(&xi);
                    assert!(
                        meets(&at, &want),
                        "table {tk}, {name} case {case}: f(g) in {want:?}, eval_at {at:?}"
                    );
                    assert!(meets(&b, &want), "table {tk}, {name} case {case}: bound");
                    checks += 1;
                }
            }
        }
    }
    assert_eq!(checks, 4 * 40 * funs().len() * 4);
}

/// Sums, differences, scalings and quotients by a float of dense models (mixed-degree
/// tables as the six-state cell's, and classic ones; coefficients of mixed signs and
/// magnitudes from 1 to 1e-17, some zero) enclose the exact rational values at random
/// points with any point of the remainders, and every range (`Tm::bound`) holds the
/// exact monomial-wise range: `c_0` plus or minus the exact sums of the odd terms'
/// magnitudes and the even terms' of each sign, plus the remainder, and is not looser
/// than it by more than a few rounding units of those sums. What the branch-free
/// passes (four lanes, the even terms summed apart) must keep.
#[test]
fn sums_scalings_and_ranges_of_dense_models_enclose_exact_values() {
    let mut rng = Rng(0x5EED_5A4E);
    let tables = dense_tables();
    let mut checked = 0usize;
    for (tk, base) in tables.iter().enumerate() {
        let exps = all_exponents(base);
        let n = base.n_vars();
        let even: Vec<bool> = (0..base.n_terms()).map(|i| base.term_even(i)).collect();
        for case in 0..80 {
            let (mut a, mut ca, ra) = dense_model(&mut rng, base, &exps);
            if case % 2 == 1 {
                // Magnitudes down to 1e-17 beside 1: additions that round.
                for v in ca.iter_mut().skip(1) {
                    *v *= 10f64.powi(-(rng.below(18) as i32));
                }
                let terms: Vec<(usize, f64)> = (1..ca.len()).map(|i| (i, ca[i])).collect();
                a = base.from_terms(ca[0], &terms).with_rem(ra);
            }
            let (b, cb, rb) = dense_model(&mut rng, base, &exps);
            let s = match rng.below(4) {
                0 => -1.0,
                1 => 0.0,
                _ => rng.coef(),
            };
            // The exact monomial-wise range of `a`.
            let (mut odd, mut pos, mut neg) = (q(0.0), q(0.0), q(0.0));
            for i in 1..ca.len() {
                let v = q(ca[i]);
                if !even[i] {
                    odd += if ca[i] < 0.0 { -v } else { v };
                } else if ca[i] > 0.0 {
                    pos += v;
                } else {
                    neg -= v;
                }
            }
            let ba = a.bound();
            let lo = q(ca[0]) - &odd - &neg + q(ra.lo);
            let hi = q(ca[0]) + &odd + &pos + q(ra.hi);
            assert!(
                contains_exact(&ba, &lo) && contains_exact(&ba, &hi),
                "table {tk}, case {case}: the range {ba:?} misses the exact monomial-wise range"
            );
            let slack = q(1e-12) * (&odd + &pos + &neg + q(ca[0].abs())) + q(1e-300);
            assert!(
                q(ba.hi) - &hi <= slack && &lo - q(ba.lo) <= slack,
                "table {tk}, case {case}: the range {ba:?} is loose"
            );
            let results = [
                ("sum", a.clone() + b.clone()),
                ("difference", a.clone() - b.clone()),
                ("scaling", a.clone() * s),
                ("quotient", a.clone() / if s == 0.0 { 3.0 } else { s }),
            ];
            for _ in 0..3 {
                let (xi, xq) = rng.point(n);
                let va = exact_at(&mut rng, &ca, &exps, &xq, &ra);
                let vb = exact_at(&mut rng, &cb, &exps, &xq, &rb);
                let d = if s == 0.0 { 3.0 } else { s };
                let exact = [&va + &vb, &va - &vb, &va * q(s), &va / q(d)];
                for ((name, r), v) in results.iter().zip(&exact) {
                    let at = r.eval_at(&xi);
                    assert!(
                        contains_exact(&at, v) && contains_exact(&r.bound(), v),
                        "table {tk}, case {case}, {name}: exact {} not in {at:?}",
                        v.to_f64().unwrap_or(f64::NAN)
                    );
                }
                assert!(contains_exact(&ba, &va), "table {tk}, case {case}: bound");
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 4 * 80 * 3);
}
