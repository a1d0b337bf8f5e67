//! `physid convert`: between formats (by extension) and bases (time ↔ one sample per crank
//! degree).

use super::{CrankArgs, InputArgs};
use crate::cmd::inspect::AngleArgs;
use crate::out::outln;
use miette::{miette, IntoDiagnostic, Result};
use physid_apps::acquisition::{to_time_basis, DecodedAngle};
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
    /// Crank-angle step [deg].
    #[arg(long, default_value_t = 1.0)]
    pub step_deg: f64,
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
    // Between formats only: a chunk at a time, memory flat however long the file (an MDF4
    // file compressed is written whole).
    let resample = args.crank_angle || args.time_basis.is_some();
    let compressed = physid_io::Format::from_extension(&args.output)
        == Some(physid_io::Format::Mdf4)
        && compression != MdfCompression::None;
    if !resample && !compressed {
        return stream(args);
    }
    let opts = args.angle.options()?;
    if opts.sensor.is_some() && !args.crank_angle {
        return Err(miette!(
            "--wheel and --quadrature decode the engine angle for --crank-angle: add --crank-angle"
        ));
    }
    let mut rec = args.read.read(&args.input, None)?;
    if args.crank_angle {
        let (out, decoded) =
            args.angle
                .to_crank_angle(&rec, &args.crank, args.step_deg, &args.input, false)?;
        if let Some(d) = decoded {
            tell_wheel(&args.input, &d);
        }
        rec = out;
    }
    if let Some(rate) = args.time_basis {
        rec = to_time_basis(&rec, rate).map_err(|e| miette!("{}: {e}", args.input.display()))?;
    }
    if let Some(names) = selection(&rec, &args.channels) {
        let mut keep = physid_core::Recording::new(rec.basis);
        keep.meta = rec.meta.clone();
        for name in names {
            let ch = rec
                .channel(&name)
                .map_err(|e| miette!("{}: {e}", args.input.display()))?;
            keep.push(ch.clone()).into_diagnostic()?;
        }
        rec = keep;
    }
    physid_io::write(
        &args.output,
        &rec,
        &WriteOptions {
            mdf_compression: compression,
        },
    )
    .into_diagnostic()?;
    wrote(&args.output, &rec, rec.len());
    Ok(())
}

/// What decoding a raw angle sensor found, on stderr: the sensor, the speed range, how the
/// firing TDC was placed, and every finding with its sample.
pub fn tell_wheel(input: &std::path::Path, d: &DecodedAngle) {
    eprintln!("{}: {}; {}", input.display(), d.summary, d.phase);
    for f in &d.findings {
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

/// A conversion between formats, read and written a chunk at a time.
fn stream(args: &Args) -> Result<()> {
    let header = args.read.open_all(&args.input)?.header().clone();
    let mut reader = match selection(&header, &args.channels) {
        Some(names) => {
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            args.read.open(&args.input, &names, &[])?
        }
        None => args.read.open_all(&args.input)?,
    };
    let mut w =
        physid_io::ChunkWriter::create(&args.output, reader.header(), &WriteOptions::default())
            .into_diagnostic()?;
    for chunk in crate::progress::Reading::new(&mut reader, &args.input) {
        w.append(&chunk.into_diagnostic()?).into_diagnostic()?;
    }
    w.close().into_diagnostic()?;
    super::warn_read(&reader, &args.input);
    wrote(&args.output, reader.header(), reader.rows_read());
    Ok(())
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
