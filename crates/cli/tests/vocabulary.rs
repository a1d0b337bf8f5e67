//! One vocabulary across the verbs (docs/cli.md): every verb's `--help` is walked and its
//! flags checked against the table of shared flags — a flag two verbs share is in the table,
//! with exactly the verbs that take it and the same value placeholder in each; the old
//! spellings are still taken (hidden from `--help`, with a warning naming the new one) and mean
//! what the new ones mean.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::physid;
use std::collections::{BTreeMap, BTreeSet};

fn help(path: &[String]) -> String {
    let mut args: Vec<&str> = path.iter().map(String::as_str).collect();
    args.push("--help");
    let o = physid(&args);
    assert!(
        o.status.success(),
        "physid {} --help failed",
        path.join(" ")
    );
    String::from_utf8(o.stdout).unwrap()
}

/// The flags a help text lists (visible ones only), with their value placeholder ("" for a
/// switch).
fn flags(text: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut in_options = false;
    for line in text.lines() {
        if line.ends_with(':') && !line.starts_with(' ') {
            in_options = line == "Options:";
            continue;
        }
        if !in_options {
            continue;
        }
        // An option's own line is indented 2 (`-h, --help`) or 6 spaces; its description 10.
        let indent = line.len() - line.trim_start().len();
        if indent != 2 && indent != 6 {
            continue;
        }
        let item = line.trim_start();
        let item = item.split_once(", ").map_or(item, |(short, long)| {
            if short.starts_with('-') && short.len() == 2 {
                long
            } else {
                item
            }
        });
        let Some(rest) = item.strip_prefix("--") else {
            continue;
        };
        let name = format!(
            "--{}",
            rest.split(|c: char| c.is_whitespace()).next().unwrap()
        );
        let value = rest
            .split_once('<')
            .and_then(|(_, v)| v.split_once('>'))
            .map_or(String::new(), |(v, _)| v.to_string());
        out.push((name, value));
    }
    out
}

/// The subcommands a help text lists.
fn commands(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut in_commands = false;
    for line in text.lines() {
        if line.ends_with(':') && !line.starts_with(' ') {
            in_commands = line == "Commands:";
            continue;
        }
        if in_commands && line.starts_with("  ") && !line.starts_with("   ") {
            let name = line.split_whitespace().next().unwrap();
            if name != "help" {
                out.push(name.to_string());
            }
        }
    }
    out
}

/// Every verb (a command with options of its own beyond --help and --quiet) and its flags.
fn verbs() -> BTreeMap<String, Vec<(String, String)>> {
    let mut out = BTreeMap::new();
    let mut todo: Vec<Vec<String>> = vec![Vec::new()];
    while let Some(path) = todo.pop() {
        let text = help(&path);
        let f = flags(&text);
        let own = f
            .iter()
            .any(|(n, _)| !["--help", "--quiet", "--version"].contains(&n.as_str()));
        let subs = commands(&text);
        if !path.is_empty() && (own || subs.is_empty()) {
            out.insert(path.join(" "), f);
        }
        for s in subs {
            let mut p = path.clone();
            p.push(s);
            todo.push(p);
        }
    }
    out
}

/// The rows of the table under `heading` in docs/cli.md, cells split on unescaped `|`.
fn table(heading: &str) -> Vec<Vec<String>> {
    let doc =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/cli.md")).unwrap();
    let start = doc
        .find(heading)
        .unwrap_or_else(|| panic!("docs/cli.md has no '{heading}'"));
    let mut rows = Vec::new();
    for line in doc[start..].lines().skip(1) {
        if line.starts_with("## ") {
            break;
        }
        if !line.starts_with('|') || line.starts_with("|---") {
            continue;
        }
        let mut cells = Vec::new();
        let mut cell = String::new();
        let mut chars = line.trim().trim_matches('|').chars().peekable();
        while let Some(c) = chars.next() {
            match c {
                '\\' if chars.peek() == Some(&'|') => {
                    cell.push('|');
                    chars.next();
                }
                '|' => cells.push(std::mem::take(&mut cell).trim().to_string()),
                c => cell.push(c),
            }
        }
        cells.push(cell.trim().to_string());
        rows.push(cells);
    }
    assert!(rows.len() > 1, "no table under '{heading}'");
    rows.remove(0); // the header
    rows
}

fn code(cell: &str) -> Vec<String> {
    cell.split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect()
}

#[test]
fn every_shared_flag_means_one_thing_in_docs_cli_md() {
    let verbs = verbs();
    // Guards against the walk itself breaking: the verbs users know are there.
    for v in [
        "estimate",
        "identify",
        "monitor shaft",
        "friction fit",
        "torque fit",
        "simulate",
        "live",
        "inspect",
    ] {
        assert!(
            verbs.contains_key(v),
            "verb {v} not found: {:?}",
            verbs.keys()
        );
    }
    let mut uses: BTreeMap<String, Vec<(String, String)>> = BTreeMap::new();
    for (verb, fl) in &verbs {
        for (name, value) in fl {
            uses.entry(name.clone())
                .or_default()
                .push((verb.clone(), value.clone()));
        }
    }
    let rows = table("## Shared flags");
    let mut documented = BTreeSet::new();
    let mut problems = Vec::new();
    for row in &rows {
        let flag = code(&row[0]).pop().unwrap();
        let values: Vec<String> = if row[1].is_empty() {
            vec![String::new()]
        } else {
            code(&row[1])
        };
        let listed: BTreeSet<String> = if row[3] == "every verb" {
            verbs.keys().cloned().collect()
        } else {
            row[3].split(',').map(|v| v.trim().to_string()).collect()
        };
        documented.insert(flag.clone());
        let Some(used) = uses.get(&flag) else {
            problems.push(format!("{flag}: in docs/cli.md but no verb takes it"));
            continue;
        };
        let actual: BTreeSet<String> = used.iter().map(|(v, _)| v.clone()).collect();
        if actual != listed {
            problems.push(format!(
                "{flag}: docs/cli.md lists {listed:?}, the verbs that take it are {actual:?}"
            ));
        }
        for (verb, value) in used {
            if !values.contains(value) {
                problems.push(format!(
                    "{flag} in {verb}: value <{value}>, docs/cli.md says {values:?}"
                ));
            }
        }
        assert!(!row[2].is_empty(), "{flag}: no meaning in docs/cli.md");
    }
    for (flag, used) in &uses {
        if used.len() > 1 && flag != "--help" && !documented.contains(flag) {
            problems.push(format!(
                "{flag}: taken by {:?} but not in docs/cli.md's shared flags",
                used.iter().map(|(v, _)| v.as_str()).collect::<Vec<_>>()
            ));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn old_spellings_are_still_taken_and_hidden() {
    let rows = table("## Old spellings, taken for this release");
    assert!(rows.len() >= 10);
    for row in &rows {
        let old = code(&row[0]).pop().unwrap();
        let new = code(&row[1]).pop().unwrap();
        let example = code(&row[3]).pop().unwrap();
        let old_flag = old.split_whitespace().next().unwrap().to_string();
        let new_flag = new.split_whitespace().next().unwrap().to_string();
        for verb in row[2].split(',').map(str::trim) {
            let path: Vec<String> = verb.split_whitespace().map(String::from).collect();
            let shown: Vec<String> = flags(&help(&path)).into_iter().map(|(n, _)| n).collect();
            assert!(
                shown.contains(&new_flag),
                "{verb}: {new_flag} not in --help"
            );
            if old_flag != new_flag {
                assert!(
                    !shown.contains(&old_flag),
                    "{verb}: the old {old_flag} is still shown in --help"
                );
            }
            // Taken: with --help after it, clap parses the old spelling (refusing it if it
            // were unknown or its value invalid) and then prints the help.
            let mut args: Vec<&str> = path.iter().map(String::as_str).collect();
            args.extend(example.split_whitespace());
            args.push("--help");
            let o = physid(&args);
            assert!(
                o.status.success(),
                "physid {}: {}",
                args.join(" "),
                String::from_utf8_lossy(&o.stderr)
            );
        }
    }
}

/// A JSON result without what differs between two runs by nature: the time taken, the
/// command line and the date.
fn answer(o: &std::process::Output) -> serde_json::Value {
    let mut v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in ["timing", "provenance"] {
        v.as_object_mut().unwrap().remove(key);
    }
    v
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The old spellings give the same answers as the new ones, with a warning naming the new.
#[test]
fn old_spellings_mean_what_the_new_ones_mean() {
    let dir = physid_testkit::Scratch::new("physid-vocabulary");
    let old_file = dir.file("old.parquet");
    let new_file = dir.file("new.parquet");
    let run = |args: &[&str]| {
        let o = physid(args);
        assert!(
            o.status.success(),
            "physid {}: {}",
            args.join(" "),
            stderr(&o)
        );
        o
    };
    let sim = |out_flag: &str, rate_flag: &str, file: &std::path::Path| {
        run(&[
            "simulate",
            "--scenario",
            "shaft-steady",
            "--duration",
            "3",
            rate_flag,
            "5000",
            out_flag,
            file.to_str().unwrap(),
        ])
    };
    let o = sim("--out", "--rate", &old_file);
    let e = stderr(&o);
    assert!(e.contains("--out FILE is now --recording FILE"), "{e}");
    assert!(e.contains("--rate is now --sample-rate"), "{e}");
    let o = sim("--recording", "--sample-rate", &new_file);
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(&old_file).unwrap(),
        std::fs::read(&new_file).unwrap(),
        "the same recording either way"
    );
    let f = new_file.to_str().unwrap();
    let monitor = |extra: &[&str]| {
        let mut args = vec!["monitor", "shaft", "--data", f, "--json"];
        args.extend(extra);
        let o = run(&args);
        (answer(&o), stderr(&o))
    };
    let (old, e) = monitor(&["--method", "rls", "--cutoff", "400", "--rate", "1000"]);
    for w in [
        "--method rls is RLS with forgetting in the shaft monitor, now called rlsf",
        "--cutoff is now --lowpass",
        "--rate is now --update-rate",
    ] {
        assert!(e.contains(w), "{e}");
    }
    let (new, e) = monitor(&[
        "--method",
        "rlsf",
        "--lowpass",
        "400",
        "--update-rate",
        "1000",
    ]);
    assert!(!e.contains("warning"), "{e}");
    assert_eq!(old, new);
    assert_eq!(new["method"], "rlsf");
    // The default is the same estimator.
    let (default, _) = monitor(&["--lowpass", "400", "--update-rate", "1000"]);
    assert_eq!(default, new);

    // estimate: --theta0 (values in --phi order) and --params NAME=VALUE.
    let est = |extra: &[&str]| {
        let mut args = vec![
            "estimate",
            "--data",
            f,
            "--y",
            "torque_shaft",
            "--phi",
            "theta_dy-theta_en,omega_dy-omega_en",
            "--free",
            "theta_dy-theta_en",
            "--json",
        ];
        args.extend(extra);
        let o = run(&args);
        (answer(&o), stderr(&o))
    };
    let (old, e) = est(&["--theta0", "0,0.95"]);
    assert!(
        e.contains("--theta0 V,… is now --params NAME=VALUE,…"),
        "{e}"
    );
    let (new, _) = est(&["--params", "omega_dy-omega_en=0.95"]);
    assert_eq!(old, new);
    assert_eq!(new["params"]["omega_dy-omega_en"], 0.95, "{new}");
    // A name that is not a regressor is named.
    let o = physid(&[
        "estimate",
        "--data",
        f,
        "--y",
        "torque_shaft",
        "--phi",
        "theta_dy",
        "--params",
        "K=1",
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("--params K: the parameters are the regressors of --phi: theta_dy"),
        "{}",
        stderr(&o)
    );
}

/// A wrong value is blamed on its flag, before any file is opened.
#[test]
fn a_wrong_value_names_its_flag() {
    for (args, want) in [
        (
            vec![
                "monitor",
                "shaft",
                "--data",
                "nofile.csv",
                "--lambda",
                "1.5",
            ],
            "'--lambda <LAMBDA>': a forgetting factor is in (0, 1], got 1.5",
        ),
        (
            vec![
                "estimate",
                "--data",
                "nofile.csv",
                "--y",
                "y",
                "--phi",
                "a",
                "--lambda",
                "1.5",
            ],
            "'--lambda <LAMBDA>': a forgetting factor is in (0, 1], got 1.5",
        ),
        (
            vec!["friction", "fit", "--data", "nofile.csv", "--lambda", "0"],
            "'--lambda <LAMBDA>': a forgetting factor is in (0, 1], got 0",
        ),
        (
            vec![
                "estimate",
                "--data",
                "nofile.csv",
                "--y",
                "y",
                "--phi",
                "a",
                "--p0",
                "-1",
            ],
            "'--p0 <P0>': expected a number > 0, got -1",
        ),
        (
            vec!["torque", "fit", "--data", "nofile.csv", "--r2", "0"],
            "'--r2 <R2>': expected a number > 0, got 0",
        ),
        (
            vec![
                "monitor",
                "shaft",
                "--data",
                "nofile.csv",
                "--method",
                "rlsx",
            ],
            "--method 'rlsx': expected rlsf, rlsvf or dsfc",
        ),
        (
            vec![
                "monitor",
                "shaft",
                "--data",
                "nofile.csv",
                "--cutoff",
                "1",
                "--lowpass",
                "2",
            ],
            "cannot be used with",
        ),
    ] {
        let o = physid(&args);
        assert!(!o.status.success(), "{args:?}");
        assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("nofile"), "{args:?}: {}", stderr(&o));
    }
}

/// torque fit: `--nominal` (old) and `--params` give the same fit; `--fix NAME=VALUE` holds a
/// parameter at that value.
#[test]
fn torque_fit_takes_params_and_fix_with_a_value() {
    let dir = physid_testkit::Scratch::new("physid-vocabulary-torque");
    let file = dir.file("fired.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "torque-steady",
        "--basis",
        "crank",
        "--duration",
        "2",
        "--recording",
        file.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let f = file.to_str().unwrap();
    let fit = |extra: &[&str]| {
        let mut args = vec!["torque", "fit", "--data", f, "--json"];
        args.extend(extra);
        let o = physid(&args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        (answer(&o), stderr(&o))
    };
    let (old, e) = fit(&["--nominal", "M_rec=0.82"]);
    assert!(e.contains("--nominal is now --params"), "{e}");
    let (new, _) = fit(&["--params", "M_rec=0.82"]);
    assert_eq!(old, new);
    // M_rec is not estimable on this recording: it stays at the value given.
    assert_eq!(new["params"]["M_rec"], 0.82, "{new}");
    let (held, _) = fit(&["--fix", "delta,r=0.0258"]);
    assert_eq!(held["params"]["r"], 0.0258, "{held}");
    assert!(
        !held["estimable"]
            .as_array()
            .unwrap()
            .iter()
            .any(|n| n == "r"),
        "{held}"
    );
}
