//! The file verb: a recording (in memory, or read a chunk at a time) through the stage
//! ([`friction_fit`], [`friction_fit_stream`], [`friction_fit_cycles`]).

use super::*;

/// Run the characterisation on a motored recording: the recording streamed through a
/// [`FrictionStage`] that chooses its coefficients on all the steady cycles (as the thesis's
/// off-line characterisation does).
pub fn friction_fit(rec: &Recording, cfg: &FrictionFitConfig) -> Result<FrictionFit, AppError> {
    let mut stage = FrictionStage::new(cfg.clone(), None)?;
    let mut out = Vec::new();
    let before = feed(&mut stage, rec, cfg, &mut out)?;
    finish(stage, out, before)
}

/// [`friction_fit`] on a time-basis recording read a chunk at a time (a file, as it comes):
/// memory does not grow with its length — the stage keeps a few numbers per cycle.
pub fn friction_fit_stream<I, E>(
    chunks: I,
    cfg: &FrictionFitConfig,
) -> Result<FrictionFit, AppError>
where
    I: IntoIterator<Item = Result<Recording, E>>,
    AppError: From<E>,
{
    let mut stage = FrictionStage::new(cfg.clone(), None)?;
    let mut out = Vec::new();
    feed_stream(&mut stage, chunks, &mut out)?;
    finish(stage, out, Vec::new())
}

/// [`friction_fit`] on a crank-angle recording (with `cycle`) read a chunk at a time: the
/// cycle means are summed as the chunks come, a few numbers per cycle, so memory does not grow
/// with the samples; the coefficients are then chosen on all the steady cycles, as for the
/// whole recording (the same numbers bit for bit).
pub fn friction_fit_cycles<I, E>(
    chunks: I,
    cfg: &FrictionFitConfig,
) -> Result<FrictionFit, AppError>
where
    I: IntoIterator<Item = Result<Recording, E>>,
    AppError: From<E>,
{
    let mut cycles = FrictionCycles::new(cfg);
    for chunk in chunks {
        cycles.push(&chunk?)?;
    }
    cycles.fit()
}

/// [`friction_fit_cycles`] for chunks that are pushed (a crank-angle recording made as a
/// time-basis file is read): the cycle means summed as they come, the fit at the end.
pub struct FrictionCycles {
    runs: CrankRuns,
    cfg: FrictionFitConfig,
}

impl FrictionCycles {
    /// The fit `cfg`, no cycle yet.
    pub fn new(cfg: &FrictionFitConfig) -> Self {
        Self {
            runs: CrankRuns::default(),
            cfg: cfg.clone(),
        }
    }

    /// The next chunk of the crank-angle recording (with `cycle`).
    pub fn push(&mut self, chunk: &Recording) -> Result<(), AppError> {
        self.runs.push(chunk, &self.cfg)
    }

    /// The coefficients, chosen on all the steady cycles.
    pub fn fit(self) -> Result<FrictionFit, AppError> {
        let mut stage = FrictionStage::new(self.cfg.clone(), None)?;
        let mut out = Vec::new();
        let (cycles, dropouts) = self.runs.finish(self.cfg.source.channel().1)?;
        for c in cycles {
            match c {
                Some(c) => stage.push_cycle(c, &mut out)?,
                None => stage.push_gap(&mut out)?,
            }
        }
        finish(stage, out, dropouts)
    }
}

/// The channels [`friction_fit_cycles`] reads from a crank-angle recording: those it needs,
/// then those it takes when they are there (ambient pressure when `p_atm_kpa` is set, the
/// simulated truth).
pub fn cycle_channels(cfg: &FrictionFitConfig) -> (Vec<&'static str>, Vec<&'static str>) {
    let mut needed = vec![
        "t",
        "cycle",
        "omega_en",
        "p_int",
        "T_oil",
        cfg.source.channel().0,
    ];
    let mut optional = Vec::new();
    if cfg.p_atm_kpa.is_none() {
        needed.push("p_atm");
    } else {
        optional.push("p_atm");
    }
    optional.extend(TRUTH_CHANNELS);
    (needed, optional)
}

/// The file verb's end: the result, with every cycle the stage put out and the dropouts it
/// left out (`before`: those of the cycle means, which the stage did not see).
fn finish(
    mut stage: FrictionStage,
    mut out: Vec<FrictionOutput>,
    before: Vec<Dropout>,
) -> Result<FrictionFit, AppError> {
    let mut fit = stage.fit(&mut out)?;
    fit.dropouts = before;
    for o in out {
        match o {
            FrictionOutput::Cycle(c) => fit.cycles.push(c),
            FrictionOutput::Dropout(d) => fit.dropouts.push(d),
            FrictionOutput::Selected { .. } => {}
        }
    }
    Ok(fit)
}

/// The channels the characterisation reads from a time-basis recording (physid names): those
/// it needs, then those it takes when they are there (ambient pressure when `p_atm_kpa` is set,
/// the simulated truth, the TDC marker).
pub fn sample_channels(cfg: &FrictionFitConfig) -> (Vec<&'static str>, Vec<&'static str>) {
    let mut needed = vec![
        "t",
        "theta_en",
        "omega_en",
        "p_int",
        "T_oil",
        cfg.source.channel().0,
    ];
    let mut optional = vec![TDC_MARKER];
    if cfg.p_atm_kpa.is_none() {
        needed.push("p_atm");
    } else {
        optional.push("p_atm");
    }
    optional.extend(TRUTH_CHANNELS);
    (needed, optional)
}
