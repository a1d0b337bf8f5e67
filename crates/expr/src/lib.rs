//! # physid-expr — models from user expressions
//!
//! Engineers state their models as formulas:
//!
//! ```text
//! sin(A)*x + B^2*y*cos(x) + sqrt(C)*x^2 + D*y^2 + E*x/y + F*2*x/y
//! ```
//!
//! with parameters named separately (`A=1,B=2,…`); every other name is an input, i.e. a data
//! column. [`ExprModel::parse`] reads the text once into a compact node array; the model
//! implements [`ParamModel`](physid_core::ParamModel), so it is evaluated generically — as `f64`
//! for values, as dual numbers for exact gradients — like a model written in Rust.
//!
//! Grammar (usual precedence; `^` binds tighter than unary minus and is right-associative, so
//! `-x^2 = -(x^2)` and `2^3^2 = 2^9`):
//!
//! ```text
//! expr  := term (('+' | '-') term)*
//! term  := unary (('*' | '/') unary)*
//! unary := ('-' | '+') unary | power
//! power := atom ('^' unary)?
//! atom  := number | name | name '(' expr (',' expr)* ')' | '(' expr ')'
//! ```
//!
//! Functions: `sqrt exp ln log10 sin cos tan asin acos atan abs` (one argument), `pow min max`
//! (two). Numbers: `12`, `1.5`, `.5`, `2e-3`, `1.5E+4`. Errors give the 1-based column.

mod compiled;
mod eval;
mod parse;
mod tape;

pub use parse::{ExprError, ExprModel, MAX_PARAMS};
