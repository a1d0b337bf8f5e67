//! The fleet's per-frame costs: a frame to and from its Arrow IPC bytes (the wire format), and
//! the stages' checkpoint written and restored — against the stages' own work on the same
//! samples, measured in the same run (the ratio is what matters on these VMs).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use physid_core::{Basis, Recording};
use physid_live::source::{ScenarioSource, Source};
use physid_live::wire::{self, Frame};
use physid_live::{Event, LiveConfig, Stages};
use physid_sim::run::{OutputBasis, RunOptions};
use physid_sim::scenario::Scenario;
use std::hint::black_box;

/// One second of the virtual cell at 12 kHz (2000 rpm, one sample per degree), in 20 ms chunks,
/// with the seven channels a load cell publishes.
fn chunks() -> (Vec<Recording>, f64) {
    let opts = RunOptions {
        duration: Some(1.0),
        basis: OutputBasis::Time(12_000.0),
        ..Default::default()
    };
    let scenario = match Scenario::load("shaft-steady") {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    };
    let mut src = match ScenarioSource::new(&scenario, &opts, 0.02) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    };
    let keep = physid_live::fleet::load::LOAD_CHANNELS;
    let mut out = Vec::new();
    while let Ok(Some(c)) = src.next_chunk() {
        let mut r = Recording::new(Basis::Time);
        for name in keep {
            if let Ok(ch) = c.channel(name) {
                let _ = r.push(ch.clone());
            }
        }
        out.push(r);
    }
    (out, src.rate_hz())
}

fn bench(c: &mut Criterion) {
    let (chunks, rate) = chunks();
    let samples: usize = chunks.iter().map(Recording::len).sum();
    let frames: Vec<Frame> = chunks
        .iter()
        .enumerate()
        .map(|(k, chunk)| Frame {
            cell: "bench".into(),
            run: 1,
            seq: k as u64 + 1,
            first_sample: 0,
            rate_hz: rate,
            end: false,
            chunk: chunk.clone(),
        })
        .collect();
    let bytes: Vec<Vec<u8>> = frames.iter().filter_map(|f| wire::encode(f).ok()).collect();
    let mut g = c.benchmark_group("fleet_per_second_of_a_12khz_cell");
    g.throughput(Throughput::Elements(samples as u64));
    g.bench_function("encode_frames", |b| {
        b.iter(|| {
            for f in &frames {
                black_box(wire::encode(black_box(f)).ok());
            }
        })
    });
    g.bench_function("decode_frames", |b| {
        b.iter(|| {
            for x in &bytes {
                black_box(wire::decode(black_box(x)).ok());
            }
        })
    });
    g.bench_function("stages", |b| {
        b.iter(|| {
            let Ok(mut s) = Stages::new(LiveConfig::default(), rate, |_: &Event| Ok(())) else {
                return;
            };
            for ch in &chunks {
                let _ = s.chunk(black_box(ch));
            }
        })
    });
    g.finish();
    // A checkpoint after the whole second: written and restored.
    let mut kinds = std::collections::BTreeMap::<String, usize>::new();
    let Ok(mut s) = Stages::new(LiveConfig::default(), rate, |e: &Event| {
        let v = serde_json::to_value(e).map_err(|e| e.to_string())?;
        *kinds
            .entry(v["type"].as_str().unwrap_or("?").to_string())
            .or_default() += 1;
        Ok(())
    }) else {
        return;
    };
    for ch in &chunks {
        if let Err(e) = s.chunk(ch) {
            panic!("{e}");
        }
    }
    let state = s.checkpoint().unwrap_or_default();
    drop(s);
    eprintln!(
        "checkpoint: {} bytes; events of the second: {kinds:?}",
        state.len()
    );
    let Ok(s) = Stages::restore(LiveConfig::default(), &state, |_: &Event| Ok(())) else {
        return;
    };
    let mut g = c.benchmark_group("fleet_checkpoint");
    g.bench_function("write", |b| b.iter(|| black_box(s.checkpoint().ok())));

    g.bench_function("restore", |b| {
        b.iter(|| {
            black_box(
                Stages::restore(LiveConfig::default(), black_box(&state), |_: &Event| Ok(()))
                    .is_ok(),
            )
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
