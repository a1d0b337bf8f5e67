//! The model seam: models written once, generic over the scalar (DESIGN.md, "The seams").
//!
//! A model is a function of inputs `φ` (plain `f64`, the data) and parameters `ϑ` (a generic
//! [`Scalar`]). Evaluated with `f64` it gives the output; evaluated with forward-mode dual
//! numbers it gives the output *and its exact derivatives* with respect to any chosen
//! parameters — the thesis used the MATLAB symbolic toolbox for these (§5.2, §8), we use
//! automatic differentiation (`num-dual`). Nothing is derived by hand or by finite differences.

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
}

/// Width of the dual numbers: the gradient is computed in chunks of this many free parameters
/// per model evaluation (one evaluation for up to 8 free parameters, two for 9–16, …).
pub const GRADIENT_CHUNK: usize = 8;

/// The dual number the [`GradientEngine`] evaluates models with (value and 8 partials).
pub type Grad = DualSVec64<GRADIENT_CHUNK>;

/// Exact gradients of a model with respect to a subset of its parameters, allocation-free
/// after construction (the dual-number parameter vector is preallocated).
#[derive(Debug, Clone)]
pub struct GradientEngine {
    duals: Vec<Grad>,
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
    /// `grad` (same length as `free`). Exact to round-off.
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
        if free.is_empty() {
            return model.eval::<f64>(inputs, params);
        }
        let mut value = 0.0;
        for (d, &p) in self.duals.iter_mut().zip(params) {
            *d = Grad::from_re(p);
        }
        for (chunk, out) in free
            .chunks(GRADIENT_CHUNK)
            .zip(grad.chunks_mut(GRADIENT_CHUNK))
        {
            for (k, &j) in chunk.iter().enumerate() {
                self.duals[j].eps = Derivative::derivative_generic(Const::<GRADIENT_CHUNK>, U1, k);
            }
            let r = model.eval(inputs, &self.duals);
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
