//! The lexer: identifiers, numbers, symbols and line ends, each with its position.

use crate::error::{Pos, SystemError};
use samara_text::{number_end, scan_lines};

/// Tokens.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Tok {
    /// Identifier: a letter or `_`, then letters, digits, `_`.
    Id(String),
    /// A finite number literal.
    Num(f64),
    /// Punctuation or operator.
    Sym(&'static str),
    /// End of a statement (a line end outside brackets).
    Newline,
    /// End of input.
    Eof,
}

/// A token with its position.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Token {
    pub tok: Tok,
    pub pos: Pos,
}

const SYMS: &[&str] = &[
    "<=", ">=", "<", ">", "=", "+", "-", "*", "/", "^", "(", ")", "[", "]", ",", "'", "|",
];

/// Largest accepted source, in bytes.
pub const MAX_SOURCE_BYTES: usize = 1 << 20;

pub(crate) fn err(file: &str, src: &str, pos: Pos, message: String, hint: &str) -> SystemError {
    let source_line = if pos.line == 0 {
        String::new()
    } else {
        src.lines().nth(pos.line - 1).unwrap_or("").to_string()
    };
    SystemError {
        file: file.into(),
        pos,
        message,
        hint: hint.into(),
        source_line,
    }
}

/// Split source text into tokens. Newlines inside `( )` or `[ ]` are ignored, and a
/// line ending in `\` continues on the next one.
pub(crate) fn lex(src: &str, file: &str) -> Result<Vec<Token>, SystemError> {
    if src.len() > MAX_SOURCE_BYTES {
        return Err(err(
            file,
            "",
            Pos::default(),
            format!(
                "the file has {} bytes, more than the limit of {MAX_SOURCE_BYTES}",
                src.len()
            ),
            "split the model or remove generated text",
        ));
    }
    let mut out: Vec<Token> = Vec::new();
    let mut depth: usize = 0;
    scan_lines(
        src,
        &mut (&mut out, &mut depth),
        |(out, depth), li, _line, chars, mut i| {
            let c = chars[i];
            let pos = Pos {
                line: li + 1,
                col: i + 1,
            };
            if c.is_ascii_alphabetic() || c == '_' {
                let s = i;
                while i < chars.len() && (chars[i].is_ascii_alphanumeric() || chars[i] == '_') {
                    i += 1;
                }
                out.push(Token {
                    tok: Tok::Id(chars[s..i].iter().collect()),
                    pos,
                });
                return Ok(i);
            }
            if c.is_ascii_digit()
                || (c == '.' && chars.get(i + 1).is_some_and(|d| d.is_ascii_digit()))
            {
                let s = i;
                i = number_end(chars, i);
                let text: String = chars[s..i].iter().collect();
                let v: f64 = match text.parse() {
                    Ok(v) => v,
                    Err(_) => {
                        return Err(err(
                            file,
                            src,
                            pos,
                            format!("`{text}` is not a number"),
                            "write numbers as 12, 0.5, 1e-3 or 2.5E+4",
                        ))
                    }
                };
                if !v.is_finite() {
                    return Err(err(
                        file,
                        src,
                        pos,
                        format!("the number `{text}` overflows a 64-bit float"),
                        "numbers must be finite (at most about 1.8e308 in magnitude)",
                    ));
                }
                if i < chars.len() && (chars[i].is_ascii_alphabetic() || chars[i] == '_') {
                    return Err(err(
                        file,
                        src,
                        Pos {
                            line: li + 1,
                            col: i + 1,
                        },
                        format!("a name cannot follow the number `{text}` directly"),
                        "write a `*` for a product (e.g. `2*x`), or start names with a letter",
                    ));
                }
                out.push(Token {
                    tok: Tok::Num(v),
                    pos,
                });
                return Ok(i);
            }
            let rest: String = chars[i..(i + 2).min(chars.len())].iter().collect();
            if let Some(sym) = SYMS.iter().find(|s| rest.starts_with(**s)) {
                match *sym {
                    "(" | "[" => **depth += 1,
                    ")" | "]" => **depth = depth.saturating_sub(1),
                    _ => {}
                }
                out.push(Token {
                    tok: Tok::Sym(sym),
                    pos,
                });
                return Ok(i + sym.len());
            }
            Err(err(
                file,
                src,
                pos,
                format!("unexpected character `{}`", c.escape_debug()),
                "names are ASCII letters, digits and `_`; operators are + - * / ^; comments start with #",
            ))
        },
        |(out, depth), li, len, continued| {
            if !continued && **depth == 0 && out.last().is_some_and(|t| t.tok != Tok::Newline) {
                out.push(Token {
                    tok: Tok::Newline,
                    pos: Pos {
                        line: li + 1,
                        col: len + 1,
                    },
                });
            }
        },
    )?;
    let end = Pos {
        line: src.lines().count().max(1),
        col: src.lines().last().map_or(1, |l| l.chars().count() + 1),
    };
    if out.last().is_some_and(|t| t.tok != Tok::Newline) {
        out.push(Token {
            tok: Tok::Newline,
            pos: end,
        });
    }
    out.push(Token {
        tok: Tok::Eof,
        pos: end,
    });
    Ok(out)
}
