//! `physid filter`: zero-phase Butterworth filtering of chosen channels (forward–backward,
//! as the thesis's acquisition chain does; equal to scipy's `sosfiltfilt`, or `filtfilt`
//! with --ba).

use super::InputArgs;
use crate::out::outln;
use miette::{miette, IntoDiagnostic, Result};
use physid_apps::acquisition::{filter_channels, FilterSpec, FilterStream};
use physid_signal::filter::Band;
use std::path::PathBuf;

/// Arguments of `physid filter`.
#[derive(clap::Args)]
pub struct Args {
    /// Input recording (time basis; CSV, Parquet or MDF4).
    pub input: PathBuf,
    /// Output file (extension picks the format).
    pub output: PathBuf,
    #[command(flatten)]
    pub read: InputArgs,
    /// Low-pass cut-off [Hz].
    #[arg(long, value_name = "HZ", conflicts_with_all = ["highpass", "bandpass"])]
    pub lowpass: Option<f64>,
    /// High-pass cut-off [Hz].
    #[arg(long, value_name = "HZ", conflicts_with = "bandpass")]
    pub highpass: Option<f64>,
    /// Band-pass edges LOW,HIGH [Hz].
    #[arg(long, value_name = "LOW,HIGH", value_delimiter = ',')]
    pub bandpass: Vec<f64>,
    /// Butterworth order (of each pass; the zero-phase result has twice the attenuation).
    #[arg(long, default_value_t = 4)]
    pub order: usize,
    /// Channels to filter (the others are copied unchanged).
    #[arg(long, value_delimiter = ',', required = true)]
    pub channels: Vec<String>,
    /// Use the transfer function (scipy's filtfilt) instead of second-order sections.
    #[arg(long)]
    pub ba: bool,
}

/// Run `physid filter`.
pub fn run(args: &Args) -> Result<()> {
    let (band, cutoff_hz) = match (args.lowpass, args.highpass, args.bandpass.as_slice()) {
        (Some(f), None, []) => (Band::Lowpass, vec![f]),
        (None, Some(f), []) => (Band::Highpass, vec![f]),
        (None, None, [lo, hi]) => (Band::Bandpass, vec![*lo, *hi]),
        (None, None, []) => {
            return Err(miette!(
                "choose a filter: --lowpass HZ, --highpass HZ or --bandpass LOW,HIGH"
            ))
        }
        _ => return Err(miette!("--bandpass takes two frequencies: LOW,HIGH")),
    };
    let spec = FilterSpec {
        band,
        cutoff_hz,
        order: args.order,
        transfer_function: args.ba,
    };
    if args.ba {
        // The transfer-function form filters the whole recording (kept to compare with
        // scipy's and MATLAB's filtfilt(b, a)): its memory grows with the recording.
        let mut rec = args.read.read(&args.input, None)?;
        filter_channels(&mut rec, &args.channels, &spec)
            .map_err(|e| miette!("{}: {e}", args.input.display()))?;
        physid_io::write(&args.output, &rec, &Default::default()).into_diagnostic()?;
    } else {
        stream_filter(args, &spec)?;
    }
    outln!(
        "wrote {} ({} filtered: {:?} Butterworth, order {}, zero phase)",
        args.output.display(),
        args.channels.join(", "),
        spec.band,
        spec.order
    );
    Ok(())
}

/// Second-order sections on the stream: read, filter and write a chunk at a time, memory flat
/// however long the recording ([`FilterStream`]).
fn stream_filter(args: &Args, spec: &FilterSpec) -> Result<()> {
    let at =
        |e: physid_apps::acquisition::AcquisitionError| miette!("{}: {e}", args.input.display());
    let mut reader = args.read.open_all(&args.input)?;
    for c in &args.channels {
        reader
            .header()
            .channel(c)
            .map_err(|e| miette!("{}: {e}", args.input.display()))?;
    }
    let mut stream = FilterStream::new(&args.channels, spec).map_err(at)?;
    let mut writer =
        physid_io::ChunkWriter::create(&args.output, reader.header(), &Default::default())
            .into_diagnostic()?;
    let written = (|| -> Result<()> {
        for chunk in crate::progress::Reading::new(&mut reader, &args.input) {
            if let Some(out) = stream.push(&chunk.into_diagnostic()?).map_err(at)? {
                writer.append(&out).into_diagnostic()?;
            }
        }
        if let Some(out) = stream.finish().map_err(at)? {
            writer.append(&out).into_diagnostic()?;
        }
        Ok(())
    })();
    if let Err(e) = written {
        // No partial file left behind: the one this command created.
        writer.discard();
        return Err(e);
    }
    writer.close().into_diagnostic()?;
    super::warn_read(&reader, &args.input);
    Ok(())
}
