//! `physid fmu export`: the archive of each FMI version — its entries, the parameters' start
//! values from `--set`, the scenario it carries readable by `physid simulate` — and bad
//! requests refused with the reason and nothing written. (The FMU's behaviour is tested in
//! crates/fmu/tests/fmi.rs over its C functions, and in FMPy by crates/py/tests/test_fmu.py.)
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;
use common::{ok_json, physid};
use std::io::Read;

fn dir(name: &str) -> physid_testkit::Scratch {
    physid_testkit::Scratch::new(&format!("physid-fmu-{name}"))
}

#[test]
fn fmu_export_writes_both_versions() {
    let d = dir("export");
    for (v, platform) in [("2", "binaries/linux64"), ("3", "binaries/x86_64-linux")] {
        let fmu = d.join(format!("cell{v}.fmu"));
        let j = ok_json(&[
            "fmu",
            "export",
            "--scenario",
            "shaft-steady",
            "--fmu",
            fmu.to_str().unwrap(),
            "--fmi",
            v,
            "--set",
            "shaft.k=1100",
            "--fault",
            "shaft.b=1.2@1",
            "--duration",
            "5",
            "--json",
        ]);
        assert_eq!(j["fmi"], format!("{v}.0"));
        assert_eq!(j["stop_time"], 5.0);
        assert_eq!(
            (&j["parameters"], &j["inputs"], &j["outputs"]),
            (&92.into(), &4.into(), &34.into())
        );
        let mut zip = zip::ZipArchive::new(std::fs::File::open(&fmu).unwrap()).unwrap();
        let mut names: Vec<String> = zip.file_names().map(|n| n.unwrap().to_string()).collect();
        names.sort();
        assert_eq!(
            names,
            [
                format!("{platform}/physid_cell.so"),
                "modelDescription.xml".into(),
                "resources/fmu.toml".into(),
                "resources/scenario.toml".into(),
            ]
        );
        let mut read = |name: &str| {
            let mut s = String::new();
            zip.by_name(name).unwrap().read_to_string(&mut s).unwrap();
            s
        };
        let xml = read("modelDescription.xml");
        assert!(xml.contains(&format!("fmiVersion=\"{v}.0\"")));
        // shaft.k's element, up to the next variable's name.
        let k = &xml[xml.find("name=\"shaft.k\"").unwrap() + 1..];
        let element = &k[..k.find(" name=\"").unwrap()];
        assert!(element.contains("start=\"1100.0\""), "{element}");
        assert!(xml.contains("stopTime=\"5.0\""));
        // The scenario in the resources is a physid scenario file, with the settings and the
        // fault.
        let scenario = d.join(format!("scenario{v}.toml"));
        let text = read("resources/scenario.toml");
        assert!(text.contains("shaft.b=1.2@1") && text.contains("1100"));
        std::fs::write(&scenario, text).unwrap();
        let rec = d.join(format!("r{v}.csv"));
        let o = physid(&[
            "simulate",
            "--scenario",
            scenario.to_str().unwrap(),
            "--duration",
            "0.01",
            "--recording",
            rec.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
}

#[test]
fn fmu_export_refuses_bad_requests() {
    let d = dir("refused");
    let text = d.join("not-a-library.so");
    std::fs::write(&text, "hello").unwrap();
    let out = d.join("cell.fmu");
    let o = out.to_str().unwrap();
    let cases: [(&[&str], &str); 8] = [
        (&["--fmu", "cell.zip"], "ends in .fmu"),
        (&["--fmi", "4"], "--fmi"),
        (&["--set", "shaft.k=-1"], "shaft.k"),
        (&["--set", "shaft.kk=1"], "shaft.kk"),
        (
            &["--fault", "shaft.k=900@100"],
            "after the experiment's stop time",
        ),
        (
            &["--library", "/nonexistent/libphysid_fmu.so"],
            "/nonexistent",
        ),
        (
            &["--library", text.to_str().unwrap()],
            "not a linux x86-64 shared library",
        ),
        (&["--scenario", "no-such-scenario"], "neither a built-in"),
    ];
    for (extra, want) in cases {
        let mut args = vec!["fmu", "export"];
        for (flag, value) in [("--scenario", "shaft-steady"), ("--fmu", o)] {
            if extra[0] != flag {
                args.extend([flag, value]);
            }
        }
        args.extend_from_slice(extra);
        let r = physid(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success(), "{extra:?}");
        assert!(err.contains(want), "{extra:?}: {err}");
        assert!(!out.exists(), "{extra:?} left a file");
    }
    assert_eq!(
        std::fs::read_dir(&*d).unwrap().count(),
        1,
        "only the text file"
    );
}
