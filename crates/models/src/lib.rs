//! # physid-models — the physics as parameterised functions
//!
//! One implementation of each model, shared by the virtual test cell and the identification
//! applications. Functions are generic over the [`Scalar`](physid_core::Scalar) where their
//! arguments are parameters someone may estimate (bore, crank radius, rod, offset), so exact
//! derivatives come for free; SI units throughout.
//!
//! * [`kinematics`] — slider-crank with piston-pin offset (SPEC §2.3, Eq. 3.29–3.32, app. B.4).
//! * [`friction`] — mean-value friction (Patton / Sandoval–Heywood as the thesis's code has it)
//!   and its 20-coefficient regression form (SPEC §2.5, Eq. 7.4–7.9).
//! * [`cyclic_torque`] — the cyclic engine torque model of the cold test (Eq. 8.2, SPEC §9),
//!   15 parameters; [`friction_fit`] — its friction cubic fitted to the mean-value model.
//! * [`shaft`] — the coupling shaft, linear in K, B and an optional torque offset (Eq. 6.1).
//! * [`motored`] — the motored cylinder pressure around TDC: polytropic compression through
//!   the slider crank with a loss, a sensor offset and a TDC offset (`physid compression fit`).
//! * [`air`] — NASA-polynomial thermodynamic properties of air (SPEC §2.2, app. B.1).

pub mod air;
pub mod cyclic_torque;
pub mod friction;
pub mod friction_fit;
pub mod kinematics;
pub mod motored;
pub mod shaft;
