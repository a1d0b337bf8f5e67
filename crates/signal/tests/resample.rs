//! The streaming resamplers against the whole-record `crank_grid` + `interp` (the reference,
//! itself checked against closed forms in `crank.rs`): bit for bit, whatever the chunking —
//! grid points falling exactly on samples and on chunk ends included — and their errors.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_signal::crank::{crank_grid, interp, CrankError};
use physid_signal::resample::{CrankChunk, CrankResampler, TimeResampler};

/// An accelerating engine sampled at 20 kHz with two channels; the angle hits the 1° grid
/// exactly at every other sample for a while (θ = k·0.5°), then runs free.
fn engine() -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let step = 1f64.to_radians();
    let n = 30_000;
    let t: Vec<f64> = (0..n).map(|i| i as f64 / 20_000.0).collect();
    let theta: Vec<f64> = (0..n)
        .map(|i| {
            if i < 4000 {
                (i as f64 * 0.5) * step
            } else {
                2000.0 * step + 90.0 * (t[i] - t[4000]) + 40.0 * (t[i] - t[4000]).powi(2)
            }
        })
        .collect();
    let p: Vec<f64> = theta
        .iter()
        .map(|th| 1e5 + 3e6 * (th * 0.5).sin().powi(8))
        .collect();
    let w: Vec<f64> = t.iter().map(|t| 100.0 + 7.0 * (30.0 * t).cos()).collect();
    (t, theta, p, w)
}

fn crank_chunked(t: &[f64], theta: &[f64], ys: &[&[f64]], tdc: f64, sizes: &[usize]) -> CrankChunk {
    let mut r = CrankResampler::new(tdc, 1.0, ys.len()).unwrap();
    let mut all = CrankChunk {
        channels: vec![Vec::new(); ys.len()],
        ..Default::default()
    };
    let mut out = CrankChunk::default();
    let append = |out: &CrankChunk, all: &mut CrankChunk| {
        all.theta.extend(&out.theta);
        all.t.extend(&out.t);
        all.cycle.extend(&out.cycle);
        all.crank_deg.extend(&out.crank_deg);
        for (a, o) in all.channels.iter_mut().zip(&out.channels) {
            a.extend(o);
        }
    };
    let (mut start, mut k) = (0, 0);
    while start < t.len() {
        let end = (start + sizes[k % sizes.len()]).min(t.len());
        k += 1;
        r.push_angle(&t[start..end], &theta[start..end]).unwrap();
        let cols: Vec<&[f64]> = ys.iter().map(|y| &y[start..end]).collect();
        r.push_channels(&t[start..end], &cols, &mut out).unwrap();
        append(&out, &mut all);
        start = end;
    }
    r.finish(&mut out);
    append(&out, &mut all);
    all
}

#[test]
fn crank_resampler_equals_the_whole_record_bit_for_bit() {
    let (t, theta, p, w) = engine();
    for tdc in [0.0, 0.37, -2.0] {
        let g = crank_grid(&t, &theta, tdc, 1.0).unwrap();
        let pw = interp(&t, &p, &g.t);
        let ww = interp(&t, &w, &g.t);
        for sizes in [
            vec![1],
            vec![2],
            vec![3, 1, 7],
            vec![999],
            vec![4000, 1],
            vec![t.len()],
        ] {
            let s = crank_chunked(&t, &theta, &[&p, &w], tdc, &sizes);
            assert_eq!(s.theta, g.theta, "{tdc} {sizes:?}");
            assert_eq!(s.t, g.t, "{tdc} {sizes:?}");
            assert_eq!(s.cycle, g.cycle, "{tdc} {sizes:?}");
            assert_eq!(s.crank_deg, g.crank_deg, "{tdc} {sizes:?}");
            assert_eq!(s.channels[0], pw, "{tdc} {sizes:?}");
            assert_eq!(s.channels[1], ww, "{tdc} {sizes:?}");
        }
    }
}

#[test]
fn crank_resampler_with_the_angle_at_its_own_times() {
    // An encoder's angle: only at its counts' times (every 7th sample), the channels at all.
    let (t, theta, p, _) = engine();
    let (ta, tha): (Vec<f64>, Vec<f64>) = (0..t.len()).step_by(7).map(|i| (t[i], theta[i])).unzip();
    let g = crank_grid(&ta, &tha, 0.1, 1.0).unwrap();
    let pw = interp(&t, &p, &g.t);
    let mut r = CrankResampler::new(0.1, 1.0, 1).unwrap();
    let mut out = CrankChunk::default();
    let (mut got_t, mut got_p): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    let mut next = 0; // the next angle sample to push
    for c in 0..t.len().div_ceil(1000) {
        let (a, b) = (c * 1000, ((c + 1) * 1000).min(t.len()));
        // The angle leads: its samples up to the first past this stretch of time.
        let upto = (b.div_ceil(7) + 1).min(ta.len());
        r.push_angle(&ta[next..upto], &tha[next..upto]).unwrap();
        next = upto;
        r.push_channels(&t[a..b], &[&p[a..b]], &mut out).unwrap();
        got_t.extend(&out.t);
        got_p.extend(&out.channels[0]);
    }
    r.finish(&mut out);
    got_t.extend(&out.t);
    got_p.extend(&out.channels[0]);
    assert_eq!(got_t, g.t);
    assert_eq!(got_p, pw);
}

#[test]
fn time_resampler_equals_the_whole_record_bit_for_bit() {
    // A crank-angle recording: time steps following the speed.
    let (t, _, p, _) = engine();
    let tc: Vec<f64> = t.iter().map(|t| t + 0.3 * t * t).collect();
    for rate in [20_000.0, 7_777.7, 50_000.0] {
        let (t0, t1) = (tc[0], tc[tc.len() - 1]);
        let n = ((t1 - t0) * rate).floor() as usize + 1;
        let grid: Vec<f64> = (0..n).map(|i| t0 + i as f64 / rate).collect();
        let want = interp(&tc, &p, &grid);
        for size in [1, 5, 4096, tc.len()] {
            let mut r = TimeResampler::new(rate, 1).unwrap();
            let (mut tt, mut out) = (Vec::new(), vec![Vec::new()]);
            let (mut gt, mut gp): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
            for (tch, pch) in tc.chunks(size).zip(p.chunks(size)) {
                r.push(tch, &[pch], &mut tt, &mut out).unwrap();
                gt.extend(&tt);
                gp.extend(&out[0]);
            }
            r.finish(&mut tt, &mut out);
            gt.extend(&tt);
            gp.extend(&out[0]);
            assert_eq!(gt, grid, "{rate} {size}");
            assert_eq!(gp, want, "{rate} {size}");
        }
    }
}

#[test]
fn errors_name_the_sample_across_chunks() {
    let mut r = CrankResampler::new(0.0, 1.0, 0).unwrap();
    r.push_angle(&[0.0, 1.0], &[0.0, 0.1]).unwrap();
    let e = r.push_angle(&[2.0, 3.0], &[0.2, 0.2]).unwrap_err();
    assert_eq!(
        e,
        CrankError::NotIncreasing {
            what: "the crank angle",
            index: 3,
            prev: 0.2,
            next: 0.2
        }
    );
    let mut r = TimeResampler::new(10.0, 1).unwrap();
    let (mut tt, mut out) = (Vec::new(), vec![Vec::new()]);
    r.push(&[0.0], &[&[1.0]], &mut tt, &mut out).unwrap();
    let e = r
        .push(&[f64::NAN], &[&[1.0]], &mut tt, &mut out)
        .unwrap_err();
    assert_eq!(e.to_string(), "time is NaN at sample 1");
    assert!(CrankResampler::new(0.0, 0.0, 1).is_err());
    assert!(TimeResampler::new(-1.0, 1).is_err());
}

/// A grid whose points from one chunk cannot fit in memory (a step of 1e-9°; a MHz over a
/// year) is refused with the points and the memory they would take, not grown until the
/// allocator aborts the process.
#[test]
fn a_grid_that_cannot_fit_in_memory_is_refused() {
    if physid_core::memory::available().is_none() {
        return; // no /proc/meminfo here: nothing to refuse against
    }
    let mut r = CrankResampler::new(0.0, 1e-9, 3).unwrap();
    let e = r
        .push_angle(&[0.0, 1.0], &[0.0, 100.0])
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("5729577951309 points of the 1e-9° crank-angle grid in the data from sample 0 on would take about")
            && e.ends_with("GB free: make the grid coarser"),
        "{e}"
    );
    // An angle scaled by 10¹² (its first chunk fine): the refusal names the jump that asks
    // for the points, from the previous chunk's last sample or within the chunk.
    let mut r = CrankResampler::new(0.0, 1.0, 3).unwrap();
    r.push_angle(&[0.0, 1e-4], &[0.0, 0.1]).unwrap();
    let e = r
        .push_angle(&[2e-4, 3e-4, 4e-4], &[0.2, 0.3, 4e11])
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with(
            "22918311805227 points of the 1° crank-angle grid in the data from sample 2 on"
        ) && e.ends_with(
            "GB free: the crank angle advances 399999999999.7 rad (63661977237 revolutions) \
                 from sample 3 to sample 4: is it in radians, and of the right scale?"
        ),
        "{e}"
    );
    let mut r = CrankResampler::new(0.0, 1.0, 3).unwrap();
    r.push_angle(&[0.0, 1e-4], &[0.0, 0.1]).unwrap();
    let e = r.push_angle(&[2e-4], &[4e11]).unwrap_err().to_string();
    assert!(e.contains("from sample 1 to sample 2:"), "{e}");
    let mut r = TimeResampler::new(1e6, 1).unwrap();
    let (mut tt, mut out) = (Vec::new(), vec![Vec::new()]);
    r.push(&[0.0, 0.5], &[&[1.0, 2.0]], &mut tt, &mut out)
        .unwrap();
    assert_eq!(tt.len(), 500_000);
    // A year of data at a MHz in one chunk.
    let e = r
        .push(&[1.0, 3.2e7], &[&[1.0, 2.0]], &mut tt, &mut out)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("points of the 1000000 Hz time basis in the data from sample 2 on")
            && e.ends_with("make the grid coarser"),
        "{e}"
    );
}
