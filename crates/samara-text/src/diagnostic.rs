//! Positions and diagnostics: `file:line:col: message`, the source line with a caret
//! under the column, and `= help: fix`, the same for both languages.

use std::fmt;

/// A position in the source (1-based line and column; line 0 means "no position in the
/// source", e.g. for a file that cannot be read, and is not printed).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Pos {
    /// Line.
    pub line: usize,
    /// Column.
    pub col: usize,
}

/// A diagnostic as `file:line:col: message` (`file: message` on line 0), the source line
/// (at most 120 characters of it, around the column) with a caret under the column when
/// the line is given, and `  = help: hint` when a hint is. Shared by the system language
/// (`samara-system`), whose errors read the same.
pub fn write_diagnostic(
    f: &mut fmt::Formatter<'_>,
    file: &str,
    pos: Pos,
    message: &str,
    hint: &str,
    source_line: &str,
) -> fmt::Result {
    if pos.line == 0 {
        writeln!(f, "{file}: {message}")?;
    } else {
        writeln!(f, "{file}:{}:{}: {message}", pos.line, pos.col)?;
    }
    if !source_line.is_empty() {
        // At most WIDTH characters of the line, around the column.
        const WIDTH: usize = 120;
        let chars: Vec<char> = source_line.chars().collect();
        let col = pos.col.saturating_sub(1).min(chars.len());
        let start = col.saturating_sub(WIDTH / 2);
        let end = (start + WIDTH).min(chars.len());
        let mut shown: String = chars[start..end].iter().collect();
        let mut caret = col - start;
        if start > 0 {
            shown.insert_str(0, "...");
            caret += 3;
        }
        if end < chars.len() {
            shown.push_str("...");
        }
        writeln!(f, "  | {shown}")?;
        writeln!(f, "  | {}^", " ".repeat(caret))?;
    }
    if !hint.is_empty() {
        write!(f, "  = help: {hint}")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    struct D(Pos, &'static str, &'static str);

    impl fmt::Display for D {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write_diagnostic(f, "a.sys", self.0, "unknown name `tehta`", self.2, self.1)
        }
    }

    #[test]
    fn caret_under_the_column_and_help_line() {
        let d = D(
            Pos { line: 3, col: 5 },
            "x = tehta",
            "did you mean `theta`?",
        );
        assert_eq!(
            d.to_string(),
            "a.sys:3:5: unknown name `tehta`\n  | x = tehta\n  |     ^\n  = help: did you mean `theta`?"
        );
        // Line 0: no position, no source line.
        let d = D(Pos::default(), "", "");
        assert_eq!(d.to_string(), "a.sys: unknown name `tehta`\n");
    }
}
