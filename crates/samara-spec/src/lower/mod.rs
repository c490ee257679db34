//! Checking and lowering: from the syntax tree to queries in the linear normal form.
//!
//! A property `P` becomes its counterexample region `domain and not P`: negation normal
//! form, then atoms with `|e|` and `norm(p - q)` expanded by exact case splits
//! (`phi(|u|) = (u >= 0 and phi(u)) or (u <= 0 and phi(-u))`;
//! `phi(max_k a_k) = or_k (and_j a_k >= a_j and phi(a_k))`), then a disjunctive normal
//! form. Raw-unit names are rewritten through the network's normalisation
//! (`raw = C + S z`, `out_raw = offset + scale out`), so the normal form speaks the
//! units of the network files.
//!
//! Split by meaning: [`decl`] (declarations and their checks), [`closed_loop`] (closed
//! loops of the plate: model, initial set, goal), [`suggest`] (name
//! suggestions), `linear` (the linear-expression type of lowering), `lowering` (property
//! instances), `nnf` (negation and disjunctive normal forms).

pub mod closed_loop;
pub mod decl;
mod linear;
mod lowering;
mod nnf;
pub mod suggest;

pub use closed_loop::{BandGoal, LoopDecl};
pub use decl::{Bindings, NetDecl, ParamDecl, PropertyDecl, Spec};
pub use lowering::{Instance, MAX_CASES, MAX_TERMS};
pub use suggest::nearest;
