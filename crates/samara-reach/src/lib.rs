//! Sound reachable sets of the network-controlled Alsomitra glider.
//!
//! The closed loop is the same as in simulation (`samara-sim`): at each control instant
//! the network reads the state, its (clipped) output is held for one period while the
//! plant flies. Here both halves run on sets:
//! - [`netstep`]: the controller output over a zonotope, kept affine in the zonotope's
//!   generators (CROWN over the zonotope);
//! - [`flow`]: validated Taylor integration of the plant (Lohner-style, on zonotopes,
//!   with the plant's own equations run on Taylor series of intervals);
//! - [`settings`]: the run's settings, the goal, and their validation;
//! - [`driver`]: the initial set as a box of parameters, cut into sub-boxes along the
//!   widest parameter, each sub-box flown over the whole horizon (sub-boxes in parallel
//!   with `rayon`); a sub-box that lost its enclosure, carries too much noise in its
//!   final `x + y` or leaves the goal undecided is cut in two along the parameter that
//!   moves the dynamics (lost enclosure) or `x + y` most, and both halves are flown
//!   again from `t = 0`, within the sub-box budget;
//! - [`sampling`]: simulated trajectories (falsification first, figures) and the check
//!   that enclosures contain them;
//! - [`verdict`]: the goal on the final sets and the verdict;
//!
//! Verdicts: `Proved` only when every sub-box's enclosure satisfies the goal; `Violated`
//! only with a concrete simulated trajectory; `Unknown` with the reason otherwise.

#![warn(missing_docs)]

pub mod adaptive;
pub mod driver;
pub mod flow;
pub mod grid;
pub mod netstep;
pub mod parts;
pub mod sampling;
pub mod settings;
mod standin;
pub mod system;
pub mod tmflow;
pub mod verdict;
pub mod zonotope;

pub use driver::{reach, Leaf, ReachResult, StepSet};
pub use sampling::{check_containment, simulate_samples, Sample};
pub use settings::{Goal, ReachError, ReachSettings, MAX_INIT, MAX_PERIODS};
pub use verdict::Verdict;
pub use zonotope::Zonotope;
