//! A recording read on a crank-angle basis — what `cycles`, `compression fit`, `convert
//! --crank-angle` and the fits read — from the command line's flags: the plan itself is the
//! library's ([`physid_apps::angle_input`]); here the flags become its options and what it
//! finds is told on stderr, with a progress bar over each read and the file in the provenance.

use super::{CrankArgs, InputArgs};
use crate::cmd::convert::{tell_findings, tell_wheel};
use crate::cmd::inspect::{tell_tdc_from, AngleArgs};
use crate::progress::Reading;
use miette::Result;
use physid_apps::acquisition::DecodedAngle;
use physid_apps::angle_input::{AngleInput, InputObserver, Watched};
use physid_apps::compression::TdcFromPressure;
use physid_io::ChunkReader;
use std::path::Path;
use std::sync::Arc;

/// What the command line tells while a file is read.
pub struct Told {
    /// `--map`, recorded in the provenance with the file.
    map: Vec<String>,
}

impl Told {
    /// For a file read with `input`'s flags.
    fn new(input: &InputArgs) -> Self {
        Self {
            map: input.map.clone(),
        }
    }
}

impl InputObserver for Told {
    fn opened(&self, path: &Path) {
        crate::provenance::record_input(path, &self.map);
    }

    fn watch<'a>(&self, reader: &'a mut ChunkReader, path: &Path) -> Watched<'a> {
        Box::new(Reading::new(reader, path))
    }

    fn read_warning(&self, path: &Path, warning: &str) {
        eprintln!("warning: {}: {warning}", path.display());
    }

    fn decoded(&self, path: &Path, decoded: &DecodedAngle) {
        tell_wheel(path, decoded);
    }

    fn findings(&self, path: &Path, findings: &[physid_signal::integrity::Finding]) {
        tell_findings(path, findings);
    }

    fn tdc_placed(&self, path: &Path, channel: &str, found: &TdcFromPressure) {
        tell_tdc_from(path, channel, found);
    }
}

/// An error of reading `path` on a crank-angle basis: the file's own I/O error with its cause,
/// as opening a file says it in every verb ([`super::InputArgs::open_all`]);
/// anything else as [`super::app_error`] says it.
pub fn read_error(path: &Path) -> impl Fn(physid_apps::error::AppError) -> miette::Report + '_ {
    move |e| match e {
        physid_apps::error::AppError::Io(e) => miette::Report::from_err(e),
        e => super::app_error(path)(e),
    }
}

/// The file `path` read with `input`'s flags at one sample per crank degree, its angle found
/// as `angle` says (the defaults: the thesis's encoders and marker; `--tdc-from` with `crank`'s
/// lengths), what it finds told on stderr ([`Told`]).
pub fn crank_input(
    input: &InputArgs,
    path: &Path,
    angle: &AngleArgs,
    crank: &CrankArgs,
) -> Result<AngleInput> {
    let told = Arc::new(Told::new(input));
    let mut plan = AngleInput::new(path, input.options(None)?, angle.options()?, told);
    if let Some(channel) = &angle.wheel.tdc_from {
        // A file that cannot be opened is named before the lengths it would need.
        plan.header().map_err(read_error(path))?;
        plan.crank = Some(crank.lengths(&format!("--tdc-from {channel}"))?);
        plan.compression_ratio = crank.compression_ratio;
        plan.tdc_from = Some(channel.clone());
        plan.hold_bytes = super::hold_bytes()?;
    }
    Ok(plan)
}
