//! `physid live --headless --json`: the shaft monitor's stage on a paced virtual cell or a
//! replayed file, NDJSON events out — the same numbers as the file verb, whatever the chunk.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::physid;
use physid_testkit::Scratch;
use serde_json::Value;

fn events(args: &[&str]) -> Vec<Value> {
    let o = physid(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let text = String::from_utf8(o.stdout).unwrap();
    let ev: Vec<Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    for e in &ev {
        assert!(e["type"].is_string() && e.get("t_s").is_some(), "{e}");
    }
    assert_eq!(
        ev.last().unwrap()["type"],
        "end",
        "the last event ends the run"
    );
    ev
}

/// Whether event `e`'s message contains `what`.
fn says(e: &Value, what: &str) -> bool {
    e["message"].as_str().is_some_and(|m| m.contains(what))
}

fn of_type<'a>(ev: &'a [Value], t: &str) -> Vec<&'a Value> {
    ev.iter().filter(|e| e["type"] == t).collect()
}

#[test]
fn a_replay_ends_on_the_file_verbs_estimate_whatever_the_chunk() {
    let s = Scratch::new("physid-live");
    let file = s.file("t01.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "3",
        "--fault",
        "shaft.k=1000@1.5",
        "--recording",
        file.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    let o = physid(&[
        "monitor",
        "shaft",
        "--data",
        file.to_str().unwrap(),
        "--json",
    ]);
    let verb: Value = serde_json::from_slice(&o.stdout).unwrap();
    let f = file.to_str().unwrap();
    let mut finals = Vec::new();
    for chunk in ["0.0001", "0.0017", "0.4096", "10"] {
        let ev = events(&[
            "live",
            "--headless",
            "--json",
            "--replay",
            f,
            "--pace",
            "max",
            "--chunk",
            chunk,
        ]);
        let end = of_type(&ev, "end")[0];
        assert_eq!(end["samples"], 30001);
        assert_eq!(end["dropped"], 0);
        let last = of_type(&ev, "estimate").last().copied().unwrap().clone();
        for p in ["K", "B"] {
            assert_eq!(last["params"][p], verb["final"][p], "chunk {chunk}: {p}");
        }
        let alarms: Vec<&Value> = of_type(&ev, "alarm");
        let verb_alarms = verb["alarms"].as_array().unwrap();
        assert_eq!(alarms.len(), verb_alarms.len(), "chunk {chunk}");
        for (a, v) in alarms.iter().zip(verb_alarms) {
            assert_eq!(a["param"], v["param"]);
            assert_eq!(a["t_s"], v["t_raised_s"]);
            assert_eq!(a["t_start_s"], v["t_start_s"]);
        }
        finals.push(last);
    }
    assert!(finals.windows(2).all(|w| w[0] == w[1]));
    // And against the simulated truth, not only the file verb (which runs the same stage): the
    // stiffness stepped to 1000 N·m/rad at 1.5 s, the damping stayed at 0.95.
    let k = finals[0]["params"]["K"].as_f64().unwrap();
    let b = finals[0]["params"]["B"].as_f64().unwrap();
    assert!(
        (k / 1000.0 - 1.0).abs() < 0.02 && (b / 0.95 - 1.0).abs() < 0.05,
        "K {k}, B {b}"
    );
    let raised: Vec<f64> = verb["alarms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| {
            assert_eq!(a["param"], "K");
            a["t_raised_s"].as_f64().unwrap()
        })
        .collect();
    assert!(
        !raised.is_empty() && raised.iter().all(|&t| t > 1.5),
        "{raised:?}"
    );
}

#[test]
fn the_virtual_cell_raises_the_stiffness_alarm_and_no_damping_alarm() {
    let ev = events(&[
        "live",
        "--headless",
        "--json",
        "--scenario",
        "shaft-steady",
        "--fault",
        "shaft.k=1000@2",
        "--duration",
        "4",
        "--pace",
        "max",
    ]);
    let alarms = of_type(&ev, "alarm");
    assert!(!alarms.is_empty(), "no alarm");
    for a in &alarms {
        assert_eq!(a["param"], "K", "{a}");
        let t = a["t_s"].as_f64().unwrap();
        assert!((2.0..4.0).contains(&t), "raised at {t}");
        // The stiffness fell from 1250 to 1000: Eq. 6.3's e = (1250 − 1000)/1250 = 0.2 once
        // the estimate has followed (the alarm waits out the dwell, by when it has), and the
        // change as read is its negative.
        let e = a["relative_error"].as_f64().unwrap();
        assert!((e - 0.2).abs() < 0.01, "relative error {e} against 0.2");
        assert_eq!(
            a["change"].as_f64(),
            a["relative_error"].as_f64().map(|e| -e)
        );
    }
    // The last estimate is the faulted shaft's: K = 1000, B unchanged at 0.95 (within 0.5 %).
    let last = of_type(&ev, "estimate").last().cloned().unwrap();
    for (p, truth) in [("K", 1000.0), ("B", 0.95)] {
        let v = last["params"][p].as_f64().unwrap();
        assert!(
            ((v - truth) / truth).abs() < 0.005,
            "{p} = {v} against {truth}"
        );
    }
    // Estimate events at most every 0.1 s of recording, in time order.
    let t: Vec<f64> = of_type(&ev, "estimate")
        .iter()
        .map(|e| e["t_s"].as_f64().unwrap())
        .collect();
    assert!(t.windows(2).all(|w| w[1] > w[0]));
    assert!(
        t.len() >= 35 && t.len() <= 42,
        "{} estimate events",
        t.len()
    );
    let k = of_type(&ev, "estimate").last().unwrap()["params"]["K"]
        .as_f64()
        .unwrap();
    assert!((k / 1000.0 - 1.0).abs() < 0.02, "K {k}");
}

#[test]
fn bad_flags_are_refused_naming_them() {
    let o = physid(&["live", "--headless", "--json", "--pace", "fast"]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("--pace") && e.contains("expected max or a factor"),
        "{e}"
    );
    let o = physid(&["live", "--headless", "--scenario", "shaft-steady"]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("add --json"), "{e}");
    let o = physid(&[
        "live",
        "--headless",
        "--json",
        "--scenario",
        "nope",
        "--pace",
        "max",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--scenario"));
}

/// Run `physid live` with `input` on stdin; its events.
fn events_from_stdin(args: &[&str], input: &str) -> Vec<Value> {
    events_from_stdin_bytes(args, input.as_bytes())
}

/// [`events_from_stdin`] with any bytes on stdin.
fn events_from_stdin_bytes(args: &[&str], input: &[u8]) -> Vec<Value> {
    use std::io::Write;
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_physid"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(input).unwrap();
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// `physid live` on frames from stdin, as fast as they come.
const FRAMES_ON_STDIN: [&str; 7] = [
    "live",
    "--headless",
    "--json",
    "--frames",
    "-",
    "--pace",
    "max",
];

/// The frames of 1000 samples (the last shorter) of a recording's frame channels, as JSON
/// lines, and its samples.
fn frames_of(file: &std::path::Path) -> (Vec<String>, usize) {
    let rec = physid_io::read(file, &Default::default()).unwrap();
    let cols: Vec<&[f64]> = physid_live::FRAME_CHANNELS
        .iter()
        .map(|c| rec.values(c).unwrap())
        .collect();
    let frame = |seq: usize, r: std::ops::Range<usize>| -> String {
        let mut obj = serde_json::Map::new();
        obj.insert("seq".into(), seq.into());
        for (name, col) in physid_live::FRAME_CHANNELS.iter().zip(&cols) {
            obj.insert((*name).into(), col[r.clone()].into());
        }
        Value::Object(obj).to_string()
    };
    let n = rec.len();
    let frames = (0..n.div_ceil(1000))
        .map(|k| frame(k, k * 1000..((k + 1) * 1000).min(n)))
        .collect();
    (frames, n)
}

/// A second of frames lost (a DAQ's dropout: 8 engine cycles at 1000 rpm) is reported as a gap,
/// and the cycle statistics go on after it: each cycle wholly before or after the gap is the
/// uninterrupted run's, JSON for JSON, under the same number; none the gap cuts is reported.
/// Before, the crank angle's advance across the gap stopped the cycle stages for the rest of
/// the run ("the crank angle advances by 1.0472e2 rad … — the cycle statistics stopped").
#[test]
fn a_gap_in_the_frames_is_resumed_after_by_the_cycle_stages() {
    let s = Scratch::new("physid-live-frame-gap");
    let file = s.file("run.csv");
    common::simulated(&file, "shaft-steady", "4");
    let (frames, _) = frames_of(&file);
    let run = |lines: &[&String]| {
        let input: String = lines.iter().map(|f| format!("{f}\n")).collect();
        events_from_stdin(&FRAMES_ON_STDIN, &input)
    };
    let whole = run(&frames.iter().collect::<Vec<_>>());
    let gappy = run(&frames
        .iter()
        .enumerate()
        .filter(|(k, _)| !(15..25).contains(k))
        .map(|(_, f)| f)
        .collect::<Vec<_>>());
    let findings = of_type(&gappy, "finding");
    assert!(
        findings.iter().any(|f| says(f, "a gap of 10000 samples")),
        "{findings:?}"
    );
    assert!(!findings.iter().any(|f| says(f, "stopped")), "{findings:?}");
    let (gap_start, gap_end) = (1.4999, 2.5);
    let outside: Vec<&Value> = of_type(&whole, "cycle")
        .into_iter()
        .filter(|c| {
            c["t_s"].as_f64().unwrap() < gap_start || c["t_start_s"].as_f64().unwrap() > gap_end
        })
        .collect();
    let got = of_type(&gappy, "cycle");
    assert_eq!(
        got, outside,
        "the cycles outside the gap, as the whole run's"
    );
    let after = got
        .iter()
        .filter(|c| c["t_start_s"].as_f64().unwrap() > gap_end)
        .count();
    assert!(after >= 10, "{after} cycles after the gap");
    assert!(of_type(&whole, "cycle").len() > got.len() + 7);
}

/// A DAQ whose software restarts mid-run — its `seq` back at 0, its clock at 0, its encoders'
/// angles counted from where they stand in their cycle and turn — goes on after a gap: no
/// frame is refused, the restart is told once, every cycle before it is the uninterrupted
/// run's, JSON for JSON, each cycle after it has the uninterrupted run's statistics, and the
/// shaft monitor goes on to the uninterrupted run's estimate. Before, every frame after the
/// restart was refused ("t starts at 0 s, not after the previous frame's 1.9999 s").
#[test]
fn a_daq_that_starts_again_goes_on_after_a_gap() {
    use std::f64::consts::{PI, TAU};
    let s = Scratch::new("physid-live-frame-restart");
    let file = s.file("run.csv");
    common::simulated(&file, "shaft-steady", "4");
    let (frames, n) = frames_of(&file);
    let whole: String = frames.iter().map(|f| format!("{f}\n")).collect();
    let whole = events_from_stdin(&FRAMES_ON_STDIN, &whole);
    // The DAQ restarts at frame 20 (t = 2 s).
    let first: Value = serde_json::from_str(&frames[20]).unwrap();
    let at = |name: &str| first[name][0].as_f64().unwrap();
    let (t0, en0, dy0) = (at("t"), at("theta_en"), at("theta_dy"));
    let (en0, dy0) = (en0 - en0.rem_euclid(4.0 * PI), dy0 - dy0.rem_euclid(TAU));
    let mut input = String::new();
    for (k, f) in frames.iter().enumerate() {
        let mut v: Value = serde_json::from_str(f).unwrap();
        if k >= 20 {
            v["seq"] = (k - 20).into();
            for (name, by) in [("t", t0), ("theta_en", en0), ("theta_dy", dy0)] {
                let sent: Vec<f64> = v[name]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|x| x.as_f64().unwrap() - by)
                    .collect();
                v[name] = sent.into();
            }
        }
        input.push_str(&format!("{v}\n"));
    }
    let restarted = events_from_stdin(&FRAMES_ON_STDIN, &input);
    assert!(
        of_type(&restarted, "error").is_empty(),
        "{:?}",
        of_type(&restarted, "error")
    );
    let told: Vec<_> = of_type(&restarted, "finding")
        .into_iter()
        .filter(|f| says(f, "the sender started again (seq 0 after 19)"))
        .collect();
    assert_eq!(told.len(), 1, "{:?}", of_type(&restarted, "finding"));
    let end = of_type(&restarted, "end")[0];
    assert_eq!(
        (end["samples"].as_u64(), end["dropped"].as_u64()),
        (Some(n as u64), Some(0))
    );
    // The cycles: before the restart, the uninterrupted run's; the one it cuts left out;
    // after it, the same statistics in the same order, numbered on.
    let before = |c: &&Value| c["t_s"].as_f64().unwrap() < t0;
    let (w_before, w_after): (Vec<&Value>, Vec<&Value>) =
        of_type(&whole, "cycle").into_iter().partition(before);
    let (r_before, r_after): (Vec<&Value>, Vec<&Value>) =
        of_type(&restarted, "cycle").into_iter().partition(before);
    assert_eq!(r_before, w_before);
    let w_after: Vec<&Value> = w_after
        .into_iter()
        .filter(|c| c["t_start_s"].as_f64().unwrap() >= t0)
        .collect();
    assert!(
        r_after.len() >= 10,
        "{} cycles after the restart",
        r_after.len()
    );
    assert_eq!(r_after.len(), w_after.len());
    for (r, w) in r_after.iter().zip(&w_after) {
        for key in ["mean", "max", "max_deg"] {
            for (name, x) in w[key].as_object().unwrap() {
                let (x, y) = (x.as_f64().unwrap(), r[key][name].as_f64().unwrap());
                assert!(
                    (x - y).abs() <= 1e-9 * x.abs().max(1.0),
                    "{key}.{name}: {y} vs {x}"
                );
            }
        }
    }
    for pair in r_after.windows(2) {
        assert_eq!(
            pair[1]["cycle"].as_i64().unwrap(),
            pair[0]["cycle"].as_i64().unwrap() + 1
        );
    }
    assert!(
        r_after[0]["cycle"].as_i64().unwrap() > r_before.last().unwrap()["cycle"].as_i64().unwrap()
    );
    // The shaft monitor goes on: estimates after the restart, ending on the uninterrupted
    // run's to 0.1 %.
    let estimates = of_type(&restarted, "estimate");
    assert!(estimates
        .iter()
        .any(|e| e["t_s"].as_f64().unwrap() > t0 + 1.0));
    let (r, w) = (
        estimates.last().unwrap(),
        of_type(&whole, "estimate").last().copied().unwrap(),
    );
    for p in ["K", "B"] {
        let (x, y) = (
            w["params"][p].as_f64().unwrap(),
            r["params"][p].as_f64().unwrap(),
        );
        assert!((y / x - 1.0).abs() < 1e-3, "{p}: {y} vs {x}");
    }
}

/// Frames from outside on stdin: bad frames are refused one by one, named by line, and the
/// run goes on — the good frames give `monitor shaft`'s very estimate; a missing frame is
/// reported as a gap.
#[test]
fn frames_from_stdin_survive_bad_frames() {
    let s = Scratch::new("physid-live");
    let file = s.file("t01.csv");
    let f = file.to_str().unwrap();
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "1.5",
        "--recording",
        f,
    ]);
    assert!(o.status.success());
    let o = physid(&["monitor", "shaft", "--data", f, "--json"]);
    let verb: Value = serde_json::from_slice(&o.stdout).unwrap();
    let (frames, n) = frames_of(&file);
    // Bad lines after frames 2, 5 and 9: not JSON, a channel too short, a repeated frame.
    let mut input = String::new();
    for (k, fr) in frames.iter().enumerate() {
        input.push_str(fr);
        input.push('\n');
        match k {
            2 => input.push_str("{\"seq\": 3, \"t\": [oops\n"),
            5 => input.push_str(&fr.replacen("\"torque_shaft\":[", "\"torque_shaft\":[1.0,", 1)),
            9 => input.push_str(fr),
            _ => {}
        }
        if matches!(k, 5 | 9) {
            input.push('\n');
        }
    }
    let ev = events_from_stdin(&FRAMES_ON_STDIN, &input);
    let errors = of_type(&ev, "error");
    assert_eq!(errors.len(), 3, "{errors:?}");
    assert_eq!(errors[0]["line"], 4);
    assert!(says(errors[0], "not a JSON object"), "{}", errors[0]);
    assert!(
        says(errors[1], "'torque_shaft' has 1001 values"),
        "{}",
        errors[1]
    );
    assert!(says(errors[2], "repeated or out of order"), "{}", errors[2]);
    let end = of_type(&ev, "end")[0];
    assert_eq!(
        (end["samples"].as_u64(), end["dropped"].as_u64()),
        (Some(n as u64), Some(3))
    );
    let last = of_type(&ev, "estimate").last().copied().unwrap().clone();
    for p in ["K", "B"] {
        assert_eq!(last["params"][p], verb["final"][p], "{p}");
    }
    // A frame missing: a finding, and the run goes on to the end.
    let gappy: String = frames
        .iter()
        .enumerate()
        .filter(|(k, _)| *k != 4)
        .map(|(_, f)| format!("{f}\n"))
        .collect();
    let ev = events_from_stdin(&FRAMES_ON_STDIN, &gappy);
    let findings = of_type(&ev, "finding");
    assert!(
        findings.iter().any(|f| f["message"]
            .as_str()
            .unwrap()
            .contains("a gap of 1000 samples")),
        "{findings:?}"
    );
    assert_eq!(
        of_type(&ev, "end")[0]["samples"].as_u64(),
        Some(n as u64 - 1000)
    );
}

/// Control messages on stdin while the virtual cell runs (at twice real time, so that they
/// arrive before the fault's time): a malformed one is refused naming the field and the run
/// goes on; a stiffness fault injected this way raises the K alarm and no B alarm.
#[test]
fn controls_on_stdin_inject_a_fault_and_bad_ones_are_named() {
    let controls = concat!(
        "{\"cmd\": \"speed\", \"rpm\": \"fast\"}\n",
        "{\"cmd\": \"fault\", \"spec\": \"shaft.k=1000@1.5\"}\n",
        "{\"cmd\": \"warp\"}\n",
    );
    let ev = events_from_stdin(
        &[
            "live",
            "--headless",
            "--json",
            "--scenario",
            "shaft-steady",
            "--duration",
            "3",
            "--pace",
            "2",
            "--controls",
            "-",
        ],
        controls,
    );
    let errors = of_type(&ev, "error");
    assert_eq!(errors.len(), 2, "{errors:?}");
    assert_eq!(errors[0]["input"], "controls");
    assert_eq!(errors[0]["line"], 1);
    assert!(says(errors[0], "field 'rpm'"), "{}", errors[0]);
    assert!(says(errors[1], "field 'cmd' is 'warp'"), "{}", errors[1]);
    let applied = of_type(&ev, "control");
    assert_eq!(applied.len(), 1);
    assert_eq!(
        (&applied[0]["cmd"], &applied[0]["line"]),
        (&Value::from("fault"), &Value::from(2))
    );
    assert!(
        applied[0]["t_s"].as_f64().is_none_or(|t| t < 1.5),
        "{}",
        applied[0]
    );
    let alarms = of_type(&ev, "alarm");
    assert!(
        !alarms.is_empty() && alarms.iter().all(|a| a["param"] == "K"),
        "{alarms:?}"
    );
    let end = of_type(&ev, "end")[0];
    assert_eq!(end["t_s"], 3.0);
    // Paced: the end reports the latency quantiles (their values are the machine's).
    let l = &end["latency_ms"];
    let (p50, p99, max) = (
        l["p50"].as_f64().unwrap(),
        l["p99"].as_f64().unwrap(),
        l["max"].as_f64().unwrap(),
    );
    assert!(p50 <= p99 && p99 <= max + 0.1, "{l}");
}

/// The cycle events of the virtual cell (a time basis, 10 kHz, integrated over the crank angle
/// on the stream) against `physid simulate --basis crank` of the same run (one sample per
/// degree from the acquisition's own crank-angle grid, its `cycle` channel): the same cycles,
/// numbered alike, with the same per-cycle means to the sensors' noise.
#[test]
fn cycle_events_agree_with_the_crank_angle_recording() {
    let ev = events(&[
        "live",
        "--headless",
        "--json",
        "--scenario",
        "shaft-steady",
        "--duration",
        "3",
        "--pace",
        "max",
    ]);
    let cycles = of_type(&ev, "cycle");
    assert!(cycles.len() >= 20, "{} cycles", cycles.len());
    assert!(
        cycles.iter().all(|c| c.get("curve").is_none()),
        "no curves headless"
    );
    let s = Scratch::new("physid-live-cycles");
    let file = s.file("crank.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "3",
        "--basis",
        "crank",
        "--recording",
        file.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rec = physid_io::read_parquet(&file, None).unwrap();
    let cycle = rec.values("cycle").unwrap();
    let mut worst: f64 = 0.0;
    for c in &cycles {
        let n = c["cycle"].as_f64().unwrap();
        let rows: Vec<usize> = (0..cycle.len()).filter(|&i| cycle[i] == n).collect();
        assert_eq!(rows.len(), 720, "cycle {n} complete in the file");
        // Numbered alike: cycle n starts when the file's cycle n does (its 0° row), within
        // the stream's sample step.
        let t0 = rec.values("t").unwrap()[rows[0]];
        let dt = (c["t_start_s"].as_f64().unwrap() - t0).abs();
        assert!(dt < 1e-4, "cycle {n} starts {dt} s away from the file's");
        for (name, scale) in [
            ("omega_en", 104.7),
            ("torque_engine", 30.0),
            ("p_cyl", 2.1e6),
        ] {
            let x = rec.values(name).unwrap();
            let want = rows.iter().map(|&i| x[i]).sum::<f64>() / 720.0;
            let got = c["mean"][name].as_f64().unwrap();
            let rel = (got - want).abs() / scale;
            worst = worst.max(rel);
            assert!(
                rel < 2e-3,
                "cycle {n} {name}: {got} vs {want} ({rel:e} of its scale)"
            );
        }
    }
    eprintln!("worst difference of a cycle mean: {worst:e} of the channel's scale");
}

/// The friction characterisation on the stream: a replayed motored recording ends on
/// `physid friction fit`'s coefficients exactly (the replay is shorter than the choice, so the
/// choice is made on all its cycles, as the file verb makes it), whatever the chunk; on the
/// virtual cell, chosen after 20 cycles, the one-step predictions then follow the simulated
/// friction within the thesis's ±5 %.
#[test]
fn friction_on_the_stream_ends_on_the_file_verbs_fit() {
    let s = Scratch::new("physid-live-friction");
    let file = s.file("sweep.parquet");
    let f = file.to_str().unwrap();
    let o = physid(&[
        "simulate",
        "--scenario",
        "friction-sweep",
        "--duration",
        "8",
        "--recording",
        f,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = physid(&["friction", "fit", "--data", f, "--preset", "cell", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let verb: Value = serde_json::from_slice(&o.stdout).unwrap();
    for chunk in ["0.0017", "10"] {
        let ev = events(&[
            "live",
            "--headless",
            "--json",
            "--replay",
            f,
            "--pace",
            "max",
            "--chunk",
            chunk,
            "--friction",
            "cell",
            "--friction-after",
            "1000",
        ]);
        let chosen = of_type(&ev, "identifiability");
        assert_eq!(chosen.len(), 1, "chunk {chunk}");
        assert_eq!(chosen[0]["app"], "friction");
        assert_eq!(chosen[0]["estimable"], verb["estimable"], "chunk {chunk}");
        assert_eq!(
            chosen[0]["estimable"].as_array().unwrap().len()
                + chosen[0]["frozen"].as_array().unwrap().len(),
            20
        );
        let cycles = of_type(&ev, "friction");
        assert_eq!(
            cycles.len() as u64,
            verb["cycles"]["used"].as_u64().unwrap()
        );
        let last = cycles.last().unwrap();
        for p in verb["estimable"].as_array().unwrap() {
            let p = p.as_str().unwrap();
            assert_eq!(last["params"][p], verb["params"][p], "chunk {chunk}: {p}");
        }
    }
    let ev = events(&[
        "live",
        "--headless",
        "--json",
        "--scenario",
        "friction-sweep",
        "--duration",
        "12",
        "--pace",
        "max",
        "--friction",
        "cell",
        "--friction-after",
        "20",
    ]);
    let chosen = of_type(&ev, "identifiability");
    assert_eq!(chosen.len(), 1);
    let cycles = of_type(&ev, "friction");
    assert!(cycles.len() > 60, "{} cycles", cycles.len());
    // The last 20 cycles' predictions, made before each cycle was seen, against the truth.
    for c in &cycles[cycles.len() - 20..] {
        let (p, t) = (
            c["predicted"].as_f64().unwrap(),
            c["truth"].as_f64().unwrap(),
        );
        assert!(
            (p / t - 1.0).abs() < 0.05,
            "cycle {}: {p} vs {t}",
            c["cycle"]
        );
    }
}

/// `physid live --headless --json --pace max --frames-socket SOCK EXTRA…`, its stdout and
/// stderr piped.
#[cfg(unix)]
fn live_on_socket(sock: &std::path::Path, extra: &[&str]) -> std::process::Child {
    use std::process::{Command, Stdio};
    Command::new(env!("CARGO_BIN_EXE_physid"))
        .args(["live", "--headless", "--json", "--pace", "max"])
        .args(extra)
        .arg("--frames-socket")
        .arg(sock)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// The events a run prints to its end, which must be a success.
fn events_at_end(mut child: std::process::Child) -> Vec<Value> {
    use std::io::Read;
    let mut out = String::new();
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut out)
        .unwrap();
    let status = child.wait().unwrap();
    assert!(status.success(), "{status:?}");
    out.lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Frames over a local socket: physid listens on a Unix socket only its user can open, a
/// client's frames give `monitor shaft`'s very estimate, the run ends when the client closes,
/// the socket is removed; a path in use is refused.
#[cfg(unix)]
#[test]
fn frames_over_a_local_socket() {
    use std::io::Write;
    use std::os::unix::fs::{FileTypeExt, PermissionsExt};
    use std::os::unix::net::UnixStream;
    use std::time::{Duration, Instant};
    let s = Scratch::new("physid-live-socket");
    let file = s.file("t01.parquet");
    let f = file.to_str().unwrap();
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "1",
        "--recording",
        f,
    ]);
    assert!(o.status.success());
    let o = physid(&["monitor", "shaft", "--data", f, "--json"]);
    let verb: Value = serde_json::from_slice(&o.stdout).unwrap();
    let rec = physid_io::read(&file, &Default::default()).unwrap();
    let sock = s.file("daq.sock");
    let child = live_on_socket(&sock, &[]);
    let deadline = Instant::now() + Duration::from_secs(20);
    while !sock.exists() {
        assert!(Instant::now() < deadline, "the socket never appeared");
        std::thread::sleep(Duration::from_millis(20));
    }
    let meta = std::fs::metadata(&sock).unwrap();
    assert!(meta.file_type().is_socket());
    assert_eq!(meta.permissions().mode() & 0o777, 0o600);
    // A second service on the same path is refused while the first listens.
    let o = physid(&[
        "live",
        "--headless",
        "--json",
        "--frames-socket",
        sock.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("already exists"));
    let mut client = UnixStream::connect(&sock).unwrap();
    let n = rec.len();
    for (k, start) in (0..n).step_by(700).enumerate() {
        let mut obj = serde_json::Map::new();
        obj.insert("seq".into(), k.into());
        for name in physid_live::FRAME_CHANNELS {
            let v = rec.values(name).unwrap();
            obj.insert(name.into(), v[start..(start + 700).min(n)].into());
        }
        writeln!(client, "{}", Value::Object(obj)).unwrap();
        if k == 3 {
            // A bad client line is refused; the run goes on.
            client.write_all(b"\xff\xfe not a frame\n").unwrap();
        }
    }
    client.shutdown(std::net::Shutdown::Write).unwrap();
    let ev = events_at_end(child);
    let end = of_type(&ev, "end")[0];
    assert_eq!(
        (end["samples"].as_u64(), end["dropped"].as_u64()),
        (Some(n as u64), Some(1))
    );
    let last = of_type(&ev, "estimate").last().copied().unwrap().clone();
    for p in ["K", "B"] {
        assert_eq!(last["params"][p], verb["final"][p], "{p}");
    }
    assert!(!sock.exists(), "the socket is removed at the end");
}

/// Frames on stdin from a sender that goes silent with its pipe open (a DAQ that hangs): SIGTERM
/// ends the run as its end does — exit 0, the `end` event with every sample taken before it —
/// instead of the run sitting in its read until the signal's 5 s grace ran out and exiting 130
/// without its `end` (the pipe is read on a thread of its own, `PipedFrames`).
#[cfg(unix)]
#[test]
fn a_signal_ends_a_run_waiting_for_frames_on_stdin() {
    use std::io::{BufRead, BufReader, Write};
    use std::process::{Command, Stdio};
    use std::time::{Duration, Instant};
    let s = Scratch::new("physid-live-stdin-signal");
    let file = s.file("t01.csv");
    common::simulated(&file, "shaft-steady", "2");
    let (frames, n) = frames_of(&file);
    let mut child = Command::new(env!("CARGO_BIN_EXE_physid"))
        .args([
            "live",
            "--headless",
            "--json",
            "--pace",
            "max",
            "--frames",
            "-",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    for f in &frames {
        writeln!(stdin, "{f}").unwrap();
    }
    stdin.flush().unwrap();
    // The events as they come, until an estimate from the last tenth of a second's samples.
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let (mut ev, mut line) = (Vec::<Value>::new(), String::new());
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        line.clear();
        assert!(
            out.read_line(&mut line).unwrap() > 0,
            "the run ended: {ev:?}"
        );
        let e: Value = serde_json::from_str(&line).unwrap();
        let late = e["type"] == "estimate" && e["t_s"].as_f64().unwrap() >= 1.9;
        ev.push(e);
        if late {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "no estimate from 1.9 s on: {ev:?}"
        );
    }
    // The sender is silent, its pipe open (`stdin` is held to the end).
    let _ = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status();
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut out, &mut rest).unwrap();
    let status = child.wait().unwrap();
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert!(status.success(), "{status:?}: {err}");
    ev.extend(
        rest.lines()
            .map(|l| serde_json::from_str::<Value>(l).unwrap()),
    );
    let end = of_type(&ev, "end");
    assert_eq!(end.len(), 1, "{err}");
    let samples = end[0]["samples"].as_u64().unwrap();
    assert!((19_000..=n as u64).contains(&samples), "{}", end[0]);
    drop(stdin);
}

/// A `stop` control while the sender is silent — frames on stdin with the pipe open, a socket
/// no client has connected to — ends the run: the control is answered (`control` event), the
/// stages finish, `end`, exit 0. Before, controls were applied only when a frame came: the run
/// sat waiting for the sender, and the panel's controls timed out ("no answer from the run
/// within 5 s"); and `--controls FILE` could not go with `--frames -` at all.
#[cfg(unix)]
#[test]
fn a_stop_control_ends_a_run_whose_sender_is_silent() {
    use std::process::{Command, Stdio};
    use std::time::{Duration, Instant};
    let s = Scratch::new("physid-live-silent-stop");
    let controls = s.file("controls.ndjson");
    std::fs::write(&controls, "{\"cmd\":\"stop\"}\n").unwrap();
    let sock = s.file("daq.sock");
    let sock = sock.to_str().unwrap();
    for source in [["--frames", "-"], ["--frames-socket", sock]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_physid"))
            .args(["live", "--headless", "--json", "--pace", "max"])
            .args(source)
            .arg("--controls")
            .arg(&controls)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // The sender: stdin held open, silent.
        let stdin = child.stdin.take();
        let deadline = Instant::now() + Duration::from_secs(60);
        while child.try_wait().unwrap().is_none() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(50));
        }
        if child.try_wait().unwrap().is_none() {
            let _ = child.kill();
            panic!("{source:?}: the run did not end at the stop control within 60 s");
        }
        drop(stdin);
        let ev = events_at_end(child);
        let stop: Vec<_> = of_type(&ev, "control")
            .into_iter()
            .filter(|e| e["cmd"] == "stop")
            .collect();
        assert_eq!(stop.len(), 1, "{source:?}: {ev:?}");
        let end = of_type(&ev, "end");
        assert_eq!(end.len(), 1, "{source:?}: {ev:?}");
        assert_eq!(end[0]["samples"], 0, "{source:?}");
        // No sample, nothing wrong: no stage says it stopped.
        assert!(of_type(&ev, "finding").is_empty(), "{source:?}: {ev:?}");
    }
    // Frames and controls cannot both be stdin.
    let o = physid(&["live", "--headless", "--frames", "-", "--controls", "-"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("both read standard input"),
        "{err}"
    );
}

/// A DAQ that connects again: with `--frames-reconnect`, a client that closes in the middle of
/// a frame is followed by the next client — the unfinished frame refused alone, the next
/// client's frames taken from its first line, its connection told as a finding, each close
/// told on stderr — and SIGTERM while waiting for a client ends the run as its end does (exit
/// 0, `end`, the socket removed): the estimate is `monitor shaft`'s on the file, exactly.
/// Before, the run ended when the first client closed.
#[cfg(unix)]
#[test]
fn a_daq_that_connects_again_goes_on() {
    use std::io::{BufRead, BufReader, Write};
    use std::os::unix::net::UnixStream;
    use std::process::Command;
    use std::time::{Duration, Instant};
    let s = Scratch::new("physid-live-reconnect");
    let file = s.file("t01.parquet");
    let f = file.to_str().unwrap();
    common::simulated(&file, "shaft-steady", "2");
    let o = physid(&["monitor", "shaft", "--data", f, "--json"]);
    let verb: Value = serde_json::from_slice(&o.stdout).unwrap();
    let (frames, n) = frames_of(&file);
    let sock = s.file("daq.sock");
    let mut child = live_on_socket(&sock, &["--frames-reconnect"]);
    // stderr's lines, as they come.
    let (tx, rx) = std::sync::mpsc::channel::<String>();
    let stderr = BufReader::new(child.stderr.take().unwrap());
    std::thread::spawn(move || {
        for line in stderr.lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut told = Vec::new();
    let mut wait_for = |what: &str| loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(line) => {
                let found = line.contains(what);
                told.push(line);
                if found {
                    return;
                }
            }
            Err(e) => panic!("{e}: no '{what}' on stderr: {told:?}"),
        }
    };
    wait_for("waiting for frames on");
    let half = frames.len() / 2;
    let mut a = UnixStream::connect(&sock).unwrap();
    for f in &frames[..half] {
        writeln!(a, "{f}").unwrap();
    }
    // The DAQ dies in the middle of a frame.
    a.write_all(&frames[half].as_bytes()[..frames[half].len() / 2])
        .unwrap();
    drop(a);
    wait_for(
        "(the 1st) closed its connection in the middle of a line (refused): waiting for the next",
    );
    // It starts again and sends from the frame it was sending.
    let mut b = UnixStream::connect(&sock).unwrap();
    for f in &frames[half..] {
        writeln!(b, "{f}").unwrap();
    }
    drop(b);
    wait_for("(the 2nd) closed its connection: waiting for the next");
    let _ = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status();
    let ev = events_at_end(child);
    let end = of_type(&ev, "end")[0];
    assert_eq!(
        (end["samples"].as_u64(), end["dropped"].as_u64()),
        (Some(n as u64), Some(1))
    );
    let errors = of_type(&ev, "error");
    assert_eq!(errors.len(), 1, "{errors:?}");
    let connected: Vec<_> = of_type(&ev, "finding")
        .into_iter()
        .filter(|e| says(e, "the 2nd client connected on"))
        .collect();
    assert_eq!(connected.len(), 1, "{ev:?}");
    let last = of_type(&ev, "estimate").last().copied().unwrap().clone();
    for p in ["K", "B"] {
        assert_eq!(last["params"][p], verb["final"][p], "{p}");
    }
    assert!(!sock.exists(), "the socket is removed at the end");
}

/// Integrity findings on the stream: encoder pulses lost from 2 s on (a sensor fault of the
/// virtual cell) are found revolution by revolution as the run goes, with their kind and
/// sample — the very findings `physid inspect` makes on the recorded file, whatever the chunk —
/// and none before the fault.
#[test]
fn integrity_findings_on_the_stream_are_inspects() {
    let s = Scratch::new("physid-live-integrity");
    let file = s.file("lossy.parquet");
    let f = file.to_str().unwrap();
    let fault = "sensors.lost_pulses_en=0.01@2";
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "4",
        "--fault",
        fault,
        "--recording",
        f,
    ]);
    assert!(o.status.success());
    let o = physid(&["inspect", f, "--json"]);
    let inspect: Value = serde_json::from_slice(&o.stdout).unwrap();
    let want: Vec<(String, u64, String)> = inspect["integrity"]["findings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            (
                f["kind"].as_str().unwrap().to_string(),
                f["index"].as_u64().unwrap(),
                f["detail"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    assert!(
        want.len() > 10 && want.iter().all(|w| w.0 == "pulse_loss"),
        "{want:?}"
    );
    let found = |ev: &[Value]| -> Vec<(String, u64, String)> {
        let mut v: Vec<_> = of_type(ev, "finding")
            .iter()
            .filter(|e| e.get("kind").is_some())
            .map(|e| {
                (
                    e["kind"].as_str().unwrap().to_string(),
                    e["sample"].as_u64().unwrap(),
                    e["message"].as_str().unwrap().to_string(),
                )
            })
            .collect();
        v.sort();
        v
    };
    let mut want_sorted = want.clone();
    want_sorted.sort();
    for chunk in ["0.0017", "10"] {
        let ev = events(&[
            "live",
            "--headless",
            "--json",
            "--replay",
            f,
            "--pace",
            "max",
            "--chunk",
            chunk,
        ]);
        assert_eq!(found(&ev), want_sorted, "chunk {chunk}");
    }
    // The virtual cell itself, live: the same findings, each at the time of its sample.
    let ev = events(&[
        "live",
        "--headless",
        "--json",
        "--scenario",
        "shaft-steady",
        "--duration",
        "4",
        "--pace",
        "max",
        "--fault",
        fault,
    ]);
    assert_eq!(found(&ev), want_sorted);
    for e in of_type(&ev, "finding") {
        let t = e["t_s"].as_f64().unwrap();
        assert!(
            (t - e["sample"].as_f64().unwrap() * 1e-4).abs() < 1e-9 && t > 1.9,
            "{e}"
        );
    }
}

/// The cyclic-torque estimation on the stream: a replayed motored recording ends on
/// `physid torque fit`'s estimates exactly (the replay is shorter than the choice, so it is made
/// on all of it, as the file verb makes it), whatever the chunk; on the virtual cell, chosen
/// after 10 cycles, the estimates find the cell's true bore, crank radius and rod length.
#[test]
fn cyclic_torque_on_the_stream_ends_on_the_file_verbs_fit() {
    let s = Scratch::new("physid-live-torque");
    let file = s.file("ramp.parquet");
    let f = file.to_str().unwrap();
    let o = physid(&[
        "simulate",
        "--scenario",
        "torque-ramp",
        "--duration",
        "2",
        "--recording",
        f,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = physid(&["torque", "fit", "--data", f, "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let verb: Value = serde_json::from_slice(&o.stdout).unwrap();
    for chunk in ["0.0017", "10"] {
        let ev = events(&[
            "live",
            "--headless",
            "--json",
            "--replay",
            f,
            "--pace",
            "max",
            "--chunk",
            chunk,
            "--torque",
            "--torque-after",
            "1000",
        ]);
        let chosen = of_type(&ev, "identifiability");
        assert_eq!(chosen.len(), 1, "chunk {chunk}");
        assert_eq!(chosen[0]["app"], "torque");
        assert_eq!(chosen[0]["estimable"], verb["estimable"], "chunk {chunk}");
        let cycles = of_type(&ev, "torque");
        assert_eq!(
            cycles.len() as u64 * 720,
            verb["samples"].as_u64().unwrap(),
            "chunk {chunk}"
        );
        let last = cycles.last().unwrap();
        for p in verb["estimable"].as_array().unwrap() {
            let p = p.as_str().unwrap();
            assert_eq!(last["params"][p], verb["params"][p], "chunk {chunk}: {p}");
            assert_eq!(last["std_err"][p], verb["std_err"][p], "chunk {chunk}: {p}");
        }
    }
    let ev = events(&[
        "live",
        "--headless",
        "--json",
        "--scenario",
        "torque-ramp",
        "--duration",
        "4",
        "--pace",
        "max",
        "--torque",
    ]);
    let last = of_type(&ev, "torque").last().copied().unwrap().clone();
    let e = physid_sim::params::CellParams::default().engine;
    for (name, truth) in [("b", e.bore), ("r", e.crank_radius), ("L", e.rod)] {
        let v = last["params"][name].as_f64().unwrap();
        assert!((v / truth - 1.0).abs() < 1e-3, "{name}: {v} vs {truth}");
    }
    assert!(last["rms_error"].as_f64().unwrap() < 0.02 * last["rms_measured"].as_f64().unwrap());
}

/// `--supervise` on a healthy, excited shaft: the live service tells the supervisor's state once
/// (everything estimated) and never a change; `monitor shaft --supervise` reports no time
/// frozen and the same final estimate as the replay.
#[test]
fn the_supervised_shaft_reports_nothing_frozen_while_excited() {
    let s = Scratch::new("physid-live-supervise");
    let file = s.file("t01.parquet");
    let f = file.to_str().unwrap();
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-ramp",
        "--duration",
        "6",
        "--recording",
        f,
    ]);
    assert!(o.status.success());
    let ev = events(&[
        "live",
        "--headless",
        "--json",
        "--replay",
        f,
        "--pace",
        "max",
        "--supervise",
    ]);
    let told = of_type(&ev, "identifiability");
    assert_eq!(told.len(), 1, "{told:?}");
    assert_eq!(told[0]["app"], "shaft");
    assert_eq!(told[0]["estimable"], serde_json::json!(["K", "B", "tau0"]));
    let o = physid(&["monitor", "shaft", "--data", f, "--json", "--supervise"]);
    assert!(o.status.success());
    let verb: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(verb["frozen_s"], serde_json::json!({"K": 0.0, "B": 0.0}));
    let last = of_type(&ev, "estimate").last().copied().unwrap().clone();
    for p in ["K", "B"] {
        assert_eq!(last["params"][p], verb["final"][p], "{p}");
    }
}

/// The virtual cell's scenario and demand mode change while it runs: `shaft-ramp`'s demand
/// from now on takes the engine from 750 rpm up at its 25 rpm/s; torque demand held at the
/// dynamometer's mean torque over the last whole cycle keeps the engine near its speed (it then
/// finds its own); an unknown scenario and a bad mode are refused by field and the run goes on.
/// Paced (4× and 2× real time) so that the controls arrive while the run is young; what is
/// checked is measured from the time each control took effect (the speed settles on the new
/// demand within 0.5 s).
#[test]
fn scenario_and_demand_mode_change_while_it_runs() {
    let rpm = |e: &Value| e["mean"]["omega_en"].as_f64().unwrap() * 30.0 / std::f64::consts::PI;
    let t = |e: &Value| e["t_s"].as_f64().unwrap();
    // When a control took effect: its event's time (null before the first chunk).
    let took_effect = |ev: &[Value], cmd: &str| {
        let c = of_type(ev, "control");
        let c = c.iter().find(|c| c["cmd"] == cmd).expect(cmd);
        c["t_s"].as_f64().unwrap_or(0.0)
    };
    let ev = events_from_stdin(
        &[
            "live", "--headless", "--json", "--scenario", "shaft-steady", "--duration", "6",
            "--pace", "4", "--controls", "-",
        ],
        "{\"cmd\":\"scenario\",\"name\":\"warp\"}\n{\"cmd\":\"mode\",\"demand\":\"fast\"}\n{\"cmd\":\"scenario\",\"name\":\"shaft-ramp\"}\n",
    );
    let errors = of_type(&ev, "error");
    assert_eq!(errors.len(), 2, "{errors:?}");
    assert!(says(errors[0], "field 'name' is 'warp'") && says(errors[0], "shaft-ramp"));
    assert!(says(errors[1], "field 'demand'"));
    let at = took_effect(&ev, "scenario");
    assert!(at < 2.0, "the scenario changed only at {at} s");
    let cycles: Vec<&Value> = of_type(&ev, "cycle")
        .into_iter()
        .filter(|c| t(c) > at + 0.5)
        .collect();
    let (first, last) = (cycles[0], cycles[cycles.len() - 1]);
    let slope = (rpm(last) - rpm(first)) / (t(last) - t(first));
    assert!((slope / 25.0 - 1.0).abs() < 0.2, "{slope} rpm/s");
    let want = 750.0 + 25.0 * (t(first) - at);
    assert!(
        (rpm(first) - want).abs() < 40.0,
        "{} rpm, {want} wanted",
        rpm(first)
    );
    let ev = events_from_stdin(
        &[
            "live",
            "--headless",
            "--json",
            "--scenario",
            "shaft-steady",
            "--duration",
            "4",
            "--pace",
            "2",
            "--controls",
            "-",
        ],
        "{\"cmd\":\"mode\",\"demand\":\"torque\"}\n",
    );
    let at = took_effect(&ev, "mode");
    assert!(at < 2.0, "the mode changed only at {at} s");
    for c in of_type(&ev, "cycle") {
        assert!(
            (rpm(c) / 1000.0 - 1.0).abs() < 0.01,
            "{} rpm at {} s",
            rpm(c),
            t(c)
        );
    }
}

/// A stage that fails does not stop the service: a replayed recording without the shaft's
/// channels gets a finding naming the missing channel, and its cycles are still counted to the
/// end.
#[test]
fn a_stage_that_fails_stops_alone() {
    let s = Scratch::new("physid-live-stage-fails");
    let full = s.file("full.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "2",
        "--recording",
        full.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    // The same recording without the dynamometer's angle.
    let all = physid_io::read(&full, &Default::default()).unwrap();
    let mut rec = physid_core::Recording::new(all.basis);
    for c in all.channels().iter().filter(|c| c.name != "theta_dy") {
        rec.push(c.clone()).unwrap();
    }
    let part = s.file("part.parquet");
    physid_io::write(&part, &rec, &Default::default()).unwrap();
    let ev = events(&[
        "live",
        "--headless",
        "--json",
        "--replay",
        part.to_str().unwrap(),
        "--pace",
        "max",
    ]);
    let stopped: Vec<&Value> = of_type(&ev, "finding")
        .into_iter()
        .filter(|f| says(f, "the shaft monitor stopped"))
        .collect();
    assert_eq!(stopped.len(), 1, "{stopped:?}");
    assert!(says(stopped[0], "theta_dy"), "{}", stopped[0]);
    assert!(of_type(&ev, "estimate").is_empty());
    assert!(of_type(&ev, "cycle").len() > 10);
    assert_eq!(of_type(&ev, "end")[0]["samples"], 20001);
}

/// A crank-angle file replayed as it is read (a first pass over `t` for the mean rate, then
/// resampled chunk by chunk) hands out the samples the recording put on a time basis whole
/// does, bit for bit, at the same rate.
#[test]
fn a_crank_angle_file_replays_as_read_as_the_whole_recording_does() {
    use physid_live::{ReplaySource, Source};
    use physid_sim::run::{simulate, OutputBasis, RunOptions};
    let s = Scratch::new("physid-replay-crank");
    let opts = RunOptions {
        duration: Some(12.0),
        basis: OutputBasis::Crank(1.0),
        ..Default::default()
    };
    let rec = simulate(
        &physid_sim::scenario::named("shaft-steady").unwrap(),
        &opts,
        |_| {},
    )
    .unwrap();
    assert!(rec.len() > physid_io::CHUNK_ROWS);
    let f = s.file("deg.parquet");
    physid_io::write(&f, &rec, &Default::default()).unwrap();
    let drain = |mut src: ReplaySource| {
        let rate = src.rate_hz();
        let mut all: Option<physid_core::Recording> = None;
        while let Some(c) = src.next_chunk().unwrap() {
            match all.as_mut() {
                None => all = Some(c),
                Some(a) => a.append(&c).unwrap(),
            }
        }
        (rate, all.unwrap())
    };
    let (rate_read, read) = drain(ReplaySource::open(&f, &Default::default(), 0.1).unwrap());
    let whole = physid_io::read(&f, &Default::default()).unwrap();
    let (rate_whole, want) = drain(ReplaySource::new(whole, 0.1).unwrap());
    assert_eq!(rate_read, rate_whole);
    assert_eq!(read.names(), want.names());
    assert!(read.len() > physid_io::CHUNK_ROWS, "{}", read.len());
    for ch in want.channels() {
        assert_eq!(
            read.values(&ch.name).unwrap(),
            &ch.values[..],
            "{}",
            ch.name
        );
    }
}

/// One unreadable control line — not UTF-8, or longer than the 64 KiB cap (never held whole)
/// — is refused with an error event naming its line, and the lines after it still act: the
/// `stop` ends a 30 s run at once.
#[test]
fn an_unreadable_control_line_is_refused_and_the_next_ones_act() {
    let mut input = b"{\"cmd\":\"spe\xff\xfeed\"}\n".to_vec();
    input.extend_from_slice(
        format!(
            "{{\"cmd\":\"fault\",\"spec\":\"{}\"}}\n",
            "x".repeat(200_000)
        )
        .as_bytes(),
    );
    input.extend_from_slice(b"{\"cmd\":\"stop\"}\n");
    let t0 = std::time::Instant::now();
    let ev = events_from_stdin_bytes(
        &[
            "live",
            "--headless",
            "--json",
            "--scenario",
            "shaft-steady",
            "--duration",
            "30",
            "--pace",
            "3",
            "--controls",
            "-",
        ],
        &input,
    );
    assert!(t0.elapsed().as_secs() < 8, "the stop was not taken");
    let errors = of_type(&ev, "error");
    assert_eq!(errors.len(), 2, "{errors:?}");
    assert!(
        says(errors[0], "line 1 of the controls is not UTF-8 (byte 12"),
        "{}",
        errors[0]
    );
    assert!(
        says(errors[1], "line 2 of the controls is 200025 bytes long"),
        "{}",
        errors[1]
    );
    assert!(errors[1]["message"].as_str().unwrap().len() < 300);
    let controls = of_type(&ev, "control");
    assert_eq!(controls.len(), 1);
    assert_eq!(controls[0]["cmd"], "stop");
    let end = of_type(&ev, "end");
    assert!(end[0]["t_s"].as_f64().unwrap() < 10.0, "{}", end[0]);
}

/// A cell that stops turning (the dynamometer switched to a zero torque demand: the engine
/// coasts down to a standstill) raises no alarm and leaves the shaft monitor running, its
/// estimates held near the healthy K and B; a speed demand below the operating envelope is
/// refused naming it, and the run goes on.
#[test]
fn a_cell_that_stops_turning_raises_no_alarm() {
    let ev = events_from_stdin(
        &[
            "live", "--headless", "--json", "--scenario", "shaft-steady", "--duration", "14",
            "--pace", "max", "--controls", "-",
        ],
        "{\"cmd\":\"speed\",\"rpm\":0}\n{\"cmd\":\"mode\",\"demand\":\"torque\"}\n{\"cmd\":\"speed\",\"rpm\":0}\n",
    );
    let errors = of_type(&ev, "error");
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(
        says(
            errors[0],
            "outside the cell's operating envelope, 500–6000 rpm"
        ),
        "{}",
        errors[0]
    );
    assert!(
        of_type(&ev, "alarm").is_empty(),
        "{:?}",
        of_type(&ev, "alarm")
    );
    assert!(
        !of_type(&ev, "finding").iter().any(|f| says(f, "stopped")),
        "a stage stopped"
    );
    // The engine did stop: its last cycles' mean speed falls below 300 rpm.
    let cycles = of_type(&ev, "cycle");
    let slowest = cycles
        .iter()
        .map(|c| c["mean"]["omega_en"].as_f64().unwrap())
        .fold(f64::INFINITY, f64::min);
    assert!(slowest < 31.4, "{slowest} rad/s");
    let last = of_type(&ev, "estimate").last().copied().unwrap();
    let (k, b) = (
        last["params"]["K"].as_f64().unwrap(),
        last["params"]["B"].as_f64().unwrap(),
    );
    // The virtual cell's shaft: K = 1250 N·m/rad, B = 0.95 N·m·s/rad.
    assert!((k / 1250.0 - 1.0).abs() < 0.05, "K = {k}");
    assert!((b / 0.95 - 1.0).abs() < 0.2, "B = {b}");
}

/// `{"cmd":"restart","stage":"shaft"}` starts the shaft monitor afresh mid-run (what brings
/// back one stopped by an error): its standard errors start again from the prior's and the
/// estimates converge again on the shaft's K; a stage the run does not have is refused by
/// field.
#[test]
fn a_stage_restarts_on_the_control() {
    use std::io::Write;
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_physid"))
        .args([
            "live",
            "--headless",
            "--json",
            "--scenario",
            "shaft-steady",
            "--duration",
            "8",
            "--pace",
            "4",
            "--controls",
            "-",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    // Well into the run (≈ 3 s of recording at pace 4).
    std::thread::sleep(std::time::Duration::from_millis(750));
    writeln!(stdin, r#"{{"cmd":"restart","stage":"torque"}}"#).unwrap();
    writeln!(stdin, r#"{{"cmd":"restart","stage":"shaft"}}"#).unwrap();
    drop(stdin);
    let o = child.wait_with_output().unwrap();
    let ev: Vec<Value> = String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let errors = of_type(&ev, "error");
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(
        says(
            errors[0],
            "field 'stage' is 'torque': this run has none (--torque)"
        ),
        "{}",
        errors[0]
    );
    let restarted = of_type(&ev, "control");
    assert_eq!(restarted.len(), 1);
    let t_restart = restarted[0]["t_s"].as_f64().unwrap();
    assert!(t_restart > 1.0, "{t_restart}");
    let se_k = |e: &Value| e["std_err"]["K"].as_f64().unwrap_or(f64::INFINITY);
    let before = of_type(&ev, "estimate")
        .into_iter()
        .rfind(|e| e["t_s"].as_f64().unwrap() <= t_restart)
        .unwrap();
    let after: Vec<&Value> = of_type(&ev, "estimate")
        .into_iter()
        .filter(|e| e["t_s"].as_f64().unwrap() > t_restart)
        .collect();
    assert!(
        after.len() > 10,
        "{} estimates after the restart",
        after.len()
    );
    assert!(
        se_k(after[0]) > 10.0 * se_k(before),
        "{} then {}",
        before,
        after[0]
    );
    let last = after.last().unwrap();
    let k = last["params"]["K"].as_f64().unwrap();
    assert!((k / 1250.0 - 1.0).abs() < 0.02, "K = {k}");
}

/// A `stop` control ends a replay (the source cannot end itself: the service does) — it was
/// refused as "only the virtual test cell takes controls" and the replay ran to its end.
#[test]
fn a_stop_control_ends_a_replay() {
    let s = Scratch::new("physid-live-stop");
    let file = s.file("run.parquet");
    let f = file.to_str().unwrap();
    common::simulated(&file, "shaft-steady", "20");
    let ev = events_from_stdin(
        &[
            "live",
            "--headless",
            "--json",
            "--replay",
            f,
            "--pace",
            "1",
            "--controls",
            "-",
        ],
        "{\"cmd\":\"stop\"}\n",
    );
    assert!(
        of_type(&ev, "error").is_empty(),
        "{:?}",
        of_type(&ev, "error")
    );
    assert_eq!(of_type(&ev, "control")[0]["cmd"], "stop");
    let end = of_type(&ev, "end")[0];
    // Ended within the first seconds of a 20 s replay at real-time pace.
    assert!(end["t_s"].as_f64().unwrap() < 5.0, "{end}");
}

/// A replayed file damaged part-way (64 bytes changed in its third row group of four: found by
/// the column chunks' CRC-32) ends the run as its end would: an `error` event (`"input":
/// "source"`) naming the file, the column and the rows, the stages' last estimate, the log
/// being recorded closed and readable with every sample it took, then `end`; exit 1 with
/// the error on stderr. Before, the events stopped mid-run: no error on the stream, no `end`.
#[test]
fn a_damaged_replay_ends_the_run_as_its_end_would() {
    let s = Scratch::new("physid-live-damaged");
    let file = s.file("run.parquet");
    common::simulated(&file, "shaft-steady", "20");
    let mut bytes = std::fs::read(&file).unwrap();
    let at = bytes.len() * 5 / 6;
    for b in &mut bytes[at..at + 64] {
        *b ^= 0xff;
    }
    std::fs::write(&file, &bytes).unwrap();
    let controls = s.file("controls.ndjson");
    std::fs::write(&controls, "{\"cmd\":\"record\",\"file\":\"log.parquet\"}\n").unwrap();
    let logs = s.file("logs");
    let o = physid(&[
        "live",
        "--headless",
        "--json",
        "--replay",
        file.to_str().unwrap(),
        "--pace",
        "max",
        "--controls",
        controls.to_str().unwrap(),
        "--log-dir",
        logs.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("corrupt Parquet"), "{stderr}");
    let ev: Vec<Value> = String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let errors = of_type(&ev, "error");
    assert_eq!(errors.len(), 1, "{errors:?}");
    let error = errors[0];
    assert_eq!(error["input"], "source");
    assert!(
        says(error, "run.parquet: corrupt Parquet: column '")
            && says(error, "of row group 2 (rows 131072 to 196607")
            && says(
                error,
                "the file was damaged or changed after it was written"
            ),
        "{error}"
    );
    let end = ev.last().unwrap();
    assert_eq!(end["type"], "end", "the run ends with `end`");
    let samples = end["samples"].as_u64().unwrap();
    // Every sample before the damaged row group went through, to the last.
    assert_eq!(samples, 131_072);
    assert_eq!(error["line"], samples, "the error names the samples taken");
    let after: Vec<&str> = ev
        .iter()
        .skip_while(|e| e["type"] != "error")
        .map(|e| e["type"].as_str().unwrap())
        .collect();
    assert_eq!(
        after,
        ["error", "estimate", "log", "end"],
        "after the error"
    );
    let log = of_type(&ev, "log");
    let last = log.last().unwrap();
    assert_eq!(last["state"], "closed", "{last}");
    assert_eq!(last["t_s"], end["t_s"], "closed at the end: {last}");
    // The control is read on its own thread: the log starts at some chunk of the run.
    let logged = last["samples"].as_u64().unwrap();
    assert!(logged > 0 && logged <= samples, "{logged} of {samples}");
    let inspect = physid(&[
        "inspect",
        logs.join("log.parquet").to_str().unwrap(),
        "--json",
    ]);
    assert!(
        inspect.status.success(),
        "{}",
        String::from_utf8_lossy(&inspect.stderr)
    );
    let summary: Value = serde_json::from_slice(&inspect.stdout).unwrap();
    for c in summary["channels"].as_array().unwrap() {
        assert_eq!(c["samples"], logged, "{c}");
    }
}

/// A NaN in a replayed file (a sensor's dropout): the shaft monitor holds it at the signal's
/// last value, tells it and goes on — its estimates go on past it and end on `monitor shaft`'s
/// on the clean file (before, it stopped for the rest of the run: "shaft: sample 5000: a shaft
/// signal is not finite"); the cycle statistics leave out the cycle it cuts, tell it, and go on
/// — every other cycle is the clean file's, JSON for JSON, under the same number (before, they
/// stopped: "cycles: channel 0 is NaN at sample 5000"); the run goes on to the file's end — it
/// used to end the whole run.
#[test]
fn a_nan_in_a_replayed_file_is_a_dropout_not_a_stop() {
    let s = Scratch::new("physid-live-nan");
    let file = s.file("run.csv");
    let f = file.to_str().unwrap();
    common::simulated(&file, "shaft-steady", "3");
    let o = physid(&["monitor", "shaft", "--data", f, "--json"]);
    let clean: Value = serde_json::from_slice(&o.stdout).unwrap();
    let args = [
        "live",
        "--headless",
        "--json",
        "--replay",
        f,
        "--pace",
        "max",
    ];
    let clean_ev = events_from_stdin(&args, "");
    common::set_cells(&file, "omega_en", 5000..5001, "nan");
    let ev = events_from_stdin(&args, "");
    let findings = of_type(&ev, "finding");
    assert!(
        findings.iter().any(|e| says(
            e,
            "shaft: 'omega_en' is not a number from sample 5000: held at its last value"
        )),
        "{findings:?}"
    );
    let estimates = of_type(&ev, "estimate");
    let last = estimates.last().unwrap();
    assert!(last["t_s"].as_f64().unwrap() > 2.5, "{last}");
    for p in ["K", "B"] {
        let (got, want) = (
            last["params"][p].as_f64().unwrap(),
            clean["final"][p].as_f64().unwrap(),
        );
        assert!((got / want - 1.0).abs() < 1e-9, "{p}: {got} vs {want}");
    }
    assert!(
        findings.iter().any(
            |e| says(e, "cycles: 'omega_en' is NaN at sample 5000 (t = 0.5")
                && says(e, "s): the cycle it cuts is left out")
        ),
        "{findings:?}"
    );
    let end = of_type(&ev, "end")[0];
    assert_eq!(end["samples"], 30001, "{end}");
    // Every cycle but the one the NaN (at 0.5 s) cuts is the clean file's.
    let cut =
        |c: &&Value| c["t_start_s"].as_f64().unwrap() <= 0.5 && c["t_s"].as_f64().unwrap() >= 0.5;
    let want: Vec<&Value> = of_type(&clean_ev, "cycle")
        .into_iter()
        .filter(|c| !cut(c))
        .collect();
    let got = of_type(&ev, "cycle");
    assert_eq!(want.len() + 1, of_type(&clean_ev, "cycle").len());
    assert!(want.len() > 15, "{} cycles", want.len());
    assert_eq!(got, want);
}

/// NaNs in the channels the cycle stages read (a cylinder pressure's dropout of 10 samples at
/// 1 s, a manifold pressure's single NaN at 2.5 s): the combustion analysis, the cyclic-torque
/// estimation and the friction characterisation each leave out the cycle it cuts, tell it once
/// with the channel and sample, and go on to the file's end — before, each stopped for the rest
/// of the run at the first. The combustion figures of every other cycle are the clean file's,
/// JSON for JSON with the same numbers; the torque and friction events before the first dropout
/// are the clean file's, and they go on after the last.
#[test]
fn a_nan_in_a_channel_a_cycle_stage_reads_leaves_out_its_cycle() {
    let s = Scratch::new("physid-live-nan-cycles");
    let file = s.file("run.csv");
    let f = file.to_str().unwrap();
    common::simulated(&file, "torque-steady", "4");
    let args = [
        "live",
        "--headless",
        "--json",
        "--replay",
        f,
        "--pace",
        "max",
        "--torque",
        "--combustion",
        "--friction",
        "cell",
    ];
    let clean = events_from_stdin(&args, "");
    common::set_cells(&file, "p_cyl", 10_000..10_010, "nan");
    common::set_cells(&file, "p_int", 25_000..25_001, "nan");
    let ev = events_from_stdin(&args, "");
    let findings = of_type(&ev, "finding");
    for (stage, what) in [
        ("combustion", "'p_cyl' is NaN at sample 10000"),
        ("torque", "'p_cyl' is NaN at sample 10000"),
        ("friction", "'p_int' is NaN at sample 25000"),
    ] {
        let told: Vec<_> = findings
            .iter()
            .filter(|e| says(e, &format!("{stage}: ")))
            .collect();
        assert_eq!(told.len(), 1, "{stage}: {findings:?}");
        assert!(
            says(told[0], &format!("{stage}: {what} (t = "))
                && says(told[0], " s): the cycle it cuts is left out"),
            "{told:?}"
        );
    }
    assert!(!findings.iter().any(|e| says(e, "stopped")), "{findings:?}");
    assert_eq!(of_type(&ev, "end")[0]["samples"], 40001);
    // The combustion figures: every cycle but the one cut the clean's (at 1000 rpm a cycle is
    // 0.12 s: the one that starts in the 0.12 s before 1 s holds it).
    let cut = |c: &&Value| (0.88..=1.0).contains(&c["t_s"].as_f64().unwrap());
    let want: Vec<&Value> = of_type(&clean, "combustion")
        .into_iter()
        .filter(|c| !cut(c))
        .collect();
    assert!(want.len() >= 25, "{}", want.len());
    assert_eq!(want.len() + 1, of_type(&clean, "combustion").len());
    assert_eq!(of_type(&ev, "combustion"), want);
    // Torque and friction go on to the end, a cycle short of the clean run, and end on its
    // estimates within their standard errors (the parameters are chosen on the samples before
    // the choice, one cycle fewer: the estimates before the dropout differ in their 6th digit).
    for kind in ["torque", "friction"] {
        let (got, want) = (of_type(&ev, kind), of_type(&clean, kind));
        assert!(want.len() >= 25 && got.len() + 1 == want.len(), "{kind}");
        let (last, clean_last) = (got[got.len() - 1], want[want.len() - 1]);
        assert!(last["t_s"].as_f64().unwrap() > 3.5, "{kind}: {last}");
        let params = last["params"].as_object().unwrap();
        assert_eq!(
            params.len(),
            clean_last["params"].as_object().unwrap().len()
        );
        for (p, v) in params {
            let (v, w) = (
                v.as_f64().unwrap(),
                clean_last["params"][p].as_f64().unwrap(),
            );
            let se = clean_last["std_err"][p].as_f64().unwrap();
            assert!((v - w).abs() <= se, "{kind} {p}: {v} against {w} ± {se}");
        }
    }
    // The file verbs on the same file: `tests/dropouts.rs`.
}

/// A crank angle that jumps by 10⁹ rad for 50 samples of a replayed file, half a second in (a bad sensor or a
/// bad frame; 9.2·10¹⁸ from a frame did the same) stops the stages that count cycles — cycles,
/// friction, torque, combustion — each with a finding naming the sample; the run goes on to the
/// end. It used to close 10⁸ empty cycles until the allocator aborted the service; the run is
/// held to 4 GiB of address space here, so that a return of it fails fast.
#[test]
fn an_angle_that_jumps_stops_the_cycle_stages_not_the_run() {
    let s = Scratch::new("physid-live-jump");
    let file = s.file("run.csv");
    let f = file.to_str().unwrap();
    common::simulated(&file, "torque-steady", "1");
    common::set_cells(&file, "theta_en", 5000..5050, "1e9");
    let args = [
        "live",
        "--headless",
        "--json",
        "--replay",
        f,
        "--pace",
        "max",
        "--torque",
        "--combustion",
        "--friction",
        "cell",
    ];
    let r = physid_testkit::fuzz::run_within(
        std::path::Path::new(env!("CARGO_BIN_EXE_physid")),
        &args,
        std::time::Duration::from_secs(120),
        Some(4),
    );
    assert!(
        matches!(r.outcome, physid_testkit::fuzz::Outcome::Done),
        "{:?}: {}",
        r.outcome,
        String::from_utf8_lossy(&r.stderr)
    );
    let ev: Vec<Value> = String::from_utf8(r.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let findings = of_type(&ev, "finding");
    for stage in ["cycles", "friction", "torque", "combustion"] {
        assert!(
            findings
                .iter()
                .any(|e| says(e, &format!("{stage}: the crank angle advances"))
                    && says(e, "at sample 5000")
                    && says(e, "at most a cycle")),
            "{stage}: {findings:?}"
        );
    }
    // The shaft monitor takes the jump out of the twist as a sensor's glitch and says so.
    assert!(
        findings
            .iter()
            .any(|e| says(e, "shaft: the twist stepped by")
                && says(e, "at sample 5000")
                && says(e, "taken out as a sensor's glitch")),
        "{findings:?}"
    );
    let end = of_type(&ev, "end")[0];
    assert_eq!(end["samples"], 10001, "{end}");
    assert!(of_type(&ev, "cycle").len() >= 2, "cycles before the jump");
}

/// `--combustion` on a replayed recording is `physid cycles` on the file: the virtual cell's
/// motored engine for 2 s on a crank-angle basis (its cycles as the cell knows them), replayed
/// in chunks of two sizes; each cycle's figures in a `combustion` event are the file verb's
/// (the same cycle numbers; the values as close as the replay's resampling — the file onto a
/// uniform time basis, the stream back onto the crank-angle grid — leaves them); a combustion
/// flag without `--combustion` is refused. The friction model's FMEP (`--friction-model cell`)
/// rides beside the measured one in both.
#[test]
fn combustion_on_the_stream_is_the_file_verbs_cycles() {
    let s = Scratch::new("physid-live-combustion");
    let file = s.file("motored.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "2",
        "--basis",
        "crank",
        "--recording",
        file.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let f = file.to_str().unwrap();
    // The virtual cell's engine (its Table 4.1 geometry), as --combustion takes it by default.
    let mut args = vec![
        "cycles",
        f,
        "--json",
        "--mfb",
        "5,50",
        "--brake-torque",
        "torque_engine",
        "--friction-model",
        "cell",
        "--friction-oil-temp",
        "90",
    ];
    args.extend([
        "--bore",
        "0.054",
        "--stroke",
        "0.0514",
        "--rod",
        "0.088",
        "--compression-ratio",
        "9.5",
    ]);
    let o = physid(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let by_file: Value = serde_json::from_slice(&o.stdout).unwrap();
    let by_file = by_file["cycles"].as_array().unwrap();
    assert!(by_file.len() >= 10, "{} cycles", by_file.len());
    let mut worst: f64 = 0.0;
    for chunk in ["0.001", "0.0137"] {
        let ev = events(&[
            "live",
            "--headless",
            "--json",
            "--replay",
            f,
            "--pace",
            "max",
            "--chunk",
            chunk,
            "--combustion",
            "--step-deg",
            "1",
            "--mfb",
            "5,50",
            "--brake-torque",
            "torque_engine",
            "--friction-model",
            "cell",
            "--friction-oil-temp",
            "90",
        ]);
        let live = of_type(&ev, "combustion");
        assert_eq!(live.len(), by_file.len(), "chunks of {chunk} s");
        for (l, c) in live.iter().zip(by_file) {
            assert_eq!(l["cycle"], c["cycle"], "{l}");
            let rel = |a: f64, b: f64| (a - b).abs() / (1.0 + a.abs());
            let dt = l["t_s"].as_f64().unwrap() - c["t_start_s"].as_f64().unwrap();
            assert!(dt.abs() < 1e-6, "{l}");
            for (event, file) in [
                ("imep", "imep_pa"),
                ("imep_gross", "imep_gross_pa"),
                ("pmep", "pmep_pa"),
                ("p_max", "p_max"),
                ("p_max_deg", "p_max_deg"),
                ("n_compression", "n_compression"),
                ("heat_release", "heat_release_j"),
                ("rpm", "rpm"),
                ("torque", "torque_nm"),
                ("bmep", "bmep_pa"),
                ("fmep", "fmep_pa"),
                ("fmep_model", "fmep_model_pa"),
            ] {
                let (a, b) = (
                    l["figures"][event].as_f64().unwrap(),
                    c[file].as_f64().unwrap(),
                );
                worst = worst.max(rel(a, b));
                // Measured: 7e-4 (IMEP, p_max), 0.07° (the peak's angle), 1.5 % of the motored
                // cycle's 1.7 J of apparent heat.
                let tol = match event {
                    "p_max_deg" => 0.1,
                    "heat_release" => 0.05,
                    _ => 2e-3,
                };
                assert!(
                    rel(a, b) < tol,
                    "cycle {}: {event} {a} (live) against {b} (file)",
                    l["cycle"]
                );
            }
            // Motored: not fired, no burn angles, the peak just before TDC.
            assert_eq!(l["figures"]["fired"], 0.0, "{l}");
            assert!(l["figures"]["mfb5_deg"].is_null(), "{l}");
            let at = l["figures"]["p_max_deg"].as_f64().unwrap();
            assert!((-2.0..0.0).contains(&at), "{l}");
        }
    }
    eprintln!("largest relative difference, stream against file: {worst:e}");
    let o = physid(&[
        "live",
        "--headless",
        "--json",
        "--replay",
        f,
        "--bore",
        "0.054",
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("add --combustion"), "{e}");
    let o = physid(&["cycles", f, "--friction-model", "nope"]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("no such preset; the presets are thesis, sandoval2002, cell"),
        "{e}"
    );
}

/// A time-basis recording of the virtual cell, whose TDC marker comes once per revolution: the
/// first marker here is the gas-exchange TDC. With `--phase-from none` the firing TDC is the
/// first marker's — said, and every cycle's pressure then peaks a revolution from it, so no
/// heat release is given and the note says why. With `--phase-from p_cyl`, and by default (the
/// recording has `p_cyl`), the compression peaks just before TDC, and `live --replay …
/// --combustion` gives the file verb's figures cycle by cycle (the stream has one cycle more at
/// its start: the compression before the first TDC is in it, where the file's blocks begin at
/// that TDC). A recording too short to tell the phase from is taken from its first marker by
/// default, and says why; told `--phase-from p_cyl`, it is refused.
#[test]
fn a_marker_once_per_revolution_is_phased_from_the_pressure() {
    let s = Scratch::new("physid-live-phase");
    let file = s.file("motored.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "2",
        "--recording",
        file.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let f = file.to_str().unwrap();
    let cycles = |extra: &[&str]| {
        let mut args = vec![
            "cycles",
            f,
            "--json",
            "--step-deg",
            "0.5",
            "--bore",
            "0.054",
            "--stroke",
            "0.0514",
            "--rod",
            "0.088",
            "--compression-ratio",
            "9.5",
        ];
        args.extend(extra);
        let o = physid(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice::<Value>(&o.stdout).unwrap()
    };
    let guess = cycles(&["--phase-from", "none"]);
    let notes: Vec<&str> = guess["notes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    let n = guess["cycles"].as_array().unwrap().len();
    assert!(
        notes
            .iter()
            .any(|n| n.starts_with("phase: the first TDC marker taken as firing")),
        "{notes:?}"
    );
    assert!(
        notes.iter().any(|m| m.starts_with(&format!(
            "{n} cycle(s): no heat release: the pressure peaks more than 90° from TDC"
        ))),
        "{notes:?}"
    );
    // The same recording with the encoder's counts as its only engine angle (no theta_en):
    // said to be a guess with --phase-from none, the pressure's peak a revolution off; with
    // p_cyl, told or by default, the firing TDC told from the pressure at the count steps, the
    // peak just before TDC.
    let counts = s.file("counts.parquet");
    let o = physid(&[
        "convert",
        f,
        counts.to_str().unwrap(),
        "--channels",
        "t,count_en,tdc,p_cyl",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let by_counts = |extra: &[&str]| {
        let mut args = vec![
            "cycles",
            counts.to_str().unwrap(),
            "--json",
            "--encoder",
            "count_en=360",
        ];
        args.extend(extra);
        let o = physid(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice::<Value>(&o.stdout).unwrap()
    };
    let guessed = by_counts(&["--phase-from", "none"]);
    assert!(
        guessed["notes"][0]
            .as_str()
            .unwrap()
            .starts_with("phase: the first TDC marker taken as firing"),
        "{}",
        guessed["notes"]
    );
    let off = guessed["cycles"][1]["p_max_deg"].as_f64().unwrap();
    assert!(off.abs() > 300.0, "{off}");
    let by_default = by_counts(&[]);
    let note = by_default["notes"][0].as_str().unwrap();
    assert!(
        note.starts_with("phase: the firing TDC at the second TDC marker ('p_cyl' higher")
            && note.ends_with("'p_cyl' by default (--phase-from none takes the first TDC)"),
        "{note}"
    );
    let told = by_counts(&["--phase-from", "p_cyl"]);
    assert_eq!(by_default["cycles"], told["cycles"]);
    assert!(
        told["notes"][0]
            .as_str()
            .unwrap()
            .starts_with("phase: the firing TDC at the second TDC marker ('p_cyl' higher"),
        "{}",
        told["notes"]
    );
    let told = told["cycles"].as_array().unwrap();
    assert!(told.len() >= 10);
    for c in told {
        let at = c["p_max_deg"].as_f64().unwrap();
        assert!((-3.0..1.0).contains(&at), "{c}");
    }
    let phased = cycles(&["--phase-from", "p_cyl"]);
    assert_eq!(cycles(&[])["cycles"], phased["cycles"]);
    let by_file = phased["cycles"].as_array().unwrap();
    assert!(by_file.len() >= 10);
    assert!(
        phased["notes"][0]
            .as_str()
            .unwrap()
            .starts_with("phase: the firing TDC at the second TDC marker ('p_cyl' higher"),
        "{}",
        phased["notes"]
    );
    for c in by_file {
        let at = c["p_max_deg"].as_f64().unwrap();
        assert!((-2.0..0.0).contains(&at), "{c}");
        let n = c["n_compression"].as_f64().unwrap();
        assert!((1.3..1.45).contains(&n), "{c}");
        assert_eq!(c["fired"], false, "{c}");
    }
    let ev = events(&[
        "live",
        "--headless",
        "--json",
        "--replay",
        f,
        "--pace",
        "max",
        "--combustion",
        "--step-deg",
        "0.5",
    ]);
    let live = of_type(&ev, "combustion");
    assert_eq!(live.len(), by_file.len() + 1);
    assert_eq!(live[0]["cycle"], 0);
    let mut worst: f64 = 0.0;
    for (l, c) in live[1..].iter().zip(by_file) {
        assert_eq!(l["cycle"], c["cycle"], "{l}");
        for (event, file) in [
            ("imep", "imep_pa"),
            ("imep_gross", "imep_gross_pa"),
            ("p_max", "p_max"),
            ("p_max_deg", "p_max_deg"),
            ("n_compression", "n_compression"),
            ("n_expansion", "n_expansion"),
        ] {
            let (a, b) = (
                l["figures"][event].as_f64().unwrap(),
                c[file].as_f64().unwrap(),
            );
            let rel = (a - b).abs() / (1.0 + a.abs());
            worst = worst.max(rel);
            // The same samples on the same grid: measured 2e-12.
            assert!(
                rel < 1e-9,
                "cycle {}: {event} {a} (live) against {b} (file)",
                l["cycle"]
            );
        }
    }
    eprintln!("largest relative difference, stream against file: {worst:e}");
    // 60 ms at 1000 rpm: one revolution, too few to tell the phase from.
    let short = s.file("short.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "0.06",
        "--recording",
        short.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let to = s.file("short-deg.parquet");
    let convert = |extra: &[&str]| {
        let mut args = vec![
            "convert",
            short.to_str().unwrap(),
            to.to_str().unwrap(),
            "--crank-angle",
        ];
        args.extend(extra);
        physid(&args)
    };
    let o = convert(&[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let read = physid_io::read(&to, &Default::default()).unwrap();
    let phase = &read.meta["phase"];
    assert!(
        phase.starts_with("the first TDC marker taken as firing")
            && phase.contains(
                "'p_cyl' could not tell: the recording spans fewer than two whole revolutions"
            ),
        "{phase}"
    );
    let o = convert(&["--phase-from", "p_cyl"]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("fewer than two whole revolutions"), "{e}");
}
