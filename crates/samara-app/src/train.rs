//! Training results as typed documents (`samara train --json`): a data-fitting run
//! ([`TrainSummary`]) and closed-loop training ([`ClosedLoopSummary`]).

use serde::{Deserialize, Serialize};

/// One restart of a training run from a degenerate network.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RestartEntry {
    /// Attempt number (0-based).
    pub attempt: usize,
    /// The seed of the network that was degenerate.
    pub seed: u64,
    /// The epoch at which it was found degenerate.
    pub epoch: usize,
    /// How it was degenerate.
    pub reason: String,
}

impl From<&samara_train::Restart> for RestartEntry {
    fn from(r: &samara_train::Restart) -> Self {
        RestartEntry {
            attempt: r.attempt,
            seed: r.seed,
            epoch: r.epoch,
            reason: r.reason.to_string(),
        }
    }
}

/// The `--json` summary of a data-fitting training run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainSummary {
    /// The method.
    pub method: String,
    /// The network file.
    pub out: String,
    /// The loss log.
    pub log: String,
    /// Held-out rows.
    pub test_rows: usize,
    /// Held-out R^2.
    pub r2: f64,
    /// Held-out RMSE.
    pub rmse: f64,
    /// Held-out MAE.
    pub mae: f64,
    /// Attack radius.
    pub eps: f64,
    /// Worst output deviation under the attack.
    pub attack_worst_deviation: f64,
    /// Mean output deviation under the attack.
    pub attack_mean_deviation: f64,
    /// `--seed`.
    pub seed: u64,
    /// The seed the kept network was initialised from.
    pub init_seed: u64,
    /// Number of restarts.
    pub restarts: usize,
    /// The restarts.
    pub restart_log: Vec<RestartEntry>,
}

/// One round of closed-loop training: its record and its time in all.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RoundEntry {
    /// The round's record.
    #[serde(flatten)]
    pub round: samara_train::cegis::Round,
    /// Training and reach time together.
    pub seconds: f64,
}

impl From<&samara_train::cegis::Round> for RoundEntry {
    fn from(r: &samara_train::cegis::Round) -> Self {
        RoundEntry {
            round: r.clone(),
            seconds: r.train_seconds + r.reach_seconds,
        }
    }
}

/// The goal closed-loop training flies to.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LoopGoal {
    /// Band half-width.
    pub ystar: f64,
    /// Start of the window.
    pub from: Option<f64>,
    /// Horizon.
    pub horizon: f64,
    /// Initial heights.
    pub y0: [f64; 2],
    /// Model.
    pub model: String,
    /// Output clip.
    pub clip: Option<[f64; 2]>,
}

/// The pre-training on the data.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pretrain {
    /// Held-out R^2.
    pub test_r2: f64,
    /// Held-out RMSE.
    pub test_rmse: f64,
    /// Epochs.
    pub epochs: usize,
    /// Time.
    pub seconds: f64,
}

/// The `--json` summary of closed-loop training.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClosedLoopSummary {
    /// Always `closed-loop`.
    pub method: String,
    /// The network file.
    pub out: String,
    /// The rounds log.
    pub log: String,
    /// The rounds figure.
    pub figure: String,
    /// The goal.
    pub goal: LoopGoal,
    /// Whether reach proved the goal.
    pub proved: bool,
    /// The last reach verdict.
    pub verdict: String,
    /// Enclosure of `x + y` at the horizon.
    pub enclosure: [f64; 2],
    /// Sampled range.
    pub sampled: [f64; 2],
    /// R^2 against the data.
    pub r2: f64,
    /// RMSE against the data.
    pub rmse: f64,
    /// Data rows.
    pub data_rows: usize,
    /// The pre-training.
    pub pretrain: Pretrain,
    /// The rounds.
    pub rounds: Vec<RoundEntry>,
    /// Training time.
    pub seconds: f64,
    /// `--seed`.
    pub seed: u64,
    /// The seed the kept network was initialised from.
    pub init_seed: u64,
    /// Number of restarts.
    pub restarts: usize,
    /// The restarts.
    pub restart_log: Vec<RestartEntry>,
}
