//! Evaluation through the model seam. `f64` (values) and the gradient dual use the formula
//! compiled into closures (`compiled.rs`); any other scalar type — a caller's own dual number,
//! say — walks the tree here, with the same results (tested).

use crate::parse::{ExprModel, Node};
use physid_core::{GradientEngine, ParamModel, Scalar};

impl ExprModel {
    /// Evaluate node `i`. With `LIFT`, a subtree that does not depend on any parameter is
    /// evaluated once in plain `f64` and promoted — what a hand-written model does with its
    /// data-only terms — instead of carrying zero derivatives through every operation.
    /// A child: leaves are read directly, without a recursive call.
    #[inline(always)]
    fn arg<T: Scalar, const LIFT: bool>(&self, i: u32, u: &[f64], p: &[T]) -> T {
        match self.nodes[i as usize] {
            Node::Param(k) => p[k],
            Node::Input(k) => T::from(u[k]),
            Node::Num(v) => T::from(v),
            _ => self.ev::<T, LIFT>(i, u, p),
        }
    }

    fn ev<T: Scalar, const LIFT: bool>(&self, i: u32, u: &[f64], p: &[T]) -> T {
        let iu = i as usize;
        if LIFT && !self.dep[iu] {
            return T::from(self.ev::<f64, false>(i, u, &[]));
        }
        match self.nodes[iu] {
            Node::Num(v) => T::from(v),
            Node::Param(k) => p[k],
            Node::Input(k) => T::from(u[k]),
            Node::Neg(a) => -self.arg::<T, LIFT>(a, u, p),
            Node::Add(a, b) => self.arg::<T, LIFT>(a, u, p) + self.arg::<T, LIFT>(b, u, p),
            Node::Sub(a, b) => self.arg::<T, LIFT>(a, u, p) - self.arg::<T, LIFT>(b, u, p),
            Node::Mul(a, b) => self.arg::<T, LIFT>(a, u, p) * self.arg::<T, LIFT>(b, u, p),
            Node::Div(a, b) => self.arg::<T, LIFT>(a, u, p) / self.arg::<T, LIFT>(b, u, p),
            Node::Pow(a, b) => {
                let base = self.arg::<T, LIFT>(a, u, p);
                if self.dep[b as usize] {
                    base.powd(self.arg::<T, LIFT>(b, u, p))
                } else {
                    base.powf(self.arg::<f64, false>(b, u, &[]))
                }
            }
            Node::PowI(a, n) => {
                let base = self.arg::<T, LIFT>(a, u, p);
                match n {
                    2 => base * base,
                    3 => base * base * base,
                    _ => base.powi(n),
                }
            }
            Node::Call(f, a) => f.apply(self.arg::<T, LIFT>(a, u, p)),
            Node::Min(a, b) => {
                let (x, y) = (self.arg::<T, LIFT>(a, u, p), self.arg::<T, LIFT>(b, u, p));
                if y.value() < x.value() {
                    y
                } else {
                    x
                }
            }
            Node::Max(a, b) => {
                let (x, y) = (self.arg::<T, LIFT>(a, u, p), self.arg::<T, LIFT>(b, u, p));
                if y.value() > x.value() {
                    y
                } else {
                    x
                }
            }
        }
    }
}

impl ParamModel for ExprModel {
    fn param_names(&self) -> &[String] {
        self.params()
    }

    fn input_names(&self) -> &[String] {
        self.inputs()
    }

    fn eval<T: Scalar>(&self, inputs: &[f64], params: &[T]) -> T {
        // The compiled closures for f64 and the gradient dual; the tree walk for any other type.
        match self.compiled.get::<T>() {
            Some(f) => f(inputs, params),
            None => self.ev::<T, true>(self.root, inputs, params),
        }
    }

    /// The sigma points through the formula's tape (`tape.rs`): each distinct operation once
    /// over all the points, the parameter-free ones once.
    fn eval_many(&self, inputs: &[f64], params: &[f64], out: &mut [f64]) {
        self.tape.eval_many(inputs, params, out);
    }

    /// The exact gradient through the formula's tape by reverse mode (`tape.rs`): each
    /// distinct operation once forwards and once backwards, whatever the number of parameters.
    fn value_and_gradient_with(
        &self,
        _engine: &mut GradientEngine,
        inputs: &[f64],
        params: &[f64],
        free: &[usize],
        grad: &mut [f64],
    ) -> f64 {
        self.tape.value_and_gradient(inputs, params, free, grad)
    }
}
