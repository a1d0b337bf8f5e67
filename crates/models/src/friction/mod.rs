//! Mean-value engine friction: Patton / Sandoval–Heywood (SPEC §2.5; thesis Eq. 3.44–3.50,
//! app. B.2–B.3), and its 20-coefficient regression form (Eq. 7.4–7.9), linear in the
//! coefficients. Two variants ([`Variant`]): as the thesis's code computes it, and as the
//! original (Sandoval 2002) states it; both share every term that they have in common.
//!
//! Units *inside* this model follow the correlations: lengths in mm, speed N in rpm, pressures
//! in kPa, oil temperature in °C, mean piston speed `S_p = 2·(S/1000)·N/60` in m/s, fmep in kPa.
//! [`Friction::tau_nm`] converts to a torque in N·m: `τ = fmep·1e3·(π(B/1000)²/4)·(r/1000)/(2π)`.
//!
//! The design parameters (B, S, κ, Di, De, Lv, Db, Lb, r) are generic over the
//! [`Scalar`](physid_core::Scalar), so their sensitivities (thesis §7.2) are exact.
//!
//! Here: the model (oil, valvetrain, design, settings, fmep and its regression form).
//! `presets.rs`: the named settings; `models.rs`: the model as `ParamModel`s with the names,
//! units and descriptions of their parameters.

use physid_core::{ParamModel, Scalar};

mod models;
mod presets;

pub use models::*;
pub use presets::*;

/// An oil grade: Vogel constants of `μ = k·exp(θ1/(θ2 + T))` [cP, T in °C] and the high-shear
/// factor `u_uo` (SPEC §2.5 table).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Oil {
    /// k [cP].
    pub k: f64,
    /// θ1 [°C].
    pub theta1: f64,
    /// θ2 [°C].
    pub theta2: f64,
    /// High-shear factor u_uo.
    pub u_uo: f64,
}

/// A valvetrain's friction constants (SPEC §2.5 table).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Valvetrain {
    /// Cff, flat-follower.
    pub cff: f64,
    /// Crf, roller-follower.
    pub crf: f64,
    /// Coh, oscillating hydrodynamic.
    pub coh: f64,
    /// Com, oscillating mixed.
    pub com: f64,
}

/// The oil grades by name (SPEC §2.5 table).
#[rustfmt::skip]
pub const OIL_GRADES: [(&str, Oil); 12] = [
    ("0W40", Oil { k: 0.01341, theta1: 1986.4, theta2: 189.7, u_uo: 0.67 }),
    ("5W20", Oil { k: 0.04576, theta1: 1224.0, theta2: 134.1, u_uo: 0.94 }),
    ("5W40", Oil { k: 0.15, theta1: 1018.74, theta2: 125.91, u_uo: 0.8 }),
    ("10W30", Oil { k: 0.1403, theta1: 869.72, theta2: 104.4, u_uo: 0.76 }),
    ("10W50A", Oil { k: 0.0352, theta1: 1658.88, theta2: 163.54, u_uo: 0.49 }),
    ("10W50B", Oil { k: 0.0507, theta1: 1362.4, theta2: 129.8, u_uo: 0.52 }),
    ("15W40A", Oil { k: 0.1223, theta1: 933.46, theta2: 103.89, u_uo: 0.9 }),
    ("15W40B", Oil { k: 0.03435, theta1: 1424.3, theta2: 137.2, u_uo: 0.79 }),
    ("20W50", Oil { k: 0.0639, theta1: 1255.46, theta2: 117.7, u_uo: 0.84 }),
    ("SAE10", Oil { k: 0.0258, theta1: 1345.42, theta2: 144.58, u_uo: 1.0 }),
    ("SAE30", Oil { k: 0.0246, theta1: 1432.29, theta2: 132.94, u_uo: 1.0 }),
    ("SAE50", Oil { k: 0.0384, theta1: 1349.94, theta2: 115.16, u_uo: 1.0 }),
];

/// The valvetrains by name (SPEC §2.5 table).
#[rustfmt::skip]
pub const VALVETRAINS: [(&str, Valvetrain); 6] = [
    ("SOHC_I", Valvetrain { cff: 600.0, crf: 0.0227, coh: 0.2, com: 42.8 }),
    ("SOHC_II", Valvetrain { cff: 400.0, crf: 0.0151, coh: 0.5, com: 21.4 }),
    ("SOHC_III", Valvetrain { cff: 200.0, crf: 0.0076, coh: 0.5, com: 10.7 }),
    ("DOHC_I", Valvetrain { cff: 600.0, crf: 0.0227, coh: 0.2, com: 25.8 }),
    ("DOHC_II", Valvetrain { cff: 133.0, crf: 0.0050, coh: 0.5, com: 10.7 }),
    ("OHV", Valvetrain { cff: 400.0, crf: 0.0151, coh: 0.5, com: 32.1 }),
];

/// Reference oil temperature of the viscosity scaling [°C].
pub const T_REF_C: f64 = 90.0;
/// Ring-tension exponent constant K (SPEC fix: 2K = 0.0476).
const K_RING: f64 = 2.38e-2;

/// An operating point (the correlations' units).
#[derive(Debug, Clone, Copy)]
pub struct OperatingPoint {
    /// Engine speed N [rpm].
    pub n_rpm: f64,
    /// Intake manifold pressure [kPa].
    pub p_int_kpa: f64,
    /// Ambient pressure [kPa].
    pub p_atm_kpa: f64,
    /// Oil temperature [°C].
    pub t_oil_c: f64,
}

impl OperatingPoint {
    /// Whether the point is inside the model's domain: speed > 0, pressures ≥ 0 (ambient > 0),
    /// oil temperature −50 … 200 °C (the Vogel form has a pole near −θ2 ≈ −100 … −190 °C).
    /// The error names the quantity, its value and what was expected.
    pub fn validate(&self) -> Result<(), InvalidFriction> {
        let checks = [
            ("engine speed [rpm]", self.n_rpm, self.n_rpm > 0.0, "> 0"),
            (
                "manifold pressure [kPa]",
                self.p_int_kpa,
                self.p_int_kpa >= 0.0,
                "≥ 0",
            ),
            (
                "ambient pressure [kPa]",
                self.p_atm_kpa,
                self.p_atm_kpa > 0.0,
                "> 0",
            ),
            (
                "oil temperature [°C]",
                self.t_oil_c,
                (-50.0..=200.0).contains(&self.t_oil_c),
                "in −50 … 200",
            ),
        ];
        for (what, v, ok, expected) in checks {
            if !(v.is_finite() && ok) {
                return Err(InvalidFriction(format!(
                    "{what} = {v}: expected a finite value {expected}"
                )));
            }
        }
        Ok(())
    }

    /// From SI quantities: speed ω [rad/s], pressures [Pa], oil temperature [K].
    pub fn from_si(omega_rad_s: f64, p_int_pa: f64, p_atm_pa: f64, t_oil_k: f64) -> Self {
        Self {
            n_rpm: omega_rad_s * 30.0 / std::f64::consts::PI,
            p_int_kpa: p_int_pa / 1e3,
            p_atm_kpa: p_atm_pa / 1e3,
            t_oil_c: t_oil_k - 273.15,
        }
    }
}

/// Design parameters (mm; κ dimensionless), generic so that each can be differentiated.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Design<T> {
    /// Bore B [mm].
    pub b: T,
    /// Stroke S [mm].
    pub s: T,
    /// Compression ratio κ.
    pub kappa: T,
    /// Intake valve diameter Di [mm].
    pub di: T,
    /// Exhaust valve diameter De [mm].
    pub de: T,
    /// Valve lift Lv [mm].
    pub lv: T,
    /// Main bearing diameter Db [mm].
    pub db: T,
    /// Main bearing length Lb [mm].
    pub lb: T,
    /// Crank radius r [mm] (for the torque).
    pub r: T,
}

/// Which statement of the model (SPEC §2.5 note).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Variant {
    /// The thesis's code (app. B.2): `s_μ = √(u_uo·μ(T)/μ(T_ref))`, the grade factor `u_uo`
    /// alone in three hydrodynamic terms, constant 4.12 kPa in rfmep, auxiliaries
    /// `8.32 + 1.86e-3·N + 7.45e-7·N²`.
    Thesis,
    /// The original (Sandoval 2002): `s_μ = √(μ(T)/μ(T_ref))` (1 at T_ref) in every
    /// hydrodynamic term, the 4.12 kPa cam-seal constant in vfmep, auxiliaries
    /// `6.23 + 5.22e-3·N − 1.79e-7·N²`.
    Sandoval2002,
}

impl Variant {
    /// Auxiliary-loss constants (a0, a1, a2): `afmep = a0 + a1·N + a2·N²` [kPa, N in rpm].
    fn auxiliaries(self) -> (f64, f64, f64) {
        match self {
            Variant::Thesis => (8.32, 1.86e-3, 7.45e-7),
            Variant::Sandoval2002 => (6.23, 5.22e-3, -1.79e-7),
        }
    }
}

impl<T: Scalar> Design<T> {
    /// From lengths in metres (κ dimensionless) to the correlations' millimetres.
    pub fn from_si(si: Design<T>) -> Self {
        Self {
            b: si.b * 1e3,
            s: si.s * 1e3,
            kappa: si.kappa,
            di: si.di * 1e3,
            de: si.de * 1e3,
            lv: si.lv * 1e3,
            db: si.db * 1e3,
            lb: si.lb * 1e3,
            r: si.r * 1e3,
        }
    }
}

/// The discrete choices: oil, valvetrain, counts and ring factors.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Settings {
    /// Which statement of the model.
    pub variant: Variant,
    /// The oil.
    pub oil: Oil,
    /// The valvetrain.
    pub valvetrain: Valvetrain,
    /// Ring tension ratio Ft/Fto.
    pub ft_fto: f64,
    /// Conformability factor Cr.
    pub cr: f64,
    /// Cylinders nc.
    pub nc: f64,
    /// Valves per cylinder nv.
    pub nv: f64,
    /// Main bearings nb.
    pub nb: f64,
}

/// fmep by component [kPa].
#[derive(Debug, Clone, Copy)]
pub struct Fmep<T> {
    /// Crankshaft.
    pub cfmep: T,
    /// Reciprocating (piston, rings, connecting rods).
    pub rfmep: T,
    /// Valvetrain.
    pub vfmep: T,
    /// Auxiliaries.
    pub afmep: T,
    /// Pumping.
    pub pmep: T,
}

impl<T: Scalar> Fmep<T> {
    /// Total fmep including pumping (the whole motoring loss).
    pub fn total(&self) -> T {
        self.cfmep + self.rfmep + self.vfmep + self.afmep + self.pmep
    }

    /// fmep without pumping (for the virtual test cell, where pumping is simulated; SPEC §2.3).
    pub fn mechanical(&self) -> T {
        self.cfmep + self.rfmep + self.vfmep + self.afmep
    }
}

/// Oil viscosity `μ(T) = k·exp(θ1/(θ2 + T))` [cP], T in °C (Vogel).
pub fn viscosity(oil: Oil, t_c: f64) -> f64 {
    oil.k * (oil.theta1 / (oil.theta2 + t_c)).exp()
}

/// The viscosity scaling `s_μ` (Eq. 3.45): `√(u_uo·μ(T)/μ(T_ref))` as the thesis's code
/// computes it (√u_uo at T_ref), `√(μ(T)/μ(T_ref))` in the original (1 at T_ref).
pub fn s_mu(st: &Settings, t_c: f64) -> f64 {
    let grade = match st.variant {
        Variant::Thesis => st.oil.u_uo,
        Variant::Sandoval2002 => 1.0,
    };
    (grade * viscosity(st.oil, t_c) / viscosity(st.oil, T_REF_C)).sqrt()
}

/// The factor of the three hydrodynamic terms (con-rod bearings, camshaft bearings,
/// oscillating hydrodynamic valvetrain) that the thesis's code scales by the grade factor
/// `u_uo` alone and the original by `s_μ`.
fn hydrodynamic_factor(st: &Settings, smu: f64) -> f64 {
    match st.variant {
        Variant::Thesis => st.oil.u_uo,
        Variant::Sandoval2002 => smu,
    }
}

/// The 20 nominal coefficients c1 … c20 of the regression form, in the order the constants
/// appear in the physical form (SPEC §2.5; c8 is the 4.12 kPa constant wherever the variant
/// puts it, c14–c16 the variant's auxiliary constants), so that both forms agree exactly.
pub fn nominal_coefficients(settings: &Settings) -> [f64; 20] {
    let Valvetrain { cff, crf, coh, com } = settings.valvetrain;
    let (a0, a1, a2) = settings.variant.auxiliaries();
    [
        1.22e5, 3.03e-4, 1.35e-10, 294.0, 4.06e4, 3.03e-4, 6.89, 4.12, 244.0, cff, crf, coh, com,
        a0, a1, a2, 1.0, 4.12e-3, 0.178, 4.12e-3,
    ]
}

/// The regressors φ1 … φ20 [kPa per unit coefficient]: `fmep = Σ c_i·φ_i` (Eq. 7.4–7.9).
/// Generic in the design so that a design parameter can be differentiated through them too.
pub fn regressors<T: Scalar>(d: &Design<T>, st: &Settings, op: &OperatingPoint) -> [T; 20] {
    let n = op.n_rpm;
    let (b, s) = (d.b, d.s);
    let sp = s * (2.0 / 1000.0 * n / 60.0); // mean piston speed [m/s]
    let smu = s_mu(st, op.t_oil_c);
    let hydro = hydrodynamic_factor(st, smu);
    let (nc, nv, nb) = (st.nc, st.nv, st.nb);
    let bbs = b * b * s * nc; // B²·S·nc
    let ratio = op.p_int_kpa / op.p_atm_kpa;
    let db3lb = d.db * d.db * d.db * d.lb;
    let speed_factor = 1.0 + 500.0 / n;
    let (ri, re) = (d.di / b, d.de / b);
    let ring =
        (d.kappa * 0.088 * smu) + d.kappa.powd(-(sp * (2.0 * K_RING)) + 1.33) * (0.182 * st.ft_fto);
    let one = T::from(1.0);
    [
        d.db / bbs,                                              // c1  crankshaft seals
        db3lb * (smu * n * nb) / bbs,                            // c2  bearings, hydrodynamic
        d.db * d.db * (n * n * nb / nc),                         // c3  bearing seals, turbulent
        sp * smu / b,                                            // c4  piston skirt
        one * (st.ft_fto * st.cr * speed_factor) / (b * b),      // c5  ring tension
        db3lb * (hydro * n * nb) / bbs,                          // c6  con-rod bearings
        ring * ratio,                                            // c7  gas-pressure loading
        one,                                                     // c8  constant (cam seal)
        one * (hydro * n * nb) / (b * b * s * nc),               // c9  camshaft bearings
        one * (speed_factor * nv) / (s * nc),                    // c10 Cff: flat follower
        one * (n * nv) / (s * nc),                               // c11 Crf: roller follower
        d.lv.powf(1.5) * (hydro * n.sqrt() * nv) / (b * s * nc), // c12 Coh: oscillating hydrodynamic
        d.lv * (speed_factor * nv) / (s * nc),                   // c13 Com: oscillating mixed
        one,                                                     // c14 auxiliaries
        one * n,                                                 // c15
        one * (n * n),                                           // c16
        one * (op.p_atm_kpa - op.p_int_kpa),                     // c17 throttling
        sp * sp * (ratio * ratio) / (ri.powi(4) * (nv * nv)),    // c18 intake valves
        sp * sp * (ratio * ratio),                               // c19 intake system
        sp * sp * (ratio * ratio) / (re.powi(4) * (nv * nv)),    // c20 exhaust valves
    ]
}

/// The physical form, term by term as SPEC §2.5 writes the thesis's code (app. B.2) — written
/// independently of [`regressors`], so that their agreement is a check.
pub fn fmep<T: Scalar>(d: &Design<T>, st: &Settings, op: &OperatingPoint) -> Fmep<T> {
    fmep_with_viscosity(d, st, op, s_mu(st, op.t_oil_c))
}

/// [`fmep`] with the viscosity scaling `smu` = [`s_mu`]`(st, op.t_oil_c)` given: a caller that
/// evaluates many operating points at one oil temperature computes it once.
pub fn fmep_with_viscosity<T: Scalar>(
    d: &Design<T>,
    st: &Settings,
    op: &OperatingPoint,
    smu: f64,
) -> Fmep<T> {
    let n = op.n_rpm;
    let (b, s, nc, nv, nb) = (d.b, d.s, st.nc, st.nv, st.nb);
    // S̄p = 2·S·N/60 with S in mm; the denominators shared by several terms once.
    let sp = s * (n * (2.0 / 1000.0 / 60.0));
    let speed_factor = 1.0 + 500.0 / n;
    let per_bbsnc = (b * b * s * nc).recip();
    let per_snc = (s * nc).recip();
    let hydro = hydrodynamic_factor(st, smu);
    let Valvetrain { cff, crf, coh, com } = st.valvetrain;
    // The 4.12 kPa constant: in rfmep in the thesis (Eq. 3.47), a cam-seal term in vfmep in
    // the original.
    let (rfmep_const, vfmep_const) = match st.variant {
        Variant::Thesis => (4.12, 0.0),
        Variant::Sandoval2002 => (0.0, 4.12),
    };
    let pr = op.p_int_kpa / op.p_atm_kpa;
    let db3lb = d.db.powi(3) * d.lb;
    let cfmep = d.db * 1.22e5 * per_bbsnc
        + db3lb * (3.03e-4 * smu * n * nb) * per_bbsnc
        + d.db * d.db * (1.35e-10 * n * n * nb / nc);
    let rfmep = sp * (2.94e2 * smu) / b
        + T::from(4.06e4 * (st.ft_fto * st.cr) * speed_factor) / (b * b)
        + db3lb * (3.03e-4 * hydro * n * nb) * per_bbsnc
        + (d.kappa * (0.088 * smu)
            + d.kappa.powd(-(sp * (2.0 * K_RING)) + 1.33) * (0.182 * st.ft_fto))
            * (6.89 * pr)
        + rfmep_const;
    let vfmep = per_bbsnc * (244.0 * hydro * n * nb)
        + per_snc * (cff * speed_factor * nv)
        + per_snc * (crf * n * nv)
        + d.lv * d.lv.sqrt() * (coh * hydro * n.sqrt() * nv) * per_snc / b
        + d.lv * (com * speed_factor * nv) * per_snc
        + vfmep_const;
    let (a0, a1, a2) = st.variant.auxiliaries();
    let afmep = T::from(a0 + a1 * n + a2 * n * n);
    let (ri, re) = (d.di / b, d.de / b);
    let pmep = T::from(op.p_atm_kpa - op.p_int_kpa)
        + sp * sp * (4.12e-3 * pr * pr) / (ri.powi(4) * (nv * nv))
        + (sp * pr) * (sp * pr) * 0.178
        + sp * sp * (4.12e-3 * pr * pr) / (re.powi(4) * (nv * nv));
    Fmep {
        cfmep,
        rfmep,
        vfmep,
        afmep,
        pmep,
    }
}

/// The mechanical fmep (no pumping) of one design, settings and oil viscosity `s_μ` as a
/// function of speed and manifold pressure ratio alone [kPa]: the terms of
/// [`fmep_with_viscosity`] gathered by how they vary with N, with `S̄p = s_p·N` and the ring
/// term's `κ^(1.33 − 2K·S̄p) = e^(r0 − r1·N)`,
///
/// ```text
/// mfmep = a + b·N + c·N² + d/N + e·√N + (p_int/p_atm)·(f + g·e^(r0 − r1·N))
/// ```
///
/// (the `1 + 500/N` of ring tension, flat followers and oscillating mixed lubrication split
/// into `a` and `d`). One division, one root and one exponential per evaluation: the form the
/// test cell evaluates at every step. The constants are [`nominal_coefficients`]'; equal to
/// the physical form to round-off (tested).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeedForm {
    a: f64,
    b: f64,
    c: f64,
    d: f64,
    e: f64,
    f: f64,
    g: f64,
    r0: f64,
    r1: f64,
}

impl SpeedForm {
    /// The form of design `d` with settings `st` at oil viscosity scaling `smu` ([`s_mu`]).
    pub fn new(d: &Design<f64>, st: &Settings, smu: f64) -> Self {
        let c = nominal_coefficients(st);
        let (b, s, nc, nv, nb) = (d.b, d.s, st.nc, st.nv, st.nb);
        let hydro = hydrodynamic_factor(st, smu);
        let per_bbsnc = (b * b * s * nc).recip();
        let per_snc = (s * nc).recip();
        let db3lb = d.db.powi(3) * d.lb;
        // Mean piston speed per rpm [m/s], S in mm.
        let sp = s * (2.0 / 1000.0 / 60.0);
        // The terms in 1 + 500/N: ring tension (c5), flat followers (c10), oscillating mixed
        // (c13).
        let speed_factor_terms =
            c[4] * st.ft_fto * st.cr / (b * b) + c[9] * nv * per_snc + c[12] * d.lv * nv * per_snc;
        let ln_kappa = d.kappa.ln();
        Self {
            // Crankshaft seals (c1), the 4.12 kPa constant (c8), auxiliaries (c14).
            a: c[0] * d.db * per_bbsnc + speed_factor_terms + c[7] + c[13],
            // Bearings (c2), piston skirt (c4), con-rod bearings (c6), camshaft bearings (c9),
            // roller followers (c11), auxiliaries (c15).
            b: c[1] * db3lb * smu * nb * per_bbsnc
                + c[3] * sp * smu / b
                + c[5] * db3lb * hydro * nb * per_bbsnc
                + c[8] * hydro * nb * per_bbsnc
                + c[10] * nv * per_snc
                + c[14],
            // Bearing seals (c3), auxiliaries (c16).
            c: c[2] * d.db * d.db * nb / nc + c[15],
            d: 500.0 * speed_factor_terms,
            // Oscillating hydrodynamic (c12).
            e: c[11] * d.lv * d.lv.sqrt() * hydro * nv * per_snc / b,
            // Gas-pressure loading of the rings (c7).
            f: c[6] * d.kappa * 0.088 * smu,
            g: c[6] * 0.182 * st.ft_fto,
            r0: 1.33 * ln_kappa,
            r1: 2.0 * K_RING * sp * ln_kappa,
        }
    }

    /// Mechanical fmep [kPa] at speed `n_rpm` [rpm] and `pr = p_int/p_atm`.
    pub fn mechanical(&self, n_rpm: f64, pr: f64) -> f64 {
        let n = n_rpm;
        self.a
            + n * (self.b + n * self.c)
            + self.d / n
            + self.e * n.sqrt()
            + pr * (self.f + self.g * (self.r0 - self.r1 * n).exp())
    }
}

/// fmep [kPa] of the regression form: `Σ c_i·φ_i` (Eq. 7.4–7.9).
pub fn fmep_regression(c: &[f64; 20], phi: &[f64; 20]) -> f64 {
    c.iter().zip(phi).map(|(c, p)| c * p).sum()
}

/// Torque from fmep [N·m]: `fmep·1e3 · π(B/1000)²/4 · (r/1000)/(2π)` (Eq. 3.44).
pub fn tau_nm<T: Scalar>(fmep_kpa: T, d: &Design<T>) -> T {
    fmep_kpa * 1e3 * (d.b / 1000.0) * (d.b / 1000.0) * (std::f64::consts::PI / 4.0) * (d.r / 1000.0)
        / (2.0 * std::f64::consts::PI)
}

/// Names of the design parameters, in [`Design`] order (thesis app. B.2: `rc` is κ).
pub const DESIGN_PARAMS: [&str; 9] = ["B", "S", "kappa", "Di", "De", "Lv", "Db", "Lb", "r"];
/// Their units.
pub const DESIGN_UNITS: [&str; 9] = ["mm", "mm", "-", "mm", "mm", "mm", "mm", "mm", "mm"];
/// One line each (`B` here is the bore, not the coupling shaft's damping).
pub const DESIGN_DESCRIPTIONS: [&str; 9] = [
    "bore",
    "stroke",
    "compression ratio",
    "intake valve diameter",
    "exhaust valve diameter",
    "valve lift",
    "main bearing diameter",
    "main bearing length",
    "crank radius (for the torque)",
];

impl<T: Scalar> Design<T> {
    /// The design from values in [`DESIGN_PARAMS`] order.
    pub fn from_array(v: [T; 9]) -> Self {
        let [b, s, kappa, di, de, lv, db, lb, r] = v;
        Self {
            b,
            s,
            kappa,
            di,
            de,
            lv,
            db,
            lb,
            r,
        }
    }

    /// The values in [`DESIGN_PARAMS`] order.
    pub fn to_array(&self) -> [T; 9] {
        [
            self.b, self.s, self.kappa, self.di, self.de, self.lv, self.db, self.lb, self.r,
        ]
    }
}

/// A design or setting the friction model cannot take, explained (the value, what was
/// expected).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct InvalidFriction(pub String);

impl From<String> for InvalidFriction {
    fn from(message: String) -> Self {
        Self(message)
    }
}

/// Names accepted by [`set_by_name`] besides [`DESIGN_PARAMS`].
pub const SETTING_NAMES: [&str; 7] = ["oil", "valvetrain", "ft_fto", "cr", "nc", "nv", "nb"];

/// Set one design parameter (mm; κ) or setting by name from its text — `B=56`, `oil=5W30`,
/// `valvetrain=DOHC_I`, `nb=5` — for `--set` on the command line. The error says what was
/// expected.
pub fn set_by_name(
    d: &mut Design<f64>,
    st: &mut Settings,
    name: &str,
    value: &str,
) -> Result<(), InvalidFriction> {
    let number = || -> Result<f64, InvalidFriction> {
        match value.trim().parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
            _ => Err(InvalidFriction(format!(
                "{name}={value}: expected a finite number > 0"
            ))),
        }
    };
    if let Some(j) = DESIGN_PARAMS.iter().position(|&p| p == name) {
        let mut a = d.to_array();
        a[j] = number()?;
        *d = Design::from_array(a);
        return Ok(());
    }
    match name {
        "oil" => {
            let g = OIL_GRADES
                .iter()
                .find(|g| g.0.eq_ignore_ascii_case(value.trim()))
                .ok_or_else(|| {
                    let list: Vec<&str> = OIL_GRADES.iter().map(|g| g.0).collect();
                    format!("oil={value}: the grades are {}", list.join(", "))
                })?;
            st.oil = g.1;
        }
        "valvetrain" => {
            let v = VALVETRAINS
                .iter()
                .find(|v| v.0.eq_ignore_ascii_case(value.trim()))
                .ok_or_else(|| {
                    let list: Vec<&str> = VALVETRAINS.iter().map(|v| v.0).collect();
                    format!(
                        "valvetrain={value}: the valvetrains are {}",
                        list.join(", ")
                    )
                })?;
            st.valvetrain = v.1;
        }
        "ft_fto" => st.ft_fto = number()?,
        "cr" => st.cr = number()?,
        "nc" => st.nc = number()?,
        "nv" => st.nv = number()?,
        "nb" => st.nb = number()?,
        _ => {
            return Err(InvalidFriction(format!(
                "'{name}' is not a friction parameter; they are {}, {}",
                DESIGN_PARAMS.join(", "),
                SETTING_NAMES.join(", ")
            )))
        }
    }
    Ok(())
}
