//! criterion benchmarks of EKF, UKF and SR-UKF on the 10-parameter benchmark model
//! (`physid_estim::workload::Bench10`, the cyclic-torque model's cost profile).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use physid_estim::workload::NonlinearWorkload;
use physid_estim::{NlMethod, SigmaPoints};

const BATCH: usize = 720;

fn nonlinear(c: &mut Criterion) {
    let mut g = c.benchmark_group("nonlinear_update_p10");
    g.throughput(Throughput::Elements(BATCH as u64));
    for method in [
        NlMethod::Ekf,
        NlMethod::Ukf(SigmaPoints::default()),
        NlMethod::Srukf(SigmaPoints::default()),
    ] {
        let mut w = match NonlinearWorkload::new(method, BATCH) {
            Ok(w) => w,
            Err(e) => panic!("{}: {e}", method.name()),
        };
        g.bench_function(method.name(), |b| b.iter(|| w.run(BATCH)));
    }
    g.finish();
}

criterion_group!(benches, nonlinear);
criterion_main!(benches);
