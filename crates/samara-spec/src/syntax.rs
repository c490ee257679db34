//! Lexer, syntax tree and parser of the samara property language (see docs/spec.md).

use std::fmt;

pub use samara_text::{number_end, scan_lines, write_diagnostic, Pos};

/// A spec error: where, what was expected, and how to fix it.
#[derive(Clone, Debug, PartialEq)]
pub struct SpecError {
    /// File name.
    pub file: String,
    /// Position.
    pub pos: Pos,
    /// What is wrong.
    pub message: String,
    /// How to fix it (may be empty).
    pub hint: String,
    /// The offending source line.
    pub source_line: String,
}

impl fmt::Display for SpecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_diagnostic(
            f,
            &self.file,
            self.pos,
            &self.message,
            &self.hint,
            &self.source_line,
        )
    }
}

impl std::error::Error for SpecError {}

/// Tokens.
#[derive(Clone, Debug, PartialEq)]
pub enum Tok {
    /// Identifier (may contain `'` and `_`).
    Id(String),
    /// Number.
    Num(f64),
    /// String literal.
    Str(String),
    /// Punctuation or operator.
    Sym(&'static str),
    /// End of line (statements are line-based, `\` continues a line).
    Newline,
    /// End of input.
    Eof,
}

/// A token with its position.
#[derive(Clone, Debug, PartialEq)]
pub struct Token {
    /// The token.
    pub tok: Tok,
    /// Where it starts.
    pub pos: Pos,
}

const SYMS: &[&str] = &[
    "=>", "<=", ">=", "==", "->", "<", ">", "=", "+", "-", "*", "/", "(", ")", "[", "]", ",", ":",
    "|", ".",
];

/// Source bytes as text, or an error naming the line and column of the first byte that
/// is not UTF-8.
pub fn decode<'a>(bytes: &'a [u8], file: &str) -> Result<&'a str, SpecError> {
    std::str::from_utf8(bytes).map_err(|e| {
        let ok = &bytes[..e.valid_up_to()];
        let line = ok.iter().filter(|b| **b == b'\n').count() + 1;
        let start = ok.iter().rposition(|b| *b == b'\n').map_or(0, |i| i + 1);
        let col = std::str::from_utf8(&ok[start..]).map_or(1, |s| s.chars().count() + 1);
        SpecError {
            file: file.into(),
            pos: Pos { line, col },
            message: "the file is not UTF-8 text".into(),
            hint: "save the file as UTF-8".into(),
            source_line: String::new(),
        }
    })
}

/// Split source text into tokens.
pub fn lex(src: &str, file: &str) -> Result<Vec<Token>, SpecError> {
    let mut out = Vec::new();
    let n_lines = scan_lines(
        src,
        &mut out,
        |out, li, line, chars, mut i| {
            let c = chars[i];
            let pos = Pos {
                line: li + 1,
                col: i + 1,
            };
            if c.is_ascii_digit()
                || (c == '.' && chars.get(i + 1).is_some_and(|d| d.is_ascii_digit()))
            {
                let start = i;
                i = number_end(chars, i);
                let text: String = chars[start..i].iter().collect();
                let parsed = text.parse::<f64>();
                let v: f64 = parsed
                    .clone()
                    .ok()
                    .filter(|v: &f64| v.is_finite())
                    .ok_or_else(|| SpecError {
                        file: file.into(),
                        pos,
                        message: if parsed.is_ok() {
                            format!("`{text}` is not a finite number (it overflows)")
                        } else {
                            format!("`{text}` is not a number")
                        },
                        hint: format!(
                            "write numbers like 0.187, -41.68 or 1e-3, of magnitude below {:e}",
                            f64::MAX
                        ),
                        source_line: line.to_string(),
                    })?;
                out.push(Token {
                    tok: Tok::Num(v),
                    pos,
                });
                return Ok(i);
            }
            if c.is_alphabetic() || c == '_' {
                let start = i;
                while i < chars.len()
                    && (chars[i].is_alphanumeric() || chars[i] == '_' || chars[i] == '\'')
                {
                    i += 1;
                }
                out.push(Token {
                    tok: Tok::Id(chars[start..i].iter().collect()),
                    pos,
                });
                return Ok(i);
            }
            if c == '"' {
                let start = i + 1;
                i += 1;
                while i < chars.len() && chars[i] != '"' {
                    i += 1;
                }
                if i >= chars.len() {
                    return Err(SpecError {
                        file: file.into(),
                        pos,
                        message: "unterminated string".into(),
                        hint: "close the string with \"".into(),
                        source_line: line.to_string(),
                    });
                }
                out.push(Token {
                    tok: Tok::Str(chars[start..i].iter().collect()),
                    pos,
                });
                return Ok(i + 1);
            }
            let rest: String = chars[i..].iter().take(2).collect();
            if let Some(s) = SYMS.iter().find(|s| rest.starts_with(**s)) {
                out.push(Token {
                    tok: Tok::Sym(s),
                    pos,
                });
                return Ok(i + s.len());
            }
            Err(SpecError {
                file: file.into(),
                pos,
                message: format!("unexpected character `{c}`"),
                hint: "operators are + - * / <= >= < > == => and, or, not; comments start with #"
                    .into(),
                source_line: line.to_string(),
            })
        },
        |out, li, len, continued| {
            if !continued {
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
    out.push(Token {
        tok: Tok::Eof,
        pos: Pos {
            line: n_lines + 1,
            col: 1,
        },
    });
    Ok(out)
}

/// A numeric or symbolic expression.
#[derive(Clone, Debug, PartialEq)]
pub enum Expr {
    /// Number.
    Num(f64),
    /// A bare name (input/output of the implicit point, parameter) or `point.component`.
    Name(Option<String>, String, Pos),
    /// `net(point)` or `net(point).output`.
    Call(String, String, Option<String>, Pos),
    /// A sum `e0 ± e1 ± ...` kept flat (a long sum is a list, not a deep tree, so no
    /// pass recurses once per term): `(subtract, term)`, the first flag is `false`.
    Sum(Vec<(bool, Expr)>),
    /// A product or quotient chain `e0 (*|/) e1 ...`, flat like [`Expr::Sum`]: the first
    /// factor, then `(divide, factor, position of the operator)`.
    Prod(Box<Expr>, Vec<(bool, Expr, Pos)>),
    /// Negation.
    Neg(Box<Expr>),
    /// `|e|`.
    Abs(Box<Expr>),
    /// `norm(p - q)`: infinity norm of the difference of two points' inputs.
    Norm(String, String, Pos),
}

/// Comparison operators.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rel {
    /// `<=`.
    Le,
    /// `<`.
    Lt,
    /// `>=`.
    Ge,
    /// `>`.
    Gt,
    /// `==`.
    Eq,
}

/// A formula.
#[derive(Clone, Debug, PartialEq)]
pub enum Formula {
    /// A chain `e0 r0 e1 r1 e2 ...` (a conjunction of comparisons).
    Chain(Vec<Expr>, Vec<Rel>, Pos),
    /// Conjunction.
    And(Vec<Formula>),
    /// Disjunction.
    Or(Vec<Formula>),
    /// Negation.
    Not(Box<Formula>),
    /// Implication.
    Implies(Box<Formula>, Box<Formula>),
}

/// A binder `for p in ...`.
#[derive(Clone, Debug, PartialEq)]
pub enum Binder {
    /// `for p in data NAME`.
    Data {
        /// Point name.
        point: String,
        /// Data set name.
        dataset: String,
        /// Position.
        pos: Pos,
    },
    /// `for p in ball(q, r)` (r in the network's input units, infinity norm).
    Ball {
        /// Point name.
        point: String,
        /// Centre point.
        centre: String,
        /// Radius.
        radius: Expr,
        /// Position.
        pos: Pos,
    },
}

/// A statement.
#[derive(Clone, Debug, PartialEq)]
pub enum Stmt {
    /// `network f(in, ...) -> (out, ...)`.
    Network {
        /// Name.
        name: String,
        /// Input names.
        inputs: Vec<String>,
        /// Output names.
        outputs: Vec<String>,
        /// Position.
        pos: Pos,
    },
    /// `normalise f input min [..] range [..]`.
    NormInput {
        /// Network.
        net: String,
        /// Minimum C.
        min: Vec<f64>,
        /// Range S.
        range: Vec<f64>,
        /// Position.
        pos: Pos,
    },
    /// `normalise f from "constants.csv"`: row 1 the minima C, row 2 the ranges S of the
    /// inputs then the outputs (like the published `Normalisation_Constants.csv`).
    NormFile {
        /// Network.
        net: String,
        /// Path (relative to the spec).
        path: String,
        /// Position.
        pos: Pos,
    },
    /// `normalise f output offset a scale b`.
    NormOutput {
        /// Network.
        net: String,
        /// Offsets per output.
        offset: Vec<f64>,
        /// Scales per output.
        scale: Vec<f64>,
        /// Position.
        pos: Pos,
    },
    /// `domain f: v in [a, b], ...`.
    Domain {
        /// Network.
        net: String,
        /// Intervals by input name.
        bounds: Vec<(String, f64, f64, Pos)>,
        /// Position.
        pos: Pos,
    },
    /// `domain f from data NAME`.
    DomainFrom {
        /// Network.
        net: String,
        /// Data set name.
        dataset: String,
        /// Position.
        pos: Pos,
    },
    /// `dataset NAME = "file" [normalised]`.
    Dataset {
        /// Name.
        name: String,
        /// Default path (relative to the spec file).
        path: String,
        /// Rows are in the first network's units (normalised) rather than raw.
        normalised: bool,
        /// Position.
        pos: Pos,
    },
    /// `param NAME [in [a, b]] [= v]`.
    Param {
        /// Name.
        name: String,
        /// Range for critical queries.
        range: Option<(f64, f64)>,
        /// Default value.
        default: Option<f64>,
        /// Position.
        pos: Pos,
    },
    /// `loop NAME of NET: model M, period P, horizon T[, clip OUT in [a, b]]`: a closed
    /// loop of the built-in plate model flown by network `NET` (sample and hold).
    Loop {
        /// Name of the loop.
        name: String,
        /// The controller network.
        net: String,
        /// Clauses `(keyword, value, position)` in the order written.
        clauses: Vec<(String, LoopValue, Pos)>,
        /// Position.
        pos: Pos,
    },
    /// `start NAME: state = v, state in [a, b], ...`: the loop's initial set.
    Start {
        /// The loop.
        lp: String,
        /// Intervals by state name (a point `= v` is `[v, v]`).
        states: Vec<(String, f64, f64, Pos)>,
        /// Position.
        pos: Pos,
    },
    /// `goal NAME: expr <= bound (at T | from T0)`: what reach decides about the loop.
    Goal {
        /// The loop.
        lp: String,
        /// The bounded expression.
        expr: Expr,
        /// The bound.
        bound: f64,
        /// `at T` (`false`) or `from T0` (`true`), and the time.
        from: bool,
        /// The time.
        time: f64,
        /// Position.
        pos: Pos,
    },
    /// `property NAME: binders formula`.
    Property {
        /// Name.
        name: String,
        /// Binders.
        binders: Vec<Binder>,
        /// Formula.
        formula: Formula,
        /// Position.
        pos: Pos,
    },
}

/// The value of one clause of a `loop` statement.
#[derive(Clone, Debug, PartialEq)]
pub enum LoopValue {
    /// `model reduced`.
    Name(String),
    /// `period 0.5`, `horizon 20`.
    Number(f64),
    /// `clip ex in [0.181, 0.193]`.
    Clip(String, f64, f64),
}

/// The deepest nesting the parser accepts (parentheses, `|...|`, `not`, unary `-`,
/// `=>` chains): deeper input is refused with a message rather than risking the stack
/// (every later pass recurses at most this deep).
pub const MAX_DEPTH: usize = 256;

/// Parser state.
pub struct Parser<'a> {
    toks: Vec<Token>,
    i: usize,
    file: &'a str,
    lines: Vec<&'a str>,
    depth: usize,
    too_deep: bool,
}

/// Parse a whole spec.
pub fn parse(src: &str, file: &str) -> Result<Vec<Stmt>, SpecError> {
    let toks = lex(src, file)?;
    let mut p = Parser {
        toks,
        i: 0,
        file,
        lines: src.lines().collect(),
        depth: 0,
        too_deep: false,
    };
    let mut out = Vec::new();
    loop {
        while p.peek() == &Tok::Newline {
            p.i += 1;
        }
        if p.peek() == &Tok::Eof {
            break;
        }
        out.push(p.stmt()?);
        match p.peek() {
            Tok::Newline | Tok::Eof => {}
            _ => {
                return Err(p.err(
                    "expected the end of the statement",
                    "put each statement on its own line",
                ))
            }
        }
    }
    Ok(out)
}

impl Parser<'_> {
    fn peek(&self) -> &Tok {
        &self.toks[self.i].tok
    }

    fn pos(&self) -> Pos {
        self.toks[self.i].pos
    }

    /// An error at the current token.
    pub fn err(&self, message: &str, hint: &str) -> SpecError {
        let pos = self.pos();
        let found = match self.peek() {
            Tok::Id(s) => format!("`{s}`"),
            Tok::Num(v) => format!("number {v}"),
            Tok::Str(s) => format!("\"{s}\""),
            Tok::Sym(s) => format!("`{s}`"),
            Tok::Newline => "the end of the line".into(),
            Tok::Eof => "the end of the file".into(),
        };
        SpecError {
            file: self.file.into(),
            pos,
            message: format!("{message}, found {found}"),
            hint: hint.into(),
            source_line: self
                .lines
                .get(pos.line.wrapping_sub(1))
                .copied()
                .unwrap_or("")
                .to_string(),
        }
    }

    /// Run `f` one nesting level deeper, refusing to go beyond [`MAX_DEPTH`].
    fn nested<T>(
        &mut self,
        f: impl FnOnce(&mut Self) -> Result<T, SpecError>,
    ) -> Result<T, SpecError> {
        if self.depth >= MAX_DEPTH {
            self.too_deep = true;
            return Err(self.err(
                &format!("nesting deeper than {MAX_DEPTH} levels"),
                "split the formula or expression into simpler parts (at most 256 nested parentheses, |...|, not, - or =>)",
            ));
        }
        self.depth += 1;
        let r = f(self);
        self.depth -= 1;
        r
    }

    fn sym(&mut self, s: &str) -> bool {
        if matches!(self.peek(), Tok::Sym(t) if *t == s) {
            self.i += 1;
            true
        } else {
            false
        }
    }

    fn expect_sym(&mut self, s: &str, hint: &str) -> Result<(), SpecError> {
        if self.sym(s) {
            Ok(())
        } else {
            Err(self.err(&format!("expected `{s}`"), hint))
        }
    }

    fn expect_kw(&mut self, k: &str, hint: &str) -> Result<(), SpecError> {
        if self.kw(k) {
            Ok(())
        } else {
            Err(self.err(&format!("expected `{k}`"), hint))
        }
    }

    fn kw(&mut self, k: &str) -> bool {
        if matches!(self.peek(), Tok::Id(t) if t == k) {
            self.i += 1;
            true
        } else {
            false
        }
    }

    fn ident(&mut self, what: &str) -> Result<String, SpecError> {
        match self.peek().clone() {
            Tok::Id(s) if !["and", "or", "not", "for", "in"].contains(&s.as_str()) => {
                self.i += 1;
                Ok(s)
            }
            _ => Err(self.err(
                &format!("expected {what}"),
                "names start with a letter or _",
            )),
        }
    }

    fn number(&mut self) -> Result<f64, SpecError> {
        let neg = self.sym("-");
        match self.peek().clone() {
            Tok::Num(v) => {
                self.i += 1;
                Ok(if neg { -v } else { v })
            }
            _ => Err(self.err("expected a number", "e.g. 0.187 or -41.68")),
        }
    }

    fn vector(&mut self) -> Result<Vec<f64>, SpecError> {
        self.expect_sym("[", "vectors are written [a, b, c]")?;
        let mut v = vec![self.number()?];
        while self.sym(",") {
            v.push(self.number()?);
        }
        self.expect_sym("]", "close the vector with ]")?;
        Ok(v)
    }

    /// `k0 v0 k1 v1` with both values read by `value`: `(v0, v1)`.
    fn keyed_pair(
        &mut self,
        keys: [&str; 2],
        hint: &str,
        value: fn(&mut Self) -> Result<Vec<f64>, SpecError>,
    ) -> Result<(Vec<f64>, Vec<f64>), SpecError> {
        self.expect_kw(keys[0], hint)?;
        let v0 = value(self)?;
        self.expect_kw(keys[1], hint)?;
        Ok((v0, value(self)?))
    }

    /// A file name in quotes.
    fn file_name(&mut self, hint: &str) -> Result<String, SpecError> {
        match self.peek().clone() {
            Tok::Str(s) => {
                self.i += 1;
                Ok(s)
            }
            _ => Err(self.err("expected a file name in quotes", hint)),
        }
    }

    /// A vector `[a, b, ...]`, or one number as a vector of one.
    fn number_or_vector(&mut self) -> Result<Vec<f64>, SpecError> {
        if matches!(self.peek(), Tok::Sym("[")) {
            self.vector()
        } else {
            Ok(vec![self.number()?])
        }
    }

    fn interval(&mut self) -> Result<(f64, f64), SpecError> {
        self.expect_sym("[", "intervals are written [lo, hi]")?;
        let a = self.number()?;
        self.expect_sym(",", "intervals are written [lo, hi]")?;
        let b = self.number()?;
        self.expect_sym("]", "intervals are written [lo, hi]")?;
        Ok((a, b))
    }

    fn names(&mut self) -> Result<Vec<String>, SpecError> {
        self.expect_sym("(", "name lists are written (a, b, c)")?;
        let mut v = vec![self.ident("a name")?];
        while self.sym(",") {
            v.push(self.ident("a name")?);
        }
        self.expect_sym(")", "close the list with )")?;
        Ok(v)
    }

    fn stmt(&mut self) -> Result<Stmt, SpecError> {
        let pos = self.pos();
        if self.kw("network") {
            let name = self.ident("the network's name")?;
            let inputs = self.names()?;
            self.expect_sym(
                "->",
                "declare outputs after ->, e.g. network f(a, b) -> (y)",
            )?;
            let outputs = self.names()?;
            return Ok(Stmt::Network {
                name,
                inputs,
                outputs,
                pos,
            });
        }
        if self.kw("normalise") || self.kw("normalize") {
            let net = self.ident("a network name")?;
            if self.kw("from") {
                let path = self.file_name("normalise f from \"constants.csv\"")?;
                return Ok(Stmt::NormFile { net, path, pos });
            }
            if self.kw("input") {
                let (min, range) = self.keyed_pair(
                    ["min", "range"],
                    "normalise f input min [..] range [..]",
                    Self::vector,
                )?;
                return Ok(Stmt::NormInput {
                    net,
                    min,
                    range,
                    pos,
                });
            }
            if self.kw("output") {
                let (offset, scale) = self.keyed_pair(
                    ["offset", "scale"],
                    "normalise f output offset 0.181 scale 0.012",
                    Self::number_or_vector,
                )?;
                return Ok(Stmt::NormOutput {
                    net,
                    offset,
                    scale,
                    pos,
                });
            }
            return Err(self.err(
                "expected `input`, `output` or `from`",
                "normalise f input min [..] range [..]",
            ));
        }
        if self.kw("domain") {
            let net = self.ident("a network name")?;
            if self.kw("from") {
                self.expect_kw("data", "domain f from data NAME")?;
                let dataset = self.ident("a data set name")?;
                return Ok(Stmt::DomainFrom { net, dataset, pos });
            }
            self.expect_sym(":", "domain f: name in [lo, hi], ...")?;
            let mut bounds = Vec::new();
            loop {
                let p = self.pos();
                let n = self.ident("an input name")?;
                self.expect_kw("in", "domain f: name in [lo, hi], ...")?;
                let (a, b) = self.interval()?;
                bounds.push((n, a, b, p));
                if !self.sym(",") {
                    break;
                }
            }
            return Ok(Stmt::Domain { net, bounds, pos });
        }
        if self.kw("dataset") {
            let name = self.ident("a data set name")?;
            self.expect_sym("=", "dataset NAME = \"file.csv\"")?;
            let path = self.file_name("dataset NAME = \"file.csv\"")?;
            let normalised = self.kw("normalised") || self.kw("normalized");
            return Ok(Stmt::Dataset {
                name,
                path,
                normalised,
                pos,
            });
        }
        if self.kw("param") {
            let name = self.ident("a parameter name")?;
            let range = if self.kw("in") {
                Some(self.interval()?)
            } else {
                None
            };
            let default = if self.sym("=") {
                Some(self.number()?)
            } else {
                None
            };
            return Ok(Stmt::Param {
                name,
                range,
                default,
                pos,
            });
        }
        if self.kw("loop") {
            return self.loop_stmt(pos);
        }
        if self.kw("start") {
            let lp = self.ident("a loop name")?;
            let hint = "start NAME: v_xp = 1, y in [1.4, 4.3], ...";
            self.expect_sym(":", hint)?;
            let mut states = Vec::new();
            loop {
                let p = self.pos();
                let n = self.ident("a state name")?;
                let (a, b) = if self.sym("=") {
                    let v = self.number()?;
                    (v, v)
                } else if self.kw("in") {
                    self.interval()?
                } else {
                    return Err(self.err("expected `=` or `in`", hint));
                };
                states.push((n, a, b, p));
                if !self.sym(",") {
                    break;
                }
            }
            return Ok(Stmt::Start { lp, states, pos });
        }
        if self.kw("goal") {
            let lp = self.ident("a loop name")?;
            let hint = "goal NAME: |x + y| <= 2 at 20 (or from 15: over [15, horizon])";
            self.expect_sym(":", hint)?;
            let expr = self.expr()?;
            self.expect_sym("<=", hint)?;
            let bound = self.number()?;
            let from = if self.kw("from") {
                true
            } else {
                self.expect_kw("at", hint)?;
                false
            };
            let time = self.number()?;
            return Ok(Stmt::Goal {
                lp,
                expr,
                bound,
                from,
                time,
                pos,
            });
        }
        if self.kw("property") {
            let name = self.ident("the property's name")?;
            self.expect_sym(":", "property NAME: formula")?;
            let mut binders = Vec::new();
            while self.kw("for") {
                let bpos = self.pos();
                let point = self.ident("a point name")?;
                self.expect_kw("in", "for p in data NAME, or for p in ball(q, eps)")?;
                if self.kw("data") {
                    let dataset = self.ident("a data set name")?;
                    binders.push(Binder::Data {
                        point,
                        dataset,
                        pos: bpos,
                    });
                } else if self.kw("ball") {
                    self.expect_sym("(", "ball(centre, radius)")?;
                    let centre = self.ident("a point name")?;
                    self.expect_sym(",", "ball(centre, radius)")?;
                    let radius = self.expr()?;
                    self.expect_sym(")", "ball(centre, radius)")?;
                    binders.push(Binder::Ball {
                        point,
                        centre,
                        radius,
                        pos: bpos,
                    });
                } else {
                    return Err(self.err(
                        "expected `data` or `ball`",
                        "for p in data NAME, or for p in ball(q, eps)",
                    ));
                }
                self.expect_sym(",", "separate binders from the formula with a comma")?;
            }
            let formula = self.formula()?;
            return Ok(Stmt::Property {
                name,
                binders,
                formula,
                pos,
            });
        }
        Err(self.err(
            "expected a statement",
            "statements start with network, normalise, domain, dataset, param, property, loop, start or goal",
        ))
    }

    /// `loop NAME of NET: clause, clause, ...` (after the keyword).
    fn loop_stmt(&mut self, pos: Pos) -> Result<Stmt, SpecError> {
        let hint =
            "loop NAME of f: model reduced, period 0.5, horizon 20, clip ex in [0.181, 0.193]";
        let name = self.ident("the loop's name")?;
        self.expect_kw("of", hint)?;
        let net = self.ident("the controller network's name")?;
        self.expect_sym(":", hint)?;
        let mut clauses = Vec::new();
        loop {
            let (p, at) = (self.pos(), self.i);
            let key = self.ident("a clause (model, period, horizon or clip)")?;
            let value = match key.as_str() {
                "model" => LoopValue::Name(self.ident("a model name")?),
                "period" | "horizon" => LoopValue::Number(self.number()?),
                "clip" => {
                    let out = self.ident("an output name")?;
                    self.expect_kw("in", "clip OUT in [lo, hi]")?;
                    let (a, b) = self.interval()?;
                    LoopValue::Clip(out, a, b)
                }
                _ => {
                    self.i = at;
                    return Err(self.err(
                        &format!("unknown clause `{key}`"),
                        "a loop's clauses are model, period, horizon and clip",
                    ));
                }
            };
            clauses.push((key, value, p));
            if !self.sym(",") {
                break;
            }
        }
        Ok(Stmt::Loop {
            name,
            net,
            clauses,
            pos,
        })
    }

    /// formula := or ('=>' formula)?
    pub fn formula(&mut self) -> Result<Formula, SpecError> {
        self.nested(|p| {
            let lhs = p.or()?;
            if p.sym("=>") {
                let rhs = p.formula()?;
                return Ok(Formula::Implies(Box::new(lhs), Box::new(rhs)));
            }
            Ok(lhs)
        })
    }

    fn or(&mut self) -> Result<Formula, SpecError> {
        self.chain("or", Self::and, Formula::Or)
    }

    fn and(&mut self) -> Result<Formula, SpecError> {
        self.chain("and", Self::unary, Formula::And)
    }

    /// `operand (kw operand)*`, flat: the lone operand, or `join` of all of them.
    fn chain(
        &mut self,
        kw: &str,
        operand: fn(&mut Self) -> Result<Formula, SpecError>,
        join: fn(Vec<Formula>) -> Formula,
    ) -> Result<Formula, SpecError> {
        let mut v = vec![operand(self)?];
        while self.kw(kw) {
            v.push(operand(self)?);
        }
        Ok(if v.len() == 1 {
            v.pop().expect("one")
        } else {
            join(v)
        })
    }

    fn unary(&mut self) -> Result<Formula, SpecError> {
        if self.kw("not") {
            return self.nested(|p| Ok(Formula::Not(Box::new(p.unary()?))));
        }
        // A parenthesised formula, or an expression starting with '('.
        if matches!(self.peek(), Tok::Sym("(")) {
            let save = self.i;
            self.i += 1;
            match self.formula() {
                Ok(f) => {
                    if self.sym(")")
                        && !matches!(
                            self.peek(),
                            Tok::Sym("<=" | ">=" | "<" | ">" | "==" | "+" | "-" | "*" | "/")
                        )
                    {
                        return Ok(f);
                    }
                }
                // Too deep is too deep either way: do not retry as an expression.
                Err(e) if self.too_deep => return Err(e),
                Err(_) => {}
            }
            self.i = save;
        }
        let pos = self.pos();
        let mut es = vec![self.expr()?];
        let mut rs = Vec::new();
        loop {
            let r = match self.peek() {
                Tok::Sym("<=") => Rel::Le,
                Tok::Sym("<") => Rel::Lt,
                Tok::Sym(">=") => Rel::Ge,
                Tok::Sym(">") => Rel::Gt,
                Tok::Sym("==") => Rel::Eq,
                _ => break,
            };
            self.i += 1;
            rs.push(r);
            es.push(self.expr()?);
        }
        if rs.is_empty() {
            return Err(self.err(
                "expected a comparison (<=, <, >=, >, ==)",
                "formulas compare expressions, e.g. ex >= 0.187",
            ));
        }
        Ok(Formula::Chain(es, rs, pos))
    }

    /// expr := term (('+'|'-') term)*
    pub fn expr(&mut self) -> Result<Expr, SpecError> {
        self.nested(|p| {
            let mut terms = vec![(false, p.term()?)];
            loop {
                if p.sym("+") {
                    terms.push((false, p.term()?));
                } else if p.sym("-") {
                    terms.push((true, p.term()?));
                } else if terms.len() == 1 {
                    return Ok(terms.pop().expect("one").1);
                } else {
                    return Ok(Expr::Sum(terms));
                }
            }
        })
    }

    fn term(&mut self) -> Result<Expr, SpecError> {
        let first = self.factor()?;
        let mut rest = Vec::new();
        loop {
            let pos = self.pos();
            if self.sym("*") {
                rest.push((false, self.factor()?, pos));
            } else if self.sym("/") {
                rest.push((true, self.factor()?, pos));
            } else if rest.is_empty() {
                return Ok(first);
            } else {
                return Ok(Expr::Prod(Box::new(first), rest));
            }
        }
    }

    fn factor(&mut self) -> Result<Expr, SpecError> {
        let pos = self.pos();
        if self.sym("-") {
            return self.nested(|p| Ok(Expr::Neg(Box::new(p.factor()?))));
        }
        if self.sym("(") {
            let e = self.expr()?;
            self.expect_sym(")", "close the parenthesis")?;
            return Ok(e);
        }
        if self.sym("|") {
            let e = self.expr()?;
            self.expect_sym("|", "close the absolute value with |")?;
            return Ok(Expr::Abs(Box::new(e)));
        }
        match self.peek().clone() {
            Tok::Num(v) => {
                self.i += 1;
                Ok(Expr::Num(v))
            }
            Tok::Id(name) if name == "norm" => {
                self.i += 1;
                self.expect_sym("(", "norm(p - q)")?;
                let a = self.ident("a point name")?;
                self.expect_sym(
                    "-",
                    "norm(p - q): the infinity norm of a difference of points",
                )?;
                let b = self.ident("a point name")?;
                self.expect_sym(")", "norm(p - q)")?;
                Ok(Expr::Norm(a, b, pos))
            }
            Tok::Id(_) => {
                let name = self.ident("a name")?;
                if self.sym("(") {
                    let point = self.ident("a point name")?;
                    self.expect_sym(")", "network applications are written f(p)")?;
                    let out = if self.sym(".") {
                        Some(self.ident("an output name")?)
                    } else {
                        None
                    };
                    return Ok(Expr::Call(name, point, out, pos));
                }
                if self.sym(".") {
                    let comp = self.ident("a component name")?;
                    return Ok(Expr::Name(Some(name), comp, pos));
                }
                Ok(Expr::Name(None, name, pos))
            }
            _ => Err(self.err(
                "expected a number, a name, ( or |",
                "e.g. -x + ystar, f(x1), |f(x1) - f(x0)|",
            )),
        }
    }
}
