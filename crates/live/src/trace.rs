//! The panel's time traces: the channels an operator watches, as bin means at a display rate
//! (a 10 kHz acquisition shown at 200 Hz), sent in [`Event::Trace`]s of a few bins each. The
//! bins are counted in samples from the stream's start, so the traces do not depend on how
//! the stream was chunked.

use crate::event::{Event, Name};
use crate::service::{LiveError, PanelFeed};
use physid_apps::error::AppError;
use physid_apps::stage::{Sink, Stage};
use physid_core::Recording;
use std::collections::BTreeMap;

/// The channels traced (those the source has), SI units: the speeds, the shaft's and the
/// engine's torque, the intake manifold pressure, the throttle.
pub const TRACE_CHANNELS: [&str; 6] = [
    "omega_en",
    "omega_dy",
    "torque_shaft",
    "torque_engine",
    "p_int",
    "throttle",
];

/// Bin means of the traced channels, a [`Stage`] whose output is the `trace` events.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct TraceStage {
    names: Vec<String>,
    /// Samples per bin, bins per event.
    bin: usize,
    per_event: usize,
    /// The bin in progress: sums and sample count.
    sum_t: f64,
    sums: Vec<f64>,
    count: usize,
    /// Finished bins not sent yet.
    t: Vec<f64>,
    values: Vec<Vec<f64>>,
    /// Samples taken from the stream's start.
    taken: u64,
}

impl TraceStage {
    /// Traces of the channels of [`TRACE_CHANNELS`] that `first` (the stream's first chunk)
    /// has, for a stream at `rate_hz` [Hz].
    pub fn new(first: &Recording, feed: &PanelFeed, rate_hz: f64) -> Result<Self, LiveError> {
        if !(feed.trace_hz > 0.0 && feed.trace_every_s > 0.0 && rate_hz > 0.0) {
            return Err(LiveError::Invalid(format!(
                "trace rate {} Hz every {} s at {} Hz: expected all > 0",
                physid_core::Num(feed.trace_hz),
                physid_core::Num(feed.trace_every_s),
                physid_core::Num(rate_hz)
            )));
        }
        let names: Vec<String> = TRACE_CHANNELS
            .into_iter()
            .filter(|c| first.channel(c).is_ok())
            .map(String::from)
            .collect();
        let bin = ((rate_hz / feed.trace_hz).round() as usize).max(1);
        let per_event = ((feed.trace_every_s * rate_hz / bin as f64).round() as usize).max(1);
        Ok(Self {
            bin,
            per_event,
            sum_t: 0.0,
            sums: vec![0.0; names.len()],
            count: 0,
            t: Vec::with_capacity(per_event),
            values: vec![Vec::with_capacity(per_event); names.len()],
            names,
            taken: 0,
        })
    }

    fn close_bin(&mut self) {
        let n = self.count as f64;
        self.t.push(self.sum_t / n);
        for (v, s) in self.values.iter_mut().zip(&mut self.sums) {
            v.push(*s / n);
            *s = 0.0;
        }
        self.sum_t = 0.0;
        self.count = 0;
    }

    fn take(&mut self) -> Event {
        let channels: BTreeMap<Name, Vec<f64>> = self
            .names
            .iter()
            .zip(&mut self.values)
            .map(|(n, v)| {
                let v = std::mem::replace(v, Vec::with_capacity(self.per_event));
                (Name::Owned(n.clone()), v)
            })
            .collect();
        let t = std::mem::replace(&mut self.t, Vec::with_capacity(self.per_event));
        Event::Trace {
            t_s: t.last().copied().unwrap_or(f64::NAN),
            t,
            channels,
            samples: self.taken,
        }
    }
}

impl Stage for TraceStage {
    type Out = Event;

    /// Take a chunk; a trace event when enough bins are finished.
    fn push(&mut self, chunk: &Recording, out: &mut dyn Sink<Event>) -> Result<(), AppError> {
        let t = chunk.values("t")?;
        let cols = self
            .names
            .iter()
            .map(|n| chunk.values(n))
            .collect::<Result<Vec<_>, _>>()?;
        self.taken += t.len() as u64;
        for i in 0..t.len() {
            self.sum_t += t[i];
            for (s, c) in self.sums.iter_mut().zip(&cols) {
                *s += c[i];
            }
            self.count += 1;
            if self.count == self.bin {
                self.close_bin();
            }
        }
        if self.t.len() >= self.per_event {
            let e = self.take();
            out.put(e);
        }
        Ok(())
    }

    /// The bins not sent yet (the last one partial), at the end of the stream.
    fn finish(&mut self, out: &mut dyn Sink<Event>) -> Result<(), AppError> {
        if self.count > 0 {
            self.close_bin();
        }
        if !self.t.is_empty() {
            let e = self.take();
            out.put(e);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use physid_core::{Basis, Channel};

    fn chunk(t: &[f64], x: &[f64]) -> Recording {
        let mut r = Recording::new(Basis::Time);
        for (name, unit, v) in [("t", "s", t), ("throttle", "deg", x)] {
            r.push(Channel {
                name: name.into(),
                unit: unit.into(),
                values: v.to_vec(),
            })
            .unwrap();
        }
        r
    }

    /// Bin means of a ramp are the ramp at the bins' middles; the same for any chunking; the
    /// last partial bin comes with the flush.
    #[test]
    fn bins_are_means_and_chunking_does_not_matter() {
        let t: Vec<f64> = (0..1003).map(|k| k as f64 * 1e-3).collect();
        let x: Vec<f64> = t.iter().map(|t| 2.0 * t + 1.0).collect();
        let feed = PanelFeed {
            trace_hz: 100.0,
            trace_every_s: 0.1,
            curve_step_deg: 2.0,
        };
        let run = |size: usize| {
            let mut st = TraceStage::new(&chunk(&t[..1], &x[..1]), &feed, 1000.0).unwrap();
            let (mut tt, mut xx): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
            let mut take = |e: Event| {
                if let Event::Trace { t, channels, .. } = e {
                    tt.extend(t);
                    xx.extend(&channels["throttle"]);
                }
            };
            let mut events = Vec::new();
            for k in (0..t.len()).step_by(size) {
                let e = (k + size).min(t.len());
                st.push(&chunk(&t[k..e], &x[k..e]), &mut events).unwrap();
            }
            st.finish(&mut events).unwrap();
            for ev in events {
                take(ev);
            }
            (tt, xx)
        };
        let (tt, xx) = run(1003);
        assert_eq!(tt.len(), 101);
        for (k, (tk, xk)) in tt.iter().zip(&xx).enumerate().take(100) {
            assert!((tk - (k as f64 * 0.01 + 0.0045)).abs() < 1e-12);
            assert!((xk - (2.0 * tk + 1.0)).abs() < 1e-12);
        }
        assert!(
            (tt[100] - 1.001).abs() < 1e-12,
            "the partial bin of 3 samples"
        );
        for size in [1, 17, 256] {
            assert_eq!(run(size), (tt.clone(), xx.clone()));
        }
    }
}
