//! Profiling helper (not shipped): RLS p = 2 on the standard workload.
fn main() {
    let p: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(2);
    let mut w = physid_estim::workload::Workload::new(physid_estim::Method::Rls, p, 4096).unwrap();
    w.run(200_000_000 / p / p).unwrap();
    println!("{:?}", w.estimator.estimate());
}
