//! What the end-to-end test files share: running the `physid` binary under test.
#![allow(dead_code)]

use std::process::{Command, Output};

/// Run the `physid` binary built for these tests with `args`.
pub fn physid(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_physid"))
        .args(args)
        .output()
        .expect("run physid")
}

/// Run `physid` with `args`, which must succeed, and parse what it prints as JSON.
pub fn ok_json(args: &[&str]) -> serde_json::Value {
    let o = physid(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).expect("JSON on stdout")
}
