//! criterion benchmarks of physid-sim.
fn main() {}
