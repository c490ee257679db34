//! Number types for samara.
//!
//! Every equation in samara (the plant, the network evaluator) is written once over
//! [`Scalar`]. `f64` simulates, [`Dual`] differentiates (forward mode), and set-valued
//! types (intervals, Taylor models) enclose. Because sets cannot honestly be ordered,
//! [`Scalar`] has no `PartialOrd`: comparisons are three-way through [`Scalar::sign`],
//! and a piecewise function whose branch is undecided takes the [`Scalar::hull`] of both
//! branches.
//!
//! The layout follows the blanket-float trait of Clarabel.rs (`src/algebra/floats.rs`):
//! one trait with the required operations and a constant helper.
#![warn(missing_docs)]

mod dual;
mod idual;
mod interval;
mod outcome;
pub mod round;
mod scalar;
mod series;
mod timeout;
mod tm;
pub mod tm_reduce;

pub use dual::Dual;
pub use idual::IDual;
pub use interval::Interval;
pub use outcome::{Outcome, Status};
pub use scalar::{Scalar, Sign};
pub use series::{conv, dconv, Series};
pub use timeout::{BadTimeout, Timeout};
pub use tm::Tm;
