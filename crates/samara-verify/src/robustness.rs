//! Local robustness sweeps over a data set (the case study's P5), computing each point's
//! exact extreme outputs over each eps-ball once and deriving every (eps, L) cell.
//!
//! - Published form: `|f(x') - ref| <= L / eps` for all x' in the ball, with `ref` the
//!   data label or `f(x)`. Per point: `dev = max(|max f - ref|, |min f - ref|)` over the
//!   ball, exact (branch and bound, or a closed form when every ReLU is stable on the
//!   ball).
//! - Intended (Lipschitz) form: `|f(x') - f(x)| <= L ||x' - x||_inf`. Per point: the
//!   local Lipschitz certificate, the largest gradient 1-norm (the dual of the infinity
//!   norm) over the activation regions that meet the ball, each region's presence decided
//!   by an LP with its phases fixed (Jordan & Dimakis, "Exactly computing the local
//!   Lipschitz constant of ReLU networks", NeurIPS 2020), and a lower bound (the gradient
//!   1-norm of the region containing x when x is interior, which secants from x approach).
//!   A cell is proved when the certificate is <= L, violated when the lower bound is > L,
//!   unknown in between (the secant from x need not reach the steepest region's slope).

use crate::net::{affine_bounds, PwlNet};
use crate::{optimise, Prepared, Settings};
use rayon::prelude::*;
use samara_nn::Network;
use samara_spec::normal::{Application, Goal, LinExpr, Query, Sense, Var};
use std::collections::HashMap;

/// Which reference the published form compares with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reference {
    /// The data set's label (the column after the inputs).
    Label,
    /// The network's own output at the data point.
    Network,
}

/// Per-point, per-eps results.
#[derive(Clone, Debug, PartialEq)]
pub struct PointBall {
    /// Data row.
    pub index: usize,
    /// Radius.
    pub eps: f64,
    /// Sound lower bound of the output over the ball (exact when the search completed,
    /// up to the gap).
    pub f_min: f64,
    /// Sound upper bound of the output over the ball.
    pub f_max: f64,
    /// Reference value.
    pub reference: f64,
    /// Largest deviation from the reference: a sound upper bound, from `f_min`/`f_max`.
    pub max_deviation: f64,
    /// The largest deviation attained at a concrete point of the ball (the outputs of
    /// the best witnesses, re-evaluated): a lower bound of the true deviation.
    pub witnessed_deviation: f64,
    /// Why the extremes were not settled (the search was cut short), if so.
    pub unknown: Option<crate::UnknownReason>,
    /// Sound upper bound of the local Lipschitz constant (infinity-norm inputs).
    pub lipschitz_upper: f64,
    /// Lower bound of it.
    pub lipschitz_lower: f64,
}

/// Outcome of one table cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    /// Points proved.
    pub proved: usize,
    /// Points violated.
    pub violated: usize,
    /// Points unknown.
    pub unknown: usize,
}

/// Past `deadline` the pattern enumeration (up to 2^14 LPs) stops and the upper bound
/// is infinite (unknown).
fn gradient_bounds(
    net: &PwlNet,
    lo: &[f64],
    hi: &[f64],
    x: &[f64],
    deadline: Option<std::time::Instant>,
) -> (f64, f64) {
    // Interval bounds per ReLU layer over the ball; enumerate the unstable neurons'
    // phases (capped); the gradient 1-norm of each pattern's linear map.
    let mut a_lo = lo.to_vec();
    let mut a_hi = hi.to_vec();
    let mut unstable: Vec<(usize, usize)> = Vec::new();
    let mut phases: Vec<Vec<i8>> = Vec::new();
    for (k, (m, relu)) in net.maps.iter().enumerate() {
        let (zl, zh) = affine_bounds(m, &a_lo, &a_hi);
        if *relu {
            let ph: Vec<i8> = zl
                .iter()
                .zip(&zh)
                .map(|(l, h)| {
                    if *l >= 0.0 {
                        1
                    } else if *h <= 0.0 {
                        -1
                    } else {
                        0
                    }
                })
                .collect();
            for (i, p) in ph.iter().enumerate() {
                if *p == 0 {
                    unstable.push((phases.len(), i));
                }
            }
            phases.push(ph);
            a_lo = zl.iter().map(|v| v.max(0.0)).collect();
            a_hi = zh.iter().map(|v| v.max(0.0)).collect();
        } else {
            a_lo = zl;
            a_hi = zh;
        }
        let _ = k;
    }
    let grad_of = |ph: &[Vec<i8>]| -> f64 {
        // Row vector g = W_L D ... D W_1 for output 0.
        let mut rows: Vec<Vec<f64>> = Vec::new();
        let n0 = net.n_inputs();
        let mut jac: Vec<Vec<f64>> = (0..n0)
            .map(|i| (0..n0).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
            .collect();
        let mut r = 0;
        for (m, relu) in &net.maps {
            let mut next = vec![vec![0.0; n0]; m.out];
            for i in 0..m.out {
                for (j, w) in m.row(i).nonzeros() {
                    for c in 0..n0 {
                        next[i][c] += w * jac[j][c];
                    }
                }
            }
            if *relu {
                for (i, row) in next.iter_mut().enumerate() {
                    if ph[r][i] < 0 {
                        row.iter_mut().for_each(|v| *v = 0.0);
                    }
                }
                r += 1;
            }
            jac = next;
        }
        rows.push(jac[0].clone());
        rows[0].iter().map(|v| v.abs()).sum()
    };
    // Lower bound: the region containing x (phases from the point itself; ties count as
    // unknown and give no lower bound).
    let mut here: Vec<Vec<i8>> = Vec::new();
    let mut a = x.to_vec();
    let mut interior = true;
    for (m, relu) in &net.maps {
        let mut z = vec![0.0; m.out];
        m.apply_f64(&a, &mut z);
        if *relu {
            here.push(z.iter().map(|v| if *v > 0.0 { 1 } else { -1 }).collect());
            interior &= z.iter().all(|v| *v != 0.0);
            z.iter_mut().for_each(|v| *v = v.max(0.0));
        }
        a = z;
    }
    let lower = if interior { grad_of(&here) } else { 0.0 };
    if unstable.len() > 14 {
        return (lower, f64::INFINITY);
    }
    let mut upper = 0.0f64;
    for mask in 0..(1u32 << unstable.len()) {
        if deadline.is_some_and(|d| std::time::Instant::now() >= d) {
            return (lower, f64::INFINITY);
        }
        let mut ph = phases.clone();
        for (b, (l, i)) in unstable.iter().enumerate() {
            ph[*l][*i] = if mask >> b & 1 == 1 { 1 } else { -1 };
        }
        let g = grad_of(&ph);
        // Only activation regions that meet the ball count; a pattern is dropped only when
        // its LP is certified infeasible, so the maximum stays an upper bound.
        if g > upper && pattern_meets_box(net, lo, hi, &ph) {
            upper = g;
        }
    }
    // Relative safety margin for the rounding of the products above.
    (lower, upper * (1.0 + 1e-12) + 1e-300)
}

/// Whether the activation pattern `ph` (one sign per ReLU) can occur for inputs in the
/// box: an LP over the box with every ReLU's phase fixed; `false` only when the LP is
/// certified infeasible.
fn pattern_meets_box(net: &PwlNet, lo: &[f64], hi: &[f64], ph: &[Vec<i8>]) -> bool {
    use crate::lp::{Lp, LpResult};
    let n = lo.len();
    let mut lp = Lp {
        n,
        lo: lo.to_vec(),
        hi: hi.to_vec(),
        ..Default::default()
    };
    let (mut alo, mut ahi) = (lo.to_vec(), hi.to_vec());
    let mut prev: Vec<usize> = (0..n).collect();
    let mut r = 0;
    for (m, relu) in &net.maps {
        let (zl, zh) = affine_bounds(m, &alo, &ahi);
        let zs: Vec<usize> = (0..m.out).map(|i| lp.n + i).collect();
        lp.n += m.out;
        lp.lo.extend_from_slice(&zl);
        lp.hi.extend_from_slice(&zh);
        for i in 0..m.out {
            let mut row = vec![(zs[i], 1.0)];
            for (j, w) in m.row(i).nonzeros() {
                row.push((prev[j], -w));
            }
            lp.eq.push((row, m.b[i]));
        }
        if *relu {
            let az: Vec<usize> = (0..m.out).map(|i| lp.n + i).collect();
            lp.n += m.out;
            for i in 0..m.out {
                lp.lo.push(0.0);
                lp.hi.push(zh[i].max(0.0));
                if ph[r][i] > 0 {
                    lp.eq.push((vec![(az[i], 1.0), (zs[i], -1.0)], 0.0));
                    lp.le.push((vec![(zs[i], -1.0)], 0.0));
                } else {
                    lp.eq.push((vec![(az[i], 1.0)], 0.0));
                    lp.le.push((vec![(zs[i], 1.0)], 0.0));
                }
            }
            r += 1;
            alo = zl.iter().map(|v| v.max(0.0)).collect();
            ahi = zh.iter().map(|v| v.max(0.0)).collect();
            prev = az;
        } else {
            alo = zl;
            ahi = zh;
            prev = zs;
        }
    }
    lp.c = vec![0.0; lp.n];
    !matches!(lp.solve(), LpResult::Infeasible)
}

/// Per-point extremes over every ball. `data` rows: inputs (network units) then the
/// label. Each search has 30 s ([`sweep_with`] takes other settings).
pub fn sweep(
    net: &Network,
    rows: &[Vec<f64>],
    eps: &[f64],
    reference: Reference,
    domain: Option<&[(f64, f64)]>,
) -> Result<Vec<PointBall>, String> {
    let s = Settings {
        timeout: crate::Timeout::from_secs(30),
        ..Default::default()
    };
    sweep_with(net, rows, eps, reference, domain, &s)
}

/// [`sweep`] with the settings of each point's searches (time and node limits); a
/// search cut short leaves its point `unknown` in the cells it cannot settle.
pub fn sweep_with(
    net: &Network,
    rows: &[Vec<f64>],
    eps: &[f64],
    reference: Reference,
    domain: Option<&[(f64, f64)]>,
    settings: &Settings,
) -> Result<Vec<PointBall>, String> {
    sweep_until(net, rows, eps, reference, domain, settings, None)
}

/// [`sweep_with`] with a deadline for the whole sweep (a command's `--timeout`): each
/// search gets at most what is left of it (its own limit `settings.timeout` still
/// applies); searches after the deadline keep only their first bounds, and their points
/// are unknown where those do not settle them.
pub fn sweep_until(
    net: &Network,
    rows: &[Vec<f64>],
    eps: &[f64],
    reference: Reference,
    domain: Option<&[(f64, f64)]>,
    settings: &Settings,
    deadline: Option<std::time::Instant>,
) -> Result<Vec<PointBall>, String> {
    let within = |s: &Settings| match deadline {
        Some(d) => Settings {
            timeout: s.timeout.min(crate::Timeout::from_duration(
                d.saturating_duration_since(std::time::Instant::now()),
            )),
            ..*s
        },
        None => *s,
    };
    let pwl = PwlNet::from_network(net).map_err(|e| e.to_string())?;
    if net.n_outputs() != 1 {
        return Err(format!(
            "robustness needs a single-output network; this one has {}",
            net.n_outputs()
        ));
    }
    let n = net.n_inputs();
    let mut nets = HashMap::new();
    nets.insert("f".to_string(), net.clone());
    let prep = Prepared::new(&nets);
    // Each radius once (a repeated radius would count every point twice in its cells).
    let mut distinct: Vec<f64> = Vec::new();
    for e in eps {
        if !distinct.contains(e) {
            distinct.push(*e);
        }
    }
    let eps = &distinct;
    let tasks: Vec<(usize, f64)> = (0..rows.len())
        .flat_map(|i| eps.iter().map(move |e| (i, *e)))
        .collect();
    let out: Vec<Result<PointBall, String>> = tasks
        .par_iter()
        .map(|&(i, e)| {
            let x = &rows[i][..n];
            let refv = match reference {
                Reference::Label => *rows[i]
                    .get(n)
                    .ok_or_else(|| format!("row {i} has no label column"))?,
                Reference::Network => net.eval_f64(x)[0],
            };
            let input_box: Vec<(f64, f64)> = x
                .iter()
                .enumerate()
                .map(|(k, v)| {
                    let (l, h) = (v - e, v + e);
                    match domain {
                        Some(d) => (l.max(d[k].0), h.min(d[k].1)),
                        None => (l, h),
                    }
                })
                .collect();
            let mut q = Query {
                name: format!("p5[{i}]"),
                applications: vec![Application {
                    network: "f".into(),
                    n_inputs: n,
                    n_outputs: 1,
                    input_box: input_box.clone(),
                }],
                free_vars: vec![],
                region: vec![vec![]],
                goal: Goal::Optimise {
                    objective: LinExpr {
                        terms: vec![(Var::Output { app: 0, index: 0 }, 1.0)],
                        constant: 0.0,
                    },
                    sense: Sense::Max,
                    label: "f".into(),
                },
            };
            let hi = optimise(&q, &prep, &within(settings)).map_err(|e| e.to_string())?;
            if let Goal::Optimise { sense, .. } = &mut q.goal {
                *sense = Sense::Min;
            }
            let lo = optimise(&q, &prep, &within(settings)).map_err(|e| e.to_string())?;
            // Sound extremes: the bounds (upper for max, lower for min); an incomplete
            // search keeps its sound bounds (which may still prove a cell) and its
            // witnesses (which may still refute one), and says why it stopped.
            let (f_max, f_min) = (hi.bound, lo.bound);
            let unknown = hi.unknown.clone().or(lo.unknown.clone());
            let witnessed_deviation = [hi.value, lo.value]
                .iter()
                .flatten()
                .map(|v| (v - refv).abs())
                .fold(f64::NEG_INFINITY, f64::max);
            let (bl, bh): (Vec<f64>, Vec<f64>) = input_box.iter().copied().unzip();
            let (ll, lu) = gradient_bounds(&pwl, &bl, &bh, x, deadline);
            Ok(PointBall {
                index: i,
                eps: e,
                f_min,
                f_max,
                reference: refv,
                max_deviation: (f_max - refv).abs().max((refv - f_min).abs()),
                witnessed_deviation,
                unknown,
                lipschitz_upper: lu,
                lipschitz_lower: ll,
            })
        })
        .collect();
    out.into_iter().collect()
}

/// The published-form cell: `dev <= L / eps`. Each point counts once per distinct
/// `eps` of the sweep (pass distinct radii to [`sweep`]).
pub fn published_cell(points: &[PointBall], eps: f64, l: f64) -> Cell {
    let mut c = Cell {
        proved: 0,
        violated: 0,
        unknown: 0,
    };
    for p in points.iter().filter(|p| p.eps == eps) {
        // Proved from the sound bound, violated only from a concrete witness; the gap
        // between them (or a search cut short) is unknown.
        if p.max_deviation <= l / eps {
            c.proved += 1;
        } else if p.witnessed_deviation > l / eps {
            c.violated += 1;
        } else {
            c.unknown += 1;
        }
    }
    c
}

/// The intended-form cell: local Lipschitz constant `<= L`.
pub fn lipschitz_cell(points: &[PointBall], eps: f64, l: f64) -> Cell {
    let mut c = Cell {
        proved: 0,
        violated: 0,
        unknown: 0,
    };
    for p in points.iter().filter(|p| p.eps == eps) {
        // A radius-0 ball holds x alone: |f(x) - f(x)| = 0 <= L * 0.
        if p.eps == 0.0 || p.lipschitz_upper <= l {
            c.proved += 1;
        } else if p.lipschitz_lower > l {
            c.violated += 1;
        } else {
            c.unknown += 1;
        }
    }
    c
}
