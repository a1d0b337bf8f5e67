//! The delivery latency's histogram (the `end` event's `latency_ms`).

/// A latency histogram: 0.1 ms bins up to 2 s, then 10 ms bins up to 2 min (no allocation
/// after construction). A quantile is its bin's upper edge, so within 0.1 ms below 2 s and
/// within 10 ms above; a quantile among latencies beyond 2 min is the largest seen.
#[derive(Debug, Clone)]
pub struct LatencyHistogram {
    bins: Vec<u64>,
    count: u64,
    max_s: f64,
}

/// Width of a fine bin [s] and where the fine bins end.
const BIN_S: f64 = 1e-4;
const FINE_S: f64 = 2.0;
/// Width of a coarse bin [s] and where they end.
const COARSE_BIN_S: f64 = 1e-2;
const COARSE_S: f64 = 120.0;
const FINE_BINS: usize = 20_000;
const BINS: usize = FINE_BINS + 11_800;

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self {
            bins: vec![0; BINS + 1],
            count: 0,
            max_s: 0.0,
        }
    }
}

impl LatencyHistogram {
    /// Count one latency [s] (negative as 0; beyond 2 min in an overflow bin).
    pub fn add(&mut self, s: f64) {
        let s = s.max(0.0);
        let k = if s < FINE_S {
            ((s / BIN_S) as usize).min(FINE_BINS - 1)
        } else if s < COARSE_S {
            (FINE_BINS + ((s - FINE_S) / COARSE_BIN_S) as usize).min(BINS - 1)
        } else {
            BINS
        };
        self.bins[k] += 1;
        self.count += 1;
        self.max_s = self.max_s.max(s);
    }

    /// The `q`-quantile [s] (the upper edge of its bin, never above the largest seen); `None`
    /// when empty.
    pub fn quantile(&self, q: f64) -> Option<f64> {
        if self.count == 0 {
            return None;
        }
        let want = (q * self.count as f64).ceil().max(1.0) as u64;
        let mut seen = 0;
        for (k, &n) in self.bins.iter().enumerate() {
            seen += n;
            if seen >= want {
                let edge = if k < FINE_BINS {
                    (k + 1) as f64 * BIN_S
                } else if k < BINS {
                    FINE_S + (k - FINE_BINS + 1) as f64 * COARSE_BIN_S
                } else {
                    self.max_s
                };
                return Some(edge.min(self.max_s));
            }
        }
        Some(self.max_s)
    }

    /// The largest [s].
    pub fn max(&self) -> f64 {
        self.max_s
    }

    /// Median, 99th percentile and largest [ms], each to 0.1 ms; `None` when empty.
    pub fn summary_ms(&self) -> Option<[f64; 3]> {
        let ms = |s: f64| (s * 1e4).round() / 10.0;
        Some([
            ms(self.quantile(0.5)?),
            ms(self.quantile(0.99)?),
            ms(self.max_s),
        ])
    }
}
