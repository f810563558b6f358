//! Arithmetic expressions over parameters: `m_c / 2`, `-l_c`, `2 * (l_c + l_t)`,
//! `4.57 * wheel_radius^-0.149 * 1e-8`.
//!
//! Grammar (usual precedence, `^` right-associative and above unary minus, so `-x^2` is
//! `-(x^2)` and `R^-0.149` is `R^(-0.149)`):
//! ```text
//! expr  := term (('+' | '-') term)*
//! term  := unary (('*' | '/') unary)*
//! unary := ('-' | '+') unary | power
//! power := atom ('^' unary)?
//! atom  := number | name | name '(' expr (',' expr)* ')' | '(' expr ')'
//! ```
//! Names are parameters, or the constant `pi`; functions are `sqrt`, `abs`, `exp`, `ln`,
//! `sin`, `cos`, `min`, `max`. Evaluation follows the tree left to right in IEEE double
//! precision, so `(m_c + 2 * m_t) * g / 4` is computed exactly as Rust computes
//! `(m_c + 2.0 * m_t) * g / 4.0`: a description reproduces hand-written arithmetic bit for bit.

use std::fmt;

/// Binary operators.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Op {
    /// `+`
    Add,
    /// `-`
    Sub,
    /// `*`
    Mul,
    /// `/`
    Div,
    /// `^` (`powf`)
    Pow,
}

/// Built-in functions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Func {
    /// Square root.
    Sqrt,
    /// Absolute value.
    Abs,
    /// `e^x`.
    Exp,
    /// Natural logarithm.
    Ln,
    /// Sine (rad).
    Sin,
    /// Cosine (rad).
    Cos,
    /// Smallest argument.
    Min,
    /// Largest argument.
    Max,
}

impl Func {
    const ALL: [(&'static str, Func, Option<usize>); 8] = [
        ("sqrt", Func::Sqrt, Some(1)),
        ("abs", Func::Abs, Some(1)),
        ("exp", Func::Exp, Some(1)),
        ("ln", Func::Ln, Some(1)),
        ("sin", Func::Sin, Some(1)),
        ("cos", Func::Cos, Some(1)),
        ("min", Func::Min, None),
        ("max", Func::Max, None),
    ];

    fn name(self) -> &'static str {
        Self::ALL.iter().find(|f| f.1 == self).expect("listed").0
    }
}

/// Whether `name` is taken by the expression language (a function or the constant `pi`), so
/// that it cannot name a parameter.
pub fn is_reserved(name: &str) -> bool {
    name == "pi" || Func::ALL.iter().any(|f| f.0 == name)
}

/// An expression tree. `Var` holds the parameter's name until [`Expr::resolve`] gives it the
/// parameter's index.
#[derive(Debug, Clone, PartialEq)]
pub enum Expr {
    /// A literal.
    Num(f64),
    /// A parameter: its name and, once resolved, its index.
    Var(String, Option<usize>),
    /// Unary minus.
    Neg(Box<Expr>),
    /// A binary operation.
    Bin(Op, Box<Expr>, Box<Expr>),
    /// A function call.
    Call(Func, Vec<Expr>),
}

/// Why an expression does not parse, with the 1-based character column in its text.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("column {column} of `{text}`: {message}")]
pub struct ExprError {
    /// The expression text.
    pub text: String,
    /// Column (1-based, characters).
    pub column: usize,
    /// What is wrong.
    pub message: String,
}

/// Longest expression text accepted (characters).
pub const MAX_LEN: usize = 4096;
/// Deepest nesting accepted.
pub const MAX_NESTING: usize = 64;

struct Lexer<'a> {
    text: &'a str,
    chars: Vec<(usize, char)>,
    at: usize,
    depth: usize,
}

impl<'a> Lexer<'a> {
    fn err(&self, message: impl Into<String>) -> ExprError {
        ExprError {
            text: self.text.to_owned(),
            column: self.at.min(self.chars.len()) + 1,
            message: message.into(),
        }
    }

    fn skip_ws(&mut self) {
        while self.at < self.chars.len() && self.chars[self.at].1.is_whitespace() {
            self.at += 1;
        }
    }

    fn peek(&mut self) -> Option<char> {
        self.skip_ws();
        self.chars.get(self.at).map(|c| c.1)
    }

    fn eat(&mut self, c: char) -> bool {
        if self.peek() == Some(c) {
            self.at += 1;
            true
        } else {
            false
        }
    }

    fn expr(&mut self) -> Result<Expr, ExprError> {
        self.depth += 1;
        if self.depth > MAX_NESTING {
            return Err(self.err(format!("nested deeper than {MAX_NESTING} levels")));
        }
        let mut left = self.term()?;
        loop {
            let op = match self.peek() {
                Some('+') => Op::Add,
                Some('-') => Op::Sub,
                _ => break,
            };
            self.at += 1;
            let right = self.term()?;
            left = Expr::Bin(op, Box::new(left), Box::new(right));
        }
        self.depth -= 1;
        Ok(left)
    }

    fn term(&mut self) -> Result<Expr, ExprError> {
        let mut left = self.unary()?;
        loop {
            let op = match self.peek() {
                Some('*') => Op::Mul,
                Some('/') => Op::Div,
                _ => break,
            };
            self.at += 1;
            let right = self.unary()?;
            left = Expr::Bin(op, Box::new(left), Box::new(right));
        }
        Ok(left)
    }

    fn unary(&mut self) -> Result<Expr, ExprError> {
        self.depth += 1;
        if self.depth > MAX_NESTING {
            return Err(self.err(format!("nested deeper than {MAX_NESTING} levels")));
        }
        let e = if self.eat('-') {
            Expr::Neg(Box::new(self.unary()?))
        } else if self.eat('+') {
            self.unary()?
        } else {
            self.power()?
        };
        self.depth -= 1;
        Ok(e)
    }

    fn power(&mut self) -> Result<Expr, ExprError> {
        let base = self.atom()?;
        if self.eat('^') {
            let exponent = self.unary()?;
            return Ok(Expr::Bin(Op::Pow, Box::new(base), Box::new(exponent)));
        }
        Ok(base)
    }

    fn atom(&mut self) -> Result<Expr, ExprError> {
        match self.peek() {
            None => Err(self.err("expected a number, a name or `(`, found the end")),
            Some('(') => {
                self.at += 1;
                let e = self.expr()?;
                if !self.eat(')') {
                    return Err(self.err("expected `)`"));
                }
                Ok(e)
            }
            Some(c) if c.is_ascii_digit() || c == '.' => self.number(),
            Some(c) if c.is_ascii_alphabetic() || c == '_' => {
                let start = self.at;
                while self.at < self.chars.len()
                    && (self.chars[self.at].1.is_ascii_alphanumeric()
                        || self.chars[self.at].1 == '_')
                {
                    self.at += 1;
                }
                let name: String = self.chars[start..self.at].iter().map(|c| c.1).collect();
                if self.peek() == Some('(') {
                    let column = start;
                    let Some(&(_, func, arity)) = Func::ALL.iter().find(|f| f.0 == name) else {
                        self.at = column;
                        let known: Vec<&str> = Func::ALL.iter().map(|f| f.0).collect();
                        return Err(self.err(format!(
                            "unknown function `{name}` (functions: {})",
                            known.join(", ")
                        )));
                    };
                    self.at += 1;
                    let mut args = vec![self.expr()?];
                    while self.eat(',') {
                        args.push(self.expr()?);
                    }
                    if !self.eat(')') {
                        return Err(self.err("expected `,` or `)`"));
                    }
                    if let Some(n) = arity {
                        if args.len() != n {
                            self.at = column;
                            return Err(self.err(format!(
                                "`{name}` takes {n} argument(s), found {}",
                                args.len()
                            )));
                        }
                    }
                    return Ok(Expr::Call(func, args));
                }
                if name == "pi" {
                    return Ok(Expr::Num(std::f64::consts::PI));
                }
                Ok(Expr::Var(name, None))
            }
            Some(c) => Err(self.err(format!("unexpected `{c}`"))),
        }
    }

    fn number(&mut self) -> Result<Expr, ExprError> {
        let start = self.at;
        let digits = |s: &mut Self| {
            while s.at < s.chars.len() && s.chars[s.at].1.is_ascii_digit() {
                s.at += 1;
            }
        };
        digits(self);
        if self.at < self.chars.len() && self.chars[self.at].1 == '.' {
            self.at += 1;
            digits(self);
        }
        if self.at < self.chars.len() && matches!(self.chars[self.at].1, 'e' | 'E') {
            let mark = self.at;
            self.at += 1;
            if self.at < self.chars.len() && matches!(self.chars[self.at].1, '+' | '-') {
                self.at += 1;
            }
            let exp_start = self.at;
            digits(self);
            if self.at == exp_start {
                self.at = mark;
                return Err(self.err("a number's exponent needs digits"));
            }
        }
        let text: String = self.chars[start..self.at].iter().map(|c| c.1).collect();
        match text.parse::<f64>() {
            Ok(v) => Ok(Expr::Num(v)),
            Err(_) => {
                self.at = start;
                Err(self.err(format!("`{text}` is not a number")))
            }
        }
    }
}

impl Expr {
    /// Parses an expression.
    pub fn parse(text: &str) -> Result<Expr, ExprError> {
        if text.chars().count() > MAX_LEN {
            return Err(ExprError {
                text: text.chars().take(40).collect::<String>() + "...",
                column: MAX_LEN,
                message: format!("longer than {MAX_LEN} characters"),
            });
        }
        let mut lx = Lexer {
            text,
            chars: text.char_indices().collect(),
            at: 0,
            depth: 0,
        };
        let e = lx.expr()?;
        if lx.peek().is_some() {
            let c = lx.chars[lx.at].1;
            return Err(lx.err(format!("unexpected `{c}` after a complete expression")));
        }
        Ok(e)
    }

    /// Parameter names the expression uses, in order of appearance (with repeats).
    pub fn names(&self) -> Vec<&str> {
        let mut out = Vec::new();
        self.walk(&mut |e| {
            if let Expr::Var(n, _) = e {
                out.push(n.as_str());
            }
        });
        out
    }

    /// Indices of the parameters the expression reads (resolved names only, with repeats).
    pub fn parameters(&self) -> Vec<usize> {
        let mut out = Vec::new();
        self.walk(&mut |e| {
            if let Expr::Var(_, Some(i)) = e {
                out.push(*i);
            }
        });
        out
    }

    fn walk<'a>(&'a self, f: &mut impl FnMut(&'a Expr)) {
        f(self);
        match self {
            Expr::Num(_) | Expr::Var(..) => {}
            Expr::Neg(e) => e.walk(f),
            Expr::Bin(_, a, b) => {
                a.walk(f);
                b.walk(f);
            }
            Expr::Call(_, args) => args.iter().for_each(|a| a.walk(f)),
        }
    }

    /// Gives every name its index by `lookup`; the first name it does not know is returned.
    pub fn resolve(&mut self, lookup: &impl Fn(&str) -> Option<usize>) -> Result<(), String> {
        match self {
            Expr::Num(_) => Ok(()),
            Expr::Var(name, id) => match lookup(name) {
                Some(i) => {
                    *id = Some(i);
                    Ok(())
                }
                None => Err(name.clone()),
            },
            Expr::Neg(e) => e.resolve(lookup),
            Expr::Bin(_, a, b) => {
                a.resolve(lookup)?;
                b.resolve(lookup)
            }
            Expr::Call(_, args) => args.iter_mut().try_for_each(|a| a.resolve(lookup)),
        }
    }

    /// The value, with parameter `i` taking `values[i]` (names must be resolved).
    pub fn eval(&self, values: &[f64]) -> f64 {
        match self {
            Expr::Num(v) => *v,
            Expr::Var(_, id) => values[id.expect("resolved before evaluation")],
            Expr::Neg(e) => -e.eval(values),
            Expr::Bin(op, a, b) => {
                let (a, b) = (a.eval(values), b.eval(values));
                match op {
                    Op::Add => a + b,
                    Op::Sub => a - b,
                    Op::Mul => a * b,
                    Op::Div => a / b,
                    Op::Pow => a.powf(b),
                }
            }
            Expr::Call(f, args) => {
                let x = args[0].eval(values);
                match f {
                    Func::Sqrt => x.sqrt(),
                    Func::Abs => x.abs(),
                    Func::Exp => x.exp(),
                    Func::Ln => x.ln(),
                    Func::Sin => x.sin(),
                    Func::Cos => x.cos(),
                    Func::Min => args[1..].iter().fold(x, |m, a| m.min(a.eval(values))),
                    Func::Max => args[1..].iter().fold(x, |m, a| m.max(a.eval(values))),
                }
            }
        }
    }

    /// Whether the expression is the literal `0` (an absent term).
    pub fn is_zero(&self) -> bool {
        matches!(self, Expr::Num(v) if *v == 0.0)
    }

    /// Splits a leading unary minus off: `-l_c` is `(-1, l_c)`, `l_c` is `(1, l_c)`. Terms
    /// whose coefficients have equal magnitudes are summed before one multiplication.
    pub fn split_sign(&self) -> (f64, &Expr) {
        match self {
            Expr::Neg(inner) => {
                let (s, e) = inner.split_sign();
                (-s, e)
            }
            e => (1.0, e),
        }
    }
}

impl fmt::Display for Expr {
    /// Fully parenthesised canonical form (used as a key; parses back to the same tree).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Expr::Num(v) => write!(f, "{v:e}"),
            Expr::Var(n, _) => f.write_str(n),
            Expr::Neg(e) => write!(f, "(-{e})"),
            Expr::Bin(op, a, b) => {
                let s = match op {
                    Op::Add => "+",
                    Op::Sub => "-",
                    Op::Mul => "*",
                    Op::Div => "/",
                    Op::Pow => "^",
                };
                write!(f, "({a} {s} {b})")
            }
            Expr::Call(func, args) => {
                write!(f, "{}(", func.name())?;
                for (i, a) in args.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    write!(f, "{a}")?;
                }
                f.write_str(")")
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eval(text: &str, names: &[(&str, f64)]) -> f64 {
        let mut e = Expr::parse(text).unwrap();
        e.resolve(&|n| names.iter().position(|(k, _)| *k == n))
            .unwrap();
        let values: Vec<f64> = names.iter().map(|p| p.1).collect();
        e.eval(&values)
    }

    #[test]
    fn precedence_associativity_and_unary_minus() {
        assert_eq!(eval("1 + 2 * 3", &[]), 7.0);
        assert_eq!(eval("(1 + 2) * 3", &[]), 9.0);
        assert_eq!(eval("8 / 4 / 2", &[]), 1.0);
        assert_eq!(eval("2 ^ 3 ^ 2", &[]), 512.0);
        assert_eq!(eval("-2 ^ 2", &[]), -4.0);
        assert_eq!(eval("2 ^ -1", &[]), 0.5);
        assert_eq!(eval("10 - 4 - 3", &[]), 3.0);
        assert_eq!(eval("--3", &[]), 3.0);
        assert_eq!(eval("max(1, 5, 3) + min(2, -1)", &[]), 4.0);
        assert_eq!(eval("sqrt(16) + abs(-2)", &[]), 6.0);
        assert_eq!(eval("pi", &[]), std::f64::consts::PI);
    }

    /// Evaluation repeats the arithmetic of the same formula written in Rust, bit for bit.
    #[test]
    fn evaluation_is_the_rust_arithmetic() {
        let (m_c, m_t, m_w, g) = (38880.0f64 * 1.07, 3060.0 * 0.93, 1517.0 * 1.11, 9.81);
        let w = eval(
            "(m_c / 2 + 2 * (m_t / 2) + 4 * (m_w / 2)) * g / 4",
            &[("m_c", m_c), ("m_t", m_t), ("m_w", m_w), ("g", g)],
        );
        let rust = (m_c / 2.0 + 2.0 * (m_t / 2.0) + 4.0 * (m_w / 2.0)) * g / 4.0;
        assert_eq!(w.to_bits(), rust.to_bits());
        let hertz = eval("4.57 * r^-0.149 * 1e-8", &[("r", 0.43)]);
        assert_eq!(
            hertz.to_bits(),
            (4.57 * 0.43f64.powf(-0.149) * 1e-8).to_bits()
        );
    }

    #[test]
    fn errors_name_the_column() {
        let e = Expr::parse("2 * (l_c + ").unwrap_err();
        assert!(e.message.contains("end"), "{e}");
        let e = Expr::parse("2 $ 3").unwrap_err();
        assert_eq!(e.column, 3);
        let e = Expr::parse("foo(1)").unwrap_err();
        assert!(e.message.contains("unknown function `foo`"), "{e}");
        assert!(Expr::parse("sqrt(1, 2)")
            .unwrap_err()
            .message
            .contains("1 argument"));
        assert!(Expr::parse("1e").is_err());
        assert!(Expr::parse("1 2").is_err());
        assert!(Expr::parse("").is_err());
        let deep = "(".repeat(200) + "1" + &")".repeat(200);
        assert!(Expr::parse(&deep).unwrap_err().message.contains("nested"));
        let mut e = Expr::parse("a + b").unwrap();
        assert_eq!(e.resolve(&|n| (n == "a").then_some(0)), Err("b".to_owned()));
    }

    #[test]
    fn sign_split_and_canonical_form() {
        let a = Expr::parse("-l_c").unwrap();
        let b = Expr::parse("l_c").unwrap();
        assert_eq!(a.split_sign().0, -1.0);
        assert_eq!(a.split_sign().1, &b);
        let e = Expr::parse("2*(l_c+l_t) - x^2").unwrap();
        assert_eq!(Expr::parse(&e.to_string()).unwrap(), e);
        assert_eq!(e.names(), ["l_c", "l_t", "x"]);
    }
}
