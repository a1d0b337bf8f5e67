//! The twin and its copies stepped together, the snapshots a jump is replayed from, and the
//! jump's replay that names the parameter behind a residual.

use crate::error::AppError;
use physid_sim::run::Run;

/// The twin and its copies, stepped together (rebuilt from the stream after a restore: a run
/// of the cell is not checkpointed).
#[derive(Clone)]
pub(super) struct Runs {
    /// The twin, then one copy per adapted parameter.
    pub(super) runs: Vec<Run>,
    /// The outputs not yet compared: `[run][channel]`.
    pub(super) out: Vec<Vec<Vec<f64>>>,
    /// The twin's engine angle over the same samples [rad].
    pub(super) theta: Vec<f64>,
    /// Stream samples the runs have been stepped through, and the twin's outputs placed in
    /// `out` (both counted from the stream's start).
    pub(super) stepped: usize,
    pub(super) placed: usize,
    /// The twin as it was at the start of the previous window and of this one and at each
    /// quarter of them: where a jump of a parameter is replayed from ([`jump_pick`]).
    pub(super) snaps: Vec<Snap>,
    /// What was done to the twin at the windows' ends since the oldest snapshot.
    pub(super) boundaries: Vec<Boundary>,
    /// The stream's inputs since the oldest snapshot, `(τ, rpm, throttle)` per sample, and
    /// the samples stepped before the first of them.
    pub(super) inputs: Vec<(f64, f64, f64)>,
    pub(super) inputs_from: usize,
    /// Samples stepped at the present window's start.
    pub(super) window_start: usize,
    /// The previous window's residual and twin outputs (a jump's replay is fitted over both).
    pub(super) prev: Option<PrevWindow>,
}

/// A window's first sample's index, its residual and the twin's outputs: `[channel][sample]`.
#[derive(Clone)]
pub(super) struct PrevWindow {
    pub(super) first: usize,
    pub(super) r: Vec<Vec<f64>>,
    pub(super) y: Vec<Vec<f64>>,
}

/// The twin at one instant: the stream samples it had been stepped through (`stepped`), the
/// index its next output would have (`placed`) and its adapted parameters' values then.
#[derive(Clone)]
pub(super) struct Snap {
    pub(super) stepped: usize,
    pub(super) placed: usize,
    pub(super) values: Vec<f64>,
    pub(super) run: Run,
}

/// A window's end: the samples stepped, the turn onto the stream's crank angle [rad] and the
/// adapted parameters' values after it.
#[derive(Clone)]
pub(super) struct Boundary {
    pub(super) stepped: usize,
    pub(super) turn: f64,
    pub(super) values: Vec<f64>,
}

/// The epoch's copies of the twin `runs.runs[0]` in `runs.runs[1..]`, the `j`-th with parameter
/// `adapt[j]` at `values[j]·(1 + step)`, their output buffers the twin's (the few samples it has
/// placed beyond the window).
pub(super) fn fork(
    runs: &mut Runs,
    adapt: &[String],
    values: &[f64],
    step: f64,
) -> Result<(), AppError> {
    let (twin, copies) = runs.runs.split_at_mut(1);
    let (lead, out) = runs.out.split_at_mut(1);
    for (j, (path, v)) in adapt.iter().zip(values).enumerate() {
        let mut c = twin[0].clone();
        c.set_live_parameter(path, v * (1.0 + step))?;
        copies[j] = c;
        out[j].clone_from(&lead[0]);
    }
    Ok(())
}

/// The parameter whose jump alone explains most — at least half — of the window's residual
/// `r` (each channel weighted by `1/σ²`, `rr = rᵀWr`), at the best of the instants the twin was
/// snapshotted at in the window: its index and relative change `gⱼ/Fⱼⱼ`, `gⱼ = Σ sⱼ·W·r`,
/// `Fⱼⱼ = Σ sⱼ·W·sⱼ`, `sⱼ` the difference between the twin's outputs `twin_out` and a copy's
/// replayed from the snapshot with parameter `j` `1 + step` times larger (the samples before
/// the snapshot: nil). `first` is the window's first sample's index. Run only in an
/// excursion's first windows: the replays (quarter windows × parameters) allocate.
#[allow(clippy::too_many_arguments)]
pub(super) fn jump_pick(
    runs: &Runs,
    channels: &[String],
    r: &[Vec<f64>],
    sigma: &[f64],
    first: usize,
    adapt: &[String],
    step: f64,
) -> Result<Option<(usize, f64)>, AppError> {
    // Over the previous window and this one: a jump placed too early is charged with the
    // response it predicts where the residual had none.
    let weighted = |rs: &[Vec<f64>]| -> f64 {
        rs.iter()
            .zip(sigma)
            .map(|(rc, s)| rc.iter().map(|x| x * x).sum::<f64>() / (s * s))
            .sum()
    };
    let rr = runs.prev.as_ref().map_or(0.0, |p| weighted(&p.r)) + weighted(r);
    let mut best: Option<(f64, usize, f64)> = None;
    for snap in &runs.snaps {
        let from = snap.stepped - runs.inputs_from;
        for (j, path) in adapt.iter().enumerate() {
            let mut copy = snap.run.clone();
            copy.set_live_parameter(path, snap.values[j] * (1.0 + step))?;
            let mut at = runs
                .boundaries
                .iter()
                .filter(|b| b.stepped > snap.stepped)
                .peekable();
            for (i, &(tau, rpm, throttle)) in runs.inputs[from..].iter().enumerate() {
                copy.hold_inputs(rpm, throttle);
                copy.step_until(tau)?;
                // What was done to the twin at a window's end, done to the copy (its jump kept).
                if let Some(b) = at.next_if(|b| b.stepped == snap.stepped + i + 1) {
                    if b.turn != 0.0 {
                        copy.turn(b.turn);
                    }
                    for (q, (p, v)) in adapt.iter().zip(&b.values).enumerate() {
                        let v = if q == j { v * (1.0 + step) } else { *v };
                        copy.set_live_parameter(p, v)?;
                    }
                }
            }
            let rec = copy.drain()?;
            let (mut g, mut f) = (0.0, 0.0);
            for (c, name) in channels.iter().enumerate() {
                let y = rec.values(name)?;
                let w2 = 1.0 / (sigma[c] * sigma[c]);
                // The previous window's samples, then this one's: (index, residual, twin).
                let prev = runs.prev.iter().flat_map(|p| {
                    (0..p.r[c].len()).map(move |k| (p.first + k, p.r[c][k], p.y[c][k]))
                });
                let this = (0..r[c].len()).map(|k| (first + k, r[c][k], runs.out[0][c][k]));
                for (at, rk, yk0) in prev.chain(this) {
                    let Some(i) = at.checked_sub(snap.placed) else {
                        continue;
                    };
                    let Some(yk) = y.get(i) else { break };
                    let s = (yk - yk0) / step;
                    g += w2 * s * rk;
                    f += w2 * s * s;
                }
            }
            let explained = g * g / (f * rr).max(f64::MIN_POSITIVE);
            if best.is_none_or(|b| explained > b.0) {
                best = Some((explained, j, g / f.max(f64::MIN_POSITIVE)));
            }
        }
    }
    Ok(best.filter(|b| b.0 >= 0.5).map(|b| (b.1, b.2)))
}
