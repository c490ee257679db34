//! Simulated trajectories from the initial box (falsification and figures) and the check
//! that a run's enclosures contain them.

use crate::settings::ReachSettings;
use rayon::prelude::*;
use samara_nn::Network;
use samara_plant::Plant;
use samara_sim::{fly, Integrator, LoopSettings, NetworkController};
use serde::Serialize;

/// A simulated trajectory: control instants only.
#[derive(Clone, Debug, Serialize)]
pub struct Sample {
    /// Initial state.
    pub initial: Vec<f64>,
    /// States at t = 0, period, 2 period, ...
    pub states: Vec<Vec<f64>>,
    /// Dense (x, y) points for figures.
    pub xy: Vec<(f64, f64)>,
    /// Dense (t, x + y).
    pub txy: Vec<(f64, f64)>,
}

/// Simulate `n` trajectories from the initial box (end points of every parameter
/// first, then uniform random points) with DOP853 at rtol 1e-10, atol 1e-12.
pub fn simulate_samples(plant: &Plant, net: &Network, s: &ReachSettings, n: usize) -> Vec<Sample> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(s.seed);
    let mut starts: Vec<Vec<f64>> = s.corners().into_iter().take(n).collect();
    while starts.len() < n {
        starts.push(
            s.init
                .iter()
                .map(|&(a, b)| if b > a { rng.gen_range(a..=b) } else { a })
                .collect(),
        );
    }
    starts
        .par_iter()
        .filter_map(|x0| simulate_one(plant, net, s, x0))
        .collect()
}

/// One simulated trajectory from `x0`, as [`simulate_samples`] flies each of its starts
/// (DOP853 at rtol 1e-10, atol 1e-12; the run's period, horizon, clip and reset
/// filter); `None` if the flight fails. Deterministic: the same start gives the same
/// trajectory bit for bit (what re-checking a sampled counterexample relies on).
pub fn simulate_one(plant: &Plant, net: &Network, s: &ReachSettings, x0: &[f64]) -> Option<Sample> {
    let ls = LoopSettings {
        period: s.period,
        horizon: s.horizon,
        integrator: Integrator::Dop853(Default::default()),
        reset_filter: s.reset_filter,
        output_step: Some(sample_step(s.period)),
    };
    let mut c = NetworkController::new(net.clone(), s.clip, "net");
    let f = fly(plant, &mut c, x0, &ls).ok()?;
    let mut states = vec![x0.to_vec()];
    states.extend(f.steps.iter().map(|r| r.state_end.clone()));
    let xy = f.dense.iter().map(|(_, st, _)| (st[4], st[5])).collect();
    let txy = f
        .dense
        .iter()
        .map(|(t, st, _)| (t, st[4] + st[5]))
        .collect();
    Some(Sample {
        initial: x0.to_vec(),
        states,
        xy,
        txy,
    })
}

/// Output spacing of the sampled trajectories: 0.05, or the nearest finer step that
/// divides the period when 0.05 does not (a step that does not divide the period makes
/// every sampled flight fail, leaving no samples at all).
fn sample_step(period: f64) -> f64 {
    let q = period / 0.05;
    if (q - q.round()).abs() <= 1e-9 * q.max(1.0) && q.round() >= 1.0 {
        0.05
    } else {
        period / q.ceil().max(1.0)
    }
}
