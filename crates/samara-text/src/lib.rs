//! What samara's two line-based languages share: the property language
//! (`samara-spec`) and the system language (`samara-system`) read their files with the
//! same line scanner and number literals ([`scan_lines`], [`number_end`]), report errors
//! in the same form ([`Pos`], [`write_diagnostic`]) and suggest names by the same edit
//! distance ([`levenshtein`]). A crate of its own, below both, so that neither language
//! depends on the other.
#![warn(missing_docs)]

mod diagnostic;
mod scan;
mod suggest;

pub use diagnostic::{write_diagnostic, Pos};
pub use scan::{number_end, scan_lines};
pub use suggest::levenshtein;
