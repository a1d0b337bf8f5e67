//! `physid friction`: the mean-value friction model (SPEC §2.5) — `eval` at an operating point,
//! `rank` of its design parameters over an operating grid (thesis §7.2, Table 7.1, Fig. 7.1).

use crate::out::outln;
use crate::plot;
use miette::{miette, IntoDiagnostic, Result, WrapErr};
use physid_apps::friction_rank::{friction_rank, RankGrid, RankTable};
use physid_models::friction::{
    fmep, preset, set_by_name, tau_nm, Design, OperatingPoint, Settings, PRESETS,
};
use std::path::PathBuf;

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
}

/// The model: preset and overrides.
#[derive(clap::Args)]
struct ModelArgs {
    /// Model preset: thesis (the thesis's code) or sandoval2002 (the original model).
    #[arg(long, default_value = "thesis")]
    preset: String,
    /// Override a design parameter (B, S, kappa, Di, De, Lv, Db, Lb, r — mm) or a setting
    /// (oil, valvetrain, ft_fto, cr, nc, nv, nb); repeatable, e.g. --set B=56 --set oil=SAE30.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
}

impl ModelArgs {
    fn build(&self) -> Result<(Design<f64>, Settings)> {
        let (mut d, mut st) = preset(&self.preset).ok_or_else(|| {
            miette!(
                "no friction preset '{}'; the presets are {}",
                self.preset,
                PRESETS.join(", ")
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
    #[arg(long)]
    n: f64,
    /// Intake manifold pressure [kPa].
    #[arg(long)]
    p_int: f64,
    /// Oil temperature [°C].
    #[arg(long)]
    t_oil: f64,
    /// Ambient pressure [kPa] (the thesis code's 101 kPa).
    #[arg(long, default_value_t = 101.0)]
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
    #[arg(long, value_delimiter = ',', default_values_t = [1000.0, 3000.0, 5000.0])]
    n: Vec<f64>,
    /// Intake manifold pressures of the grid [kPa].
    #[arg(long, value_delimiter = ',', default_values_t = [10.0, 55.0, 100.0])]
    p_int: Vec<f64>,
    /// Oil temperatures of the grid [°C].
    #[arg(long, value_delimiter = ',', default_values_t = [20.0, 55.0, 90.0])]
    t_oil: Vec<f64>,
    /// Ambient pressure [kPa].
    #[arg(long, default_value_t = 101.0)]
    p_atm: f64,
    /// The parameters to rank [default: B,S,kappa,Di,De,Lv,Db,Lb,r].
    #[arg(long, value_delimiter = ',')]
    params: Vec<String>,
    #[command(flatten)]
    model: ModelArgs,
    /// Print JSON: {"parameters": [...], "tests": [{n_rpm, p_int_kpa, t_oil_c, ranking}]}.
    #[arg(long)]
    json: bool,
    /// Directory for the heat map rank.svg (like the thesis's Fig. 7.1).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Run `physid friction`.
pub fn run(args: &Args) -> Result<()> {
    match &args.command {
        Command::Eval(a) => eval(a),
        Command::Rank(a) => rank(a),
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
        outln!("{}", serde_json::to_string_pretty(&j).into_diagnostic()?);
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

fn rank(a: &RankArgs) -> Result<()> {
    let (d, st) = a.model.build()?;
    let grid = RankGrid {
        n_rpm: a.n.clone(),
        p_int_kpa: a.p_int.clone(),
        t_oil_c: a.t_oil.clone(),
        p_atm_kpa: a.p_atm,
    };
    let t = friction_rank(&d, &st, &grid, &a.params).map_err(|e| miette!("{e}"))?;
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir)
            .into_diagnostic()
            .wrap_err_with(|| format!("creating {}", dir.display()))?;
        let svg = dir.join("rank.svg");
        heatmap(&t, &a.model.preset, &svg)?;
        if !a.json {
            outln!("wrote {}", svg.display());
        }
    }
    if a.json {
        let tests: Vec<_> = t
            .tests
            .iter()
            .map(|x| {
                serde_json::json!({
                    "n_rpm": x.op.n_rpm,
                    "p_int_kpa": x.op.p_int_kpa,
                    "t_oil_c": x.op.t_oil_c,
                    "tau_fri_nm": x.tau_nm,
                    "ranking": x.order.iter().map(|&j| &t.parameters[j]).collect::<Vec<_>>(),
                    "sensitivity": t.parameters.iter().zip(&x.sensitivity)
                        .map(|(p, z)| (p.clone(), serde_json::json!(z)))
                        .collect::<serde_json::Map<_, _>>(),
                })
            })
            .collect();
        let j = serde_json::json!({"parameters": t.parameters, "tests": tests});
        outln!("{}", serde_json::to_string_pretty(&j).into_diagnostic()?);
        return Ok(());
    }
    outln!(
        "Rank of each design parameter by |normalised sensitivity| of the friction torque (1 = most sensitive; {} preset, p_atm {} kPa)",
        a.model.preset,
        a.p_atm
    );
    let mut head = format!(
        "{:>4} {:>6} {:>6} {:>6} {:>8} ",
        "test", "N", "p_int", "T_oil", "τ_fri"
    );
    for p in &t.parameters {
        head.push_str(&format!("{p:>6}"));
    }
    outln!("{head}");
    outln!(
        "{:>4} {:>6} {:>6} {:>6} {:>8}",
        "",
        "rpm",
        "kPa",
        "°C",
        "N·m"
    );
    for (i, x) in t.tests.iter().enumerate() {
        let mut line = format!(
            "{:>4} {:>6} {:>6} {:>6} {:>8.4} ",
            i + 1,
            x.op.n_rpm,
            x.op.p_int_kpa,
            x.op.t_oil_c,
            x.tau_nm
        );
        for r in &x.rank {
            line.push_str(&format!("{r:>6}"));
        }
        outln!("{line}");
    }
    Ok(())
}

/// The heat map of a ranking table (thesis Fig. 7.1) as SVG.
pub fn heatmap(t: &RankTable, preset: &str, path: &std::path::Path) -> Result<()> {
    let rows: Vec<String> = t
        .tests
        .iter()
        .enumerate()
        .map(|(i, x)| {
            format!(
                "{:>2}: {} rpm, {} kPa, {} °C",
                i + 1,
                x.op.n_rpm,
                x.op.p_int_kpa,
                x.op.t_oil_c
            )
        })
        .collect();
    let ranks: Vec<Vec<usize>> = t.tests.iter().map(|x| x.rank.clone()).collect();
    plot::rank_heatmap(
        path,
        &format!("Friction design-parameter ranks ({preset}; 1 = most sensitive)"),
        &rows,
        &t.parameters,
        &ranks,
    )
}
