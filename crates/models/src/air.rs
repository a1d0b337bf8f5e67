//! Thermodynamic properties of air from NASA 7-coefficient polynomials (SPEC §2.2; thesis
//! app. B.1 "Thermochemistry"; Gordon & McBride 1976).
//!
//! Air is 1 kmol O₂ + 79/21 kmol N₂. Per species `cp/R_i = a1 + a2T + a3T² + a4T³ + a5T⁴` and
//! `h/(R_i T) = a1 + a2T/2 + a3T²/3 + a4T³/4 + a5T⁴/5 + a6/T`; the mixture's molar properties are
//! the mole-fraction averages, divided by its molar mass for mass-specific values;
//! `u = h − R·T`, `c_v = c_p − R`. Temperatures in K, energies in J/kg.

/// Universal gas constant [J/(kmol·K)] (SPEC §2.2).
pub const R_U: f64 = 8314.34;
/// Molar mass of O₂ [kg/kmol].
pub const M_O2: f64 = 31.999;
/// Molar mass of N₂ [kg/kmol].
pub const M_N2: f64 = 28.013;
/// Moles of N₂ per mole of O₂ in air.
pub const N2_PER_O2: f64 = 79.0 / 21.0;
/// Boundary between the polynomials' low and high ranges [K].
pub const T_MID: f64 = 1000.0;

/// (a1 … a7) for 300–1000 K and 1000–5000 K (SPEC §2.2 table).
const O2: [[f64; 7]; 2] = [
    [
        3.6255985,
        -1.8782184e-3,
        7.0554544e-6,
        -6.7635137e-9,
        2.1555993e-12,
        -1.0475226e3,
        4.3052778,
    ],
    [
        3.6219535,
        7.3618264e-4,
        -1.9652228e-7,
        3.6201558e-11,
        -2.8945627e-15,
        -1.2019825e3,
        3.6150960,
    ],
];
const N2: [[f64; 7]; 2] = [
    [
        3.6748261,
        -1.2081500e-3,
        2.3240102e-6,
        -6.3217559e-10,
        -2.2577253e-13,
        -1.0611588e3,
        2.3580424,
    ],
    [
        2.8963194,
        1.5154866e-3,
        -5.7235277e-7,
        9.9807393e-11,
        -6.5223555e-15,
        -9.0586184e2,
        6.1615148,
    ],
];

/// Mole fractions of O₂ and N₂.
const X_O2: f64 = 1.0 / (1.0 + N2_PER_O2);
const X_N2: f64 = N2_PER_O2 / (1.0 + N2_PER_O2);
/// Molar mass of air [kg/kmol].
const M_AIR: f64 = X_O2 * M_O2 + X_N2 * M_N2;
/// Specific gas constant of air [J/(kg·K)].
const R_AIR: f64 = R_U / M_AIR;

/// The mixture's coefficients: the mole-fraction average of the species' (the properties are
/// linear in the coefficients, so one polynomial serves for the mixture).
const fn mix(o: &[f64; 7], n: &[f64; 7]) -> [f64; 7] {
    let mut m = [0.0; 7];
    let mut i = 0;
    while i < 7 {
        m[i] = X_O2 * o[i] + X_N2 * n[i];
        i += 1;
    }
    m
}
const AIR: [[f64; 7]; 2] = [mix(&O2[0], &N2[0]), mix(&O2[1], &N2[1])];

/// The enthalpy polynomial's coefficients `h/R = a6 + T·(a1 + T·(a2/2 + T·(a3/3 + T·(a4/4 +
/// T·a5/5))))`, divided once here instead of per evaluation.
const fn enthalpy_coefficients(a: &[f64; 7]) -> [f64; 6] {
    [a[0], a[1] / 2.0, a[2] / 3.0, a[3] / 4.0, a[4] / 5.0, a[5]]
}
const AIR_H: [[f64; 6]; 2] = [
    enthalpy_coefficients(&AIR[0]),
    enthalpy_coefficients(&AIR[1]),
];

/// The range of the polynomials that holds `t`.
fn range(t: f64) -> usize {
    usize::from(t >= T_MID)
}

fn cp_over_r(a: &[f64; 7], t: f64) -> f64 {
    a[0] + t * (a[1] + t * (a[2] + t * (a[3] + t * a[4])))
}

/// `h/R` [K] (`h/(R·T)` of the header times T, without its division).
fn h_over_r(b: &[f64; 6], t: f64) -> f64 {
    b[5] + t * (b[0] + t * (b[1] + t * (b[2] + t * (b[3] + t * b[4]))))
}

/// Molar mass of air [kg/kmol].
pub fn molar_mass() -> f64 {
    M_AIR
}

/// Specific gas constant of air R [J/(kg·K)].
pub fn gas_constant() -> f64 {
    R_AIR
}

/// `(c_p(T), h(T))` together (one choice of the polynomials' range) [J/(kg·K)], [J/kg]: what a
/// gas-dynamics step needs of each volume (`c_v = c_p − R`, `u = h − R·T`, `γ = c_p/c_v`).
pub fn cp_and_enthalpy(t: f64) -> (f64, f64) {
    let i = range(t);
    (
        cp_over_r(&AIR[i], t) * R_AIR,
        h_over_r(&AIR_H[i], t) * R_AIR,
    )
}

/// Specific heat at constant pressure c_p(T) [J/(kg·K)].
pub fn cp(t: f64) -> f64 {
    cp_over_r(&AIR[range(t)], t) * R_AIR
}

/// Specific heat at constant volume c_v(T) = c_p − R [J/(kg·K)].
pub fn cv(t: f64) -> f64 {
    cp(t) - gas_constant()
}

/// Ratio of specific heats γ(T) = c_p/c_v.
pub fn gamma(t: f64) -> f64 {
    let c = cp(t);
    c / (c - R_AIR)
}

/// Specific enthalpy h(T) [J/kg] (the polynomials' datum: formation enthalpy of the elements).
pub fn enthalpy(t: f64) -> f64 {
    h_over_r(&AIR_H[range(t)], t) * R_AIR
}

/// Specific internal energy u(T) = h − R·T [J/kg].
pub fn internal_energy(t: f64) -> f64 {
    enthalpy(t) - gas_constant() * t
}
