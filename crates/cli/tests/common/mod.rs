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

/// Run `physid ARGS` (a shell word list) on a pseudo-terminal made by `script` (util-linux),
/// progress shown at once; what the terminal showed, stdout and stderr together.
pub fn on_a_terminal(args: &str) -> String {
    let cmd = format!(
        "PHYSID_PROGRESS_AFTER_MS=0 {} {args}",
        env!("CARGO_BIN_EXE_physid")
    );
    let o = Command::new("script")
        .args(["-qec", &cmd, "/dev/null"])
        .output()
        .expect("script (util-linux) runs a command on a pseudo-terminal");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}
