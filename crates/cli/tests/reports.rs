//! Reports that read right (docs/cli.md, issue "one vocabulary … reports"): every report and
//! JSON result states its provenance, checked against coreutils' `sha256sum`; parameters carry
//! a unit and a meaning; the shaft plot shows the healthy value, the alarm bounds and the alarm
//! instant, its legend beside the plot (never over the data); the friction headline quotes the
//! error against the measurement.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::physid;

fn sha256sum(path: &std::path::Path) -> String {
    let o = std::process::Command::new("sha256sum")
        .arg(path)
        .output()
        .expect("sha256sum (coreutils)");
    String::from_utf8(o.stdout)
        .unwrap()
        .split_whitespace()
        .next()
        .unwrap()
        .to_string()
}

/// The x coordinates of the SVG `<text>` elements whose content is `label`.
fn text_x(svg: &str, label: &str) -> Vec<f64> {
    let mut xs = Vec::new();
    for part in svg.split("<text").skip(1) {
        let Some((attrs, rest)) = part.split_once('>') else {
            continue;
        };
        let content = rest.split('<').next().unwrap_or("");
        if content.trim() != label {
            continue;
        }
        if let Some(x) = attrs
            .split("x=\"")
            .nth(1)
            .and_then(|v| v.split('"').next())
            .and_then(|v| v.parse().ok())
        {
            xs.push(x);
        }
    }
    xs
}

#[test]
fn a_result_states_where_it_came_from() {
    let dir = physid_testkit::Scratch::new("physid-reports");
    let rec = dir.file("t01.csv");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "4",
        "--fault",
        "shaft.k=1100@2",
        "--recording",
        rec.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    // A --map that renames a column to itself is still a --map the reader was given.
    let out = dir.file("report");
    let o = physid(&[
        "monitor",
        "shaft",
        "--data",
        rec.to_str().unwrap(),
        "--map",
        "torque_shaft=torque_shaft",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let p = &j["provenance"];
    let version = String::from_utf8(physid(&["--version"]).stdout).unwrap();
    assert_eq!(
        version.trim(),
        format!("physid {}", p["physid"].as_str().unwrap())
    );
    let date = p["date"].as_str().unwrap();
    assert!(date.starts_with("20") && date.ends_with('Z'), "{date}");
    let command = p["command"].as_str().unwrap();
    assert!(
        command.starts_with("physid monitor shaft --data ")
            && command.contains("--map torque_shaft=torque_shaft"),
        "{command}"
    );
    let input = &p["inputs"][0];
    assert_eq!(input["path"], rec.to_str().unwrap());
    assert_eq!(input["sha256"], sha256sum(&rec).as_str());
    assert_eq!(
        input["bytes"].as_u64().unwrap(),
        std::fs::metadata(&rec).unwrap().len()
    );
    assert_eq!(p["map"][0], "torque_shaft=torque_shaft");
    // The report's JSON and its HTML say the same.
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("shaft.json")).unwrap()).unwrap();
    assert_eq!(saved["provenance"]["inputs"], p["inputs"]);
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("<h2>Provenance</h2>"));
    assert!(html.contains(&sha256sum(&rec)));
    assert!(html.contains("torque_shaft=torque_shaft"));
    // What was done to the signals before the estimator is stated.
    assert!(
        html.contains("low-passed at 500 Hz (zero phase, Butterworth of order 4), then one sample in 5 taken from the recording's 10000 Hz"),
        "{html}"
    );
    // The plot: the healthy value, the alarm bounds and the alarm's instant in the legend,
    // which sits right of the 960-pixel plotting column.
    let svg = std::fs::read_to_string(out.join("shaft.svg")).unwrap();
    for label in [
        "estimate",
        "±3σ",
        "truth (simulated)",
        "healthy",
        "alarm bounds (±10 %)",
        "alarm raised",
    ] {
        let xs = text_x(&svg, label);
        assert!(!xs.is_empty(), "no legend entry '{label}'");
        assert!(xs.iter().all(|&x| x >= 960.0), "'{label}' at {xs:?}");
    }
}

#[test]
fn the_demo_report_explains_its_parameters() {
    let dir = physid_testkit::Scratch::new("physid-reports-demo");
    let out = dir.file("demo");
    let o = physid(&["demo", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    // Every parameter table has a unit and a meaning: the friction model's design (B is the
    // bore there), its regression coefficients, the cyclic torque's parameters.
    for row in [
        "<td class=\"t\">B</td><td class=\"t\">mm</td><td class=\"t\">bore</td>",
        "<td class=\"t\">c1</td><td class=\"t\">kPa·mm²</td><td class=\"t\">crankshaft seals: Db/(B²·S·nc)</td>",
        "<td class=\"t\">M_rec</td><td class=\"t\">kg</td><td class=\"t\">reciprocating mass",
        "<td class=\"t\">b</td><td class=\"t\">m</td><td class=\"t\">bore</td>",
    ] {
        assert!(html.contains(row), "missing {row}");
    }
    // The friction headline is the error a user has: against the measured cycle means.
    assert!(html.contains("Prediction error against the measured cycle means"));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert!(summary["provenance"]["command"]
        .as_str()
        .unwrap()
        .starts_with("physid demo --out "));
    // The demo reads no file: it simulates its recordings.
    assert_eq!(summary["provenance"]["inputs"], serde_json::json!([]));
}

/// `cycles --tracks` and `compression fit --tracks`: the per-cycle and per-TDC tables a user
/// takes away, in the format the extension names, equal to the JSON result.
#[test]
fn per_cycle_results_are_written_as_tracks() {
    let dir = physid_testkit::Scratch::new("physid-reports-cycles");
    let rec = dir.file("motored.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "friction-sweep",
        "--basis",
        "crank",
        "--duration",
        "2",
        "--recording",
        rec.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let tracks = dir.file("cycles.mf4");
    let o = physid(&[
        "cycles",
        rec.to_str().unwrap(),
        "--json",
        "--tracks",
        tracks.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // Read with only the channels it takes (the pressure, cycle, crank_deg, t), the analysis
    // answers as on the whole file.
    j.as_object_mut().unwrap().remove("provenance");
    let whole = physid_io::read(&rec, &Default::default()).unwrap();
    let want =
        physid_apps::pressure::analyse(&whole, "p_cyl", None, physid_apps::pressure::Pegging::None)
            .unwrap();
    assert_eq!(j, serde_json::to_value(&want).unwrap());
    let cycles = j["cycles"].as_array().unwrap();
    assert!(cycles.len() >= 10, "{}", cycles.len());
    let t = physid_io::read(&tracks, &Default::default()).unwrap();
    assert_eq!(t.channel("p_max").unwrap().unit, "Pa");
    for (k, c) in cycles.iter().enumerate() {
        assert_eq!(t.values("p_max").unwrap()[k], c["p_max"].as_f64().unwrap());
        assert_eq!(t.values("rpm").unwrap()[k], c["rpm"].as_f64().unwrap());
        assert_eq!(t.values("cycle").unwrap()[k], c["cycle"].as_f64().unwrap());
    }
    let tracks = dir.file("tdc.csv");
    let o = physid(&[
        "compression",
        "fit",
        "--data",
        rec.to_str().unwrap(),
        "--stroke",
        "0.0514",
        "--rod",
        "0.088",
        "--json",
        "--tracks",
        tracks.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let t = physid_io::read(&tracks, &Default::default()).unwrap();
    assert_eq!(t.len(), j["events"].as_array().unwrap().len());
}

/// `cycles --out DIR` on the fired virtual cell (`fired-steady`, a crank-angle recording): the
/// report draws the mean cycle and the chosen one (pressure, heat release rate, mass fraction
/// burned; p–V, log p–log V; the trends), `cycles.json` carries the mean cycle, whose IMEP —
/// linear in the pressure — is the cycles' mean IMEP, and `tracks.csv` a row per cycle; a cycle
/// that is not there is refused by name.
#[test]
fn the_combustion_report_draws_the_mean_and_a_chosen_cycle() {
    let s = physid_testkit::Scratch::new("physid-cycles-report");
    let rec = s.file("fired.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "fired-steady",
        "--duration",
        "1",
        "--basis",
        "crank",
        "--recording",
        rec.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let dir = s.file("report");
    let args = |extra: &[&str]| {
        let mut a = vec![
            "cycles",
            rec.to_str().unwrap(),
            "--bore",
            "0.054",
            "--stroke",
            "0.0514",
            "--rod",
            "0.088",
            "--compression-ratio",
            "9.5",
            "--out",
            dir.to_str().unwrap(),
        ];
        a.extend_from_slice(extra);
        physid(&a)
    };
    let o = args(&["--report-cycle", "3"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    for want in [
        "mean of",
        "cycle 3",
        "mass fraction burned",
        "p–V diagram",
        "Per-cycle trends",
    ] {
        assert!(html.contains(want), "{want}");
    }
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("cycles.json")).unwrap()).unwrap();
    let cycles = j["cycles"].as_array().unwrap();
    let mean = &j["mean_cycle"];
    assert_eq!(mean["cycle"].as_u64().unwrap() as usize, cycles.len());
    let imep: f64 = cycles
        .iter()
        .map(|c| c["imep_pa"].as_f64().unwrap())
        .sum::<f64>()
        / cycles.len() as f64;
    assert!(
        (mean["imep_pa"].as_f64().unwrap() / imep - 1.0).abs() < 1e-9,
        "{mean}"
    );
    assert_eq!(mean["fired"], true);
    let csv = std::fs::read_to_string(dir.join("tracks.csv")).unwrap();
    assert_eq!(csv.lines().count(), 2 + cycles.len());
    let o = args(&["--report-cycle", "999"]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("--report-cycle 999: no such complete cycle"),
        "{e}"
    );
    // Without the geometry there is no heat release: the report draws the pressure alone
    // (it used to panic slicing the empty heat release).
    let bare = s.file("bare");
    let o = physid(&[
        "cycles",
        rec.to_str().unwrap(),
        "--out",
        bare.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = std::fs::read_to_string(bare.join("report.html")).unwrap();
    assert!(html.contains("mean of"), "the mean cycle is drawn");
    assert!(
        !html.contains("mass fraction burned"),
        "no heat release drawn"
    );
}
