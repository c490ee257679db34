//! The typed contents of `results.json`: one type per stage result, so the stages, the
//! stage cache and the report read and write the same fields by name, and a cached
//! entry that no longer has the shape of its stage is recomputed instead of rendered
//! with holes.
//!
//! `results.json` has always been written with its keys in sorted order (it was a
//! `serde_json::Value`, whose maps are sorted); the fields below are therefore declared
//! in sorted order of their JSON names, so serialising a type gives the same bytes as
//! before. `results_are_written_in_sorted_key_order` checks it.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A computed real number as `results.json` holds it: finite numbers as numbers,
/// non-finite ones (a lost enclosure, a stage without a goal) as `null`, read back as
/// NaN. Formatting helpers show a non-finite value as `-` (or `?`), never as `NaN`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Real(pub f64);

impl Real {
    /// The value if it is finite.
    pub fn get(self) -> Option<f64> {
        self.0.is_finite().then_some(self.0)
    }

    /// `None` as NaN (written as `null`).
    pub fn of(v: Option<f64>) -> Real {
        Real(v.unwrap_or(f64::NAN))
    }

    /// Four decimals, or `-` where the number is not finite.
    pub fn f4(self) -> String {
        self.get()
            .map(|x| format!("{x:.4}"))
            .unwrap_or_else(|| "-".into())
    }

    /// As JSON writes it (`20.0`, `0.5`, `null`): the report quotes some settings in
    /// that form.
    pub fn json(self) -> String {
        serde_json::to_string(&self).unwrap_or_else(|_| "null".into())
    }
}

impl From<f64> for Real {
    fn from(x: f64) -> Self {
        Real(x)
    }
}

/// Real numbers of a slice.
pub fn reals(v: &[f64]) -> Vec<Real> {
    v.iter().map(|&x| Real(x)).collect()
}

/// A pair of real numbers (an interval `[lo, hi]`).
pub fn pair(v: [f64; 2]) -> [Real; 2] {
    [Real(v[0]), Real(v[1])]
}

impl Serialize for Real {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self.get() {
            Some(x) => s.serialize_f64(x),
            None => s.serialize_none(),
        }
    }
}

impl<'de> Deserialize<'de> for Real {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Ok(Real::of(Option::<f64>::deserialize(d)?))
    }
}

/// `results.json`: the run's header and every stage's result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Results {
    /// The command line, as recorded in the report.
    pub command_line: String,
    /// `quick` or `full`.
    pub mode: String,
    /// The samara version that produced the run.
    pub samara_version: String,
    /// Wall time of the run.
    pub seconds: f64,
    /// The specification P1-P4 were lowered from.
    pub spec: SpecDigest,
    /// The stages' results.
    pub stages: Stages,
}

/// The specification of a run: its file name and the FNV-1a hash of its text.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SpecDigest {
    /// The file name, as given.
    pub file: String,
    /// FNV-1a 64-bit hash of the text.
    pub fnv1a: String,
}

/// The results of the stages that ran, by stage name.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Stages {
    /// Stage 5: closed-loop flights.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub closed_loop: Option<FlightsResult>,
    /// Stage 1: the PID data set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data: Option<DataResult>,
    /// Stage 6: reachability.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reach: Option<ReachStageResult>,
    /// Stage 2: training.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub train: Option<TrainResult>,
    /// Stages 3-4: critical values and P5 tables.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub verify: Option<VerifyResult>,
}

impl Stages {
    /// The stored result of stage `name` as JSON (`null` if it has not run), for the
    /// stage cache.
    pub fn entry_json(&self, name: &str) -> serde_json::Value {
        fn j<T: Serialize>(v: &Option<T>) -> serde_json::Value {
            serde_json::to_value(v).unwrap_or(serde_json::Value::Null)
        }
        match name {
            "data" => j(&self.data),
            "train" => j(&self.train),
            "verify" => j(&self.verify),
            "closed_loop" => j(&self.closed_loop),
            "reach" => j(&self.reach),
            _ => serde_json::Value::Null,
        }
    }

    /// Restore stage `name`'s result from its cached JSON; false (and nothing changed)
    /// if the JSON does not have the stage's shape or the stage is unknown.
    pub fn restore(&mut self, name: &str, v: serde_json::Value) -> bool {
        fn put<T: serde::de::DeserializeOwned>(slot: &mut Option<T>, v: serde_json::Value) -> bool {
            match serde_json::from_value(v) {
                Ok(t) => {
                    *slot = Some(t);
                    true
                }
                Err(_) => false,
            }
        }
        match name {
            "data" => put(&mut self.data, v),
            "train" => put(&mut self.train, v),
            "verify" => put(&mut self.verify, v),
            "closed_loop" => put(&mut self.closed_loop, v),
            "reach" => put(&mut self.reach, v),
            _ => false,
        }
    }
}

/// Stage 1: the PID data set, its constants, and (with `--published`) how it compares
/// with the published files.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DataResult {
    /// x + y at the end of each PID flight.
    #[serde(rename = "final")]
    pub finals: Vec<FinalPoint>,
    /// Min-max constants of the data set: minima.
    pub normalisation_min: Vec<Real>,
    /// Min-max constants of the data set: ranges.
    pub normalisation_range: Vec<Real>,
    /// The first two rows of the published `Normalisation_Constants.csv`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub published_constants: Option<Vec<Vec<Real>>>,
    /// Largest difference between the published constants and the data's (raw units).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub published_constants_vs_data_max_abs: Option<Real>,
    /// Largest absolute difference from the published `Training_Data.csv`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub published_max_abs_deviation: Option<Real>,
    /// Rows of the published data set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub published_rows: Option<usize>,
    /// Rows of the regenerated data set.
    pub rows: usize,
}

/// Where one PID flight ends.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FinalPoint {
    /// x + y at t = 20.
    pub x_plus_y: Real,
    /// The start's y0.
    pub y0: Real,
}

/// Stage 2: the controllers samara trained, and the box and constants they were
/// trained over.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrainResult {
    /// The closed-loop method's rounds (null when it did not run).
    pub closed_loop: Option<ClosedLoopResult>,
    /// Upper corner of the data's box (raw units).
    pub domain_hi: Vec<Real>,
    /// Lower corner of the data's box (raw units).
    pub domain_lo: Vec<Real>,
    /// One row per training method.
    pub networks: Vec<TrainedNetwork>,
    /// Min-max constants the networks were trained in: minima.
    pub norm_min: Vec<Real>,
    /// Min-max constants the networks were trained in: ranges.
    pub norm_range: Vec<Real>,
}

/// One trained controller (the closed-loop row has no attack or MAE figures: null).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrainedNetwork {
    /// Mean deviation found by the attack on the test points.
    pub attack_mean: Real,
    /// Worst deviation found by the attack on the test points.
    pub attack_worst: Real,
    /// Training epochs.
    pub epochs: usize,
    /// Attack radius (normalised inputs).
    pub eps: Real,
    /// The ONNX file, relative to the output folder.
    pub file: String,
    /// Mean absolute error on the test points.
    pub mae: Real,
    /// The training method.
    pub method: String,
    /// Test R^2.
    pub r2: Real,
    /// R^2 against every PID data row.
    pub r2_all: Real,
    /// RMSE on the test points.
    pub rmse: Real,
    /// Wall time of the training.
    pub seconds: Real,
}

/// The closed-loop method: its setting, outcome and rounds.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ClosedLoopResult {
    /// Weight of the data MSE.
    pub data_weight: Real,
    /// Reach's enclosure of x + y at the horizon.
    pub enclosure: [Real; 2],
    /// The rounds figure.
    pub figure: String,
    /// The goal bound on |x + y|.
    pub goal_ystar: Real,
    /// Horizon.
    pub horizon: Real,
    /// Whether reach proved the goal.
    pub proved: bool,
    /// R^2 against every PID data row.
    pub r2_all: Real,
    /// The rounds.
    pub rounds: Vec<RoundRow>,
    /// Wall time.
    pub seconds: Real,
    /// Adam steps per round.
    pub steps_per_round: usize,
    /// The training loss's bound on |x + y|.
    pub training_bound: Real,
    /// Reach's verdict on the final network.
    pub verdict: String,
    /// The interval of y0.
    pub y0: [Real; 2],
}

/// One round of closed-loop training.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RoundRow {
    /// Starts added to the flight set after the round.
    pub added: Vec<Real>,
    /// Reach's enclosure of x + y at the horizon (null where lost).
    pub enclosure: [Real; 2],
    /// Loss at the end of the round.
    pub loss: Real,
    /// Sub-boxes of the round's reach run.
    pub max_leaves: usize,
    /// Data MSE.
    pub mse: Real,
    /// Closed-loop penalty.
    pub penalty: Real,
    /// R^2 against every PID data row.
    pub r2: Real,
    /// Round number.
    pub round: usize,
    /// The sampled range of x + y at the horizon.
    pub sampled: [Real; 2],
    /// Training plus reach time.
    pub seconds: Real,
    /// Flights in the training set.
    pub starts: usize,
    /// Adam steps taken.
    pub steps: usize,
    /// Reach's verdict.
    pub verdict: String,
}

/// Stages 3-4: critical values of P1-P4 and P5 tables for every network.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct VerifyResult {
    /// The P5 tables' Lipschitz constants (columns).
    #[serde(rename = "L")]
    pub l: Vec<Real>,
    /// The P5 tables' radii (rows).
    pub eps: Vec<Real>,
    /// One entry per network.
    pub networks: Vec<VerifiedNetwork>,
}

/// One network's critical values and P5 tables.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct VerifiedNetwork {
    /// P1-P4, in order.
    pub critical: Vec<CriticalRow>,
    /// Wall time of the four optimisations.
    pub critical_seconds: Real,
    /// The network's label.
    pub network: String,
    /// The P5 tables (null for a network without data in its units).
    pub p5: Option<P5Tables>,
}

/// One critical value: the search's value, bound, flags, and why it is incomplete.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CriticalRow {
    /// Whether the value is attained by a witness.
    pub attained: bool,
    /// The sound bound.
    pub bound: Real,
    /// Whether the search is complete (only a complete search makes a claim).
    pub complete: bool,
    /// The value (null: no counterexample for any value).
    pub critical: Real,
    /// The extreme of x + y over the input box.
    pub domain_extreme: Real,
    /// The property.
    pub property: String,
    /// Why the search is incomplete (null for a complete one).
    pub unknown_reason: Option<ReasonRow>,
    /// The property holds only vacuously at the value.
    pub vacuous: bool,
}

/// Why a search stopped short: a machine tag and the message.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ReasonRow {
    /// `timeout`, `node_limit`, ...
    pub kind: String,
    /// The message, with its fix.
    pub message: String,
}

/// The P5 tables of one network: shares of points proved, rows eps, columns L.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct P5Tables {
    /// The intended local-Lipschitz form.
    pub lipschitz: Vec<Vec<Real>>,
    /// Points left unknown by the Lipschitz form.
    pub lipschitz_unknown: Vec<Vec<usize>>,
    /// Largest |f(x) - label| over the points.
    pub max_label_gap: Real,
    /// Points checked.
    pub points: usize,
    /// The published form against the data label.
    pub published_label: Vec<Vec<Real>>,
    /// The published form with f(x) as reference.
    pub published_network: Vec<Vec<Real>>,
    /// Wall time.
    pub seconds: Real,
}

/// Stage 5: every raw-unit controller flown from the published starts.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FlightsResult {
    /// One row per controller.
    pub controllers: Vec<FlownController>,
    /// The published starts (y0).
    pub starts: Vec<Real>,
}

/// One controller's flights.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FlownController {
    /// The controller's label.
    pub controller: String,
    /// x + y at t = 20 from each start.
    pub final_x_plus_y: Vec<Real>,
    /// The largest |x + y| over the starts.
    pub worst: Real,
}

/// Stage 6: reachable sets of every raw-unit controller on the spec's loop.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ReachStageResult {
    /// The output clip, if any.
    pub clip: Option<[Real; 2]>,
    /// Start of the goal's time window (null: the horizon only).
    pub goal_from: Real,
    /// The goal bound on |x + y| (null without a goal).
    pub goal_ystar: Real,
    /// Horizon.
    pub horizon: Real,
    /// The loop's name in the spec.
    #[serde(rename = "loop")]
    pub loop_name: String,
    /// The plant model's name.
    pub model: String,
    /// One row per controller.
    pub networks: Vec<ReachedNetwork>,
    /// Control period.
    pub period: Real,
    /// The interval of y0.
    pub y0: [Real; 2],
}

/// One controller's reach run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ReachedNetwork {
    /// The controller's label.
    pub controller: String,
    /// The figure, relative to the output folder.
    pub figure: String,
    /// Enclosure of x + y at the horizon.
    pub final_x_plus_y: [Real; 2],
    /// Enclosure width over the sampled range.
    pub ratio: Real,
    /// The verdict's reason.
    pub reason: String,
    /// The sampled range of x + y at the horizon.
    pub sampled_x_plus_y: [Real; 2],
    /// Wall time.
    pub seconds: Real,
    /// Sub-boxes that lost validation.
    pub stopped: usize,
    /// The earliest time a sub-box lost validation (null: none did).
    pub stopped_at: Real,
    /// Sub-boxes flown.
    pub subproblems: usize,
    /// The verdict.
    pub verdict: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_reals_are_written_as_null_and_read_back_as_not_finite() {
        let v = vec![Real(1.5), Real(f64::INFINITY), Real(f64::NAN), Real(20.0)];
        let text = serde_json::to_string(&v).unwrap();
        assert_eq!(text, "[1.5,null,null,20.0]");
        let back: Vec<Real> = serde_json::from_str(&text).unwrap();
        assert_eq!(back[0], Real(1.5));
        assert!(back[1].get().is_none() && back[2].get().is_none());
        assert_eq!(back[1].f4(), "-");
        // Exactly as a JSON value prints it (the report quoted `Value`s before).
        for x in [1e-5, 20.0, 0.5, 1e300, f64::NAN] {
            assert_eq!(Real(x).json(), serde_json::Value::from(x).to_string());
        }
    }

    /// One of every result type, every optional part present.
    fn full_results() -> Results {
        let r = Real(0.5);
        let critical = CriticalRow {
            attained: true,
            bound: r,
            complete: false,
            critical: r,
            domain_extreme: r,
            property: "p1".into(),
            unknown_reason: Some(ReasonRow {
                kind: "timeout".into(),
                message: "m".into(),
            }),
            vacuous: false,
        };
        let trained = TrainedNetwork {
            attack_mean: r,
            attack_worst: r,
            epochs: 1,
            eps: r,
            file: "f".into(),
            mae: r,
            method: "plain".into(),
            r2: r,
            r2_all: r,
            rmse: r,
            seconds: r,
        };
        let round = RoundRow {
            added: vec![r],
            enclosure: [r, r],
            loss: r,
            max_leaves: 1,
            mse: r,
            penalty: r,
            r2: r,
            round: 0,
            sampled: [r, r],
            seconds: r,
            starts: 1,
            steps: 1,
            verdict: "proved".into(),
        };
        Results {
            command_line: "c".into(),
            mode: "quick".into(),
            samara_version: "0".into(),
            seconds: 1.0,
            spec: SpecDigest {
                file: "s".into(),
                fnv1a: "0".into(),
            },
            stages: Stages {
                closed_loop: Some(FlightsResult {
                    controllers: vec![FlownController {
                        controller: "c".into(),
                        final_x_plus_y: vec![r],
                        worst: r,
                    }],
                    starts: vec![r],
                }),
                data: Some(DataResult {
                    finals: vec![FinalPoint { x_plus_y: r, y0: r }],
                    normalisation_min: vec![r],
                    normalisation_range: vec![r],
                    published_constants: Some(vec![vec![r]]),
                    published_constants_vs_data_max_abs: Some(r),
                    published_max_abs_deviation: Some(r),
                    published_rows: Some(1),
                    rows: 1,
                }),
                reach: Some(ReachStageResult {
                    clip: Some([r, r]),
                    goal_from: r,
                    goal_ystar: r,
                    horizon: r,
                    loop_name: "published".into(),
                    model: "reduced".into(),
                    networks: vec![ReachedNetwork {
                        controller: "c".into(),
                        figure: "f".into(),
                        final_x_plus_y: [r, r],
                        ratio: r,
                        reason: "r".into(),
                        sampled_x_plus_y: [r, r],
                        seconds: r,
                        stopped: 0,
                        stopped_at: r,
                        subproblems: 1,
                        verdict: "proved".into(),
                    }],
                    period: r,
                    y0: [r, r],
                }),
                train: Some(TrainResult {
                    closed_loop: Some(ClosedLoopResult {
                        data_weight: r,
                        enclosure: [r, r],
                        figure: "f".into(),
                        goal_ystar: r,
                        horizon: r,
                        proved: true,
                        r2_all: r,
                        rounds: vec![round],
                        seconds: r,
                        steps_per_round: 1,
                        training_bound: r,
                        verdict: "proved".into(),
                        y0: [r, r],
                    }),
                    domain_hi: vec![r],
                    domain_lo: vec![r],
                    networks: vec![trained],
                    norm_min: vec![r],
                    norm_range: vec![r],
                }),
                verify: Some(VerifyResult {
                    l: vec![r],
                    eps: vec![r],
                    networks: vec![VerifiedNetwork {
                        critical: vec![critical],
                        critical_seconds: r,
                        network: "n".into(),
                        p5: Some(P5Tables {
                            lipschitz: vec![vec![r]],
                            lipschitz_unknown: vec![vec![0]],
                            max_label_gap: r,
                            points: 1,
                            published_label: vec![vec![r]],
                            published_network: vec![vec![r]],
                            seconds: r,
                        }),
                    }],
                }),
            },
        }
    }

    /// results.json was a `serde_json::Value` (sorted maps) before it was typed: the
    /// typed document must serialise to the same bytes, so its fields are declared in
    /// sorted order. Serialising through a `Value` sorts the keys; the direct
    /// serialisation must agree at every depth.
    #[test]
    fn results_are_written_in_sorted_key_order() {
        let r = full_results();
        let direct = serde_json::to_string_pretty(&r).unwrap();
        let sorted = serde_json::to_string_pretty(&serde_json::to_value(&r).unwrap()).unwrap();
        assert_eq!(direct, sorted);
    }

    /// Every stage's result goes through the stage cache (JSON) and back unchanged.
    #[test]
    fn stage_results_survive_the_cache() {
        let full = full_results();
        let mut back = Stages::default();
        for name in ["data", "train", "verify", "closed_loop", "reach"] {
            assert!(back.restore(name, full.stages.entry_json(name)), "{name}");
        }
        assert_eq!(
            serde_json::to_string(&back).unwrap(),
            serde_json::to_string(&full.stages).unwrap()
        );
        // A cached entry of another shape is refused (and recomputed by the run).
        assert!(!back.restore("train", serde_json::json!({"networks": 3})));
        assert!(!back.restore("no-such-stage", serde_json::Value::Null));
    }
}
