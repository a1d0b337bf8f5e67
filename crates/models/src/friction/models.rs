//! The friction model as [`ParamModel`]s for identification: the friction torque over the
//! design parameters ([`FrictionTorque`], thesis §7.2) and over the 20 regression coefficients
//! ([`FrictionRegression`], Eq. 7.4–7.9), with their names, units and descriptions.

use super::*;

/// The friction torque `τ_fri` [N·m] as a model of its design parameters ([`DESIGN_PARAMS`],
/// mm and κ) through the seam, so that their sensitivities are exact (thesis §7.2, app. B.2).
/// Inputs: `n_rpm`, `p_int_kpa`, `p_atm_kpa`, `t_oil_c`. The fmep includes pumping, as the
/// thesis's ranking code has it, unless built [`without_pumping`](Self::without_pumping).
#[derive(Debug, Clone)]
pub struct FrictionTorque {
    settings: Settings,
    pumping: bool,
    params: Vec<String>,
    inputs: Vec<String>,
}

impl FrictionTorque {
    /// Input names, in order.
    pub const INPUTS: [&'static str; 4] = ["n_rpm", "p_int_kpa", "p_atm_kpa", "t_oil_c"];

    /// The model for the given discrete settings (oil, valvetrain, counts, variant).
    pub fn new(settings: Settings) -> Self {
        Self {
            settings,
            pumping: true,
            params: DESIGN_PARAMS.iter().map(|s| s.to_string()).collect(),
            inputs: Self::INPUTS.iter().map(|s| s.to_string()).collect(),
        }
    }

    /// The mechanical friction alone (pumping excluded; SPEC §2.3).
    pub fn without_pumping(mut self) -> Self {
        self.pumping = false;
        self
    }

    /// The model's inputs for an operating point.
    pub fn inputs(op: &OperatingPoint) -> [f64; 4] {
        [op.n_rpm, op.p_int_kpa, op.p_atm_kpa, op.t_oil_c]
    }
}

impl ParamModel for FrictionTorque {
    fn param_names(&self) -> &[String] {
        &self.params
    }

    fn input_names(&self) -> &[String] {
        &self.inputs
    }

    fn eval<T: Scalar>(&self, u: &[f64], p: &[T]) -> T {
        let d = Design::from_array([p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8]]);
        let op = OperatingPoint {
            n_rpm: u[0],
            p_int_kpa: u[1],
            p_atm_kpa: u[2],
            t_oil_c: u[3],
        };
        let f = fmep(&d, &self.settings, &op);
        let total = if self.pumping {
            f.total()
        } else {
            f.mechanical()
        };
        tau_nm(total, &d)
    }
}

/// The units of c1 … c20: each multiplies its term of [`regressors`] into fmep [kPa], the term
/// in the design's mm, the speed N in rpm, the mean piston speed S_p in m/s and pressures in
/// kPa (the viscosity factors and the valve count ratios are dimensionless).
pub const REGRESSION_UNITS: [&str; 20] = [
    "kPa·mm²",
    "kPa/(mm·rpm)",
    "kPa/(mm²·rpm²)",
    "kPa·mm·s/m",
    "kPa·mm²",
    "kPa/(mm·rpm)",
    "kPa",
    "kPa",
    "kPa·mm³/rpm",
    "kPa·mm",
    "kPa·mm/rpm",
    "kPa·mm^0.5/rpm^0.5",
    "kPa",
    "kPa",
    "kPa/rpm",
    "kPa/rpm²",
    "-",
    "kPa·s²/m²",
    "kPa·s²/m²",
    "kPa·s²/m²",
];
/// What each of c1 … c20 stands for: the friction source and its term (thesis Eq. 7.4–7.9).
pub const REGRESSION_DESCRIPTIONS: [&str; 20] = [
    "crankshaft seals: Db/(B²·S·nc)",
    "main bearings, hydrodynamic: Db³·Lb·s_μ·N·nb/(B²·S·nc)",
    "bearing seals, turbulent: Db²·N²·nb/nc",
    "piston skirt: S_p·s_μ/B",
    "ring tension: (ft/fto)·cr·(1 + 500/N)/B²",
    "con-rod bearings: Db³·Lb·h·N·nb/(B²·S·nc)",
    "gas-pressure loading of the rings: ring factor·p_int/p_atm",
    "constant (the 4.12 kPa cam seal)",
    "camshaft bearings: h·N·nb/(B²·S·nc)",
    "flat followers: (1 + 500/N)·nv/(S·nc)",
    "roller followers: N·nv/(S·nc)",
    "oscillating hydrodynamic: Lv^1.5·h·√N·nv/(B·S·nc)",
    "oscillating mixed: Lv·(1 + 500/N)·nv/(S·nc)",
    "auxiliaries, constant",
    "auxiliaries: N",
    "auxiliaries: N²",
    "throttling: p_atm − p_int",
    "intake valves: S_p²·(p_int/p_atm)²/((Di/B)⁴·nv²)",
    "intake system: S_p²·(p_int/p_atm)²",
    "exhaust valves: S_p²·(p_int/p_atm)²/((De/B)⁴·nv²)",
];

/// Names of the regression coefficients c1 … c20, in order.
pub const REGRESSION_PARAMS: [&str; 20] = [
    "c1", "c2", "c3", "c4", "c5", "c6", "c7", "c8", "c9", "c10", "c11", "c12", "c13", "c14", "c15",
    "c16", "c17", "c18", "c19", "c20",
];

/// The friction torque as the regression form, a model *linear* in c1 … c20 (thesis Eq. 7.4–7.9,
/// §7.3): `τ_fri = Σ c_i·ψ_i` [N·m] with `ψ_i = tau_nm(φ_i)` — the regressors of
/// [`regressors`] turned into torque with the design's bore and crank radius (Eq. 3.44). The
/// design and the discrete settings are fixed; pumping (c17 … c20) is included, as the thesis's
/// characterisation has it. Inputs as [`FrictionTorque`]: `n_rpm`, `p_int_kpa`, `p_atm_kpa`,
/// `t_oil_c`.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct FrictionRegression {
    design: Design<f64>,
    settings: Settings,
    params: Vec<String>,
    inputs: Vec<String>,
}

impl FrictionRegression {
    /// The regression form of an engine with this design and these settings.
    pub fn new(design: Design<f64>, settings: Settings) -> Self {
        Self {
            design,
            settings,
            params: REGRESSION_PARAMS.iter().map(|s| s.to_string()).collect(),
            inputs: FrictionTorque::INPUTS
                .iter()
                .map(|s| s.to_string())
                .collect(),
        }
    }

    /// The nominal coefficients of this engine's settings ([`nominal_coefficients`]).
    pub fn nominal(&self) -> [f64; 20] {
        nominal_coefficients(&self.settings)
    }

    /// The regressor `ψ` [N·m per unit coefficient] at an operating point.
    pub fn regressor(&self, op: &OperatingPoint) -> [f64; 20] {
        let phi = regressors(&self.design, &self.settings, op);
        let k = tau_nm(1.0, &self.design);
        phi.map(|v| v * k)
    }
}

impl ParamModel for FrictionRegression {
    fn param_names(&self) -> &[String] {
        &self.params
    }

    fn input_names(&self) -> &[String] {
        &self.inputs
    }

    fn eval<T: Scalar>(&self, u: &[f64], p: &[T]) -> T {
        let op = OperatingPoint {
            n_rpm: u[0],
            p_int_kpa: u[1],
            p_atm_kpa: u[2],
            t_oil_c: u[3],
        };
        self.regressor(&op)
            .iter()
            .zip(p)
            .fold(T::from(0.0), |acc, (&psi, &c)| acc + c * psi)
    }
}
