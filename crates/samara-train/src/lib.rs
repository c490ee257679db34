//! Training of network controllers for samara: plain MSE regression, adversarial
//! training (FGSM as published, PGD), a Lipschitz penalty whose gradient is really
//! applied, and property-driven training with the DL2 and Goedel differentiable logics.
//! Data sets come as CSV or IDX; the trained network carries its min-max normalisation
//! as the IR's input/output layers and exports to ONNX through `samara-nn`. The
//! closed-loop method ([`cegis`]) trains through the sample-and-hold loop and checks the
//! result with `samara-reach` in counterexample-guided rounds.
#![warn(missing_docs)]
// Numeric kernels index parameter, gradient and cache arrays by the same index.
#![allow(clippy::needless_range_loop)]

/// Data sets (CSV, IDX), min-max constants and splits; they live in `samara-nn` so the
/// specification language can read data sets too.
pub use samara_nn::data;
pub mod cegis;
pub mod closed_loop;
pub mod mlp;
pub mod property;
pub mod region;
pub mod train;

pub use cegis::{train_closed_loop, CegisOptions, CegisOutcome, Round};
pub use closed_loop::ClosedLoopLoss;
pub use data::{read_table, DataError, MinMax, Table};
pub use property::{
    case_study_spec, from_query, rescale_query, spec_properties, with_units, Formula,
    FromQueryError, Logic, Property, SpecPropertyError, CASE_STUDY_SPEC,
};
pub use region::Region;
pub use train::{
    attempt_seed, min_rows, train, Attack, Degeneracy, LogRow, Method, Metrics, Restart,
    TrainError, TrainOptions, TrainOutcome, DEFAULT_MAX_RESTARTS,
};
