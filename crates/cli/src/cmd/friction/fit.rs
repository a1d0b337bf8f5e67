//! `physid friction fit`: the regression coefficients fitted to a motored recording (thesis
//! §7.3, Application 2), its report section and its tracks.

use super::*;

pub(super) fn fit(a: &FitArgs) -> Result<()> {
    let (d, st) = a.model.build()?;
    let mut cfg = FrictionFitConfig::new(d, st);
    cfg.source = TorqueSource::parse(&a.source)
        .ok_or_else(|| miette!("--source '{}': expected engine or shaft", a.source))?;
    cfg.selection = a.cutoff;
    cfg.estimate = (!a.estimate.is_empty()).then(|| a.estimate.clone());
    cfg.s0 = a.s0;
    cfg.lambda = a.lambda;
    cfg.transient_s = a.transient;
    cfg.p_atm_kpa = a.p_atm;
    // A time-basis file streams through the stage, a crank-angle one (with `cycle`) through
    // the cycle means, each reading only the channels it takes; a time basis whose angle is an
    // encoder's counts is resampled to 1° as it is read (`CrankInput`), into the cycle means.
    let header = a.input.open_all(&a.data)?.header().clone();
    let r = if friction_fit::streams(&header) {
        let (needed, optional) = friction_fit::sample_channels(&cfg);
        let mut reader = a.input.open(&a.data, &needed, &optional)?;
        let r = friction_fit_stream(Reading::new(&mut reader, &a.data), &cfg);
        crate::cmd::warn_read(&reader, &a.data);
        r
    } else if header.channel("cycle").is_ok() {
        let (needed, optional) = friction_fit::cycle_channels(&cfg);
        let mut reader = a.input.open(&a.data, &needed, &optional)?;
        let r = friction_fit::friction_fit_cycles(Reading::new(&mut reader, &a.data), &cfg);
        crate::cmd::warn_read(&reader, &a.data);
        r
    } else if header.basis == physid_core::Basis::Time {
        // The engine angle from an encoder's counts: the crank-angle samples as they are made.
        let (angle, crank) = (AngleArgs::default(), CrankArgs::default());
        let input = crank_input(&a.input, &a.data, &angle, &crank)?;
        let (needed, optional) = friction_fit::cycle_channels(&cfg);
        let made = ["cycle"];
        input
            .require(
                &needed
                    .iter()
                    .filter(|n| !made.contains(n))
                    .copied()
                    .collect::<Vec<_>>(),
            )
            .map_err(crate::cmd::app_error(&a.data))?;
        let channels: Vec<&str> = needed.into_iter().chain(optional).collect();
        let (cycles, _) = input
            .read(
                Some(&channels),
                |_| Ok(FrictionCycles::new(&cfg)),
                |s, chunk| s.push(chunk),
            )
            .map_err(crate::cmd::app_error(&a.data))?;
        cycles.fit()
    } else {
        friction_fit(&a.input.read(&a.data, None)?, &cfg)
    }
    .map_err(crate::cmd::app_error(&a.data))?;
    crate::cmd::warn_dropouts(&r.dropouts, &a.data);
    if let Some(path) = &a.tracks {
        write_tracks(path, &r)?;
    }
    let j = r.summary();
    if let Some(dir) = &a.out {
        let title = "physid — friction fit";
        report::write(dir, title, &a.data, "friction_fit.json", &j, |rep, dir| {
            fit_report_section(rep, &r, &cfg, dir)
        })?;
    }
    if a.json {
        crate::provenance::print_json(&j)?;
        return Ok(());
    }
    outln!(
        "{}: {} steady cycles ({} skipped as not steady)",
        a.data.display(),
        r.data.len(),
        r.data.skipped_unsteady
    );
    outln!("  estimable: {}", r.estimable.join(", "));
    outln!("  coefficient      nominal        final    change   std error");
    for name in &r.estimable {
        let j = coefficient_index(name);
        outln!(
            "  {:<8} {:>12.4e} {:>12.4e} {:>8.1} % {:>11.3e}",
            name,
            r.nominal[j],
            r.params[j],
            100.0 * (r.params[j] - r.nominal[j]) / r.nominal[j],
            r.std_err[j].unwrap_or(f64::NAN)
        );
    }
    outln!(
        "  prediction error: final {:+.2} %, max after the {} s transient {:.2} %{}",
        r.final_error_pct,
        physid_core::Num(a.transient),
        r.max_error_after_transient_pct,
        r.max_truth_error_after_transient_pct
            .map_or(String::new(), |t| format!(
                " (against the simulated truth {t:.2} %)"
            ))
    );
    outln!(
        "  NMSE (Eq. 6.4): nominal model {:.3e}, fitted {:.3e}",
        r.nmse_nominal,
        r.nmse_final
    );
    if let Some(dir) = &a.out {
        outln!("wrote {}", dir.join("report.html").display());
    }
    Ok(())
}

fn coefficient_index(name: &str) -> usize {
    REGRESSION_PARAMS
        .iter()
        .position(|p| *p == name)
        .unwrap_or(0)
}

/// Write the friction-fit section of a report (and its SVG into `dir`).
pub fn fit_report_section(
    rep: &mut Report,
    r: &FrictionFit,
    cfg: &FrictionFitConfig,
    dir: &Path,
) -> Result<()> {
    rep.section("Engine friction characterisation (thesis §7.3)");
    rep.para(
        &format!(
            "{} steady motored cycles ({} skipped at speed or throttle steps); motoring torque from {}. \
             Identifiability of the regression coefficients c1 … c20 (Alg. 5.1, thesis scaling), then \
             DSFC (λ = {}, S0 = {}·I in relative coordinates) on the estimable ones, the rest fixed at \
             their nominal values.",
            r.data.len(),
            r.data.skipped_unsteady,
            match cfg.source {
                TorqueSource::Engine => "the engine load cell (−torque_engine)",
                TorqueSource::Shaft => "the shaft transducer",
            },
            cfg.lambda,
            cfg.s0
        ),
        None,
    );
    for d in &r.dropouts {
        rep.para(&d.message(), Some("note"));
    }
    let glossary = report::Glossary {
        names: &REGRESSION_PARAMS,
        units: &REGRESSION_UNITS,
        descriptions: &REGRESSION_DESCRIPTIONS,
    };
    rep.ranking(
        &r.ranking,
        glossary,
        "Identifiability of c1 … c20: residual profile (Alg. 5.1)",
        &dir.join("friction_fit_residuals.svg"),
    )?;
    rep.table(
        &[
            "coefficient",
            "unit",
            "meaning",
            "nominal",
            "final",
            "change",
            "std error",
        ],
        &r.estimable
            .iter()
            .map(|n| {
                let j = coefficient_index(n);
                let (unit, meaning) = glossary.of(n);
                vec![
                    n.clone(),
                    unit,
                    meaning,
                    format!("{:.4e}", r.nominal[j]),
                    format!("{:.4e}", r.params[j]),
                    format!(
                        "{:+.1} %",
                        100.0 * (r.params[j] - r.nominal[j]) / r.nominal[j]
                    ),
                    r.std_err[j].map_or("—".into(), |s| format!("{s:.3e}")),
                ]
            })
            .collect::<Vec<_>>(),
    );
    // The headline is what a user has: the error against the measured cycle means; the
    // simulated truth, when the recording carries it, comes second.
    let truth = r.max_truth_error_after_transient_pct.map_or(String::new(), |t| {
        format!(
            " Against the simulated friction (known here, not in a real test): at most {t:.2} %; the ±{} % objective is judged on it, since the measured means carry the sensors' noise.",
            physid_apps::friction_fit::OBJECTIVE_PCT
        )
    });
    rep.para(
        &format!(
            "Prediction error against the measured cycle means after the {} s start-up transient: at most {:.2} % (final {:+.2} %); NMSE {:.3e} (nominal) → {:.3e} (fitted).{truth}",
            cfg.transient_s,
            r.max_error_after_transient_pct,
            r.final_error_pct,
            r.nmse_nominal,
            r.nmse_final
        ),
        Some(if r.objective_met() { "ok" } else { "alarm" }),
    );
    let svg = dir.join("friction_fit.svg");
    let mut torque = vec![
        Series {
            name: "measured".into(),
            x: &r.data.t_s,
            y: &r.data.tau_nm,
            color: PALETTE[1],
            reference: true,
        },
        Series {
            name: "nominal model".into(),
            x: &r.data.t_s,
            y: &r.predicted_nominal,
            color: PALETTE[4],
            reference: false,
        },
        Series {
            name: "predicted (DSFC)".into(),
            x: &r.data.t_s,
            y: &r.predicted,
            color: PALETTE[0],
            reference: false,
        },
    ];
    if let Some(tr) = &r.data.truth_nm {
        torque.push(Series {
            name: "simulated truth".into(),
            x: &r.data.t_s,
            y: tr,
            color: PALETTE[2],
            reference: true,
        });
    }
    let errors = vec![Series {
        name: "prediction error vs measured".into(),
        x: &r.data.t_s,
        y: &r.error_pct,
        color: PALETTE[0],
        reference: false,
    }];
    // The error axis is set by the error after the start-up transient (the estimator's first
    // cycles, from the nominal coefficients, are clipped at the frame) and the objective.
    let t0 = r.data.t_s.first().copied().unwrap_or(0.0);
    let after: Vec<f64> = r
        .data
        .t_s
        .iter()
        .zip(&r.error_pct)
        .filter(|(t, e)| **t - t0 >= cfg.transient_s && e.is_finite())
        .map(|(_, e)| *e)
        .collect();
    let objective = format!("objective ±{OBJECTIVE_PCT} %");
    let error_marks = vec![
        plot::Mark::value(objective.as_str(), OBJECTIVE_PCT, PALETTE[3]),
        plot::Mark::value(objective.as_str(), -OBJECTIVE_PCT, PALETTE[3]),
        plot::Mark::instant(
            "end of start-up transient",
            t0 + cfg.transient_s,
            plot::REFERENCE,
        ),
    ];
    let error_range = (
        after.iter().copied().fold(-OBJECTIVE_PCT, f64::min) * 1.2,
        after.iter().copied().fold(OBJECTIVE_PCT, f64::max) * 1.2,
    );
    let inputs = vec![Series {
        name: "speed [rpm]".into(),
        x: &r.data.t_s,
        y: &r.data.n_rpm,
        color: PALETTE[2],
        reference: false,
    }];
    let p_int = vec![Series {
        name: "manifold pressure [kPa]".into(),
        x: &r.data.t_s,
        y: &r.data.p_int_kpa,
        color: PALETTE[4],
        reference: false,
    }];
    plot::panels(
        &svg,
        "Cycle-mean friction torque: measured and predicted",
        "time [s]",
        &[
            Panel {
                ylabel: "friction torque [N·m]".into(),
                series: torque,
                ..Default::default()
            },
            Panel {
                ylabel: "error [%]".into(),
                series: errors,
                marks: error_marks,
                y_range: Some(error_range),
            },
            Panel {
                ylabel: "N [rpm]".into(),
                series: inputs,
                ..Default::default()
            },
            Panel {
                ylabel: "p_int [kPa]".into(),
                series: p_int,
                ..Default::default()
            },
        ],
    )?;
    rep.svg(&svg)
}

/// `--tracks`: a row per steady cycle (see the flag).
fn write_tracks(path: &Path, r: &FrictionFit) -> Result<()> {
    let d = &r.data;
    let truth = d.truth_nm.is_some();
    let mut columns: Vec<(String, String)> = [
        ("t", "s"),
        ("cycle", "-"),
        ("n", "rpm"),
        ("p_int", "kPa"),
        ("p_atm", "kPa"),
        ("T_oil", "degC"),
        ("measured", "N*m"),
        ("predicted", "N*m"),
        ("nominal", "N*m"),
    ]
    .iter()
    .map(|(n, u)| (n.to_string(), u.to_string()))
    .collect();
    if truth {
        columns.push(("truth".into(), "N*m".into()));
    }
    columns.extend(r.estimable.iter().map(|c| (c.clone(), String::new())));
    columns.extend(
        r.estimable
            .iter()
            .map(|c| (format!("{c}_std_err"), String::new())),
    );
    let mut f = crate::tracks::TrackFile::create(path, columns)?;
    for c in &r.cycles {
        let k = d
            .cycle
            .iter()
            .position(|&x| x == c.cycle)
            .ok_or_else(|| miette!("cycle {} is not among the cycle means", c.cycle))?;
        let mut row = vec![
            c.t_s,
            c.cycle as f64,
            d.n_rpm[k],
            d.p_int_kpa[k],
            d.p_atm_kpa[k],
            d.t_oil_c[k],
            c.measured_nm,
            c.predicted_nm,
            c.nominal_nm,
        ];
        if truth {
            row.push(c.truth_nm.unwrap_or(f64::NAN));
        }
        row.extend(&c.params);
        row.extend(&c.std_err);
        f.row(row)?;
    }
    f.close()
}
