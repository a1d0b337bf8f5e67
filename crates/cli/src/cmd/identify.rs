//! `physid identify`: which parameters of a model a recording can resolve (thesis §5.2,
//! Alg. 5.1), with their precision; several recordings compare experiments (Table 8.1).

use super::named_values;
use crate::out::outln;
use miette::{miette, IntoDiagnostic, Result};
use physid_apps::model_choice::ModelChoice;
use physid_apps::recording_rows::{Column, RecordingRows};
use physid_core::ParamModel;
use physid_ident::{
    identify, Cutoff, IdentConfig, Identification, Scaling, Selection, SigmaSource,
};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// Arguments of `physid identify`.
#[derive(clap::Args)]
pub struct Args {
    /// Recording (CSV, Parquet or MDF4); give several to compare experiments.
    #[arg(long, value_name = "FILE", required = true)]
    pub data: Vec<PathBuf>,
    /// The model as a formula; its data columns are the names that are not parameters.
    #[arg(long, value_name = "FORMULA", conflicts_with = "model")]
    pub expr: Option<String>,
    /// Nominal values NAME=VALUE,… (all parameters with --expr; overrides with --model).
    #[arg(long, value_name = "NAME=VALUE,…", value_delimiter = ',')]
    pub params: Vec<String>,
    /// A built-in model: example-5.1, shaft, shaft-offset, cyclic-torque, friction-regression.
    #[arg(long)]
    pub model: Option<String>,
    /// The measured output column: thesis scaling then divides by it, and the precision comes
    /// from a least-squares fit (without it: the model's output at the nominal values).
    #[arg(long, value_name = "COL")]
    pub y: Option<String>,
    /// Sensitivity scaling: thesis (ϑ0/y, Eq. 5.11), sigma (ϑ0/σ_y) or none.
    #[arg(long, default_value = "thesis")]
    pub scaling: Scaling,
    /// Thesis-scaling guard: rows with |y| below this fraction of rms(y) divide by it instead.
    #[arg(long, value_name = "FRACTION", default_value_t = 1e-3)]
    pub scaling_guard: f64,
    /// Deprecated: --scaling-guard (--guard is the wind-up guard's action in estimate).
    #[arg(long = "guard", hide = true, conflicts_with = "scaling_guard")]
    pub guard_old: Option<f64>,
    /// Subtract each sensitivity column's mean first (Eq. 5.9 as printed).
    #[arg(long)]
    pub centre: bool,
    /// Cut-off: repeat (the thesis's: stop when a column repeats), a number (absolute residual
    /// sum of squares), or wu (the MSE criterion of Wu et al. 2011; needs --y).
    #[arg(long, default_value = "repeat", conflicts_with = "cutoff_rel")]
    pub cutoff: Selection,
    /// Cut-off relative to the first residual.
    #[arg(long)]
    pub cutoff_rel: Option<f64>,
    /// Analyse only these parameters (the rest held at their nominal values).
    #[arg(long, value_name = "NAME,…", value_delimiter = ',')]
    pub free: Vec<String>,
    /// Measurement noise standard deviation for the Fisher information [output units]
    /// (default: estimated from the fit with --y; otherwise 1).
    #[arg(long)]
    pub sigma: Option<f64>,
    #[command(flatten)]
    pub input: super::InputArgs,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// The model and its nominal values.
fn build(args: &Args) -> Result<(ModelChoice, Vec<f64>)> {
    let (names, values) = named_values(&args.params, "--params")?;
    if args.expr.is_some() && names.is_empty() {
        return Err(miette!(
            "--expr needs the parameters and their nominal values: --params A=1,B=2,…"
        ));
    }
    let params: Vec<(String, f64)> = names.into_iter().zip(values).collect();
    ModelChoice::build(args.expr.as_deref(), args.model.as_deref(), &params).map_err(|e| {
        let flag = if args.expr.is_some() {
            "--expr"
        } else {
            "--model"
        };
        miette!("{flag}: {e}")
    })
}

fn cutoff(args: &Args) -> Result<Selection> {
    if let Some(r) = args.cutoff_rel {
        if !(r.is_finite() && r >= 0.0) {
            return Err(miette!(
                "--cutoff-rel {r}: expected a fraction ≥ 0",
                r = physid_core::Num(r)
            ));
        }
        return Ok(Selection::Rule(Cutoff::Relative(r)));
    }
    match args.cutoff {
        Selection::Wu { .. } if args.y.is_none() => Err(miette!(
            "--cutoff wu fits the top-ranked parameters: it needs the measured output, --y COL"
        )),
        Selection::Wu { .. } => Ok(Selection::Wu {
            sigma2: args.sigma.map(|s| s * s),
        }),
        rule => Ok(rule),
    }
}

/// Run `physid identify`.
pub fn run(args: &Args) -> Result<()> {
    let mut reports = analyse_files(args)?;
    if args.json {
        let v = if reports.len() == 1 {
            reports.remove(0)
        } else {
            json!({ "experiments": reports })
        };
        crate::provenance::print_json_value(v)?;
        return Ok(());
    }
    if reports.len() > 1 {
        print_comparison(&reports);
    }
    Ok(())
}

/// Analyse every `--data` file (printing each table unless `--json`); the JSON report of each.
pub fn analyse_files(args: &Args) -> Result<Vec<Value>> {
    let (model, nominal) = build(args)?;
    let config = IdentConfig {
        scaling: args.scaling,
        guard: super::renamed(args.guard_old, "--guard", "--scaling-guard")
            .unwrap_or(args.scaling_guard),
        centre: args.centre,
    };
    let choice = cutoff(args)?;
    if let Some(s) = args.sigma {
        if !(s.is_finite() && s > 0.0) {
            return Err(miette!("--sigma {s}: expected a standard deviation > 0"));
        }
    }
    let mut reports = Vec::new();
    for path in &args.data {
        // Only the columns the analysis takes are read.
        let header = args.input.open_all(path)?.header().clone();
        if let ModelChoice::Expr(m) = &model {
            m.check_inputs(&header.names())
                .map_err(|e| miette!("--expr: {e} (in {})", path.display()))?;
        }
        for c in model.input_names() {
            header
                .channel(c)
                .map_err(|e| miette!("{}: the model needs column '{c}': {e}", path.display()))?;
        }
        if let Some(c) = &args.y {
            header
                .channel(c)
                .map_err(|e| miette!("{}: {e}", path.display()))?;
        }
        // The analyses go over the file in passes: held after the first when it fits the
        // hold limit, else read again each time.
        let rows = RecordingRows::file(
            path,
            &args.input.options(None)?,
            model
                .input_names()
                .iter()
                .map(|c| Column::named(c))
                .collect(),
            args.y.as_deref().map(Column::named),
            // The time, when the file has it: whether it only goes forward is said.
            &["t"],
            super::hold_bytes()?,
        )
        .map_err(super::app_error(path))?;
        crate::provenance::record_input(path, &args.input.map);
        let r = identify_one(&model, path, &rows, &nominal, args, config, &choice)?;
        if let Some(w) = rows.warning() {
            eprintln!("warning: {}: {w}", path.display());
        }
        reports.push(r);
    }
    Ok(reports)
}

/// Analyse one recording; print the table unless JSON; return the JSON report.
fn identify_one<M: ParamModel>(
    model: &M,
    path: &Path,
    rows: &RecordingRows,
    nominal: &[f64],
    args: &Args,
    config: IdentConfig,
    choice: &Selection,
) -> Result<Value> {
    let file = path.display().to_string();
    let names = model.param_names();
    let free: Vec<usize> = args
        .free
        .iter()
        .map(|f| {
            names
                .iter()
                .position(|n| n == f)
                .ok_or_else(|| miette!("--free {f}: the parameters are {}", names.join(", ")))
        })
        .collect::<Result<_>>()?;
    let id = identify(model, rows, nominal, &free, config, *choice, args.sigma).map_err(
        |e| match e {
            // Placed by file line, as every verb does.
            physid_ident::IdentError::BadValue { row, column, value } => miette!(
                "{file}, {}: '{column}' is {value} (expected a finite number)",
                super::locate(rows.header(), row)
            ),
            // A reading error names the file.
            physid_ident::IdentError::Read(e) => miette!("{e}"),
            e => miette!("{file}: {e}"),
        },
    )?;
    if !args.json {
        print_report(&id, &file);
    }
    #[derive(serde::Serialize)]
    struct FileReport<'a> {
        data: &'a str,
        #[serde(flatten)]
        report: physid_ident::IdentReport<'a>,
    }
    serde_json::to_value(FileReport {
        data: &file,
        report: id.report(),
    })
    .into_diagnostic()
}

/// The residual profile as a bar on a log scale: 1 → full width, 1e-16 → empty.
fn bar(relative: f64) -> String {
    let w = 30.0;
    let f = if relative > 0.0 {
        (1.0 + relative.log10() / 16.0).clamp(0.0, 1.0)
    } else {
        0.0
    };
    "█".repeat((w * f).round() as usize)
}

fn print_report(id: &Identification, file: &str) {
    let (a, k) = (&id.analysis, id.k);
    let (sel, unident) = (id.estimable(), id.unidentifiable());
    outln!(
        "{file}: {} rows, {} parameters, scaling {}{}",
        a.rows,
        a.names.len(),
        a.config.scaling.name(),
        if a.guarded_rows > 0 {
            format!(" ({} rows hit the |y| guard)", a.guarded_rows)
        } else {
            String::new()
        }
    );
    outln!(
        "{:>4}  {:<10} {:>14} {:>12}  residual profile (log, 1 … 1e-16)",
        "step",
        "parameter",
        "residual SS",
        "relative"
    );
    for (i, s) in a.ranking.steps.iter().enumerate() {
        outln!(
            "{:>4}  {:<10} {:>14.6e} {:>12.3e}  {}{}",
            i + 1,
            a.names[s.param],
            s.residual_ss,
            s.relative,
            bar(s.relative),
            if i + 1 == k { "  ← cut-off" } else { "" }
        );
    }
    outln!("estimable ({k}): {}", sel.join(", "));
    outln!("unidentifiable ({}): {}", unident.len(), unident.join(", "));
    if !a.unit_scaled.is_empty() {
        let n: Vec<&str> = a.unit_scaled.iter().map(|&i| a.names[i].as_str()).collect();
        outln!(
            "note: nominal value 0, column scaled by 1: {}",
            n.join(", ")
        );
    }
    if id.sigma2.is_nan() {
        outln!("note: {}", physid_ident::report::SIGMA2_OUTSIDE);
    }
    if let Some(q) = &id.quant {
        let src = match id.sigma_source {
            SigmaSource::Fit => "from the fit's residuals",
            SigmaSource::Given => "given",
            SigmaSource::Unit => "per unit noise variance (give --sigma or --y)",
        };
        outln!(
            "precision of the estimable parameters (σ² = {:.4e}, {src}):",
            id.sigma2
        );
        outln!(
            "  {:<10} {:>14} {:>12} {:>28} {:>9}",
            "parameter",
            "value",
            "std err",
            "95 % interval",
            "t"
        );
        for (i, n) in sel.iter().enumerate() {
            outln!(
                "  {:<10} {:>14.6e} {:>12.3e} [{:>12.5e}, {:>12.5e}] {:>9.2}",
                n,
                id.values[i],
                q.std_err[i],
                q.ci95[i].0,
                q.ci95[i].1,
                q.t_values[i]
            );
        }
        outln!(
            "  collinearity index γ = {:.4}, D-criterion det(FIM) = {:.4e}",
            id.collinearity,
            id.design.map_or(f64::NAN, |c| c.d)
        );
    }
}

fn print_comparison(reports: &[Value]) {
    outln!();
    outln!("experiment comparison");
    outln!(
        "{:<40} {:>9} {:>14}  estimable",
        "data",
        "rows",
        "D-criterion"
    );
    for r in reports {
        let est: Vec<&str> = r["ranking"]
            .as_array()
            .map(|v| v.iter().filter_map(|s| s["param"].as_str()).collect())
            .unwrap_or_default();
        let d = match &r["d_criterion"] {
            Value::Number(n) => format!("{:.4e}", n.as_f64().unwrap_or(f64::NAN)),
            other => other.to_string(),
        };
        outln!(
            "{:<40} {:>9} {:>14}  {} ({})",
            r["data"].as_str().unwrap_or(""),
            r["rows"],
            d,
            est.len(),
            est.join(", ")
        );
    }
}
