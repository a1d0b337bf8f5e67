//! `physid estimate`: recursive estimation from a CSV file — a linear regression `y = φᵀϑ`
//! (rls, rlsf, rlsvf, kf, dsfc) or a model from an expression (ekf, ukf, srukf).

use super::named_values;
use crate::out::outln;
use crate::tracks::TrackFile;
use miette::{miette, IntoDiagnostic, Result};
use physid_core::{ParamSet, Recording};
use physid_estim::metrics::Prediction;
use physid_estim::{
    build_linear, feed, CovSpec, EstimError, EstimatorSpec, FeedError, FeedSummary, GuardAction,
    MethodName, OnBad, Recursive, RunSummary, SigmaPoints, VfVariant, WindupGuard,
};
use physid_expr::ExprModel;
use std::path::PathBuf;

/// Arguments of `physid estimate`.
#[derive(clap::Args)]
pub struct Args {
    /// Recording (CSV with a header row, Parquet or MDF4).
    #[arg(long, value_name = "FILE")]
    pub data: PathBuf,
    #[command(flatten)]
    pub input: super::InputArgs,
    /// Column of the measured output y.
    #[arg(long, value_name = "COL")]
    pub y: String,
    /// Linear methods: the regressor φ, comma separated — columns, or formulas over columns
    /// (`theta_dy-theta_en`, `omega_en^2`; without commas), or `1` for an offset; they name the
    /// parameters.
    #[arg(long, value_delimiter = ',')]
    pub phi: Vec<String>,
    /// Non-linear methods: the model, e.g. 'A*exp(-B*x) + C*x'; names not in --params are
    /// data columns.
    #[arg(long, value_name = "FORMULA")]
    pub expr: Option<String>,
    /// The parameters' initial (nominal) values NAME=VALUE: with --expr every parameter, e.g.
    /// A=1,B=0.5; with --phi any of the regressors' parameters, named as in --phi (the others
    /// start at 0).
    #[arg(long, value_name = "NAME=VALUE,…", value_delimiter = ',')]
    pub params: Vec<String>,
    /// Estimator: rls, rlsf (constant or, with --lambda0, time-varying λ), rlsvf, kf, dsfc;
    /// ekf, ukf, srukf for --expr models.
    #[arg(long, default_value = "rlsf")]
    pub method: MethodName,
    /// Forgetting factor λ ∈ (0, 1] (rlsf, dsfc; with --lambda0 it is λ(0)) [default: 0.98].
    #[arg(long, value_name = "LAMBDA", value_parser = super::range::forgetting, allow_negative_numbers = true)]
    pub lambda: Option<f64>,
    /// Time-varying forgetting λ(t) = λ0·λ(t−1) + 1 − λ0 (Eq. 5.24) for rlsf.
    #[arg(long, value_parser = super::range::forgetting, allow_negative_numbers = true)]
    pub lambda0: Option<f64>,
    /// Per-parameter forgetting factors for rlsvf, in --phi order.
    #[arg(long, value_delimiter = ',')]
    pub lambdas: Option<Vec<f64>>,
    /// Vector-forgetting form: published (thesis Alg. 5.4) or symmetric.
    #[arg(long, default_value = "published")]
    pub vf_variant: VfVariant,
    /// Initial covariance P0 = C·I [default: 1000 for linear methods, 100 for ekf/ukf/srukf].
    #[arg(long, value_name = "P0", value_parser = super::range::positive, allow_negative_numbers = true)]
    pub p0: Option<f64>,
    /// Deprecated: --params NAME=VALUE (the values in --phi order).
    #[arg(
        long,
        hide = true,
        value_delimiter = ',',
        allow_negative_numbers = true,
        conflicts_with = "params"
    )]
    pub theta0: Option<Vec<f64>>,
    /// Estimate only these parameters; the others stay at their initial values.
    #[arg(long, value_name = "NAME,…", value_delimiter = ',')]
    pub free: Option<Vec<String>>,
    /// Kalman-type methods (kf, ekf, ukf, srukf): parameter random-walk variance, R1 = X·I.
    #[arg(long, default_value_t = 0.0, value_parser = super::range::nonnegative, allow_negative_numbers = true)]
    pub r1: f64,
    /// Kalman-type methods: measurement noise variance R2.
    #[arg(long, value_name = "R2", default_value_t = 1.0, value_parser = super::range::positive, allow_negative_numbers = true)]
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
    /// Non-linear methods: keep a parameter within limits, NAME=LOW:HIGH (repeatable).
    #[arg(long, value_name = "NAME=LOW:HIGH")]
    pub limits: Vec<String>,
    /// Deprecated: --limits (--bound is the alarms' relative-error bound in the other verbs).
    #[arg(long = "bound", hide = true, conflicts_with = "limits")]
    pub bound_old: Vec<String>,
    /// Wind-up guard (linear methods): bound on trace(P).
    #[arg(long, value_parser = super::range::positive, allow_negative_numbers = true)]
    pub max_trace: Option<f64>,
    /// Wind-up guard action beyond the bound: scale or reset.
    #[arg(long, default_value = "scale")]
    pub guard: GuardAction,
    /// Samples with NaN/inf: error (stop and report) or skip (count them).
    #[arg(long, default_value = "error")]
    pub on_bad: OnBad,
    /// Write the time, one-step prediction, prediction error, estimates and standard errors of
    /// every sample to this file (.csv, .parquet or .mf4), as they come.
    #[arg(long, value_name = "FILE")]
    pub tracks: Option<PathBuf>,
    /// Deprecated: --tracks.
    #[arg(long, hide = true)]
    pub out: Option<PathBuf>,
    /// Print the result as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The estimator `--method` names with its tuning from the flags (λ 0.98 unless given; P(0)
/// 1000·I for a regression, 100·I for a filter over a model).
fn spec(args: &Args) -> EstimatorSpec {
    let mut spec = EstimatorSpec::new(args.method);
    spec.lambda = args.lambda.unwrap_or(0.98);
    spec.lambda0 = args.lambda0;
    spec.lambdas.clone_from(&args.lambdas);
    spec.vf_variant = args.vf_variant;
    if let Some(p0) = args.p0 {
        spec.p0 = CovSpec::Scaled(p0);
    }
    spec.r1 = CovSpec::Scaled(args.r1);
    spec.r2 = args.r2;
    spec.sigma_points = SigmaPoints {
        alpha: args.alpha,
        beta: args.beta,
        kappa: args.kappa,
    };
    spec.scaled = args.scaled;
    spec.guard = args.max_trace.map(|max_trace| WindupGuard {
        max_trace,
        action: args.guard,
    });
    spec
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
    // The file read a chunk at a time, only the columns the estimator takes; the tracks
    // (--out) written as they come.
    let file = args.data.display().to_string();
    let header = args.input.open_all(&args.data)?.header().clone();

    let (mut est, columns, params, free): (Box<dyn Recursive>, Vec<String>, ParamSet, _) = if args
        .method
        .is_model_based()
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
            .check_inputs(&header.names())
            .map_err(|e| miette!("--expr: {e} (in {file})"))?;
        let columns: Vec<String> = model.inputs().to_vec();
        let params = ParamSet::new(names, values).into_diagnostic()?;
        let free = free_set(args, &params)?;
        let mut bounds = Vec::new();
        let (flag, limits) = if args.bound_old.is_empty() {
            ("--limits", &args.limits)
        } else {
            super::deprecated("--bound NAME=LOW:HIGH in estimate is now --limits NAME=LOW:HIGH");
            ("--bound", &args.bound_old)
        };
        for b in limits {
            let (n, range) = b
                .split_once('=')
                .ok_or_else(|| miette!("{flag} '{b}': expected NAME=LOW:HIGH"))?;
            let (lo, hi) = range
                .split_once(':')
                .and_then(|(l, h)| Some((l.trim().parse().ok()?, h.trim().parse().ok()?)))
                .ok_or_else(|| miette!("{flag} '{b}': expected NAME=LOW:HIGH with numbers"))?;
            bounds.push((n.trim().to_string(), lo, hi));
        }
        let spec = EstimatorSpec {
            bounds,
            ..spec(args)
        };
        let est = physid_estim::build(&spec, model, &params, &free).into_diagnostic()?;
        (est, columns, params, free)
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
        if !args.limits.is_empty() || !args.bound_old.is_empty() {
            return Err(miette!(
                "--limits is for the non-linear methods (ekf, ukf, srukf with --expr)"
            ));
        }
        let p = args.phi.len();
        let mut theta0 = vec![0.0; p];
        if let Some(old) = &args.theta0 {
            super::deprecated("--theta0 V,… is now --params NAME=VALUE,… (names as in --phi)");
            if old.len() != p {
                return Err(miette!(
                    "--theta0: {} values for the {p} regressors of --phi",
                    old.len()
                ));
            }
            theta0.clone_from(old);
        }
        let (names, values) = named_values(&args.params, "--params")?;
        for (n, v) in names.iter().zip(values) {
            let j = args.phi.iter().position(|c| c == n).ok_or_else(|| {
                miette!(
                    "--params {n}: the parameters are the regressors of --phi: {}",
                    args.phi.join(", ")
                )
            })?;
            theta0[j] = v;
        }
        let params = ParamSet::new(args.phi.clone(), theta0).into_diagnostic()?;
        let free = free_set(args, &params)?;
        let est = build_linear(&spec(args), &params, &free).into_diagnostic()?;
        (Box::new(est), args.phi.clone(), params, free)
    };
    let names: Vec<String> = params
        .free_names(&free)
        .into_iter()
        .map(String::from)
        .collect();
    header
        .channel(&args.y)
        .map_err(|e| miette!("{file}: {e}"))?;
    let regressors: Vec<Regressor> = columns
        .iter()
        .map(|c| Regressor::of(c, &header).map_err(|e| miette!("{file}: {e}")))
        .collect::<Result<_>>()?;
    let mut wanted: Vec<&str> = vec![args.y.as_str()];
    for c in regressors.iter().flat_map(Regressor::columns) {
        if !wanted.contains(&c) {
            wanted.push(c);
        }
    }
    // The time when the file has it: for the tracks, and whether it only goes forward.
    let optional: &[&str] = &["t"];
    let mut reader = args.input.open(&args.data, &wanted, optional)?;

    let method_name = est.method_name();
    // --tracks (or the old --out): time, prediction, error, estimates and standard errors of
    // every sample, written as they come.
    let tracks_path = match (&args.tracks, &args.out) {
        (Some(p), _) => Some(p),
        (None, Some(p)) => {
            eprintln!(
                "warning: estimate --out FILE is now --tracks FILE (CSV, Parquet or MDF4 by the extension); --out will be removed"
            );
            Some(p)
        }
        (None, None) => None,
    };
    let y_unit = reader
        .header()
        .channel(&args.y)
        .map(|c| c.unit.clone())
        .unwrap_or_default();
    let has_t = reader.header().channel("t").is_ok();
    let mut tracks = match tracks_path {
        Some(path) => {
            let mut columns = vec![
                ("t".to_string(), if has_t { "s" } else { "" }.to_string()),
                ("y_predicted".into(), y_unit.clone()),
                ("prediction_error".into(), y_unit),
            ];
            columns.extend(names.iter().map(|n| (n.clone(), String::new())));
            columns.extend(
                names
                    .iter()
                    .map(|n| (format!("{n}_std_err"), String::new())),
            );
            Some(TrackFile::create(path, columns)?)
        }
        None => None,
    };
    let mut track_error = None;
    let mut prediction = Prediction::default();
    let mut fed = FeedSummary {
        accepted: 0,
        skipped: 0,
        seconds: 0.0,
    };
    let mut offset = 0;
    // Sample i of the file is on this line (CSV), for the messages.
    let at_line = reader.header().clone();
    let mut order = physid_apps::time_order::TimeOrder::default();
    for chunk in crate::progress::Reading::new(&mut reader, &args.data) {
        let chunk = chunk.into_diagnostic()?;
        let y = chunk.values(&args.y).into_diagnostic()?;
        // The sample index stands for the time in a file without `t`.
        let t = chunk.values("t").ok();
        if let Some(t) = t {
            order.push(t);
        }
        let derived: Vec<Option<Vec<f64>>> = regressors
            .iter()
            .map(|r| r.derive(&chunk).map_err(|e| miette!("{file}: {e}")))
            .collect::<Result<_>>()?;
        let cols: Vec<&[f64]> = regressors
            .iter()
            .zip(&derived)
            .map(|(r, d)| match (r, d) {
                (_, Some(v)) => Ok(v.as_slice()),
                (Regressor::Column(c), None) => chunk.values(c.as_str()).into_diagnostic(),
                (Regressor::Derived(..), None) => Err(miette!("a formula without its values")),
            })
            .collect::<Result<_>>()?;
        let part = feed(est.as_mut(), &cols, y, args.on_bad, |i, step, est| {
            prediction.push(y[i], y[i] - step.prediction_error);
            if let Some(tf) = &mut tracks {
                let se = est.std_errors();
                let theta = est.estimate();
                let t = t.map_or((offset + i) as f64, |t| t[i]);
                let row = [t, y[i] - step.prediction_error, step.prediction_error]
                    .into_iter()
                    .chain(theta.iter().copied())
                    .chain((0..theta.len()).map(|j| se.as_ref().map_or(f64::NAN, |s| s[j])));
                if let Err(e) = tf.row(row) {
                    track_error.get_or_insert(e);
                }
            }
        })
        .map_err(|FeedError { sample, error }| {
            let at = super::locate(&at_line, offset + sample);
            match error {
                EstimError::NonFinite { what, value, .. } => miette!(
                    "{file}, {at}: {what} is not finite ({value}); use --on-bad skip to skip such samples"
                ),
                e => miette!("{file}, {at}: {e}"),
            }
        })?;
        if let Some(e) = track_error.take() {
            return Err(e);
        }
        fed += part;
        offset += y.len();
    }
    super::warn_read(&reader, &args.data);
    if let Some(n) = order.note() {
        eprintln!("warning: {file}: {n}");
    }
    if let Some(tf) = tracks {
        tf.close()?;
    }
    let FeedSummary {
        accepted,
        skipped,
        seconds,
    } = fed;
    if accepted == 0 {
        return Err(miette!("{file}: no usable samples ({skipped} skipped)"));
    }
    let theta = est.estimate();
    // What the data resolved (physid_estim::resolution): an unresolved parameter keeps its
    // estimate but gets no standard error — the data cannot support one.
    let summary = RunSummary::new(est.as_ref(), &fed, &prediction);
    let has_std_err = est.std_errors().is_some();

    if args.json {
        crate::provenance::print_json(&summary)?;
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
        summary.timing.updates_per_s
    );
    outln!(
        "{:<16} {:>16} {:>14}",
        "parameter",
        "estimate",
        "std. error"
    );
    for (j, nm) in names.iter().enumerate() {
        let s = match summary.std_err[nm] {
            _ if !has_std_err => "-".to_string(),
            None => "unresolved".to_string(),
            Some(v) => format!("{v:.6e}"),
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
    if !summary.unresolved.is_empty() {
        outln!(
            "the data do not resolve {}: their variance fell by less than half, or they cannot be told apart from the others (collinear); their estimates are not supported by the data",
            summary.unresolved.join(", ")
        );
    }
    let show = |v: Option<f64>| v.map_or("undefined".to_string(), |v| format!("{v:.4e}"));
    outln!(
        "one-step prediction: NMSE {} (Eq. 6.4), NRMSE {}, fit {}",
        show(summary.nmse),
        show(summary.nrmse),
        summary
            .fit_percent
            .map_or("undefined".to_string(), |v| format!("{v:.2} %"))
    );
    if let Some(r) = summary.repairs {
        outln!("covariance repairs: {r}");
    }
    if let Some(n) = summary.projections.filter(|n| *n > 0) {
        outln!("bounds enforced: {n} times (an estimate is at a bound)");
    }
    Ok(())
}

/// One regressor of `--phi`: a column of the file, or a formula over its columns.
enum Regressor {
    Column(String),
    Derived(ExprModel),
}

impl Regressor {
    /// `text` as a column of `header` if it is one, else as a formula over its columns.
    fn of(text: &str, header: &Recording) -> std::result::Result<Self, String> {
        if header.channel(text).is_ok() {
            return Ok(Self::Column(text.to_string()));
        }
        let no_column = || {
            header
                .channel(text)
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default()
        };
        // A formula without columns is a constant regressor (`1`: an offset).
        let model = ExprModel::parse::<&str>(text, &[])
            .map_err(|e| format!("{}; as a formula: {e}", no_column()))?;
        model
            .check_inputs(&header.names())
            .map_err(|e| format!("--phi '{text}': {e}"))?;
        Ok(Self::Derived(model))
    }

    /// The columns it reads.
    fn columns(&self) -> Vec<&str> {
        match self {
            Self::Column(c) => vec![c.as_str()],
            Self::Derived(m) => m.inputs().iter().map(String::as_str).collect(),
        }
    }

    /// A formula's values over `chunk` (`None` for a column, read as it is).
    fn derive(&self, chunk: &Recording) -> std::result::Result<Option<Vec<f64>>, String> {
        let Self::Derived(m) = self else {
            return Ok(None);
        };
        let inputs: Vec<&[f64]> = m
            .inputs()
            .iter()
            .map(|c| chunk.values(c).map_err(|e| e.to_string()))
            .collect::<std::result::Result<_, _>>()?;
        let mut u = vec![0.0; inputs.len()];
        Ok(Some(
            (0..chunk.len())
                .map(|i| {
                    for (x, col) in u.iter_mut().zip(&inputs) {
                        *x = col[i];
                    }
                    physid_core::ParamModel::eval::<f64>(m, &u, &[])
                })
                .collect(),
        ))
    }
}
