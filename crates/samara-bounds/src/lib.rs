//! Sound bounds of piecewise-linear networks, and the input-domain branch and bound built
//! on them.
//!
//! A network here is the chain of affine maps of [`pwl::PwlNet`] (the exact engine's
//! encoding, clamps rewritten as ReLUs): `z_k = W_k a_{k-1} + b_k`, each followed by a
//! ReLU or not, the last one not. Two pieces:
//!
//! - [`symbolic`]: forward symbolic interval propagation (Neurify, Wang et al., NeurIPS
//!   2018; the forward form of DeepPoly, Singh et al., POPL 2019). Every neuron carries a
//!   lower and an upper linear function of the inputs; a ReLU maps them by monotonicity
//!   (`relu(L) <= relu(z) <= relu(U)`) and relaxes each by its own range. The cost grows
//!   with the number of inputs, not the width, which suits low-dimensional inputs (the
//!   case study's 6, ACAS Xu's 5). Floating point cannot break a bound: every linear
//!   function carries a slack that provably covers the rounding of the f64 arithmetic
//!   that built it (Higham's bound `gamma_n = n u / (1 - n u)` per dot product).
//! - [`linset`]: CROWN (Zhang et al., NeurIPS 2018) over a linear set with input noise,
//!   for ReLU, Clamp, Tanh and Sigmoid networks with normalisation: affine bounds of the
//!   outputs in the set's parameters, with the same rigorous rounding.
//! - [`search`]: input-domain branch and bound for queries "is there an `x` in a box with
//!   `f(x)` in a polytope?" (the VNN-LIB shape): a projected-gradient attack first,
//!   then splitting the box (look-ahead, or the largest smear as in ReluVal, Wang et al.,
//!   USENIX Security 2018) until every piece is proved empty or a point is found. Points
//!   are re-evaluated concretely before they are reported.
//!   Boxes with 64 or more inputs (images) are decided by ReLU splitting instead
//!   (`relusplit`): beta-CROWN bounds (Wang et al., NeurIPS 2021) per phase set, after
//!   the same checks of the whole box.
//! - [`smooth`]: the same input-split search for networks with any activation (sigmoid,
//!   tanh, the step `Sign`), CROWN over the free inputs after the inputs fixed in every
//!   case are folded into the first layer's bias (the fold's rounding carried as a bias
//!   radius), the interval rule alone after a layer of steps; several networks side by
//!   side with inputs carried to the outputs ([`smooth::Apps`]) state relational
//!   queries and constraints over inputs; VNN-COMP 2023's `dist_shift` (8 free inputs of
//!   792) is its shape. Both searches share their attack (`attack`: projected gradient
//!   descent from seeded starts) and the order of their frontier (`work`).
//! - [`constant`]: interval bounds rounded only where an operation was inexact, which
//!   decide degenerate constraints (an output exactly 0 on the box, two outputs of the
//!   same expression compared) that the widened bounds of the search never close.
//! - [`lp`]: the min-max LP over a few linear bounds that gives the search its weights
//!   for combining a conjunction's constraints.
//! - [`phases`]: ReLU-phase splitting of the search's pieces that few ReLUs cross, with
//!   bounds over each phase set from a small LP certified by weak duality (nnenum's
//!   exact star-set step, Bak et al., CAV 2020; the phase multipliers play the part of
//!   beta-CROWN's, Wang et al., NeurIPS 2021); [`lp`] also gives those LP multipliers.
//! - [`optimise`]: branch and bound for the maximum of a linear objective over one
//!   network's graph under linear constraints on its inputs, outputs and extra variables
//!   (critical values), input and ReLU splitting with LP bounds certified by weak duality.
//! - [`rules`]: one home per operator's bound rules (ReLU, clamp, sigmoid, tanh: the
//!   interval rule, the linear relaxation, the slope range), which every routine above
//!   and reachability's network step take their relaxations from.
#![warn(missing_docs)]

mod adam;
mod attack;
pub mod constant;
mod exact;
pub mod linset;
pub mod lp;
pub mod optimise;
pub mod phases;
pub mod pwl;
mod query;
pub mod refine;
mod relusplit;
pub mod rules;
pub mod search;
pub mod smooth;
pub mod symbolic;
#[cfg(test)]
mod testnet;
mod work;
