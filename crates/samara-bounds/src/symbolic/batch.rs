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

/// Coefficient matrices with fewer than one non-zero entry in this many go row by row
/// over their non-zero entries instead of through the blocks.
const SPARSE_BELOW: usize = 4;

/// Whether every map of `maps` is stored dense with finite weights: the batched
/// pull-backs multiply the weights by zero coefficients that the row loop skips, which
/// is harmless only then (`0 * inf` is a NaN); a sparse map (a lowered convolution) goes
/// by the row loop over its non-zeros.
pub(super) fn finite(maps: &[(Affine, bool)]) -> bool {
    maps.iter().all(|(m, _)| {
        m.as_dense()
            .is_some_and(|w| w.iter().all(|w| w.is_finite()))
    })
}

/// `n[.., tb..tb + B] = m w[.., tb..tb + B]` for the rows `rb..rb + 4` of `m` (row stride
/// `k`) and the weights `w` (`k` rows of stride `ld`, `n`'s stride too).
#[inline(always)]
fn block<const B: usize>(
    m: &[f64],
    k: usize,
    rb: usize,
    w: &[f64],
    ld: usize,
    tb: usize,
    n: &mut [f64],
) {
    let (m0, m1, m2, m3) = (
        &m[rb * k..(rb + 1) * k],
        &m[(rb + 1) * k..(rb + 2) * k],
        &m[(rb + 2) * k..(rb + 3) * k],
        &m[(rb + 3) * k..(rb + 4) * k],
    );
    let mut acc = [[0.0f64; B]; BLOCK];
    for i in 0..k {
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
/// [`BLOCK`]) and the weights `w` (`k` rows of stride `ld`; `n` has stride `ld`).
fn product(m: &[f64], k: usize, rows: usize, w: &[f64], ld: usize, n: &mut [f64]) {
    for rb in (0..rows).step_by(BLOCK) {
        let mut tb = 0;
        while tb + BLOCK <= ld {
            block::<BLOCK>(m, k, rb, w, ld, tb, n);
            tb += BLOCK;
        }
        while tb + 2 <= ld {
            block::<2>(m, k, rb, w, ld, tb, n);
            tb += 2;
        }
        if tb < ld {
            block::<1>(m, k, rb, w, ld, tb, n);
        }
    }
}

/// One bounded layer of a chain as the batched pull-backs see it.
struct LiveLayer {
    /// The outputs of the map that can carry a coefficient below a ReLU: those not off
    /// (`!(u <= 0)`, NaNs included, as [`super::relax_relu`] tests it), every output
    /// when the map has no ReLU. A pull-back's coefficient on an off neuron is 0, so the
    /// products run over these only (the module's note: adding the other terms, all
    /// `+-0`, would change nothing).
    idx: Vec<usize>,
    /// Whether a ReLU follows the map.
    relu: bool,
    /// The positions in `idx` of the neurons that are on (`l >= 0`): their coefficients
    /// pass; the others are unstable, relaxed by their coefficient's sign.
    on: Vec<usize>,
    /// The positions in `idx` of the unstable neurons.
    un: Vec<usize>,
    /// The map's weights restricted to the rows `idx` and the previous layer's `idx`
    /// columns (every input for the first map), row-major.
    w: Vec<f64>,
}

/// The layers of a chain bounded so far ([`Live::extend`]), in the packed form of
/// [`LiveLayer`]: built once per layer for all the batches of [`pull_units`] through it.
#[derive(Default)]
pub(super) struct Live {
    layers: Vec<LiveLayer>,
}

impl Live {
    /// Add the layers of `pre` (bounds of the outputs of `maps[j]`, `j < pre.len()`) not
    /// yet packed.
    pub(super) fn extend(&mut self, maps: &[(Affine, bool)], pre: &[Vec<(f64, f64)>]) {
        for j in self.layers.len()..pre.len() {
            let (m, relu) = (&maps[j].0, maps[j].1);
            let b = &pre[j];
            let idx: Vec<usize> = match relu {
                true => (0..m.out)
                    .filter(|&t| b[t].1 > 0.0 || b[t].1.is_nan())
                    .collect(),
                false => (0..m.out).collect(),
            };
            let (mut on, mut un) = (Vec::new(), Vec::new());
            if relu {
                for (p, &t) in idx.iter().enumerate() {
                    match b[t].0 >= 0.0 {
                        true => on.push(p),
                        false => un.push(p),
                    }
                }
            }
            let all: Vec<usize>;
            let cols = match j {
                0 => {
                    all = (0..m.inp).collect();
                    &all
                }
                _ => &self.layers[j - 1].idx,
            };
            let mut w = Vec::with_capacity(idx.len() * cols.len());
            for &i in &idx {
                let row = m.dense_row(i);
                w.extend(cols.iter().map(|&t| row[t]));
            }
            self.layers.push(LiveLayer {
                idx,
                relu,
                on,
                un,
                w,
            });
        }
    }
}

/// The pull-backs of the objectives `s * z_i` for `(i, s)` in `objs` (`s` is 1 or -1,
/// `z_i` output `i` of the last map of `maps`) through `maps` and the ReLU relaxations
/// of the bounds `pre` with the chord slopes `slopes`, with the row magnitudes `rowmag`
/// for the rounding bound: for each objective the [`Linear`] that
/// `backward_core(maps, pre, c, 0.0, None, None, Mags::Rows(rowmag), None, Some(slopes))`
/// gives for `c = s e_i`, bit for bit, when the weights are [`finite`]. `live` holds
/// the layers of `pre` ([`Live::extend`]). The coefficients live on the layers' `idx`
/// positions only.
pub(super) fn pull_units(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    live: &Live,
    objs: &[(usize, f64)],
    rowmag: &[Vec<f64>],
    slopes: &[Vec<f64>],
) -> Vec<Linear> {
    let r = objs.len();
    let rows = r.div_ceil(BLOCK) * BLOCK;
    let last = maps.len() - 1;
    let mut cst = vec![0.0f64; r];
    let mut err = vec![0.0f64; r];
    // The coefficients over the live outputs of map `j` (`mu`, stride `k`) and over the
    // live outputs of map `j - 1` (`nu`, stride `n`; every input of map 0 at `j = 0`).
    let mut mu: Vec<f64> = Vec::new();
    let mut k = 0;
    let mut nu: Vec<f64> = Vec::new();
    let all: Vec<usize> = (0..maps[0].0.inp).collect();
    let mut n = 0;
    for j in (0..maps.len()).rev() {
        let m = &maps[j].0;
        let g = gamma(m.out + 1);
        let cols = match j {
            0 => &all,
            _ => &live.layers[j - 1].idx,
        };
        n = cols.len();
        if j == last {
            // mu = s e_i: the row loop's one term, `0 + s w_it` (so `-0` becomes `+0`
            // as there).
            nu.resize(nu.len().max(rows * n), 0.0);
            for (q, &(i, s)) in objs.iter().enumerate() {
                let p = s * m.b[i];
                cst[q] += p;
                let cmag = 0.0f64.abs() + p.abs();
                let wmag = 0.0 + s.abs() * rowmag[j][i];
                err[q] += g * (cmag + wmag);
                let w = m.dense_row(i);
                for (o, &t) in nu[q * n..(q + 1) * n].iter_mut().zip(cols) {
                    *o = 0.0 + s * w[t];
                }
            }
        } else {
            let lay = &live.layers[j];
            for (q, c) in cst.iter_mut().enumerate() {
                let row = &mu[q * k..(q + 1) * k];
                let mut cmag = c.abs();
                let mut wmag = 0.0;
                for (&mi, &i) in row.iter().zip(&lay.idx) {
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
            // Every entry is written by the product: no zeroing.
            nu.resize(nu.len().max(rows * n), 0.0);
            let nnz = mu[..r * k].iter().filter(|v| **v != 0.0).count();
            if nnz * SPARSE_BELOW < r * k {
                // Mostly zero coefficients: the row loop's axpy over the non-zero ones
                // does less work than the blocks (the same sums, see the module's note).
                for q in 0..r {
                    let out = &mut nu[q * n..(q + 1) * n];
                    out.fill(0.0);
                    for (p, &mi) in mu[q * k..(q + 1) * k].iter().enumerate() {
                        if mi == 0.0 {
                            continue;
                        }
                        for (o, &wt) in out.iter_mut().zip(&lay.w[p * n..(p + 1) * n]) {
                            *o += mi * wt;
                        }
                    }
                }
            } else {
                product(&mu, k, rows, &lay.w, n, &mut nu);
            }
        }
        if j == 0 {
            break;
        }
        k = n;
        // Every entry of the objectives' rows is written below; the padding rows are 0.
        mu.resize(mu.len().max(rows * k), 0.0);
        mu[r * k..rows * k].fill(0.0);
        let lay = &live.layers[j - 1];
        if lay.relu {
            // `relax_relu`'s operations, in its order: it skips a coefficient `v == 0`,
            // which here is `+0` (see the module's note), so copying it changes nothing.
            let (b, sl) = (&pre[j - 1], &slopes[j - 1]);
            for q in 0..r {
                let v = &nu[q * k..(q + 1) * k];
                let z = &mut mu[q * k..(q + 1) * k];
                for &p in &lay.on {
                    z[p] = v[p];
                }
                let (c, e) = (&mut cst[q], &mut err[q]);
                for &p in &lay.un {
                    let t = lay.idx[p];
                    let (l, u) = b[t];
                    let v = v[p];
                    z[p] = 0.0;
                    if v == 0.0 {
                        continue;
                    }
                    if v < 0.0 {
                        let s = sl[t];
                        z[p] = v * s;
                        let cc = -(v * s) * l;
                        *c += cc;
                        *e += 2.0 * f64::EPSILON * (z[p].abs() * l.abs().max(u.abs()) + cc.abs())
                            + f64::EPSILON * c.abs();
                    } else if relu::default_lower_slope(l, u) == 1.0 {
                        z[p] = v;
                    }
                }
            }
        } else {
            mu[..r * k].copy_from_slice(&nu[..r * k]);
        }
    }
    (0..r)
        .map(|q| Linear {
            coef: nu[q * n..(q + 1) * n].to_vec(),
            cst: cst[q],
            slack: inflate(err[q]),
        })
        .collect()
}
