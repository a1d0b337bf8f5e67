//! Ranking of the friction model's design parameters (thesis §7.2, app. B.2; Table 7.1 and
//! Fig. 7.1, regenerated).
//!
//! At each operating point of a grid, the normalised sensitivity of the friction torque to each
//! design parameter, `z_j = (ϑ_j/τ_fri)·∂τ_fri/∂ϑ_j` (exact, through the model seam), and the
//! parameters ranked by `z_j²` (the thesis code's `sumsqr` of a one-row sensitivity), most
//! sensitive first; ties go to the lower index. The default grid is the thesis's 3³ full
//! factorial, with engine speed varying fastest (MATLAB `fullfact` order): test 1 is
//! (1000 rpm, 10 kPa, 20 °C), test 2 is (3000 rpm, 10 kPa, 20 °C).

use physid_core::{GradientEngine, ParamModel};
use physid_models::friction::{Design, FrictionTorque, OperatingPoint, Settings, DESIGN_PARAMS};
use serde::Serialize;
use std::collections::BTreeMap;
use thiserror::Error;

/// What can go wrong in the ranking.
#[derive(Debug, Error, PartialEq)]
pub enum RankError {
    /// An operating point outside the model's domain, or an empty grid.
    #[error("{0}")]
    BadGrid(String),
    /// A parameter name is not a design parameter.
    #[error("'{0}' is not a design parameter; they are {list}", list = DESIGN_PARAMS.join(", "))]
    UnknownParameter(String),
    /// The friction torque is zero or not finite: normalised sensitivities are undefined.
    #[error("friction torque {tau} N·m at {n_rpm} rpm, {p_int_kpa} kPa, {t_oil_c} °C: normalised sensitivities are undefined")]
    Degenerate {
        /// Torque.
        tau: f64,
        /// Speed.
        n_rpm: f64,
        /// Manifold pressure.
        p_int_kpa: f64,
        /// Oil temperature.
        t_oil_c: f64,
    },
}

/// The operating grid: every combination of the three lists (speed varying fastest).
#[derive(Debug, Clone)]
pub struct RankGrid {
    /// Engine speeds [rpm].
    pub n_rpm: Vec<f64>,
    /// Intake manifold pressures [kPa].
    pub p_int_kpa: Vec<f64>,
    /// Oil temperatures [°C].
    pub t_oil_c: Vec<f64>,
    /// Ambient pressure [kPa] (the thesis code's 101 kPa by default).
    pub p_atm_kpa: f64,
}

impl Default for RankGrid {
    /// The thesis's 3³ design: N ∈ {1000, 3000, 5000} rpm, p_int ∈ {10, 55, 100} kPa,
    /// T_oil ∈ {20, 55, 90} °C, p_atm = 101 kPa.
    fn default() -> Self {
        Self {
            n_rpm: vec![1000.0, 3000.0, 5000.0],
            p_int_kpa: vec![10.0, 55.0, 100.0],
            t_oil_c: vec![20.0, 55.0, 90.0],
            p_atm_kpa: 101.0,
        }
    }
}

impl RankGrid {
    /// The operating points, speed fastest, then manifold pressure, then oil temperature.
    pub fn points(&self) -> Vec<OperatingPoint> {
        let mut v =
            Vec::with_capacity(self.n_rpm.len() * self.p_int_kpa.len() * self.t_oil_c.len());
        for &t_oil_c in &self.t_oil_c {
            for &p_int_kpa in &self.p_int_kpa {
                for &n_rpm in &self.n_rpm {
                    v.push(OperatingPoint {
                        n_rpm,
                        p_int_kpa,
                        p_atm_kpa: self.p_atm_kpa,
                        t_oil_c,
                    });
                }
            }
        }
        v
    }

    fn check(&self) -> Result<(), RankError> {
        if self.n_rpm.is_empty() || self.p_int_kpa.is_empty() || self.t_oil_c.is_empty() {
            return Err(RankError::BadGrid(
                "the grid needs at least one speed, one manifold pressure and one oil temperature"
                    .into(),
            ));
        }
        self.points()
            .iter()
            .try_for_each(OperatingPoint::validate)
            .map_err(|e| RankError::BadGrid(e.to_string()))
    }
}

/// One test (operating point) of the ranking.
#[derive(Debug, Clone)]
pub struct RankTest {
    /// The operating point.
    pub op: OperatingPoint,
    /// Friction torque there [N·m].
    pub tau_nm: f64,
    /// Normalised sensitivity `z_j` of each ranked parameter (in [`RankTable::parameters`]
    /// order).
    pub sensitivity: Vec<f64>,
    /// Parameter indices (into [`RankTable::parameters`]), most sensitive first.
    pub order: Vec<usize>,
    /// Rank of each parameter (1 = most sensitive), in [`RankTable::parameters`] order.
    pub rank: Vec<usize>,
}

/// The ranking table (thesis Table 7.1).
#[derive(Debug, Clone)]
pub struct RankTable {
    /// The ranked parameters' names.
    pub parameters: Vec<String>,
    /// One entry per operating point.
    pub tests: Vec<RankTest>,
}

/// One test of a ranking table as plain data.
#[derive(Debug, Clone, Serialize)]
pub struct RankTestSummary<'a> {
    /// Speed [rpm].
    pub n_rpm: f64,
    /// Manifold pressure [kPa].
    pub p_int_kpa: f64,
    /// Oil temperature [°C].
    pub t_oil_c: f64,
    /// Friction torque [N·m].
    pub tau_fri_nm: f64,
    /// The design parameters, most sensitive first.
    pub ranking: Vec<&'a str>,
    /// Each parameter's normalised sensitivity.
    pub sensitivity: BTreeMap<&'a str, f64>,
}

/// A ranking table as `physid friction rank --json` prints it.
#[derive(Debug, Clone, Serialize)]
pub struct RankSummary<'a> {
    /// The design parameters.
    pub parameters: &'a [String],
    /// The tests.
    pub tests: Vec<RankTestSummary<'a>>,
}

impl RankTable {
    /// The table as plain data.
    pub fn summary(&self) -> RankSummary<'_> {
        let names = |idx: &[usize]| idx.iter().map(|&j| self.parameters[j].as_str()).collect();
        RankSummary {
            parameters: &self.parameters,
            tests: self
                .tests
                .iter()
                .map(|x| RankTestSummary {
                    n_rpm: x.op.n_rpm,
                    p_int_kpa: x.op.p_int_kpa,
                    t_oil_c: x.op.t_oil_c,
                    tau_fri_nm: x.tau_nm,
                    ranking: names(&x.order),
                    sensitivity: self
                        .parameters
                        .iter()
                        .map(String::as_str)
                        .zip(x.sensitivity.iter().copied())
                        .collect(),
                })
                .collect(),
        }
    }
}

/// Rank the design parameters named in `params` (all of [`DESIGN_PARAMS`] if empty) of the
/// design `d` with settings `st` at every point of `grid`.
pub fn friction_rank(
    d: &Design<f64>,
    st: &Settings,
    grid: &RankGrid,
    params: &[String],
) -> Result<RankTable, RankError> {
    grid.check()?;
    let free: Vec<usize> = if params.is_empty() {
        (0..DESIGN_PARAMS.len()).collect()
    } else {
        params
            .iter()
            .map(|p| {
                DESIGN_PARAMS
                    .iter()
                    .position(|q| q == p)
                    .ok_or_else(|| RankError::UnknownParameter(p.clone()))
            })
            .collect::<Result<_, _>>()?
    };
    let model = FrictionTorque::new(*st);
    let values = d.to_array();
    let mut engine = GradientEngine::new(model.param_names().len());
    let mut grad = vec![0.0; free.len()];
    let mut tests = Vec::new();
    for op in grid.points() {
        let tau = engine.value_and_gradient(
            &model,
            &FrictionTorque::inputs(&op),
            &values,
            &free,
            &mut grad,
        );
        if !(tau.is_finite() && tau != 0.0) {
            return Err(RankError::Degenerate {
                tau,
                n_rpm: op.n_rpm,
                p_int_kpa: op.p_int_kpa,
                t_oil_c: op.t_oil_c,
            });
        }
        let sensitivity: Vec<f64> = free
            .iter()
            .zip(&grad)
            .map(|(&j, g)| values[j] / tau * g)
            .collect();
        let mut order: Vec<usize> = (0..free.len()).collect();
        // Stable sort: equal sums of squares keep the lower index first.
        order.sort_by(|&a, &b| {
            let (sa, sb) = (sensitivity[a].powi(2), sensitivity[b].powi(2));
            sb.total_cmp(&sa)
        });
        let mut rank = vec![0; free.len()];
        for (pos, &j) in order.iter().enumerate() {
            rank[j] = pos + 1;
        }
        tests.push(RankTest {
            op,
            tau_nm: tau,
            sensitivity,
            order,
            rank,
        });
    }
    Ok(RankTable {
        parameters: free.iter().map(|&j| DESIGN_PARAMS[j].to_string()).collect(),
        tests,
    })
}
