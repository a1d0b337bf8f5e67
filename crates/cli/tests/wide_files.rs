//! Files of many columns (issue 41, item 2): reading is linear in the columns up to the
//! documented limit (`physid_io::MAX_CHANNELS`), and a wider file is refused before any sample
//! is read. Each run has a deadline far beyond its linear cost — a hang detector (a 100 000-
//! column header took 119 s while each channel was found by scanning the others; 1.6 s now in
//! a debug build), not a measure of speed.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_testkit::fuzz::{run_within, wide_csv as wide, Outcome, Ran};
use std::path::Path;
use std::time::Duration;

/// `physid ARGS`, killed at `deadline` (then the test fails naming the command).
fn physid_within(args: &[&str], deadline: Duration) -> Ran {
    let r = run_within(
        Path::new(env!("CARGO_BIN_EXE_physid")),
        args,
        deadline,
        None,
    );
    assert!(
        r.outcome != Outcome::Hang,
        "physid {args:?} did not finish within {deadline:?}: work that is not linear in the columns?"
    );
    r
}

#[test]
fn a_header_of_100_000_columns_is_read_in_linear_time() {
    let s = physid_testkit::Scratch::new("physid-wide");
    let file = s.file("wide.csv");
    wide(&file, physid_io::MAX_CHANNELS).unwrap();
    let f = file.to_str().unwrap();
    let o = physid_within(&["inspect", f, "--json"], Duration::from_secs(60));
    assert_eq!(
        o.outcome,
        Outcome::Done,
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let channels = v["channels"].as_array().unwrap();
    assert_eq!(channels.len(), physid_io::MAX_CHANNELS);
    assert_eq!(channels[99_999]["name"], "c99999");
    // A verb that needs channels the file lacks refuses it at once, naming what is missing and
    // a few of the channels there are (not 100 000 names).
    let o = physid_within(&["monitor", "shaft", "--data", f], Duration::from_secs(60));
    assert_eq!(o.outcome, Outcome::Refused);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("no channel 't'") && err.contains("c39 … (100000 in all)"),
        "{err}"
    );
    assert!(err.len() < 4000, "{} bytes of error", err.len());
}

#[test]
fn a_file_wider_than_the_limit_is_refused_by_its_count() {
    let s = physid_testkit::Scratch::new("physid-wider");
    let file = s.file("wider.csv");
    wide(&file, physid_io::MAX_CHANNELS + 1).unwrap();
    let o = physid_within(
        &["inspect", file.to_str().unwrap()],
        Duration::from_secs(60),
    );
    assert_eq!(o.outcome, Outcome::Refused);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("100001 channels: physid reads at most 100000 at once"),
        "{err}"
    );
}
