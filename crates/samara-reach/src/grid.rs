//! A fixed grid over the initial set, each cell its own Taylor-model run
//! ([`reach_system`]), so that a covering run that needs hundreds of cells (issue 14's
//! six-state glider set: about 650 cells of a third of each velocity and angle interval
//! and an eighth of the height, 300-550 s each) can be cut into independent parts: a
//! range of cells per process, per Slurm array task or per Ray task, and the parts merged
//! afterwards ([`merge_parts`]).
//!
//! Data flow: `pieces[i]` equal parts along state `i` make `prod(pieces)` cells,
//! numbered in row-major order (the last state fastest). Each cell of a range is flown by
//! [`reach_system`] with the run's settings and its own sub-box budget (`max_boxes` per
//! cell), `samples / cells` falsification flights (at least the cell's centre and
//! corners) seeded by the cell's number, and what is left of the run's wall-clock budget.
//! The results of consecutive ranges merge into the result of their union:
//! - verdict: `violated` if a cell's flight misses a goal (the first such cell), else
//!   `unknown` if a cell is undecided, else `proved` (or `none` without goals);
//! - `covered`: the cells' covered shares weighted by their number (cells have equal
//!   volume);
//! - hulls and measures: the hulls over the cells (a measure's enclosure only when every
//!   cell encloses it);
//! - leaves and flights: concatenated in cell order.
//!
//! Without a wall-clock budget, and where no cell's sub-box budget binds, each cell's
//! result does not depend on which process flew it, so the merge of any cut of the cells
//! into ranges is the one-process grid run (checked in `tests/grid.rs`).

use crate::taylor::SystemViolation;
use crate::taylor::{
    reach_system, MeasureRange, SystemReach, SystemReachError, SystemReachSettings, SystemVerdict,
};
use rayon::prelude::*;
use samara_nn::Network;
use samara_system::System;
use std::ops::Range;
use std::time::Instant;

/// Most cells a grid may have.
pub const MAX_CELLS: usize = 100_000;

/// The number of cells of `pieces` (their product), checked against the initial set:
/// one entry per state, each at least 1, more than 1 only where the state's initial
/// interval has a width, and at most [`MAX_CELLS`] cells.
pub fn cell_count(sys: &System, pieces: &[usize]) -> Result<usize, SystemReachError> {
    if pieces.len() != sys.dim() {
        return Err(SystemReachError::Setting(format!(
            "the grid has {} entries for {} states: give one number of pieces per state",
            pieces.len(),
            sys.dim()
        )));
    }
    let mut n: usize = 1;
    for (i, &k) in pieces.iter().enumerate() {
        let (lo, hi) = sys.init[i];
        if k == 0 {
            return Err(SystemReachError::Setting(format!(
                "the grid cuts state {} into 0 pieces: give at least 1",
                sys.states[i]
            )));
        }
        if k > 1 && lo >= hi {
            return Err(SystemReachError::Setting(format!(
                "the grid cuts state {} into {k} pieces, but its initial value is the single point {lo}: cut only states with an initial interval",
                sys.states[i]
            )));
        }
        n = n.saturating_mul(k);
    }
    if n > MAX_CELLS {
        return Err(SystemReachError::Setting(format!(
            "the grid has {n} cells, more than {MAX_CELLS}: cut fewer states or into fewer pieces"
        )));
    }
    Ok(n)
}

/// The initial box of cell `c` (row-major, the last state fastest). Neighbouring cells
/// share their boundary values exactly, and the outer cells end on the initial set's
/// own ends, so the cells tile the initial set without a gap.
pub fn cell_box(init: &[(f64, f64)], pieces: &[usize], c: usize) -> Vec<(f64, f64)> {
    let mut idx = vec![0usize; pieces.len()];
    let mut r = c;
    for i in (0..pieces.len()).rev() {
        idx[i] = r % pieces[i];
        r /= pieces[i];
    }
    let edge = |i: usize, j: usize| -> f64 {
        let (lo, hi) = init[i];
        if j == 0 {
            lo
        } else if j == pieces[i] {
            hi
        } else {
            lo + (hi - lo) * (j as f64 / pieces[i] as f64)
        }
    };
    (0..pieces.len())
        .map(|i| (edge(i, idx[i]), edge(i, idx[i] + 1)))
        .collect()
}

/// The cells `cells` of the grid `pieces` over `sys`'s initial set, each flown by
/// [`reach_system`] (in parallel), merged into one result over the range (see the
/// module doc). `s.timeout` bounds the whole range; `s.max_boxes` each cell.
pub fn reach_cells(
    sys: &System,
    net: &Network,
    s: &SystemReachSettings,
    pieces: &[usize],
    cells: Range<usize>,
) -> Result<SystemReach, SystemReachError> {
    let total = cell_count(sys, pieces)?;
    if cells.start >= cells.end || cells.end > total {
        return Err(SystemReachError::Setting(format!(
            "cells {}..{} are not a non-empty range within the grid's {total} cells",
            cells.start, cells.end
        )));
    }
    let t0 = Instant::now();
    let samples = s.samples.div_ceil(total).max(1);
    let parts: Vec<Result<SystemReach, SystemReachError>> = cells
        .clone()
        .into_par_iter()
        .map(|c| {
            let mut cs = s.clone();
            cs.samples = samples;
            cs.seed = s.seed.wrapping_add(c as u64);
            // What is left of the range's budget (a cell started after it is spent
            // stops at once and reports so).
            cs.timeout = s.timeout.left(t0);
            let mut csys = sys.clone();
            csys.init = cell_box(&sys.init, pieces, c);
            reach_system(&csys, net, &cs)
        })
        .collect();
    let parts = parts.into_iter().collect::<Result<Vec<_>, _>>()?;
    let mut r = merge_parts(parts.into_iter().map(|p| (1, p)).collect());
    r.seconds = t0.elapsed().as_secs_f64();
    Ok(r)
}

/// Merge the results of consecutive cell ranges, each with its number of cells, in
/// cell order, into the result of their union (module doc). `seconds` is the sum of the
/// parts' (the compute time, not a wall time).
///
/// # Panics
/// If `parts` is empty.
pub fn merge_parts(parts: Vec<(usize, SystemReach)>) -> SystemReach {
    assert!(!parts.is_empty(), "merge_parts: no parts");
    let cells: usize = parts.iter().map(|(n, _)| n).sum();
    let covered = parts
        .iter()
        .map(|(n, p)| *n as f64 * p.covered)
        .sum::<f64>()
        / cells as f64;
    // Exactly 1 only when every part is (no rounding of a weighted mean).
    let covered = if parts.iter().all(|(_, p)| p.covered == 1.0) {
        1.0
    } else {
        covered.min(1.0 - f64::EPSILON)
    };
    let undecided: Vec<(usize, &str)> = parts
        .iter()
        .enumerate()
        .filter_map(|(i, (_, p))| match &p.verdict {
            SystemVerdict::Unknown { reason } => Some((i, reason.as_str())),
            _ => None,
        })
        .collect();
    let verdict = if let Some((_, p)) = parts
        .iter()
        .find(|(_, p)| matches!(p.verdict, SystemVerdict::Violated(SystemViolation { .. })))
    {
        p.verdict.clone()
    } else if let Some((_, first)) = undecided.first() {
        SystemVerdict::Unknown {
            reason: if parts.len() == 1 {
                first.to_string()
            } else {
                format!(
                    "{} of {} parts undecided; the first: {first}",
                    undecided.len(),
                    parts.len()
                )
            },
        }
    } else if parts
        .iter()
        .all(|(_, p)| matches!(p.verdict, SystemVerdict::NoGoal))
    {
        SystemVerdict::NoGoal
    } else {
        SystemVerdict::Proved
    };
    let hull = |rows: &dyn Fn(&SystemReach) -> &Vec<Vec<[f64; 2]>>| -> Vec<Vec<[f64; 2]>> {
        let n = parts.iter().map(|(_, p)| rows(p).len()).min().unwrap_or(0);
        (0..n)
            .map(|k| {
                let dim = rows(&parts[0].1)[k].len();
                (0..dim)
                    .map(|i| {
                        parts
                            .iter()
                            .fold([f64::INFINITY, f64::NEG_INFINITY], |a, (_, p)| {
                                let v = rows(p)[k][i];
                                [a[0].min(v[0]), a[1].max(v[1])]
                            })
                    })
                    .collect()
            })
            .collect()
    };
    let instants = hull(&|p: &SystemReach| &p.instants);
    let periods = hull(&|p: &SystemReach| &p.periods);
    let measures = (0..parts[0].1.measures.len())
        .map(|j| {
            let join = |a: Option<[f64; 2]>, b: Option<[f64; 2]>| match (a, b) {
                (Some(a), Some(b)) => Some([a[0].min(b[0]), a[1].max(b[1])]),
                (a, None) => a,
                (None, b) => b,
            };
            let enclosure = if parts
                .iter()
                .all(|(_, p)| p.measures.get(j).is_some_and(|m| m.enclosure.is_some()))
            {
                parts
                    .iter()
                    .fold(None, |a, (_, p)| join(a, p.measures[j].enclosure))
            } else {
                None
            };
            let sampled = parts.iter().fold(None, |a, (_, p)| {
                join(a, p.measures.get(j).and_then(|m| m.sampled))
            });
            let ratio = match (enclosure, sampled) {
                (Some(e), Some(s)) if s[1] > s[0] => Some((e[1] - e[0]) / (s[1] - s[0])),
                _ => None,
            };
            MeasureRange {
                name: parts[0].1.measures[j].name.clone(),
                enclosure,
                sampled,
                ratio,
            }
        })
        .collect();
    let first = &parts[0].1;
    let (system, network_error) = (first.system.clone(), first.network_error);
    let order = parts.iter().map(|(_, p)| p.order).max().unwrap_or(0);
    let seconds = parts.iter().map(|(_, p)| p.seconds).sum();
    let mut leaves = Vec::new();
    let mut flights = Vec::new();
    for (_, p) in parts {
        leaves.extend(p.leaves);
        flights.extend(p.flights);
    }
    SystemReach {
        system,
        verdict,
        instants,
        periods,
        boxes: leaves.len(),
        covered,
        order,
        // With `auto`, every cell chooses its own mode; the first cell's is reported.
        network_error,
        seconds,
        leaves,
        measures,
        flights,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Random grids over random boxes: the cells share their boundary values exactly,
    /// the outer ones end on the box's ends, and a random point lies in the cell its
    /// coordinates' pieces name (so no point of the box is left out).
    #[test]
    fn cells_tile_the_box_exactly() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..200 {
            let d = rng.gen_range(1..5);
            let init: Vec<(f64, f64)> = (0..d)
                .map(|_| {
                    let lo: f64 = rng.gen_range(-10.0..10.0);
                    (lo, lo + rng.gen_range(1e-6..5.0))
                })
                .collect();
            let pieces: Vec<usize> = (0..d).map(|_| rng.gen_range(1..8)).collect();
            let total: usize = pieces.iter().product();
            let cells: Vec<Vec<(f64, f64)>> =
                (0..total).map(|c| cell_box(&init, &pieces, c)).collect();
            for i in 0..d {
                // Along state i, the distinct cell intervals chain from lo to hi.
                let mut ends: Vec<(f64, f64)> = cells.iter().map(|c| c[i]).collect();
                ends.sort_by(|a, b| a.0.total_cmp(&b.0));
                ends.dedup();
                assert_eq!(ends.len(), pieces[i]);
                assert_eq!(ends[0].0, init[i].0);
                assert_eq!(ends[pieces[i] - 1].1, init[i].1);
                for w in ends.windows(2) {
                    assert_eq!(w[0].1, w[1].0);
                    assert!(w[0].0 < w[0].1);
                }
            }
            for _ in 0..50 {
                let x: Vec<f64> = init.iter().map(|&(l, h)| rng.gen_range(l..=h)).collect();
                let inside = cells
                    .iter()
                    .filter(|c| c.iter().zip(&x).all(|(b, v)| b.0 <= *v && *v <= b.1))
                    .count();
                assert!(inside >= 1, "{x:?} in no cell");
            }
        }
    }
}
