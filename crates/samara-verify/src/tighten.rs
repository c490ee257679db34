//! LP-based tightening of each neuron's pre-activation bounds.
//!
//! Layer by layer, for every ReLU neuron that the current (interval and DeepPoly)
//! bounds leave unstable, two LPs give the largest and the smallest value of its
//! pre-activation `z_k[i] = W_k[i] . a_{k-1} + b_k[i]` over the triangle relaxation of
//! the layers before it (Ehlers 2017), the input box and the query's constraints on the
//! inputs alone. Each LP bound is made sound from the dual by weak duality, exactly as
//! the engine's node bounds are ([`crate::lp`]), and the bias is added with outward
//! rounding; a failed solve falls back to the box bound (still sound, just loose). After
//! each layer the later layers' bounds are re-derived by interval propagation and
//! DeepPoly from the tightened ones, so the next layer's LPs see the tighter triangles.
//!
//! The per-neuron LPs of one layer are independent and solved in parallel with rayon.
//! Cost: two LPs per unstable neuron, each the size of a node LP up to that layer.
//!
//! The ReLU-phase branch and bound that applied it (lazily, see [`LpTighten`]) was
//! removed when every exact question moved to the optimiser of `samara-bounds`, which
//! tightens the earliest unstable layer by LP at each node itself; [`lp_tighten`]
//! stays as a tested bound routine (and [`LpTighten`] as a setting no search reads).
//! The notes below are from when the phase search used it.
//!
//! Measured (2-core machine shared with other jobs; `critical_table` and
//! `lp_tighten_bench` examples, and `samara critical --lp-tighten`): over the case
//! study's whole input domain DeepPoly is already close to the LP bounds (the
//! 6-64-32-1 network: 26 unstable neurons before, 23 after; the 6-6-4-1 ones: none
//! stabilised), so tightening saves few nodes: P1-P4 CPU time with `Root` is equal on
//! three published networks, halved on `adversarial_model_norm` (its P4 needs 297
//! nodes without, about 100 with), equal on the 6-64-32-1 network through the
//! case-study queries, and 20 % slower through `samara critical` (its P1 search ends
//! soon after the delayed tightening). `Depth(d)` with `d >= 1` is slower everywhere.
//! Hence the default `Off`.

use crate::lp::{Lp, LpResult, Row};
use crate::net::{affine_bounds, clamp_to_phases, deeppoly, down, up, PwlNet};
use rayon::prelude::*;

/// When the removed ReLU-phase search tightened pre-activation bounds with LPs (a
/// [`crate::Settings`] field that no search reads any more; see the module notes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LpTighten {
    /// Interval and DeepPoly bounds only.
    #[default]
    Off,
    /// Once, for the root problem, delayed until the search has solved as many node
    /// LPs as the tightening will (two per unstable neuron); every later node uses the
    /// tightened bounds. A search that settles in a few nodes never pays for it.
    Root,
    /// At every node with at most this many fixed ReLU phases, when its LP leaves it
    /// to be branched on (the LP is then solved again); children inherit the
    /// tightened bounds. `Depth(0)`: the root, at once.
    Depth(usize),
}

impl LpTighten {
    /// Whether a node with `depth` fixed phases is tightened when it is branched on.
    pub fn at(self, depth: usize) -> bool {
        match self {
            LpTighten::Off | LpTighten::Root => false,
            LpTighten::Depth(d) => depth <= d,
        }
    }
}

/// A linear constraint on the inputs of one network: `sum coef * x[j] <= rhs`
/// (or `== rhs` when `eq`).
#[derive(Clone, Debug, PartialEq)]
pub struct InputConstraint {
    /// Sparse row over input indices.
    pub row: Row,
    /// Right-hand side.
    pub rhs: f64,
    /// Equality.
    pub eq: bool,
}

/// What a tightening pass did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TightenStats {
    /// LPs solved.
    pub lps: usize,
    /// Neurons whose bounds the LPs improved.
    pub improved: usize,
    /// Unstable neurons that the LPs made stable.
    pub stabilised: usize,
}

/// Interval bounds of every map's pre-activations over the box, with the phases
/// `fixed` (per ReLU map: 1 active, -1 inactive, 0 free) applied, then DeepPoly: the
/// engine's bounds at a node. `None` if the phases contradict the box.
#[allow(clippy::type_complexity)]
pub fn base_bounds(
    net: &PwlNet,
    x_lo: &[f64],
    x_hi: &[f64],
    fixed: &[Vec<i8>],
) -> Option<(Vec<Vec<f64>>, Vec<Vec<f64>>)> {
    let mut lo: Vec<Vec<f64>> = net
        .maps
        .iter()
        .map(|m| vec![f64::NEG_INFINITY; m.0.out])
        .collect();
    let mut hi: Vec<Vec<f64>> = net
        .maps
        .iter()
        .map(|m| vec![f64::INFINITY; m.0.out])
        .collect();
    propagate(net, x_lo, x_hi, fixed, &mut lo, &mut hi, 0).then_some((lo, hi))
}

/// Phases per map (`None` for maps without a ReLU).
fn phase_of<'a>(net: &PwlNet, fixed: &'a [Vec<i8>]) -> Vec<Option<&'a [i8]>> {
    let mut r = 0;
    net.maps
        .iter()
        .map(|(_, relu)| {
            if *relu {
                r += 1;
                Some(fixed[r - 1].as_slice())
            } else {
                None
            }
        })
        .collect()
}

/// Re-derive the bounds of maps `from..` by intervals (intersected with the current
/// ones) and then DeepPoly over the whole network. `false` if some bound is empty.
fn propagate(
    net: &PwlNet,
    x_lo: &[f64],
    x_hi: &[f64],
    fixed: &[Vec<i8>],
    lo: &mut [Vec<f64>],
    hi: &mut [Vec<f64>],
    from: usize,
) -> bool {
    let ph = phase_of(net, fixed);
    let clip = |k: usize, lo: &mut [Vec<f64>], hi: &mut [Vec<f64>]| -> bool {
        if let Some(p) = ph[k] {
            clamp_to_phases(p, &mut lo[k], &mut hi[k]);
        }
        lo[k].iter().zip(&hi[k]).all(|(l, h)| l <= h)
    };
    let act = |k: usize, lo: &[Vec<f64>], hi: &[Vec<f64>]| -> (Vec<f64>, Vec<f64>) {
        if k == 0 {
            return (x_lo.to_vec(), x_hi.to_vec());
        }
        if net.maps[k - 1].1 {
            (
                lo[k - 1].iter().map(|v| v.max(0.0)).collect(),
                hi[k - 1].iter().map(|v| v.max(0.0)).collect(),
            )
        } else {
            (lo[k - 1].clone(), hi[k - 1].clone())
        }
    };
    for k in from..net.maps.len() {
        let (al, ah) = act(k, lo, hi);
        let (zl, zh) = affine_bounds(&net.maps[k].0, &al, &ah);
        for i in 0..zl.len() {
            lo[k][i] = lo[k][i].max(zl[i]);
            hi[k][i] = hi[k][i].min(zh[i]);
        }
        if !clip(k, lo, hi) {
            return false;
        }
    }
    if net.maps.len() > 1 {
        deeppoly(net, x_lo, x_hi, fixed, lo, hi);
        for k in 0..net.maps.len() {
            if !clip(k, lo, hi) {
                return false;
            }
        }
    }
    true
}

/// The LP relaxation of maps `0..k` (variables: inputs, then per map `z` and, after a
/// ReLU, `a`) and the offset of map `k`'s input variables.
#[allow(clippy::too_many_arguments)]
fn prefix_lp(
    net: &PwlNet,
    x_lo: &[f64],
    x_hi: &[f64],
    inputs: &[InputConstraint],
    fixed: &[Vec<i8>],
    lo: &[Vec<f64>],
    hi: &[Vec<f64>],
    k: usize,
) -> (Lp, usize) {
    let ph = phase_of(net, fixed);
    let mut lp = Lp {
        n: net.n_inputs(),
        lo: x_lo.to_vec(),
        hi: x_hi.to_vec(),
        ..Default::default()
    };
    for c in inputs {
        if c.eq {
            lp.eq.push((c.row.clone(), c.rhs));
        } else {
            lp.le.push((c.row.clone(), c.rhs));
        }
    }
    let mut prev = 0;
    for j in 0..k {
        let (m, relu) = &net.maps[j];
        let zo = lp.n;
        lp.n += m.out;
        lp.lo.extend_from_slice(&lo[j]);
        lp.hi.extend_from_slice(&hi[j]);
        lp.push_affine(m, zo, prev);
        if !*relu {
            prev = zo;
            continue;
        }
        let p = ph[j].expect("relu map");
        let a = lp.n;
        lp.n += m.out;
        lp.lo.extend(lo[j].iter().map(|v| v.max(0.0)));
        lp.hi.extend(hi[j].iter().map(|v| v.max(0.0)));
        lp.push_relu(a, zo, &lo[j], &hi[j], p);
        prev = a;
    }
    lp.c = vec![0.0; lp.n];
    (lp, prev)
}

/// Tighten `lo`/`hi` (per map, per neuron; tightened in place and never loosened) with
/// LPs, layer by layer, for the neurons of ReLU maps that are unstable (`lo < 0 < hi`,
/// phase free). `inputs` are linear constraints on the inputs that also hold (they make
/// the first layer worth tightening too). Returns `None` when an LP proves the phases,
/// the box and `inputs` inconsistent (the node is empty).
#[allow(clippy::too_many_arguments)]
pub fn lp_tighten(
    net: &PwlNet,
    x_lo: &[f64],
    x_hi: &[f64],
    inputs: &[InputConstraint],
    fixed: &[Vec<i8>],
    lo: &mut [Vec<f64>],
    hi: &mut [Vec<f64>],
    parallel: bool,
) -> Option<TightenStats> {
    let ph = phase_of(net, fixed);
    let mut stats = TightenStats::default();
    let first = if inputs.is_empty() { 1 } else { 0 };
    for k in first..net.maps.len() {
        let Some(p) = ph[k] else { continue };
        let todo: Vec<usize> = (0..lo[k].len())
            .filter(|&i| p[i] == 0 && lo[k][i] < 0.0 && hi[k][i] > 0.0)
            .collect();
        if todo.is_empty() {
            continue;
        }
        let (base, prev) = prefix_lp(net, x_lo, x_hi, inputs, fixed, lo, hi, k);
        let m = &net.maps[k].0;
        // Sound max of s * W_k[i] . a_{k-1} (s = 1 upper, -1 lower); None if infeasible.
        let solve = |&(i, s): &(usize, f64)| -> Option<f64> {
            let mut lp = base.clone();
            for t in 0..m.inp {
                lp.c[prev + t] = s * m.w[i * m.inp + t];
            }
            match lp.solve() {
                LpResult::Infeasible => None,
                LpResult::Bound { upper, .. } | LpResult::Failed { upper } => Some(upper),
            }
        };
        let tasks: Vec<(usize, f64)> = todo.iter().flat_map(|&i| [(i, 1.0), (i, -1.0)]).collect();
        let res: Vec<Option<f64>> = if parallel {
            tasks.par_iter().map(solve).collect()
        } else {
            tasks.iter().map(solve).collect()
        };
        stats.lps += tasks.len();
        let before: Vec<(f64, f64)> = todo.iter().map(|&i| (lo[k][i], hi[k][i])).collect();
        for (&(i, s), r) in tasks.iter().zip(res) {
            let v = r?;
            let b = m.b[i];
            if s > 0.0 {
                hi[k][i] = hi[k][i].min(up(v + b));
            } else {
                lo[k][i] = lo[k][i].max(down(b - v));
            }
        }
        for (&i, b) in todo.iter().zip(before) {
            if (lo[k][i], hi[k][i]) != b {
                stats.improved += 1;
            }
            if lo[k][i] >= 0.0 || hi[k][i] <= 0.0 {
                stats.stabilised += 1;
            }
        }
        if !propagate(net, x_lo, x_hi, fixed, lo, hi, k + 1) {
            return None;
        }
    }
    Some(stats)
}
