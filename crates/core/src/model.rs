//! The model seam: models written once, generic over the scalar (DESIGN.md, "The seams").
//!
//! A model is a function of inputs `φ` (plain `f64`, the data) and parameters `ϑ` (a generic
//! [`Scalar`]). Evaluated with `f64` it gives the output; evaluated with forward-mode dual
//! numbers it gives the output *and its exact derivatives* with respect to any chosen
//! parameters — the thesis used the MATLAB symbolic toolbox for these (§5.2, §8), we use
//! automatic differentiation (`num-dual`). Nothing is derived by hand or by finite differences;
//! a model may only tell the engine which parameters it is affine in, whose partials are then
//! its regressors (the cyclic-torque model's friction coefficients, see
//! [`ParamModel::value_and_gradient_with`]).

use nalgebra::{Const, U1};
use num_dual::{Derivative, DualNum, DualSVec64};

/// A number a model can be evaluated with: `f64`, or a `num-dual` dual number. Arithmetic with
/// `Self` and with `f64`, `From<f64>`, and the elementary functions (`sin`, `exp`, `ln`, `sqrt`,
/// `powf`, `powd`, `abs`, …) come from [`DualNum`].
pub trait Scalar: DualNum<Primitive = f64> + Copy {
    /// The plain value (the real part of a dual number).
    fn value(&self) -> f64 {
        self.re()
    }
}

impl<T: DualNum<Primitive = f64> + Copy> Scalar for T {}

/// A parameterised model `y = h(φ, ϑ)`.
pub trait ParamModel {
    /// Parameter names, in the order [`eval`](Self::eval) takes them.
    fn param_names(&self) -> &[String];
    /// Input (data channel) names, in the order [`eval`](Self::eval) takes them.
    fn input_names(&self) -> &[String];
    /// The output for inputs `inputs` and parameters `params` (same orders as the names).
    fn eval<T: Scalar>(&self, inputs: &[f64], params: &[T]) -> T;

    /// `h(φ, ϑ_k)` of several parameter vectors at the same inputs — an unscented filter's
    /// sigma points: `params` holds them one after another (`out.len()` vectors of equal
    /// length), `out` receives their outputs in that order. The default evaluates each; a model
    /// overrides it to compute what depends on the inputs alone once (a crank angle's sine and
    /// cosine, a friction polynomial's regressors) — equal to [`eval`](Self::eval) of each,
    /// bit for bit.
    fn eval_many(&self, inputs: &[f64], params: &[f64], out: &mut [f64]) {
        let len = params.len().checked_div(out.len()).unwrap_or(0);
        for (k, o) in out.iter_mut().enumerate() {
            *o = self.eval::<f64>(inputs, &params[k * len..(k + 1) * len]);
        }
    }

    /// `h(φ, ϑ)` and `∂h/∂ϑ_j` for each `j` in `free`, written into `grad` — what
    /// [`GradientEngine::value_and_gradient`] returns. The default is forward mode through
    /// [`eval`](Self::eval) ([`GradientEngine::forward`]). A model may override it to use its
    /// structure (parameters it is affine in, say) as long as the result stays exact to
    /// round-off; callers go through the engine, which checks the buffer sizes first.
    fn value_and_gradient_with(
        &self,
        engine: &mut GradientEngine,
        inputs: &[f64],
        params: &[f64],
        free: &[usize],
        grad: &mut [f64],
    ) -> f64 {
        if free.is_empty() {
            return self.eval::<f64>(inputs, params);
        }
        engine.forward(params, free, grad, |duals| self.eval(inputs, duals))
    }
}

/// The object-safe face of a [`ParamModel`] (whose `eval` is generic over the scalar, so it
/// cannot be a trait object): the value and the exact gradient, for code that holds models of
/// different types behind one pointer. Every [`ParamModel`] is one (blanket impl).
pub trait DynModel {
    /// Parameter names, in order.
    fn param_names(&self) -> &[String];
    /// Input names, in order.
    fn input_names(&self) -> &[String];
    /// `h(φ, ϑ)`.
    fn value(&self, inputs: &[f64], params: &[f64]) -> f64;
    /// `h(φ, ϑ)` and `∂h/∂ϑ_j` for `j` in `free` ([`GradientEngine::value_and_gradient`]).
    fn value_and_gradient(
        &self,
        engine: &mut GradientEngine,
        inputs: &[f64],
        params: &[f64],
        free: &[usize],
        grad: &mut [f64],
    ) -> f64;
}

impl<M: ParamModel> DynModel for M {
    fn param_names(&self) -> &[String] {
        ParamModel::param_names(self)
    }
    fn input_names(&self) -> &[String] {
        ParamModel::input_names(self)
    }
    fn value(&self, inputs: &[f64], params: &[f64]) -> f64 {
        self.eval::<f64>(inputs, params)
    }
    fn value_and_gradient(
        &self,
        engine: &mut GradientEngine,
        inputs: &[f64],
        params: &[f64],
        free: &[usize],
        grad: &mut [f64],
    ) -> f64 {
        engine.value_and_gradient(self, inputs, params, free, grad)
    }
}

/// Width of the dual numbers: the gradient is computed in chunks of this many free parameters
/// per model evaluation (one evaluation for up to 8 free parameters, two for 9–16, …).
pub const GRADIENT_CHUNK: usize = 8;

/// The dual number the [`GradientEngine`] evaluates models with (value and 8 partials).
pub type Grad = DualSVec64<GRADIENT_CHUNK>;

/// Exact gradients of a model with respect to a subset of its parameters, allocation-free
/// after construction (the dual-number parameter vector is preallocated). Serialised as its
/// size: it holds no state between evaluations.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
#[serde(from = "usize", into = "usize")]
pub struct GradientEngine {
    duals: Vec<Grad>,
}

impl From<usize> for GradientEngine {
    fn from(n_params: usize) -> Self {
        Self::new(n_params)
    }
}

impl From<GradientEngine> for usize {
    fn from(engine: GradientEngine) -> usize {
        engine.n_params()
    }
}

impl GradientEngine {
    /// An engine for models with `n_params` parameters.
    pub fn new(n_params: usize) -> Self {
        Self {
            duals: vec![Grad::from_re(0.0); n_params],
        }
    }

    /// Number of parameters this engine was built for.
    pub fn n_params(&self) -> usize {
        self.duals.len()
    }

    /// `h(φ, ϑ)` and `∂h/∂ϑ_j` for each `j` in `free` (indices into `params`), written into
    /// `grad` (same length as `free`). Exact to round-off. The model computes it
    /// ([`ParamModel::value_and_gradient_with`]; forward mode unless it knows better).
    ///
    /// # Panics
    /// If `params.len()` differs from [`n_params`](Self::n_params) or `grad.len()` from
    /// `free.len()` — sizes are the caller's invariants, checked where the estimator is built.
    pub fn value_and_gradient<M: ParamModel>(
        &mut self,
        model: &M,
        inputs: &[f64],
        params: &[f64],
        free: &[usize],
        grad: &mut [f64],
    ) -> f64 {
        assert_eq!(params.len(), self.duals.len(), "parameter vector length");
        assert_eq!(grad.len(), free.len(), "gradient buffer length");
        model.value_and_gradient_with(self, inputs, params, free, grad)
    }

    /// Forward mode: `f` evaluated on the parameters as dual numbers, the parameters in `free`
    /// seeded [`GRADIENT_CHUNK`] at a time (one call of `f` per chunk). Returns `f`'s value and
    /// writes `∂f/∂ϑ_j` for each `j` in `free` into `grad`. `f` is called once, unseeded, when
    /// `free` is empty.
    ///
    /// # Panics
    /// As [`value_and_gradient`](Self::value_and_gradient).
    pub fn forward(
        &mut self,
        params: &[f64],
        free: &[usize],
        grad: &mut [f64],
        mut f: impl FnMut(&[Grad]) -> Grad,
    ) -> f64 {
        assert_eq!(params.len(), self.duals.len(), "parameter vector length");
        assert_eq!(grad.len(), free.len(), "gradient buffer length");
        for (d, &p) in self.duals.iter_mut().zip(params) {
            *d = Grad::from_re(p);
        }
        if free.is_empty() {
            return f(&self.duals).re;
        }
        let mut value = 0.0;
        for (chunk, out) in free
            .chunks(GRADIENT_CHUNK)
            .zip(grad.chunks_mut(GRADIENT_CHUNK))
        {
            for (k, &j) in chunk.iter().enumerate() {
                self.duals[j].eps = Derivative::derivative_generic(Const::<GRADIENT_CHUNK>, U1, k);
            }
            let r = f(&self.duals);
            // Back to constants for the next chunk.
            for &j in chunk {
                self.duals[j].eps = Derivative::none();
            }
            value = r.re;
            match r.eps.0 {
                Some(e) => {
                    for (k, g) in out.iter_mut().enumerate() {
                        *g = e[k];
                    }
                }
                None => out.fill(0.0),
            }
        }
        value
    }
}
