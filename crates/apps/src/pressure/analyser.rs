//! [`CycleAnalyser`]: the recording's blocks, a chunk at a time, made into cycles (the second
//! half of a block and the first half of the next), each cycle's figures, their spread.

use super::*;

/// A longest run of one `cycle` value kept before the step of `crank_deg` is known (a file
/// whose angle never advances): beyond it the run is partial whatever its length.
const MAX_RUN: usize = 1 << 20;

/// A block's second half (180° … 360° before the next firing TDC): the next cycle's compression.
#[derive(Debug, Clone)]
struct Tail {
    cycle: f64,
    t: Vec<f64>,
    deg: Vec<f64>,
    p: Vec<f64>,
    torque: Vec<f64>,
}

/// The cycles' figures on a stream of crank-angle chunks: each block's samples are gathered
/// until the next block starts, the cycle its first half completes computed, its second half
/// kept for the next — it holds a block and a half and a few numbers per cycle, whatever the
/// recording's length.
#[derive(Debug, Clone)]
pub struct CycleAnalyser {
    channel: String,
    unit: String,
    /// Each cycle's figures.
    per_cycle: PerCycle,
    need_pa: bool,
    unit_check: UnitCheck,
    step: FirstAdvance,
    /// The current cycle's index and samples.
    run: Option<f64>,
    run_len: usize,
    run_t: Vec<f64>,
    run_deg: Vec<f64>,
    run_p: Vec<f64>,
    /// The brake torque's samples (with [`Self::with_brake`]).
    run_torque: Vec<f64>,
    cycles: Vec<CycleFigures>,
    partial: usize,
    /// The dropouts, and the cycles they cut (left out).
    dropouts: DropoutLog,
    cut: usize,
    /// Complete blocks whose TDC had no complete compression before it (the first).
    no_compression: usize,
    /// The last complete block's second half: the next cycle's compression.
    tail: Option<Tail>,
    notes: Vec<String>,
    /// Scratch for a cycle: angle ATDC.
    atdc: Vec<f64>,
    /// The sum of the complete cycles' pressures and times at each sample, their number (all
    /// of one length, on the same angles) — the ensemble mean's.
    ensemble: Option<(Vec<f64>, Vec<f64>, usize)>,
    /// The cycle whose curves are kept ([`Self::with_chosen_cycle`]; `None`: the last), and the
    /// kept curve.
    chosen: Option<i64>,
    kept: Option<CycleCurve>,
}

impl CycleAnalyser {
    /// The analysis of `p_channel` in crank-angle recordings with `header`'s channels.
    pub fn new(
        header: &Recording,
        p_channel: &str,
        geometry: Option<&Geometry>,
        peg: Pegging,
    ) -> Result<Self, AppError> {
        if header.basis != Basis::CrankAngle {
            return Err(AppError::Invalid(
                "the recording is on a time basis: convert it with --crank-angle first (or give the engine angle: --wheel, --encoder)".into(),
            ));
        }
        if let Some(g) = geometry {
            g.validate()?;
        }
        let unit_check = UnitCheck::new(header, p_channel)?;
        for name in ["cycle", "crank_deg", "t"] {
            header.channel(name)?;
        }
        let unit = header.channel(p_channel)?.unit.clone();
        let mut notes = Vec::new();
        if let Some(phase) = header.meta.get("phase") {
            notes.push(format!("phase: {phase}"));
        }
        if geometry.is_some() && unit != "Pa" {
            notes.push(format!(
                "'{p_channel}' is in '{unit}', not Pa: no IMEP, heat release or burn angles (calibrate it with --scale {p_channel}=GAIN,OFFSET into Pa: docs/data.md, \"A sensor of unknown gain\")"
            ));
        }
        if matches!(peg, Pegging::Polytropic(_)) && geometry.is_none() {
            return Err(AppError::Invalid(
                "polytropic pegging needs the geometry (--bore, --stroke, --rod, --compression-ratio)"
                    .into(),
            ));
        }
        Ok(Self {
            channel: p_channel.to_string(),
            per_cycle: PerCycle::new(PerCycleSettings {
                geometry: geometry.copied(),
                peg,
                heat: HeatRelease::default(),
                knock: None,
                in_pa: unit == "Pa",
                brake: None,
                lowpass: None,
                friction: None,
            }),
            unit,
            need_pa: geometry.is_some(),
            unit_check,
            step: FirstAdvance::default(),
            run: None,
            run_len: 0,
            run_t: Vec::new(),
            run_deg: Vec::new(),
            run_p: Vec::new(),
            run_torque: Vec::new(),
            cycles: Vec::new(),
            partial: 0,
            dropouts: DropoutLog::default(),
            cut: 0,
            no_compression: 0,
            tail: None,
            notes,
            atdc: Vec::new(),
            ensemble: None,
            chosen: None,
            kept: None,
        })
    }

    /// The heat release's γ, window and burn fractions ([`HeatRelease::default`] unless
    /// given; checked).
    pub fn with_heat_release(mut self, heat: HeatRelease) -> Result<Self, AppError> {
        heat.validate()?;
        self.per_cycle = PerCycle::new(PerCycleSettings {
            heat,
            ..self.per_cycle.settings().clone()
        });
        Ok(self)
    }

    /// BMEP and FMEP from the brake torque channel `brake.channel` of the recordings with
    /// `header`'s channels (in N·m; checked).
    pub fn with_brake(mut self, header: &Recording, brake: Brake) -> Result<Self, AppError> {
        brake.validate().map_err(AppError::Invalid)?;
        check_torque_unit(header, &brake.channel)?;
        self.per_cycle = PerCycle::new(PerCycleSettings {
            brake: Some(brake),
            ..self.per_cycle.settings().clone()
        });
        Ok(self)
    }

    /// The friction model's FMEP beside the measured ([`crate::fmep_model`]; checked).
    pub fn with_friction_model(mut self, model: FrictionModel) -> Result<Self, AppError> {
        model.validate().map_err(AppError::Invalid)?;
        self.per_cycle = PerCycle::new(PerCycleSettings {
            friction: Some(model),
            ..self.per_cycle.settings().clone()
        });
        Ok(self)
    }

    /// A zero-phase low-pass on each cycle's pressure before its figures (checked).
    pub fn with_lowpass(mut self, lowpass: PressureLowpass) -> Result<Self, AppError> {
        lowpass.validate().map_err(AppError::Invalid)?;
        self.per_cycle = PerCycle::new(PerCycleSettings {
            lowpass: Some(lowpass),
            ..self.per_cycle.settings().clone()
        });
        Ok(self)
    }

    /// Keep the curves of cycle `cycle` for a report (the last complete cycle's otherwise).
    pub fn with_chosen_cycle(mut self, cycle: Option<i64>) -> Self {
        self.chosen = cycle;
        self
    }

    /// Knock figures too ([`crate::knock`]; checked; with the pressure in Pa).
    pub fn with_knock(mut self, knock: Knock) -> Result<Self, AppError> {
        knock.validate().map_err(AppError::Invalid)?;
        if self.unit != "Pa" {
            self.notes.push(format!(
                "'{}' is in '{}', not Pa: no knock figures",
                self.channel, self.unit
            ));
        }
        self.per_cycle = PerCycle::new(PerCycleSettings {
            knock: Some(knock),
            ..self.per_cycle.settings().clone()
        });
        Ok(self)
    }

    /// The next chunk of the recording. A pressure or brake torque that is not a number (a
    /// sensor's dropout) is told once and left out with the cycles it cuts.
    pub fn push(&mut self, chunk: &Recording) -> Result<(), AppError> {
        let (cycle, deg, t, p) = (
            chunk.values("cycle")?,
            chunk.values("crank_deg")?,
            chunk.values("t")?,
            chunk.values(&self.channel)?,
        );
        self.unit_check.push(p);
        let torque = match &self.per_cycle.settings().brake {
            Some(b) => Some((b.channel.as_str(), chunk.values(&b.channel)?)),
            None => None,
        };
        let mut channels = vec![(self.channel.as_str(), p)];
        channels.extend(torque);
        self.dropouts.see(&channels, t);
        let torque = torque.map(|(_, q)| q);
        for i in 0..cycle.len() {
            self.step.see(deg[i]);
            if self.run.is_some_and(|c| c != cycle[i]) {
                self.close_run();
            }
            self.run = Some(cycle[i]);
            self.run_len += 1;
            let cap = self.per_cycle().map_or(MAX_RUN, |n| n + 1);
            if self.run_t.len() < cap {
                self.run_t.push(t[i]);
                self.run_deg.push(deg[i]);
                self.run_p.push(p[i]);
                if let Some(q) = torque {
                    self.run_torque.push(q[i]);
                }
            }
        }
        Ok(())
    }

    /// The curve of a cycle just analysed (its pressure as pegged), with its heat release.
    fn curve(&self, cycle: i64, rpm: f64) -> CycleCurve {
        CycleCurve {
            cycle,
            p: self.per_cycle.pegged().0.to_vec(),
            heat: self
                .per_cycle
                .last_heat(&self.atdc, rpm)
                .map(|a| a.q)
                .unwrap_or_default(),
        }
    }

    /// The samples per cycle, once `crank_deg` has advanced.
    fn per_cycle(&self) -> Option<usize> {
        self.step.step().map(|s| (720.0 / s).round() as usize)
    }

    /// The end of the recording: the figures and their spread.
    pub fn finish(mut self) -> Result<CycleAnalysis, AppError> {
        if self.step.step().is_none() {
            return Err(AppError::Invalid("crank_deg never advances".into()));
        }
        self.close_run();
        let mut notes = Vec::new();
        notes.extend(self.unit_check.finish(self.need_pa)?);
        notes.append(&mut self.notes);
        if self.no_compression > 0 {
            notes.push(format!(
                "{} cycle(s) left out without the compression before their TDC (a cycle is −360° … 360° ATDC: the first TDC has none)",
                self.no_compression
            ));
        }
        if self.partial > 0 {
            notes.push(format!(
                "{} partial cycle(s) left out (fewer than {} samples)",
                self.partial,
                self.per_cycle().unwrap_or(0)
            ));
        }
        let dropouts = std::mem::take(&mut self.dropouts.found);
        if self.cut > 0 {
            notes.push(format!(
                "{} cycle(s) cut by {} dropout(s) left out (a sample that is not a number)",
                self.cut,
                dropouts.len()
            ));
        }
        // The ensemble mean, analysed as one cycle (on the last cycle's angles: all alike).
        let mut mean_curve = None;
        let mean_cycle = match self.ensemble.take() {
            Some((sum_p, sum_t, n)) if n >= 2 && sum_p.len() == self.atdc.len() => {
                let p: Vec<f64> = sum_p.iter().map(|s| s / n as f64).collect();
                let t: Vec<f64> = sum_t.iter().map(|s| s / n as f64).collect();
                let atdc = std::mem::take(&mut self.atdc);
                let mut f =
                    self.per_cycle
                        .figures(n as i64, CycleTimes::of(&t, &atdc), &atdc, &p, None);
                // Not a cycle of the engine's: no misfire history; its time is the mean time
                // from a cycle's start to its TDC.
                if let Some(b) = f.burn.as_mut() {
                    (b.misfire, b.partial_burn) = (false, false);
                }
                self.atdc = atdc;
                mean_curve = Some(self.curve(n as i64, f.rpm));
                Some(f)
            }
            _ => None,
        };
        let curves = (!self.atdc.is_empty()).then(|| {
            let hr = &self.per_cycle.settings().heat;
            let (lo, hi) = hr.window;
            CycleCurves {
                atdc: self.atdc.clone(),
                volume: self.per_cycle.pegged().1.to_vec(),
                heat_deg: self
                    .atdc
                    .iter()
                    .copied()
                    .filter(|a| *a >= lo && *a <= hi)
                    .collect(),
                mean: mean_curve,
                chosen: self.kept.take(),
            }
        });
        let cycles = self.cycles;
        // What cycles left out, said once with how many.
        let mut left_out: Vec<(&str, usize)> = Vec::new();
        for n in cycles.iter().flat_map(|c| &c.notes) {
            match left_out.iter_mut().find(|(m, _)| *m == n.as_str()) {
                Some((_, k)) => *k += 1,
                None => left_out.push((n, 1)),
            }
        }
        for (n, k) in left_out {
            notes.push(format!("{k} cycle(s): {n}"));
        }
        // The spread over the fired cycles when some fired (a motored cycle's IMEP is its
        // loss, not a combustion's); over them all otherwise.
        let fired = |c: &CycleFigures| c.burn.as_ref().is_some_and(|b| b.fired);
        let any_fired = cycles.iter().any(fired);
        let imeps: Vec<f64> = cycles
            .iter()
            .filter(|c| !any_fired || fired(c))
            .filter_map(|c| c.imep_pa)
            .collect();
        let motored = cycles
            .iter()
            .filter(|c| c.burn.as_ref().is_some_and(|b| !b.fired))
            .count();
        if any_fired && motored > 0 {
            notes.push(format!(
                "CoV and LNV of IMEP over the {} fired cycle(s); {motored} motored left out",
                imeps.len()
            ));
        }
        let mean = imeps.iter().sum::<f64>() / imeps.len() as f64;
        let cov_imep = (imeps.len() >= 2).then(|| {
            let n = imeps.len() as f64;
            let var = imeps.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
            var.sqrt() / mean.abs()
        });
        // Lowest normalised value: the smallest IMEP over the mean (Heywood §9.4).
        let lnv_imep = (any_fired && imeps.len() >= 2)
            .then(|| imeps.iter().copied().fold(f64::INFINITY, f64::min) / mean);
        let settings = self.per_cycle.settings();
        Ok(CycleAnalysis {
            mean_cycle,
            curves,
            mfb: settings.heat.mfb.clone(),
            knock: settings.knock.is_some(),
            brake: settings.brake.is_some(),
            friction: settings.friction.is_some(),
            channel: self.channel,
            unit: self.unit,
            cycles,
            cov_imep,
            lnv_imep,
            notes,
            dropouts,
        })
    }

    /// The current block — from a firing TDC to the next — is over. A cycle is the compression
    /// before its firing TDC and the expansion after (−360° … 360° ATDC): the second half of the
    /// block before and the first half of this one. Its figures when both are complete and
    /// consecutive, else one partial more; this block's second half waits for the next.
    fn close_run(&mut self) {
        let (Some(c), len) = (self.run.take(), std::mem::take(&mut self.run_len)) else {
            return;
        };
        let complete = self.per_cycle().filter(|&n| c >= 0.0 && len == n);
        // The block's halves, split half a step before 360° (angles carry rounding).
        let half_step = 0.5 * self.step.step().unwrap_or(0.0);
        let head = self.run_deg.partition_point(|&d| d < 360.0 - half_step);
        // The recording's last block, cut short after its first half: the expansion is whole.
        let expansion = complete.or_else(|| {
            self.per_cycle().filter(|&n| {
                c >= 0.0 && head == n / 2 && self.run_deg.first().is_some_and(|&d| d < half_step)
            })
        });
        let prev = self.tail.take();
        match (expansion, prev) {
            (Some(_), Some(tail))
                if tail.cycle + 1.0 == c
                    && !tail.t.is_empty()
                    && self.run_deg.first().is_some_and(|&d| d < 360.0) =>
            {
                // The cycle's samples: the compression (the block before's second half,
                // −360° … 0 ATDC) …
                let mut t = tail.t;
                let mut p = tail.p;
                // Angles on the grid where they are off it by rounding only (a resampled file's
                // 536.9999999999982°), so that a window's ends take the same samples as the
                // stream's exact grid.
                // The step a cycle of n samples has (the first advance carries rounding too).
                let step = self
                    .per_cycle()
                    .map_or(2.0 * half_step, |n| 720.0 / n as f64);
                let snap = |d: f64| {
                    let g = (d / step).round() * step;
                    if (d - g).abs() < 1e-9 * step {
                        g
                    } else {
                        d
                    }
                };
                self.atdc.clear();
                self.atdc.extend(tail.deg.iter().map(|&d| snap(d) - 720.0));
                // … and the expansion (this block's first half, 0 … 360°).
                t.extend_from_slice(&self.run_t[..head]);
                self.atdc
                    .extend(self.run_deg[..head].iter().map(|&d| snap(d)));
                p.extend_from_slice(&self.run_p[..head]);
                let mut torque = tail.torque;
                torque.extend_from_slice(self.run_torque.get(..head).unwrap_or_default());
                // A dropout cuts it: left out.
                if !p.iter().chain(&torque).all(|v| v.is_finite()) {
                    self.cut += 1;
                } else {
                    let torque = (torque.len() == p.len()).then_some(torque.as_slice());
                    let times = CycleTimes::of(&t, &self.atdc);
                    let f = self
                        .per_cycle
                        .figures(c as i64, times, &self.atdc, &p, torque);
                    let rpm = f.rpm;
                    self.cycles.push(f);
                    if self.chosen.is_none_or(|k| k == c as i64) {
                        self.kept = Some(self.curve(c as i64, rpm));
                    }
                    // The ensemble: cycles of the first one's length (the same angles).
                    match &mut self.ensemble {
                        None => {
                            self.ensemble =
                                Some((p.clone(), t.iter().map(|x| x - t[0]).collect(), 1))
                        }
                        Some((sum_p, sum_t, n)) if sum_p.len() == p.len() => {
                            for (s, x) in sum_p.iter_mut().zip(&p) {
                                *s += x;
                            }
                            for (s, x) in sum_t.iter_mut().zip(&t) {
                                *s += x - t[0];
                            }
                            *n += 1;
                        }
                        Some(_) => {}
                    }
                }
            }
            (Some(_), _) => self.no_compression += 1,
            (None, _) => self.partial += 1,
        }
        if complete.is_none() && expansion.is_some() {
            // Its second half, cut short, is the next cycle's compression: that cycle is partial.
            self.partial += 1;
        }
        // The second half is the next cycle's compression when it is whole: the block is, or it
        // is the recording's first, begun before 360° (a file that starts mid-cycle).
        let half = self.run_deg.len() - head;
        let whole_half = self.per_cycle().is_some_and(|n| {
            head > 0 && half + 1 >= n / 2 && half <= n / 2 + 1 && self.cycles.is_empty()
        });
        if complete.is_some() || whole_half {
            self.tail = Some(Tail {
                cycle: c,
                t: self.run_t[head..].to_vec(),
                deg: self.run_deg[head..].to_vec(),
                p: self.run_p[head..].to_vec(),
                torque: self.run_torque.get(head..).unwrap_or_default().to_vec(),
            });
        }
        self.run_t.clear();
        self.run_deg.clear();
        self.run_p.clear();
        self.run_torque.clear();
    }
}
