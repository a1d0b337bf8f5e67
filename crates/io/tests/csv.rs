//! CSV as physid writes it and as test-cell software writes it: a units row found by content,
//! `name [unit]` headers, `;` separators with decimal commas, tabs, CRLF line ends numbered as
//! an editor numbers them, a cut-short last line, errors that name the line and column — and
//! pandas reading physid's CSV with its one documented option (`golden/csv/gen_pandas.py`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::{Basis, Channel, Recording};
use physid_io::{read, read_csv, write_csv, CsvOptions, ReadOptions};
use physid_testkit::Scratch;
use std::path::PathBuf;

fn golden() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden/csv")
}

fn plain(path: &std::path::Path) -> Result<Recording, String> {
    read(path, &ReadOptions::default()).map_err(|e| e.to_string())
}

#[test]
fn physid_reads_the_csv_it_writes_with_no_option() {
    let s = Scratch::new("physid-io");
    let mut r = Recording::new(Basis::Time);
    for (name, unit, v) in [
        ("t", "s", vec![0.0, 1e-4, 2e-4]),
        (
            "omega_en",
            "rad/s",
            vec![104.71975511965977, 0.1, 1.0 / 3.0],
        ),
        ("count_en", "-", vec![0.0, 1.0, 1.0]),
        ("flag", "", vec![1.0, 0.0, f64::NAN]),
    ] {
        r.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values: v,
        })
        .unwrap();
    }
    let f = s.file("w.csv");
    write_csv(&f, &r).unwrap();
    let text = std::fs::read_to_string(&f).unwrap();
    assert!(
        text.starts_with("t,omega_en,count_en,flag\ns,rad/s,-,\n0,"),
        "{text}"
    );
    let back = plain(&f).unwrap();
    assert_eq!(back.names(), r.names());
    for ch in r.channels() {
        let b = back.channel(&ch.name).unwrap();
        assert_eq!(b.unit, ch.unit);
        assert!(b
            .values
            .iter()
            .zip(&ch.values)
            .all(|(x, y)| x == y || (x.is_nan() && y.is_nan())));
    }
    assert_eq!(back.meta["first_data_line"], "3");
    // Without units nothing is written for them, and nothing is skipped on reading.
    let mut bare = r.clone();
    bare = {
        let mut q = Recording::new(Basis::Time);
        for c in bare.channels() {
            q.push(Channel {
                unit: String::new(),
                ..c.clone()
            })
            .unwrap();
        }
        q
    };
    write_csv(&f, &bare).unwrap();
    let back = plain(&f).unwrap();
    assert_eq!(back.len(), 3);
    assert_eq!(back.meta["first_data_line"], "2");
}

#[test]
fn test_cell_exports_semicolons_decimal_commas_tabs_and_bracketed_units() {
    let s = Scratch::new("physid-io");
    // European test-cell software: ';' separators, decimal commas, units in a second row.
    let f = s.file("eu.csv");
    std::fs::write(
        &f,
        "Zeit;omega_en;p_int\r\ns;rpm;bar\r\n0,000;1000;0,95\r\n0,001;1500,5;1,013\r\n",
    )
    .unwrap();
    let r = read(
        &f,
        &ReadOptions {
            map: ReadOptions::parse_map(&["t=Zeit".into()]).unwrap(),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(r.values("t").unwrap(), [0.0, 0.001]);
    let w = r.values("omega_en").unwrap();
    assert!((w[0] - 1000.0 * std::f64::consts::PI / 30.0).abs() < 1e-12);
    assert!((w[1] - 1500.5 * std::f64::consts::PI / 30.0).abs() < 1e-12);
    let p = r.values("p_int").unwrap();
    assert!((p[0] - 95_000.0).abs() < 1e-9 && (p[1] - 101_300.0).abs() < 1e-9);
    // Tabs, and units in the header as `name [unit]`.
    let f = s.file("tab.txt");
    std::fs::write(&f, "t [s]\tT_oil [°C]\tx\n0\t90\t1,5\n1\t91\t2\n").unwrap();
    let r = plain(&f).unwrap();
    assert_eq!(r.names(), ["t", "T_oil", "x"]);
    assert_eq!(r.channel("T_oil").unwrap().unit, "K");
    assert!((r.values("T_oil").unwrap()[1] - 364.15).abs() < 1e-12);
    assert_eq!(r.values("x").unwrap(), [1.5, 2.0]);
    // A decimal-comma file with ',' separators cannot be told apart: the error says why.
    let f = s.file("ambiguous.csv");
    std::fs::write(&f, "t,x\n0,1,5\n").unwrap();
    let e = plain(&f).unwrap_err();
    assert!(
        e.contains("line 2: 3 cells, but the header has 2 (decimal commas?"),
        "{e}"
    );
}

#[test]
fn crlf_files_are_numbered_as_an_editor_numbers_them() {
    let s = Scratch::new("physid-io");
    let f = s.file("crlf.csv");
    let mut text = String::from("t,x\r\n");
    for i in 2..5000 {
        text.push_str(&format!("{},{}\r\n", i, i as f64 * 0.5));
    }
    text.push_str("5000,oops\r\n");
    std::fs::write(&f, &text).unwrap();
    let e = plain(&f).unwrap_err();
    assert!(
        e.ends_with("line 5000, column 'x': 'oops' is not a number"),
        "{e}"
    );
    // The same with a units row and '\n' ends.
    let f = s.file("lf.csv");
    std::fs::write(&f, "t,x\ns,m\n0,1\n1,2\n2,bad\n").unwrap();
    let e = plain(&f).unwrap_err();
    assert!(
        e.ends_with("line 5, column 'x': 'bad' is not a number"),
        "{e}"
    );
}

#[test]
fn a_cut_short_last_line_is_read_with_a_warning() {
    let s = Scratch::new("physid-io");
    let f = s.file("cut.csv");
    std::fs::write(&f, "t,x\n0,1\n1,2").unwrap();
    let r = plain(&f).unwrap();
    assert_eq!(r.values("x").unwrap(), [1.0, 2.0]);
    assert!(r.meta["warning"].contains("line 3"), "{:?}", r.meta);
    let f = s.file("whole.csv");
    std::fs::write(&f, "t,x\n0,1\n1,2\n").unwrap();
    assert!(!plain(&f).unwrap().meta.contains_key("warning"));
}

#[test]
fn errors_name_file_line_and_column() {
    let s = Scratch::new("physid-io");
    let case = |name: &str, text: &str| {
        let f = s.file(name);
        std::fs::write(&f, text).unwrap();
        plain(&f).unwrap_err()
    };
    let e = case("bad.csv", "a,b\n1,2\n3,x7\n");
    assert!(
        e.ends_with("bad.csv, line 3, column 'b': 'x7' is not a number"),
        "{e}"
    );
    // A second row with numbers and text is data with a bad cell, not units.
    let e = case("mixed.csv", "a,b\n1,x\n");
    assert!(
        e.ends_with("line 2, column 'b': 'x' is not a number"),
        "{e}"
    );
    assert!(case("empty.csv", "").contains("no header row"));
    assert!(case("hdr.csv", "a,b\n").contains("no data rows"));
    assert!(case("units-only.csv", "a,b\ns,m\n").contains("no data rows"));
    let e = case("ragged.csv", "a,b\n1,2\n3\n");
    assert!(e.contains("line 3: 1 cells, but the header has 2"), "{e}");
    assert!(case("dup.csv", "a,a\n1,2\n").contains("channel 'a' appears twice"));
    let e = read_csv("/nonexistent/x.csv", &CsvOptions::default()).unwrap_err();
    assert!(matches!(e, physid_io::IoError::Os { .. }));
}

/// The committed file physid wrote (`PHYSID_BLESS=1` rewrites it and then the script must be
/// run again): small, with every kind of number the writer produces.
fn golden_recording() -> Recording {
    let mut r = Recording::new(Basis::Time);
    let n = 40;
    let cols: [(&str, &str, Vec<f64>); 4] = [
        ("t", "s", (0..n).map(|i| i as f64 * 1e-4).collect()),
        (
            "p_cyl",
            "Pa",
            (0..n)
                .map(|i| 1e5 + (i as f64 * 0.37).sin() * 2.5e6 / 3.0)
                .collect(),
        ),
        (
            "omega_en",
            "rad/s",
            (0..n).map(|i| 104.0 + 1e-9 * i as f64 - 1e-300).collect(),
        ),
        ("count_en", "-", (0..n).map(|i| (i / 3) as f64).collect()),
    ];
    for (name, unit, v) in cols {
        r.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values: v,
        })
        .unwrap();
    }
    r
}

#[test]
fn pandas_reads_physids_csv() {
    let rec = golden_recording();
    let committed = golden().join("physid_written.csv");
    if std::env::var("PHYSID_BLESS").is_ok() {
        write_csv(&committed, &rec).unwrap();
    }
    // The committed file is what the writer writes today, byte for byte.
    let s = Scratch::new("physid-io");
    let now = s.file("now.csv");
    write_csv(&now, &rec).unwrap();
    assert_eq!(
        std::fs::read(&now).unwrap(),
        std::fs::read(&committed).unwrap()
    );
    // pandas (gen_pandas.py) read the same columns, values and units physid reads.
    let exp: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(golden().join("pandas_read.json")).unwrap())
            .unwrap();
    let back = plain(&committed).unwrap();
    let cols: Vec<&str> = exp["columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    assert_eq!(back.names(), cols);
    // pandas reads whole-number columns as int64, the rest as float64; the values agree.
    for t in exp["dtypes"].as_array().unwrap() {
        assert!(t == "float64" || t == "int64", "{t}");
    }
    for ch in back.channels() {
        assert_eq!(exp["units"][&ch.name], ch.unit.as_str());
        let pandas: Vec<f64> = exp["values"][&ch.name]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap().parse().unwrap())
            .collect();
        assert!(pandas == ch.values, "{}", ch.name);
    }
}

/// A lab recording as it comes: a `.dat` file of columns of numbers aligned with spaces, in
/// scientific notation, no header row (the columns named with `--columns`), leading spaces, a
/// blank line; read with a sensor calibration (`--scale`) into the unit `--map` states, then to
/// SI. A bad cell is placed on its line of the file.
#[test]
fn whitespace_columns_without_a_header_and_a_calibration() {
    let s = Scratch::new("physid-io");
    let f = s.file("lab.dat");
    std::fs::write(
        &f,
        "  0.000000e+00   -7.812500e-01   1.250000e+00\n\
         \x20 1.000000e-05    4.375000e+00   1.260000e+00\n\
         \n\
         \x20 2.000000e-05\t  -7.500000e-01   1.270000e+00\n",
    )
    .unwrap();
    let opts = ReadOptions {
        columns: Some(vec!["t".into(), "enc".into(), "p_cyl".into()]),
        map: ReadOptions::parse_map(&["p_cyl=p_cyl:bar".into()]).unwrap(),
        scale: ReadOptions::parse_scale(&["p_cyl=10,-2".into()]).unwrap(),
        ..Default::default()
    };
    let r = read(&f, &opts).unwrap();
    assert_eq!(r.names(), ["t", "enc", "p_cyl"]);
    assert_eq!(r.values("t").unwrap(), [0.0, 1e-5, 2e-5]);
    assert_eq!(r.values("enc").unwrap(), [-0.78125, 4.375, -0.75]);
    // (10·v − 2) bar → Pa.
    let p = r.values("p_cyl").unwrap();
    for (got, v) in p.iter().zip([1.25, 1.26, 1.27]) {
        assert!((got - (10.0 * v - 2.0) * 1e5).abs() < 1e-6, "{got}");
    }
    assert_eq!(r.channel("p_cyl").unwrap().unit, "Pa");
    assert_eq!(r.meta["csv_separator"], "whitespace");
    assert_eq!(r.meta["first_data_line"], "1");
    // Decimal commas between spaces, a header row this time.
    let g = s.file("komma.txt");
    std::fs::write(&g, "t  x\n0,5  1,25\n1,5  2,5\n").unwrap();
    let r = plain(&g).unwrap();
    assert_eq!(r.values("x").unwrap(), [1.25, 2.5]);
    // "a, b, c" is still comma-separated.
    let h = s.file("spaced.csv");
    std::fs::write(&h, "t, x\n0, 1.5\n1, 2.5\n").unwrap();
    assert_eq!(plain(&h).unwrap().values("x").unwrap(), [1.5, 2.5]);
    // A bad cell on line 4 of the file (the blank line counts).
    std::fs::write(&f, "0 1\n1 2\n\n2 x3\n").unwrap();
    let e = read(
        &f,
        &ReadOptions {
            columns: Some(vec!["t".into(), "y".into()]),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("line 4") && e.contains("'x3'"), "{e}");
    // Fewer names than columns.
    std::fs::write(&f, "0 1 2\n1 2 3\n").unwrap();
    let e = read(
        &f,
        &ReadOptions {
            columns: Some(vec!["t".into(), "y".into()]),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("line 1: 3 cells") && e.contains("--columns"),
        "{e}"
    );
    // --columns with a file that has a header: its first line is not numbers.
    let e = read(
        &g,
        &ReadOptions {
            columns: Some(vec!["t".into(), "x".into()]),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("line 1"), "{e}");
    // A calibration of a channel that is not there; a bad one.
    let e = read(
        &g,
        &ReadOptions {
            scale: ReadOptions::parse_scale(&["p_cyl=1,0".into()]).unwrap(),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("p_cyl (in --scale)"), "{e}");
    assert!(ReadOptions::parse_scale(&["p_cyl=2".into()]).is_err());
    assert!(ReadOptions::parse_scale(&["p_cyl=0,1".into()]).is_err());
}

/// A pressure sensor's volts, labelled V in the file: `--scale` maps them into the channel's
/// SI unit (a standard channel), and says so; without it, V is refused for a pressure.
#[test]
fn a_calibration_from_the_sensor_unit_gives_the_si_unit() {
    let s = Scratch::new("physid-io");
    let f = s.file("volts.csv");
    std::fs::write(&f, "t,p_cyl,aux\ns,V,V\n0,1.5,2\n1e-5,2.0,3\n").unwrap();
    let opts = ReadOptions {
        scale: ReadOptions::parse_scale(&["p_cyl=2e5,1e5".into(), "aux=2,0".into()]).unwrap(),
        ..Default::default()
    };
    let r = read(&f, &opts).unwrap();
    assert_eq!(r.channel("p_cyl").unwrap().unit, "Pa");
    assert_eq!(r.values("p_cyl").unwrap(), [4e5, 5e5]);
    assert!(
        r.meta["calibrated"].contains("p_cyl: V → Pa"),
        "{:?}",
        r.meta
    );
    // A channel that is not a standard one keeps its unit.
    assert_eq!(r.channel("aux").unwrap().unit, "V");
    assert_eq!(r.values("aux").unwrap(), [4.0, 6.0]);
    let e = plain(&f).unwrap_err().to_string();
    assert!(e.contains("p_cyl") && e.contains("'V'"), "{e}");
}
