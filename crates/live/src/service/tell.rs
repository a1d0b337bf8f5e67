//! How each application's stage is started for a live run and how its outputs are told as
//! events ([`Tell`]): the integrity checks, the shaft monitor, the cycle statistics, the
//! friction characterisation and the cyclic-torque estimation.

use super::slot::{At, Tell};
use super::*;
use physid_apps::combustion_stage::CombustionOutput;
use physid_apps::shaft_monitor::ShaftSample;
use physid_apps::stage::Dropout;
use physid_core::Sink;

/// The integrity checks on the stream (`physid inspect`'s, as the chunks come), set up on its
/// first chunk: the encoders and the TDC marker of [`AcquisitionOptions`] it has, time against
/// the sample step.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct Integrity {
    rate_hz: f64,
    stream: Option<IntegrityStream>,
}

impl Stage for Integrity {
    type Out = IntegrityFinding;

    fn push(
        &mut self,
        chunk: &Recording,
        out: &mut dyn Sink<IntegrityFinding>,
    ) -> Result<(), AppError> {
        let rate_hz = self.rate_hz;
        let stream = self.stream.get_or_insert_with(|| {
            let opts = AcquisitionOptions::default().integrity_options(chunk, None);
            IntegrityStream::new(&opts, Basis::Time, Some(1.0 / rate_hz))
        });
        Stage::push(stream, chunk, out)
    }

    fn finish(&mut self, out: &mut dyn Sink<IntegrityFinding>) -> Result<(), AppError> {
        match self.stream.as_mut() {
            Some(stream) => Stage::finish(stream, out),
            None => Ok(()),
        }
    }
}

impl Tell for Integrity {
    const NAME: &'static str = "integrity";
    const STOPPED: &'static str = "the integrity checks stopped";
    const FLAG: &'static str = "always";
    type Told = ();

    fn start(_cfg: &LiveConfig, rate_hz: f64) -> Result<Option<Self>, LiveError> {
        Ok(Some(Self {
            rate_hz,
            stream: None,
        }))
    }

    /// A finding made certain, at its sample's time.
    fn tell(&self, _: &mut (), f: &IntegrityFinding, at: At, events: &mut dyn Sink<Event>) {
        events.put(Event::Finding {
            t_s: at.t_first + f.index as f64 / at.rate_hz,
            message: f.detail.clone(),
            kind: Some(f.kind),
            sample: Some(f.index),
        });
    }
}

/// What telling the shaft monitor's outputs remembers.
#[derive(Debug, Default, Serialize, Deserialize)]
pub(super) struct ShaftTold {
    /// K, B, τ0 frozen by the excitation supervisor, as last told.
    frozen: Option<[bool; 3]>,
    /// The time of the last estimate told [s].
    last_sent: Option<f64>,
    /// The latest estimate not told (thinned out to one each `estimate_every_s`): told at the
    /// end.
    pending: Option<ShaftSample>,
}

impl Tell for ShaftStage {
    const NAME: &'static str = "shaft";
    const STOPPED: &'static str = "the shaft monitor stopped";
    const FLAG: &'static str = "always";
    type Told = ShaftTold;

    fn start(cfg: &LiveConfig, rate_hz: f64) -> Result<Option<Self>, LiveError> {
        Ok(Some(ShaftStage::new(&cfg.monitor, rate_hz)?))
    }

    /// An alarm at once; an estimate at most each `estimate_every_s` (the latest held back is
    /// told at the end); the excitation supervisor's changes (and, supervised, the start) as
    /// they happen.
    fn tell(&self, told: &mut ShaftTold, o: &ShaftOutput, at: At, events: &mut dyn Sink<Event>) {
        let s = match o {
            ShaftOutput::Alarm(a) => return events.put(Event::shaft_alarm(a)),
            ShaftOutput::Glitch(g) => {
                return events.put(Event::finding(g.t_s, format!("shaft: {}", g.message)))
            }
            ShaftOutput::Sample(s) if at.end => {
                told.pending = Some(*s);
                return;
            }
            ShaftOutput::Sample(s) => s,
        };
        if at.cfg.monitor.supervise && told.frozen != Some(s.frozen) {
            told.frozen = Some(s.frozen);
            let names = ["K", "B", "tau0"];
            let pick = |frozen: bool| -> Vec<String> {
                names
                    .iter()
                    .zip(s.frozen)
                    .filter(|(_, f)| *f == frozen)
                    .map(|(n, _)| n.to_string())
                    .collect()
            };
            events.put(Event::Identifiability {
                app: App::Shaft,
                t_s: s.t_s,
                estimable: pick(false),
                frozen: pick(true),
            });
        }
        if told
            .last_sent
            .is_none_or(|l| s.t_s - l >= at.cfg.estimate_every_s)
        {
            events.put(Event::shaft_estimate(s));
            told.last_sent = Some(s.t_s);
            told.pending = None;
        } else {
            told.pending = Some(*s);
        }
    }

    /// The last estimate: the monitor's final one, or the latest held back.
    fn tell_end(told: &mut ShaftTold, _at: At, events: &mut dyn Sink<Event>) {
        if let Some(s) = told.pending.take() {
            events.put(Event::shaft_estimate(&s));
        }
    }

    fn restarted(told: &mut ShaftTold) {
        told.frozen = None;
    }
}

impl Tell for CycleStage {
    const NAME: &'static str = "cycles";
    const STOPPED: &'static str =
        r#"the cycle statistics stopped (restart: {"cmd":"restart","stage":"cycles"})"#;
    const FLAG: &'static str = "always";
    /// Cycles told.
    type Told = usize;

    /// The channels of [`CYCLE_CHANNELS`] the source has (set up on the next chunk, counting
    /// cycles from there).
    fn start(cfg: &LiveConfig, _rate_hz: f64) -> Result<Option<Self>, LiveError> {
        let step = cfg.panel.map(|p| p.curve_step_deg);
        Ok(Some(CycleStage::new(&CYCLE_CHANNELS, cfg.theta_tdc, step)))
    }

    fn tell(&self, told: &mut usize, c: &CycleOutput, _at: At, events: &mut dyn Sink<Event>) {
        match c {
            CycleOutput::Cycle(c) => {
                let step = self.curve_step_deg().unwrap_or(0.0);
                *told += 1;
                events.put(Event::cycle(c, self.channels(), step));
            }
            CycleOutput::Dropout(d) => dropout::<Self>(d, events),
        }
    }
}

/// A dropout stage `S` left out, as a finding.
fn dropout<S: Tell>(d: &Dropout, events: &mut dyn Sink<Event>) {
    events.put(Event::finding(
        d.t_s,
        format!("{}: {}", S::NAME, d.message()),
    ));
}

/// `estimable` and the rest of `all` as an identifiability event of `app`.
fn identifiability(app: App, t_s: f64, estimable: &[String], all: &[&str]) -> Event {
    Event::Identifiability {
        app,
        t_s,
        frozen: all
            .iter()
            .filter(|p| !estimable.iter().any(|e| e == *p))
            .map(|p| p.to_string())
            .collect(),
        estimable: estimable.to_vec(),
    }
}

/// `names` paired with `values`.
fn by_name<N: ToString>(names: &[N], values: &[f64]) -> std::collections::BTreeMap<String, f64> {
    names
        .iter()
        .map(|n| n.to_string())
        .zip(values.iter().copied())
        .collect()
}

impl Tell for FrictionStage {
    const NAME: &'static str = "friction";
    const STOPPED: &'static str = "the friction characterisation stopped";
    const FLAG: &'static str = "--friction";
    type Told = ();

    fn start(cfg: &LiveConfig, _rate_hz: f64) -> Result<Option<Self>, LiveError> {
        let Some(f) = &cfg.friction else {
            return Ok(None);
        };
        let mut stage = FrictionStage::new(f.fit.clone(), Some(f.select_after))?;
        stage.set_theta_tdc(cfg.theta_tdc)?;
        Ok(Some(stage))
    }

    /// The choice of parameters; then each cycle's friction, measured, predicted, nominal and
    /// true, with the estimates.
    fn tell(&self, _: &mut (), o: &FrictionOutput, _at: At, events: &mut dyn Sink<Event>) {
        events.put(match o {
            FrictionOutput::Dropout(d) => return dropout::<Self>(d, events),
            FrictionOutput::Selected { t_s, estimable, .. } => {
                identifiability(App::Friction, *t_s, estimable, &REGRESSION_PARAMS)
            }
            FrictionOutput::Cycle(s) => {
                let names = self.estimable().unwrap_or_default();
                Event::Friction {
                    cycle: s.cycle,
                    t_s: s.t_s,
                    measured: s.measured_nm,
                    predicted: s.predicted_nm,
                    nominal: s.nominal_nm,
                    truth: s.truth_nm,
                    params: by_name(names, &s.params),
                    std_err: by_name(names, &s.std_err),
                }
            }
        });
    }
}

impl Tell for TorqueStage {
    const NAME: &'static str = "torque";
    const STOPPED: &'static str = "the cyclic-torque estimation stopped";
    const FLAG: &'static str = "--torque";
    type Told = ();

    fn start(cfg: &LiveConfig, _rate_hz: f64) -> Result<Option<Self>, LiveError> {
        let Some(t) = &cfg.torque else {
            return Ok(None);
        };
        let mut stage = TorqueStage::new(t.fit.clone(), t.select_after_cycles.max(1) * 720)?;
        stage.set_theta_tdc(cfg.theta_tdc)?;
        Ok(Some(stage))
    }

    /// The choice of parameters; then each cycle's estimates and torque errors.
    fn tell(&self, _: &mut (), o: &TorqueOutput, _at: At, events: &mut dyn Sink<Event>) {
        events.put(match o {
            TorqueOutput::Dropout(d) => return dropout::<Self>(d, events),
            TorqueOutput::Selected { t_s, estimable, .. } => identifiability(
                App::Torque,
                *t_s,
                estimable,
                &physid_models::cyclic_torque::PARAMS,
            ),
            TorqueOutput::Cycle(c) => {
                let names = self.estimable().unwrap_or_default();
                Event::Torque {
                    t_s: c.t_s,
                    params: by_name(&names, &c.params),
                    std_err: by_name(&names, &c.std_err),
                    rms_error: c.rms_error_nm,
                    rms_measured: c.rms_measured_nm,
                }
            }
        });
    }
}

impl Tell for CombustionStage {
    const NAME: &'static str = "combustion";
    const STOPPED: &'static str =
        r#"the combustion analysis stopped (restart: {"cmd":"restart","stage":"combustion"})"#;
    const FLAG: &'static str = "--combustion";
    type Told = ();

    fn start(cfg: &LiveConfig, _rate_hz: f64) -> Result<Option<Self>, LiveError> {
        let Some(c) = &cfg.combustion else {
            return Ok(None);
        };
        let stage =
            CombustionStage::new(&c.channel, c.settings.clone(), cfg.theta_tdc, c.step_deg)?;
        // The panel's view: a cycle's pressure and heat release rate, as its cyclic view's grid.
        Ok(Some(match cfg.panel {
            Some(p) => stage.with_curves(p.curve_step_deg),
            None => stage,
        }))
    }

    /// Each cycle's figures by their `cycles --tracks` names, with its curves when due.
    fn tell(&self, _: &mut (), o: &CombustionOutput, _at: At, events: &mut dyn Sink<Event>) {
        let cc = match o {
            CombustionOutput::Cycle(cc) => cc,
            CombustionOutput::Dropout(d) => return dropout::<Self>(d, events),
        };
        let c = &cc.figures;
        let s = self.settings();
        let figures = physid_apps::per_cycle::figure_columns(
            "",
            &s.heat.mfb,
            s.knock.is_some(),
            s.brake.is_some(),
            s.friction.is_some(),
        )
        .into_iter()
        .filter(|col| col.name != "t" && col.name != "cycle")
        .map(|col| (crate::event::Name::from(col.name), (col.value)(c)))
        .collect();
        events.put(Event::Combustion {
            cycle: c.cycle,
            t_s: c.t_start_s,
            figures,
            notes: c.notes.clone(),
            curve: cc.curve.as_ref().map(|k| crate::event::Curve {
                step_deg: k.step_deg,
                channels: [("p".into(), k.p.clone()), ("hrr".into(), k.hrr.clone())]
                    .into_iter()
                    .collect(),
            }),
        });
    }
}

impl Tell for TwinStage {
    const NAME: &'static str = "twin";
    const STOPPED: &'static str = r#"the twin stopped (restart: {"cmd":"restart","stage":"twin"})"#;
    const FLAG: &'static str = "--twin";
    type Told = ();

    fn start(cfg: &LiveConfig, rate_hz: f64) -> Result<Option<Self>, LiveError> {
        let Some(t) = &cfg.twin else {
            return Ok(None);
        };
        let mut t = t.clone();
        t.theta_tdc = cfg.theta_tdc;
        Ok(Some(TwinStage::new(t, rate_hz)?))
    }

    /// Each window's estimates and residuals; an alarm naming the parameter that moved.
    fn tell(&self, _: &mut (), o: &TwinOut, _at: At, events: &mut dyn Sink<Event>) {
        events.put(match o {
            TwinOut::Window(w) => Event::Twin {
                t_s: w.t_s,
                params: w.params.iter().cloned().collect(),
                std_err: w
                    .params
                    .iter()
                    .zip(&w.std_err)
                    .map(|((p, _), s)| (p.clone(), *s))
                    .collect(),
                frozen: w.frozen.clone(),
                residual: w.residual.iter().cloned().collect(),
                measured: w.measured.iter().cloned().collect(),
                twin: w.twin.iter().cloned().collect(),
            },
            TwinOut::Alarm(a) => Event::Alarm {
                app: App::Twin,
                param: a.param.clone(),
                t_s: a.t_s,
                t_start_s: a.t_start_s,
                relative_error: -a.change,
                change: a.change,
            },
        });
    }
}
