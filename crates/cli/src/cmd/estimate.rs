//! `physid estimate`: recursive estimation from a CSV file — a linear regression `y = φᵀϑ`
//! (rls, rlsf, rlsvf, kf, dsfc) or a model from an expression (ekf, ukf, srukf).

use super::named_values;
use crate::out::outln;
use miette::{miette, IntoDiagnostic, Result, WrapErr};
use physid_core::{Basis, Channel, ParamSet, Recording};
use physid_estim::resolution::resolution;
use physid_estim::{
    metrics, CovSpec, EstimError, EstimatorConfig, GuardAction, LinearEstimator, Method, NlConfig,
    NlMethod, NonlinearEstimator, SigmaPoints, Step, VfVariant, WindupGuard,
};
use physid_expr::ExprModel;
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `physid estimate`.
#[derive(clap::Args)]
pub struct Args {
    /// Recording (CSV with a header row, Parquet or MDF4).
    #[arg(long)]
    pub data: PathBuf,
    #[command(flatten)]
    pub input: super::InputArgs,
    /// Column of the measured output y.
    #[arg(long)]
    pub y: String,
    /// Linear methods: columns of the regressor φ, comma separated; they name the parameters.
    #[arg(long, value_delimiter = ',')]
    pub phi: Vec<String>,
    /// Non-linear methods: the model, e.g. 'A*exp(-B*x) + C*x'; names not in --params are
    /// data columns.
    #[arg(long)]
    pub expr: Option<String>,
    /// Non-linear methods: parameters with their initial (nominal) values, e.g. A=1,B=0.5.
    #[arg(long, value_delimiter = ',')]
    pub params: Vec<String>,
    /// Estimator: rls, rlsf (constant or, with --lambda0, time-varying λ), rlsvf, kf, dsfc;
    /// ekf, ukf, srukf for --expr models.
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
    /// Initial covariance P0 = C·I [default: 1000 for linear methods, 100 for ekf/ukf/srukf].
    #[arg(long)]
    pub p0: Option<f64>,
    /// Linear methods: initial (nominal) values, in --phi order [default: all 0].
    #[arg(long, value_delimiter = ',')]
    pub theta0: Option<Vec<f64>>,
    /// Estimate only these parameters; the others stay at their initial values.
    #[arg(long, value_delimiter = ',')]
    pub free: Option<Vec<String>>,
    /// Kalman-type methods (kf, ekf, ukf, srukf): parameter random-walk variance, R1 = X·I.
    #[arg(long, default_value_t = 0.0)]
    pub r1: f64,
    /// Kalman-type methods: measurement noise variance R2.
    #[arg(long, default_value_t = 1.0)]
    pub r2: f64,
    /// UKF sigma points: α [default: 1, the thesis's].
    #[arg(long, default_value_t = 1.0)]
    pub alpha: f64,
    /// UKF sigma points: β [default: 2].
    #[arg(long, default_value_t = 2.0)]
    pub beta: f64,
    /// UKF sigma points: κ [default: 3 − l, the thesis's].
    #[arg(long)]
    pub kappa: Option<f64>,
    /// Non-linear methods: estimate in scaled coordinates ϑ = ϑ0·(1 + x) (P0 then in relative
    /// units).
    #[arg(long)]
    pub scaled: bool,
    /// Non-linear methods: bound a parameter, NAME=LOW:HIGH (repeatable).
    #[arg(long)]
    pub bound: Vec<String>,
    /// Wind-up guard (linear methods): bound on trace(P).
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

/// What the command needs of a recursive estimator, whichever kind it is.
trait Online {
    /// Feed sample `i` of the recording.
    fn update(&mut self, i: usize) -> Result<Step, EstimError>;
    /// Free-parameter estimates.
    fn free_estimate(&self) -> Vec<f64>;
    /// Their standard errors, when they can be estimated yet.
    fn std_errors(&self) -> Option<Vec<f64>>;
    /// The covariance now, in the coordinates the run started from with [`Online::p0`].
    fn covariance(&self) -> nalgebra::DMatrix<f64>;
    /// The starting covariance.
    fn p0(&self) -> &nalgebra::DMatrix<f64>;
    /// Covariance repairs so far (the UKFs; `None` where the method has none).
    fn repairs(&self) -> Option<u64> {
        None
    }
    /// Times a bound was enforced (non-linear methods with --bound).
    fn projections(&self) -> Option<u64> {
        None
    }
}

struct LinearRun<'a> {
    est: LinearEstimator,
    p0: nalgebra::DMatrix<f64>,
    cols: Vec<&'a [f64]>,
    y: &'a [f64],
    phi: Vec<f64>,
}

impl Online for LinearRun<'_> {
    fn update(&mut self, i: usize) -> Result<Step, EstimError> {
        for (f, c) in self.phi.iter_mut().zip(&self.cols) {
            *f = c[i];
        }
        self.est.update(&self.phi, self.y[i])
    }
    fn free_estimate(&self) -> Vec<f64> {
        self.est.estimate().to_vec()
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        self.est.std_errors().ok()
    }
    fn covariance(&self) -> nalgebra::DMatrix<f64> {
        self.est.covariance()
    }
    fn p0(&self) -> &nalgebra::DMatrix<f64> {
        &self.p0
    }
}

struct NonlinearRun<'a> {
    est: NonlinearEstimator<ExprModel>,
    p0: nalgebra::DMatrix<f64>,
    cols: Vec<&'a [f64]>,
    y: &'a [f64],
    u: Vec<f64>,
}

impl Online for NonlinearRun<'_> {
    fn update(&mut self, i: usize) -> Result<Step, EstimError> {
        for (f, c) in self.u.iter_mut().zip(&self.cols) {
            *f = c[i];
        }
        self.est.update(&self.u, self.y[i])
    }
    fn free_estimate(&self) -> Vec<f64> {
        self.est.estimate()
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        Some(self.est.std_errors())
    }
    fn covariance(&self) -> nalgebra::DMatrix<f64> {
        self.est.covariance()
    }
    fn p0(&self) -> &nalgebra::DMatrix<f64> {
        &self.p0
    }
    fn repairs(&self) -> Option<u64> {
        Some(self.est.repairs())
    }
    fn projections(&self) -> Option<u64> {
        Some(self.est.projections())
    }
}

fn linear_method(args: &Args, p: usize) -> Result<Method> {
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
                "unknown method '{m}'; the methods are: rls, rlsf, rlsvf, kf, dsfc, ekf, ukf, srukf"
            ))
        }
    })
}

/// The free/fixed view from --free.
fn free_set(args: &Args, params: &ParamSet) -> Result<physid_core::FreeSet> {
    match &args.free {
        Some(names) => params.free(names).into_diagnostic(),
        None => Ok(params.all_free()),
    }
}

/// Run the estimation.
pub fn run(args: &Args) -> Result<()> {
    let skip_bad = match args.on_bad.as_str() {
        "error" => false,
        "skip" => true,
        v => return Err(miette!("--on-bad '{v}': expected error or skip")),
    };
    let rec = args.input.read(&args.data, None)?;
    let file = args.data.display().to_string();
    let column = |c: &str| rec.values(c).map_err(|e| miette!("{file}: {e}"));
    let y = column(&args.y)?;
    let nonlinear = matches!(args.method.as_str(), "ekf" | "ukf" | "srukf");

    let (mut online, params, free, method_name): (Box<dyn Online>, ParamSet, _, &str) = if nonlinear
    {
        let text = args.expr.as_deref().ok_or_else(|| {
            miette!(
                "--method {} needs a model: --expr '…' --params NAME=VALUE,…",
                args.method
            )
        })?;
        if !args.phi.is_empty() {
            return Err(miette!("--phi is for the linear methods; with --expr the data columns are the names in the expression"));
        }
        let (names, values) = named_values(&args.params, "--params")?;
        let model = ExprModel::parse(text, &names).map_err(|e| miette!("--expr: {e}"))?;
        model
            .check_inputs(&rec.names())
            .map_err(|e| miette!("--expr: {e} (in {file})"))?;
        let cols: Vec<&[f64]> = model
            .inputs()
            .iter()
            .map(|c| column(c))
            .collect::<Result<_>>()?;
        let params = ParamSet::new(names, values).into_diagnostic()?;
        let free = free_set(args, &params)?;
        let sp = SigmaPoints {
            alpha: args.alpha,
            beta: args.beta,
            kappa: args.kappa,
        };
        let mut bounds = Vec::new();
        for b in &args.bound {
            let (n, range) = b
                .split_once('=')
                .ok_or_else(|| miette!("--bound '{b}': expected NAME=LOW:HIGH"))?;
            let (lo, hi) = range
                .split_once(':')
                .and_then(|(l, h)| Some((l.trim().parse().ok()?, h.trim().parse().ok()?)))
                .ok_or_else(|| miette!("--bound '{b}': expected NAME=LOW:HIGH with numbers"))?;
            bounds.push((n.trim().to_string(), lo, hi));
        }
        let cfg = NlConfig {
            method: match args.method.as_str() {
                "ekf" => NlMethod::Ekf,
                "ukf" => NlMethod::Ukf(sp),
                _ => NlMethod::Srukf(sp),
            },
            p0: CovSpec::Scaled(args.p0.unwrap_or(100.0)),
            r1: CovSpec::Scaled(args.r1),
            r2: args.r2,
            scaled: args.scaled,
            bounds,
        };
        let name = cfg.method.name();
        let est = NonlinearEstimator::new(model, &params, &free, &cfg).into_diagnostic()?;
        let p0 = cfg
            .p0
            .to_matrix(free.free().len(), "P0")
            .into_diagnostic()?;
        let u = vec![0.0; cols.len()];
        (
            Box::new(NonlinearRun {
                est,
                p0,
                cols,
                y,
                u,
            }),
            params,
            free,
            name,
        )
    } else {
        if args.phi.is_empty() {
            return Err(miette!(
                "--method {} needs the regressor columns: --phi COL,COL,…",
                args.method
            ));
        }
        if args.expr.is_some() {
            return Err(miette!("--expr needs --method ekf, ukf or srukf"));
        }
        let cols: Vec<&[f64]> = args.phi.iter().map(|c| column(c)).collect::<Result<_>>()?;
        let p = cols.len();
        let theta0 = args.theta0.clone().unwrap_or_else(|| vec![0.0; p]);
        let params = ParamSet::new(args.phi.clone(), theta0).into_diagnostic()?;
        let free = free_set(args, &params)?;
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
            method: linear_method(args, free.free().len())?,
            p0: CovSpec::Scaled(args.p0.unwrap_or(1000.0)),
            guard,
        };
        let name = cfg.method.name();
        let est = LinearEstimator::new(&cfg, &params, &free).into_diagnostic()?;
        let p0 = cfg
            .p0
            .to_matrix(free.free().len(), "P0")
            .into_diagnostic()?;
        (
            Box::new(LinearRun {
                est,
                p0,
                cols,
                y,
                phi: vec![0.0; p],
            }),
            params,
            free,
            name,
        )
    };
    let names: Vec<String> = params
        .free_names(&free)
        .into_iter()
        .map(String::from)
        .collect();
    let nfree = names.len();

    let line = |i: usize| super::locate(&rec, i);
    let n = y.len();
    let mut measured = Vec::with_capacity(n);
    let mut predicted = Vec::with_capacity(n);
    let mut track: Vec<Vec<f64>> = vec![Vec::new(); 2 * nfree + 2];
    let mut skipped = 0usize;
    let mut seconds = 0.0;
    for (i, &yi) in y.iter().enumerate() {
        let t0 = Instant::now();
        let r = online.update(i);
        seconds += t0.elapsed().as_secs_f64();
        match r {
            Ok(step) => {
                measured.push(yi);
                predicted.push(yi - step.prediction_error);
                if args.out.is_some() {
                    let se = online.std_errors();
                    track[0].push(yi - step.prediction_error);
                    track[1].push(step.prediction_error);
                    for (j, v) in online.free_estimate().into_iter().enumerate() {
                        track[2 + j].push(v);
                        track[2 + nfree + j].push(se.as_ref().map_or(f64::NAN, |s| s[j]));
                    }
                }
            }
            Err(EstimError::NonFinite { .. }) if skip_bad => skipped += 1,
            Err(EstimError::NonFinite { what, value, .. }) => {
                return Err(miette!(
                    "{file}, {}: {what} is not finite ({value}); \
                     use --on-bad skip to skip such samples",
                    line(i)
                ))
            }
            Err(e) => return Err(miette!("{file}, {}: {e}", line(i))),
        }
    }
    let accepted = measured.len();
    if accepted == 0 {
        return Err(miette!("{file}: no usable samples ({skipped} skipped)"));
    }
    let theta = online.free_estimate();
    // What the data resolved (physid_estim::resolution): an unresolved parameter keeps its
    // estimate but gets no standard error — the data cannot support one.
    let res = resolution(&online.covariance(), online.p0());
    let unresolved: Vec<&String> = res.unresolved().iter().map(|&j| &names[j]).collect();
    let std_err: Option<Vec<Option<f64>>> = online.std_errors().map(|s| {
        s.iter()
            .enumerate()
            .map(|(j, &v)| res.resolved[j].then_some(v))
            .collect()
    });
    let mut full = params.nominal().to_vec();
    free.scatter(&theta, &mut full);
    let repairs = online.repairs();
    let projections = online.projections();
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
            cols.push((nm.clone(), std::mem::take(&mut track[2 + j])));
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

    let rate = accepted as f64 / seconds.max(1e-12);
    if args.json {
        let params_json: serde_json::Map<_, _> = params
            .names()
            .iter()
            .zip(&full)
            .map(|(k, v)| (k.clone(), json!(v)))
            .collect();
        let se: serde_json::Map<_, _> = names
            .iter()
            .enumerate()
            .map(|(j, k)| (k.clone(), json!(std_err.as_ref().and_then(|s| s[j]))))
            .collect();
        let resolution_json: serde_json::Map<_, _> = names
            .iter()
            .enumerate()
            .map(|(j, k)| {
                (
                    k.clone(),
                    json!({"resolved": res.resolved[j],
                           "variance_ratio": res.variance_ratio[j],
                           "independence": res.independence[j]}),
                )
            })
            .collect();
        let mut out = json!({
            "method": method_name,
            "samples": accepted,
            "skipped": skipped,
            "params": params_json,
            "std_err": se,
            "unresolved": unresolved,
            "resolution": resolution_json,
            "nmse": nmse,
            "nrmse": nrmse,
            "fit_percent": fit,
            "timing": {"seconds": seconds, "updates_per_s": rate},
        });
        if let Some(r) = repairs {
            out["repairs"] = json!(r);
        }
        if let Some(n) = projections {
            out["projections"] = json!(n);
        }
        outln!("{}", serde_json::to_string_pretty(&out).into_diagnostic()?);
        return Ok(());
    }
    outln!(
        "{method_name} on {file}: {accepted} samples{} ({:.3} s, {:.0} updates/s)",
        if skipped > 0 {
            format!(", {skipped} skipped (non-finite)")
        } else {
            String::new()
        },
        seconds,
        rate
    );
    outln!(
        "{:<16} {:>16} {:>14}",
        "parameter",
        "estimate",
        "std. error"
    );
    for (j, nm) in names.iter().enumerate() {
        let s = match std_err.as_ref() {
            None => "-".to_string(),
            Some(s) => s[j].map_or("unresolved".to_string(), |v| format!("{v:.6e}")),
        };
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
    if !unresolved.is_empty() {
        outln!(
            "the data do not resolve {}: their variance fell by less than half, or they cannot be told apart from the others (collinear); their estimates are not supported by the data",
            unresolved
                .iter()
                .map(|s| s.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let show = |v: Option<f64>| v.map_or("undefined".to_string(), |v| format!("{v:.4e}"));
    outln!(
        "one-step prediction: NMSE {} (Eq. 6.4), NRMSE {}, fit {}",
        show(nmse),
        show(nrmse),
        fit.map_or("undefined".to_string(), |v| format!("{v:.2} %"))
    );
    if let Some(r) = repairs {
        outln!("covariance repairs: {r}");
    }
    if let Some(n) = projections.filter(|n| *n > 0) {
        outln!("bounds enforced: {n} times (an estimate is at a bound)");
    }
    Ok(())
}
