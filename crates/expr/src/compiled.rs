//! Formulas compiled into closures — threaded code — for the two scalar types the product
//! evaluates models with: `f64` (values) and [`Grad`] (exact gradients). Each node becomes a
//! closure that calls its children directly, so there is no single dispatch point whose
//! target changes at every node (the tree walk's cost, measured: see BENCHMARKS.md).
//!
//! For the dual, parameter-free subtrees become `f64` closures whose result is promoted once.
//! Leaf operands (parameters, inputs, numbers) are read inside their parent's closure — both
//! operands of a binary operation when both are leaves, the operand of a function, power or
//! negation when it is a parameter or an input — so a leaf costs no call of its own.

use crate::parse::{ExprModel, Func, Node};
use physid_core::{Grad, Scalar};
use std::any::Any;
use std::sync::Arc;

/// A compiled formula for scalar type `T`.
pub(crate) type Compiled<T> = Box<dyn Fn(&[f64], &[T]) -> T + Send + Sync>;

/// The compiled forms of one formula, shared between clones of the model.
#[derive(Clone)]
pub(crate) struct CompiledSet(Arc<Vec<Box<dyn Any + Send + Sync>>>);

impl std::fmt::Debug for CompiledSet {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("CompiledSet(f64, Grad)")
    }
}

impl Default for CompiledSet {
    fn default() -> Self {
        Self(Arc::new(Vec::new()))
    }
}

impl CompiledSet {
    pub(crate) fn new(m: &ExprModel) -> Self {
        // Values need no lifting: every node is f64 already.
        let f: Compiled<f64> = compile::<f64>(m, m.root, false);
        let g: Compiled<Grad> = compile::<Grad>(m, m.root, true);
        Self(Arc::new(vec![Box::new(f), Box::new(g)]))
    }

    /// The compiled form for `T`, if `T` is one of the compiled types.
    #[inline]
    pub(crate) fn get<T: Scalar>(&self) -> Option<&Compiled<T>> {
        self.0.iter().find_map(|c| c.downcast_ref::<Compiled<T>>())
    }
}

/// A leaf operand read inside its parent's closure.
#[derive(Clone, Copy)]
enum Leaf {
    Param(usize),
    Input(usize),
    Const(f64),
}

fn leaf_of(m: &ExprModel, i: u32) -> Option<Leaf> {
    match m.nodes[i as usize] {
        Node::Param(k) => Some(Leaf::Param(k)),
        Node::Input(k) => Some(Leaf::Input(k)),
        Node::Num(v) => Some(Leaf::Const(v)),
        _ => None,
    }
}

/// `a op b` with the cheapest closure for the operand kinds: both compiled, or one a leaf.
/// (Combining a dual with a plain `f64` operand through num-dual's mixed operations measured
/// slower than promoting the operand: 2.9 M against 4.9 M gradients/s on Example 5.1.)
macro_rules! binary {
    ($m:expr, $a:expr, $b:expr, $lift:expr, |$x:ident, $y:ident| $body:expr) => {{
        match (leaf_of($m, $a), leaf_of($m, $b)) {
            // Both leaves (other than two numbers), read inline.
            (Some(Leaf::Param(i)), Some(Leaf::Param(k))) => Box::new(move |_, p| {
                let ($x, $y) = (p[i], p[k]);
                $body
            }),
            (Some(Leaf::Param(i)), Some(Leaf::Input(k))) => Box::new(move |u, p| {
                let ($x, $y) = (p[i], T::from(u[k]));
                $body
            }),
            (Some(Leaf::Param(i)), Some(Leaf::Const(v))) => Box::new(move |_, p| {
                let ($x, $y) = (p[i], T::from(v));
                $body
            }),
            (Some(Leaf::Input(i)), Some(Leaf::Param(k))) => Box::new(move |u, p| {
                let ($x, $y) = (T::from(u[i]), p[k]);
                $body
            }),
            (Some(Leaf::Const(v)), Some(Leaf::Param(k))) => Box::new(move |_, p| {
                let ($x, $y) = (T::from(v), p[k]);
                $body
            }),
            (Some(Leaf::Input(i)), Some(Leaf::Input(k))) => Box::new(move |u, _| {
                let ($x, $y) = (T::from(u[i]), T::from(u[k]));
                $body
            }),
            (Some(Leaf::Input(i)), Some(Leaf::Const(v))) => Box::new(move |u, _| {
                let ($x, $y) = (T::from(u[i]), T::from(v));
                $body
            }),
            (Some(Leaf::Const(v)), Some(Leaf::Input(k))) => Box::new(move |u, _| {
                let ($x, $y) = (T::from(v), T::from(u[k]));
                $body
            }),
            (_, Some(Leaf::Param(k))) => {
                let fa = compile::<T>($m, $a, $lift);
                Box::new(move |u, p| {
                    let ($x, $y) = (fa(u, p), p[k]);
                    $body
                })
            }
            (_, Some(Leaf::Input(k))) => {
                let fa = compile::<T>($m, $a, $lift);
                Box::new(move |u, p| {
                    let ($x, $y) = (fa(u, p), T::from(u[k]));
                    $body
                })
            }
            (_, Some(Leaf::Const(v))) => {
                let fa = compile::<T>($m, $a, $lift);
                Box::new(move |u, p| {
                    let ($x, $y) = (fa(u, p), T::from(v));
                    $body
                })
            }
            (Some(Leaf::Param(k)), None) => {
                let fb = compile::<T>($m, $b, $lift);
                Box::new(move |u, p| {
                    let ($x, $y) = (p[k], fb(u, p));
                    $body
                })
            }
            (Some(Leaf::Input(k)), None) => {
                let fb = compile::<T>($m, $b, $lift);
                Box::new(move |u, p| {
                    let ($x, $y) = (T::from(u[k]), fb(u, p));
                    $body
                })
            }
            _ => {
                let fa = compile::<T>($m, $a, $lift);
                let fb = compile::<T>($m, $b, $lift);
                Box::new(move |u, p| {
                    let ($x, $y) = (fa(u, p), fb(u, p));
                    $body
                })
            }
        }
    }};
}

/// `f(a)` with the cheapest closure: a parameter or input operand read inline, else its
/// compiled form.
macro_rules! unary {
    ($m:expr, $a:expr, $lift:expr, |$x:ident| $body:expr) => {{
        match leaf_of($m, $a) {
            Some(Leaf::Param(k)) => Box::new(move |_, p| {
                let $x = p[k];
                $body
            }),
            Some(Leaf::Input(k)) => Box::new(move |u, _| {
                let $x = T::from(u[k]);
                $body
            }),
            _ => {
                let fa = compile::<T>($m, $a, $lift);
                Box::new(move |u, p| {
                    let $x = fa(u, p);
                    $body
                })
            }
        }
    }};
}

/// Compile node `i`; with `lift`, a parameter-free subtree is compiled for `f64` and promoted.
fn compile<T: Scalar + Send + Sync>(m: &ExprModel, i: u32, lift: bool) -> Compiled<T> {
    if lift && !m.dep[i as usize] {
        let g = compile::<f64>(m, i, false);
        return Box::new(move |u, _| T::from(g(u, &[])));
    }
    match m.nodes[i as usize] {
        Node::Num(v) => Box::new(move |_, _| T::from(v)),
        Node::Param(k) => Box::new(move |_, p| p[k]),
        Node::Input(k) => Box::new(move |u, _| T::from(u[k])),
        Node::Neg(a) => unary!(m, a, lift, |x| -x),
        Node::Add(a, b) => binary!(m, a, b, lift, |x, y| x + y),
        Node::Sub(a, b) => binary!(m, a, b, lift, |x, y| x - y),
        Node::Mul(a, b) => binary!(m, a, b, lift, |x, y| x * y),
        Node::Div(a, b) => binary!(m, a, b, lift, |x, y| x / y),
        Node::Min(a, b) => binary!(m, a, b, lift, |x, y| if y.value() < x.value() {
            y
        } else {
            x
        }),
        Node::Max(a, b) => binary!(m, a, b, lift, |x, y| if y.value() > x.value() {
            y
        } else {
            x
        }),
        Node::PowI(a, n) => match n {
            2 => unary!(m, a, lift, |x| x * x),
            3 => unary!(m, a, lift, |x| x * x * x),
            _ => unary!(m, a, lift, |x| x.powi(n)),
        },
        Node::Pow(a, b) => {
            let fa = compile::<T>(m, a, lift);
            if m.dep[b as usize] {
                let fb = compile::<T>(m, b, lift);
                Box::new(move |u, p| fa(u, p).powd(fb(u, p)))
            } else {
                let e = compile::<f64>(m, b, false);
                Box::new(move |u, p| fa(u, p).powf(e(u, &[])))
            }
        }
        Node::Call(f, a) => match f {
            Func::Sqrt => unary!(m, a, lift, |x| x.sqrt()),
            Func::Exp => unary!(m, a, lift, |x| x.exp()),
            Func::Ln => unary!(m, a, lift, |x| x.ln()),
            Func::Log10 => unary!(m, a, lift, |x| x.log10()),
            Func::Sin => unary!(m, a, lift, |x| x.sin()),
            Func::Cos => unary!(m, a, lift, |x| x.cos()),
            Func::Tan => unary!(m, a, lift, |x| x.tan()),
            Func::Asin => unary!(m, a, lift, |x| x.asin()),
            Func::Acos => unary!(m, a, lift, |x| x.acos()),
            Func::Atan => unary!(m, a, lift, |x| x.atan()),
            Func::Abs => unary!(m, a, lift, |x| x.abs()),
        },
    }
}
