//! Training of network controllers for samara: plain MSE regression, adversarial
//! training (FGSM as published, PGD), a Lipschitz penalty whose gradient is really
//! applied, and property-driven training with the DL2 and Goedel differentiable logics.
//! Data sets come as CSV or IDX; the trained network carries its min-max normalisation
//! as the IR's input/output layers and exports to ONNX through `samara-nn`.

// Numeric kernels index parameter, gradient and cache arrays by the same index.
#![allow(clippy::needless_range_loop)]

/// Data sets (CSV, IDX), min-max constants and splits; they live in `samara-nn` so the
/// specification language can read data sets too.
pub use samara_nn::data;
pub mod mlp;
pub mod property;
pub mod region;
pub mod train;

pub use data::{read_table, DataError, MinMax, Table};
pub use property::{
    case_study, from_query, rescale_query, Formula, FromQueryError, Logic, Property, Units,
};
pub use region::Region;
pub use train::{train, Attack, LogRow, Method, Metrics, TrainError, TrainOptions, TrainOutcome};
