//! A model chosen by name (the built-in models) or given as a formula (the expression
//! language), with its nominal parameter values — the one place the command line and pipeline
//! files turn "which model" into a [`ParamModel`].
//!
//! [`ParamModel`] is generic over its scalar, so it is not object-safe: a chosen model is an
//! enum that is itself a [`ParamModel`], delegating to the model inside (one `match` per
//! evaluation — nothing beside the model's own arithmetic).

use crate::cell::CellParams;
use crate::error::AppError;
use crate::example_5_1::{Model51, NOMINAL as NOMINAL_51};
use crate::torque_fit::cyclic_torque_nominal;
use physid_core::{GradientEngine, ParamModel, Scalar};
use physid_expr::ExprModel;
use physid_models::cyclic_torque::CyclicTorque;
use physid_models::friction::FrictionRegression;
use physid_models::shaft::{Shaft, NOMINAL as NOMINAL_SHAFT};

/// The parameters of the built-in model `name`: their names, units and one-line meanings
/// (`None` for a name that is not built in, or whose parameters have no units: Example 5.1).
pub fn glossary(
    name: &str,
) -> Option<(
    &'static [&'static str],
    &'static [&'static str],
    &'static [&'static str],
)> {
    use physid_models::{cyclic_torque, friction, shaft};
    match name {
        "shaft" | "shaft-offset" => Some((&shaft::PARAMS, &shaft::UNITS, &shaft::DESCRIPTIONS)),
        "cyclic-torque" => Some((
            &cyclic_torque::PARAMS,
            &cyclic_torque::UNITS,
            &cyclic_torque::DESCRIPTIONS,
        )),
        "friction-regression" => Some((
            &friction::REGRESSION_PARAMS,
            &friction::REGRESSION_UNITS,
            &friction::REGRESSION_DESCRIPTIONS,
        )),
        _ => None,
    }
}

/// The built-in models: name, parameters with their nominal values, inputs.
pub const BUILTIN: [(&str, &str, &str); 5] = [
    (
        "example-5.1",
        "A … F = 1 … 6 (thesis Example 5.1)",
        "x, y",
    ),
    (
        "shaft",
        "K = 1250 N·m/rad, B = 0.95 N·m·s/rad (Eq. 6.1, Table 6.1)",
        "theta_dy, theta_en, omega_dy, omega_en",
    ),
    (
        "shaft-offset",
        "K, B as shaft, tau0 = 0 N·m (encoder zero offset)",
        "as shaft",
    ),
    (
        "cyclic-torque",
        "M_rec, b, L, r, delta, c1 … c10: the test cell's engine, friction cubic fitted to the mean-value model (Eq. 8.2)",
        "theta, omega, alpha, p_cyl, p_crank [Pa], T_oil [°C]",
    ),
    (
        "friction-regression",
        "c1 … c20 of the mean-value friction model on the test cell's engine (Eq. 7.4–7.9)",
        "n_rpm, p_int_kpa, p_atm_kpa, t_oil_c",
    ),
];

/// A chosen model.
#[derive(Debug, Clone)]
pub enum ModelChoice {
    /// From a formula.
    Expr(ExprModel),
    /// Thesis Example 5.1.
    Ex51(Model51),
    /// The coupling shaft (with or without the offset term).
    Shaft(Shaft),
    /// The cyclic engine torque.
    Cyclic(CyclicTorque),
    /// The friction regression form.
    Friction(FrictionRegression),
}

/// `$body` with `$m` bound to the concrete model inside `$self`.
macro_rules! delegate {
    ($self:expr, $m:ident => $body:expr) => {
        match $self {
            ModelChoice::Expr($m) => $body,
            ModelChoice::Ex51($m) => $body,
            ModelChoice::Shaft($m) => $body,
            ModelChoice::Cyclic($m) => $body,
            ModelChoice::Friction($m) => $body,
        }
    };
}

impl ParamModel for ModelChoice {
    fn param_names(&self) -> &[String] {
        delegate!(self, m => m.param_names())
    }
    fn input_names(&self) -> &[String] {
        delegate!(self, m => m.input_names())
    }
    fn eval<T: Scalar>(&self, inputs: &[f64], params: &[T]) -> T {
        delegate!(self, m => m.eval(inputs, params))
    }
    fn eval_many(&self, inputs: &[f64], params: &[f64], out: &mut [f64]) {
        delegate!(self, m => m.eval_many(inputs, params, out))
    }
    fn value_and_gradient_with(
        &self,
        engine: &mut GradientEngine,
        inputs: &[f64],
        params: &[f64],
        free: &[usize],
        grad: &mut [f64],
    ) -> f64 {
        delegate!(self, m => m.value_and_gradient_with(engine, inputs, params, free, grad))
    }
}

impl ModelChoice {
    /// A model from a formula (`expr`, with every parameter given a nominal value in
    /// `params`) or by built-in name, its nominal values overridden by `params`. Errors say
    /// what was expected.
    pub fn build(
        expr: Option<&str>,
        builtin: Option<&str>,
        params: &[(String, f64)],
    ) -> Result<(Self, Vec<f64>), AppError> {
        if let Some(text) = expr {
            if params.is_empty() {
                return Err(AppError::Invalid(
                    "a formula needs its parameters and their nominal values (A=1, B=2, …)".into(),
                ));
            }
            let names: Vec<&str> = params.iter().map(|p| p.0.as_str()).collect();
            let m = ExprModel::parse(text, &names).map_err(|e| e.to_string())?;
            return Ok((Self::Expr(m), params.iter().map(|p| p.1).collect()));
        }
        let list = || BUILTIN.iter().map(|b| b.0).collect::<Vec<_>>().join(", ");
        let name = builtin.ok_or_else(|| {
            format!(
                "a model is needed: a formula, or a built-in one ({})",
                list()
            )
        })?;
        let cell = CellParams::default();
        let (model, mut nominal) = match name {
            "example-5.1" => (Self::Ex51(Model51::default()), NOMINAL_51.to_vec()),
            "shaft" => (Self::Shaft(Shaft::new(false)), NOMINAL_SHAFT.to_vec()),
            "shaft-offset" => (
                Self::Shaft(Shaft::new(true)),
                vec![NOMINAL_SHAFT[0], NOMINAL_SHAFT[1], 0.0],
            ),
            "cyclic-torque" => (
                Self::Cyclic(CyclicTorque::default()),
                cyclic_torque_nominal(&cell)?.to_vec(),
            ),
            "friction-regression" => {
                let (d, st) = crate::cell::cell_friction_model();
                let m = FrictionRegression::new(d, st);
                let c0 = m.nominal().to_vec();
                (Self::Friction(m), c0)
            }
            other => {
                return Err(AppError::Invalid(format!(
                    "no built-in model '{other}'; they are {}",
                    list()
                )))
            }
        };
        let pnames = model.param_names();
        for (n, v) in params {
            let j = pnames.iter().position(|p| p == n).ok_or_else(|| {
                format!(
                    "parameter '{n}': model '{name}' has the parameters {}",
                    pnames.join(", ")
                )
            })?;
            nominal[j] = *v;
        }
        Ok((model, nominal))
    }
}
