//! The windows gone over in passes ([`TdcEvents`]): held within a limit, or gathered again from
//! a source read again (a [`Reopen`] of [`Recordings`]: a file read again, a recording in
//! memory).

use super::*;

/// One TDC's window as a pass over [`TdcEvents`] shows it.
#[derive(Debug, Clone, Copy)]
pub struct Window<'w> {
    /// The cycle that starts at this TDC.
    pub cycle: i64,
    /// The time at TDC [s].
    pub t_s: f64,
    /// Mean speed over the window [rpm].
    pub rpm: f64,
    /// Angles [deg ATDC] …
    pub atdc: &'w [f64],
    /// … and the pressure there.
    pub p: &'w [f64],
}

/// What the first pass over [`TdcEvents`] found.
#[derive(Debug, Clone, Default)]
pub struct FirstPass {
    /// The pressure channel's unit.
    pub unit: String,
    /// What was left out, and a unit that looks wrong.
    pub notes: Vec<String>,
    /// How many TDCs' windows …
    pub events: usize,
    /// … and their samples.
    pub rows: usize,
}

/// The TDCs' windows, held in one pooled buffer: the angle grid once, the pressures one
/// window after another.
#[derive(Debug, Default)]
pub(super) struct HeldWindows {
    atdc: Vec<f64>,
    at: Vec<(i64, f64, f64)>,
    p: Vec<f64>,
}

#[derive(Debug)]
pub(super) enum Held {
    NotYet,
    Whole(HeldWindows),
    TooLarge,
}

/// The firing TDCs' windows of a crank-angle recording ([`EventCollector`]) gone over in
/// passes — the fit over all of them is a pass per Gauss–Newton iteration: held after the first
/// pass when they take at most a limit (8 bytes a sample, the angles once), else gathered again
/// from the recording on every pass — so that memory is at most the limit, or a reader's
/// chunk, whatever the recording's length. Each window is one chunk of its [`Rows`] (the
/// motored model's input `atdc`, the pressure as the output).
pub struct TdcEvents<'a> {
    source: &'a dyn Reopen<Recordings, AppError>,
    channel: String,
    window: (f64, f64),
    hold_bytes: usize,
    held: std::cell::RefCell<Held>,
    first: std::cell::RefCell<Option<FirstPass>>,
}

/// One pass's handling of the windows as they are gathered.
pub(super) struct Gathering<'v, E> {
    visit: &'v mut dyn FnMut(&Window) -> Result<(), E>,
    keep: Option<HeldWindows>,
    hold_bytes: usize,
    events: usize,
    rows: usize,
    /// Windows left out as fired ([`fired`]).
    fired: usize,
    failed: Option<E>,
}

impl<E> Gathering<'_, E> {
    pub(super) fn take(&mut self, e: TdcEvent) -> Result<(), AppError> {
        // The motored model fits motored cycles: a fired one is left out (and counted).
        if fired(&e.atdc, &e.p, 0.0) == Some(true) {
            self.fired += 1;
            return Ok(());
        }
        self.events += 1;
        self.rows += e.p.len();
        let w = Window {
            cycle: e.cycle,
            t_s: e.t_s,
            rpm: e.rpm,
            atdc: &e.atdc,
            p: &e.p,
        };
        if let Err(err) = (self.visit)(&w) {
            self.failed = Some(err);
            return Err(AppError::Invalid("the pass was stopped".into()));
        }
        if let Some(k) = &mut self.keep {
            let bytes = (k.p.len() + e.p.len() + e.atdc.len()) * 8 + (k.at.len() + 1) * 24;
            if bytes > self.hold_bytes {
                self.keep = None;
            } else {
                if k.atdc.is_empty() {
                    k.atdc = e.atdc;
                }
                k.at.push((e.cycle, e.t_s, e.rpm));
                k.p.extend_from_slice(&e.p);
            }
        }
        Ok(())
    }
}

impl<'a> TdcEvents<'a> {
    /// The windows `window` [deg ATDC] of `channel` around the firing TDCs of `source`, held
    /// after the first pass if they take at most `hold_bytes`.
    pub fn new(
        source: &'a dyn Reopen<Recordings, AppError>,
        channel: &str,
        window: (f64, f64),
        hold_bytes: usize,
    ) -> Self {
        Self {
            source,
            channel: channel.to_string(),
            window,
            hold_bytes,
            held: std::cell::RefCell::new(Held::NotYet),
            first: std::cell::RefCell::new(None),
        }
    }

    /// What the first pass found (making it now if none was made).
    pub fn first_pass(&self) -> Result<FirstPass, AppError> {
        if self.first.borrow().is_none() {
            self.each::<AppError>(&mut |_| Ok(()))?;
        }
        Ok(self.first.borrow().clone().unwrap_or_default())
    }

    /// Whether the windows are held (after a first pass, within the limit).
    pub fn held(&self) -> bool {
        matches!(*self.held.borrow(), Held::Whole(_))
    }

    /// Go over the windows once, in order: `visit` each. An error of `visit` ends the pass
    /// and is returned.
    pub fn each<E: From<AppError>>(
        &self,
        visit: &mut dyn FnMut(&Window) -> Result<(), E>,
    ) -> Result<(), E> {
        if let Held::Whole(h) = &*self.held.borrow() {
            let n = h.atdc.len();
            for (k, &(cycle, t_s, rpm)) in h.at.iter().enumerate() {
                visit(&Window {
                    cycle,
                    t_s,
                    rpm,
                    atdc: &h.atdc,
                    p: &h.p[k * n..(k + 1) * n],
                })?;
            }
            return Ok(());
        }
        let first = matches!(*self.held.borrow(), Held::NotYet);
        let mut g = Gathering {
            visit,
            keep: first.then(HeldWindows::default),
            hold_bytes: self.hold_bytes,
            events: 0,
            rows: 0,
            fired: 0,
            failed: None,
        };
        let mut collector: Option<EventCollector> = None;
        let mut unit: Option<(String, crate::pressure::UnitCheck)> = None;
        let mut gather = || -> Result<Vec<String>, AppError> {
            self.source.pass(&mut |chunk| {
                let c = match &mut collector {
                    Some(c) => c,
                    None => {
                        if first {
                            unit = Some((
                                chunk.channel(&self.channel)?.unit.clone(),
                                crate::pressure::UnitCheck::new(chunk, &self.channel)?,
                            ));
                        }
                        collector.insert(EventCollector::new(chunk, &self.channel, self.window)?)
                    }
                };
                if let Some((_, check)) = &mut unit {
                    check.push(chunk.values(&self.channel)?);
                }
                c.push(chunk)?;
                c.drain().try_for_each(|e| g.take(e))
            })?;
            let Some(c) = collector.take() else {
                return Err(AppError::Invalid("the recording has no channels".into()));
            };
            let (rest, mut notes) = c.finish()?;
            rest.into_iter().try_for_each(|e| g.take(e))?;
            if let Some((_, check)) = &unit {
                if let Some(n) = check.finish(false)? {
                    notes.insert(0, n);
                }
            }
            Ok(notes)
        };
        let notes = match gather() {
            Ok(notes) => notes,
            Err(e) => return Err(g.failed.take().unwrap_or_else(|| e.into())),
        };
        let mut notes = notes;
        if g.fired > 0 {
            notes.push(format!(
                "{} fired TDC window(s) left out (the pressure 60° … 100° after TDC above that as far before by more than {:.0} %): the motored model fits the {} motored one(s)",
                g.fired,
                (FIRED_RATIO - 1.0) * 100.0,
                g.events
            ));
        }
        if first {
            *self.first.borrow_mut() = Some(FirstPass {
                unit: unit.map(|(u, _)| u).unwrap_or_default(),
                notes,
                events: g.events,
                rows: g.rows,
            });
            *self.held.borrow_mut() = g.keep.map_or(Held::TooLarge, Held::Whole);
        } else if let Some(f) = &*self.first.borrow() {
            if (f.events, f.rows) != (g.events, g.rows) {
                return Err(AppError::Invalid(format!(
                    "the recording changed between passes: {} TDC window(s) of {} samples, then {} of {}",
                    f.events, f.rows, g.events, g.rows
                ))
                .into());
            }
        }
        Ok(())
    }
}

impl Rows for TdcEvents<'_> {}

impl Reopen<DataRows, IdentError> for TdcEvents<'_> {
    fn pass(
        &self,
        visit: &mut dyn for<'c> FnMut(&'c Data<'c>) -> Result<(), IdentError>,
    ) -> Result<(), IdentError> {
        self.each(&mut |w| {
            visit(&Data {
                inputs: vec![w.atdc],
                y: Some(w.p),
            })
        })
    }
}
