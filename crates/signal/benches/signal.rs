//! criterion benchmarks of physid-signal.
fn main() {}
