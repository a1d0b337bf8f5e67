//! What the end-to-end test files share: running the `physid` binary under test.

use std::process::{Command, Output};

/// Run the `physid` binary built for these tests with `args`.
pub fn physid(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_physid"))
        .args(args)
        .output()
        .expect("run physid")
}
