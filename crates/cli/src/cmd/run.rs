//! `physid run PIPELINE.toml`: the qualitative adaptive identification loop (thesis Fig. 5.7)
//! from a file — identifiability, estimation of the estimable subset, the objective.

use crate::out::outln;
use crate::plot::{self, Panel, Series, PALETTE};
use crate::report::{self, Report};
use miette::{miette, Result};
use physid_apps::pipeline::{run_pipeline_data, Pipeline, PipelineResult};
use std::path::{Path, PathBuf};

/// Arguments of `physid run`.
#[derive(clap::Args)]
pub struct Args {
    /// The pipeline file (TOML: [model], [data], [identifiability], [estimator], [objective];
    /// see docs/pipeline.md).
    pipeline: PathBuf,
    /// Print JSON: {"estimable", "params", "std_err", "unresolved", "objective": {"metric", "value_pct",
    /// "limit_pct", "met"}, …}.
    #[arg(long)]
    json: bool,
    /// Directory for the report (report.html with its SVGs, pipeline.json).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Write the run's tracks — time, measured output, one-step prediction and each estimated
    /// parameter, at the report's ≈ 4000 points — to this file (.csv, .parquet or .mf4).
    #[arg(long, value_name = "FILE")]
    tracks: Option<PathBuf>,
}

fn report<'a>(r: &'a PipelineResult, p: &'a Pipeline, file: &Path, dir: &Path) -> Result<Report> {
    let mut rep = Report::new(
        "physid — qualitative adaptive identification",
        &format!("{}", file.display()),
    );
    rep.section("Identifiability (Alg. 5.1)");
    rep.para(
        &format!(
            "{} rows; scaling {}, cut-off {}; held by design: {}.",
            r.rows,
            p.identifiability.scaling,
            p.identifiability.cutoff,
            if p.model.fixed.is_empty() {
                "none".to_string()
            } else {
                p.model.fixed.join(", ")
            }
        ),
        None,
    );
    // A built-in model's parameters have units and meanings; a formula's are the user's
    // (model.units, model.descriptions).
    let names: Vec<&str> = r.names.iter().map(String::as_str).collect();
    let text = |m: &'a std::collections::BTreeMap<String, String>, none: &'a str| -> Vec<&'a str> {
        r.names
            .iter()
            .map(|n| m.get(n).map_or(none, String::as_str))
            .collect()
    };
    let (units, descriptions) = (text(&p.model.units, "—"), text(&p.model.descriptions, ""));
    let glossary = p
        .model
        .builtin
        .as_deref()
        .and_then(physid_apps::model_choice::glossary)
        .map_or(
            report::Glossary {
                names: &names,
                units: &units,
                descriptions: &descriptions,
            },
            |(names, units, descriptions)| report::Glossary {
                names,
                units,
                descriptions,
            },
        );
    rep.ranking(
        &r.ranking,
        glossary,
        "Residual profile (Alg. 5.1)",
        &dir.join("pipeline_residuals.svg"),
    )?;
    rep.section(&format!("Estimation ({})", r.method));
    rep.table(
        &[
            "parameter",
            "unit",
            "meaning",
            "nominal",
            "final",
            "std error",
        ],
        &r.names
            .iter()
            .enumerate()
            .filter(|(_, n)| r.estimable.contains(n))
            .map(|(j, n)| {
                let (unit, meaning) = glossary.of(n);
                vec![
                    n.clone(),
                    unit,
                    meaning,
                    format!("{:.6e}", r.nominal[j]),
                    format!("{:.6e}", r.params[j]),
                    r.std_err[j].map_or("unresolved by the data".into(), |s| format!("{s:.2e}")),
                ]
            })
            .collect::<Vec<_>>(),
    );
    let o = &r.objective;
    rep.para(
        &format!(
            "Objective: one-step-ahead prediction {} {:.3} % {} the limit {} % over {} samples after {} s — {}.",
            o.metric,
            o.value_pct,
            if o.met { "within" } else { "beyond" },
            o.limit_pct,
            o.samples,
            p.objective.after_s,
            if o.met { "MET" } else { "NOT MET: refine — another experiment (more excitation) or another subset" }
        ),
        Some(if o.met { "ok" } else { "alarm" }),
    );
    let svg = dir.join("pipeline.svg");
    let mut panels = vec![Panel {
        ylabel: format!("{} (output)", p.model.output),
        series: vec![
            Series {
                name: "measured".into(),
                x: &r.t,
                y: &r.measured,
                color: PALETTE[1],
                reference: true,
            },
            Series {
                name: "one-step prediction".into(),
                x: &r.t,
                y: &r.predicted,
                color: PALETTE[0],
                reference: false,
            },
        ],
        ..Default::default()
    }];
    for (name, v) in &r.tracks {
        let (unit, _) = glossary.of(name);
        panels.push(Panel {
            ylabel: if unit == "—" {
                name.clone()
            } else {
                format!("{name} [{unit}]")
            },
            series: vec![Series {
                name: "estimate".into(),
                x: &r.t,
                y: v,
                color: PALETTE[0],
                reference: false,
            }],
            ..Default::default()
        });
    }
    plot::panels(&svg, "Prediction and parameter tracks", "time [s]", &panels)?;
    rep.svg(&svg)?;
    Ok(rep)
}

/// Run `physid run`.
pub fn run(args: &Args) -> Result<()> {
    let p = Pipeline::load(&args.pipeline).map_err(|e| miette!("{e}"))?;
    let working = crate::progress::Working::new(&format!("running {}", args.pipeline.display()));
    if let Some(f) = p.data.file.as_ref().filter(|_| p.data.scenario.is_none()) {
        crate::provenance::record_input(f, &[]);
    }
    let (r, rec) = run_pipeline_data(&p, super::hold_bytes()?)
        .map_err(|e| miette!("{}: {e}", args.pipeline.display()))?;
    drop(working);
    let j = r.summary();
    if let Some(path) = &args.tracks {
        // The output as the model takes it: CHANNEL or CHANNEL:UNIT.
        let y_unit = match p.model.output.split_once(':') {
            Some((_, unit)) => unit.to_string(),
            None => rec
                .channel(&p.model.output)
                .map(|c| c.unit.clone())
                .unwrap_or_default(),
        };
        let mut columns: Vec<(String, String)> = vec![
            ("t".into(), "s".into()),
            ("measured".into(), y_unit.clone()),
            ("predicted".into(), y_unit),
        ];
        columns.extend(r.tracks.iter().map(|(n, _)| (n.clone(), String::new())));
        let mut f = crate::tracks::TrackFile::create(path, columns)?;
        for k in 0..r.t.len() {
            f.row(
                [r.t[k], r.measured[k], r.predicted[k]]
                    .into_iter()
                    .chain(r.tracks.iter().map(|(_, v)| v[k])),
            )?;
        }
        f.close()?;
    }
    if let Some(dir) = &args.out {
        report::create_dir(dir)?;
        let rep = report(&r, &p, &args.pipeline, dir)?;
        report::finish(dir, rep, "pipeline.json", &j)?;
    }
    if args.json {
        crate::provenance::print_json(&j)?;
    } else {
        outln!("{}: {} rows", args.pipeline.display(), r.rows);
        outln!("  estimable: {}", r.estimable.join(", "));
        for (j, n) in r.names.iter().enumerate() {
            if !r.estimable.contains(n) {
                continue;
            }
            outln!(
                "  {n:<10} {:>14.6e} → {:>14.6e} {}",
                r.nominal[j],
                r.params[j],
                r.std_err[j].map_or("(unresolved by the data)".into(), |se| format!(
                    "± {se:.2e}"
                ))
            );
        }
        let o = &r.objective;
        outln!(
            "  objective: {} {:.3} % (limit {} %) — {}",
            o.metric,
            o.value_pct,
            o.limit_pct,
            if o.met { "met" } else { "NOT met" }
        );
        if let Some(dir) = &args.out {
            outln!("wrote {}", dir.join("report.html").display());
        }
    }
    if r.objective.met {
        Ok(())
    } else {
        Err(miette!(
            "the objective was not met ({} {:.3} % > {} %)",
            r.objective.metric,
            r.objective.value_pct,
            r.objective.limit_pct
        ))
    }
}
