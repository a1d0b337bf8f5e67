//! `physid estimate`: recursive estimation of a linear regression `y = φᵀϑ` from a CSV file.

use crate::out::outln;
use miette::{miette, IntoDiagnostic, Result, WrapErr};
use physid_core::{Basis, Channel, ParamSet, Recording};
use physid_estim::{
    metrics, CovSpec, EstimError, EstimatorConfig, GuardAction, LinearEstimator, Method, VfVariant,
    WindupGuard,
};
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `physid estimate`.
#[derive(clap::Args)]
pub struct Args {
    /// CSV file: a header row of column names, then one row per sample.
    #[arg(long)]
    pub data: PathBuf,
    /// The file's second row holds units.
    #[arg(long)]
    pub units_row: bool,
    /// Column of the measured output y.
    #[arg(long)]
    pub y: String,
    /// Columns of the regressor φ, comma separated; they name the parameters.
    #[arg(long, value_delimiter = ',', required = true)]
    pub phi: Vec<String>,
    /// Estimator: rls, rlsf (constant or, with --lambda0, time-varying λ), rlsvf, kf, dsfc.
    #[arg(long, default_value = "rlsf")]
    pub method: String,
    /// Forgetting factor λ ∈ (0, 1] (rlsf, dsfc; with --lambda0 it is λ(0)) [default: 0.98].
    #[arg(long)]
    pub lambda: Option<f64>,
    /// Time-varying forgetting λ(t) = λ0·λ(t−1) + 1 − λ0 (Eq. 5.24) for rlsf.
    #[arg(long)]
    pub lambda0: Option<f64>,
    /// Per-parameter forgetting factors for rlsvf, in --phi order.
    #[arg(long, value_delimiter = ',')]
    pub lambdas: Option<Vec<f64>>,
    /// Vector-forgetting form: published (thesis Alg. 5.4) or symmetric.
    #[arg(long, default_value = "published")]
    pub vf_variant: String,
    /// Initial covariance P0 = C·I.
    #[arg(long, default_value_t = 1000.0)]
    pub p0: f64,
    /// Initial (nominal) values, in --phi order [default: all 0].
    #[arg(long, value_delimiter = ',')]
    pub theta0: Option<Vec<f64>>,
    /// Estimate only these parameters; the others stay at their --theta0 values.
    #[arg(long, value_delimiter = ',')]
    pub free: Option<Vec<String>>,
    /// Kalman: parameter random-walk variance, R1 = X·I.
    #[arg(long, default_value_t = 0.0)]
    pub r1: f64,
    /// Kalman: measurement noise variance R2.
    #[arg(long, default_value_t = 1.0)]
    pub r2: f64,
    /// Wind-up guard: bound on trace(P).
    #[arg(long)]
    pub max_trace: Option<f64>,
    /// Wind-up guard action beyond the bound: scale or reset.
    #[arg(long, default_value = "scale")]
    pub guard: String,
    /// Samples with NaN/inf: error (stop and report) or skip (count them).
    #[arg(long, default_value = "error")]
    pub on_bad: String,
    /// Write the estimates, standard errors and prediction error of every sample to this CSV.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the result as JSON.
    #[arg(long)]
    pub json: bool,
}

fn method(args: &Args, p: usize) -> Result<Method> {
    let lambda = args.lambda.unwrap_or(0.98);
    Ok(match args.method.as_str() {
        "rls" => Method::Rls,
        "rlsf" => match args.lambda0 {
            Some(lambda0) => Method::RlsfTv {
                lambda0,
                lambda_init: lambda,
            },
            None => Method::Rlsf { lambda },
        },
        "rlsvf" => Method::Rlsvf {
            lambdas: match &args.lambdas {
                Some(l) => l.clone(),
                None => vec![lambda; p],
            },
            variant: match args.vf_variant.as_str() {
                "published" => VfVariant::Published,
                "symmetric" => VfVariant::Symmetric,
                v => {
                    return Err(miette!(
                        "--vf-variant '{v}': expected published or symmetric"
                    ))
                }
            },
        },
        "kf" => Method::Kalman {
            r1: CovSpec::Scaled(args.r1),
            r2: args.r2,
        },
        "dsfc" => Method::Dsfc { lambda },
        m => {
            return Err(miette!(
                "unknown method '{m}'; the methods are: rls, rlsf, rlsvf, kf, dsfc"
            ))
        }
    })
}

/// Run the estimation.
pub fn run(args: &Args) -> Result<()> {
    let skip_bad = match args.on_bad.as_str() {
        "error" => false,
        "skip" => true,
        v => return Err(miette!("--on-bad '{v}': expected error or skip")),
    };
    let opts = physid_io::CsvOptions {
        units_row: args.units_row,
        ..Default::default()
    };
    let rec = physid_io::read_csv(&args.data, &opts).into_diagnostic()?;
    let file = args.data.display().to_string();
    let y = rec.values(&args.y).map_err(|e| miette!("{file}: {e}"))?;
    let cols: Vec<&[f64]> = args
        .phi
        .iter()
        .map(|c| rec.values(c).map_err(|e| miette!("{file}: {e}")))
        .collect::<Result<_>>()?;
    let p = cols.len();
    let theta0 = args.theta0.clone().unwrap_or_else(|| vec![0.0; p]);
    let params = ParamSet::new(args.phi.clone(), theta0).into_diagnostic()?;
    let free = match &args.free {
        Some(names) => params.free(names).into_diagnostic()?,
        None => params.all_free(),
    };
    let guard = match args.max_trace {
        None => None,
        Some(max_trace) => Some(WindupGuard {
            max_trace,
            action: match args.guard.as_str() {
                "scale" => GuardAction::Scale,
                "reset" => GuardAction::Reset,
                v => return Err(miette!("--guard '{v}': expected scale or reset")),
            },
        }),
    };
    let cfg = EstimatorConfig {
        method: method(args, free.free().len())?,
        p0: CovSpec::Scaled(args.p0),
        guard,
    };
    let mut est = LinearEstimator::new(&cfg, &params, &free).into_diagnostic()?;
    let nfree = free.free().len();

    // Line of sample i in the file: header, optional units row, 1-based.
    let line = |i: usize| i + 2 + usize::from(args.units_row);
    let n = y.len();
    let mut phi = vec![0.0; p];
    let mut measured = Vec::with_capacity(n);
    let mut predicted = Vec::with_capacity(n);
    let mut track: Vec<Vec<f64>> = vec![Vec::new(); 2 * nfree + 2];
    let mut se = vec![0.0; nfree];
    let mut skipped = 0usize;
    for i in 0..n {
        for (f, c) in phi.iter_mut().zip(&cols) {
            *f = c[i];
        }
        match est.update(&phi, y[i]) {
            Ok(step) => {
                measured.push(y[i]);
                predicted.push(y[i] - step.prediction_error);
                if args.out.is_some() {
                    let ok = est.std_errors_into(&mut se).is_ok();
                    track[0].push(y[i] - step.prediction_error);
                    track[1].push(step.prediction_error);
                    for j in 0..nfree {
                        track[2 + j].push(est.estimate()[j]);
                        track[2 + nfree + j].push(if ok { se[j] } else { f64::NAN });
                    }
                }
            }
            Err(EstimError::NonFinite { .. }) if skip_bad => skipped += 1,
            Err(EstimError::NonFinite { what, value, .. }) => {
                return Err(miette!(
                    "{file}, line {} (sample {i}): {what} is not finite ({value}); \
                     use --on-bad skip to skip such samples",
                    line(i)
                ))
            }
            Err(e) => return Err(miette!("{file}, line {} (sample {i}): {e}", line(i))),
        }
    }
    if est.samples() == 0 {
        return Err(miette!("{file}: no usable samples ({skipped} skipped)"));
    }
    let names = est.free_names();
    let theta = est.estimate().to_vec();
    let std_err = est.std_errors().ok();
    let nmse = metrics::nmse(&measured, &predicted);
    let nrmse = metrics::nrmse(&measured, &predicted);
    let fit = metrics::fit_percent(&measured, &predicted);

    if let Some(out) = &args.out {
        let mut r = Recording::new(Basis::Time);
        let mut cols: Vec<(String, Vec<f64>)> = vec![
            ("y_predicted".into(), std::mem::take(&mut track[0])),
            ("prediction_error".into(), std::mem::take(&mut track[1])),
        ];
        for (j, nm) in names.iter().enumerate() {
            cols.push(((*nm).to_string(), std::mem::take(&mut track[2 + j])));
        }
        for (j, nm) in names.iter().enumerate() {
            cols.push((
                format!("{nm}_std_err"),
                std::mem::take(&mut track[2 + nfree + j]),
            ));
        }
        for (name, values) in cols {
            r.push(Channel {
                name,
                unit: String::new(),
                values,
            })
            .into_diagnostic()?;
        }
        physid_io::write_csv(out, &r)
            .into_diagnostic()
            .wrap_err("writing --out")?;
    }

    if args.json {
        let params: serde_json::Map<_, _> = params
            .names()
            .iter()
            .zip(est.estimate_full())
            .map(|(k, v)| (k.clone(), json!(v)))
            .collect();
        let se: serde_json::Map<_, _> = names
            .iter()
            .enumerate()
            .map(|(j, k)| (k.to_string(), json!(std_err.as_ref().map(|s| s[j]))))
            .collect();
        let out = json!({
            "method": cfg.method.name(),
            "samples": est.samples(),
            "skipped": skipped,
            "params": params,
            "std_err": se,
            "nmse": nmse,
            "nrmse": nrmse,
            "fit_percent": fit,
        });
        outln!("{}", serde_json::to_string_pretty(&out).into_diagnostic()?);
        return Ok(());
    }
    outln!(
        "{} on {file}: {} samples{}",
        cfg.method.name(),
        est.samples(),
        if skipped > 0 {
            format!(", {skipped} skipped (non-finite)")
        } else {
            String::new()
        }
    );
    outln!(
        "{:<16} {:>16} {:>14}",
        "parameter",
        "estimate",
        "std. error"
    );
    for (j, nm) in names.iter().enumerate() {
        let s = std_err
            .as_ref()
            .map_or("-".to_string(), |s| format!("{:.6e}", s[j]));
        outln!("{nm:<16} {:>16.8e} {s:>14}", theta[j]);
    }
    for i in free.fixed() {
        outln!(
            "{:<16} {:>16.8e} {:>14}",
            params.names()[*i],
            params.nominal()[*i],
            "(fixed)"
        );
    }
    let show = |v: Option<f64>| v.map_or("undefined".to_string(), |v| format!("{v:.4e}"));
    outln!(
        "one-step prediction: NMSE {} (Eq. 6.4), NRMSE {}, fit {}",
        show(nmse),
        show(nrmse),
        fit.map_or("undefined".to_string(), |v| format!("{v:.2} %"))
    );
    Ok(())
}
