//! The named model settings: the thesis's and Sandoval (2002)'s ([`preset`]).

use super::*;

/// The named presets, for the command line.
pub const PRESETS: [&str; 2] = ["thesis", "sandoval2002"];

/// A preset by name ([`PRESETS`]); `None` for an unknown name.
pub fn preset(name: &str) -> Option<(Design<f64>, Settings)> {
    match name {
        "thesis" => Some(thesis_preset()),
        "sandoval2002" => Some(sandoval2002_preset()),
        _ => None,
    }
}

/// The original model ([`Variant::Sandoval2002`]) on the thesis's engine and oil: the same
/// geometry and settings as [`thesis_preset`], so the two differ only in the model statement.
pub fn sandoval2002_preset() -> (Design<f64>, Settings) {
    let (d, st) = thesis_preset();
    (
        d,
        Settings {
            variant: Variant::Sandoval2002,
            ..st
        },
    )
}

/// The thesis preset (app. B.2–B.3): 0W40, SOHC_III, Ft/Fto = 1, Cr = 1, nc = 1, nv = 2,
/// nb = 2, B = 54, S = 51.5, r = 25.7, Db = 52, Lb = 13, Lv = 9, Di = 27, De = 23 mm, κ = 12
/// (the friction study's value; the engine's is 9.5 — SPEC §2.5).
pub fn thesis_preset() -> (Design<f64>, Settings) {
    (
        Design {
            b: 54.0,
            s: 51.5,
            kappa: 12.0,
            di: 27.0,
            de: 23.0,
            lv: 9.0,
            db: 52.0,
            lb: 13.0,
            r: 25.7,
        },
        Settings {
            variant: Variant::Thesis,
            oil: OIL_GRADES[0].1,
            valvetrain: VALVETRAINS[2].1,
            ft_fto: 1.0,
            cr: 1.0,
            nc: 1.0,
            nv: 2.0,
            nb: 2.0,
        },
    )
}
