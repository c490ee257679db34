//! Multivariate Taylor models over the parameter box `[-1, 1]^n` (Makino & Berz,
//! "Taylor models and other validated functional inclusion methods", *Int. J. Pure Appl.
//! Math.* 4(4), 2003).
//!
//! A [`Tm`] is a pair `(p, r)`: a polynomial `p` with `f64` coefficients in `n` parameters
//! `xi in [-1, 1]^n` of total degree `<= order`, and an [`Interval`] remainder `r`. It
//! *encloses* a function `g` when `g(xi) - p(xi) in r` for every `xi` in the box, where
//! `p(xi)` is evaluated in exact real arithmetic from the stored coefficients. Every
//! operation maps enclosures of its operands to an enclosure of the exact real result.
//!
//! A *mixed-degree* model ([`Tm::with_lifted_weight`]) counts the degree with weights:
//! its first parameters weigh 1 and the later ones (remainders lifted to parameters by a
//! flow) weigh `W`, and "degree" below then means that weighted degree. Products add
//! weighted degrees, so every truncation rule stays sound.
//!
//! # Rounding policy
//!
//! Coefficients are computed in IEEE 754 binary64 with round-to-nearest (the platform
//! default, which Rust does not change). Each such operation `c = fl(a op b)` satisfies
//! `|c - a op b| <= u |c| + eta` with `u = 2^-53`, `eta = 2^-1074` (the `eta` term only
//! for `*` and `/`, where the result may underflow; sums of floats are exact when they
//! underflow). The error bounds are accumulated in `f64` with every step rounded upward
//! (`next_up`), and added to the remainder as `[-e, e]` through the outward-rounded
//! [`Interval`] operations:
//!
//! * sums and scalings: `e = u * sum |c_k| + (number of products) * eta`;
//! * products: each output coefficient is a recursive sum of at most `m` products, with
//!   `m` the largest number of monomial pairs that map to one monomial (precomputed per
//!   `(n, order)`), so `e = gamma_m * sum |a_i b_j| + 2 (pairs) eta`, `gamma_m = m u / (1 - m u)`
//!   (Higham, *Accuracy and Stability of Numerical Algorithms*, 2002, sec. 3.1);
//! * sums of `P` products added into one vector (a series' convolution): each output
//!   coefficient is one recursive sum of at most `P m` products, so
//!   `e = gamma_{P m} * sum |a_i b_j| + 2 (pairs) eta` over all of them.
//!
//! Terms of total degree `> order` are bounded over the box and moved into the
//! remainder: in products by `|a_i| sum_{deg b_j > order - deg a_i} |b_j|` (symmetric);
//! when a model is converted to a lower order by `[0, c]` (resp. `[c, 0]`) for monomials
//! with all exponents even and `[-|c|, |c|]` otherwise. The polynomial range used by
//! [`Tm::bound`] is the same monomial-wise bound. A coefficient that overflows (or turns
//! NaN) makes the whole model the *entire* model: zero polynomial, remainder `(-inf, inf)`;
//! no model ever holds a non-finite coefficient or a NaN remainder end.
//!
//! # Elementary functions
//!
//! `f(x)` is expanded about the constant coefficient `c` of `x`: with `h = x - c` and
//! `H = bound(h)`, `f(c + h) = sum_{k <= d} a_k h^k + a_{d+1}(c + theta h) h^{d+1}`
//! (Lagrange), `d = min(order, 8)`. The `a_k = f^(k)(c) / k!` are enclosed by running `f` on
//! a `Series<Interval, 10>` seeded at the point `[c, c]`; the polynomial uses `mid(a_k)`
//! (Horner, with the sound products above) and `rad(a_k) |H|^k` goes to the remainder.
//! The Lagrange coefficient is enclosed by the same series seeded with the interval
//! `c + H` (its `k`-th coefficient encloses `f^(k)(xi) / k!` over the interval), times
//! `H^(d+1)`. When a series coefficient is not finite (the range leaves the domain: a
//! pole of `tan` or `1/x`, `sqrt`/`ln` at or below 0, overflow of `exp`), the result falls
//! back to the interval function of [`Tm::bound`] as a constant-plus-remainder model, with
//! the conventions of [`Interval`] (`sqrt` of a range reaching below 0 encloses the square
//! roots of its non-negative part, `ln` of a range touching 0 has lower end `-inf`); an
//! interval result that is NaN (the range lies wholly outside the domain) becomes the
//! entire model.

// Numeric kernels index several arrays by one index; the explicit forms mirror the formulas.
#![allow(clippy::assign_op_pattern, clippy::needless_range_loop)]

use crate::interval::Interval;
use crate::round::{down as dn, sum_dn, sum_up, up, UNIT_ROUNDOFF};
use crate::scalar::{Scalar, Sign};
use crate::series::Series;
use std::borrow::Cow;
use std::cell::RefCell;
use std::collections::HashMap;
use std::fmt;
use std::hash::{BuildHasherDefault, Hasher};
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};
use std::rc::Rc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};

/// Unit roundoff of binary64, round-to-nearest.
const U: f64 = UNIT_ROUNDOFF;
/// Smallest positive subnormal, `2^-1074`.
const ETA: f64 = f64::MIN_POSITIVE * f64::EPSILON;
/// Largest Taylor degree of the elementary-function expansions (the series hold 10 terms).
const MAX_DEG: u32 = 8;
/// Largest supported order (exponents are stored as `u8`).
const MAX_ORDER: u32 = 64;

type S10 = Series<Interval, 10>;

/// A multiply-rotate hasher (the FxHash scheme of rustc) for the exponent-vector and
/// table-pair keys: the monomial index is looked up once per term in conversions and
/// re-parameterisations, where SipHash cost a third of a Taylor-model flow's time
/// (`perf`, six-state glider set). The keys are the program's own, so no flooding
/// resistance is needed.
#[derive(Default, Clone, Copy)]
struct FxHasher(u64);

impl Hasher for FxHasher {
    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut w = [0u8; 8];
            w[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(w));
        }
    }
    #[inline]
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    #[inline]
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
    #[inline]
    fn finish(&self) -> u64 {
        self.0
    }
}

type FxMap<K, V> = HashMap<K, V, BuildHasherDefault<FxHasher>>;

/// Upper bound of the exact sum of `n` non-negative floats from `s`, their float sum
/// in round-to-nearest, in any order of additions: `|s - exact| <= gamma_{n-1} exact`
/// (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed. 2002, (4.4)), so
/// `exact <= s / (1 - gamma_{n-1}) <= s (1 + 4 n u)` while `n u <= 1/4`. Additions
/// never round inexactly below the normal range (sums of subnormals are exact), so no
/// absolute term is needed. Replaces one rounding up per term, whose chain of
/// dependent `next_up`s made the sums latency-bound. NaN gives infinity.
#[inline]
fn nonneg_sum_bound(s: f64, n: usize) -> f64 {
    if s.is_nan() {
        return f64::INFINITY;
    }
    if n <= 1 || s == 0.0 || s == f64::INFINITY {
        return s;
    }
    debug_assert!((n as f64) * U <= 0.25);
    up(s + up(s * up(4.0 * n as f64 * U)))
}

/// Upper bound of the exact `sum_i a_i b_i` of `n` products of non-negative floats from
/// `s`, its float value (each product rounded, then summed in any order): each term
/// carries one rounding of its product and at most `n - 1` of the sum, so
/// `gamma_n` bounds the relative error ([`nonneg_sum_bound`] with `n + 1`), and a
/// product that underflows is off by at most half of the smallest subnormal `ETA`
/// (counted as a whole `ETA` per term, before the relative factor).
#[inline]
fn nonneg_dot_bound(s: f64, n: usize) -> f64 {
    if n == 0 {
        return s;
    }
    nonneg_sum_bound(up(s + n as f64 * ETA), n + 1)
}

/// Interval sum, each end rounded outward only when inexact.
#[inline(always)]
fn iadd(a: Interval, b: Interval) -> Interval {
    Interval {
        lo: sum_dn(a.lo, b.lo),
        hi: sum_up(a.hi, b.hi),
    }
}

#[inline(always)]
fn sym(e: f64) -> Interval {
    Interval { lo: -e, hi: e }
}

#[inline(always)]
fn is_zero(i: &Interval) -> bool {
    i.lo == 0.0 && i.hi == 0.0
}

#[inline(always)]
fn has_nan(i: &Interval) -> bool {
    i.lo.is_nan() || i.hi.is_nan()
}

/// Upper bound of the radius of `i` about its midpoint `i.value()`.
fn rad(i: &Interval) -> f64 {
    let m = i.value();
    up(i.hi - m).max(up(m - i.lo))
}

/// Monomial and multiplication tables for one `(n, order, full, lw)`.
///
/// Parameters `0..full` weigh 1 toward the order and parameters `full..n` weigh `lw`
/// (a *mixed-degree* table: a monomial is kept when `sum_k w_k e_k <= order`). With
/// `lw = 1` every parameter weighs 1 and the table is the classic one of total degree
/// `<= order`. Truncation by a weighted degree is as sound as by the total degree:
/// weighted degrees add under products, so a product's dropped terms are exactly the
/// pairs whose weights sum past the order, and they are bounded into the remainder.
/// With `lw = order`, the parameters past `full` enter linearly only, as the
/// symbolic remainders of Flow* (Chen & Sankaranarayanan, "Decomposed reachability
/// analysis for nonlinear systems", RTSS 2016) and the generators of a zonotope do.
struct Table {
    n: usize,
    order: u32,
    /// Parameters `0..full` have weight 1, the others `lw` (`full = n`, `lw = 1`: classic).
    full: usize,
    /// Weight of the parameters `full..n`.
    lw: u32,
    /// Total degree of each monomial (graded order: degree-`d` monomials precede
    /// degree-`d+1` ones; the degree-1 monomials are `xi_0, ..., xi_{n-1}`).
    deg: Vec<u32>,
    /// Weighted degree of each monomial (the total degree on classic tables): what the
    /// truncation of products compares with the order.
    wdeg: Vec<u32>,
    /// Whether every exponent of the monomial is even (its range over the box is `[0, 1]`).
    even: Vec<bool>,
    /// Exponents, `n` per monomial.
    exps: Vec<u8>,
    /// Start of row `i` in `mul`.
    row: Vec<usize>,
    /// `mul[row[i] + j]`: index of `m_i m_j` for the `j` of degree `<= order - deg_i`,
    /// the first `rowlen[deg_i]` monomials (classic tables), or for the
    /// `j = part[row[i] + ..]` with `wdeg_i + wdeg_j <= order` (mixed tables, whose
    /// monomials of one weighted degree are not contiguous).
    mul: Vec<u32>,
    /// The partner `j` of every `mul` entry on mixed tables (empty on classic ones).
    part: Vec<u32>,
    /// The rows `i >= 1` with a partner besides the constant (weighted degree below the
    /// order), in index order: the only rows [`Tm::mul_on`]'s scatter visits (at order
    /// 4 with 36 lifted parameters of weight 2, 335 of 1,884).
    scat: Vec<u32>,
    /// `rowlen[w]`: the length of a row of weighted degree `w` (its partners: the
    /// monomials of weighted degree `<= order - w`), so that the number of pairs of a
    /// product is a sum over weighted degrees.
    rowlen: Vec<usize>,
    /// `wl[wls[4 w + l]..wls[4 w + l + 1]]`: the monomials of weighted degree `w` in
    /// lane `l` (`j mod 4`, the last `len mod 4` monomials in lane 0), in index order:
    /// [`Tm::wsums`] sums each lane in a register rather than through memory.
    wl: Vec<u32>,
    wls: Vec<usize>,
    /// `vars[vstart[i]..vstart[i + 1]]`: the parameters of monomial `i` (its nonzero
    /// exponents, in parameter order), so that passes over a model's terms visit a few
    /// parameters per monomial rather than all `n`.
    vstart: Vec<u32>,
    vars: Vec<u32>,
    /// `gamma_m` for the largest number `m` of pairs mapping to one monomial (rounded up).
    gamma: f64,
    /// That `m`: how many additions of one product land on one coefficient at most.
    pairmax: f64,
    /// Exponent vector to index.
    index: FxMap<Vec<u8>, u32>,
}

/// SplitMix64 (Steele, Lea & Flood, "Fast splittable pseudorandom number generators",
/// OOPSLA 2014): well-mixed 64-bit constants for [`Table::build`]'s additive hash.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn gen_monomials(n: usize, d: u32, cur: &mut Vec<u8>, out: &mut Vec<Vec<u8>>) {
    if cur.len() == n {
        if d == 0 {
            out.push(cur.clone());
        }
        return;
    }
    if cur.len() + 1 == n {
        cur.push(d as u8);
        out.push(cur.clone());
        cur.pop();
        return;
    }
    for e in (0..=d).rev() {
        cur.push(e as u8);
        gen_monomials(n, d - e, cur, out);
        cur.pop();
    }
}

impl Table {
    fn build(n: usize, order: u32, full: usize, lw: u32) -> Table {
        assert!(order <= MAX_ORDER, "Tm order {order} exceeds {MAX_ORDER}");
        let weight = |k: usize| if k < full { 1 } else { lw };
        let mut mons: Vec<Vec<u8>> = Vec::new();
        let mut pre = Vec::with_capacity(order as usize + 1);
        let mut deg = Vec::new();
        let mut wdeg = Vec::new();
        let mut all = Vec::new();
        for d in 0..=order {
            all.clear();
            gen_monomials(n, d, &mut Vec::with_capacity(n), &mut all);
            for e in all.drain(..) {
                let w: u32 = e
                    .iter()
                    .enumerate()
                    .map(|(k, &x)| weight(k) * x as u32)
                    .sum();
                if w <= order {
                    mons.push(e);
                    deg.push(d);
                    wdeg.push(w);
                }
            }
            pre.push(mons.len());
        }
        let mixed = full < n && lw > 1;
        let len = mons.len();
        assert!(len < u32::MAX as usize, "Tm table too large");
        let index: FxMap<Vec<u8>, u32> = mons
            .iter()
            .enumerate()
            .map(|(i, e)| (e.clone(), i as u32))
            .collect();
        let even = mons.iter().map(|e| e.iter().all(|&k| k % 2 == 0)).collect();
        let mut row = Vec::with_capacity(len + 1);
        let mut mul = Vec::new();
        let mut part = Vec::new();
        let mut count = vec![0usize; len];
        // Products by an additive hash: h(e) = sum_k e_k R_k (mod 2^64) gives
        // h(m_i m_j) = h(m_i) + h(m_j), one addition per pair instead of hashing an
        // exponent vector. The product is always in the table, so the lookup returns it
        // exactly when h is injective on the table, which is checked (another seed
        // otherwise).
        let (hash, by_hash) = (0u64..)
            .find_map(|seed| {
                let r: Vec<u64> = (0..n as u64)
                    .map(|k| splitmix64(seed * 1_000_003 + k))
                    .collect();
                let hash: Vec<u64> = mons
                    .iter()
                    .map(|e| {
                        e.iter().zip(&r).fold(0u64, |h, (&x, &rk)| {
                            h.wrapping_add(rk.wrapping_mul(x as u64))
                        })
                    })
                    .collect();
                let mut by_hash: FxMap<u64, u32> = FxMap::default();
                by_hash.reserve(len);
                for (i, &h) in hash.iter().enumerate() {
                    if by_hash.insert(h, i as u32).is_some() {
                        return None;
                    }
                }
                Some((hash, by_hash))
            })
            .expect("an injective seed exists");
        // On mixed tables, `upto[w]`: the monomials of weighted degree <= w in index
        // order (the partners of a monomial of weighted degree `order - w`), so that a
        // row costs its partners rather than a pass over the whole table.
        let upto: Vec<Vec<usize>> = if mixed {
            (0..=order)
                .map(|w| (0..len).filter(|&j| wdeg[j] <= w).collect())
                .collect()
        } else {
            Vec::new()
        };
        for i in 0..len {
            row.push(mul.len());
            let partners: &[usize] = if mixed {
                &upto[(order - wdeg[i]) as usize]
            } else {
                &[]
            };
            let classic = 0..if mixed {
                0
            } else {
                pre[(order - deg[i]) as usize]
            };
            let hi = hash[i];
            for j in partners.iter().copied().chain(classic) {
                let idx = by_hash[&hi.wrapping_add(hash[j])];
                count[idx as usize] += 1;
                mul.push(idx);
                if mixed {
                    part.push(j as u32);
                }
            }
        }
        row.push(mul.len());
        // What `Tm::mul_on` relies on: row 0 pairs the constant with every monomial at
        // its own index, and every row's first pair is `m_i * 1` at index `i`.
        assert!(row[1] - row[0] == len, "Tm table: row 0 is not complete");
        for i in 0..len {
            let j0 = if mixed { part[row[i]] as usize } else { 0 };
            assert!(
                row[i + 1] > row[i] && j0 == 0 && mul[row[i]] as usize == i,
                "Tm table: row {i} does not start with the constant"
            );
            if i == 0 {
                assert!((0..len).all(|j| mul[j] as usize == j && (!mixed || part[j] as usize == j)));
            }
        }
        // Row lengths depend on the weighted degree alone (checked), and every index
        // of the scatter is inside the table.
        let mut rowlen = vec![0usize; order as usize + 1];
        for i in 0..len {
            let l = row[i + 1] - row[i];
            let w = wdeg[i] as usize;
            assert!(
                rowlen[w] == 0 || rowlen[w] == l,
                "Tm table: rows of weighted degree {w} differ in length"
            );
            rowlen[w] = l;
        }
        assert!(mul.iter().chain(&part).all(|&k| (k as usize) < len));
        let scat: Vec<u32> = (1..len)
            .filter(|&i| row[i + 1] - row[i] > 1)
            .map(|i| i as u32)
            .collect();
        let len4 = len - len % 4;
        let mut groups: Vec<Vec<u32>> = vec![Vec::new(); (order as usize + 1) * 4];
        for (j, &w) in wdeg.iter().enumerate() {
            let lane = if j < len4 { j % 4 } else { 0 };
            groups[w as usize * 4 + lane].push(j as u32);
        }
        let mut wls = vec![0];
        let mut wl = Vec::with_capacity(len);
        for g in groups {
            wl.extend(g);
            wls.push(wl.len());
        }
        let mut vstart = Vec::with_capacity(len + 1);
        let mut vars = Vec::new();
        for e in &mons {
            vstart.push(vars.len() as u32);
            vars.extend(
                e.iter()
                    .enumerate()
                    .filter(|&(_, &x)| x > 0)
                    .map(|(k, _)| k as u32),
            );
        }
        vstart.push(vars.len() as u32);
        let m = count.iter().copied().max().unwrap_or(1).max(1) as f64;
        let gamma = up(up(m * U) / dn(1.0 - m * U));
        let exps = mons.concat();
        Table {
            n,
            order,
            full,
            lw,
            deg,
            wdeg,
            even,
            exps,
            row,
            mul,
            part,
            scat,
            rowlen,
            wl,
            wls,
            vstart,
            vars,
            gamma,
            pairmax: m,
            index,
        }
    }

    /// The parameters of monomial `i` (its nonzero exponents).
    #[inline(always)]
    fn vars_of(&self, i: usize) -> &[u32] {
        &self.vars[self.vstart[i] as usize..self.vstart[i + 1] as usize]
    }

    /// Whether parameters past `full` weigh more than 1 (the table may still hold no
    /// such parameter yet: `full = n`).
    fn is_mixed(&self) -> bool {
        self.lw > 1
    }

    #[inline(always)]
    fn len(&self) -> usize {
        self.deg.len()
    }

    fn exps(&self, i: usize) -> &[u8] {
        &self.exps[i * self.n..(i + 1) * self.n]
    }
}

/// The table for `(n, order)` with every parameter of weight 1 (classic).
fn table(n: usize, order: u32) -> &'static Table {
    table_mixed(n, order, n, 1)
}

/// The table for `(n, order, full, lw)` (see [`Table`]), built once per process and
/// leaked (one per key in use); a per-thread cache keeps lookups free of lock traffic.
/// Keys are normalised: `lw = 1` means classic (`full = n`), `lw` is at most `order`.
fn table_mixed(n: usize, order: u32, full: usize, lw: u32) -> &'static Table {
    let lw = lw.min(order).max(1);
    let full = if lw == 1 { n } else { full };
    thread_local! {
        static CACHE: RefCell<Vec<&'static Table>> = const { RefCell::new(Vec::new()) };
    }
    type Key = (usize, u32, usize, u32);
    static REG: OnceLock<Mutex<HashMap<Key, &'static Table>>> = OnceLock::new();
    CACHE.with(|cache| {
        if let Some(t) = cache
            .borrow()
            .iter()
            .find(|t| t.n == n && t.order == order && t.full == full && t.lw == lw)
        {
            return *t;
        }
        let t: &'static Table = REG
            .get_or_init(Default::default)
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .entry((n, order, full, lw))
            .or_insert_with(|| Box::leak(Box::new(Table::build(n, order, full, lw))));
        cache.borrow_mut().push(t);
        t
    })
}

/// A Taylor model `p(xi) + r` over `xi in [-1, 1]^n` (see the module documentation).
///
/// Models made by [`Scalar::cst`] and [`Tm::from_interval`] have no parameters and no
/// order of their own: combined with another model they adopt its order. Binary
/// operations between models with different `n` treat the one with fewer parameters as
/// independent of the extra ones (the result has the larger `n`); the result order is the
/// smaller of the operands' explicit orders.
#[derive(Clone)]
pub struct Tm {
    t: &'static Table,
    /// Whether the order was given explicitly (false for `cst`/`from_interval` models).
    fixed: bool,
    c: Vec<f64>,
    rem: Interval,
    /// A lower bound of every value the model stands for (`-inf` when unknown): squares
    /// are `>= 0`, whatever the monomial-wise bound of their polynomial says, so
    /// `sqrt(x^2 + eps)` keeps its domain where `x` straddles 0.
    lo: f64,
    /// The upward bounds `[sn, sp]` of the downward and upward extent of the
    /// non-constant terms over the box (what [`Tm::poly_range`] adds to the constant),
    /// computed on first use and kept until a non-constant coefficient changes (NaN:
    /// not yet computed): a product reads each operand's range where the other has a
    /// remainder, and a series convolution multiplies each coefficient many times.
    ext: Ext,
    /// The same kind of kept bounds for the terms a conversion to a lower order drops
    /// ([`Drops`]), reset together with `ext`.
    drops: Drops,
    /// The magnitudes of the non-constant terms by weighted degree ([`Tm::wsums`]),
    /// computed on first use and reset together with `ext`.
    wsums: OnceLock<Box<[WSum]>>,
}

/// Per weighted degree `w`: the sum of `|c_i|` over the monomials of weighted degree `w`
/// in the four lanes and order of additions of [`Tm::bound_sums`], combined as
/// `(l0 + l1) + (l2 + l3)`, and the number of nonzero `c_i`.
#[derive(Clone, Copy)]
struct WSum {
    sum: f64,
    nz: usize,
}

/// [`Tm::ext`] not yet computed.
const NO_EXT: [f64; 2] = [f64::NAN, f64::NAN];

/// A model's kept extents `[sn, sp]` ([`Tm::ext`]; NaN: not computed), in atomics so
/// that models stay `Sync`: threads that read one model's range at once both compute
/// the same numbers, and `sn` is published after `sp` (release / acquire), so a reader
/// that sees `sn` sees `sp` too.
struct Ext([AtomicU64; 2]);

impl Ext {
    fn new(v: [f64; 2]) -> Ext {
        Ext([
            AtomicU64::new(v[0].to_bits()),
            AtomicU64::new(v[1].to_bits()),
        ])
    }
    fn get(&self) -> [f64; 2] {
        let sn = f64::from_bits(self.0[0].load(Ordering::Acquire));
        let sp = f64::from_bits(self.0[1].load(Ordering::Relaxed));
        if sp.is_nan() {
            return NO_EXT;
        }
        [sn, sp]
    }
    fn set(&self, v: [f64; 2]) {
        self.0[1].store(v[1].to_bits(), Ordering::Relaxed);
        self.0[0].store(v[0].to_bits(), Ordering::Release);
    }
}

impl Clone for Ext {
    fn clone(&self) -> Ext {
        Ext::new(self.get())
    }
}

/// Target orders `1..=DROP_SLOTS` whose dropped extents [`Drops`] keeps.
const DROP_SLOTS: usize = 6;

/// A model's kept bounds `[sn, sp]` of the terms that [`Tm::convert`] bounds into the
/// remainder when it lowers the model to order `k` on the same parameters and weights,
/// and the kept extents ([`Tm::ext`]) of the lowered model's own terms (slot `k - 1`;
/// NaN: not computed). Series products under the joint degree of (parameters, time)
/// lower the same time coefficient to the same order once for every product that reads
/// it (`series::conv` multiplies coefficient 0 by every later one, each of a lower
/// order), and the sum over the dropped terms, nearly the whole model at order 4 with
/// lifted parameters, cost as much as the products themselves
/// (`bench/reach/cell_cost.md`, i48-r). Both depend on the non-constant coefficients
/// only, so they are reset exactly where [`Tm::ext`] is. Allocated on the first
/// lowering; a clone copies them.
#[derive(Default)]
struct Drops(
    OnceLock<Box<[[Ext; 2]; DROP_SLOTS]>>,
    /// The lowered models themselves (`fixed`, as products ask for them), kept on
    /// first use: a series' coefficient is lowered to the same order for every later
    /// order's convolution. Each with the source's constant coefficient, remainder and
    /// lower bound it was made from ([`Tm::lowering_key`]), which operations change
    /// without [`Tm::touch`]: a kept model is used only while they are the same. Not
    /// copied by a clone.
    OnceLock<Box<[OnceLock<KeptLowering>; DROP_SLOTS]>>,
);

/// A lowered model and the lowering key of the source it was made from.
type KeptLowering = (Tm, [u64; 4]);

impl Drops {
    /// The kept bounds for target order `k` (dropped terms, lowered model's extents),
    /// if computed.
    fn get(&self, k: u32) -> Option<([f64; 2], [f64; 2])> {
        let slots = self.0.get()?;
        let [d, e] = &slots[k as usize - 1];
        let (d, e) = (d.get(), e.get());
        (!d[0].is_nan()).then_some((d, e))
    }
    fn set(&self, k: u32, dropped: [f64; 2], lowered: [f64; 2]) {
        let slots = self.0.get_or_init(|| {
            Box::new(std::array::from_fn(|_| {
                [Ext::new(NO_EXT), Ext::new(NO_EXT)]
            }))
        });
        let [d, e] = &slots[k as usize - 1];
        // The lowered extents first: a reader that sees the dropped ones sees them.
        e.set(lowered);
        d.set(dropped);
    }
}

impl Drops {
    /// The kept lowered model for target order `k`, if computed from a source with
    /// the lowering key `key`.
    fn lowered(&self, k: u32, key: [u64; 4]) -> Option<&Tm> {
        let (m, made) = self.1.get()?[k as usize - 1].get()?;
        (*made == key).then_some(m)
    }
    /// Keeps `m` as the lowered model for target order `k` of a source with key `key`
    /// (unless one is kept); `m` back as a reference when it is the kept one.
    fn keep_lowered(&self, k: u32, m: Tm, key: [u64; 4]) -> Cow<'_, Tm> {
        let slots = self
            .1
            .get_or_init(|| Box::new(std::array::from_fn(|_| OnceLock::new())));
        let mut m = Some(m);
        let (kept, made) = slots[k as usize - 1].get_or_init(|| (m.take().expect("once"), key));
        match m {
            None if *made == key => Cow::Borrowed(kept),
            None => Cow::Owned(kept.clone()),
            Some(m) => Cow::Owned(m),
        }
    }
}

impl Clone for Drops {
    fn clone(&self) -> Drops {
        let d = Drops::default();
        if let Some(slots) = self.0.get() {
            let _ = d.0.set(Box::new(std::array::from_fn(|k| {
                [slots[k][0].clone(), slots[k][1].clone()]
            })));
        }
        d
    }
}

impl fmt::Debug for Tm {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let terms: Vec<(Vec<u8>, f64)> = (0..self.t.len())
            .filter(|&i| self.c[i] != 0.0)
            .map(|i| (self.t.exps(i).to_vec(), self.c[i]))
            .collect();
        f.debug_struct("Tm")
            .field("n", &self.t.n)
            .field("order", &self.t.order)
            .field("fixed", &self.fixed)
            .field("terms", &terms)
            .field("rem", &self.rem)
            .field("lo", &self.lo)
            .finish()
    }
}

/// The kept values that debug builds recheck against a fresh computation
/// ([`recheck_now`]): one counter each, so that one check's calls do not shift another's.
#[cfg(debug_assertions)]
#[derive(Clone, Copy)]
enum Recheck {
    /// [`Tm::check_kept_extent`].
    Extent,
    /// [`Tm::check_kept_lowered`].
    Lowered,
    /// [`Tm::check_kept_drops`].
    Drops,
    /// [`Tm::check_kept_wsums`].
    Wsums,
}

/// Debug builds: whether this call of the check `which` recomputes its kept value (one
/// call in 16 per thread: the 16th, 32nd, ...), so that a stale cache fails the tests
/// that reach it while the tests' cost stays near the release build's (which has no
/// checks: its bits do not depend on this).
#[cfg(debug_assertions)]
fn recheck_now(which: Recheck) -> bool {
    thread_local! {
        static CALLS: std::cell::Cell<[u32; 4]> = const { std::cell::Cell::new([0; 4]) };
    }
    CALLS.with(|c| {
        let mut calls = c.get();
        let n = calls[which as usize].wrapping_add(1);
        calls[which as usize] = n;
        c.set(calls);
        n.is_multiple_of(16)
    })
}

/// How the monomials of `from` land on `to` (which of them `to` has, at which index,
/// and which it lacks: past its weighted order), for tables with `from.n <= to.n` (the
/// extra parameters appended).
/// Built once per pair and thread: a flow converts between the same few tables (states
/// in `n` parameters meeting inputs in `n + 1`) at every operation of every step.
fn conversion(from: &'static Table, to: &'static Table) -> Rc<Conversion> {
    thread_local! {
        static MAPS: RefCell<FxMap<(usize, usize), Rc<Conversion>>> = RefCell::new(FxMap::default());
    }
    let key = (from as *const Table as usize, to as *const Table as usize);
    MAPS.with(|maps| {
        if let Some(m) = maps.borrow().get(&key) {
            return m.clone();
        }
        let mut k = vec![0u8; to.n];
        let mut conv = Conversion {
            kept: Vec::new(),
            dropped: Vec::new(),
        };
        for i in 0..from.len() {
            k[..from.n].copy_from_slice(from.exps(i));
            match to.index.get(&k) {
                Some(&j) => conv.kept.push((i as u32, j)),
                None => conv.dropped.push(i as u32),
            }
        }
        let m = Rc::new(conv);
        let mut maps = maps.borrow_mut();
        // Tables are leaked and few, but a long run re-parameterises often: keep the
        // cache bounded.
        if maps.len() >= 4096 {
            maps.clear();
        }
        maps.insert(key, m.clone());
        m
    })
}

/// Where [`Tm::reparam`] puts each monomial of `from` when parameter `k` becomes
/// `map[k]` of `to`'s (`u32::MAX`: bounded into the remainder, because it has a dropped
/// parameter or lies past `to`'s weighted order). Kept for the last few maps of each
/// thread: an order reduction renumbers every state and input by one map.
fn renumbering(from: &'static Table, to: &'static Table, map: &[Option<usize>]) -> Rc<Vec<u32>> {
    type Entry = (usize, usize, Vec<Option<usize>>, Rc<Vec<u32>>);
    thread_local! {
        static LAST: RefCell<Vec<Entry>> = const { RefCell::new(Vec::new()) };
    }
    let (fk, tk) = (from as *const Table as usize, to as *const Table as usize);
    LAST.with(|last| {
        if let Some(e) = last
            .borrow()
            .iter()
            .find(|e| e.0 == fk && e.1 == tk && e.2 == map)
        {
            return e.3.clone();
        }
        let mut out = vec![u32::MAX; from.len()];
        let mut key = vec![0u8; to.n];
        out[0] = 0;
        for (i, o) in out.iter_mut().enumerate().skip(1) {
            key.iter_mut().for_each(|e| *e = 0);
            let mut dropped = false;
            let exps = from.exps(i);
            for &k in from.vars_of(i) {
                match map[k as usize] {
                    Some(j) => key[j] = exps[k as usize],
                    None => dropped = true,
                }
            }
            // A kept monomial past the new table's weighted order (a parameter moved
            // to a heavier place) is bounded like a dropped one.
            if !dropped {
                if let Some(&idx) = to.index.get(&key) {
                    *o = idx;
                }
            }
        }
        let out = Rc::new(out);
        let mut last = last.borrow_mut();
        if last.len() >= 4 {
            last.remove(0);
        }
        last.push((fk, tk, map.to_vec(), out.clone()));
        out
    })
}

/// How the monomials of one table land on another ([`conversion`]).
struct Conversion {
    /// `(index in the source, index in the target)` of the monomials both have.
    kept: Vec<(u32, u32)>,
    /// Source monomials the target lacks (past its weighted order).
    dropped: Vec<u32>,
}

/// The common table and fixedness of a binary operation.
fn common(a: &Tm, b: &Tm) -> (&'static Table, bool) {
    common_of((a.t, a.fixed), (b.t, b.fixed))
}

/// [`common`] on `(table, fixed)` pairs: what a binary operation's result is made on.
fn common_of(
    (at, af): (&'static Table, bool),
    (bt, bf): (&'static Table, bool),
) -> (&'static Table, bool) {
    if std::ptr::eq(at, bt) {
        return (at, af || bf);
    }
    let n = at.n.max(bt.n);
    let (order, fixed) = match (af, bf) {
        (true, true) => (at.order.min(bt.order), true),
        (true, false) => (at.order, true),
        (false, true) => (bt.order, true),
        (false, false) => (at.order.min(bt.order), false),
    };
    // A mixed table's weights win over a classic one's (whose parameters past the
    // mixed table's `full` are truncated as the mixed weights say, soundly).
    let eff = |t: &Table| if t.is_mixed() { t.full } else { usize::MAX };
    let full = eff(at).min(eff(bt));
    let lw = at.lw.max(bt.lw);
    // The key `table_mixed` normalises to (classic tables ignore `full`).
    let fits =
        |t: &Table| t.n == n && t.order == order && t.lw == lw && (lw == 1 || t.full == full);
    if fits(at) {
        (at, fixed)
    } else if fits(bt) {
        (bt, fixed)
    } else {
        (table_mixed(n, order, full, lw), fixed)
    }
}

/// `[0, c]` or `[c, 0]`-style bound accumulation: adds the range of `c * m` (`m` a
/// monomial, `even` when its range is `[0, 1]`) to the upward bounds `(sn, sp)` of the
/// downward and upward extent.
#[inline(always)]
fn acc_range(c: f64, even: bool, sn: &mut f64, sp: &mut f64) {
    if even {
        if c > 0.0 {
            *sp = sum_up(*sp, c);
        } else {
            *sn = sum_up(*sn, -c); // NaN lands here and gives +inf
        }
    } else {
        let a = c.abs();
        *sp = sum_up(*sp, a);
        *sn = sum_up(*sn, a);
    }
}

impl Tm {
    fn raw(t: &'static Table, fixed: bool, c: Vec<f64>, rem: Interval) -> Tm {
        Tm {
            t,
            fixed,
            c,
            rem,
            lo: f64::NEG_INFINITY,
            ext: Ext::new(NO_EXT),
            drops: Drops::default(),
            wsums: OnceLock::new(),
        }
    }

    /// Forgets the kept ranges ([`Tm::ext`], [`Tm::drops`]): to be called before any
    /// non-constant coefficient changes.
    fn touch(&mut self) {
        self.ext.set(NO_EXT);
        self.drops = Drops::default();
        self.wsums = OnceLock::new();
    }

    /// [`Tm::finish`] for a model whose coefficients are known finite (copies of a
    /// valid model's, or sums whose magnitudes summed to a finite number): only the
    /// remainder can break the invariant.
    fn finish_rem(self) -> Tm {
        if has_nan(&self.rem) {
            Tm::entire_on(self.t, self.fixed)
        } else {
            self
        }
    }

    /// The entire model on `t`: zero polynomial, remainder the whole line.
    fn entire_on(t: &'static Table, fixed: bool) -> Tm {
        Tm::raw(t, fixed, vec![0.0; t.len()], Interval::entire())
    }

    /// Enforces the invariant: finite coefficients, NaN-free remainder.
    fn finish(self) -> Tm {
        if has_nan(&self.rem) || !self.c.iter().all(|v| v.is_finite()) {
            Tm::entire_on(self.t, self.fixed)
        } else {
            self
        }
    }

    fn constant_on(t: &'static Table, fixed: bool, v: f64) -> Tm {
        let mut c = vec![0.0; t.len()];
        c[0] = v;
        let mut m = Tm::raw(t, fixed, c, Interval::point(0.0)).finish();
        if v.is_finite() {
            m.lo = v;
        }
        m
    }

    fn from_interval_on(t: &'static Table, fixed: bool, i: Interval) -> Tm {
        if has_nan(&i) {
            return Tm::entire_on(t, fixed);
        }
        let mut c = vec![0.0; t.len()];
        let rem = if i.lo.is_finite() && i.hi.is_finite() {
            let m = 0.5 * i.lo + 0.5 * i.hi;
            c[0] = m;
            Interval {
                lo: sum_dn(i.lo, -m).min(0.0),
                hi: sum_up(i.hi, -m).max(0.0),
            }
        } else {
            i
        };
        let mut m = Tm::raw(t, fixed, c, rem);
        m.lo = i.lo;
        m
    }

    /// The constant `c` as a model in `n` parameters of order `order`.
    pub fn constant(c: f64, n: usize, order: u32) -> Tm {
        Tm::constant_on(table(n, order), true, c)
    }

    /// The parameter `xi_k` (`k < n`) as a model in `n` parameters of order `order`
    /// (for `order = 0` the parameter goes into the remainder as `[-1, 1]`).
    pub fn var(k: usize, n: usize, order: u32) -> Tm {
        assert!(k < n, "Tm::var: parameter {k} out of {n}");
        let mut coef = vec![0.0; n];
        coef[k] = 1.0;
        Tm::affine(0.0, &coef, order)
    }

    /// `cst + sum_k coef[k] xi_k`, a model in `n = coef.len()` parameters of order `order`
    /// (for `order = 0` the linear terms are bounded into the remainder).
    pub fn affine(cst: f64, coef: &[f64], order: u32) -> Tm {
        Tm::affine_on(table(coef.len(), order), cst, coef)
    }

    /// `cst + sum_k coef[k] xi_k` on table `t` (`coef.len() = t.n`; for order 0 the
    /// linear terms are bounded into the remainder).
    fn affine_on(t: &'static Table, cst: f64, coef: &[f64]) -> Tm {
        let (n, order) = (t.n, t.order);
        let mut c = vec![0.0; t.len()];
        c[0] = cst;
        let mut rem = Interval::point(0.0);
        if order >= 1 {
            c[1..=n].copy_from_slice(coef);
        } else {
            let mut s = 0.0;
            for &v in coef {
                s = up(s + v.abs());
            }
            rem = sym(s);
        }
        Tm::raw(t, true, c, rem).finish()
    }

    /// The same model on a *mixed-degree* table: its `n` parameters keep weight 1, and
    /// every parameter added later (by an operation with a model in more parameters, or
    /// [`Tm::param`]) weighs `lw` toward the order, so that with `lw = order` it enters
    /// the polynomials linearly only. Symbolic remainders (the parameters a flow lifts
    /// its interval remainders to) then cost a coefficient each instead of a share of
    /// every monomial of the order: at order 3 with 6 weight-1 and 20 lifted parameters
    /// the table has 104 monomials instead of 3,654. `lw = 1` gives the classic table.
    pub fn with_lifted_weight(self, lw: u32) -> Tm {
        let t = table_mixed(self.t.n, self.t.order, self.t.n, lw);
        let fixed = self.fixed;
        self.into_table(t, fixed)
    }

    /// The number of weight-1 parameters of a mixed-degree model (see
    /// [`Tm::with_lifted_weight`]); `None` for a classic one.
    pub fn full_params(&self) -> Option<usize> {
        self.t.is_mixed().then_some(self.t.full)
    }

    /// The parameter `xi_k` (`k < n`) as a model in `n` parameters with this model's
    /// order and weights (a mixed-degree model's new parameters weigh as it says).
    pub fn param(&self, k: usize, n: usize) -> Tm {
        assert!(k < n, "Tm::param: parameter {k} out of {n}");
        let mut coef = vec![0.0; n];
        coef[k] = 1.0;
        Tm::affine_on(
            table_mixed(n, self.t.order, self.t.full, self.t.lw),
            0.0,
            &coef,
        )
    }

    /// `cst + sum_k coef[k] xi_k` in `n = coef.len()` parameters of order `order`, with
    /// this model's parameter weights: on a mixed-degree model, the same weight-1
    /// parameters and lifted weight ([`Tm::with_lifted_weight`]); on a classic one, a
    /// classic table, as [`Tm::affine`].
    ///
    /// Models built beside mixed-degree ones (the network's outputs over the states, a
    /// zero input) must be made so: a classic table in all the lifted parameters has
    /// every monomial of the order in them (249,900 at order 4 in 47 parameters, where
    /// the mixed table has 2,219), and building it took seconds that no deadline saw.
    pub fn affine_like(&self, cst: f64, coef: &[f64], order: u32) -> Tm {
        let n = coef.len();
        Tm::affine_on(
            table_mixed(n, order, self.t.full.min(n), self.t.lw),
            cst,
            coef,
        )
    }

    /// The constant `c` in `n` parameters of order `order` with this model's parameter
    /// weights ([`Tm::affine_like`]; [`Tm::constant`] for a classic model).
    pub fn constant_like(&self, c: f64, n: usize, order: u32) -> Tm {
        Tm::constant_on(
            table_mixed(n, order, self.t.full.min(n), self.t.lw),
            true,
            c,
        )
    }

    /// A model without parameters whose value is any point of `i` (like [`Scalar::cst`],
    /// it adopts the order of the models it is combined with). An interval with a NaN
    /// end gives the entire model.
    pub fn from_interval(i: Interval) -> Tm {
        Tm::from_interval_on(table(0, 0), false, i)
    }

    /// Adds `r` to the remainder (interval sum, outward rounded).
    pub fn with_rem(mut self, r: Interval) -> Tm {
        self.rem = iadd(self.rem, r);
        self.lo = sum_dn(self.lo, r.lo);
        // The coefficients are unchanged (finite, by the invariant).
        self.finish_rem()
    }

    /// The model split into its polynomial part (remainder zero) and its remainder:
    /// `self = poly + rem` exactly, so a caller can give the remainder a parameter of
    /// its own (a symbolic remainder) instead of an interval.
    pub fn split_rem(mut self) -> (Tm, Interval) {
        let r = self.rem;
        self.rem = Interval::point(0.0);
        self.lo = f64::NEG_INFINITY;
        (self, r)
    }

    /// The remainder interval.
    pub fn rem(&self) -> Interval {
        self.rem
    }

    /// Number of parameters `n`.
    pub fn n_vars(&self) -> usize {
        self.t.n
    }

    /// The order (largest total degree of the polynomial part). Models without an
    /// explicit order (from [`Scalar::cst`], [`Tm::from_interval`]) report 0.
    pub fn order(&self) -> u32 {
        self.t.order
    }

    /// Range bound of the polynomial terms with index `>= start` (without the constant
    /// term, which is added exactly by the caller).
    ///
    /// The magnitudes are summed in round-to-nearest with each addition's exact error
    /// kept aside by TwoSum (the odd terms in four lanes, the even ones by sign; no
    /// directed rounding: this is the hot loop of every product with a remainder). The exact sum is
    /// the float sum plus the errors; their magnitudes, summed in float, are raised by
    /// the a-priori bound of recursive summation of `n` nonnegative terms (the float sum
    /// `e~` of exact sum `e` has `e <= e~ / (1 - gamma_n) <= e~ (1 + 4 (n + 2) eps)`;
    /// Higham, "Accuracy and Stability of Numerical Algorithms", 2nd ed., section 4.2).
    /// Exact sums stay exact (every error is 0). A NaN coefficient gives the entire line.
    fn poly_range_from(&self, start: usize, c0: f64) -> Interval {
        let whole = start <= 1;
        if whole {
            let [sn, sp] = self.ext.get();
            if !sn.is_nan() {
                #[cfg(debug_assertions)]
                self.check_kept_extent([sn, sp], start);
                return Tm::range_of(c0, sn, sp);
            }
        }
        let [sn, sp] = self.extent_from(start);
        if whole {
            self.ext.set([sn, sp]);
        }
        Tm::range_of(c0, sn, sp)
    }

    /// Debug builds (every test): one kept extent in 16 read is recomputed from the
    /// coefficients and must agree bit for bit, so that an operation added later that
    /// changes a coefficient without resetting [`Tm::ext`] (a stale, unsound range)
    /// fails the tests that use it instead of passing unnoticed. One in 16 keeps the
    /// tests' cost near the release build's (the kept ranges save 6-9 % of the
    /// six-state cell; `bench/reach/cell_cost.md`).
    #[cfg(debug_assertions)]
    fn check_kept_extent(&self, kept: [f64; 2], start: usize) {
        if recheck_now(Recheck::Extent) {
            let fresh = self.extent_from(start);
            assert!(
                fresh[0].to_bits() == kept[0].to_bits() && fresh[1].to_bits() == kept[1].to_bits(),
                "a Taylor model's kept range {kept:?} is stale (its coefficients give {fresh:?}): an operation changed a coefficient without resetting Tm::ext"
            );
        }
    }

    /// `c0` plus the extents `[-sn, sp]`, outward.
    fn range_of(c0: f64, sn: f64, sp: f64) -> Interval {
        if sn == 0.0 && sp == 0.0 {
            return Interval::point(c0);
        }
        Interval {
            lo: sum_dn(c0, -sn),
            hi: sum_up(c0, sp),
        }
    }

    /// Upward bounds `[sn, sp]` of the downward and upward extent over the box of the
    /// terms with index `>= start` (at least 1; `[inf, inf]` where a coefficient is NaN).
    fn extent_from(&self, start: usize) -> [f64; 2] {
        #[inline(always)]
        fn acc(s: &mut f64, err: &mut f64, a: f64) {
            let t = *s + a;
            let bb = t - *s;
            *err += ((*s - (t - bb)) + (a - bb)).abs();
            *s = t;
        }
        // The odd terms (nearly all of a dense model's) in four lanes by index, so that
        // consecutive terms do not wait for each other's sum (a chain of dependent
        // TwoSums was 4 cycles a term); the even ones by sign in one sum each. The
        // lanes are then summed by TwoSum too, their errors kept with the others'.
        let (mut odd, mut eo) = ([0.0f64; 4], [0.0f64; 4]);
        let (mut pos, mut neg) = (0.0f64, 0.0f64);
        let (mut ep, mut en) = (0.0f64, 0.0f64);
        let from = start.max(1).min(self.t.len());
        let (c, even) = (&self.c[from..], &self.t.even[from..self.t.len()]);
        let (cq, eq) = (c.chunks_exact(4), even.chunks_exact(4));
        let (ct, et) = (cq.remainder(), eq.remainder());
        for (cv, ev) in cq.zip(eq) {
            for l in 0..4 {
                let (v, a) = (cv[l], cv[l].abs());
                if !ev[l] {
                    acc(&mut odd[l], &mut eo[l], a);
                } else if v > 0.0 {
                    acc(&mut pos, &mut ep, a);
                } else {
                    // NaN lands here too and makes the range entire below.
                    acc(&mut neg, &mut en, a);
                }
            }
        }
        for (&v, &e) in ct.iter().zip(et) {
            let a = v.abs();
            if !e {
                acc(&mut odd[0], &mut eo[0], a);
            } else if v > 0.0 {
                acc(&mut pos, &mut ep, a);
            } else {
                acc(&mut neg, &mut en, a);
            }
        }
        let mut ec = 0.0f64;
        let (mut s01, mut s23) = (odd[0], odd[2]);
        acc(&mut s01, &mut ec, odd[1]);
        acc(&mut s23, &mut ec, odd[3]);
        acc(&mut s01, &mut ec, s23);
        let (odd, eo) = (s01, ((eo[0] + eo[1]) + (eo[2] + eo[3])) + ec);
        if odd.is_nan() || pos.is_nan() || neg.is_nan() {
            return [f64::INFINITY, f64::INFINITY];
        }
        // `n` terms and three sums of lanes: at most `n + 3` errors summed.
        let n = self.c.len() - from + 3;
        let raise = 1.0 + 4.0 * (n as f64 + 2.0) * f64::EPSILON;
        // Upper bound of a sum from its float value and its errors' magnitudes.
        let lift = |s: f64, err: f64| {
            if !s.is_finite() || err == 0.0 {
                s
            } else if err.is_nan() {
                f64::INFINITY
            } else {
                sum_up(s, up(err * raise))
            }
        };
        let (odd, pos, neg) = (lift(odd, eo), lift(pos, ep), lift(neg, en));
        [sum_up(odd, neg), sum_up(odd, pos)]
    }

    /// Range of the polynomial part over the box (without the remainder).
    fn poly_range(&self) -> Interval {
        self.poly_range_from(1, self.c[0])
    }

    /// A sound range of the model over the box: the polynomial's range (monomial-wise,
    /// `[0, 1]` for monomials with all exponents even) plus the remainder.
    pub fn bound(&self) -> Interval {
        let p = self.poly_range();
        let b = iadd(p, self.rem);
        if self.lo > b.lo {
            Interval {
                lo: self.lo.min(b.hi),
                hi: b.hi,
            }
        } else {
            b
        }
    }

    /// `(constant coefficient, degree-1 coefficients)`; the vector has length `n` (zeros
    /// for an order-0 model).
    pub fn linear_part(&self) -> (f64, Vec<f64>) {
        let n = self.t.n;
        let lin = if self.t.order >= 1 {
            self.c[1..=n].to_vec()
        } else {
            vec![0.0; n]
        };
        (self.c[0], lin)
    }

    /// A sound range of `self - constant - linear terms` over the box: the terms of
    /// degree `>= 2` plus the remainder.
    pub fn nonlinear_bound(&self) -> Interval {
        let start = if self.t.order >= 1 { self.t.n + 1 } else { 1 };
        iadd(self.poly_range_from(start, 0.0), self.rem)
    }

    /// A sound enclosure of the model's value at the parameter point `xi` (length `n`):
    /// `p(xi)` in outward-rounded interval arithmetic, plus the remainder.
    pub fn eval_at(&self, xi: &[f64]) -> Interval {
        let n = self.t.n;
        assert!(
            xi.len() >= n,
            "Tm::eval_at: {} coordinates for {n} parameters",
            xi.len()
        );
        let ord = self.t.order as usize;
        let w = ord + 1;
        let mut pw = vec![Interval::point(1.0); n * w];
        for k in 0..n {
            for e in 1..=ord {
                pw[k * w + e] = pw[k * w + e - 1] * Interval::point(xi[k]);
            }
        }
        let mut acc = Interval::point(0.0);
        for i in 0..self.t.len() {
            let v = self.c[i];
            if v == 0.0 {
                continue;
            }
            let mut m = Interval::point(v);
            for (k, &e) in self.t.exps(i).iter().enumerate() {
                if e > 0 {
                    m = m * pw[k * w + e as usize];
                }
            }
            acc = acc + m;
        }
        acc + self.rem
    }

    /// Number of monomials of the model's table (constant, then the degree-1 ones
    /// `xi_0 .. xi_{n-1}`, then higher degrees in graded order): the range of the
    /// indices [`Tm::coef`], [`Tm::term`] and [`Tm::term_degree`] take.
    pub fn n_terms(&self) -> usize {
        self.t.len()
    }

    /// The coefficient of monomial `i` (see [`Tm::n_terms`]).
    pub fn coef(&self, i: usize) -> f64 {
        self.c[i]
    }

    /// Total degree of monomial `i`.
    pub fn term_degree(&self, i: usize) -> u32 {
        self.t.deg[i]
    }

    /// Whether every exponent of monomial `i` is even (its range over the box is
    /// `[0, 1]` instead of `[-1, 1]`).
    pub fn term_even(&self, i: usize) -> bool {
        self.t.even[i]
    }

    /// Monomial `i` of this model's table as a model of its own (coefficient 1, no
    /// remainder): with [`Tm::coef`], a caller can treat a model's higher-order terms as
    /// extra variables and substitute them back exactly.
    pub fn term(&self, i: usize) -> Tm {
        let mut c = vec![0.0; self.t.len()];
        c[i] = 1.0;
        let mut m = Tm::raw(self.t, true, c, Interval::point(0.0));
        if self.t.even[i] {
            m.lo = 0.0;
        }
        m
    }

    /// `cst + sum a * m_i` over `terms = [(i, a), ..]` on this model's table (`m_i` its
    /// monomials, each index at most once, `i >= 1`), remainder zero: the coefficients
    /// are placed as given, so the result is exact.
    ///
    /// # Panics
    /// If an index is 0, out of range or repeated.
    pub fn from_terms(&self, cst: f64, terms: &[(usize, f64)]) -> Tm {
        let mut c = vec![0.0; self.t.len()];
        let mut seen = vec![false; self.t.len()];
        c[0] = cst;
        for &(i, a) in terms {
            assert!(
                i >= 1 && i < c.len() && !seen[i],
                "Tm::from_terms: bad or repeated index {i}"
            );
            seen[i] = true;
            c[i] = a;
        }
        Tm::raw(self.t, true, c, Interval::point(0.0)).finish()
    }

    /// The same model at a lower order `order` (same parameters and weights): the terms
    /// past it are bounded into the remainder (`[0, |c|]`-style for even monomials).
    /// An order at or above the model's own, or a model without an order of its own,
    /// gives the model unchanged.
    pub fn with_order(self, order: u32) -> Tm {
        if !self.fixed || order >= self.t.order {
            return self;
        }
        let t = table_mixed(self.t.n, order, self.t.full, self.t.lw);
        self.into_table(t, true)
    }

    /// This model on `other`'s table when `other` has at least its parameters and at
    /// least its order (exact: every monomial is there); otherwise unchanged. Lets a
    /// sum of a low-order and a high-order model keep the high order (binary operations
    /// take the smaller order).
    pub fn raised_to(self, other: &Tm) -> Tm {
        if !self.fixed
            || !other.fixed
            || std::ptr::eq(self.t, other.t)
            || self.t.n > other.t.n
            || self.t.order > other.t.order
        {
            return self;
        }
        self.into_table(other.t, true)
    }

    /// Puts every model with an explicit order on the one table their binary operations
    /// would meet on (the most parameters, the smallest order, mixed weights winning),
    /// where that move is exact: a model with a nonzero term the table lacks (a higher
    /// order, or a monomial past the table's weights) is left as it is, so no model
    /// loses a term here. Models without an order of their own are left as they are. A
    /// flow whose held inputs carry one more parameter than its states (a lifted
    /// network error) then converts each state once per period instead of at every
    /// operation of every step.
    pub fn share_table(ms: &mut [Tm]) {
        let Some((t, _)) = ms
            .iter()
            .filter(|m| m.fixed)
            .map(|m| (m.t, true))
            .reduce(common_of)
        else {
            return;
        };
        // The common table has the most parameters, so every model converts onto it.
        for m in ms.iter_mut().filter(|m| m.fixed && !std::ptr::eq(m.t, t)) {
            let exact = conversion(m.t, t)
                .dropped
                .iter()
                .all(|&i| m.c[i as usize] == 0.0);
            if exact {
                *m = std::mem::replace(m, Tm::cst(0.0)).into_table(t, true);
            }
        }
    }

    /// Whether `self` and `other` have the same parameters and order (one monomial
    /// table), so that their coefficients line up index by index.
    pub fn same_basis(&self, other: &Tm) -> bool {
        std::ptr::eq(self.t, other.t)
    }

    /// Per parameter `k`, the sum of `|c|` over the monomials that contain `xi_k`: how
    /// much of the model's range depends on it (the weight by which order reduction
    /// chooses the parameters to keep, as Girard's reduction ranks a zonotope's
    /// generators by their norms; Girard, HSCC 2005).
    pub fn param_weights(&self) -> Vec<f64> {
        let n = self.t.n;
        let mut w = vec![0.0; n];
        for i in 1..self.t.len() {
            let v = self.c[i].abs();
            if v == 0.0 {
                continue;
            }
            for &k in self.t.vars_of(i) {
                w[k as usize] += v;
            }
        }
        w
    }

    /// The model with its parameters renumbered: parameter `k` becomes `map[k]` of `n`
    /// new ones (kept at the same order), or is dropped when `map[k]` is `None`. Every
    /// monomial containing a dropped parameter is bounded over the box (`[0, |c|]`-style
    /// for even monomials, `[-|c|, |c|]` otherwise) and added to the remainder, so the
    /// result contains the model for every value of the dropped parameters: the
    /// order-reduction step of Taylor-model flows (the dropped dependence becomes an
    /// interval, as a zonotope's reduced generators become a box).
    pub fn reparam(&self, map: &[Option<usize>], n: usize) -> Tm {
        assert!(
            map.len() >= self.t.n,
            "Tm::reparam: {} entries for {} parameters",
            map.len(),
            self.t.n
        );
        let mut seen = vec![false; n];
        for j in map.iter().take(self.t.n).flatten() {
            assert!(*j < n, "Tm::reparam: parameter {j} out of {n}");
            assert!(!seen[*j], "Tm::reparam: two parameters map to {j}");
            seen[*j] = true;
        }
        let t = table_mixed(n, self.t.order, self.t.full, self.t.lw);
        let to = renumbering(self.t, t, &map[..self.t.n]);
        let mut c = vec![0.0; t.len()];
        c[0] = self.c[0];
        let (mut sn, mut sp) = (0.0, 0.0);
        for i in 1..self.t.len() {
            let v = self.c[i];
            if v == 0.0 {
                continue;
            }
            match to[i] {
                // Two old monomials never meet in one new one (the map is injective on
                // kept parameters), so this is a copy, not a sum.
                idx if idx != u32::MAX => c[idx as usize] = v,
                _ => acc_range(v, self.t.even[i], &mut sn, &mut sp),
            }
        }
        let rem = Interval {
            lo: sum_dn(self.rem.lo, -sn),
            hi: sum_up(self.rem.hi, sp),
        };
        let mut out = Tm::raw(t, self.fixed, c, rem).finish();
        out.lo = self.lo;
        out
    }

    /// This model on table `t` (more parameters and/or lower order); terms above the new
    /// order are bounded into the remainder.
    fn convert(&self, t: &'static Table, fixed: bool) -> Cow<'_, Tm> {
        if std::ptr::eq(self.t, t) {
            if self.fixed == fixed {
                return Cow::Borrowed(self);
            }
            let mut r = self.clone();
            r.fixed = fixed;
            return Cow::Owned(r);
        }
        debug_assert!(self.t.n <= t.n);
        // Kept for lowerings on the same parameters and weights (`Drops`).
        let slot = (t.n == self.t.n
            && t.full == self.t.full
            && t.lw == self.t.lw
            && t.order < self.t.order
            && (1..=DROP_SLOTS as u32).contains(&t.order))
        .then_some(t.order);
        if let (Some(k), true) = (slot, fixed) {
            if let Some(m) = self.drops.lowered(k, self.lowering_key()) {
                #[cfg(debug_assertions)]
                self.check_kept_lowered(m);
                return Cow::Borrowed(m);
            }
        }
        let map = conversion(self.t, t);
        let mut c = vec![0.0; t.len()];
        for &(i, j) in &map.kept {
            c[j as usize] = self.c[i as usize];
        }
        let kept = slot.and_then(|k| self.drops.get(k));
        let [sn, sp] = match kept {
            Some((dropped, _)) => {
                #[cfg(debug_assertions)]
                self.check_kept_drops(dropped, &map);
                dropped
            }
            None => Tm::dropped_extent(self, &map),
        };
        let mut rem = self.rem;
        if sn != 0.0 || sp != 0.0 {
            rem = rem + Interval { lo: -sn, hi: sp };
        }
        // The coefficients are copies of this (valid) model's: only the remainder can
        // break the invariant.
        let mut out = Tm::raw(t, fixed, c, rem).finish_rem();
        out.lo = self.lo;
        match (slot, kept) {
            // The lowered model's range, as its own `extent_from` gave it the first time
            // (a lowered operand's range is read by every product where the other
            // operand has a remainder).
            (Some(_), Some((_, lowered))) => out.ext.set(lowered),
            (Some(k), None) => {
                let lowered = out.extent_from(1);
                out.ext.set(lowered);
                self.drops.set(k, [sn, sp], lowered);
            }
            _ => {}
        }
        match (slot, fixed) {
            (Some(k), true) => self.drops.keep_lowered(k, out, self.lowering_key()),
            _ => Cow::Owned(out),
        }
    }

    /// What a lowered model takes from its source besides the non-constant
    /// coefficients (whose changes [`Tm::touch`] sees): the constant coefficient, the
    /// remainder and the lower bound, as bits.
    fn lowering_key(&self) -> [u64; 4] {
        [
            self.c[0].to_bits(),
            self.rem.lo.to_bits(),
            self.rem.hi.to_bits(),
            self.lo.to_bits(),
        ]
    }

    /// Debug builds: one kept lowered model in 16 used is lowered again and must agree
    /// bit for bit (coefficients, remainder, lower bound).
    #[cfg(debug_assertions)]
    fn check_kept_lowered(&self, kept: &Tm) {
        if recheck_now(Recheck::Lowered) {
            let map = conversion(self.t, kept.t);
            let mut c = vec![0.0; kept.t.len()];
            for &(i, j) in &map.kept {
                c[j as usize] = self.c[i as usize];
            }
            let [sn, sp] = self.dropped_extent(&map);
            let mut rem = self.rem;
            if sn != 0.0 || sp != 0.0 {
                rem = rem + Interval { lo: -sn, hi: sp };
            }
            let fresh = Tm::raw(kept.t, true, c, rem).finish_rem();
            let eq = |x: f64, y: f64| x.to_bits() == y.to_bits();
            assert!(
                eq(fresh.rem.lo, kept.rem.lo)
                    && eq(fresh.rem.hi, kept.rem.hi)
                    && eq(self.lo, kept.lo)
                    && fresh.c.iter().zip(&kept.c).all(|(&x, &y)| eq(x, y)),
                "a Taylor model's kept lowering is stale: an operation changed a coefficient without Tm::touch"
            );
        }
    }

    /// Upward bounds `[sn, sp]` of the downward and upward extent of the terms a
    /// conversion `map` drops (past the target's weighted order): summed in
    /// round-to-nearest and raised by the a-priori bound of recursive summation of
    /// nonnegative terms (as in `poly_range_from`; a NaN gives `+inf`).
    fn dropped_extent(&self, map: &Conversion) -> [f64; 2] {
        let (mut odd, mut pos, mut neg) = (0.0f64, 0.0f64, 0.0f64);
        for &i in &map.dropped {
            let v = self.c[i as usize];
            if !self.t.even[i as usize] {
                odd += v.abs();
            } else if v > 0.0 {
                pos += v;
            } else {
                neg -= v;
            }
        }
        let raise = 1.0 + 4.0 * (map.dropped.len() as f64 + 2.0) * f64::EPSILON;
        // `up` of a NaN is +inf; an exact zero stays zero (nothing dropped).
        let lift = |v: f64| if v == 0.0 { 0.0 } else { up(v * raise) };
        let (odd, pos, neg) = (lift(odd), lift(pos), lift(neg));
        let sp = if pos == 0.0 { odd } else { up(odd + pos) };
        let sn = if neg == 0.0 { odd } else { up(odd + neg) };
        [sn, sp]
    }

    /// Debug builds: one kept dropped extent in 16 used is recomputed and must agree
    /// bit for bit (as [`Tm::check_kept_extent`] for the polynomial's range).
    #[cfg(debug_assertions)]
    fn check_kept_drops(&self, kept: [f64; 2], map: &Conversion) {
        if recheck_now(Recheck::Drops) {
            let fresh = self.dropped_extent(map);
            assert!(
                fresh[0].to_bits() == kept[0].to_bits() && fresh[1].to_bits() == kept[1].to_bits(),
                "a Taylor model's kept dropped extent {kept:?} is stale (its coefficients give {fresh:?}): an operation changed a coefficient without Tm::touch"
            );
        }
    }

    fn into_table(self, t: &'static Table, fixed: bool) -> Tm {
        if std::ptr::eq(self.t, t) {
            Tm { fixed, ..self }
        } else {
            self.convert(t, fixed).into_owned()
        }
    }

    /// `self + s * o` for `s = +-1`.
    fn add_signed(self, o: &Tm, s: f64) -> Tm {
        let (t, fixed) = common(&self, o);
        let mut a = self.into_table(t, fixed);
        let b = o.convert(t, fixed);
        // Each inexact sum is off by at most u |z| (Higham (2.5)); their magnitudes are
        // summed plainly and bounded once ([`nonneg_sum_bound`]).
        let (mut sa, mut cnt) = (0.0, 0usize);
        a.touch();
        for (x, &y) in a.c.iter_mut().zip(&b.c) {
            if y != 0.0 {
                let z = *x + s * y;
                if *x != 0.0 {
                    sa += z.abs();
                    cnt += 1;
                }
                *x = z;
            }
        }
        // Every coefficient is finite when the magnitudes of the changed ones summed to
        // a finite number (the others are an operand's), so only the remainder needs
        // the invariant's check then.
        let finite = sa.is_finite();
        let sa = nonneg_sum_bound(sa, cnt);
        let br = if s > 0.0 { b.rem } else { -b.rem };
        a.rem = iadd(a.rem, br);
        if sa != 0.0 {
            a.rem = a.rem + sym(up(sa * U));
        }
        // The sum of two values is at least the sum of their lower bounds.
        a.lo = if s > 0.0 {
            sum_dn(a.lo, b.lo)
        } else {
            f64::NEG_INFINITY
        };
        if finite {
            a.finish_rem()
        } else {
            a.finish()
        }
    }

    /// `s * self` for a float `s`.
    fn scale(mut self, s: f64) -> Tm {
        if s == 1.0 {
            return self;
        }
        let (mut sa, mut cnt) = (0.0, 0usize);
        self.touch();
        for v in self.c.iter_mut() {
            if *v != 0.0 {
                *v *= s;
                sa += v.abs();
                cnt += 1;
            }
        }
        // Finite magnitudes: every (nonzero) coefficient is finite.
        let finite = sa.is_finite();
        let sa = nonneg_sum_bound(sa, cnt);
        self.rem = self.rem * s;
        if cnt > 0 && (s.abs() != 1.0 && s != 0.0) {
            self.rem = self.rem + sym(up(up(sa * U) + cnt as f64 * ETA));
        }
        self.lo = if s >= 0.0 && self.lo.is_finite() {
            (Interval::point(self.lo) * s).lo
        } else {
            f64::NEG_INFINITY
        };
        if finite {
            self.finish_rem()
        } else {
            self.finish()
        }
    }

    /// `self / s` for a float `s`.
    fn div_f64(mut self, s: f64) -> Tm {
        let (mut sa, mut cnt) = (0.0, 0usize);
        self.touch();
        for v in self.c.iter_mut() {
            if *v != 0.0 {
                *v /= s;
                sa += v.abs();
                cnt += 1;
            }
        }
        // Finite magnitudes: every (nonzero) coefficient is finite.
        let finite = sa.is_finite();
        let sa = nonneg_sum_bound(sa, cnt);
        self.rem = self.rem / s;
        if cnt > 0 && s.abs() != 1.0 {
            self.rem = self.rem + sym(up(up(sa * U) + cnt as f64 * ETA));
        }
        self.lo = if s > 0.0 && self.lo.is_finite() {
            (Interval::point(self.lo) / s).lo
        } else {
            f64::NEG_INFINITY
        };
        if finite {
            self.finish_rem()
        } else {
            self.finish()
        }
    }

    /// `self + s` for a float `s`.
    fn add_f64(mut self, s: f64) -> Tm {
        let x = self.c[0];
        let z = x + s;
        self.c[0] = z;
        if x != 0.0 && s != 0.0 {
            self.rem = self.rem + sym(up(z.abs() * U));
        }
        self.lo = sum_dn(self.lo, s);
        self.finish()
    }

    /// The product of two models (references; the result on the common table).
    fn mul_ref(a: &Tm, b: &Tm) -> Tm {
        let (t, fixed) = common(a, b);
        Tm::mul_on(a, b, t, fixed)
    }

    /// The product of two models on table `t` (the common table, or one of the same
    /// parameters and weights and a lower order: the operands are lowered to it first,
    /// their dropped terms bounded into their remainders).
    fn mul_on(a: &Tm, b: &Tm, t: &'static Table, fixed: bool) -> Tm {
        if a.t.len() == 1 {
            return Tm::mul_const(b.convert(t, fixed).into_owned(), a.c[0], a.rem);
        }
        if b.t.len() == 1 {
            return Tm::mul_const(a.convert(t, fixed).into_owned(), b.c[0], b.rem);
        }
        let a = a.convert(t, fixed);
        let b = b.convert(t, fixed);
        let len = t.len();
        let (kept, trunc, pairs) = Tm::bound_sums(&a, &b, t);
        // Row 0 (`a_0` times every `b_j`, at index `j`) is the first addition into
        // every coefficient: `0 + a_0 b_j`, made here with the vector.
        let a0 = a.c[0];
        let mut r: Vec<f64> = if a0 != 0.0 {
            b.c[..len].iter().map(|&bj| 0.0 + a0 * bj).collect()
        } else {
            vec![0.0; len]
        };
        Tm::scatter(&mut r, &a, &b, t, false);
        let err = up(up(t.gamma * kept) + 2.0 * pairs as f64 * ETA);
        let mut rem = sym(up(err + trunc));
        // Each operand's polynomial range only where the other has a remainder.
        if !is_zero(&a.rem) {
            rem = rem + a.rem * b.poly_range() + a.rem * b.rem;
        }
        if !is_zero(&b.rem) {
            rem = rem + b.rem * a.poly_range();
        }
        // Every coefficient is at most the sum of its pairs' |a_i b_j|, so at most
        // `kept` (up to the rounding of the sums), which bounds them all: when it is
        // far from overflow, no coefficient can be infinite or NaN (the operands'
        // are finite), and only the remainder needs the invariant's check.
        if kept < f64::MAX / 4.0 {
            if has_nan(&rem) {
                return Tm::entire_on(t, fixed);
            }
            return Tm::raw(t, fixed, r, rem);
        }
        Tm::raw(t, fixed, r, rem).finish()
    }

    /// The sums of `|c_i|` and the nonzero `c_i` by weighted degree (`order + 1`
    /// entries, [`WSum`]): the non-constant terms' kept in the model (they depend on
    /// the non-constant coefficients only, as [`Tm::ext`]), the constant's (weighted
    /// degree 0, the only monomial of it) from `c_0`.
    fn wsums(&self) -> (&[WSum], WSum) {
        let kept = self.wsums.get_or_init(|| self.wsums_fresh().into());
        #[cfg(debug_assertions)]
        self.check_kept_wsums(kept);
        let c0 = self.c[0];
        let w0 = WSum {
            sum: c0.abs(),
            nz: (c0 != 0.0) as usize,
        };
        (kept, w0)
    }

    /// [`Tm::wsums`] computed from the coefficients: four lanes (`j mod 4`, the last
    /// `len mod 4` terms in lane 0), each summed in index order from the table's lists
    /// of each weighted degree's monomials by lane ([`Table::wl`]), the four lanes side
    /// by side; the constant's entry left to the reader.
    fn wsums_fresh(&self) -> Vec<WSum> {
        let t = self.t;
        let ord = t.order as usize;
        let c = &self.c[..t.len()];
        let mut out = vec![WSum { sum: 0.0, nz: 0 }; ord + 1];
        for (d, o) in out.iter_mut().enumerate().skip(1) {
            let g = |l: usize| &t.wl[t.wls[d * 4 + l]..t.wls[d * 4 + l + 1]];
            let gs = [g(0), g(1), g(2), g(3)];
            let m = gs.iter().map(|x| x.len()).min().unwrap_or(0);
            let (mut s, mut nz) = ([0.0f64; 4], [0usize; 4]);
            for q in 0..m {
                for l in 0..4 {
                    let v = c[gs[l][q] as usize];
                    s[l] += v.abs();
                    nz[l] += (v != 0.0) as usize;
                }
            }
            for l in 0..4 {
                for &j in &gs[l][m..] {
                    let v = c[j as usize];
                    s[l] += v.abs();
                    nz[l] += (v != 0.0) as usize;
                }
            }
            *o = WSum {
                sum: (s[0] + s[1]) + (s[2] + s[3]),
                nz: (nz[0] + nz[1]) + (nz[2] + nz[3]),
            };
        }
        out
    }

    /// Debug builds: one kept [`Tm::wsums`] in 16 read is recomputed and must agree bit
    /// for bit (but the constant's entry, which the reader takes from `c_0`).
    #[cfg(debug_assertions)]
    fn check_kept_wsums(&self, kept: &[WSum]) {
        if recheck_now(Recheck::Wsums) {
            let fresh = self.wsums_fresh();
            let same = fresh.len() == kept.len()
                && fresh
                    .iter()
                    .zip(kept)
                    .skip(1)
                    .all(|(a, b)| a.sum.to_bits() == b.sum.to_bits() && a.nz == b.nz);
            assert!(
                same,
                "a Taylor model's kept sums by weighted degree are stale: an operation changed a coefficient without Tm::touch"
            );
        }
    }

    /// The error sums of the product of `a` and `b` on their table `t`: upper bounds of
    /// `sum |a_i b_j|` over the pairs kept (`wdeg_i + wdeg_j <= order`) and over the
    /// pairs truncated, and the number of pairs kept (nonzero `a_i` only).
    fn bound_sums(a: &Tm, b: &Tm, t: &'static Table) -> (f64, f64, usize) {
        let len = t.len();
        let ord = t.order as usize;
        // Upward sums of |b_j| by degree, then by degree <= d and >= d, from the sums of
        // |b_j| and |a_i| by weighted degree each model keeps ([`Tm::wsums`]: four
        // partial sums per degree, bounded once here, [`nonneg_sum_bound`], `len`
        // terms at most, instead of rounding up after every term). An operand of
        // several products (a series' coefficient in every later order's convolution,
        // the argument of a Horner sum) is summed once.
        const W: usize = MAX_ORDER as usize + 2;
        let ((wa, a0), (wb, b0)) = (a.wsums(), b.wsums());
        let at = |w: &[WSum], w0: WSum, d: usize| if d == 0 { w0 } else { w[d] };
        let mut le = [0.0f64; W];
        let mut ge = [0.0f64; W];
        for d in 0..=ord {
            le[d] = nonneg_sum_bound(at(wb, b0, d).sum, len);
        }
        ge[..=ord].copy_from_slice(&le[..=ord]);
        for d in 1..=ord {
            le[d] = up(le[d] + le[d - 1]);
        }
        for d in (0..ord).rev() {
            ge[d] = up(ge[d] + ge[d + 1]);
        }
        // The bound sums `sum_i |a_i| le[keep_i]` and `sum_i |a_i| ge[keep_i + 1]`
        // (`keep_i = ord - wdeg_i`) by weighted degree: the sums of |a_i| of each
        // weighted degree (four lanes, each bounded once, [`nonneg_sum_bound`]) times
        // the `le` and `ge` of their rows, summed and bounded once
        // ([`nonneg_dot_bound`], `ord + 1` products), so no chain of dependent
        // additions runs through every row; and the pairs of the rows of nonzero
        // `a_i` (their count by weighted degree times the rows' length).
        let (mut kept, mut trunc, mut pairs) = (0.0f64, 0.0f64, 0usize);
        for d in 0..=ord {
            let WSum { sum, nz } = at(wa, a0, d);
            if nz == 0 {
                continue;
            }
            let ad = nonneg_sum_bound(sum, len);
            kept += ad * le[ord - d];
            if d > 0 {
                trunc += ad * ge[ord - d + 1];
            }
            pairs += nz * t.rowlen[d];
        }
        let kept = nonneg_dot_bound(kept, ord + 1);
        let trunc = nonneg_dot_bound(trunc, ord + 1);
        (kept, trunc, pairs)
    }

    /// Adds the kept pairs `a_i b_j` of the product of `a` and `b` on their table `t`
    /// into `r` (`t.len()` entries), row 0 (`a_0 b_j`) too when `row0`.
    fn scatter(r: &mut [f64], a: &Tm, b: &Tm, t: &'static Table, row0: bool) {
        let len = t.len();
        // The products, in the order of additions of the row-by-row scatter (so the
        // same numbers): row 0 (`a_0` times every `b_j`, at index `j`: the first
        // addition into each coefficient) as one contiguous pass; the rows of
        // `Table::scat` (the others have no partner but the constant) in index order;
        // and the first pair of every other row (`a_i b_0`, at index `i`,
        // [`Table::build`] checks both) after all rows, where it is the last addition
        // into coefficient `i`, since every other pair landing there has a divisor of
        // `m_i`, of a lower degree, so an earlier row. At order 4 with 36 lifted
        // parameters the first and last are 3,400 of the 11,000 pairs, and at order 2
        // (the later time coefficients under the joint degree) most of them.
        let (ac, bc) = (&a.c[..len], &b.c[..len]);
        let wd = &t.wdeg[..len];
        let a0 = ac[0];
        let b0 = bc[0];
        // Local slices: the scatter's stores cannot alias them, so the loops keep their
        // pointers in registers instead of reloading them through `a` and `b`.
        let rr = &mut r[..len];
        if row0 && a0 != 0.0 {
            for (x, &bj) in rr.iter_mut().zip(bc) {
                *x += a0 * bj;
            }
        }
        let (mul, part, rowv) = (&t.mul[..], &t.part[..], &t.row[..]);
        for &i in &t.scat {
            let i = i as usize;
            let ai = ac[i];
            if ai == 0.0 {
                continue;
            }
            if part.is_empty() {
                let m = t.rowlen[wd[i] as usize];
                let row = &mul[rowv[i] + 1..rowv[i] + m];
                for (&bj, &k) in bc[1..m].iter().zip(row) {
                    rr[k as usize] += ai * bj;
                }
            } else {
                let (s, e) = (rowv[i] + 1, rowv[i + 1]);
                for (&j, &k) in part[s..e].iter().zip(&mul[s..e]) {
                    rr[k as usize] += ai * bc[j as usize];
                }
            }
        }
        // Without a test of `a_i`: a zero `a_i` adds `+-0`, which leaves every sum as it
        // is, since no sum here is `-0` (each starts as `0 + a_0 b_k` or `+0`, and a sum
        // is `-0` only when both terms are); so the pass vectorises, with the same
        // numbers. On sub-slices rather than `skip(1)`, whose iterator kept the loop
        // scalar (a sixth of the product's time, `perf annotate`, round 51).
        for (x, &ai) in rr[1..].iter_mut().zip(&ac[1..]) {
            *x += ai * b0;
        }
    }

    /// `sum_p a_p b_p` on table `t` (the operands' common table, or a lower order of
    /// it), the products added into one vector: each coefficient is then one recursive
    /// sum of at most `P m` products for `P` pairs of operands (`m` = [`Table::pairmax`]),
    /// so the rounding error of all of them is bounded by `gamma_{P m}` times the sum of
    /// their `|a_i b_j|` (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd
    /// ed. 2002, sec. 3.1; the same bound as one product's, with `P m` terms), plus the
    /// underflow terms; the truncated pairs and the remainders' products are bounded
    /// per pair as in [`Tm::mul_on`]. Against the products one by one and their sums
    /// (a vector, a pass and an error term per addition), one vector and one pass per
    /// product: a series' convolution (`series::conv`) sums up to nine products.
    fn sum_of_products<'a>(
        pairs: impl Iterator<Item = (&'a Tm, &'a Tm)>,
        t: &'static Table,
        fixed: bool,
    ) -> Tm {
        let len = t.len();
        let mut r = vec![0.0; len];
        let (mut kept, mut trunc, mut npairs, mut np) = (0.0f64, 0.0f64, 0usize, 0usize);
        let mut rem = Interval::point(0.0);
        for (a, b) in pairs {
            let a = a.convert(t, fixed);
            let b = b.convert(t, fixed);
            let (k, tr, pr) = Tm::bound_sums(&a, &b, t);
            kept = up(kept + k);
            trunc = up(trunc + tr);
            npairs += pr;
            np += 1;
            Tm::scatter(&mut r, &a, &b, t, true);
            if !is_zero(&a.rem) {
                rem = rem + a.rem * b.poly_range() + a.rem * b.rem;
            }
            if !is_zero(&b.rem) {
                rem = rem + b.rem * a.poly_range();
            }
        }
        let m = np as f64 * t.pairmax;
        let gamma = up(up(m * U) / dn(1.0 - m * U));
        let err = up(up(gamma * kept) + 2.0 * npairs as f64 * ETA);
        let rem = sym(up(err + trunc)) + rem;
        // Every coefficient is at most `kept` (as in `mul_on`).
        if kept < f64::MAX / 4.0 {
            if has_nan(&rem) {
                return Tm::entire_on(t, fixed);
            }
            return Tm::raw(t, fixed, r, rem);
        }
        Tm::raw(t, fixed, r, rem).finish()
    }

    /// `x * (s + r)` for a float `s` and an interval `r`.
    fn mul_const(x: Tm, s: f64, r: Interval) -> Tm {
        if is_zero(&r) {
            return x.scale(s);
        }
        let b = x.bound();
        x.scale(s).with_rem(r * b)
    }

    /// Taylor expansion of `f` about the constant coefficient (module documentation);
    /// `fs` is `f` on series, `fi` on intervals (the fallback).
    fn expand(&self, fs: impl Fn(&S10) -> S10, fi: impl Fn(&Interval) -> Interval) -> Tm {
        let x = self.bound();
        let fallback = || Tm::from_interval_on(self.t, self.fixed, fi(&x));
        if self.t.len() == 1 {
            return fallback();
        }
        let c = self.c[0];
        let mut h = self.clone();
        h.c[0] = 0.0;
        h.lo = f64::NEG_INFINITY;
        let mut hb = h.bound();
        if !(c.is_finite() && hb.lo.is_finite() && hb.hi.is_finite()) {
            return fallback();
        }
        // Every value is >= lo, so the deviation from c is >= lo - c (the Lagrange point
        // lies between c and a value).
        let floor = sum_dn(self.lo, -c);
        if floor > hb.lo {
            hb.lo = floor.min(hb.hi);
        }
        // The Lagrange point c + theta h lies in c + conv(0, H).
        let hz = Interval {
            lo: hb.lo.min(0.0),
            hi: hb.hi.max(0.0),
        };
        let deg = self.t.order.min(MAX_DEG) as usize;
        let seed = |v: Interval, n: usize| {
            let mut s = S10::var(v);
            s.c[1] = Interval::point(1.0);
            s.n = n;
            s
        };
        let pa = fs(&seed(Interval::point(c), deg + 1));
        let pr = fs(&seed(Interval::point(c) + hz, deg + 2));
        let fin = |i: &Interval| i.lo.is_finite() && i.hi.is_finite();
        let lag = pr.c[deg + 1];
        if pa.bad || pr.bad || !fin(&lag) || !pa.c[..=deg].iter().all(fin) {
            return fallback();
        }
        let mag = (-hb.lo).max(hb.hi);
        let mut p = Tm::constant_on(self.t, self.fixed, pa.c[deg].value());
        for k in (0..deg).rev() {
            p = Tm::mul_ref(&p, &h).add_f64(pa.c[k].value());
        }
        let (mut rs, mut mk) = (0.0f64, 1.0f64);
        for k in 0..=deg {
            rs = up(rs + up(rad(&pa.c[k]) * mk));
            mk = up(mk * mag);
        }
        let r = sym(rs) + lag * hb.powi(deg as u32 + 1);
        let out = p.with_rem(r);
        if !(out.rem.lo.is_finite() && out.rem.hi.is_finite()) {
            return fallback();
        }
        // Where the expansion diverges (the range is wide against the distance to a
        // singularity, e.g. sqrt near 0), its remainder can exceed the plain interval
        // enclosure of f over the range: then the interval, sound too, is the tighter model.
        // (Compared by the remainder alone: the polynomial part keeps the dependence
        // even where its range bound is loose.)
        let fb = fi(&x);
        if fb.hi - fb.lo < out.rem.hi - out.rem.lo {
            fallback()
        } else {
            out
        }
    }

    /// `1 / self`.
    fn recip(&self) -> Tm {
        self.expand(|s| S10::cst(1.0) / *s, |i| Interval::point(1.0) / *i)
    }
}

// ---------------------------------------------------------------------------------------
// Operators.

impl Add for Tm {
    type Output = Tm;
    fn add(self, o: Tm) -> Tm {
        self.add_signed(&o, 1.0)
    }
}
impl Sub for Tm {
    type Output = Tm;
    fn sub(self, o: Tm) -> Tm {
        self.add_signed(&o, -1.0)
    }
}
impl Mul for Tm {
    type Output = Tm;
    fn mul(self, o: Tm) -> Tm {
        Tm::mul_ref(&self, &o)
    }
}
impl Div for Tm {
    type Output = Tm;
    fn div(self, o: Tm) -> Tm {
        self.div_by(&o)
    }
}

/// Most reciprocals [`Tm::div_by`] keeps per thread.
const KEPT_RECIPS: usize = 16;

/// `(divisor, order, its reciprocal at that order)`, most recent first.
type KeptRecip = (Tm, u32, Rc<Tm>);

/// Whether two models are the same bit for bit (table, coefficients, remainder, lower
/// bound): then every operation gives the same numbers on both.
fn same_bits(a: &Tm, b: &Tm) -> bool {
    let eq = |x: f64, y: f64| x.to_bits() == y.to_bits();
    std::ptr::eq(a.t, b.t)
        && a.fixed == b.fixed
        && eq(a.rem.lo, b.rem.lo)
        && eq(a.rem.hi, b.rem.hi)
        && eq(a.lo, b.lo)
        && a.c.len() == b.c.len()
        && a.c.iter().zip(&b.c).all(|(&x, &y)| eq(x, y))
}

impl Tm {
    /// `self / o`, the reciprocal of `o` kept for the next quotients by the same
    /// divisor at the same order (the last [`KEPT_RECIPS`] per thread, matched bit for
    /// bit, so the same numbers as computing it again). A series' quotient recurrence
    /// divides by its denominator's constant coefficient once per time order
    /// (`samara_system::taylor`, Moore 1966), and a quotient by a held input once per
    /// order of every step of the period: the reciprocal, an elementary-function
    /// expansion of four products at order 4, was computed each time.
    ///
    /// The quotient has the numerator's order when that is the lower one: the
    /// denominator's reciprocal is then expanded at that order too (its terms past it
    /// bounded into the remainder first, soundly) instead of at its own.
    fn div_by(self, o: &Tm) -> Tm {
        thread_local! {
            static KEPT: RefCell<Vec<KeptRecip>> = const { RefCell::new(Vec::new()) };
        }
        let lower = self.fixed && o.fixed && self.t.order < o.t.order;
        let order = if lower { self.t.order } else { o.t.order };
        let found = KEPT.with(|k| {
            let mut k = k.borrow_mut();
            let at = k.iter().position(|e| e.1 == order && same_bits(&e.0, o))?;
            let e = k.remove(at);
            let r = e.2.clone();
            k.insert(0, e);
            Some(r)
        });
        let r = match found {
            Some(r) => r,
            None => {
                let r = Rc::new(if lower {
                    o.clone().with_order(order).recip()
                } else {
                    o.recip()
                });
                KEPT.with(|k| {
                    let mut k = k.borrow_mut();
                    k.truncate(KEPT_RECIPS - 1);
                    k.insert(0, (o.clone(), order, r.clone()));
                });
                r
            }
        };
        Tm::mul_ref(&self, &r)
    }
}
impl Add<&Tm> for Tm {
    type Output = Tm;
    /// Sum into this model's coefficients, the other operand borrowed (no copy of it).
    fn add(self, o: &Tm) -> Tm {
        self.add_signed(o, 1.0)
    }
}
impl<'a> Add<&'a Tm> for &'a Tm {
    type Output = Tm;
    /// Sum without consuming the operands.
    fn add(self, o: &Tm) -> Tm {
        self.clone().add_signed(o, 1.0)
    }
}
impl<'a> Sub<&'a Tm> for &'a Tm {
    type Output = Tm;
    /// Difference without consuming the operands.
    fn sub(self, o: &Tm) -> Tm {
        self.clone().add_signed(o, -1.0)
    }
}
impl<'a> Mul<&'a Tm> for &'a Tm {
    type Output = Tm;
    /// Product without consuming (or cloning) the operands.
    fn mul(self, o: &Tm) -> Tm {
        Tm::mul_ref(self, o)
    }
}
impl Neg for Tm {
    type Output = Tm;
    fn neg(mut self) -> Tm {
        for v in self.c.iter_mut() {
            *v = -*v;
        }
        // The extents trade places (the dropped ones are recomputed when needed).
        let [sn, sp] = self.ext.get();
        self.drops = Drops::default();
        self.ext.set([sp, sn]);
        self.rem = -self.rem;
        self.lo = f64::NEG_INFINITY;
        self
    }
}
impl Add<f64> for Tm {
    type Output = Tm;
    fn add(self, o: f64) -> Tm {
        self.add_f64(o)
    }
}
impl Sub<f64> for Tm {
    type Output = Tm;
    fn sub(self, o: f64) -> Tm {
        self.add_f64(-o)
    }
}
impl Mul<f64> for Tm {
    type Output = Tm;
    fn mul(self, o: f64) -> Tm {
        self.scale(o)
    }
}
impl Div<f64> for Tm {
    type Output = Tm;
    fn div(self, o: f64) -> Tm {
        self.div_f64(o)
    }
}
impl AddAssign for Tm {
    fn add_assign(&mut self, o: Tm) {
        let a = std::mem::take(&mut self.c);
        let me = Tm::raw(self.t, self.fixed, a, self.rem);
        *self = me.add_signed(&o, 1.0);
    }
}
impl SubAssign for Tm {
    fn sub_assign(&mut self, o: Tm) {
        let a = std::mem::take(&mut self.c);
        let me = Tm::raw(self.t, self.fixed, a, self.rem);
        *self = me.add_signed(&o, -1.0);
    }
}
impl MulAssign for Tm {
    fn mul_assign(&mut self, o: Tm) {
        *self = Tm::mul_ref(self, &o);
    }
}

impl Scalar for Tm {
    /// The constant `c` with no parameters and no order of its own.
    fn cst(c: f64) -> Self {
        Tm::constant_on(table(0, 0), false, c)
    }
    /// The constant coefficient.
    fn value(&self) -> f64 {
        self.c[0]
    }
    fn sin(&self) -> Self {
        self.expand(|s| s.sin(), |i| i.sin())
    }
    fn cos(&self) -> Self {
        self.expand(|s| s.cos(), |i| i.cos())
    }
    fn tanh(&self) -> Self {
        self.expand(|s| s.tanh(), |i| i.tanh())
    }
    fn atan(&self) -> Self {
        self.expand(|s| s.atan(), |i| i.atan())
    }
    fn sqrt(&self) -> Self {
        let mut r = self.expand(|s| s.sqrt(), |i| i.sqrt());
        // Only for a defined result: an out-of-domain argument stays the entire model.
        if r.bound().hi.is_finite() {
            r.lo = r.lo.max(Interval::point(self.lo.max(0.0)).sqrt().lo);
        }
        r
    }
    fn exp(&self) -> Self {
        let mut r = self.expand(|s| s.exp(), |i| i.exp());
        if r.bound().hi.is_finite() {
            r.lo = r.lo.max(0.0);
        }
        r
    }
    fn ln(&self) -> Self {
        self.expand(|s| s.ln(), |i| i.ln())
    }
    fn tan(&self) -> Self {
        self.expand(|s| s.tan(), |i| i.tan())
    }
    fn sigmoid(&self) -> Self {
        self.expand(|s| s.sigmoid(), |i| i.sigmoid())
    }
    /// `+-self` when the sign is decided, otherwise the interval `|bound|` as a constant
    /// plus remainder.
    fn abs(&self) -> Self {
        match self.sign() {
            Sign::Positive | Sign::NonNegative | Sign::Zero => self.clone(),
            Sign::Negative | Sign::NonPositive => -self.clone(),
            Sign::Mixed => Tm::from_interval_on(self.t, self.fixed, self.bound().abs()),
        }
    }
    fn mul_by_ref(&self, o: &Self) -> Self {
        Tm::mul_ref(self, o)
    }
    /// The products summed into one vector with one rounding-error bound
    /// (`Tm::sum_of_products`) where every operand has an order of its own and
    /// parameters; otherwise one by one, as the default.
    fn conv_capped(a: &[Tm], b: &[Tm], lo: usize, i: usize, cap: u32) -> Tm {
        let ops = || (lo..=i).flat_map(|j| [&a[j], &b[i - j]]);
        if i == lo || ops().any(|m| !m.fixed || m.t.len() == 1) {
            let mut acc = a[lo].mul_capped(&b[i - lo], cap);
            for j in lo + 1..=i {
                acc += a[j].mul_capped(&b[i - j], cap);
            }
            return acc;
        }
        let (t, fixed) = ops()
            .map(|m| (m.t, m.fixed))
            .reduce(common_of)
            .expect("at least one pair");
        let t = if cap < t.order {
            table_mixed(t.n, cap, t.full, t.lw)
        } else {
            t
        };
        Tm::sum_of_products((lo..=i).map(|j| (&a[j], &b[i - j])), t, fixed)
    }
    fn add_by_ref(&self, o: &Self) -> Self {
        self.clone().add_signed(o, 1.0)
    }
    fn sub_by_ref(&self, o: &Self) -> Self {
        self.clone().add_signed(o, -1.0)
    }
    fn div_by_ref(self, o: &Self) -> Self {
        self.div_by(o)
    }
    /// The order of a model with an explicit one (`u32::MAX` otherwise: constants
    /// adopt their partner's).
    fn trunc_order(&self) -> u32 {
        if self.fixed {
            self.t.order
        } else {
            u32::MAX
        }
    }
    /// The product on the common table at order `cap` at most: the operands are
    /// lowered to `cap` first (as a sum with a model of order `cap` would lower their
    /// product), so that a product whose sum ends at a lower order does not compute
    /// its terms past it.
    fn mul_capped(&self, o: &Self, cap: u32) -> Self {
        let (t, fixed) = common(self, o);
        if fixed && cap < t.order {
            Tm::mul_on(self, o, table_mixed(t.n, cap, t.full, t.lw), fixed)
        } else {
            Tm::mul_on(self, o, t, fixed)
        }
    }
    fn sqr(&self) -> Self {
        let mut r = Tm::mul_ref(self, self);
        r.lo = r.lo.max(0.0);
        r
    }
    /// `max(self, 0)`. Undecided: the chord of the triangle relaxation (below).
    fn relu(&self) -> Self {
        let b = self.bound();
        match b.sign() {
            Sign::Positive | Sign::NonNegative | Sign::Zero => self.clone(),
            Sign::Negative | Sign::NonPositive => Tm::constant_on(self.t, self.fixed, 0.0),
            Sign::Mixed => {
                // The chord of the triangle relaxation (Ehlers, ATVA 2017; DeepZ's slope,
                // Singh et al., NeurIPS 2018): with `x in [l, u]`, l < 0 < u and any
                // `lam in [0, 1]`, `relu(x) - lam x` is convex and piecewise linear, 0 at
                // 0, so it lies in `[0, max(-lam l, (1 - lam) u)]`; `lam = u / (u - l)`
                // makes both ends equal. It keeps `lam` of the dependence on the
                // parameters where the interval `[0, u]` keeps none.
                let lam = (b.hi / (b.hi - b.lo)).clamp(0.0, 1.0);
                if !(b.lo.is_finite() && b.hi.is_finite() && lam.is_finite()) {
                    return Tm::from_interval_on(
                        self.t,
                        self.fixed,
                        Interval { lo: 0.0, hi: b.hi },
                    );
                }
                let at_lo = Interval::point(-b.lo) * Interval::point(lam);
                let at_hi = Interval::point(b.hi) * (Interval::point(1.0) - Interval::point(lam));
                let gap = at_lo.hi.max(at_hi.hi);
                (self.clone() * lam).with_rem(Interval { lo: 0.0, hi: gap })
            }
        }
    }
    /// `min(self, other)`; undecided: `self - relu(self - other)`.
    fn smin(&self, other: &Self) -> Self {
        let d = self.clone() - other.clone();
        match d.sign() {
            Sign::Negative | Sign::Zero | Sign::NonPositive => self.clone(),
            Sign::Positive | Sign::NonNegative => other.clone(),
            Sign::Mixed => self.clone() - d.relu(),
        }
    }
    /// `max(self, other)`; undecided: `other + relu(self - other)`.
    fn smax(&self, other: &Self) -> Self {
        let d = self.clone() - other.clone();
        match d.sign() {
            Sign::Positive | Sign::Zero | Sign::NonNegative => self.clone(),
            Sign::Negative | Sign::NonPositive => other.clone(),
            Sign::Mixed => other.clone() + d.relu(),
        }
    }
    /// Clamp into `[lo, hi]`; undecided ends through `relu` as in `smax`/`smin`.
    fn clamp_to(&self, lo: f64, hi: f64) -> Self {
        let low = match self.sign_minus(lo) {
            Sign::Negative | Sign::Zero | Sign::NonPositive => {
                return Tm::constant_on(self.t, self.fixed, lo).smin(&Tm::cst(hi));
            }
            Sign::Positive | Sign::NonNegative => self.clone(),
            Sign::Mixed => (self.clone() - lo).relu() + lo,
        };
        match low.sign_minus(hi) {
            Sign::Positive | Sign::Zero | Sign::NonNegative => {
                Tm::constant_on(self.t, self.fixed, hi)
            }
            Sign::Negative | Sign::NonPositive => low,
            Sign::Mixed => -((-low + hi).relu()) + hi,
        }
    }
    fn sign(&self) -> Sign {
        self.bound().sign()
    }
    /// `self + conv(0, bound(other - self))`: encloses every value between `self(xi)` and
    /// `other(xi)` for every `xi`.
    fn hull(&self, other: &Self) -> Self {
        let d = (other.clone() - self.clone()).bound();
        let (t, fixed) = common(self, other);
        let r = Interval {
            lo: d.lo.min(0.0),
            hi: d.hi.max(0.0),
        };
        self.convert(t, fixed).into_owned().with_rem(r)
    }
}

#[cfg(test)]
mod tests {
    //! The once-bounded sums against exact integer arithmetic: every value is an integer
    //! multiple of a power of two, so the exact sum is an `i128`, and a bound `B` is
    //! sound iff `floor(B * 2^k) >= exact` (the exact sum is an integer in those units).
    use super::*;
    use proptest::prelude::*;

    /// `floor(x * 2^k)` as an integer, `k` split into steps that keep `x` finite.
    fn scaled(mut x: f64, mut k: i32) -> i128 {
        while k > 0 {
            let s = k.min(500);
            x *= 2f64.powi(s);
            k -= s;
        }
        x.floor() as i128
    }

    /// The sum in the order of `Tm::mul_ref`'s per-degree sums: four lanes by index.
    fn lanes(v: &[f64]) -> f64 {
        let mut l = [0.0f64; 4];
        for (j, x) in v.iter().enumerate() {
            l[j & 3] += x;
        }
        (l[0] + l[1]) + (l[2] + l[3])
    }

    /// Numerators (each exact as a float): uniform, or one large value and many just below half its ulp (each
    /// dropped by every float addition), the worst case of a plain sum.
    fn numerators() -> impl Strategy<Value = Vec<u64>> {
        prop_oneof![
            prop::collection::vec(0u64..(1 << 53), 1..400),
            // 2^60 + a multiple of its ulp (256): exact; 127 is below half the ulp.
            (1usize..2000, 0u64..(1 << 20)).prop_map(|(n, jitter)| {
                let mut v = vec![(1u64 << 60) + 256 * jitter];
                v.extend(std::iter::repeat_n(127, n));
                v
            }),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        #[test]
        fn sum_bound_holds_for_any_order(k in numerators()) {
            let v: Vec<f64> = k.iter().map(|&x| x as f64 * 2f64.powi(-60)).collect();
            let exact: i128 = k.iter().map(|&x| x as i128).sum();
            for s in [v.iter().sum::<f64>(), lanes(&v), v.iter().rev().sum::<f64>()] {
                let b = nonneg_sum_bound(s, v.len());
                prop_assert!(scaled(b, 60) >= exact, "bound {b} below the exact sum");
                // Not loose: within 4 n u of the exact sum (plus the ulp the rounding
                // up may add).
                let e = exact as f64 * 2f64.powi(-60);
                prop_assert!(b <= e * (1.0 + 8.0 * v.len() as f64 * U) + f64::MIN_POSITIVE);
            }
        }

        #[test]
        fn dot_bound_holds_with_rounded_and_underflowing_products(
            pq in prop::collection::vec((0u64..(1 << 40), 0u64..(1 << 40)), 1..300),
            tiny in any::<bool>(),
        ) {
            // Units of 2^-60 (normal products) or 2^-1080 (products far below the
            // normal range, rounded to multiples of 2^-1074).
            let (e, k) = if tiny { (-540, 1080) } else { (-30, 60) };
            let mut s = 0.0f64;
            for &(p, q) in &pq {
                s += (p as f64 * 2f64.powi(e)) * (q as f64 * 2f64.powi(e));
            }
            let exact: i128 = pq.iter().map(|&(p, q)| p as i128 * q as i128).sum();
            let b = nonneg_dot_bound(s, pq.len());
            prop_assert!(scaled(b, k) >= exact, "bound {b} below the exact sum");
        }
    }

    #[test]
    fn sum_bound_edge_cases() {
        assert_eq!(nonneg_sum_bound(0.0, 10), 0.0);
        assert_eq!(nonneg_sum_bound(3.0, 1), 3.0);
        assert_eq!(nonneg_sum_bound(f64::INFINITY, 10), f64::INFINITY);
        assert_eq!(nonneg_sum_bound(f64::NAN, 10), f64::INFINITY);
        assert_eq!(nonneg_dot_bound(2.0, 0), 2.0);
        assert!(nonneg_dot_bound(0.0, 3) > 0.0);
    }

    /// `affine_like` / `constant_like` keep the weights of the model they are called on:
    /// beside a mixed-degree model (6 weight-1 parameters, lifted weight 2, order 4) the
    /// result is on the mixed table in 47 parameters (2,219 monomials:
    /// C(10, 4) + 41 C(8, 2) + C(42, 2)), not the classic one (C(51, 4) = 249,900), holds
    /// exactly the coefficients given, and adding it to the model leaves the model's
    /// table; beside a classic model it is on `Tm::affine`'s and `Tm::constant`'s table.
    #[test]
    fn like_constructors_keep_the_parameter_weights() {
        let (order, full, n) = (4, 6, 47);
        let mixed = (Tm::var(0, full, order) * 0.5 + 1.0).with_lifted_weight(2);
        let state = mixed.clone() + mixed.param(n - 1, n);
        assert_eq!(state.full_params(), Some(full));
        let coef: Vec<f64> = (0..n).map(|k| 0.25 * k as f64 - 3.0).collect();
        let a = state.affine_like(1.5, &coef, order);
        assert_eq!(a.full_params(), Some(full));
        assert_eq!((a.n_vars(), a.order(), a.n_terms()), (n, order, 2_219));
        assert!(a.same_basis(&state));
        assert!((a.clone() + state.clone()).same_basis(&state));
        assert_eq!(a.coef(0), 1.5);
        for k in 1..=n {
            assert_eq!(a.coef(k), coef[k - 1], "xi_{}", k - 1);
        }
        assert!((n + 1..a.n_terms()).all(|i| a.coef(i) == 0.0));
        assert_eq!(a.rem(), Interval::point(0.0));
        let z = state.constant_like(2.0, n, order);
        assert!(z.same_basis(&state));
        assert_eq!(z.bound(), Interval::point(2.0));
        // On a classic model: the classic table, as `Tm::affine` and `Tm::constant`.
        let c = Tm::var(0, 3, 2);
        assert!(c
            .affine_like(0.5, &[1.0, 2.0, 3.0], 2)
            .same_basis(&Tm::affine(0.0, &[0.0; 3], 2)));
        assert!(c
            .constant_like(0.5, 5, 2)
            .same_basis(&Tm::constant(0.0, 5, 2)));
        assert_eq!(c.constant_like(0.5, 5, 2).full_params(), None);
    }

    /// The kept extents ([`Tm::ext`]) never go stale: a model whose range was read
    /// (so kept) and then changed by each coefficient-changing operation (sum,
    /// difference, in-place sum, products by a model and by a float, quotient by a float,
    /// negation, a constant added, a change of table) reads the same range as one
    /// recomputed from its coefficients; and the polynomial's value at a random point
    /// lies in that range.
    /// A product past overflow (the coefficient scan it skips below overflow) is still
    /// the entire model.
    #[test]
    fn kept_ranges_follow_every_operation() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let fresh = |m: &Tm| {
            let [sn, sp] = m.extent_from(1);
            Tm::range_of(m.c[0], sn, sp)
        };
        let check = |m: &Tm, what: &str| {
            assert_eq!(m.poly_range(), fresh(m), "{what}: first read");
            assert_eq!(m.poly_range(), fresh(m), "{what}: kept");
        };
        for _ in 0..50 {
            let n = 3;
            let mut rnd = || rng.gen_range(-1.0..1.0);
            let x: Vec<Tm> = (0..n)
                .map(|k| {
                    (Tm::var(k, n, 3) * (0.5 + rnd()) + rnd()).with_rem(Interval::new(-1e-3, 1e-3))
                })
                .collect();
            let a = x[0].clone() * x[1].clone() + x[2].sqr();
            let b = x[1].clone() * x[2].clone() - x[0].clone();
            let _ = (a.bound(), b.bound());
            let ops: Vec<(&str, Tm)> = vec![
                ("sum", a.clone() + b.clone()),
                ("difference", a.clone() - b.clone()),
                ("in-place sum", {
                    let mut c = a.clone();
                    c += b.clone();
                    c
                }),
                ("product", a.clone() * b.clone()),
                ("product by ref", a.mul_by_ref(&b)),
                ("square", a.sqr()),
                ("scaled", a.clone() * 0.3),
                ("quotient", a.clone() / 3.0),
                ("negated", -a.clone()),
                ("shifted", a.clone() + 0.25),
                ("lower order", a.clone().with_order(2)),
                ("more parameters", a.clone() + Tm::var(3, 4, 3)),
            ];
            for (what, m) in &ops {
                check(m, what);
                let xi: Vec<f64> = (0..m.n_vars()).map(|_| rnd()).collect();
                // The polynomial's value at the point lies in its (kept) range.
                let v = m.clone().split_rem().0.eval_at(&xi);
                let bd = m.poly_range();
                assert!(
                    bd.lo <= v.lo && v.hi <= bd.hi,
                    "{what}: {v:?} outside {bd:?}"
                );
            }
        }
        let big = Tm::var(0, 2, 2) * 1e200 + Tm::var(1, 2, 2) * 1e200;
        let _ = big.bound();
        let p = big.clone() * big;
        assert_eq!(
            p.bound(),
            Interval::entire(),
            "an overflowing product is entire"
        );
    }

    /// The sums by weighted degree from the table's lane lists ([`Tm::wsums_fresh`])
    /// are, bit for bit, those of the pass over the coefficients in index order that
    /// `Tm::mul_on` made before them (four lanes by `j mod 4`, the tail in lane 0), on
    /// classic and mixed tables of every length mod 4.
    #[test]
    fn sums_by_weighted_degree_match_the_pass_in_index_order() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for &(n, order, full, lw) in &[
            (3, 4, 3, 1),
            (5, 3, 5, 1),
            (8, 4, 2, 2),
            (9, 4, 6, 2),
            (7, 5, 3, 3),
        ] {
            let t = table_mixed(n, order, full, lw);
            for _ in 0..20 {
                let c: Vec<f64> = (0..t.len())
                    .map(|_| match rng.gen_range(0..4) {
                        0 => 0.0,
                        1 => rng.gen_range(-1.0..1.0) * 1e-17,
                        _ => rng.gen_range(-1.0..1.0),
                    })
                    .collect();
                let m = Tm::raw(t, true, c.clone(), Interval::point(0.0));
                const W: usize = MAX_ORDER as usize + 2;
                let (mut part4, mut nz4) = ([[0.0f64; W]; 4], [[0usize; W]; 4]);
                let len = c.len();
                let mut j = 0;
                while j + 4 <= len {
                    for lane in 0..4 {
                        let w = t.wdeg[j + lane] as usize;
                        part4[lane][w] += c[j + lane].abs();
                        nz4[lane][w] += (c[j + lane] != 0.0) as usize;
                    }
                    j += 4;
                }
                while j < len {
                    let w = t.wdeg[j] as usize;
                    part4[0][w] += c[j].abs();
                    nz4[0][w] += (c[j] != 0.0) as usize;
                    j += 1;
                }
                let (kept, w0) = m.wsums();
                for d in 0..=order as usize {
                    let want = (part4[0][d] + part4[1][d]) + (part4[2][d] + part4[3][d]);
                    let nz = (nz4[0][d] + nz4[1][d]) + (nz4[2][d] + nz4[3][d]);
                    let got = if d == 0 { w0 } else { kept[d] };
                    assert_eq!(
                        got.sum.to_bits(),
                        want.to_bits(),
                        "{:?}, degree {d}",
                        (n, order, full, lw)
                    );
                    assert_eq!(got.nz, nz);
                }
            }
        }
    }

    /// A kept lowering ([`Drops`]'s lowered models) is used only for the source it was
    /// made from: after operations that change the constant, the remainder or the lower
    /// bound without [`Tm::touch`] (a remainder added, a constant added, the remainder
    /// split off), and after those that change the other coefficients, the lowering is
    /// bit for bit that of a model rebuilt from the coefficients; and a kept one is
    /// what lowering afresh gives.
    #[test]
    fn kept_lowerings_follow_their_source() {
        let x0 = Tm::var(0, 3, 4).with_lifted_weight(2);
        let (x1, x2) = (x0.param(1, 5), x0.param(2, 5));
        let m = (x0.clone() * 0.5 + x1.clone() * x2.clone() * 0.25 + 1.0).sqr()
            + x0.param(4, 5) * 0.1
            + x1.clone() * x1.clone() * x2.clone() * 0.125;
        let m = m.with_rem(Interval::new(-1e-6, 2e-6));
        let rebuilt = |x: &Tm| {
            let mut r = Tm::raw(x.t, x.fixed, x.c.clone(), x.rem);
            r.lo = x.lo;
            r
        };
        let warm = |x: Tm| {
            for k in 1..x.t.order {
                let t = table_mixed(x.t.n, k, x.t.full, x.t.lw);
                let _ = x.convert(t, true);
            }
            x
        };
        let variants: Vec<(&str, Tm)> = vec![
            ("as it is", warm(rebuilt(&m))),
            (
                "remainder added",
                warm(rebuilt(&m)).with_rem(Interval::new(-1e-3, 0.0)),
            ),
            ("constant added", warm(rebuilt(&m)) + 0.25),
            ("remainder split off", warm(rebuilt(&m)).split_rem().0),
            ("scaled", warm(rebuilt(&m)) * 3.0),
            ("sum", warm(rebuilt(&m)) + x1.clone()),
            ("negated", -warm(rebuilt(&m))),
        ];
        for (what, v) in &variants {
            for k in 1..v.t.order {
                let t = table_mixed(v.t.n, k, v.t.full, v.t.lw);
                for _ in 0..2 {
                    let got = v.convert(t, true);
                    let want = rebuilt(v).convert(t, true).into_owned();
                    assert!(same_bits(&got, &want), "{what}, order {k}");
                    assert_eq!(got.poly_range(), want.poly_range(), "{what}, order {k}");
                }
            }
        }
    }

    /// Quotients through the kept reciprocals ([`Tm::div_by`]) are, bit for bit, the
    /// quotients computed afresh (the numerator times the reciprocal of the divisor at
    /// the quotient's order), on first use, when kept, and after other divisors pushed
    /// them out; numerators at the divisor's order and lower ones (the divisor lowered
    /// first), on mixed and classic tables, and constants over a model. The sums and
    /// differences by reference are the sums by value, bit for bit.
    #[test]
    fn kept_reciprocals_give_the_quotients_computed_afresh() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for lw in [1, 2] {
            let (full, n, order) = (3, 5, 4);
            let model = |rng: &mut rand_chacha::ChaCha8Rng, c0: f64| {
                let base = Tm::constant(c0, full, order).with_lifted_weight(lw);
                let mut m = base.clone();
                for k in 0..n {
                    let v = base.param(k, n) * rng.gen_range(-0.1..0.1);
                    m = m + v.clone() + v.clone() * v * rng.gen_range(-0.5..0.5);
                }
                m.with_rem(Interval::new(-1e-9, 2e-9))
            };
            let divisors: Vec<Tm> = (0..KEPT_RECIPS + 4)
                .map(|k| model(&mut rng, 2.0 + k as f64))
                .collect();
            let mut nums: Vec<Tm> = (0..3).map(|_| model(&mut rng, 0.5)).collect();
            nums.push(model(&mut rng, 0.5).with_order(3));
            nums.push(model(&mut rng, 1.5).with_order(2));
            nums.push(Tm::cst(3.0));
            let fresh = |x: &Tm, d: &Tm| {
                let d = if x.fixed && x.t.order < d.t.order {
                    d.clone().with_order(x.t.order)
                } else {
                    d.clone()
                };
                Tm::mul_ref(x, &d.recip())
            };
            for _ in 0..2 {
                for d in &divisors {
                    for x in &nums {
                        let want = fresh(x, d);
                        assert!(same_bits(&(x.clone() / d.clone()), &want));
                        assert!(same_bits(&x.clone().div_by_ref(d), &want), "kept");
                    }
                }
            }
            let (a, b) = (&nums[0], &nums[3]);
            assert!(same_bits(&a.add_by_ref(b), &(a.clone() + b.clone())));
            assert!(same_bits(&a.sub_by_ref(b), &(a.clone() - b.clone())));
            assert!(same_bits(&b.sub_by_ref(a), &(b.clone() - a.clone())));
        }
    }

    /// A kept range made stale on purpose (a coefficient changed behind the cache's
    /// back, as a future operation that forgot the reset would) is caught by the debug
    /// builds' check within 16 reads.
    #[test]
    #[cfg(debug_assertions)]
    #[should_panic(expected = "is stale")]
    fn a_stale_kept_range_fails_the_debug_check() {
        let mut m = Tm::var(0, 2, 3) * 0.5 + Tm::var(1, 2, 3) * 0.25;
        let _ = m.bound();
        m.c[1] = 4.0;
        for _ in 0..16 {
            let _ = m.bound();
        }
    }

    /// The product table by exponent vectors, independently of the additive hash that
    /// builds it: every entry of `mul` is the index of the sum of its pair's exponents,
    /// every pair within the order appears once, and no other (classic and mixed
    /// tables; the reach runs use 6 of weight 1 and up to 40 of weight 2).
    #[test]
    fn product_table_matches_exponent_sums() {
        for &(n, order, full, lw) in &[(3, 4, 3, 1), (6, 4, 6, 1), (8, 4, 2, 2), (20, 4, 6, 2)] {
            let t = Table::build(n, order, full, lw);
            let len = t.len();
            let w = |e: &[u8]| -> u32 {
                e.iter()
                    .enumerate()
                    .map(|(k, &x)| if k < full { x as u32 } else { lw * x as u32 })
                    .sum()
            };
            let mut seen = 0usize;
            for i in 0..len {
                let (s, e) = (t.row[i], t.row[i + 1]);
                let partners: Vec<usize> = if t.part.is_empty() {
                    (0..e - s).collect()
                } else {
                    t.part[s..e].iter().map(|&j| j as usize).collect()
                };
                let want: Vec<usize> = (0..len)
                    .filter(|&j| w(t.exps(i)) + w(t.exps(j)) <= order)
                    .collect();
                assert_eq!(
                    partners,
                    want,
                    "partners of {i} on {:?}",
                    (n, order, full, lw)
                );
                for (&j, &k) in partners.iter().zip(&t.mul[s..e]) {
                    let sum: Vec<u8> = t
                        .exps(i)
                        .iter()
                        .zip(t.exps(j))
                        .map(|(a, b)| a + b)
                        .collect();
                    assert_eq!(t.exps(k as usize), &sum[..]);
                    seen += 1;
                }
            }
            assert_eq!(seen, t.mul.len());
        }
    }
}
