//! The form of a robustness property and the checks of a sweep's radii, bounds and
//! names, shared by the command line's flags ([`crate::args::RobustnessArgs`]) and the
//! sweep itself ([`crate::robustness`]), so neither imports the other for them.

use crate::{input, AppError};
use serde::{Deserialize, Serialize};

/// The form of the robustness property.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Form {
    /// `|f(x') - ref| <= L / eps` (the published P5).
    Published,
    /// `|f(x') - f(x)| <= L ||x' - x||`.
    Lipschitz,
}

impl Form {
    /// The form named `s` (`published`, `lipschitz`).
    pub fn parse(s: &str) -> Option<Form> {
        match s {
            "published" => Some(Form::Published),
            "lipschitz" => Some(Form::Lipschitz),
            _ => None,
        }
    }

    /// Its name.
    pub fn text(self) -> &'static str {
        match self {
            Form::Published => "published",
            Form::Lipschitz => "lipschitz",
        }
    }
}

/// A radius of a robustness sweep: greater than 0 and at most 1e6.
pub fn radius_ok(e: f64) -> bool {
    e > 0.0 && e <= 1e6
}

/// What [`radius_ok`] allows, for messages.
pub const RADIUS_ALLOWED: &str = "a radius > 0 and at most 1e6 (in the network's input units)";

/// A Lipschitz bound of a robustness table: finite and at least 0.
pub fn bound_ok(l: f64) -> bool {
    l.is_finite() && l >= 0.0
}

/// What [`bound_ok`] allows, for messages.
pub const BOUND_ALLOWED: &str = "finite and >= 0";

/// The reference of the published form, by name (`label` or `network`); the message
/// names the argument in `front`'s words.
pub fn parse_reference(
    front: crate::Front,
    s: &str,
) -> Result<samara_verify::robustness::Reference, AppError> {
    use samara_verify::robustness::Reference;
    match s {
        "label" => Ok(Reference::Label),
        "network" => Ok(Reference::Network),
        o => input(format!(
            "{} {o:?}: choose label or network",
            front.arg("reference")
        )),
    }
}

/// The form of the robustness property, by name (`published` or `lipschitz`).
pub fn parse_form(front: crate::Front, s: &str) -> Result<Form, AppError> {
    match Form::parse(s) {
        Some(f) => Ok(f),
        None => input(format!(
            "{} {s:?}: choose published or lipschitz",
            front.arg("form")
        )),
    }
}
