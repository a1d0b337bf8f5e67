//! `physid cycles --out DIR`: the combustion report — the summary and notes, the pressure, heat
//! release rate and mass fraction burned of the ensemble mean cycle and a chosen one against
//! crank angle, their p–V and log p–log V diagrams, and the per-cycle trends (IMEP, MFB50,
//! p_max, and with knock MAPO against its threshold) — beside `cycles.json` and `tracks.csv`.

use crate::plot::{self, Mark, Panel, Series, PALETTE};
use crate::report::Report;
use miette::Result;
use physid_apps::pressure::{CycleAnalysis, CycleCurve, CycleCurves};
use std::path::Path;

/// The report's sections on `a`, its figures in `dir`; `knock_threshold_pa` when knock was
/// asked for.
pub fn report(
    rep: &mut Report,
    a: &CycleAnalysis,
    dir: &Path,
    knock_threshold_pa: Option<f64>,
) -> Result<()> {
    rep.section("Summary");
    let opt = |v: Option<f64>, scale: f64, d: usize| {
        v.map_or("–".to_string(), |v| format!("{:.*}", d, v * scale))
    };
    let fired = a
        .cycles
        .iter()
        .filter(|c| c.burn.as_ref().is_some_and(|b| b.fired))
        .count();
    let flagged = |f: fn(&physid_apps::combustion::Burn) -> bool| {
        a.cycles
            .iter()
            .filter(|c| c.burn.as_ref().is_some_and(f))
            .count()
    };
    let mut rows = vec![
        vec!["cycles".into(), a.cycles.len().to_string()],
        vec!["fired".into(), fired.to_string()],
        vec!["misfires".into(), flagged(|b| b.misfire).to_string()],
        vec![
            "partial burns".into(),
            flagged(|b| b.partial_burn).to_string(),
        ],
        vec!["CoV of IMEP [%]".into(), opt(a.cov_imep, 100.0, 2)],
        vec!["LNV of IMEP [%]".into(), opt(a.lnv_imep, 100.0, 1)],
    ];
    if let Some(m) = &a.mean_cycle {
        let b = m.burn.as_ref();
        rows.extend([
            vec![
                format!("mean cycle ({} averaged): IMEP [bar]", m.cycle),
                opt(m.imep_pa, 1e-5, 3),
            ],
            vec!["mean cycle: PMEP [bar]".into(), opt(m.pmep_pa, 1e-5, 3)],
            vec![
                format!("mean cycle: p_max [{}]", a.unit),
                format!("{:.5e}", m.p_max),
            ],
            vec![
                "mean cycle: p_max at [deg ATDC]".into(),
                format!("{:.2}", m.p_max_deg),
            ],
            vec![
                "mean cycle: heat released [J]".into(),
                opt(b.map(|b| b.heat_release_j), 1.0, 1),
            ],
            vec![
                "mean cycle: MFB50 [deg ATDC]".into(),
                opt(b.and_then(|b| b.mfb(50.0)), 1.0, 2),
            ],
        ]);
    }
    if let Some(k) = knock_threshold_pa {
        let knocked = a
            .cycles
            .iter()
            .filter(|c| c.knock.is_some_and(|k| k.knock))
            .count();
        rows.push(vec![
            format!("knocking (MAPO > {:.2} bar)", k * 1e-5),
            knocked.to_string(),
        ]);
    }
    rep.table(&["", "value"], &rows);
    for n in &a.notes {
        rep.para(n, Some("note"));
    }
    for d in &a.dropouts {
        rep.para(&d.message(), Some("note"));
    }
    if let Some(c) = &a.curves {
        curves(rep, c, &a.unit, dir)?;
    }
    trends(rep, a, dir, knock_threshold_pa)
}

/// The mean and the chosen cycle against crank angle and volume.
fn curves(rep: &mut Report, c: &CycleCurves, unit: &str, dir: &Path) -> Result<()> {
    let cycles: Vec<(&str, &CycleCurve)> = [("mean", &c.mean), ("cycle", &c.chosen)]
        .into_iter()
        .filter_map(|(n, c)| c.as_ref().map(|c| (n, c)))
        .collect();
    let label = |n: &str, c: &CycleCurve| {
        if n == "mean" {
            format!("mean of {} cycles", c.cycle)
        } else {
            format!("cycle {}", c.cycle)
        }
    };
    let in_pa = unit == "Pa";
    let (p_scale, p_unit) = if in_pa { (1e-5, "bar") } else { (1.0, unit) };
    let scaled: Vec<Vec<f64>> = cycles
        .iter()
        .map(|(_, k)| k.p.iter().map(|p| p * p_scale).collect())
        .collect();
    // The heat release rate (central differences) and the burned fraction of each.
    let rate_and_fraction = |q: &[f64]| -> (Vec<f64>, Vec<f64>) {
        let a = &c.heat_deg;
        let n = q.len().min(a.len());
        if n == 0 {
            // No heat release (no geometry given): nothing to draw.
            return (Vec::new(), Vec::new());
        }
        let rate = (0..n)
            .map(|k| {
                let (i, j) = (k.saturating_sub(1), (k + 1).min(n - 1));
                if j > i {
                    (q[j] - q[i]) / (a[j] - a[i])
                } else {
                    0.0
                }
            })
            .collect();
        let k_max = (0..n).max_by(|&i, &j| q[i].total_cmp(&q[j])).unwrap_or(0);
        let q_min = q[..=k_max.min(n.saturating_sub(1))]
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        let span = q.get(k_max).map_or(1.0, |m| m - q_min);
        let fraction = (0..n)
            .map(|k| {
                if k <= k_max {
                    ((q[k] - q_min) / span).max(0.0)
                } else {
                    1.0
                }
            })
            .collect();
        (rate, fraction)
    };
    let heat: Vec<(Vec<f64>, Vec<f64>)> = cycles
        .iter()
        .map(|(_, k)| rate_and_fraction(&k.heat))
        .collect();
    let mut pressure = Panel {
        ylabel: format!("p [{p_unit}]"),
        ..Default::default()
    };
    let mut rate = Panel {
        ylabel: "dQ/dθ [J/deg]".into(),
        ..Default::default()
    };
    let mut burned = Panel {
        ylabel: "mass fraction burned [-]".into(),
        ..Default::default()
    };
    for (k, (n, cyc)) in cycles.iter().enumerate() {
        let color = PALETTE[k];
        pressure.series.push(Series {
            name: label(n, cyc),
            x: &c.atdc,
            y: &scaled[k],
            color,
            reference: false,
        });
        if !cyc.heat.is_empty() {
            let m = heat[k].0.len();
            rate.series.push(Series {
                name: label(n, cyc),
                x: &c.heat_deg[..m],
                y: &heat[k].0,
                color,
                reference: false,
            });
            burned.series.push(Series {
                name: label(n, cyc),
                x: &c.heat_deg[..m],
                y: &heat[k].1,
                color,
                reference: false,
            });
        }
    }
    for v in [0.1, 0.5, 0.9] {
        burned
            .marks
            .push(Mark::value(format!("{:.0} %", v * 100.0), v, PALETTE[4]));
    }
    let mut panels = vec![pressure];
    let title = if rate.series.is_empty() {
        "Pressure (no heat release without the engine's geometry)"
    } else {
        panels.extend([rate, burned]);
        "Pressure, heat release rate and mass fraction burned"
    };
    rep.section("The mean cycle and a chosen one");
    let svg = dir.join("cycles_crank_angle.svg");
    plot::panels(&svg, title, "crank angle [deg ATDC]", &panels)?;
    rep.svg(&svg)?;
    if c.volume.len() == c.atdc.len() {
        let v_cm3: Vec<f64> = c.volume.iter().map(|v| v * 1e6).collect();
        let ln_v: Vec<f64> = c.volume.iter().map(|v| v.ln()).collect();
        let ln_p: Vec<Vec<f64>> = cycles
            .iter()
            .map(|(_, k)| {
                k.p.iter()
                    .map(|p| if *p > 0.0 { p.ln() } else { f64::NAN })
                    .collect()
            })
            .collect();
        let mut p_v = Panel {
            ylabel: format!("p [{p_unit}]"),
            ..Default::default()
        };
        let mut log_pv = Panel {
            ylabel: "ln p".into(),
            ..Default::default()
        };
        for (k, (n, cyc)) in cycles.iter().enumerate() {
            p_v.series.push(Series {
                name: label(n, cyc),
                x: &v_cm3,
                y: &scaled[k],
                color: PALETTE[k],
                reference: false,
            });
            log_pv.series.push(Series {
                name: label(n, cyc),
                x: &ln_v,
                y: &ln_p[k],
                color: PALETTE[k],
                reference: false,
            });
        }
        let svg = dir.join("cycles_pv.svg");
        plot::panels(&svg, "p–V diagram", "V [cm³]", &[p_v])?;
        rep.svg(&svg)?;
        let svg = dir.join("cycles_log_pv.svg");
        plot::panels(
            &svg,
            "log p – log V (the polytropes are straight lines)",
            "ln (V / m³)",
            &[log_pv],
        )?;
        rep.svg(&svg)?;
    }
    Ok(())
}

/// A panel of one curve.
fn one<'a>(
    ylabel: &str,
    name: &str,
    x: &'a [f64],
    y: &'a [f64],
    color: plotters::style::RGBColor,
) -> Panel<'a> {
    Panel {
        ylabel: ylabel.into(),
        series: vec![Series {
            name: name.into(),
            x,
            y,
            color,
            reference: false,
        }],
        ..Default::default()
    }
}

/// IMEP, MFB50, p_max (and MAPO) per cycle.
fn trends(rep: &mut Report, a: &CycleAnalysis, dir: &Path, knock: Option<f64>) -> Result<()> {
    if a.cycles.is_empty() {
        return Ok(());
    }
    let x: Vec<f64> = a.cycles.iter().map(|c| c.cycle as f64).collect();
    let nan = |v: Option<f64>| v.unwrap_or(f64::NAN);
    let imep: Vec<f64> = a.cycles.iter().map(|c| nan(c.imep_pa) * 1e-5).collect();
    let mfb50: Vec<f64> = a
        .cycles
        .iter()
        .map(|c| nan(c.burn.as_ref().and_then(|b| b.mfb(50.0))))
        .collect();
    let in_pa = a.unit == "Pa";
    let p_max: Vec<f64> = a
        .cycles
        .iter()
        .map(|c| c.p_max * if in_pa { 1e-5 } else { 1.0 })
        .collect();
    let mapo: Vec<f64> = a
        .cycles
        .iter()
        .map(|c| c.knock.map_or(f64::NAN, |k| k.mapo_pa * 1e-5))
        .collect();
    let mut panels = Vec::new();
    if imep.iter().any(|v| v.is_finite()) {
        panels.push(one("IMEP [bar]", "net IMEP", &x, &imep, PALETTE[0]));
    }
    if mfb50.iter().any(|v| v.is_finite()) {
        panels.push(one("MFB50 [deg ATDC]", "MFB50", &x, &mfb50, PALETTE[1]));
    }
    let unit = if in_pa { "bar" } else { a.unit.as_str() };
    panels.push(one(
        &format!("p_max [{unit}]"),
        "p_max",
        &x,
        &p_max,
        PALETTE[2],
    ));
    if let Some(threshold) = knock {
        let mut k = one("MAPO [bar]", "MAPO", &x, &mapo, PALETTE[3]);
        k.marks
            .push(Mark::value("knock threshold", threshold * 1e-5, PALETTE[4]));
        panels.push(k);
    }
    rep.section("Cycle by cycle");
    let svg = dir.join("cycles_trends.svg");
    plot::panels(&svg, "Per-cycle trends", "cycle", &panels)?;
    rep.svg(&svg)
}
