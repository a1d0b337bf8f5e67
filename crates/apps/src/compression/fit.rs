//! The fit over all the TDCs at once, per TDC and recursively ([`compression_fit_events`]).

use super::*;

/// The fit over the TDCs' windows (steps 2–5 of the module's doc), a pass over them for the
/// starting values, one per Gauss–Newton iteration and one for the fit per event.
pub fn compression_fit_events(
    events: &TdcEvents,
    cfg: &CompressionConfig,
) -> Result<CompressionFit, AppError> {
    cfg.validate()?;
    // The first pass: the pressures the starting values take, per TDC.
    let (mut p_a, mut p_max, mut a0) = (Vec::new(), Vec::new(), f64::NAN);
    events.each::<AppError>(&mut |w| {
        p_a.push(w.p[0]);
        p_max.push(w.p.iter().copied().fold(f64::MIN, f64::max));
        a0 = w.atdc[0];
        Ok(())
    })?;
    let FirstPass {
        unit,
        mut notes,
        rows,
        events: n_events,
    } = events.first_pass()?;
    if p_a.is_empty() {
        return Err(AppError::Invalid(format!(
            "no motored firing TDC with the whole window {}° … {}° ATDC of '{}' in the recording{}",
            cfg.window_deg.0,
            cfg.window_deg.1,
            cfg.channel,
            if notes.is_empty() {
                String::new()
            } else {
                format!(" ({})", notes.join("; "))
            }
        )));
    }
    let model = Motored::new(cfg.stroke, cfg.rod);
    let mut start = start_values(p_a, p_max, a0, &model);
    for (name, v) in &cfg.held {
        let j = PARAMS.iter().position(|p| p == name).unwrap_or(0);
        start[j] = *v;
    }
    let held: Vec<usize> = cfg
        .held
        .iter()
        .filter_map(|(n, _)| PARAMS.iter().position(|p| p == n))
        .collect();
    let free: Vec<usize> = (0..PARAMS.len()).filter(|j| !held.contains(j)).collect();
    if free.is_empty() {
        return Err(AppError::Invalid(
            "every parameter is held with --set: nothing to fit".into(),
        ));
    }
    // All events at once: the windows as rows, a pass per Gauss–Newton iteration.
    let pooled = events;
    let full = fit_subset(&model, pooled, &start, &free, 100)?;
    // The ranking at nominal values, as the thesis ranks: the starting values with the three
    // that start at 0 (and so would have no relative sensitivity) at a typical size — the Wu
    // criterion fits the top K from there (from the full fit, every K would fit alike).
    let nominal = nominal_values(&start, &held);
    let analysis = analyse(&model, pooled, &nominal, &free, IdentConfig::default())?;
    let (k, wu) = cfg.selection.resolve(&model, pooled, &analysis)?;
    let ranking = analysis.ranked(k);
    let mut fitted: Vec<usize> = analysis.top(k).iter().map(|&i| free[i]).collect();
    fitted.sort_unstable();
    if fitted.is_empty() {
        return Err(AppError::Invalid(
            "the identifiability analysis finds no parameter the data resolve".into(),
        ));
    }
    let collinearity = analysis.collinearity(
        &fitted
            .iter()
            .filter_map(|j| free.iter().position(|f| f == j))
            .collect::<Vec<_>>(),
    );
    let dof = rows.saturating_sub(free.len()).max(1);
    let confounded = quantify(
        &full.gram,
        (full.rss / dof as f64).max(f64::MIN_POSITIVE),
        &free.iter().map(|&j| full.theta[j]).collect::<Vec<_>>(),
        rows,
    )
    .ok()
    .map(|q| {
        let mut pairs = Vec::new();
        for a in 0..free.len() {
            for b in a + 1..free.len() {
                let r = q.correlation[(a, b)];
                if r.abs() > 0.95 {
                    pairs.push(Confounded {
                        a: PARAMS[free[a]].into(),
                        b: PARAMS[free[b]].into(),
                        correlation: r,
                    });
                }
            }
        }
        pairs
    });
    // The fitted set on all events, the rest at their starting values: where each event starts.
    let pooled_fit = fit_subset(&model, pooled, &start, &fitted, 100)?;
    let kf = fitted.len();
    let mut info = DMatrix::<f64>::zeros(kf, kf);
    let mut fused: Option<Vec<f64>> = None;
    let mut fused_se = vec![f64::NAN; kf];
    let mut fits = Vec::with_capacity(n_events);
    let mut rss_total = 0.0;
    let mut engine = GradientEngine::new(PARAMS.len());
    let mut g = vec![0.0; kf];
    // The last TDC fitted: its cycle, angles and pressures.
    let mut last = (0_i64, Vec::new(), Vec::new());
    events.each::<AppError>(&mut |e| {
        let (atdc, p) = (e.atdc, e.p);
        let f = fit_subset(&model, &data(atdc, p), &pooled_fit.theta, &fitted, 50)?;
        rss_total += f.rss;
        let n = atdc.len();
        let sigma2 = (f.rss / n.saturating_sub(kf).max(1) as f64).max(f64::MIN_POSITIVE);
        let values: Vec<f64> = fitted.iter().map(|&j| f.theta[j]).collect();
        let Ok(q) = quantify(&f.gram, sigma2, &values, n) else {
            notes.push(format!(
                "the TDC of cycle {} (t = {:.4} s): the fitted parameters' information is singular there; left out",
                e.cycle, e.t_s
            ));
            return Ok(());
        };
        // Recursive Gauss–Newton: the first TDC's own fit, then each TDC linearised at the
        // estimate so far.
        let theta = match fused.take() {
            None => {
                info = q.fim.clone();
                f.theta.clone()
            }
            Some(mut th) => {
                let mut jtj = DMatrix::<f64>::zeros(kf, kf);
                let mut jtr = DVector::<f64>::zeros(kf);
                for (&a, &y) in atdc.iter().zip(p) {
                    let h = engine.value_and_gradient(&model, &[a], &th, &fitted, &mut g);
                    let gv = DVector::from_column_slice(&g);
                    jtj += &gv * gv.transpose();
                    jtr += gv * (y - h);
                }
                info += jtj / sigma2;
                if let Some(ch) = info.clone().cholesky() {
                    let step = ch.solve(&(jtr / sigma2));
                    for (i, &j) in fitted.iter().enumerate() {
                        th[j] += step[i];
                    }
                }
                th
            }
        };
        if let Some(ch) = info.clone().cholesky() {
            let cov = ch.inverse();
            for (i, se) in fused_se.iter_mut().enumerate() {
                *se = cov[(i, i)].sqrt();
            }
        }
        let fused_now: Vec<f64> = fitted.iter().map(|&j| theta[j]).collect();
        fused = Some(theta);
        fits.push(EventFit {
            cycle: e.cycle,
            t_s: e.t_s,
            rpm: e.rpm,
            values,
            std_err: q.std_err.clone(),
            recursive: fused_now,
            recursive_std_err: fused_se.clone(),
            rms_residual: (f.rss / n as f64).sqrt(),
        });
        last.0 = e.cycle;
        last.1.clear();
        last.1.extend_from_slice(atdc);
        last.2.clear();
        last.2.extend_from_slice(p);
        Ok(())
    })?;
    if fused.is_none() {
        return Err(AppError::Invalid(
            "no TDC could be fitted: every event's information is singular".into(),
        ));
    };
    // The estimate: the fit over all the TDCs at once, its intervals from their information.
    let batch_values: Vec<f64> = fitted.iter().map(|&j| pooled_fit.theta[j]).collect();
    let batch = quantify(
        &pooled_fit.gram,
        (pooled_fit.rss / rows.saturating_sub(kf).max(1) as f64).max(f64::MIN_POSITIVE),
        &batch_values,
        rows,
    )?;
    let estimates = (0..PARAMS.len())
        .map(|j| {
            let base = ParamEstimate {
                name: PARAMS[j].into(),
                unit: if UNITS[j] == "P" {
                    unit.clone()
                } else {
                    UNITS[j].into()
                },
                description: DESCRIPTIONS[j].into(),
                status: if held.contains(&j) {
                    "held"
                } else {
                    "unresolved"
                },
                value: start[j],
                std_err: None,
                ci95: None,
                between_events_std_err: None,
            };
            match fitted.iter().position(|&f| f == j) {
                None => base,
                Some(i) => {
                    let v = pooled_fit.theta[j];
                    let per: Vec<f64> = fits.iter().map(|f| f.values[i]).collect();
                    let m = per.len() as f64;
                    let between = (per.len() >= 2).then(|| {
                        let mean = per.iter().sum::<f64>() / m;
                        (per.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (m - 1.0) / m).sqrt()
                    });
                    ParamEstimate {
                        status: "fitted",
                        value: v,
                        std_err: Some(batch.std_err[i]),
                        ci95: Some(batch.ci95[i]),
                        between_events_std_err: between,
                        ..base
                    }
                }
            }
        })
        .collect::<Vec<_>>();
    let theta: Vec<f64> = estimates.iter().map(|e| e.value).collect();
    let (cycle, atdc, measured) = last;
    let trace = Trace {
        cycle,
        fitted: atdc
            .iter()
            .map(|&a| model.eval::<f64>(&[a], &theta))
            .collect(),
        atdc,
        measured,
    };
    let wu_j = wu.map(|(_, j)| j);
    let implausible: Vec<String> = cfg
        .plausible
        .iter()
        .filter_map(|(name, lo, hi)| {
            let e = estimates.iter().find(|e| &e.name == name)?;
            (e.status == "fitted" && !(*lo..=*hi).contains(&e.value)).then(|| {
                format!(
                    "{name} = {} is outside {lo} … {hi} ({}): not the engine's — the trace does not resolve it, or the cycles are not motored (hold it: --fix {name}=VALUE{}; or widen: --plausible {name}=LO,HI)",
                    e.value,
                    e.description,
                    if name == "eps" { ", or --compression-ratio" } else { "" }
                )
            })
        })
        .collect();
    notes.extend(implausible.iter().map(|w| format!("not physical: {w}")));
    Ok(CompressionFit {
        channel: cfg.channel.clone(),
        unit,
        window_deg: cfg.window_deg,
        start,
        ranking,
        wu_j,
        confounded,
        collinearity,
        fitted: fitted.iter().map(|&j| PARAMS[j].to_string()).collect(),
        peak_deg: peak_angle(&model, &theta),
        estimates,
        events: fits,
        rms_residual: (rss_total / rows as f64).sqrt(),
        trace,
        implausible,
        notes,
    })
}
