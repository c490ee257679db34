//! Diagnostics: every error of the spec language names `file:line:column`, shows the
//! source line with a caret under the offending text, says what was expected and,
//! where one is known, suggests the fix.

use std::fmt;

/// A byte range in a source text.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Span {
    /// First byte.
    pub start: usize,
    /// One past the last byte.
    pub end: usize,
}

impl Span {
    /// The smallest span covering both.
    pub fn to(self, other: Span) -> Span {
        Span {
            start: self.start.min(other.start),
            end: self.end.max(other.end),
        }
    }
}

/// An error of the spec language, rendered with its place in the source.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub struct SpecError {
    /// What went wrong (one line).
    pub message: String,
    /// File name (as given).
    pub file: String,
    /// 1-based line.
    pub line: usize,
    /// 1-based column (in characters).
    pub column: usize,
    /// The source line.
    pub source_line: String,
    /// Width of the caret in characters (at least 1).
    pub width: usize,
    /// What was expected there, if known.
    pub expected: Option<String>,
    /// The suggested fix, if known.
    pub help: Option<String>,
}

impl SpecError {
    /// An error at `span` of `src` (file name `file`).
    pub fn at(file: &str, src: &str, span: Span, message: impl Into<String>) -> Self {
        let start = floor_char(src, span.start.min(src.len()));
        let end = floor_char(src, span.end.min(src.len()).max(start));
        let line_start = src[..start].rfind('\n').map(|i| i + 1).unwrap_or(0);
        let line_end = src[start..]
            .find('\n')
            .map(|i| start + i)
            .unwrap_or(src.len());
        let line = src[..start].matches('\n').count() + 1;
        let column = src[line_start..start].chars().count() + 1;
        let width = src[start..end.min(line_end).max(start)]
            .chars()
            .count()
            .max(1);
        SpecError {
            message: message.into(),
            file: file.to_string(),
            line,
            column,
            source_line: src[line_start..line_end].to_string(),
            width,
            expected: None,
            help: None,
        }
    }

    /// An error with no place in a source (e.g. a missing file given on the command line).
    pub fn plain(file: &str, message: impl Into<String>) -> Self {
        SpecError {
            message: message.into(),
            file: file.to_string(),
            line: 0,
            column: 0,
            source_line: String::new(),
            width: 0,
            expected: None,
            help: None,
        }
    }

    /// Add what was expected.
    pub fn expected(mut self, e: impl Into<String>) -> Self {
        self.expected = Some(e.into());
        self
    }

    /// Add a suggested fix.
    pub fn help(mut self, h: impl Into<String>) -> Self {
        self.help = Some(h.into());
        self
    }
}

fn floor_char(s: &str, mut i: usize) -> usize {
    while i > 0 && !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

impl fmt::Display for SpecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}", self.message)?;
        if self.line == 0 {
            write!(f, "  --> {}", self.file)?;
        } else {
            let num = self.line.to_string();
            let pad = " ".repeat(num.len());
            writeln!(f, "  --> {}:{}:{}", self.file, self.line, self.column)?;
            writeln!(f, "{pad} |")?;
            writeln!(f, "{num} | {}", self.source_line.replace('\t', " "))?;
            write!(
                f,
                "{pad} | {}{}",
                " ".repeat(self.column - 1),
                "^".repeat(self.width)
            )?;
            if let Some(e) = &self.expected {
                write!(f, " expected {e}")?;
            }
        }
        if self.line == 0 {
            if let Some(e) = &self.expected {
                write!(f, "\n  = expected {e}")?;
            }
        }
        if let Some(h) = &self.help {
            write!(f, "\n  = help: {h}")?;
        }
        Ok(())
    }
}

/// Levenshtein distance (for "did you mean" suggestions).
pub fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for i in 1..=a.len() {
        let mut cur = vec![i; b.len() + 1];
        for j in 1..=b.len() {
            let sub = prev[j - 1] + usize::from(a[i - 1] != b[j - 1]);
            cur[j] = sub.min(prev[j] + 1).min(cur[j - 1] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

/// The nearest of `candidates` to `name`, if close enough to be a plausible typo.
pub fn nearest<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<String> {
    let mut best: Option<(usize, &str)> = None;
    for c in candidates {
        let d = edit_distance(&name.to_lowercase(), &c.to_lowercase());
        if best.map(|(bd, _)| d < bd).unwrap_or(true) {
            best = Some((d, c));
        }
    }
    best.filter(|(d, c)| *d <= (c.chars().count().max(name.chars().count()) / 2).max(2))
        .map(|(_, c)| c.to_string())
}
