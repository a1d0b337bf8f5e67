//! What is in a recording (`physid inspect`): the channels, the rate, the cycles, the integrity
//! check, and what a raw angle sensor's channel turns out to be (a toothed wheel recognised).

use super::*;

/// One channel in the summary.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelSummary {
    /// Name.
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Samples.
    pub samples: usize,
}

/// What `physid inspect` reports.
#[derive(Debug, Clone, Serialize)]
pub struct Inspection {
    /// `time` or `crank_angle`.
    pub basis: &'static str,
    /// The channels.
    pub channels: Vec<ChannelSummary>,
    /// Duration [s] (from `t`), if known.
    pub duration_s: Option<f64>,
    /// Sample rate [Hz] (1 / median interval of `t`) on a time basis.
    pub sample_rate_hz: Option<f64>,
    /// Complete engine cycles (720°): counted from `cycle` on a crank-angle basis, from TDC
    /// markers (two per cycle) on a time basis.
    pub cycles: Option<usize>,
    /// The integrity check (with the trigger wheel's findings when one is decoded).
    pub integrity: Integrity,
    /// What decoding the trigger wheel found (`--wheel`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wheel: Option<WheelSummary>,
    /// Without an engine angle: the channels whose signal is a trigger wheel's, and which.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub recognised: Vec<RecognisedWheel>,
}

/// A channel recognised as a trigger wheel's signal.
#[derive(Debug, Clone, Serialize)]
pub struct RecognisedWheel {
    /// The channel.
    pub channel: String,
    /// The wheel, `N-M` (what `--wheel CHANNEL=N-M` takes).
    pub wheel: String,
    /// Teeth per revolution (N − M).
    pub teeth: u32,
    /// Missing teeth in the gap (M).
    pub missing: u32,
    /// Gaps seen.
    pub gaps: usize,
}

/// A trigger wheel as decoded by `physid inspect --wheel`.
#[derive(Debug, Clone, Serialize)]
pub struct WheelSummary {
    /// The sensor's channel.
    pub channel: String,
    /// The wheel given (`N-M`; a pulse encoder's `N-0`).
    pub wheel: String,
    /// A pulse encoder's index channel (`--index-raw`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub index: Option<String>,
    /// Teeth per revolution (N − M) and missing teeth (M).
    pub teeth: u32,
    /// Missing teeth in the gap.
    pub missing: u32,
    /// Tooth edges decoded (extra edges dropped).
    pub edges: usize,
    /// Whole revolutions between the first and last gap (index pulse).
    pub revolutions: usize,
    /// The slowest and fastest speed over a tooth [rpm].
    pub rpm_min: f64,
    /// See `rpm_min`.
    pub rpm_max: f64,
    /// Glitch pulses rejected.
    pub glitches: usize,
    /// Why the signal could not be decoded as the wheel given (then the rest is empty).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// Summarise a recording and check its integrity: an [`Inspector`] over it, in one chunk (and
/// a trigger wheel named decoded, [`inspect_wheel`]).
pub fn inspect(rec: &Recording, opts: &AcquisitionOptions) -> Inspection {
    let mut i = Inspector::new(rec, opts);
    i.push(rec);
    let mut i = i.finish();
    inspect_wheel(&mut i, rec, opts, rec);
    i
}

/// [`inspect`] on a recording read a chunk at a time (`physid inspect` on a file, whatever
/// its length): the channels' sample counts, the duration, the sample rate (1 / the median
/// step of the first [`NOMINAL_SAMPLES`]), the complete cycles and the integrity check
/// ([`IntegrityCheck`]), all taken as the chunks pass. Memory does not grow with the
/// recording: the first chunks are held only until the samples per cycle and the nominal step
/// are known from them.
#[derive(Debug, Clone)]
pub struct Inspector {
    opts: AcquisitionOptions,
    header: Recording,
    /// Held until the samples per cycle are known (crank-angle basis) — at most
    /// [`NOMINAL_SAMPLES`] samples.
    pending: Vec<Recording>,
    pending_rows: usize,
    check: Option<IntegrityCheck>,
    per_cycle: Option<usize>,
    t_head: Vec<f64>,
    t_span: Option<(f64, f64)>,
    rows: usize,
    /// Cycle runs: the current (value, length) and the complete ones so far.
    run: Option<(f64, usize)>,
    complete: usize,
    /// Marker rising edges so far, and the marker's last value.
    edges: usize,
    prev_marker: Option<f64>,
    prev_deg: Option<f64>,
    /// Without an engine angle: the edges of the channels that may be a wheel's signal, over
    /// their first [`RECOGNISE_SAMPLES`], to recognise one ([`physid_signal::wheel::recognise`]).
    candidates: Vec<(String, EdgeDetector)>,
}

/// The samples of a channel [`Inspector`] looks at to recognise a trigger wheel.
pub const RECOGNISE_SAMPLES: usize = 1 << 21;

/// Channels [`Inspector`] tries as a trigger wheel's signal: on a time basis with no engine
/// angle given or present, those without a standard name whose unit is none, a voltage or a
/// count (at most 8).
fn wheel_candidates(header: &Recording, opts: &AcquisitionOptions) -> Vec<(String, EdgeDetector)> {
    let has_angle = header.channel("theta_en").is_ok()
        || opts.encoders.iter().any(|(n, _)| header.channel(n).is_ok());
    if opts.sensor.is_some() || has_angle || header.basis != Basis::Time {
        return Vec::new();
    }
    header
        .channels()
        .iter()
        .filter(|c| {
            c.name != "t"
                && physid_core::standard_unit(&c.name).is_none()
                && (c.unit.is_empty()
                    || physid_core::units::lookup(&c.unit)
                        .is_some_and(|u| ["voltage", "dimensionless"].contains(&u.dimension)))
        })
        .take(8)
        .map(|c| (c.name.clone(), EdgeDetector::new(&EdgeOptions::default())))
        .collect()
}

impl Inspector {
    /// An inspection of a recording with `header`'s channels, units and basis.
    pub fn new(header: &Recording, opts: &AcquisitionOptions) -> Self {
        Self {
            opts: opts.clone(),
            header: header.slice(0..0),
            pending: Vec::new(),
            pending_rows: 0,
            check: None,
            per_cycle: None,
            t_head: Vec::new(),
            t_span: None,
            rows: 0,
            run: None,
            complete: 0,
            edges: 0,
            prev_marker: None,
            prev_deg: None,
            candidates: wheel_candidates(header, opts),
        }
    }

    /// Take the next chunk.
    pub fn push(&mut self, chunk: &Recording) {
        if self.check.is_some() {
            self.scan(chunk);
            return;
        }
        if self.per_cycle.is_none() {
            // The samples per cycle from the first positive step of `crank_deg`.
            if let Ok(d) = chunk.values("crank_deg") {
                let mut prev = self.prev_deg;
                for &v in d {
                    if let Some(step) = prev.map(|p| v - p).filter(|s| *s > 0.0) {
                        self.per_cycle = Some((720.0 / step).round() as usize);
                        break;
                    }
                    prev = Some(v);
                }
                self.prev_deg = d.last().copied().or(self.prev_deg);
            }
        }
        self.pending_rows += chunk.len();
        self.pending.push(chunk.clone());
        if self.per_cycle.is_some()
            || self.header.channel("crank_deg").is_err()
            || self.pending_rows >= NOMINAL_SAMPLES
        {
            self.start();
        }
    }

    fn start(&mut self) {
        self.check = Some(IntegrityCheck::new(
            &self.opts.integrity_options(&self.header, self.per_cycle),
            &self.header,
        ));
        for c in std::mem::take(&mut self.pending) {
            self.scan(&c);
        }
    }

    fn scan(&mut self, chunk: &Recording) {
        if let Some(c) = self.check.as_mut() {
            c.push(chunk);
        }
        self.rows += chunk.len();
        if let Ok(t) = chunk.values("t") {
            let room = RECOGNISE_SAMPLES.saturating_sub(self.rows - chunk.len());
            let n = t.len().min(room);
            for (name, d) in self.candidates.iter_mut() {
                if let (Ok(v), true) = (chunk.values(name), n > 0) {
                    d.push(&t[..n], &v[..n]);
                }
            }
        }
        if let Ok(t) = chunk.values("t") {
            let room = NOMINAL_SAMPLES.saturating_sub(self.t_head.len());
            self.t_head.extend_from_slice(&t[..t.len().min(room)]);
            if let (Some(&a), Some(&b)) = (t.first(), t.last()) {
                self.t_span = Some((self.t_span.map_or(a, |s| s.0), b));
            }
        }
        match self.header.basis {
            Basis::CrankAngle => {
                if let Ok(cycle) = chunk.values("cycle") {
                    for &v in cycle {
                        match &mut self.run {
                            Some((value, len)) if *value == v => *len += 1,
                            run => {
                                if let Some((_, len)) = run.take() {
                                    self.complete +=
                                        usize::from(self.per_cycle.is_none_or(|p| len == p));
                                }
                                *run = Some((v, 1));
                            }
                        }
                    }
                }
            }
            Basis::Time => {
                if let Ok(m) = chunk.values(&self.opts.marker) {
                    for &v in m {
                        if v != 0.0 && self.prev_marker.is_none_or(|p| p == 0.0) {
                            self.edges += 1;
                        }
                        self.prev_marker = Some(v);
                    }
                }
            }
        }
    }

    /// The end of the recording: the inspection.
    pub fn finish(mut self) -> Inspection {
        if self.check.is_none() {
            self.start();
        }
        let rec = &self.header;
        let has = |n: &str| rec.channel(n).is_ok();
        let cycles = match rec.basis {
            Basis::CrankAngle => has("cycle").then(|| {
                let last = self
                    .run
                    .is_some_and(|(_, len)| self.per_cycle.is_none_or(|p| len == p));
                self.complete + usize::from(last)
            }),
            Basis::Time => has(&self.opts.marker).then(|| self.edges.saturating_sub(1) / 2),
        };
        let mut integrity = self.check.map(IntegrityCheck::finish).unwrap_or_else(|| {
            IntegrityCheck::new(&IntegrityOptions::default(), &self.header).finish()
        });
        let recognised = self
            .candidates
            .into_iter()
            .filter_map(|(channel, d)| {
                let r = recognise(&d.finish().ok()?)?;
                Some(RecognisedWheel {
                    channel,
                    wheel: r.wheel.to_string(),
                    teeth: r.wheel.present(),
                    missing: r.wheel.missing,
                    gaps: r.gaps,
                })
            })
            .collect();
        // The sampling's step (a time basis): the median's, unless the stamps are jittered
        // (rounded), then the mean's — and said.
        let median = median_step(&self.t_head);
        let mut step = median;
        if let (Basis::Time, Some(m), Some(mean)) = (rec.basis, median, mean_step(&self.t_head)) {
            if (mean / m - 1.0).abs() > JITTER {
                step = Some(mean);
                let (lo, hi) = self
                    .t_head
                    .windows(2)
                    .map(|w| w[1] - w[0])
                    .filter(|&d| d > 0.5 * m && d < 1.5 * m)
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), d| {
                        (a.min(d), b.max(d))
                    });
                integrity.notes.push(Finding {
                    kind: FindingKind::Note,
                    index: 0,
                    detail: format!(
                        "the time stamps are jittered: steps {:.6} … {:.6} ms, median {:.6} ms, mean {:.6} ms (stamps rounded?): the sample rate is the mean step's, {:.3} Hz, not the median's {:.3} Hz",
                        lo * 1e3,
                        hi * 1e3,
                        m * 1e3,
                        mean * 1e3,
                        1.0 / mean,
                        1.0 / m
                    ),
                });
            }
        }
        Inspection {
            basis: match rec.basis {
                Basis::Time => "time",
                Basis::CrankAngle => "crank_angle",
            },
            channels: rec
                .channels()
                .iter()
                .map(|c| ChannelSummary {
                    name: c.name.clone(),
                    unit: c.unit.clone(),
                    samples: self.rows,
                })
                .collect(),
            duration_s: self.t_span.map(|(a, b)| b - a),
            sample_rate_hz: match rec.basis {
                Basis::Time => step.map(|d| 1.0 / d),
                Basis::CrankAngle => None,
            },
            cycles,
            integrity,
            wheel: None,
            recognised,
        }
    }
}

/// The trigger wheel `opts` names (`--wheel`), decoded as the recording is gone over — two
/// passes of `source` over `t` and its channel: where the gap is, then each edge's angle
/// ([`sensor`]) — into the inspection `i`: its summary, and what the decoding found among the
/// integrity findings (why it could not be decoded, when not). Nothing without a wheel in
/// `opts` or on a time basis without its channel.
pub fn inspect_wheel(
    i: &mut Inspection,
    header: &Recording,
    opts: &AcquisitionOptions,
    source: &dyn Reopen<Recordings, AppError>,
) {
    let Some(spec) = opts.sensor.as_ref() else {
        return;
    };
    // A pulse encoder is a wheel of N pitches and no gap, its reference the index.
    let (channel, wheel, index) = match &spec.sensor {
        AngleSensor::Wheel { channel, wheel, .. } => (channel, *wheel, None),
        AngleSensor::Pulses {
            channel,
            pulses,
            index,
            ..
        } => (
            channel,
            Wheel {
                teeth: *pulses,
                missing: 0,
            },
            Some(index),
        ),
        AngleSensor::Quadrature { .. } => return,
    };
    let present = |c: &str| header.channel(c).is_ok();
    if !present(channel) || !index.is_none_or(|z| present(z)) || header.basis != Basis::Time {
        return;
    }
    let mut summary = WheelSummary {
        channel: channel.to_string(),
        wheel: wheel.to_string(),
        index: index.cloned(),
        teeth: wheel.present(),
        missing: wheel.missing,
        edges: 0,
        revolutions: 0,
        rpm_min: f64::NAN,
        rpm_max: f64::NAN,
        glitches: 0,
        error: None,
    };
    let integrity = &mut i.integrity;
    let decoded =
        sensor_calibration(spec, source).and_then(|cal| sensor::sensor_pass(spec, &cal, source));
    match decoded {
        Ok(Some(a)) => {
            summary.edges = a.edges;
            summary.revolutions = a.revolutions;
            summary.glitches = a.glitches;
            (summary.rpm_min, summary.rpm_max) = a.rpm;
            for f in a.findings {
                if f.kind == FindingKind::Note {
                    integrity.notes.push(f);
                } else {
                    integrity.ok = false;
                    integrity.findings.push(f);
                }
            }
            integrity.findings.sort_by_key(|f| f.index);
        }
        Ok(None) => {}
        Err(e) => {
            let e = e.to_string();
            integrity.ok = false;
            integrity.findings.push(Finding {
                kind: FindingKind::UnevenPulses,
                index: 0,
                detail: e.clone(),
            });
            summary.error = Some(e);
        }
    }
    i.wheel = Some(summary);
}
