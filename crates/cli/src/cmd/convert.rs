//! `physid convert`: between formats (by extension) and bases (time ↔ one sample per crank
//! degree).

use super::{CrankArgs, InputArgs};
use crate::cmd::crank_input::crank_input;
use crate::cmd::inspect::AngleArgs;
use crate::out::outln;
use miette::{miette, IntoDiagnostic, Result};
use physid_apps::acquisition::{DecodedAngle, TimeBasisStream};
use physid_apps::error::AppError;
use physid_io::{MdfCompression, WriteOptions};
use std::path::PathBuf;

/// Arguments of `physid convert`.
#[derive(clap::Args)]
pub struct Args {
    /// Input recording (CSV, Parquet or MDF4).
    pub input: PathBuf,
    /// Output file; its extension picks the format (.csv, .parquet, .mf4).
    pub output: PathBuf,
    #[command(flatten)]
    pub read: InputArgs,
    /// Only these channels (after --map).
    #[arg(long, value_delimiter = ',')]
    pub channels: Vec<String>,
    /// Resample to one sample every --step-deg crank degrees from the first TDC marker (engine
    /// angle from `theta_en`, the engine encoder's counts, or a trigger wheel's signal with
    /// --wheel).
    #[arg(long, conflicts_with = "time_basis")]
    pub crank_angle: bool,
    /// Crank-angle step [deg] of --crank-angle [default: 1].
    #[arg(long)]
    pub step_deg: Option<f64>,
    /// Resample a crank-angle recording to a uniform time basis at this rate [Hz].
    #[arg(long, value_name = "HZ")]
    pub time_basis: Option<f64>,
    #[command(flatten)]
    pub angle: AngleArgs,
    #[command(flatten)]
    pub crank: CrankArgs,
    /// MDF4 output compression: none, deflate or transposed.
    #[arg(long, default_value = "none")]
    pub compression: String,
}

/// Run `physid convert`.
pub fn run(args: &Args) -> Result<()> {
    let compression = match args.compression.as_str() {
        "none" => MdfCompression::None,
        "deflate" => MdfCompression::Deflate,
        "transposed" => MdfCompression::TransposedDeflate,
        c => {
            return Err(miette!(
                "--compression '{c}': expected none, deflate or transposed"
            ))
        }
    };
    // The crank's lengths serve --tdc-from alone.
    let length = [
        (args.crank.stroke.is_some(), "--stroke"),
        (args.crank.rod.is_some(), "--rod"),
        (
            args.crank.compression_ratio.is_some(),
            "--compression-ratio",
        ),
    ]
    .into_iter()
    .find_map(|(given, flag)| given.then_some(flag));
    let crank_only = (args.step_deg.is_some().then_some("--step-deg"))
        .or_else(|| args.angle.crank_angle_flag())
        .or(length);
    if let (false, Some(flag)) = (args.crank_angle, crank_only) {
        return Err(miette!(
            "{flag} is for a reading on a crank-angle basis: add --crank-angle (without it, convert changes the format only, or the basis to time with --time-basis)"
        ));
    }
    if let (None, Some(flag)) = (&args.angle.wheel.tdc_from, length) {
        return Err(miette!(
            "{flag} is for placing the TDC from a motored pressure (--tdc-from CHANNEL): without it, it would be ignored"
        ));
    }
    let write = WriteOptions {
        mdf_compression: compression,
    };
    let at = super::app_error(&args.input);
    let chosen: Vec<&str> = args.channels.iter().map(String::as_str).collect();
    let chosen = (!chosen.is_empty()).then_some(chosen.as_slice());
    let sink = if args.crank_angle {
        let header = args.read.open_all(&args.input)?.header().clone();
        if header.basis == physid_core::Basis::CrankAngle {
            return Err(miette!(
                "{}: the recording is already on a crank-angle basis",
                args.input.display()
            ));
        }
        let mut input = crank_input(&args.read, &args.input, &args.angle, &args.crank)?;
        input.step_deg = args.step_deg.unwrap_or(1.0);
        input
            .read(
                chosen,
                |h| Sink::create(&args.output, h, &args.channels, &write),
                |s, chunk| s.append(chunk),
            )
            .map_err(&at)?
            .0
    } else if let Some(rate) = args.time_basis {
        let mut reader = match chosen {
            Some(c) => {
                let mut names = vec!["t"];
                names.extend(c.iter().filter(|n| **n != "t"));
                args.read.open(&args.input, &names, &[])?
            }
            None => args.read.open_all(&args.input)?,
        };
        let mut to_time = TimeBasisStream::new(reader.header(), rate).map_err(|e| at(e.into()))?;
        let header = to_time.header().map_err(|e| at(e.into()))?;
        let mut sink = Sink::create(&args.output, &header, &args.channels, &write).map_err(&at)?;
        for chunk in crate::progress::Reading::new(&mut reader, &args.input) {
            let chunk = chunk.into_diagnostic()?;
            let out = to_time.push(&chunk).map_err(|e| at(e.into()))?;
            sink.append(&out).map_err(&at)?;
        }
        let out = to_time.finish().map_err(|e| at(e.into()))?;
        sink.append(&out).map_err(&at)?;
        super::warn_read(&reader, &args.input);
        sink
    } else {
        // Between formats: only the channels kept.
        let header = args.read.open_all(&args.input)?.header().clone();
        let mut reader = match selection(&header, &args.channels) {
            Some(names) => {
                let names: Vec<&str> = names.iter().map(String::as_str).collect();
                args.read.open(&args.input, &names, &[])?
            }
            None => args.read.open_all(&args.input)?,
        };
        let mut sink =
            Sink::create(&args.output, reader.header(), &args.channels, &write).map_err(&at)?;
        for chunk in crate::progress::Reading::new(&mut reader, &args.input) {
            sink.append(&chunk.into_diagnostic()?).map_err(&at)?;
        }
        super::warn_read(&reader, &args.input);
        sink
    };
    sink.close().map_err(&at)
}

/// Where the converted recording goes: a chunk at a time, memory flat however long the file
/// (an MDF4 file written compressed too: block by block); `--channels` picked from each chunk.
struct Sink {
    /// The file being written (`None` once an interruption has closed it).
    writer: Option<physid_io::ChunkWriter>,
    names: Vec<String>,
    path: PathBuf,
    header: physid_core::Recording,
    samples: usize,
    /// Set by SIGINT or SIGTERM: the file is closed (readable) and kept, and the conversion
    /// ends with an error saying how much it holds.
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl Sink {
    fn create(
        path: &std::path::Path,
        header: &physid_core::Recording,
        channels: &[String],
        opts: &WriteOptions,
    ) -> Result<Self, AppError> {
        let names = selection(header, channels)
            .unwrap_or_else(|| header.names().iter().map(|n| n.to_string()).collect());
        let header = pick(header, &names)?;
        let stop = super::stop_on_signal().map_err(|e| AppError::Invalid(e.to_string()))?;
        Ok(Sink {
            writer: Some(physid_io::ChunkWriter::create(path, &header, opts)?),
            names,
            path: path.to_path_buf(),
            header,
            samples: 0,
            stop,
        })
    }

    fn append(&mut self, chunk: &physid_core::Recording) -> Result<(), AppError> {
        let Some(w) = self.writer.as_mut() else {
            return Err(self.interrupted());
        };
        w.append(&pick(chunk, &self.names)?)?;
        self.samples += chunk.len();
        if self.stop.load(std::sync::atomic::Ordering::Relaxed) {
            if let Some(w) = self.writer.take() {
                w.close()?;
            }
            return Err(self.interrupted());
        }
        Ok(())
    }

    /// What an interruption left.
    fn interrupted(&self) -> AppError {
        AppError::Invalid(format!(
            "interrupted by a signal: {} holds the first {} samples, closed and readable",
            self.path.display(),
            self.samples
        ))
    }

    fn close(mut self) -> Result<(), AppError> {
        let Some(w) = self.writer.take() else {
            return Err(self.interrupted());
        };
        if self.samples == 0 && self.header.basis == physid_core::Basis::CrankAngle {
            // An empty crank-angle file would only fail later, less clearly.
            w.discard();
            return Err(AppError::Invalid(format!(
                "no sample on a crank-angle basis, so {} is not written: {}",
                self.path.display(),
                physid_apps::angle_input::NO_CRANK_SAMPLE
            )));
        }
        w.close()?;
        wrote(&self.path, &self.header, self.samples);
        Ok(())
    }
}

/// The channels `names` of `rec`, in that order.
fn pick(
    rec: &physid_core::Recording,
    names: &[String],
) -> Result<physid_core::Recording, AppError> {
    let mut out = physid_core::Recording::new(rec.basis);
    out.meta = rec.meta.clone();
    for n in names {
        out.push(rec.channel(n)?.clone())?;
    }
    Ok(out)
}

/// What decoding a raw angle sensor found, on stderr: the sensor, the speed range, how the
/// firing TDC was placed, and every finding with its sample.
pub fn tell_wheel(input: &std::path::Path, d: &DecodedAngle) {
    eprintln!("{}: {}; {}", input.display(), d.summary, d.phase);
    tell_findings(input, &d.findings);
}

/// What decoding a raw angle sensor found wrong with the data, on stderr: each finding with
/// its sample.
pub fn tell_findings(input: &std::path::Path, findings: &[physid_signal::integrity::Finding]) {
    for f in findings {
        eprintln!("{}: sample {}: {}", input.display(), f.index, f.detail);
    }
}

/// The channels `--channels` keeps of `rec`'s: the basis channels it has first (they come
/// along), then those named; `None` without `--channels`.
fn selection(rec: &physid_core::Recording, channels: &[String]) -> Option<Vec<String>> {
    if channels.is_empty() {
        return None;
    }
    let basis_channels = ["t", "theta", "cycle", "crank_deg"];
    Some(
        basis_channels
            .iter()
            .filter(|n| rec.channel(n).is_ok() && !channels.iter().any(|c| c == *n))
            .map(|s| s.to_string())
            .chain(channels.iter().cloned())
            .collect(),
    )
}

fn wrote(path: &std::path::Path, rec: &physid_core::Recording, samples: usize) {
    outln!(
        "wrote {} ({} channels × {} samples, {} basis)",
        path.display(),
        rec.channels().len(),
        samples,
        match rec.basis {
            physid_core::Basis::Time => "time",
            physid_core::Basis::CrankAngle => "crank-angle",
        }
    );
}
