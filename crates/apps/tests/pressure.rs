//! Cylinder-pressure analysis against closed forms: an ideal cycle — polytropic compression
//! `p·Vⁿ = C₁` from BDC to TDC, polytropic expansion `p·Vⁿ = C₃` back to BDC, gas exchange at
//! constant pressure — whose net work is `(C₃ − C₁)·(V_c^{1−n} − V_bdc^{1−n})/(n − 1)` and whose
//! exponents are `n` on both strokes. The volume is written here from the textbook slider
//! crank, not taken from physid.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_apps::pressure::{analyse, Geometry, Pegging};
use physid_core::{Basis, Channel, Recording};

const BORE: f64 = 0.084;
const STROKE: f64 = 0.09;
const ROD: f64 = 0.15;
const CR: f64 = 10.0;
const N: f64 = 1.3;
const P0: f64 = 1e5;

fn volume(atdc_deg: f64) -> f64 {
    let r = STROKE / 2.0;
    let a = atdc_deg.to_radians();
    let s = r * (1.0 - a.cos()) + ROD - (ROD * ROD - (r * a.sin()).powi(2)).sqrt();
    let area = std::f64::consts::PI * BORE * BORE / 4.0;
    area * STROKE / (CR - 1.0) + area * s
}

/// Cycles at 0.1° steps, 1500 rpm, expansion pressures at BDC `p3` (one per cycle), the
/// measured pressure `offset` below the true one.
fn recording(p3: &[f64], offset: f64) -> Recording {
    let step = 0.1;
    let per = (720.0 / step) as usize;
    let (mut t, mut cycle, mut deg, mut p) = (vec![], vec![], vec![], vec![]);
    let vbdc = volume(180.0);
    let w = 1500.0 * 6.0; // deg/s
    for (c, &p3) in p3.iter().enumerate() {
        for k in 0..per {
            let d = k as f64 * step;
            let atdc = if d >= 360.0 { d - 720.0 } else { d };
            let v = volume(atdc);
            let pressure = if (0.0..=180.0).contains(&atdc) {
                p3 * (vbdc / v).powf(N)
            } else if (-180.0..0.0).contains(&atdc) {
                P0 * (vbdc / v).powf(N)
            } else {
                P0
            };
            t.push((c * per + k) as f64 * step / w);
            cycle.push(c as f64);
            deg.push(d);
            p.push(pressure - offset);
        }
    }
    let mut rec = Recording::new(Basis::CrankAngle);
    for (name, unit, values) in [
        ("t", "s", t),
        ("cycle", "-", cycle),
        ("crank_deg", "deg", deg),
        ("p_cyl", "Pa", p),
    ] {
        rec.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values,
        })
        .unwrap();
    }
    rec
}

fn closed_form_imep(p3: f64) -> f64 {
    let (vc, vbdc) = (volume(0.0), volume(180.0));
    let (c1, c3) = (P0 * vbdc.powf(N), p3 * vbdc.powf(N));
    let work = (c3 - c1) * (vc.powf(1.0 - N) - vbdc.powf(1.0 - N)) / (N - 1.0);
    work / (vbdc - vc)
}

fn geometry() -> Geometry {
    Geometry {
        bore: BORE,
        stroke: STROKE,
        rod: ROD,
        compression_ratio: CR,
    }
}

#[test]
fn imep_exponents_and_peak_of_an_ideal_cycle_equal_their_closed_forms() {
    // Four blocks from firing TDC to firing TDC: three cycles (−360° … 360° ATDC) — the first
    // TDC has no compression before it — each with the expansion after its own TDC.
    let p3 = [2.9e5, 3e5, 3.3e5, 2.7e5];
    let a = analyse(
        &recording(&p3, 0.0),
        "p_cyl",
        Some(&geometry()),
        Pegging::None,
    )
    .unwrap();
    assert_eq!(a.cycles.len(), 3);
    assert!(
        a.notes
            .iter()
            .any(|n| n.starts_with("1 cycle(s) left out without the compression")),
        "{:?}",
        a.notes
    );
    let mut want = Vec::new();
    for (c, &p) in a.cycles.iter().zip(&p3[1..]) {
        let imep = closed_form_imep(p);
        want.push(imep);
        let got = c.imep_pa.unwrap();
        assert!((got / imep - 1.0).abs() < 1e-5, "{got} vs {imep}");
        // Gas exchange at constant pressure does no net work: gross = net.
        assert!((c.imep_gross_pa.unwrap() / imep - 1.0).abs() < 1e-5);
        assert!(
            (c.n_compression.unwrap() - N).abs() < 1e-9,
            "{:?}",
            c.n_compression
        );
        assert!((c.n_expansion.unwrap() - N).abs() < 1e-9);
        // The peak is a jump at TDC (heat added at once), not the smooth maximum the parabola
        // between samples assumes: placed within half a step (0.05°) of it.
        assert!(c.p_max_deg.abs() <= 0.05 + 1e-12, "{}", c.p_max_deg);
        let p_tdc = p * (volume(180.0) / volume(0.0)).powf(N);
        assert!((c.p_max / p_tdc - 1.0).abs() < 1e-12);
        assert!((c.rpm - 1500.0).abs() < 1e-6, "{}", c.rpm);
    }
    let mean = want.iter().sum::<f64>() / 3.0;
    let sd = (want.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 2.0).sqrt();
    assert!((a.cov_imep.unwrap() / (sd / mean) - 1.0).abs() < 1e-4);
}

#[test]
fn pegging_recovers_the_offset_and_leaves_imep_alone() {
    let offset = 0.4e5;
    let g = geometry();
    let clean = analyse(
        &recording(&[3e5, 3e5], 0.0),
        "p_cyl",
        Some(&g),
        Pegging::None,
    )
    .unwrap();
    let shifted = recording(&[3e5, 3e5], offset);
    for peg in [Pegging::Bdc(P0), Pegging::Polytropic(N)] {
        let a = analyse(&shifted, "p_cyl", Some(&g), peg).unwrap();
        let c = &a.cycles[0];
        assert!(
            (c.peg_offset / offset - 1.0).abs() < 1e-9,
            "{peg:?}: {}",
            c.peg_offset
        );
        assert!((c.p_max / clean.cycles[0].p_max - 1.0).abs() < 1e-12);
        assert!((c.imep_pa.unwrap() / clean.cycles[0].imep_pa.unwrap() - 1.0).abs() < 1e-9);
        assert!((c.n_compression.unwrap() - N).abs() < 1e-9);
    }
    // Unpegged, the exponent from the offset pressure is wrong (why pegging matters).
    let raw = analyse(&shifted, "p_cyl", Some(&g), Pegging::None).unwrap();
    assert!((raw.cycles[0].n_compression.unwrap() - N).abs() > 0.05);
}

/// An unpegged sensor reading below zero on compression: no exponent there, and why — in the
/// cycle's record and once, counted, in the analysis' notes (it used to be dropped silently).
#[test]
fn an_exponent_left_out_is_said_with_its_reason() {
    // 2 bar below the true pressure: negative early in compression. Three blocks: two cycles.
    let a = analyse(
        &recording(&[3e5, 3e5, 3e5], 2e5),
        "p_cyl",
        Some(&geometry()),
        Pegging::None,
    )
    .unwrap();
    for c in &a.cycles {
        assert!(c.n_compression.is_none() && c.n_expansion.is_some());
        assert_eq!(c.notes.len(), 1, "{:?}", c.notes);
        assert!(
            c.notes[0].starts_with("n_compression left out: the pressure is not positive")
                && c.notes[0].contains("between -100° and -40° ATDC"),
            "{}",
            c.notes[0]
        );
    }
    let said: Vec<&String> = a
        .notes
        .iter()
        .filter(|n| n.contains("n_compression"))
        .collect();
    assert_eq!(said.len(), 1, "{:?}", a.notes);
    assert!(
        said[0].starts_with("2 cycle(s): n_compression left out"),
        "{}",
        said[0]
    );
    // Pegged, it is there and nothing is said.
    let pegged = analyse(
        &recording(&[3e5, 3e5, 3e5], 2e5),
        "p_cyl",
        Some(&geometry()),
        Pegging::Bdc(P0),
    )
    .unwrap();
    assert!(pegged.cycles.iter().all(|c| c.notes.is_empty()));
    assert!((pegged.cycles[0].n_compression.unwrap() - N).abs() < 1e-9);
}

#[test]
fn without_geometry_or_pa_what_is_left_out_is_said() {
    let rec = recording(&[3e5, 3e5], 0.0);
    let a = analyse(&rec, "p_cyl", None, Pegging::None).unwrap();
    assert!(a.cycles[0].imep_pa.is_none() && a.cov_imep.is_none());
    assert!(analyse(&rec, "p_cyl", None, Pegging::Polytropic(1.3)).is_err());
    let mut bad = geometry();
    bad.rod = 0.01;
    let e = analyse(&rec, "p_cyl", Some(&bad), Pegging::None).unwrap_err();
    assert!(e.to_string().contains("rod"), "{e}");
    let e = analyse(&rec, "p_int", None, Pegging::None).unwrap_err();
    assert!(e.to_string().contains("p_int"), "{e}");
}

/// A pressure channel in the wrong unit: a unit of another quantity is refused; values that
/// cannot be Pa (bar labelled Pa) are refused where IMEP needs Pa, else noted — naming the
/// channel and the sample.
#[test]
fn a_pressure_in_the_wrong_unit_is_named_with_its_sample() {
    let mut rec = recording(&[3e5, 3e5], 0.0);
    let bar: Vec<f64> = rec
        .values("p_cyl")
        .unwrap()
        .iter()
        .map(|p| p / 1e5)
        .collect();
    let peak = bar
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap()
        .0;
    rec.replace_values("p_cyl", bar).unwrap();
    let e = analyse(&rec, "p_cyl", Some(&geometry()), Pegging::None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("'p_cyl'") && e.contains(&format!("sample {peak}")) && e.contains("--scale"),
        "{e}"
    );
    let a = analyse(&rec, "p_cyl", None, Pegging::None).unwrap();
    assert!(
        a.notes.iter().any(|n| n.contains("sample")),
        "{:?}",
        a.notes
    );
    // Degrees Celsius are not a pressure.
    let mut hot = Recording::new(Basis::CrankAngle);
    for c in rec.channels() {
        let mut c = c.clone();
        if c.name == "p_cyl" {
            c.unit = "degC".into();
        }
        hot.push(c).unwrap();
    }
    let e = analyse(&hot, "p_cyl", None, Pegging::None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("'p_cyl' is in 'degC'") && e.contains("not a pressure"),
        "{e}"
    );
}

/// The analysis on a stream: however the recording is cut into chunks — one sample, a prime
/// number, a cycle less one, more than a cycle, the whole — the figures are those of the whole
/// recording, bit for bit (a partial last cycle included; its notes too).
#[test]
fn the_analysis_is_the_same_however_the_recording_is_chunked() {
    use physid_apps::pressure::CycleAnalyser;
    let full = recording(&[3e5, 3.2e5, 2.9e5, 3.1e5], 2e4);
    // A partial cycle at the end.
    let rec = full.slice(0..full.len() - 1000);
    let g = geometry();
    for peg in [Pegging::None, Pegging::Polytropic(N), Pegging::Bdc(P0)] {
        let want = analyse(&rec, "p_cyl", Some(&g), peg).unwrap();
        // Four blocks, the last cut 100° short: three cycles (the first TDC has no compression
        // before it; the last block's expansion is whole), and the next TDC's left out.
        assert_eq!(want.cycles.len(), 3);
        assert!(
            want.notes.iter().any(|n| n.contains("1 partial")),
            "{:?}",
            want.notes
        );
        for size in [1, 13, 7199, 7201, rec.len()] {
            let mut a = CycleAnalyser::new(&rec.slice(0..0), "p_cyl", Some(&g), peg).unwrap();
            let mut start = 0;
            while start < rec.len() {
                a.push(&rec.slice(start..start + size)).unwrap();
                start += size;
            }
            assert_eq!(a.finish().unwrap(), want, "{peg:?} {size}");
        }
    }
}

/// A recording that starts mid-cycle (here 20° after a firing TDC) keeps the cycle after it:
/// the first block is partial, but its second half — the next cycle's compression — is whole.
/// Starting after 360° it would not be, and that cycle is left out, said so.
#[test]
fn a_recording_starting_mid_cycle_keeps_its_first_whole_cycle() {
    let full = recording(&[3e5, 3.2e5, 2.9e5], 0.0);
    let g = geometry();
    let early = analyse(
        &full.slice(200..full.len()),
        "p_cyl",
        Some(&g),
        Pegging::None,
    )
    .unwrap();
    assert_eq!(early.cycles.len(), 2, "{:?}", early.notes);
    let whole = analyse(&full, "p_cyl", Some(&g), Pegging::None).unwrap();
    assert_eq!(early.cycles, whole.cycles);
    assert!(early.notes.iter().any(|n| n.contains("1 partial")));
    assert!(!early
        .notes
        .iter()
        .any(|n| n.contains("without the compression")));
    // From 380° on the first block's compression is cut: that cycle is left out.
    let late = analyse(
        &full.slice(3800..full.len()),
        "p_cyl",
        Some(&g),
        Pegging::None,
    )
    .unwrap();
    assert_eq!(late.cycles.len(), 1);
    assert!(
        late.notes
            .iter()
            .any(|n| n.starts_with("1 cycle(s) left out without the compression")),
        "{:?}",
        late.notes
    );
}
