//! `physid example 5.2`: thesis Example 5.2 — CSV of the estimates and a plot like Fig. 5.6.

use crate::out::{out, outln};
use crate::plot::{self, Panel, Series, PALETTE};
use crate::report::Report;
use miette::{miette, IntoDiagnostic, Result};
use physid_apps::example_5_1::example_5_1_data;
use physid_apps::example_5_2::{example_5_2, Example52, Example52Config};
use physid_core::{Basis, Channel, Recording};
use std::path::PathBuf;

/// Arguments of `physid example`.
#[derive(clap::Args)]
pub struct Args {
    /// Which example: 5.1 (which parameters are estimable: the orthogonal ranking) or 5.2
    /// (RLS, RLSF and vector forgetting tracking a parameter step).
    pub id: String,
    /// Directory for the CSV and SVG [default: physid-out/example-<id>].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Run the example.
pub fn run(args: &Args) -> Result<()> {
    match args.id.as_str() {
        "5.1" => run_5_1(args),
        "5.2" => run_5_2(args),
        other => Err(miette!(
            "no example '{other}'; the examples are: 5.1 (identifiability), 5.2 (tracking)"
        )),
    }
}

/// Example 5.1: write the generated data as CSV, then analyse it exactly as
/// `physid identify --data <csv> --model example-5.1` does.
fn run_5_1(args: &Args) -> Result<()> {
    let d = example_5_1_data(51);
    let dir = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("physid-out/example-5.1"));
    crate::report::create_dir(&dir)?;
    let csv = dir.join("example-5.1.csv");
    let mut rec = Recording::new(Basis::Time);
    for (name, v) in [("t", &d.t), ("x", &d.x), ("y", &d.y), ("z", &d.z)] {
        rec.push(Channel {
            name: name.into(),
            unit: if name == "t" {
                "s".into()
            } else {
                String::new()
            },
            values: v.clone(),
        })
        .into_diagnostic()?;
    }
    physid_io::write_csv(&csv, &rec).into_diagnostic()?;
    if !args.json {
        outln!("Thesis Example 5.1: z = sin(A)·x + B²·y·cos(x) + sqrt(C)·x² + D·y² + E·x/y + F·2x/y, A…F = 1…6");
        outln!(
            "(x = 30·sin(0.7t), y = 30 + 3·cos(0.45t), each plus unit white noise; 100 Hz, 20 s)\n"
        );
    }
    let reports = super::identify::analyse_files(&super::identify::Args {
        data: vec![csv.clone()],
        expr: None,
        params: Vec::new(),
        model: Some("example-5.1".into()),
        y: None,
        scaling: physid_ident::Scaling::Thesis,
        scaling_guard: 1e-3,
        guard_old: None,
        centre: false,
        cutoff: physid_ident::Selection::Rule(physid_ident::Cutoff::Repeat),
        cutoff_rel: None,
        free: Vec::new(),
        sigma: None,
        input: super::InputArgs {
            units_row: true, // write_csv wrote the units row
            ..Default::default()
        },
        json: args.json,
    })?;
    let report = reports.into_iter().next().unwrap_or_default();
    let mut rep = Report::new(
        "physid — thesis Example 5.1",
        "z = sin(A)·x + B²·y·cos(x) + sqrt(C)·x² + D·y² + E·x/y + F·2x/y, A…F = 1…6; x = 30·sin(0.7t), y = 30 + 3·cos(0.45t), each plus unit white noise; 100 Hz, 20 s",
    );
    rep.section("Identifiability ranking (Alg. 5.1, thesis scaling, repeat cut-off)");
    let rows: Vec<Vec<String>> = report["ranking"]
        .as_array()
        .map(|a| {
            a.iter()
                .enumerate()
                .map(|(i, s)| {
                    vec![
                        (i + 1).to_string(),
                        s["param"].as_str().unwrap_or("").to_string(),
                        format!("{:.4e}", s["residual_ss"].as_f64().unwrap_or(f64::NAN)),
                        format!("{:.4e}", s["relative"].as_f64().unwrap_or(f64::NAN)),
                    ]
                })
                .collect()
        })
        .unwrap_or_default();
    rep.table(&["rank", "parameter", "residual SS", "relative"], &rows);
    rep.para(
        &format!(
            "Not identifiable: {}. The data: {}.",
            report["unidentifiable"]
                .as_array()
                .map(|a| a
                    .iter()
                    .filter_map(|v| v.as_str())
                    .collect::<Vec<_>>()
                    .join(", "))
                .unwrap_or_default(),
            csv.display()
        ),
        None,
    );
    rep.write(&dir.join("report.html"))?;
    std::fs::write(
        dir.join("example-5.1.json"),
        serde_json::to_string_pretty(&crate::provenance::with(&report)).into_diagnostic()?,
    )
    .into_diagnostic()?;
    if args.json {
        crate::provenance::print_json(&report)?;
    } else {
        outln!(
            "\nwrote {} and {}",
            csv.display(),
            dir.join("report.html").display()
        );
    }
    Ok(())
}

fn run_5_2(args: &Args) -> Result<()> {
    let r = example_5_2(&Example52Config::default()).into_diagnostic()?;
    let dir = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("physid-out/example-5.2"));
    crate::report::create_dir(&dir)?;
    let csv = dir.join("example-5.2.csv");
    physid_io::write_csv(&csv, &recording(&r)).into_diagnostic()?;
    let svg = dir.join("example-5.2.svg");
    plot_5_2(&r, &svg)?;
    let mut rep = Report::new(
        "physid — thesis Example 5.2",
        "z = A(t)·sin(x) + B·y², A steps 10 → 4 at t = 5 s, B = 0.5; 1 kHz, noise σ = 0.01, ϑ0 = 0, P0 = 1000·I; RLSF λ = 0.97; vector forgetting Λ = diag(0.97, 1)",
    );

    let at = |t: f64| {
        r.t.iter()
            .position(|&s| s >= t - 1e-9)
            .unwrap_or(r.t.len() - 1)
    };
    let times = [4.99, 5.1, 7.0, 10.0];
    rep.section("Estimates of A and B (cf. thesis Fig. 5.6)");
    let mut header = vec!["method".to_string()];
    header.extend(times.iter().map(|t| format!("A, B at {t} s")));
    let mut rows: Vec<Vec<String>> = r
        .tracks
        .iter()
        .map(|tr| {
            let mut row = vec![tr.method.clone()];
            row.extend(
                times
                    .iter()
                    .map(|&t| format!("{:.3}, {:.4}", tr.a[at(t)], tr.b[at(t)])),
            );
            row
        })
        .collect();
    let mut truth = vec!["truth".to_string()];
    truth.extend(
        times
            .iter()
            .map(|&t| format!("{:.3}, {:.4}", r.a_true[at(t)], r.b_true)),
    );
    rows.push(truth);
    rep.table(
        &header.iter().map(String::as_str).collect::<Vec<_>>(),
        &rows,
    );
    rep.svg(&svg)?;
    rep.write(&dir.join("report.html"))?;
    if args.json {
        let mut methods = serde_json::Map::new();
        for tr in &r.tracks {
            let pts: Vec<_> = times
                .iter()
                .map(|&t| serde_json::json!({"t_s": t, "A": tr.a[at(t)], "B": tr.b[at(t)]}))
                .collect();
            methods.insert(tr.method.clone(), serde_json::Value::Array(pts));
        }
        let out = serde_json::json!({"example": "5.2", "estimates": methods,
            "csv": csv.display().to_string(), "svg": svg.display().to_string()});
        let text =
            serde_json::to_string_pretty(&crate::provenance::with(&out)).into_diagnostic()?;
        std::fs::write(dir.join("example-5.2.json"), &text).into_diagnostic()?;
        outln!("{text}");
        return Ok(());
    }
    outln!("Thesis Example 5.2: z = A(t)·sin(x) + B·y², A steps 10 → 4 at t = 5 s, B = 0.5");
    outln!("(1 kHz, noise σ = 0.01, ϑ0 = 0, P0 = 1000·I; RLSF λ = 0.97; vector forgetting Λ = diag(0.97, 1))\n");
    out!("{:<8}", "method");
    for t in times {
        out!("  {:>17}", format!("A, B at {t} s"));
    }
    outln!();
    for tr in &r.tracks {
        out!("{:<8}", tr.method);
        for t in times {
            let k = at(t);
            out!("  {:>8.3} {:>8.4}", tr.a[k], tr.b[k]);
        }
        outln!();
    }
    out!("{:<8}", "truth");
    for t in times {
        out!("  {:>8.3} {:>8.4}", r.a_true[at(t)], r.b_true);
    }
    outln!();
    outln!(
        "\nwrote {}, {} and {}",
        csv.display(),
        svg.display(),
        dir.join("report.html").display()
    );
    Ok(())
}

fn recording(r: &Example52) -> Recording {
    let mut rec = Recording::new(Basis::Time);
    let mut add = |name: &str, unit: &str, values: Vec<f64>| {
        // Names are distinct and lengths equal by construction.
        let _ = rec.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values,
        });
    };
    add("t", "s", r.t.clone());
    add("x", "", r.x.clone());
    add("y", "", r.y.clone());
    add("z", "", r.z.clone());
    add("A_true", "", r.a_true.clone());
    add("B_true", "", vec![r.b_true; r.t.len()]);
    for tr in &r.tracks {
        add(&format!("A_{}", tr.method), "", tr.a.clone());
        add(&format!("B_{}", tr.method), "", tr.b.clone());
    }
    rec
}

fn plot_5_2(r: &Example52, path: &std::path::Path) -> Result<()> {
    let b_true = vec![r.b_true; r.t.len()];
    let label = |m: &str| match m {
        "rls" => "RLS".to_string(),
        "rlsf" => "RLSF (λ = 0.97)".to_string(),
        "rlsvf" => "vector forgetting (0.97, 1)".to_string(),
        other => other.to_string(),
    };
    let mut panels = Vec::new();
    for (name, truth, pick) in [("A", &r.a_true, 0usize), ("B", &b_true, 1usize)] {
        let mut series = vec![Series {
            name: "truth".into(),
            x: &r.t,
            y: truth,
            color: plotters::style::RGBColor(80, 80, 80),
            reference: true,
        }];
        for (i, tr) in r.tracks.iter().enumerate() {
            series.push(Series {
                name: label(&tr.method),
                x: &r.t,
                y: if pick == 0 { &tr.a } else { &tr.b },
                color: PALETTE[i % PALETTE.len()],
                reference: false,
            });
        }
        panels.push(Panel {
            ylabel: name.into(),
            series,
            ..Default::default()
        });
    }
    plot::panels(
        path,
        "Example 5.2 — tracking a step in A (cf. thesis Fig. 5.6)",
        "t [s]",
        &panels,
    )
}
