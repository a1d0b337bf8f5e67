//! `physid friction rank`: the design parameters ranked over an operating grid (thesis §7.2,
//! Table 7.1), the heat map (Fig. 7.1) and the parameters' table.

use super::*;

pub(super) fn rank(a: &RankArgs) -> Result<()> {
    let (d, st) = a.model.build()?;
    let grid = RankGrid {
        n_rpm: a.n.clone(),
        p_int_kpa: a.p_int.clone(),
        t_oil_c: a.t_oil.clone(),
        p_atm_kpa: a.p_atm,
    };
    let working = crate::progress::Working::new("ranking the design parameters over the grid");
    let free = if a.params_old.is_empty() {
        &a.free
    } else {
        crate::cmd::deprecated("--params NAME,… in friction rank is now --free NAME,…");
        &a.params_old
    };
    let t = friction_rank(&d, &st, &grid, free).map_err(|e| miette!("{e}"))?;
    drop(working);
    if let Some(dir) = &a.out {
        report::create_dir(dir)?;
        let svg = dir.join("rank.svg");
        heatmap(&t, &a.model.preset, &svg)?;
        let mut rep = Report::new(
            "physid — friction design-parameter ranking",
            &format!(
                "Mean-value friction model ({} preset), p_atm {} kPa (thesis §7.2, Table 7.1, Fig. 7.1)",
                a.model.preset, a.p_atm
            ),
        );
        rep.section("Rank of each design parameter (1 = most sensitive)");
        rep.para("By |normalised sensitivity| (ϑ/τ)·∂τ/∂ϑ of the friction torque, exact derivatives, at each operating point.", None);
        let mut header = vec![
            "test",
            "N [rpm]",
            "p_int [kPa]",
            "T_oil [°C]",
            "τ_fri [N·m]",
        ];
        header.extend(t.parameters.iter().map(String::as_str));
        let rows: Vec<Vec<String>> = t
            .tests
            .iter()
            .enumerate()
            .map(|(i, x)| {
                let mut row = vec![
                    (i + 1).to_string(),
                    x.op.n_rpm.to_string(),
                    x.op.p_int_kpa.to_string(),
                    x.op.t_oil_c.to_string(),
                    format!("{:.4}", x.tau_nm),
                ];
                row.extend(x.rank.iter().map(|r| r.to_string()));
                row
            })
            .collect();
        rep.table(&header, &rows);
        rep.svg(&svg)?;
        design_table(&mut rep, &t.parameters);
        report::finish(dir, rep, "rank.json", &t.summary())?;
        if !a.json {
            outln!(
                "wrote {} and {}",
                svg.display(),
                dir.join("report.html").display()
            );
        }
    }
    if a.json {
        crate::provenance::print_json(&t.summary())?;
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

/// The friction model's design parameters `names` with their units and meanings, as a table.
pub fn design_table(rep: &mut Report, names: &[String]) {
    let g = report::Glossary {
        names: &physid_models::friction::DESIGN_PARAMS,
        units: &physid_models::friction::DESIGN_UNITS,
        descriptions: &physid_models::friction::DESIGN_DESCRIPTIONS,
    };
    let rows: Vec<Vec<String>> = names
        .iter()
        .map(|n| {
            let (unit, meaning) = g.of(n);
            vec![n.clone(), unit, meaning]
        })
        .collect();
    rep.table(&["parameter", "unit", "meaning"], &rows);
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
