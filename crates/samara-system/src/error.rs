//! Errors of the system language: file, line, column, what is wrong, how to fix it.

use std::fmt;

pub use samara_text::Pos;

/// A system-file error. Displayed as `file:line:col: message`, the source line with a
/// caret, and `= help: fix`. The CLI exits with [`SystemError::EXIT_CODE`] on it.
#[derive(Clone, Debug, PartialEq)]
pub struct SystemError {
    /// File name.
    pub file: String,
    /// Position.
    pub pos: Pos,
    /// What is wrong.
    pub message: String,
    /// How to fix it (may be empty).
    pub hint: String,
    /// The offending source line (may be empty).
    pub source_line: String,
}

impl SystemError {
    /// Exit code of a command that fails on a bad system file (a bad input).
    pub const EXIT_CODE: i32 = 2;
}

impl fmt::Display for SystemError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        samara_text::write_diagnostic(
            f,
            &self.file,
            self.pos,
            &self.message,
            &self.hint,
            &self.source_line,
        )
    }
}

impl std::error::Error for SystemError {}

/// The closest candidate to `name` (distance at most a third of its length, at least
/// 1, or a case-insensitive match); names over 128 characters get no suggestion.
pub(crate) fn closest<'a>(name: &str, candidates: impl Iterator<Item = &'a str>) -> Option<String> {
    if name.chars().count() > 128 {
        return None;
    }
    let limit = (name.chars().count() / 3).max(1);
    let mut best: Option<(usize, &str)> = None;
    for c in candidates {
        if c.chars().count() > 128 {
            continue;
        }
        let d = if c.eq_ignore_ascii_case(name) {
            0
        } else {
            samara_text::levenshtein(name, c)
        };
        let better = match best {
            None => true,
            // Ties go to the alphabetically first name: suggestions are deterministic.
            Some((bd, bc)) => d < bd || (d == bd && c < bc),
        };
        if d <= limit && better {
            best = Some((d, c));
        }
    }
    best.map(|(_, c)| c.to_string())
}
