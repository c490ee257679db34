//! CROWN's intermediate bounds with the pull-backs of a layer's neurons batched: the
//! objectives `z_i` and `-z_i` of many neurons go back through each map together, as one
//! matrix-matrix product `N = M W` (register-blocked: a 4 x 4 block of `N` is kept in
//! registers while the inner index runs, so each weight loaded serves four rows and
//! each coefficient four columns)
//! instead of one row-vector product per objective (Zhang et al., NeurIPS 2018, bound
//! every neuron of a layer this way, as a matrix; auto_LiRPA does the same).
//!
//! Same bits as [`backward_core`]: each entry of `N` is the sum over the inner index in
//! ascending order starting from `+0`, as in its row loop. That loop skips the inner
//! indices whose coefficient is 0; the block adds their products, which are `+-0` (the
//! weights are finite, checked by [`finite`]), and adding `+-0` changes no sum: a non-zero sum stays
//! itself, and a sum started at `+0` is never `-0` (in round-to-nearest `x + y` is `-0`
//! only when both are), so `+0 + -0 = +0` leaves it too. The scalar parts of each
//! pull-back (the bias terms, the rounding bound, the ReLU relaxation of
//! [`super::relax_relu`]) are its operations in its order; Rust never fuses a multiply
//! and an add.

use super::{gamma, inflate, relu, Linear};
use samara_nn::Affine;

/// The rows of the kernel's blocks of `N`, and its columns.
const BLOCK: usize = 4;

/// Whether every weight of `maps` is finite: the batched pull-backs multiply the weights
/// by zero coefficients that the row loop skips, which is harmless only then (`0 * inf`
/// is a NaN).
pub(super) fn finite(maps: &[(Affine, bool)]) -> bool {
    maps.iter().all(|(m, _)| m.w.iter().all(|w| w.is_finite()))
}

/// `n[.., tb..tb + B] = m w[.., tb..tb + B]` for the rows `rb..rb + 4` of `m` (row stride
/// `k`) and the weights `w` of `a` (row stride `a.inp`, `n`'s too), over the inner
/// indices `act`.
#[inline(always)]
fn block<const B: usize>(
    m: &[f64],
    k: usize,
    rb: usize,
    act: &[usize],
    a: &Affine,
    tb: usize,
    n: &mut [f64],
) {
    let (w, ld) = (&a.w[..], a.inp);
    let (m0, m1, m2, m3) = (
        &m[rb * k..(rb + 1) * k],
        &m[(rb + 1) * k..(rb + 2) * k],
        &m[(rb + 2) * k..(rb + 3) * k],
        &m[(rb + 3) * k..(rb + 4) * k],
    );
    let mut acc = [[0.0f64; B]; BLOCK];
    for &i in act {
        let wi: &[f64; B] = w[i * ld + tb..i * ld + tb + B]
            .try_into()
            .expect("a block of the row");
        let a = [m0[i], m1[i], m2[i], m3[i]];
        for (q, aq) in a.iter().enumerate() {
            for c in 0..B {
                acc[q][c] += aq * wi[c];
            }
        }
    }
    for (q, row) in acc.iter().enumerate() {
        n[(rb + q) * ld + tb..(rb + q) * ld + tb + B].copy_from_slice(row);
    }
}

/// `n = m w` for the first `rows` rows of `m` (row stride `k`, `rows` a multiple of
/// [`BLOCK`]) and the weights of `a` (`n` has row stride `a.inp`), over the inner
/// indices `act` only (ascending; every other column of `m` is 0 in every row).
fn product(m: &[f64], k: usize, rows: usize, act: &[usize], a: &Affine, n: &mut [f64]) {
    let ld = a.inp;
    for rb in (0..rows).step_by(BLOCK) {
        let mut tb = 0;
        while tb + BLOCK <= ld {
            block::<BLOCK>(m, k, rb, act, a, tb, n);
            tb += BLOCK;
        }
        while tb + 2 <= ld {
            block::<2>(m, k, rb, act, a, tb, n);
            tb += 2;
        }
        if tb < ld {
            block::<1>(m, k, rb, act, a, tb, n);
        }
    }
}

/// The pull-backs of the objectives `s * z_i` for `(i, s)` in `objs` (`s` is 1 or -1,
/// `z_i` output `i` of the last map of `maps`) through `maps` and the ReLU relaxations
/// of the bounds `pre` with the chord slopes `slopes`, with the row magnitudes `rowmag`
/// for the rounding bound: for each objective the [`Linear`] that
/// `backward_core(maps, pre, c, 0.0, None, None, Mags::Rows(rowmag), None, Some(slopes))`
/// gives for `c = s e_i`, bit for bit, when the weights are [`finite`].
pub(super) fn pull_units(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    objs: &[(usize, f64)],
    rowmag: &[Vec<f64>],
    slopes: &[Vec<f64>],
) -> Vec<Linear> {
    let r = objs.len();
    let rows = r.div_ceil(BLOCK) * BLOCK;
    let last = maps.len() - 1;
    let mut cst = vec![0.0f64; r];
    let mut err = vec![0.0f64; r];
    // The coefficients over the current map's outputs (stride `k`) and over its inputs
    // (stride `m.inp`).
    let mut mu: Vec<f64> = Vec::new();
    let mut k = 0;
    let mut nu: Vec<f64> = Vec::new();
    let mut act: Vec<usize> = Vec::new();
    for j in (0..maps.len()).rev() {
        let m = &maps[j].0;
        let g = gamma(m.out + 1);
        nu.clear();
        nu.resize(rows * m.inp, 0.0);
        if j == last {
            // mu = s e_i: the row loop's one term, `0 + s w_it` (so `-0` becomes `+0`
            // as there).
            for (q, &(i, s)) in objs.iter().enumerate() {
                let p = s * m.b[i];
                cst[q] += p;
                let cmag = 0.0f64.abs() + p.abs();
                let wmag = 0.0 + s.abs() * rowmag[j][i];
                err[q] += g * (cmag + wmag);
                let w = &m.w[i * m.inp..(i + 1) * m.inp];
                for (o, &wt) in nu[q * m.inp..(q + 1) * m.inp].iter_mut().zip(w) {
                    *o += s * wt;
                }
            }
        } else {
            for (q, c) in cst.iter_mut().enumerate() {
                let row = &mu[q * k..q * k + m.out];
                let mut cmag = c.abs();
                let mut wmag = 0.0;
                for &i in &act {
                    let mi = row[i];
                    if mi == 0.0 {
                        continue;
                    }
                    let p = mi * m.b[i];
                    *c += p;
                    cmag += p.abs();
                    wmag += mi.abs() * rowmag[j][i];
                }
                err[q] += g * (cmag + wmag);
            }
            product(&mu, k, rows, &act, m, &mut nu);
        }
        if j == 0 {
            break;
        }
        k = m.inp;
        mu.clear();
        mu.resize(rows * k, 0.0);
        act.clear();
        if maps[j - 1].1 {
            // The layer's neurons by phase: off ones (`u <= 0`) give 0 in every row,
            // so the next product skips them; on ones pass their coefficient; unstable
            // ones are relaxed by its sign. `relax_relu`'s operations, in its order: it
            // skips a coefficient `v == 0`, which here is `+0` (see the module's note),
            // so copying it changes nothing.
            let b = &pre[j - 1];
            // (`!(u <= 0)` and `!(l >= 0)`, as `relax_relu` tests them, NaNs included.)
            act.extend((0..k).filter(|&t| b[t].1 > 0.0 || b[t].1.is_nan()));
            let on: Vec<usize> = act.iter().copied().filter(|&t| b[t].0 >= 0.0).collect();
            let un: Vec<usize> = act
                .iter()
                .copied()
                .filter(|&t| b[t].0 < 0.0 || b[t].0.is_nan())
                .collect();
            let sl = &slopes[j - 1];
            for q in 0..r {
                let v = &nu[q * k..(q + 1) * k];
                let z = &mut mu[q * k..(q + 1) * k];
                for &t in &on {
                    z[t] = v[t];
                }
                let (c, e) = (&mut cst[q], &mut err[q]);
                for &t in &un {
                    let (l, u) = b[t];
                    let v = v[t];
                    if v == 0.0 {
                        continue;
                    }
                    if v < 0.0 {
                        let s = sl[t];
                        z[t] = v * s;
                        let cc = -(v * s) * l;
                        *c += cc;
                        *e += 2.0 * f64::EPSILON * (z[t].abs() * l.abs().max(u.abs()) + cc.abs())
                            + f64::EPSILON * c.abs();
                    } else if relu::default_lower_slope(l, u) == 1.0 {
                        z[t] = v;
                    }
                }
            }
        } else {
            mu[..r * k].copy_from_slice(&nu[..r * k]);
            act.extend(0..k);
        }
    }
    let inp = maps[0].0.inp;
    (0..r)
        .map(|q| Linear {
            coef: nu[q * inp..(q + 1) * inp].to_vec(),
            cst: cst[q],
            slack: inflate(err[q]),
        })
        .collect()
}
