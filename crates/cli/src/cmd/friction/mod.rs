//! `physid friction`: the mean-value friction model (SPEC §2.5) — `eval` at an operating point,
//! `rank` of its design parameters over an operating grid (thesis §7.2, Table 7.1, Fig. 7.1),
//! `fit` of its regression coefficients to a motored recording (thesis §7.3, Application 2).
//!
//! Here: the arguments, `eval`; `fit.rs`: the fit and its report; `rank.rs`: the ranking and its
//! heat map.

mod fit;
mod rank;

pub use fit::fit_report_section;
pub use rank::{design_table, heatmap};

use super::crank_input::crank_input;
use super::inspect::AngleArgs;
use super::CrankArgs;
use crate::out::outln;
use crate::plot::{self, Panel, Series, PALETTE};
use crate::progress::Reading;
use crate::report::{self, Report};
use miette::{miette, Result};
use physid_apps::friction_fit::{
    self, friction_fit, friction_fit_stream, friction_preset, FrictionCycles, FrictionFit,
    FrictionFitConfig, TorqueSource, FRICTION_PRESETS, OBJECTIVE_PCT,
};
use physid_apps::friction_rank::{friction_rank, RankGrid, RankTable};
use physid_ident::Selection;
use physid_models::friction::{
    fmep, set_by_name, tau_nm, Design, OperatingPoint, Settings, REGRESSION_DESCRIPTIONS,
    REGRESSION_PARAMS, REGRESSION_UNITS,
};
use std::path::{Path, PathBuf};

/// Arguments of `physid friction`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// fmep by component [kPa] and the friction torque [N·m] at one operating point.
    ///
    /// Example: physid friction eval --n 1000 --p-int 100 --t-oil 35 --json
    Eval(EvalArgs),
    /// Rank the design parameters by the normalised sensitivity of the friction torque at each
    /// point of an operating grid (default: the thesis's 3³ design, 27 tests).
    ///
    /// Example: physid friction rank --out rank   (table, rank.svg heat map)
    Rank(RankArgs),
    /// Characterise the engine's friction from a motored recording (thesis §7.3): cycle-mean
    /// motoring torque, identifiability of the regression coefficients c1 … c20, DSFC on the
    /// estimable ones, prediction error over time.
    ///
    /// Example: physid friction fit --data sweep.parquet --preset cell --out fit
    Fit(FitArgs),
}

/// The model: preset and overrides.
#[derive(clap::Args)]
struct ModelArgs {
    /// Model preset: thesis (the thesis's code), sandoval2002 (the original model) or cell (the
    /// built-in virtual test cell's engine: its geometry with the thesis's oil and valvetrain).
    #[arg(long, default_value = "thesis")]
    preset: String,
    /// Override a design parameter (B, S, kappa, Di, De, Lv, Db, Lb, r — mm) or a setting
    /// (oil, valvetrain, ft_fto, cr, nc, nv, nb); repeatable, e.g. --set B=56 --set oil=SAE30.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
}

impl ModelArgs {
    fn build(&self) -> Result<(Design<f64>, Settings)> {
        let (mut d, mut st) = friction_preset(&self.preset).ok_or_else(|| {
            miette!(
                "no friction preset '{}'; the presets are {}",
                self.preset,
                FRICTION_PRESETS.join(", ")
            )
        })?;
        for s in &self.set {
            let (name, value) = s
                .split_once('=')
                .ok_or_else(|| miette!("--set {s}: expected NAME=VALUE, e.g. --set B=56"))?;
            set_by_name(&mut d, &mut st, name.trim(), value).map_err(|e| miette!("--set {e}"))?;
        }
        Ok((d, st))
    }
}

#[derive(clap::Args)]
struct EvalArgs {
    /// Engine speed [rpm].
    #[arg(long, value_parser = super::range::rpm, allow_negative_numbers = true)]
    n: f64,
    /// Intake manifold pressure [kPa].
    #[arg(long, value_parser = super::range::kpa, allow_negative_numbers = true)]
    p_int: f64,
    /// Oil temperature [°C].
    #[arg(long, value_parser = super::range::celsius, allow_negative_numbers = true)]
    t_oil: f64,
    /// Ambient pressure [kPa] (the thesis code's 101 kPa).
    #[arg(long, value_name = "KPA", default_value_t = 101.0, value_parser = super::range::kpa, allow_negative_numbers = true)]
    p_atm: f64,
    #[command(flatten)]
    model: ModelArgs,
    /// Print JSON: {"fmep_kpa": {cfmep, rfmep, vfmep, afmep, pmep, total}, "tau_fri_nm"}.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct RankArgs {
    /// Engine speeds of the grid [rpm].
    #[arg(long, value_delimiter = ',', default_values_t = [1000.0, 3000.0, 5000.0], value_parser = super::range::rpm, allow_negative_numbers = true)]
    n: Vec<f64>,
    /// Intake manifold pressures of the grid [kPa].
    #[arg(long, value_delimiter = ',', default_values_t = [10.0, 55.0, 100.0], value_parser = super::range::kpa, allow_negative_numbers = true)]
    p_int: Vec<f64>,
    /// Oil temperatures of the grid [°C].
    #[arg(long, value_delimiter = ',', default_values_t = [20.0, 55.0, 90.0], value_parser = super::range::celsius, allow_negative_numbers = true)]
    t_oil: Vec<f64>,
    /// Ambient pressure [kPa].
    #[arg(long, value_name = "KPA", default_value_t = 101.0, value_parser = super::range::kpa, allow_negative_numbers = true)]
    p_atm: f64,
    /// The parameters to rank (the others held) [default: B,S,kappa,Di,De,Lv,Db,Lb,r].
    #[arg(long, value_name = "NAME,…", value_delimiter = ',')]
    free: Vec<String>,
    /// Deprecated: --free (--params gives parameter values in the other verbs).
    #[arg(
        long = "params",
        hide = true,
        value_delimiter = ',',
        conflicts_with = "free"
    )]
    params_old: Vec<String>,
    #[command(flatten)]
    model: ModelArgs,
    /// Print JSON: {"parameters": [...], "tests": [{n_rpm, p_int_kpa, t_oil_c, ranking}]}.
    #[arg(long)]
    json: bool,
    /// Directory for the report: report.html, the heat map rank.svg (like the thesis's Fig. 7.1), rank.json.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

#[derive(clap::Args)]
struct FitArgs {
    /// Motored recording: crank-angle basis with `cycle` (or a time basis with the engine
    /// encoder `count_en` and the TDC marker `tdc`), `omega_en`, `p_int`, `T_oil`, `p_atm` and
    /// the torque channel.
    #[arg(long, value_name = "FILE")]
    data: PathBuf,
    #[command(flatten)]
    input: super::InputArgs,
    #[command(flatten)]
    model: ModelArgs,
    /// Motoring torque from the engine load cell (−torque_engine) or the shaft transducer
    /// (+torque_shaft).
    #[arg(long, default_value = "engine")]
    source: String,
    /// How many ranked coefficients to estimate: repeat (the thesis's), wu, rel:FRACTION or an
    /// absolute residual.
    #[arg(long, default_value = "repeat")]
    cutoff: Selection,
    /// Estimate these coefficients (e.g. c4,c17, as a test from `physid design --app friction`
    /// was designed for) instead of the ranked estimable subset; the ranking is still reported.
    #[arg(
        long,
        value_name = "NAME,…",
        value_delimiter = ',',
        conflicts_with = "cutoff"
    )]
    estimate: Vec<String>,
    /// DSFC initial square-root covariance S0 = s0·I, in relative coordinates c = c0·(1 + x).
    #[arg(long, default_value_t = 10.0, value_parser = super::range::positive, allow_negative_numbers = true)]
    s0: f64,
    /// DSFC forgetting factor λ ∈ (0, 1].
    #[arg(long, value_name = "LAMBDA", default_value_t = 1.0, value_parser = super::range::forgetting, allow_negative_numbers = true)]
    lambda: f64,
    /// Start-up transient excluded from the maximum error [s].
    #[arg(long, default_value_t = 5.0, value_parser = super::range::nonnegative, allow_negative_numbers = true)]
    transient: f64,
    /// Ambient pressure [kPa] if the recording has no p_atm channel.
    #[arg(long, value_name = "KPA")]
    p_atm: Option<f64>,
    /// Print JSON: {"estimable", "params", "std_err", "prediction_error_pct": {"final",
    /// "max_after_transient"}, …}.
    #[arg(long)]
    json: bool,
    /// Directory for the report (report.html with its SVGs, friction_fit.json).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Write every steady cycle — its operating point, the measured, one-step predicted,
    /// nominal (and simulated) friction torque, the estimable coefficients and their standard
    /// errors — to this file (.csv, .parquet or .mf4), with units.
    #[arg(long, value_name = "FILE")]
    tracks: Option<PathBuf>,
}

/// Run `physid friction`.
pub fn run(args: &Args) -> Result<()> {
    match &args.command {
        Command::Eval(a) => eval(a),
        Command::Rank(a) => rank::rank(a),
        Command::Fit(a) => fit::fit(a),
    }
}

fn eval(a: &EvalArgs) -> Result<()> {
    let (d, st) = a.model.build()?;
    let op = OperatingPoint {
        n_rpm: a.n,
        p_int_kpa: a.p_int,
        p_atm_kpa: a.p_atm,
        t_oil_c: a.t_oil,
    };
    op.validate().map_err(|e| miette!("{e}"))?;
    let f = fmep(&d, &st, &op);
    let tau = tau_nm(f.total(), &d);
    if a.json {
        let j = serde_json::json!({
            "fmep_kpa": {
                "cfmep": f.cfmep, "rfmep": f.rfmep, "vfmep": f.vfmep,
                "afmep": f.afmep, "pmep": f.pmep, "total": f.total(),
            },
            "tau_fri_nm": tau,
        });
        crate::provenance::print_json(&j)?;
        return Ok(());
    }
    outln!(
        "friction ({} preset) at {} rpm, p_int {} kPa, p_atm {} kPa, oil {} °C",
        a.model.preset,
        a.n,
        a.p_int,
        a.p_atm,
        a.t_oil
    );
    outln!("  component          fmep [kPa]");
    for (name, v) in [
        ("crankshaft (cfmep)", f.cfmep),
        ("reciprocating (rfmep)", f.rfmep),
        ("valvetrain (vfmep)", f.vfmep),
        ("auxiliaries (afmep)", f.afmep),
        ("pumping (pmep)", f.pmep),
    ] {
        outln!("  {name:<22}{v:>10.3}");
    }
    outln!("  {:<22}{:>10.3}", "total", f.total());
    outln!(
        "  friction torque      {tau:>10.4} N·m   (without pumping {:.4} N·m)",
        tau_nm(f.mechanical(), &d)
    );
    Ok(())
}
