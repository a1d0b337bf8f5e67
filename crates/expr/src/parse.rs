//! Tokenizer, recursive-descent parser, errors with columns, and the canonical printed form.

use std::fmt;

/// What is wrong with an expression; columns are 1-based character positions.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExprError {
    /// The expression is empty.
    #[error("the expression is empty")]
    Empty,
    /// A character that starts no token.
    #[error("unexpected character '{ch}' at column {column}")]
    BadChar {
        /// The character.
        ch: char,
        /// Where.
        column: usize,
    },
    /// A malformed or out-of-range number.
    #[error("bad number '{text}' at column {column}")]
    BadNumber {
        /// The text.
        text: String,
        /// Where.
        column: usize,
    },
    /// A token where something else was expected.
    #[error("expected {expected} at column {column}, found '{found}'")]
    Unexpected {
        /// What was expected.
        expected: &'static str,
        /// What was found.
        found: String,
        /// Where.
        column: usize,
    },
    /// The text ended too early.
    #[error("unexpected end of the expression: expected {expected}")]
    UnexpectedEnd {
        /// What was expected.
        expected: &'static str,
    },
    /// A call of a function that does not exist.
    #[error("unknown function '{name}' at column {column} (the functions are: {FUNCTIONS})")]
    UnknownFunction {
        /// The name.
        name: String,
        /// Where.
        column: usize,
    },
    /// A function called with the wrong number of arguments.
    #[error("function '{name}' at column {column} takes {expected} argument(s), got {got}")]
    Arity {
        /// The function.
        name: String,
        /// Arguments it takes.
        expected: usize,
        /// Arguments given.
        got: usize,
        /// Where.
        column: usize,
    },
    /// A name that is neither a parameter nor one of the data's columns.
    #[error("name '{name}' at column {column} is neither a parameter nor a data column (parameters: {params}; columns: {columns})")]
    UnknownName {
        /// The name.
        name: String,
        /// Where it first appears.
        column: usize,
        /// The parameters, comma separated.
        params: String,
        /// The data columns, comma separated.
        columns: String,
    },
    /// A parameter that the expression does not use (usually a typo).
    #[error("parameter '{0}' does not appear in the expression")]
    UnusedParameter(String),
    /// A parameter named twice.
    #[error("parameter '{0}' is given twice")]
    DuplicateParameter(String),
    /// Nesting deeper than the evaluator supports.
    #[error("the expression is nested more than {MAX_DEPTH} levels deep at column {column}")]
    TooDeep {
        /// Where.
        column: usize,
    },
    /// More parameters than an analysis of them can take in bounded time.
    #[error("{count} parameters: a formula may have at most {MAX_PARAMS} (the ranking's work grows with the cube of their number; 300 took 28 s on 3 000 rows)")]
    TooManyParams {
        /// How many were given.
        count: usize,
    },
    /// A chain of operations longer than the evaluator supports (a sum of thousands of terms).
    #[error("the expression is a chain of more than {MAX_TREE_DEPTH} operations at column {column} (the evaluator recurses through it): write it with fewer terms")]
    TooLong {
        /// Where the limit is passed.
        column: usize,
    },
}

/// Longest chain of operations accepted (`a + b + c + …` is a chain as long as its terms):
/// bounds the evaluator's, the differentiator's and the printer's recursion.
pub const MAX_TREE_DEPTH: usize = 1000;

/// Deepest nesting accepted (bounds the evaluator's recursion).
pub const MAX_DEPTH: usize = 200;

/// Most parameters a formula may have: identifiability's ranking (Alg. 5.1) and the filters
/// work in time growing with the cube of their number (300 parameters on 3 001 rows: 28 s;
/// 10 000: past 2 minutes), so a formula beyond this is refused before any work. The thesis's
/// largest model has 20 (the friction coefficients).
pub const MAX_PARAMS: usize = 200;

const FUNCTIONS: &str =
    "sqrt, exp, ln (also log), log10, sin, cos, tan, asin, acos, atan, abs, pow, min, max";

/// One-argument functions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum Func {
    Sqrt,
    Exp,
    Ln,
    Log10,
    Sin,
    Cos,
    Tan,
    Asin,
    Acos,
    Atan,
    Abs,
}

impl Func {
    /// The function at `x`, in the scalar type's own arithmetic (for `f64`, the calls every
    /// evaluation of a formula makes: the tree walk, the closures, the tape).
    #[inline(always)]
    pub(crate) fn apply<T: physid_core::Scalar>(self, x: T) -> T {
        match self {
            Func::Sqrt => x.sqrt(),
            Func::Exp => x.exp(),
            Func::Ln => x.ln(),
            Func::Log10 => x.log10(),
            Func::Sin => x.sin(),
            Func::Cos => x.cos(),
            Func::Tan => x.tan(),
            Func::Asin => x.asin(),
            Func::Acos => x.acos(),
            Func::Atan => x.atan(),
            Func::Abs => x.abs(),
        }
    }

    /// The function's derivative at `x`, where its value is `fx` (reverse mode's local
    /// partial: `d/dx sqrt = 1/(2·sqrt x)`, `d/dx tan = 1 + tan²x`, `d/dx |x| = sign x`, …).
    pub(crate) fn derivative(self, x: f64, fx: f64) -> f64 {
        match self {
            Func::Sqrt => 0.5 / fx,
            Func::Exp => fx,
            Func::Ln => 1.0 / x,
            Func::Log10 => 1.0 / (x * std::f64::consts::LN_10),
            Func::Sin => x.cos(),
            Func::Cos => -x.sin(),
            Func::Tan => 1.0 + fx * fx,
            Func::Asin => 1.0 / (1.0 - x * x).sqrt(),
            Func::Acos => -1.0 / (1.0 - x * x).sqrt(),
            Func::Atan => 1.0 / (1.0 + x * x),
            Func::Abs => x.signum(),
        }
    }

    fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "sqrt" => Func::Sqrt,
            "exp" => Func::Exp,
            // `log` is the natural logarithm, as in MATLAB and numpy; `log10` is base 10.
            "ln" | "log" => Func::Ln,
            "log10" => Func::Log10,
            "sin" => Func::Sin,
            "cos" => Func::Cos,
            "tan" => Func::Tan,
            "asin" => Func::Asin,
            "acos" => Func::Acos,
            "atan" => Func::Atan,
            "abs" => Func::Abs,
            _ => return None,
        })
    }

    fn name(self) -> &'static str {
        match self {
            Func::Sqrt => "sqrt",
            Func::Exp => "exp",
            Func::Ln => "ln",
            Func::Log10 => "log10",
            Func::Sin => "sin",
            Func::Cos => "cos",
            Func::Tan => "tan",
            Func::Asin => "asin",
            Func::Acos => "acos",
            Func::Atan => "atan",
            Func::Abs => "abs",
        }
    }
}

/// A node of the expression, children by index into the node array.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Node {
    Num(f64),
    Param(usize),
    Input(usize),
    Neg(u32),
    Add(u32, u32),
    Sub(u32, u32),
    Mul(u32, u32),
    Div(u32, u32),
    Pow(u32, u32),
    /// `a^n` with a small integer constant exponent, resolved once after parsing (prints as
    /// `a^n`).
    PowI(u32, i32),
    Call(Func, u32),
    Min(u32, u32),
    Max(u32, u32),
}

impl Node {
    /// The children's indices (none for a leaf, one or two).
    pub(crate) fn children(self) -> [Option<u32>; 2] {
        match self {
            Node::Num(_) | Node::Param(_) | Node::Input(_) => [None, None],
            Node::Neg(a) | Node::Call(_, a) | Node::PowI(a, _) => [Some(a), None],
            Node::Add(a, b)
            | Node::Sub(a, b)
            | Node::Mul(a, b)
            | Node::Div(a, b)
            | Node::Pow(a, b)
            | Node::Min(a, b)
            | Node::Max(a, b) => [Some(a), Some(b)],
        }
    }

    /// The same operation with each child index `c` replaced by `f(c)`.
    pub(crate) fn with_children(self, f: impl Fn(u32) -> u32) -> Self {
        match self {
            Node::Num(_) | Node::Param(_) | Node::Input(_) => self,
            Node::Neg(a) => Node::Neg(f(a)),
            Node::Call(g, a) => Node::Call(g, f(a)),
            Node::PowI(a, n) => Node::PowI(f(a), n),
            Node::Add(a, b) => Node::Add(f(a), f(b)),
            Node::Sub(a, b) => Node::Sub(f(a), f(b)),
            Node::Mul(a, b) => Node::Mul(f(a), f(b)),
            Node::Div(a, b) => Node::Div(f(a), f(b)),
            Node::Pow(a, b) => Node::Pow(f(a), f(b)),
            Node::Min(a, b) => Node::Min(f(a), f(b)),
            Node::Max(a, b) => Node::Max(f(a), f(b)),
        }
    }
}

/// A model parsed from an expression: parameters named by the caller, every other name an
/// input (data column). Serialised as its text and parameter names, parsed again when read.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "ExprSource", into = "ExprSource")]
pub struct ExprModel {
    text: String,
    pub(crate) nodes: Vec<Node>,
    /// Whether each node depends on a parameter (else it is evaluated in plain f64).
    pub(crate) dep: Vec<bool>,
    pub(crate) root: u32,
    params: Vec<String>,
    inputs: Vec<String>,
    input_columns: Vec<usize>,
    /// The formula compiled for `f64` and the gradient dual.
    pub(crate) compiled: crate::compiled::CompiledSet,
    /// Its distinct operations, for many parameter vectors at once (shared between clones).
    pub(crate) tape: std::sync::Arc<crate::tape::Tape>,
}

/// What an [`ExprModel`] is made from: its serialised form.
#[derive(serde::Serialize, serde::Deserialize)]
struct ExprSource {
    text: String,
    params: Vec<String>,
}

impl From<ExprModel> for ExprSource {
    fn from(m: ExprModel) -> Self {
        Self {
            text: m.text,
            params: m.params,
        }
    }
}

impl TryFrom<ExprSource> for ExprModel {
    type Error = ExprError;
    fn try_from(s: ExprSource) -> Result<Self, ExprError> {
        Self::parse(&s.text, &s.params)
    }
}

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Num(f64),
    Name(String),
    Op(char),
}

fn tokenize(text: &str) -> Result<Vec<(Tok, usize)>, ExprError> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let column = i + 1;
        if c.is_whitespace() {
            i += 1;
        } else if c.is_ascii_digit()
            || (c == '.' && chars.get(i + 1).is_some_and(|d| d.is_ascii_digit()))
        {
            let start = i;
            while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
                i += 1;
            }
            if i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
                let mut j = i + 1;
                if j < chars.len() && (chars[j] == '+' || chars[j] == '-') {
                    j += 1;
                }
                if j < chars.len() && chars[j].is_ascii_digit() {
                    i = j;
                    while i < chars.len() && chars[i].is_ascii_digit() {
                        i += 1;
                    }
                } else {
                    let text: String = chars[start..j.min(chars.len())].iter().collect();
                    return Err(ExprError::BadNumber { text, column });
                }
            }
            let text: String = chars[start..i].iter().collect();
            match text.parse::<f64>() {
                Ok(v) if v.is_finite() => out.push((Tok::Num(v), column)),
                _ => return Err(ExprError::BadNumber { text, column }),
            }
        } else if c.is_alphabetic() || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            out.push((Tok::Name(chars[start..i].iter().collect()), column));
        } else if "+-*/^(),".contains(c) {
            out.push((Tok::Op(c), column));
            i += 1;
        } else {
            return Err(ExprError::BadChar { ch: c, column });
        }
    }
    Ok(out)
}

struct Parser<'a> {
    toks: Vec<(Tok, usize)>,
    pos: usize,
    nodes: Vec<Node>,
    params: &'a [String],
    inputs: Vec<String>,
    input_columns: Vec<usize>,
    used: Vec<bool>,
    depth: usize,
    /// Each node's depth in the tree (children precede parents).
    heights: Vec<u32>,
    /// Where the tree first grew past [`MAX_TREE_DEPTH`].
    too_long: Option<usize>,
}

impl Parser<'_> {
    fn peek(&self) -> Option<&Tok> {
        self.toks.get(self.pos).map(|(t, _)| t)
    }

    fn column(&self) -> usize {
        self.toks.get(self.pos).map_or(0, |(_, c)| *c)
    }

    fn push(&mut self, n: Node) -> u32 {
        let height = 1 + n
            .children()
            .iter()
            .flatten()
            .map(|&c| self.heights[c as usize])
            .max()
            .unwrap_or(0);
        if height as usize > MAX_TREE_DEPTH && self.too_long.is_none() {
            self.too_long = Some(self.column());
        }
        self.heights.push(height);
        self.nodes.push(n);
        (self.nodes.len() - 1) as u32
    }

    fn unexpected(&self, expected: &'static str) -> ExprError {
        match self.toks.get(self.pos) {
            None => ExprError::UnexpectedEnd { expected },
            Some((t, column)) => ExprError::Unexpected {
                expected,
                found: match t {
                    Tok::Num(v) => v.to_string(),
                    Tok::Name(n) => n.clone(),
                    Tok::Op(c) => c.to_string(),
                },
                column: *column,
            },
        }
    }

    fn enter(&mut self) -> Result<(), ExprError> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return Err(ExprError::TooDeep {
                column: self.column(),
            });
        }
        Ok(())
    }

    fn expr(&mut self) -> Result<u32, ExprError> {
        self.enter()?;
        let mut left = self.term()?;
        while let Some(Tok::Op(c @ ('+' | '-'))) = self.peek().cloned() {
            self.pos += 1;
            let right = self.term()?;
            left = self.push(if c == '+' {
                Node::Add(left, right)
            } else {
                Node::Sub(left, right)
            });
        }
        self.depth -= 1;
        Ok(left)
    }

    fn term(&mut self) -> Result<u32, ExprError> {
        let mut left = self.unary()?;
        while let Some(Tok::Op(c @ ('*' | '/'))) = self.peek().cloned() {
            self.pos += 1;
            let right = self.unary()?;
            left = self.push(if c == '*' {
                Node::Mul(left, right)
            } else {
                Node::Div(left, right)
            });
        }
        Ok(left)
    }

    fn unary(&mut self) -> Result<u32, ExprError> {
        self.enter()?;
        let r = match self.peek() {
            Some(Tok::Op('-')) => {
                self.pos += 1;
                let inner = self.unary()?;
                Ok(self.push(Node::Neg(inner)))
            }
            Some(Tok::Op('+')) => {
                self.pos += 1;
                self.unary()
            }
            _ => self.power(),
        };
        self.depth -= 1;
        r
    }

    fn power(&mut self) -> Result<u32, ExprError> {
        let base = self.atom()?;
        if let Some(Tok::Op('^')) = self.peek() {
            self.pos += 1;
            let exp = self.unary()?;
            return Ok(self.push(Node::Pow(base, exp)));
        }
        Ok(base)
    }

    fn atom(&mut self) -> Result<u32, ExprError> {
        let column = self.column();
        match self.peek().cloned() {
            Some(Tok::Num(v)) => {
                self.pos += 1;
                Ok(self.push(Node::Num(v)))
            }
            Some(Tok::Op('(')) => {
                self.pos += 1;
                let e = self.expr()?;
                self.expect_close()?;
                Ok(e)
            }
            Some(Tok::Name(name)) => {
                self.pos += 1;
                if let Some(Tok::Op('(')) = self.peek() {
                    self.pos += 1;
                    return self.call(&name, column);
                }
                if let Some(i) = self.params.iter().position(|p| *p == name) {
                    self.used[i] = true;
                    return Ok(self.push(Node::Param(i)));
                }
                let i = match self.inputs.iter().position(|n| *n == name) {
                    Some(i) => i,
                    None => {
                        self.inputs.push(name);
                        self.input_columns.push(column);
                        self.inputs.len() - 1
                    }
                };
                Ok(self.push(Node::Input(i)))
            }
            _ => Err(self.unexpected("a number, a name or '('")),
        }
    }

    fn expect_close(&mut self) -> Result<(), ExprError> {
        match self.peek() {
            Some(Tok::Op(')')) => {
                self.pos += 1;
                Ok(())
            }
            _ => Err(self.unexpected("')'")),
        }
    }

    fn call(&mut self, name: &str, column: usize) -> Result<u32, ExprError> {
        let func = Func::from_name(name);
        let binary = matches!(name, "pow" | "min" | "max");
        if func.is_none() && !binary {
            return Err(ExprError::UnknownFunction {
                name: name.to_string(),
                column,
            });
        }
        let mut args = vec![self.expr()?];
        while let Some(Tok::Op(',')) = self.peek() {
            self.pos += 1;
            args.push(self.expr()?);
        }
        self.expect_close()?;
        let expected = if binary { 2 } else { 1 };
        if args.len() != expected {
            return Err(ExprError::Arity {
                name: name.to_string(),
                expected,
                got: args.len(),
                column,
            });
        }
        Ok(match (func, name) {
            (Some(f), _) => self.push(Node::Call(f, args[0])),
            (None, "pow") => self.push(Node::Pow(args[0], args[1])),
            (None, "min") => self.push(Node::Min(args[0], args[1])),
            _ => self.push(Node::Max(args[0], args[1])),
        })
    }
}

impl ExprModel {
    /// Parse `text` with parameters `params` (in the order [`eval`](physid_core::ParamModel::eval)
    /// takes them); every other name in the text becomes an input, in order of first appearance.
    pub fn parse<S: AsRef<str>>(text: &str, params: &[S]) -> Result<Self, ExprError> {
        if params.len() > MAX_PARAMS {
            return Err(ExprError::TooManyParams {
                count: params.len(),
            });
        }
        let params: Vec<String> = params.iter().map(|s| s.as_ref().to_string()).collect();
        for (i, p) in params.iter().enumerate() {
            if params[..i].contains(p) {
                return Err(ExprError::DuplicateParameter(p.clone()));
            }
        }
        let toks = tokenize(text)?;
        if toks.is_empty() {
            return Err(ExprError::Empty);
        }
        let mut parser = Parser {
            toks,
            pos: 0,
            nodes: Vec::new(),
            params: &params,
            inputs: Vec::new(),
            input_columns: Vec::new(),
            used: vec![false; params.len()],
            depth: 0,
            heights: Vec::new(),
            too_long: None,
        };
        let root = parser.expr();
        if let Some(column) = parser.too_long {
            return Err(ExprError::TooLong { column });
        }
        let root = root?;
        if parser.pos < parser.toks.len() {
            return Err(parser.unexpected("an operator or the end"));
        }
        if let Some(i) = parser.used.iter().position(|u| !u) {
            return Err(ExprError::UnusedParameter(params[i].clone()));
        }
        let Parser {
            nodes,
            inputs,
            input_columns,
            ..
        } = parser;
        // `x^2`, `x^-1`: exact integer powers, decided once here rather than at every evaluation.
        let mut nodes = nodes;
        for k in 0..nodes.len() {
            if let Node::Pow(a, b) = nodes[k] {
                if let Node::Num(n) = nodes[b as usize] {
                    if n.fract() == 0.0 && n.abs() <= 64.0 {
                        nodes[k] = Node::PowI(a, n as i32);
                    }
                }
            }
        }
        // Children precede parents in the array, so one forward pass settles dependence.
        let mut dep = vec![false; nodes.len()];
        for i in 0..nodes.len() {
            dep[i] = matches!(nodes[i], Node::Param(_))
                || nodes[i]
                    .children()
                    .iter()
                    .flatten()
                    .any(|&c| dep[c as usize]);
        }
        let mut model = Self {
            text: text.to_string(),
            nodes,
            dep,
            root,
            params,
            inputs,
            input_columns,
            compiled: Default::default(),
            tape: Default::default(),
        };
        model.compiled = crate::compiled::CompiledSet::new(&model);
        model.tape = std::sync::Arc::new(crate::tape::Tape::new(&model));
        Ok(model)
    }

    /// Check that every input of the expression is one of `columns` (the data's channels).
    pub fn check_inputs<S: AsRef<str>>(&self, columns: &[S]) -> Result<(), ExprError> {
        for (name, &column) in self.inputs.iter().zip(&self.input_columns) {
            if !columns.iter().any(|c| c.as_ref() == name) {
                return Err(ExprError::UnknownName {
                    name: name.clone(),
                    column,
                    params: self.params.join(", "),
                    columns: columns
                        .iter()
                        .map(|c| c.as_ref())
                        .collect::<Vec<_>>()
                        .join(", "),
                });
            }
        }
        Ok(())
    }

    /// The text as given.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// Parameter names.
    pub fn params(&self) -> &[String] {
        &self.params
    }

    /// Input names, in order of first appearance.
    pub fn inputs(&self) -> &[String] {
        &self.inputs
    }

    fn prec(&self, i: u32) -> u8 {
        match self.nodes[i as usize] {
            Node::Add(..) | Node::Sub(..) => 1,
            Node::Mul(..) | Node::Div(..) => 2,
            Node::Neg(_) => 3,
            Node::Pow(..) | Node::PowI(..) => 4,
            _ => 5,
        }
    }

    fn write(&self, f: &mut fmt::Formatter, i: u32, min_prec: u8) -> fmt::Result {
        let paren = self.prec(i) < min_prec;
        if paren {
            f.write_str("(")?;
        }
        let bin = |f: &mut fmt::Formatter, a, b, op: &str, p: u8| -> fmt::Result {
            self.write(f, a, p)?;
            f.write_str(op)?;
            self.write(f, b, p + 1)
        };
        match self.nodes[i as usize] {
            Node::Num(v) => write!(f, "{v}")?,
            Node::Param(k) => f.write_str(&self.params[k])?,
            Node::Input(k) => f.write_str(&self.inputs[k])?,
            Node::Neg(a) => {
                f.write_str("-")?;
                self.write(f, a, 3)?;
            }
            Node::Add(a, b) => bin(f, a, b, " + ", 1)?,
            Node::Sub(a, b) => bin(f, a, b, " - ", 1)?,
            Node::Mul(a, b) => bin(f, a, b, "*", 2)?,
            Node::Div(a, b) => bin(f, a, b, "/", 2)?,
            Node::Pow(a, b) => {
                self.write(f, a, 5)?;
                f.write_str("^")?;
                self.write(f, b, 3)?;
            }
            Node::PowI(a, n) => {
                self.write(f, a, 5)?;
                write!(f, "^{n}")?;
            }
            Node::Call(func, a) => {
                write!(f, "{}(", func.name())?;
                self.write(f, a, 0)?;
                f.write_str(")")?;
            }
            Node::Min(a, b) | Node::Max(a, b) => {
                let name = if matches!(self.nodes[i as usize], Node::Min(..)) {
                    "min"
                } else {
                    "max"
                };
                write!(f, "{name}(")?;
                self.write(f, a, 0)?;
                f.write_str(", ")?;
                self.write(f, b, 0)?;
                f.write_str(")")?;
            }
        }
        if paren {
            f.write_str(")")?;
        }
        Ok(())
    }
}

/// The canonical form: minimal parentheses, numbers in shortest round-trip form. Parsing it
/// gives the same tree.
impl fmt::Display for ExprModel {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        self.write(f, self.root, 0)
    }
}
