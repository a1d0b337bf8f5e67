//! Per-cycle statistics on a stream against closed forms and against the whole-record path
//! (crank-angle resampling, then per-cycle means), and the same for any chunking.
#![allow(clippy::unwrap_used)]

use physid_signal::crank::{crank_grid, cycle_stats, interp};
use physid_signal::cycles::{CycleStream, CycleSummary, Dropout};
use std::f64::consts::PI;

/// An accelerating engine from 1000 rpm (α = 400 rad/s²), 10 kHz, 2 s; θ from 0.
fn engine() -> (Vec<f64>, Vec<f64>) {
    let t: Vec<f64> = (0..20_000).map(|k| k as f64 * 1e-4).collect();
    let w0 = 1000.0 * 2.0 * PI / 60.0;
    let th = t.iter().map(|&t| w0 * t + 200.0 * t * t).collect();
    (t, th)
}

fn stream(
    t: &[f64],
    th: &[f64],
    x: &[Vec<f64>],
    chunk: usize,
    curve: Option<f64>,
    tdc: f64,
) -> Vec<CycleSummary> {
    let mut s = CycleStream::new(x.len(), tdc, curve).unwrap();
    push_all(&mut s, t, th, x, chunk)
}

/// `t`, `th` and the channels `x` pushed into `s` in chunks of `chunk` samples.
fn push_all(
    s: &mut CycleStream,
    t: &[f64],
    th: &[f64],
    x: &[Vec<f64>],
    chunk: usize,
) -> Vec<CycleSummary> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < t.len() {
        let e = (i + chunk).min(t.len());
        let cols: Vec<&[f64]> = x.iter().map(|c| &c[i..e]).collect();
        s.push(&t[i..e], &th[i..e], &cols, &mut out).unwrap();
        i = e;
    }
    out
}

/// x = a + b·cos θ + c·sin(θ/2): its crank-angle mean over every cycle is `a` (the trapezoidal
/// rule on ≈1° steps: within 1e-4·b); x = cos(θ − 1 rad) peaks at 57.3° and 417.3°.
#[test]
fn means_and_peaks_against_closed_forms() {
    let (t, th) = engine();
    let x0: Vec<f64> = th
        .iter()
        .map(|&a| 5.0 + 2.0 * a.cos() + 0.5 * (a / 2.0).sin())
        .collect();
    let x1: Vec<f64> = th.iter().map(|&a| (a - 1.0).cos()).collect();
    let cycles = stream(&t, &th, &[x0, x1], 4096, None, 0.0);
    // θ(2 s) = 209.4 + 800 = 1009 rad = 80.3 cycles: 80 complete.
    assert_eq!(cycles.len(), 80);
    for (k, c) in cycles.iter().enumerate() {
        assert_eq!(c.cycle, k as i64);
        assert!((c.mean[0] - 5.0).abs() < 2e-4, "cycle {k}: {}", c.mean[0]);
        assert!((c.mean[1]).abs() < 1e-4, "cycle {k}: {}", c.mean[1]);
        // The peak sample lies within one sample's angle of the true peak.
        let dth = (w(c.t_end_s)).to_degrees() * 1e-4;
        assert!(
            (c.max_deg[1] - 57.2958).abs() < dth || (c.max_deg[1] - 417.2958).abs() < dth,
            "cycle {k}: peak at {}°",
            c.max_deg[1]
        );
        assert!(c.max[1] <= 1.0 && c.max[1] > 1.0 - (dth.to_radians()).powi(2));
        // The boundaries are θ = 4πk: t from θ(t) = 4πk.
        let t_at = |a: f64| {
            let w0 = 1000.0 * 2.0 * PI / 60.0;
            (-w0 + (w0 * w0 + 800.0 * a).sqrt()) / 400.0
        };
        assert!((c.t_start_s - t_at(4.0 * PI * k as f64)).abs() < 1e-6);
        assert!((c.t_end_s - t_at(4.0 * PI * (k + 1) as f64)).abs() < 1e-6);
    }
}

/// When the engine of [`engine`], started `offset` rad into a cycle, reaches its next cycle.
fn t_first_boundary(offset: f64) -> f64 {
    let w0 = 1000.0 * 2.0 * PI / 60.0;
    (-w0 + (w0 * w0 + 800.0 * (4.0 * PI - offset)).sqrt()) / 400.0
}

/// The engine's speed at `t` [rad/s].
fn w(t: f64) -> f64 {
    1000.0 * 2.0 * PI / 60.0 + 400.0 * t
}

/// A channel linear in θ is interpolated exactly: its curve is θ on the grid and its mean the
/// cycle's middle angle, its start and end values the boundary angles; cycles start at the
/// given TDC angle.
#[test]
fn curves_are_exact_for_a_linear_channel() {
    let (t, th) = engine();
    let tdc = 1.0;
    let cycles = stream(&t, &th, std::slice::from_ref(&th), 17, Some(2.0), tdc);
    // θ from 0 to 1009 rad: the cycle before TDC is partial, 80 complete.
    assert_eq!(cycles.len(), 80);
    for c in &cycles {
        // The first cycle that starts in the stream starts at the TDC angle.
        let start = tdc + 4.0 * PI * c.cycle as f64;
        let curve = &c.curve.as_ref().unwrap()[0];
        assert_eq!(curve.len(), 360);
        for (k, v) in curve.iter().enumerate() {
            let want = start + (2.0 * k as f64).to_radians();
            assert!((v - want).abs() < 1e-10 * want, "{k}: {v} vs {want}");
        }
        assert!((c.mean[0] - (start + 2.0 * PI)).abs() < 1e-9 * start);
        // The values at the boundaries are the boundary angles.
        assert!((c.start[0] - start).abs() < 1e-10 * start);
        assert!((c.end[0] - (start + 4.0 * PI)).abs() < 1e-10 * start);
    }
}

/// The same cycles, bit for bit, for chunks of 1, 17, 4096 samples and whole.
#[test]
fn any_chunking_gives_the_same_cycles() {
    let (t, th) = engine();
    let x: Vec<f64> = th.iter().map(|&a| (3.0 * a).sin() * a.sqrt()).collect();
    let whole = stream(&t, &th, std::slice::from_ref(&x), t.len(), Some(1.0), 0.3);
    assert_eq!(whole.len(), 80);
    for chunk in [1, 17, 4096] {
        assert_eq!(
            stream(&t, &th, std::slice::from_ref(&x), chunk, Some(1.0), 0.3),
            whole
        );
    }
}

/// Against the whole-record path (another code path): resample to 1° with `crank_grid`, then
/// per-cycle sample means with `cycle_stats` — the two agree to the resampling's error.
#[test]
fn agrees_with_the_whole_record_crank_angle_path() {
    let (t, th) = engine();
    let x: Vec<f64> = th
        .iter()
        .map(|&a| 1e5 * (1.0 + 20.0 * (-(a % (4.0 * PI) - 2.0 * PI).powi(2) * 4.0).exp()))
        .collect();
    let cycles = stream(&t, &th, std::slice::from_ref(&x), 4096, None, 0.0);
    let grid = crank_grid(&t, &th, 0.0, 1.0).unwrap();
    let xg = interp(&th, &x, &grid.theta);
    let stats = cycle_stats(&grid.cycle, &xg);
    for c in &cycles {
        let s = stats.iter().find(|s| s.cycle == c.cycle).unwrap();
        assert_eq!(s.samples, 720);
        let rel = (c.mean[0] - s.mean).abs() / s.mean;
        assert!(
            rel < 1e-4,
            "cycle {}: {} vs {} ({rel:e})",
            c.cycle,
            c.mean[0],
            s.mean
        );
        // Both take the peak from samples (the stream: ≤ 5° apart; the grid: 1°).
        assert!((c.max[0] - s.max).abs() / s.max < 1e-2);
    }
}

/// An engine at rest adds nothing; the partial first cycle is not reported; a NaN is an error
/// naming its sample.
#[test]
fn rest_partial_cycles_and_nan() {
    let (t, th0) = engine();
    // Start mid-cycle, and stand still for 100 samples in cycle 3.
    let th: Vec<f64> = (0..th0.len())
        .map(|i| 2.0 + th0[if i < 3000 { i } else { (i - 100).max(3000) }])
        .collect();
    let x: Vec<f64> = th.iter().map(|&a| a.cos()).collect();
    let cycles = stream(&t, &th, std::slice::from_ref(&x), 64, None, 0.0);
    assert_eq!(cycles[0].cycle, 0, "the partial cycle is not reported");
    assert!((cycles[0].t_start_s - t_first_boundary(2.0)).abs() < 1e-6);
    assert!(cycles.iter().all(|c| c.mean[0].abs() < 1e-4));
    let mut s = CycleStream::new(1, 0.0, None).unwrap();
    let mut bad = x.clone();
    bad[70] = f64::NAN;
    let e = s
        .push(&t[..100], &th[..100], &[&bad[..100]], &mut Vec::new())
        .unwrap_err();
    assert!(e.to_string().contains("sample 70"), "{e}");
    assert!(CycleStream::new(1, 0.0, Some(7.0)).is_err());
    // Finer than a hundredth of a degree: refused, not 5.8 TB asked for one cycle's curve.
    assert!(CycleStream::new(1, 0.0, Some(0.01)).is_ok());
    let e = CycleStream::new(1, 0.0, Some(1e-9))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("curve step 1e-9°") && e.contains("at least 0.01°"),
        "{e}"
    );
}

/// The curves alone (`curves_only`, its inline path for finite chunks) are the full stream's
/// curves, bit for bit, for chunks of 1, 17, 4096 samples and whole — on an engine that stops
/// for 100 samples and with a grid finer than the samples (several points between two
/// samples) and coarser; a chunk with a NaN is refused naming its sample.
#[test]
fn curves_only_are_the_full_streams_curves() {
    let (t, th0) = engine();
    let th: Vec<f64> = (0..th0.len())
        .map(|i| 0.7 + th0[if i < 3000 { i } else { (i - 100).max(3000) }])
        .collect();
    let x: Vec<f64> = th.iter().map(|&a| (3.0 * a).sin() * a.sqrt()).collect();
    let y: Vec<f64> = t.iter().map(|&t| 1e5 * (1.0 + t)).collect();
    let cols = [x.clone(), y.clone()];
    for step in [0.25, 1.0, 6.0] {
        let full = stream(&t, &th, &cols, t.len(), Some(step), 0.3);
        assert!(full.len() > 60);
        for chunk in [1, 17, 4096, t.len()] {
            let mut s = CycleStream::new(2, 0.3, Some(step)).unwrap().curves_only();
            let out = push_all(&mut s, &t, &th, &cols, chunk);
            assert_eq!(out.len(), full.len());
            for (a, b) in out.iter().zip(&full) {
                assert_eq!(
                    (a.cycle, a.t_start_s, a.t_end_s),
                    (b.cycle, b.t_start_s, b.t_end_s)
                );
                assert_eq!(
                    a.curve, b.curve,
                    "step {step}, chunk {chunk}, cycle {}",
                    a.cycle
                );
                assert_eq!(a.curve.as_ref().unwrap()[0].len(), (720.0 / step) as usize);
                assert!(a.mean.is_empty());
            }
        }
    }
    let mut s = CycleStream::new(1, 0.0, Some(1.0)).unwrap().curves_only();
    s.push(&t[..100], &th[..100], &[&x[..100]], &mut Vec::new())
        .unwrap();
    let mut bad = x[100..200].to_vec();
    bad[30] = f64::NAN;
    let e = s
        .push(&t[100..200], &th[100..200], &[&bad], &mut Vec::new())
        .unwrap_err();
    assert!(e.to_string().contains("sample 130"), "{e}");
}

/// The times asked for at grid points are the time's own curve there, bit for bit, by the
/// per-sample path (statistics kept) and the curves-only path, in chunks of any size; a point
/// past the grid is refused.
#[test]
fn times_at_grid_points_are_the_times_curve() {
    let (t, th0) = engine();
    let th: Vec<f64> = th0.iter().map(|a| a + 0.7).collect();
    let x: Vec<f64> = th.iter().map(|&a| (3.0 * a).sin() * a.sqrt()).collect();
    for step in [0.25, 1.0] {
        let points = (720.0 / step) as usize;
        let marks = [0, 5, points / 2, points - 1];
        for curves_only in [false, true] {
            for chunk in [1, 17, 4096, t.len()] {
                let mut s = CycleStream::new(2, 0.3, Some(step))
                    .unwrap()
                    .with_times_at(&marks)
                    .unwrap();
                if curves_only {
                    s = s.curves_only();
                }
                let out = push_all(&mut s, &t, &th, &[x.clone(), t.clone()], chunk);
                assert!(out.len() > 60);
                for c in &out {
                    let curve = &c.curve.as_ref().unwrap()[1];
                    let want: Vec<f64> = marks.iter().map(|&k| curve[k]).collect();
                    assert_eq!(
                        c.times, want,
                        "step {step}, chunk {chunk}, cycle {}",
                        c.cycle
                    );
                }
            }
        }
    }
    let s = CycleStream::new(1, 0.0, Some(1.0)).unwrap();
    assert!(s.with_times_at(&[720]).is_err());
}

/// A gap in the data — 0.1 s of samples missing, time and angle (≈ 1.7 cycles at 1000 rpm: a
/// DAQ's dropout, frames lost) — is resumed after: the cycles wholly before and wholly after it
/// are the uninterrupted stream's, bit for bit, with the same numbers, and none that the gap
/// cuts is reported — whatever the chunking, with statistics and on the curves alone. Before,
/// it was an error and the stream (the live service's cycle stages) stopped for good. An angle
/// that jumps as far with the time not advancing at a crank's speed is still refused.
#[test]
fn a_gap_in_the_data_is_resumed_after_with_the_cycles_numbered_on() {
    let (t, th) = engine();
    let x: Vec<f64> = th
        .iter()
        .map(|&a| 1.0 + a.sin() + 0.1 * (3.0 * a).cos())
        .collect();
    let (lost_from, lost_to) = (8_000, 9_000);
    let keep = |v: &[f64]| -> Vec<f64> { [&v[..lost_from], &v[lost_to..]].concat() };
    let (tg, thg, xg) = (keep(&t), keep(&th), keep(&x));
    let (gap_start, gap_end) = (t[lost_from - 1], t[lost_to]);
    for curves_only in [false, true] {
        let make = || {
            let s = CycleStream::new(1, 0.3, Some(2.0)).unwrap();
            if curves_only {
                s.curves_only()
            } else {
                s
            }
        };
        let whole = push_all(&mut make(), &t, &th, std::slice::from_ref(&x), 20_000);
        let outside: Vec<&CycleSummary> = whole
            .iter()
            .filter(|c| c.t_end_s < gap_start || c.t_start_s > gap_end)
            .collect();
        assert!(outside.len() >= 20, "{} cycles", outside.len());
        assert!(outside.len() < whole.len(), "the gap cuts a cycle");
        for chunk in [1, 64, 999, 20_000] {
            let mut s = make();
            let got = push_all(&mut s, &tg, &thg, std::slice::from_ref(&xg), chunk);
            assert_eq!(s.gaps(), 1, "chunk {chunk}");
            assert_eq!(got.len(), outside.len(), "chunk {chunk}");
            for (g, w) in got.iter().zip(&outside) {
                assert_eq!(g, *w, "chunk {chunk}, cycle {}", w.cycle);
            }
        }
    }
    // The same advance with the time stepping as before (a sensor's jump, not a gap): refused.
    let mut jump = th.clone();
    let d = th[lost_to] - th[lost_from - 1];
    for a in &mut jump[lost_from..] {
        *a += d;
    }
    let mut s = CycleStream::new(1, 0.3, None).unwrap();
    let err = s
        .push(&t, &jump, &[&x], &mut Vec::new())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(&format!("sample {lost_from}")) && err.contains("not the crank's"),
        "{err}"
    );
}

/// A dropout — a run of samples whose channel or angle is not a number (a sensor's NaN) — is
/// left out as a gap: every cycle it does not touch is the clean stream's, bit for bit and with
/// its number, the cycles it touches are not reported, and each dropout is told once, at its
/// first sample, whatever the chunking (a dropout across a chunk's end is not told again) —
/// with statistics and on the curves alone. Without a dropout it is exactly `push`. A time that
/// is not a number inside a dropout is still an error naming its sample.
#[test]
fn a_dropout_is_left_out_as_a_gap_and_told_once() {
    let (t, th) = engine();
    let x: Vec<f64> = th.iter().map(|&a| 2.0 + a.cos()).collect();
    let y: Vec<f64> = th.iter().map(|&a| (0.5 * a).sin()).collect();
    // A channel's dropout of 30 samples, a single NaN angle, an infinite value.
    let (mut xd, mut thd, mut yd) = (x.clone(), th.clone(), y.clone());
    xd[5_000..5_030].fill(f64::NAN);
    thd[12_000] = f64::NAN;
    yd[16_000] = f64::INFINITY;
    let bad = [5_000..5_030, 12_000..12_001, 16_000..16_001];
    let touched = |c: &CycleSummary| {
        bad.iter()
            .any(|r| c.t_start_s <= t[r.end] && c.t_end_s >= t[r.start - 1])
    };
    for curves_only in [false, true] {
        let make = || {
            let s = CycleStream::new(2, 0.3, Some(1.0)).unwrap();
            if curves_only {
                s.curves_only()
            } else {
                s
            }
        };
        let clean = push_all(&mut make(), &t, &th, &[x.clone(), y.clone()], 20_000);
        let kept: Vec<&CycleSummary> = clean.iter().filter(|c| !touched(c)).collect();
        assert!(
            kept.len() >= 15 && kept.len() + 3 <= clean.len(),
            "{}",
            kept.len()
        );
        for chunk in [1, 7, 1000, 20_000] {
            let mut s = make();
            let (mut got, mut told) = (Vec::new(), Vec::<Dropout>::new());
            let mut i = 0;
            while i < t.len() {
                let e = (i + chunk).min(t.len());
                s.push_past_dropouts(&t[i..e], &thd[i..e], &[&xd[i..e], &yd[i..e]], &mut got)
                    .unwrap();
                told.extend_from_slice(s.dropouts());
                i = e;
            }
            assert_eq!(got.len(), kept.len(), "chunk {chunk}");
            for (g, w) in got.iter().zip(&kept) {
                assert_eq!(g, *w, "chunk {chunk}, cycle {}", w.cycle);
            }
            let at: Vec<(usize, Option<usize>)> =
                told.iter().map(|d| (d.sample, d.channel)).collect();
            assert_eq!(
                at,
                [(5_000, Some(0)), (12_000, None), (16_000, Some(1))],
                "chunk {chunk}"
            );
            assert_eq!(told[0].t, t[5_000]);
            assert!(told[0].value.is_nan() && told[2].value == f64::INFINITY);
            assert_eq!(s.seen(), t.len());
        }
        // Without a dropout, `push`'s cycles.
        let mut s = make();
        let mut got = Vec::new();
        s.push_past_dropouts(&t, &th, &[&x, &y], &mut got).unwrap();
        assert!(s.dropouts().is_empty());
        assert_eq!(got, clean);
    }
    // A time that is not a number in a dropout: an error naming the sample.
    let mut tb = t.clone();
    tb[5_010] = f64::NAN;
    let mut s = CycleStream::new(2, 0.3, None).unwrap();
    let err = s
        .push_past_dropouts(&tb, &thd, &[&xd, &yd], &mut Vec::new())
        .unwrap_err()
        .to_string();
    assert!(err.contains("sample 5010"), "{err}");
}

/// A crank angle that jumps by more than a cycle between two samples (a bad sensor's 10⁹ rad,
/// a frame's 9.2·10¹⁸) is an error naming the sample, on the path with statistics and on the
/// curves alone, whatever the chunking — not 10⁸ empty cycles closed, each with its curves,
/// until the memory runs out. The cycles before it are reported; a jump of just under a cycle
/// (a gap of 700°) is taken.
#[test]
fn an_angle_that_jumps_more_than_a_cycle_is_refused_naming_its_sample() {
    let (t, th) = engine();
    let x: Vec<f64> = th.iter().map(|&a| a.cos()).collect();
    for jump in [1e9, 9.2e18, 4.0 * PI + 0.01] {
        let mut bad = th[..3000].to_vec();
        bad[2500] += jump;
        for curves_only in [false, true] {
            for chunk in [1, 64, 3000] {
                let mut s = CycleStream::new(1, 0.0, Some(1.0)).unwrap();
                if curves_only {
                    s = s.curves_only();
                }
                let mut out = Vec::new();
                let mut err = None;
                for i in (0..3000).step_by(chunk) {
                    let e = (i + chunk).min(3000);
                    if let Err(m) = s.push(&t[i..e], &bad[i..e], &[&x[i..e]], &mut out) {
                        err = Some(m.to_string());
                        break;
                    }
                }
                let err = err.unwrap_or_else(|| panic!("jump {jump} taken"));
                assert!(
                    err.contains("sample 2500") && err.contains("at most a cycle"),
                    "{err}"
                );
                let before = t[2499] * 1000.0 * PI / 30.0 / (4.0 * PI);
                assert!(out.len() + 2 >= before as usize, "{} cycles", out.len());
            }
        }
    }
    // 700° of angle lost between two samples: taken.
    let mut gap = th[..3000].to_vec();
    for a in &mut gap[2500..] {
        *a += 700f64.to_radians();
    }
    let mut s = CycleStream::new(1, 0.0, Some(1.0)).unwrap();
    s.push(&t[..3000], &gap, &[&x[..3000]], &mut Vec::new())
        .unwrap();
}
