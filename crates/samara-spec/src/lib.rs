//! The samara property language: one text for the properties, read by verification,
//! training and reports. See `docs/spec.md` for the reference.
//!
//! - [`syntax`]: lexer and parser (errors name file:line:column with a caret and a fix);
//! - [`lower`]: checking (names, dimensions, linearity, bound parameters) and lowering to
//!   the linear normal form ([`normal`]) that solvers take;
//! - [`vnnlib`]: VNN-LIB 1.0 export and import.
#![warn(missing_docs)]

pub mod lower;
pub mod normal;
pub mod syntax;
pub mod vnnlib;

pub use lower::{BandGoal, Bindings, Instance, LoopDecl, Spec};
pub use syntax::SpecError;
