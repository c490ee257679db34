//! Settings of a system-file reachability run: the run's settings and their defaults,
//! the measures (affine expressions of the states) reported over the sets, the
//! network-error ladder and the run's errors.

use super::flow::TmFlowSettings;
use samara_num::{Interval, Scalar, Tm};
use samara_system::{GoalKind, System, When};
use serde::{Deserialize, Serialize};

/// Settings of a system reachability run.
#[derive(Clone, Debug)]
pub struct SystemReachSettings {
    /// Order of the Taylor models (default 4).
    pub order: usize,
    /// Largest number of sub-boxes of the initial set (default 256).
    pub max_boxes: usize,
    /// Simulated flights for falsification before the sets (default 200).
    pub samples: usize,
    /// Seed of the random starts.
    pub seed: u64,
    /// The flowpipe's settings.
    pub flow: TmFlowSettings,
    /// Wall-clock budget; the run stops splitting and reports `unknown` when it is
    /// spent (default: none).
    pub timeout: samara_num::Timeout,
    /// Re-parameterise the set at a control instant when its remainders have grown
    /// (`precondition`; default on).
    pub precondition: bool,
    /// How the network step's error enters the set (`None`: chosen per run, see
    /// [`NetworkError`]; default).
    pub network_error: Option<NetworkError>,
    /// Affine functions of the state whose range at the horizon the run reports, on
    /// the sets and on the flights (default none).
    pub measures: Vec<Measure>,
}

/// An affine function of the state, `offset + coef . x`, whose range at the horizon a
/// run reports twice: enclosed by the sets and spread by the simulated flights. Their
/// ratio is the overestimation that the width criteria of a benchmark measure (the
/// glider's `x + y`: issue 14's "x + y width at t = 20 at most 2x the spread").
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Measure {
    /// What it is called in reports (`x + y`, a goal's text).
    pub name: String,
    /// Coefficients, one per state.
    pub coef: Vec<f64>,
    /// Constant term.
    pub offset: f64,
}

impl Measure {
    /// Its value at one state (f64, for flights).
    pub fn at(&self, x: &[f64]) -> f64 {
        self.offset + self.coef.iter().zip(x).map(|(a, v)| a * v).sum::<f64>()
    }

    /// A sound enclosure over a set: on the Taylor models (the states' dependence
    /// kept), met with the interval sum over the hull (both enclose it).
    pub(crate) fn over(&self, x: &[Tm], hull: &[Interval]) -> Interval {
        let mut by_hull = Interval::point(self.offset);
        for (a, h) in self.coef.iter().zip(hull) {
            if *a != 0.0 {
                by_hull += Interval::point(*a) * *h;
            }
        }
        if x.is_empty() {
            return by_hull;
        }
        // Both hold every value; `meet` keeps the hull's where the other is not finite
        // (a model with a NaN is the whole line) or, by rounding, misses it.
        crate::taylor_step::meet(affine_on(&self.coef, self.offset, x).bound(), by_hull)
    }
}

/// `b + a . x` on Taylor models (the terms with `a_i = 0` skipped): an affine function
/// of the states with their dependence kept, for affine bands and measures.
pub(crate) fn affine_on(a: &[f64], b: f64, x: &[Tm]) -> Tm {
    let mut v = Tm::cst(b);
    for (ai, xi) in a.iter().zip(x) {
        if *ai != 0.0 {
            v += xi.clone() * *ai;
        }
    }
    v
}

/// The measures a system file's goals give: the expression of every affine band
/// checked at the end (named by the goal's text).
pub fn end_band_measures(sys: &System) -> Vec<Measure> {
    sys.goals
        .iter()
        .filter_map(|g| match (&g.kind, &g.when) {
            (
                GoalKind::Band {
                    linear: Some((a, b)),
                    ..
                },
                When::End,
            ) => Some(Measure {
                name: g.text.clone(),
                coef: a.clone(),
                offset: *b,
            }),
            _ => None,
        })
        .collect()
}

/// A measure's range at the horizon: the sets' enclosure (hull over the sub-boxes;
/// `None` unless every sub-box has sets there) and the flights' spread.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MeasureRange {
    /// The measure's name.
    pub name: String,
    /// Enclosure by the sets.
    pub enclosure: Option<[f64; 2]>,
    /// Range over the simulated flights.
    pub sampled: Option<[f64; 2]>,
    /// Enclosure width over sampled width (where both exist and the latter is > 0).
    pub ratio: Option<f64>,
}

/// How the error of the network step (CROWN's gap, the remainder of the controller's
/// Taylor model) enters the set that the plant then carries over the period.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NetworkError {
    /// As an interval remainder of each input: cheapest, but the states the input
    /// drives lose their correlation through it.
    Interval,
    /// As a fresh parameter per input and period (a symbolic remainder, as a
    /// zonotope's new generator or the predicate variable of NNV's star sets), so the
    /// flow keeps the states it drives correlated; at most `extra` parameters beyond
    /// the state count are kept before the set is re-parameterised (`precondition`),
    /// and never more than the term budget of the order allows.
    Symbolic {
        /// Parameters allowed beyond the number of states.
        extra: usize,
    },
}

impl NetworkError {
    /// A mode by name: `interval`, `symbolic` (20 extra parameters), `symbolic:N`
    /// (`N` from 1 to 256) or `auto` (`None`: chosen per run). The error says what to give.
    pub fn parse(v: &str) -> Result<Option<NetworkError>, String> {
        Ok(match v {
            "auto" => None,
            "interval" => Some(NetworkError::Interval),
            "symbolic" => Some(NetworkError::Symbolic { extra: 20 }),
            _ => {
                let n: usize = v
                    .strip_prefix("symbolic:")
                    .and_then(|n| n.parse().ok())
                    .filter(|n| (1..=256).contains(n))
                    .ok_or_else(|| "give `interval`, `symbolic`, `symbolic:N` (N = 1 to 256 extra parameters; past the term budget of the order, N is lowered) or `auto`".to_string())?;
                Some(NetworkError::Symbolic { extra: n })
            }
        })
    }
}

/// The modes tried on the whole initial set when the run chooses (`network_error:
/// None`), cheapest first, each with the largest Taylor-model order it uses (`None`:
/// the run's): the first to decide the goals is kept; when none does, the sub-boxes
/// are flown with the one whose flight got furthest. Symbolic remainders go with
/// order 3: the parameters they add cost less there, and on TORA, the unicycle and
/// NAV order 3 with 20 extra parameters decides where order 4 with 6 or 19 does not
/// (docs/reach.md).
pub const NETWORK_ERROR_LADDER: [(NetworkError, Option<usize>); 2] = [
    (NetworkError::Interval, None),
    (NetworkError::Symbolic { extra: 20 }, Some(3)),
];

impl Default for SystemReachSettings {
    fn default() -> Self {
        SystemReachSettings {
            order: 4,
            max_boxes: 256,
            samples: 200,
            seed: 1,
            flow: TmFlowSettings::default(),
            timeout: samara_num::Timeout::none(),
            precondition: true,
            network_error: None,
            measures: Vec::new(),
        }
    }
}

/// Why a run could not start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SystemReachError {
    /// The network does not fit the system.
    #[error("the network has {n_in} inputs and {n_out} outputs; the system observes {obs} values and reads {reads} network outputs: use the controller made for this system")]
    Shape {
        /// Network inputs.
        n_in: usize,
        /// Network outputs.
        n_out: usize,
        /// Values the system observes.
        obs: usize,
        /// Network outputs the system reads.
        reads: usize,
    },
    /// A setting is out of range.
    #[error("{0}")]
    Setting(String),
    /// The simulation of a start failed.
    #[error("simulating a start failed: {0}")]
    Simulation(String),
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A measure keeps the states' dependence (x - x is 0 on the Taylor models, [-2, 2]
    /// on the hull), and a model with a NaN (the whole line) leaves the hull's bound.
    #[test]
    fn measures_keep_dependence_and_survive_nan_models() {
        let m = Measure {
            name: "a - b".into(),
            coef: vec![1.0, -1.0],
            offset: 0.5,
        };
        let x = vec![Tm::var(0, 1, 2), Tm::var(0, 1, 2)];
        let hull = vec![Interval::new(-1.0, 1.0); 2];
        let r = m.over(&x, &hull);
        assert!(r.lo <= 0.5 && 0.5 <= r.hi && r.hi - r.lo < 1e-12, "{r:?}");
        assert_eq!(m.at(&[3.0, 1.0]), 2.5);
        let nan = vec![Tm::cst(f64::NAN), Tm::cst(0.0)];
        let r = m.over(&nan, &hull);
        assert!(r.lo <= -1.5 && r.hi >= 2.5, "{r:?}");
    }
}
