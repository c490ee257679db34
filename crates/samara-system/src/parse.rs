//! The parser: tokens to statements and expression trees. Sums and products are flat
//! chains, so a tree is only as deep as its brackets, unary signs, powers, calls and
//! `if`s, and that nesting is capped at [`MAX_NESTING`]: no input can overflow the
//! stack of the parser, the compiler or the destructor.

use crate::error::{Pos, SystemError};
use crate::lex::{err, Tok, Token};

/// Deepest accepted nesting of brackets, unary signs, powers, calls and `if`s.
pub const MAX_NESTING: usize = 256;

/// Binary operators of a chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Bin {
    Add,
    Sub,
    Mul,
    Div,
}

/// Comparisons of an `if`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Cmp {
    Lt,
    Le,
    Gt,
    Ge,
}

/// Expression trees.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Expr {
    Num(f64, Pos),
    Name(String, Pos),
    Net(usize, Pos),
    Neg(Box<Expr>, Pos),
    /// `first op1 e1 op2 e2 ...`, evaluated left to right; one precedence level.
    Chain(Box<Expr>, Vec<(Bin, Pos, Expr)>),
    Pow(Box<Expr>, Box<Expr>, Pos),
    Call(String, Vec<Expr>, Pos),
    /// `if l cmp r then a else b`.
    If(Cmp, Box<[Expr; 4]>, Pos),
}

impl Expr {
    pub(crate) fn pos(&self) -> Pos {
        match self {
            Expr::Num(_, p)
            | Expr::Name(_, p)
            | Expr::Net(_, p)
            | Expr::Neg(_, p)
            | Expr::Pow(_, _, p)
            | Expr::Call(_, _, p)
            | Expr::If(_, _, p) => *p,
            Expr::Chain(first, _) => first.pos(),
        }
    }
}

/// When a goal is checked.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum WhenAst {
    End,
    Always(Option<(Expr, Expr)>),
    Eventually(Option<(Expr, Expr)>),
}

/// Goal kinds.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum GoalAst {
    Reach(Vec<(String, Pos, Expr, Expr)>),
    Avoid(Vec<(String, Pos, Expr, Expr)>),
    /// `expr in [lo, hi]`, `expr <= hi`, `expr >= lo`, `|expr| <= hi`.
    Band {
        expr: Expr,
        lo: Option<Expr>,
        hi: Option<Expr>,
        abs: bool,
    },
}

/// Statements.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Stmt {
    System(String, Pos),
    State(Vec<(String, Pos)>),
    Input(Vec<(String, Pos)>),
    Param(String, Pos, Expr),
    Let(String, Pos, Expr),
    Eq(String, Pos, Expr),
    Period(Expr, Pos),
    Horizon(Expr, Pos),
    Observe(Vec<Expr>, Pos),
    Actuate {
        name: String,
        pos: Pos,
        expr: Expr,
        clip: Option<(Expr, Expr)>,
    },
    Reset(String, Pos, Expr),
    Init(String, Pos, Expr, Expr),
    Goal(GoalAst, WhenAst, Pos),
    /// `mode NAME in [V1, V2, ...]`: a finite discrete state and its values.
    Mode(String, Pos, Vec<(String, Pos)>),
    /// `next x = expr`: the discrete-time update of a state.
    Next(String, Pos, Expr),
    /// `next MODE = argmax(net)`: the mode's new value is the index of the largest
    /// network output.
    NextArgmax(String, Pos),
    /// `networks by MODE`: one network per mode value, chosen by its current value.
    NetworksBy(String, Pos),
    /// `actuate u = E1, E2, ... when MODE = VALUE`: the values `u` may take when the
    /// mode's new value is `VALUE`.
    ActuateTable {
        name: String,
        pos: Pos,
        values: Vec<Expr>,
        mode: (String, Pos),
        value: (String, Pos),
    },
}

/// The functions of the language with their number of arguments (min, max).
pub(crate) fn function_arity(name: &str) -> Option<(usize, usize)> {
    Some(match name {
        "sqrt" | "exp" | "log" | "ln" | "sin" | "cos" | "tan" | "tanh" | "atan" | "abs"
        | "sign" => (1, 1),
        "min" | "max" => (2, 64),
        _ => return None,
    })
}

/// The function names, for suggestions.
pub(crate) const FUNCTIONS: &[&str] = &[
    "sqrt", "exp", "log", "ln", "sin", "cos", "tan", "tanh", "atan", "abs", "sign", "min", "max",
];

/// Statement keywords (not usable as names).
pub(crate) const KEYWORDS: &[&str] = &[
    "system",
    "state",
    "input",
    "param",
    "let",
    "period",
    "horizon",
    "observe",
    "actuate",
    "reset",
    "init",
    "goal",
    "if",
    "then",
    "else",
    "net",
    "clip",
    "in",
    "reach",
    "avoid",
    "band",
    "at",
    "end",
    "always",
    "eventually",
    "pi",
];

struct Parser<'a> {
    toks: &'a [Token],
    i: usize,
    file: &'a str,
    src: &'a str,
    depth: usize,
}

type R<T> = Result<T, SystemError>;

fn describe(t: &Tok) -> String {
    match t {
        Tok::Id(s) => format!("`{s}`"),
        Tok::Num(v) => format!("the number {v}"),
        Tok::Sym(s) => format!("`{s}`"),
        Tok::Newline => "the end of the line".into(),
        Tok::Eof => "the end of the file".into(),
    }
}

impl<'a> Parser<'a> {
    fn peek(&self) -> &Tok {
        &self.toks[self.i].tok
    }
    fn pos(&self) -> Pos {
        self.toks[self.i].pos
    }
    fn bump(&mut self) -> Token {
        let t = self.toks[self.i].clone();
        if self.i + 1 < self.toks.len() {
            self.i += 1;
        }
        t
    }
    fn fail<T>(&self, pos: Pos, message: String, hint: &str) -> R<T> {
        Err(err(self.file, self.src, pos, message, hint))
    }
    fn is_sym(&self, s: &str) -> bool {
        matches!(self.peek(), Tok::Sym(x) if *x == s)
    }
    fn is_kw(&self, s: &str) -> bool {
        matches!(self.peek(), Tok::Id(x) if x == s)
    }
    fn expect_sym(&mut self, s: &str, hint: &str) -> R<Pos> {
        if self.is_sym(s) {
            Ok(self.bump().pos)
        } else {
            let found = describe(self.peek());
            self.fail(self.pos(), format!("expected `{s}`, found {found}"), hint)
        }
    }
    fn expect_kw(&mut self, s: &str, hint: &str) -> R<Pos> {
        if self.is_kw(s) {
            Ok(self.bump().pos)
        } else {
            let found = describe(self.peek());
            self.fail(self.pos(), format!("expected `{s}`, found {found}"), hint)
        }
    }
    fn name(&mut self, what: &str, hint: &str) -> R<(String, Pos)> {
        match self.peek().clone() {
            Tok::Id(s) => {
                let pos = self.bump().pos;
                if KEYWORDS.contains(&s.as_str()) || function_arity(&s).is_some() {
                    return self.fail(
                        pos,
                        format!("`{s}` is reserved and cannot name {what}"),
                        "pick another name (keywords and function names are reserved)",
                    );
                }
                Ok((s, pos))
            }
            t => self.fail(
                self.pos(),
                format!("expected {what}, found {}", describe(&t)),
                hint,
            ),
        }
    }
    fn end_of_statement(&mut self) -> R<()> {
        match self.peek() {
            Tok::Newline => {
                self.bump();
                Ok(())
            }
            Tok::Eof => Ok(()),
            t => {
                let found = describe(t);
                self.fail(
                    self.pos(),
                    format!("expected the end of the statement, found {found}"),
                    "one statement per line; continue a long line with `\\` or inside brackets",
                )
            }
        }
    }
    fn enter(&mut self, pos: Pos) -> R<()> {
        self.depth += 1;
        if self.depth > MAX_NESTING {
            return self.fail(
                pos,
                format!("the expression nests deeper than {MAX_NESTING} levels"),
                "name intermediate results with `let` definitions",
            );
        }
        Ok(())
    }

    fn expr(&mut self) -> R<Expr> {
        if self.is_kw("if") {
            let pos = self.bump().pos;
            self.enter(pos)?;
            let l = self.sum()?;
            let cmp = match self.peek() {
                Tok::Sym("<") => Cmp::Lt,
                Tok::Sym("<=") => Cmp::Le,
                Tok::Sym(">") => Cmp::Gt,
                Tok::Sym(">=") => Cmp::Ge,
                t => {
                    let found = describe(t);
                    return self.fail(
                        self.pos(),
                        format!("expected a comparison (< <= > >=), found {found}"),
                        "write `if a < b then x else y`",
                    );
                }
            };
            self.bump();
            let r = self.sum()?;
            self.expect_kw("then", "write `if a < b then x else y`")?;
            let a = self.expr()?;
            self.expect_kw("else", "write `if a < b then x else y`")?;
            let b = self.expr()?;
            self.depth -= 1;
            return Ok(Expr::If(cmp, Box::new([l, r, a, b]), pos));
        }
        self.sum()
    }

    fn sum(&mut self) -> R<Expr> {
        let first = self.product()?;
        let mut rest = Vec::new();
        loop {
            let op = match self.peek() {
                Tok::Sym("+") => Bin::Add,
                Tok::Sym("-") => Bin::Sub,
                _ => break,
            };
            let pos = self.bump().pos;
            rest.push((op, pos, self.product()?));
        }
        Ok(if rest.is_empty() {
            first
        } else {
            Expr::Chain(Box::new(first), rest)
        })
    }

    fn product(&mut self) -> R<Expr> {
        let first = self.unary()?;
        let mut rest = Vec::new();
        loop {
            let op = match self.peek() {
                Tok::Sym("*") => Bin::Mul,
                Tok::Sym("/") => Bin::Div,
                _ => break,
            };
            let pos = self.bump().pos;
            rest.push((op, pos, self.unary()?));
        }
        Ok(if rest.is_empty() {
            first
        } else {
            Expr::Chain(Box::new(first), rest)
        })
    }

    fn unary(&mut self) -> R<Expr> {
        if self.is_sym("-") || self.is_sym("+") {
            let t = self.bump();
            self.enter(t.pos)?;
            let e = self.unary()?;
            self.depth -= 1;
            return Ok(if t.tok == Tok::Sym("-") {
                Expr::Neg(Box::new(e), t.pos)
            } else {
                e
            });
        }
        let base = self.primary()?;
        if self.is_sym("^") {
            let pos = self.bump().pos;
            self.enter(pos)?;
            let e = self.unary()?;
            self.depth -= 1;
            return Ok(Expr::Pow(Box::new(base), Box::new(e), pos));
        }
        Ok(base)
    }

    fn primary(&mut self) -> R<Expr> {
        let t = self.bump();
        match t.tok {
            Tok::Num(v) => Ok(Expr::Num(v, t.pos)),
            Tok::Sym("(") => {
                self.enter(t.pos)?;
                let e = self.expr()?;
                self.expect_sym(")", "close the bracket opened here")?;
                self.depth -= 1;
                Ok(e)
            }
            Tok::Id(s) if s == "net" => {
                self.expect_sym("[", "network outputs are written `net[0]`, `net[1]`, ...")?;
                let p = self.pos();
                let k = match self.bump().tok {
                    Tok::Num(v) if v >= 0.0 && v.fract() == 0.0 && v < 65536.0 => v as usize,
                    _ => {
                        return self.fail(
                            p,
                            "a network output index must be an integer from 0 to 65535".into(),
                            "write `net[0]` for the first output",
                        )
                    }
                };
                self.expect_sym("]", "network outputs are written `net[0]`")?;
                Ok(Expr::Net(k, t.pos))
            }
            Tok::Id(s) => {
                if self.is_sym("(") {
                    self.bump();
                    self.enter(t.pos)?;
                    let mut args = Vec::new();
                    if !self.is_sym(")") {
                        loop {
                            args.push(self.expr()?);
                            if self.is_sym(",") {
                                self.bump();
                            } else {
                                break;
                            }
                        }
                    }
                    self.expect_sym(
                        ")",
                        "separate arguments with `,` and close the call with `)`",
                    )?;
                    self.depth -= 1;
                    Ok(Expr::Call(s, args, t.pos))
                } else {
                    Ok(Expr::Name(s, t.pos))
                }
            }
            other => self.fail(
                t.pos,
                format!(
                    "expected a number, a name or `(`, found {}",
                    describe(&other)
                ),
                "complete the expression",
            ),
        }
    }

    /// `[lo, hi]`
    fn range(&mut self) -> R<(Expr, Expr)> {
        self.expect_sym("[", "write an interval as `[lo, hi]`")?;
        let lo = self.expr()?;
        self.expect_sym(",", "write an interval as `[lo, hi]`")?;
        let hi = self.expr()?;
        self.expect_sym("]", "write an interval as `[lo, hi]`")?;
        Ok((lo, hi))
    }

    fn names(&mut self, what: &str, hint: &str) -> R<Vec<(String, Pos)>> {
        let mut v = vec![self.name(what, hint)?];
        while self.is_sym(",") {
            self.bump();
            v.push(self.name(what, hint)?);
        }
        Ok(v)
    }

    fn boxes(&mut self) -> R<Vec<(String, Pos, Expr, Expr)>> {
        let mut v = Vec::new();
        loop {
            let (n, p) = self.name(
                "a state name",
                "write e.g. `goal reach x in [-1, 1], y in [0, 2] at end`",
            )?;
            self.expect_kw("in", "write e.g. `x in [-1, 1]`")?;
            let (lo, hi) = self.range()?;
            v.push((n, p, lo, hi));
            if self.is_sym(",") {
                self.bump();
            } else {
                return Ok(v);
            }
        }
    }

    fn window(&mut self) -> R<Option<(Expr, Expr)>> {
        if self.is_sym("[") {
            Ok(Some(self.range()?))
        } else {
            Ok(None)
        }
    }

    fn statement(&mut self) -> R<Option<Stmt>> {
        let t = self.toks[self.i].clone();
        let kw = match &t.tok {
            Tok::Newline => {
                self.bump();
                return Ok(None);
            }
            Tok::Id(s) => s.clone(),
            other => {
                return self.fail(
                    t.pos,
                    format!("expected a statement, found {}", describe(other)),
                    "statements start with state, input, param, let, NAME' =, next, mode, networks, period, horizon, observe, actuate, reset, init or goal",
                )
            }
        };
        // `x' = expr`
        if matches!(
            self.toks.get(self.i + 1).map(|t| &t.tok),
            Some(Tok::Sym("'"))
        ) {
            self.bump();
            self.bump();
            self.expect_sym("=", "write a differential equation as `x' = expr`")?;
            let e = self.expr()?;
            self.end_of_statement()?;
            return Ok(Some(Stmt::Eq(kw, t.pos, e)));
        }
        self.bump();
        let st = match kw.as_str() {
            "system" => {
                let (n, p) = self.name("a system name", "write `system my_plant`")?;
                Stmt::System(n, p)
            }
            "state" => Stmt::State(self.names("a state name", "write `state x, v`")?),
            "input" => Stmt::Input(self.names("an input name", "write `input u`")?),
            "param" | "let" => {
                let (n, p) =
                    self.name("a name", "write `param g = 9.81` or `let s = sin(theta)`")?;
                self.expect_sym("=", "write `param g = 9.81` or `let s = sin(theta)`")?;
                let e = self.expr()?;
                if kw == "param" {
                    Stmt::Param(n, p, e)
                } else {
                    Stmt::Let(n, p, e)
                }
            }
            "next" => {
                let hint = "write `next x = x + period * v` or `next MODE = argmax(net)`";
                let (n, p) = self.name("a state or mode name", hint)?;
                self.expect_sym("=", hint)?;
                if self.is_kw("argmax") {
                    self.bump();
                    self.expect_sym("(", "write `argmax(net)`")?;
                    self.expect_kw("net", "write `argmax(net)`: the network's outputs")?;
                    self.expect_sym(")", "write `argmax(net)`")?;
                    Stmt::NextArgmax(n, p)
                } else {
                    Stmt::Next(n, p, self.expr()?)
                }
            }
            "mode" => {
                let hint = "write `mode adv in [COC, DNC, DND]`";
                let (n, p) = self.name("a mode name", hint)?;
                self.expect_kw("in", hint)?;
                self.expect_sym("[", hint)?;
                let v = self.names("a mode value", hint)?;
                self.expect_sym("]", hint)?;
                Stmt::Mode(n, p, v)
            }
            "networks" => {
                let hint = "write `networks by adv`: one network per value of the mode";
                self.expect_kw("by", hint)?;
                let (n, p) = self.name("a mode name", hint)?;
                Stmt::NetworksBy(n, p)
            }
            "period" => Stmt::Period(self.expr()?, t.pos),
            "horizon" => Stmt::Horizon(self.expr()?, t.pos),
            "observe" => {
                let mut v = vec![self.expr()?];
                while self.is_sym(",") {
                    self.bump();
                    v.push(self.expr()?);
                }
                Stmt::Observe(v, t.pos)
            }
            "actuate" => {
                let (n, p) =
                    self.name("an input name", "write `actuate u = net[0] clip [-1, 1]`")?;
                self.expect_sym("=", "write `actuate u = 2 * net[0] - 1`")?;
                let e = self.expr()?;
                if self.is_sym(",") || self.is_kw("when") {
                    let hint = "write `actuate acc = -1, 0, 1 when adv = COC`";
                    let mut values = vec![e];
                    while self.is_sym(",") {
                        self.bump();
                        values.push(self.expr()?);
                    }
                    self.expect_kw("when", hint)?;
                    let mode = self.name("a mode name", hint)?;
                    self.expect_sym("=", hint)?;
                    let value = self.name("a mode value", hint)?;
                    self.end_of_statement()?;
                    return Ok(Some(Stmt::ActuateTable {
                        name: n,
                        pos: p,
                        values,
                        mode,
                        value,
                    }));
                }
                let clip = if self.is_kw("clip") {
                    self.bump();
                    Some(self.range()?)
                } else {
                    None
                };
                Stmt::Actuate {
                    name: n,
                    pos: p,
                    expr: e,
                    clip,
                }
            }
            "reset" => {
                let (n, p) = self.name("a state name", "write `reset E = 0`")?;
                self.expect_sym("=", "write `reset E = 0`")?;
                Stmt::Reset(n, p, self.expr()?)
            }
            "init" => {
                let (n, p) =
                    self.name("a state name", "write `init x = 1` or `init x in [0, 1]`")?;
                if self.is_sym("=") {
                    self.bump();
                    let e = self.expr()?;
                    Stmt::Init(n, p, e.clone(), e)
                } else {
                    self.expect_kw("in", "write `init x = 1` or `init x in [0, 1]`")?;
                    let (lo, hi) = self.range()?;
                    Stmt::Init(n, p, lo, hi)
                }
            }
            "goal" => {
                let g = if self.is_kw("reach") {
                    self.bump();
                    GoalAst::Reach(self.boxes()?)
                } else if self.is_kw("avoid") {
                    self.bump();
                    GoalAst::Avoid(self.boxes()?)
                } else if self.is_kw("band") {
                    self.bump();
                    let abs = self.is_sym("|");
                    if abs {
                        self.bump();
                    }
                    let e = self.sum()?;
                    if abs {
                        self.expect_sym("|", "write `goal band |x + y| <= 2 at end`")?;
                    }
                    let hint = "write `|e| <= Y`, `e <= hi`, `e >= lo` or `e in [lo, hi]`";
                    let (lo, hi) = if abs {
                        self.expect_sym("<=", hint)?;
                        (None, Some(self.sum()?))
                    } else if self.is_sym("<=") {
                        self.bump();
                        (None, Some(self.sum()?))
                    } else if self.is_sym(">=") {
                        self.bump();
                        (Some(self.sum()?), None)
                    } else if self.is_kw("in") {
                        self.bump();
                        let (l, h) = self.range()?;
                        (Some(l), Some(h))
                    } else {
                        let found = describe(self.peek());
                        return self.fail(
                            self.pos(),
                            format!("expected `<=`, `>=` or `in`, found {found}"),
                            hint,
                        );
                    };
                    GoalAst::Band {
                        expr: e,
                        lo,
                        hi,
                        abs,
                    }
                } else {
                    let found = describe(self.peek());
                    return self.fail(
                        self.pos(),
                        format!("expected `reach`, `avoid` or `band`, found {found}"),
                        "write `goal reach x in [0, 1] at end`, `goal avoid ... always` or `goal band |x + y| <= 2 at end`",
                    );
                };
                let hint = "end a goal with `at end`, `always`, `always [t1, t2]`, `eventually` or `eventually [t1, t2]`";
                let w = if self.is_kw("at") {
                    self.bump();
                    self.expect_kw("end", hint)?;
                    WhenAst::End
                } else if self.is_kw("always") {
                    self.bump();
                    WhenAst::Always(self.window()?)
                } else if self.is_kw("eventually") {
                    self.bump();
                    WhenAst::Eventually(self.window()?)
                } else {
                    let found = describe(self.peek());
                    return self.fail(
                        self.pos(),
                        format!("expected when the goal is checked, found {found}"),
                        hint,
                    );
                };
                Stmt::Goal(g, w, t.pos)
            }
            other => {
                let known = [
                    "system", "state", "input", "param", "let", "period", "horizon", "observe",
                    "actuate", "reset", "init", "goal", "next", "mode", "networks",
                ];
                let hint = match crate::error::closest(other, known.iter().copied()) {
                    Some(s) => format!("did you mean `{s}`? (a differential equation is written `{other}' = expr`)"),
                    None => format!("statements start with one of: {}, or are equations `x' = expr`", known.join(", ")),
                };
                return self.fail(t.pos, format!("unknown statement `{other}`"), &hint);
            }
        };
        self.end_of_statement()?;
        Ok(Some(st))
    }
}

/// Parse a token list into statements.
pub(crate) fn parse(toks: &[Token], file: &str, src: &str) -> R<Vec<Stmt>> {
    let mut p = Parser {
        toks,
        i: 0,
        file,
        src,
        depth: 0,
    };
    let mut out = Vec::new();
    while *p.peek() != Tok::Eof {
        if let Some(s) = p.statement()? {
            out.push(s);
        }
    }
    Ok(out)
}
