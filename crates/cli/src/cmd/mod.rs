//! One module per verb.

pub mod bench;
pub mod bench_combustion;
pub mod bench_twin;
pub mod combustion_args;
pub mod compression;
pub mod convert;
pub mod crank_input;
pub mod cycles;
pub mod cycles_report;
pub mod demo;
pub mod design;
pub mod estimate;
pub mod example;
pub mod filter;
pub mod fmu;
pub mod friction;
pub mod identify;
pub mod inspect;
pub mod live;
pub mod live_stages;
pub mod monitor;
pub mod recover;
pub mod run;
pub mod simulate;
pub mod torque;
pub mod twin;
pub mod twin_check;
pub mod worker;

use miette::{miette, IntoDiagnostic, Result};
use physid_core::Recording;
use std::path::Path;

/// How to read a recording file (every format: CSV, Parquet, MDF4 by extension).
#[derive(clap::Args, Clone, Debug, Default)]
pub struct InputArgs {
    /// Read the file's column COLUMN as channel NAME (repeatable), e.g. --map omega_en=EngSpeed;
    /// state its unit where the file gives none with :UNIT, e.g. --map omega_en=EngSpeed:rpm.
    /// Standard channels are converted to SI on reading (rpm → rad/s, deg → rad, °C → K, bar → Pa).
    #[arg(long = "map", value_name = "NAME=COLUMN[:UNIT]")]
    pub map: Vec<String>,
    /// CSV: the file's second row holds units (found without this flag when the row has no
    /// numbers).
    #[arg(long)]
    pub units_row: bool,
    /// A text file without a header row (columns of numbers separated by commas, semicolons,
    /// tabs or spaces): its columns' names, e.g. --columns t,enc,p_cyl.
    #[arg(long, value_delimiter = ',', value_name = "NAME,…")]
    pub columns: Vec<String>,
    /// Linear sensor calibration: read channel NAME as GAIN·value + OFFSET in its unit
    /// (repeatable), e.g. --scale p_cyl=2.5e5,1e5 for a pressure sensor's volts into Pa.
    #[arg(long = "scale", value_name = "NAME=GAIN,OFFSET")]
    pub scale: Vec<String>,
}

/// The slider crank's lengths (`physid_models::kinematics`) and the compression ratio: what
/// the motored-pressure model needs (`--tdc-from`, `physid compression fit`).
#[derive(clap::Args, Clone, Debug, Default)]
pub struct CrankArgs {
    /// Stroke [m].
    #[arg(long, value_name = "M")]
    pub stroke: Option<f64>,
    /// Connecting-rod length [m].
    #[arg(long, value_name = "M")]
    pub rod: Option<f64>,
    /// Compression ratio [-] (held, not fitted, by the motored model of --tdc-from and
    /// `compression fit`).
    #[arg(long, value_name = "RATIO")]
    pub compression_ratio: Option<f64>,
}

impl CrankArgs {
    /// Stroke and rod, both needed `for` what is said.
    pub fn lengths(&self, what: &str) -> Result<(f64, f64)> {
        match (self.stroke, self.rod) {
            (Some(s), Some(r)) => Ok((s, r)),
            _ => Err(miette!(
                "{what} needs the crank's lengths: --stroke and --rod [m] (e.g. --stroke 0.09 --rod 0.15)"
            )),
        }
    }
}

/// The cylinder's geometry: the crank's lengths, the bore and the compression ratio.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct GeometryArgs {
    /// Bore [m].
    #[arg(long, value_name = "M")]
    pub bore: Option<f64>,
    #[command(flatten)]
    pub crank: CrankArgs,
}

impl GeometryArgs {
    /// The whole geometry when any of --bore and --compression-ratio is given (then all four
    /// are needed); `None` without them.
    pub fn full(&self) -> Result<Option<physid_apps::pressure::Geometry>> {
        if self.bore.is_none() && self.crank.compression_ratio.is_none() {
            return Ok(None);
        }
        let missing: Vec<&str> = [
            ("--bore", self.bore.is_none()),
            ("--stroke", self.crank.stroke.is_none()),
            ("--rod", self.crank.rod.is_none()),
            (
                "--compression-ratio",
                self.crank.compression_ratio.is_none(),
            ),
        ]
        .iter()
        .filter(|(_, m)| *m)
        .map(|(n, _)| *n)
        .collect();
        if !missing.is_empty() {
            return Err(miette!(
                "the cylinder's geometry needs --bore, --stroke, --rod and --compression-ratio; missing {}",
                missing.join(", ")
            ));
        }
        let g = physid_apps::pressure::Geometry {
            bore: self.bore.unwrap_or(f64::NAN),
            stroke: self.crank.stroke.unwrap_or(f64::NAN),
            rod: self.crank.rod.unwrap_or(f64::NAN),
            compression_ratio: self.crank.compression_ratio.unwrap_or(f64::NAN),
        };
        g.validate().map_err(|e| miette!("{e}"))?;
        Ok(Some(g))
    }
}

impl InputArgs {
    /// Read `path`, optionally only `channels` (physid names).
    pub fn read(&self, path: &Path, channels: Option<Vec<String>>) -> Result<Recording> {
        crate::provenance::record_input(path, &self.map);
        let rec = physid_io::read(path, &self.options(channels)?).into_diagnostic()?;
        // What the reader noticed but read all the same (a cut-short last line) is said.
        if let Some(w) = rec.meta.get("warning") {
            eprintln!("warning: {}: {w}", path.display());
        }
        Ok(rec)
    }

    /// The reading options these flags give, for `channels` (all if `None`).
    pub fn options(&self, channels: Option<Vec<String>>) -> Result<physid_io::ReadOptions> {
        Ok(physid_io::ReadOptions {
            channels,
            map: physid_io::ReadOptions::parse_map(&self.map).map_err(|e| miette!("{e}"))?,
            units_row: self.units_row,
            columns: (!self.columns.is_empty()).then(|| self.columns.clone()),
            scale: physid_io::ReadOptions::parse_scale(&self.scale).map_err(|e| miette!("{e}"))?,
            ..Default::default()
        })
    }

    /// Open `path` to read a chunk at a time, every channel.
    pub fn open_all(&self, path: &Path) -> Result<physid_io::ChunkReader> {
        crate::provenance::record_input(path, &self.map);
        physid_io::ChunkReader::open(path, &self.options(None)?).into_diagnostic()
    }

    /// Open `path` to read a chunk at a time ([`physid_io::ChunkReader`]): the `needed`
    /// channels (physid names; the file must have them), then those of `optional` it has.
    pub fn open(
        &self,
        path: &Path,
        needed: &[&str],
        optional: &[&str],
    ) -> Result<physid_io::ChunkReader> {
        let mut names: Vec<String> = needed.iter().map(|s| s.to_string()).collect();
        if !optional.is_empty() {
            let all = self.open_all(path)?;
            let has = |n: &str| all.header().channel(n).is_ok();
            names.extend(optional.iter().filter(|n| has(n)).map(|n| n.to_string()));
        }
        crate::provenance::record_input(path, &self.map);
        physid_io::ChunkReader::open(path, &self.options(Some(names))?).into_diagnostic()
    }
}

/// An application's error on the file `path`, for the user (a reading error names the file
/// already).
pub fn app_error(path: &Path) -> impl Fn(physid_apps::error::AppError) -> miette::Report + '_ {
    move |e| match e {
        // A reading error names the file.
        physid_apps::error::AppError::Io(e) => miette!("{e}"),
        physid_apps::error::AppError::Ident(physid_ident::IdentError::Read(e)) => miette!("{e}"),
        e => miette!("{}: {e}", path.display()),
    }
}

/// What a reader noticed but read all the same (a cut-short last line), said once the file
/// has been read to its end.
pub fn warn_read(reader: &physid_io::ChunkReader, path: &Path) {
    if let Some(w) = reader.header().meta.get("warning") {
        eprintln!("warning: {}: {w}", path.display());
    }
}

/// Each dropout a file verb left out with the cycle it cuts, as a warning on stderr (the
/// `--json` result lists them too).
pub fn warn_dropouts(dropouts: &[physid_apps::stage::Dropout], path: &Path) {
    for d in dropouts {
        eprintln!("warning: {}: {}", path.display(), d.message());
    }
}

/// How much of a recording's columns a verb that goes over them in passes (`identify`, `run`,
/// `torque fit`) holds after the first: `PHYSID_HOLD_MB` (default 256); beyond it, each pass
/// reads the file again — slower, in memory independent of the recording's length.
pub fn hold_bytes() -> Result<usize> {
    match std::env::var("PHYSID_HOLD_MB") {
        Err(_) => Ok(physid_apps::recording_rows::DEFAULT_HOLD_BYTES),
        Ok(v) => v
            .trim()
            .parse::<usize>()
            .ok()
            .and_then(|mb| mb.checked_mul(1 << 20))
            .ok_or_else(|| {
                miette!("PHYSID_HOLD_MB={v}: expected a whole number of MiB (0: always read again)")
            }),
    }
}

/// Where sample `i` of a recording read from a file is, for error messages: the CSV line
/// (from the reader's `first_data_line`), else the index.
pub fn locate(rec: &Recording, i: usize) -> String {
    match rec
        .meta
        .get("first_data_line")
        .and_then(|l| l.parse::<usize>().ok())
    {
        Some(l) => format!("line {} (sample {i})", l + i),
        None => format!("sample {i}"),
    }
}

/// A flag's old spelling, still taken for this release (docs/cli.md lists them): the value
/// given under it, if any, with a warning on stderr naming the new spelling. The two are
/// declared `conflicts_with` each other, so at most one was given.
pub fn renamed<T>(old: Option<T>, old_flag: &str, new_flag: &str) -> Option<T> {
    if old.is_some() {
        deprecated(&format!("{old_flag} is now {new_flag}"));
    }
    old
}

/// A deprecation warning on stderr: `what` (an old spelling and its new one), taken for this
/// release only.
pub fn deprecated(what: &str) {
    eprintln!("warning: {what} (the old spelling is taken for this release only; docs/cli.md)");
}

/// `NAME=VALUE,…` into names and values.
pub fn named_values(items: &[String], flag: &str) -> Result<(Vec<String>, Vec<f64>)> {
    let mut names = Vec::new();
    let mut values = Vec::new();
    for item in items {
        let (n, v) = item
            .split_once('=')
            .ok_or_else(|| miette!("{flag} '{item}': expected NAME=VALUE"))?;
        let v: f64 = v
            .trim()
            .parse()
            .map_err(|_| miette!("{flag} '{item}': '{v}' is not a number"))?;
        names.push(n.trim().to_string());
        values.push(v);
    }
    Ok((names, values))
}

/// Value parsers for flags with a physical range: clap's error names the flag and the value,
/// and these say the range (`invalid value '-5' for '--duration <S>': expected a time > 0 s`).
pub mod range {
    fn number(s: &str) -> Result<f64, String> {
        s.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("'{s}' is not a finite number"))
    }

    /// A duration, rate or step: > 0.
    pub fn positive(s: &str) -> Result<f64, String> {
        let v = number(s)?;
        if v > 0.0 {
            Ok(v)
        } else {
            Err(format!("expected a number > 0, got {}", s.trim()))
        }
    }

    /// A variance or a time that may be zero: ≥ 0.
    pub fn nonnegative(s: &str) -> Result<f64, String> {
        let v = number(s)?;
        if v >= 0.0 {
            Ok(v)
        } else {
            Err(format!("expected a number ≥ 0, got {}", s.trim()))
        }
    }

    /// A forgetting factor: 0 < λ ≤ 1.
    pub fn forgetting(s: &str) -> Result<f64, String> {
        let v = number(s)?;
        if v > 0.0 && v <= 1.0 {
            Ok(v)
        } else {
            Err(format!(
                "a forgetting factor is in (0, 1], got {}",
                s.trim()
            ))
        }
    }

    /// An engine speed in rpm: 0 < n ≤ 20 000.
    pub fn rpm(s: &str) -> Result<f64, String> {
        let v = number(s)?;
        if v > 0.0 && v <= 20_000.0 {
            Ok(v)
        } else {
            Err(format!(
                "an engine speed in rpm is in (0, 20000], got {}",
                s.trim()
            ))
        }
    }

    /// A manifold or ambient pressure in kPa: 0 < p ≤ 500 (a value in Pa is named as such).
    pub fn kpa(s: &str) -> Result<f64, String> {
        let v = number(s)?;
        if v > 0.0 && v <= 500.0 {
            Ok(v)
        } else if v > 500.0 && v <= 500_000.0 {
            Err(format!(
                "the pressure is in kPa (0 < p ≤ 500); {v} looks like Pa: {} kPa",
                v / 1e3
            ))
        } else {
            Err(format!(
                "a pressure in kPa is in (0, 500], got {}",
                s.trim()
            ))
        }
    }

    /// An oil or air temperature in °C: −50 … 250 (a value in K is named as such).
    pub fn celsius(s: &str) -> Result<f64, String> {
        let v = number(s)?;
        if (-50.0..=250.0).contains(&v) {
            Ok(v)
        } else if (250.0..=523.15).contains(&v) {
            Err(format!(
                "the temperature is in °C (−50 … 250); {v} looks like K: {} °C",
                v - 273.15
            ))
        } else {
            Err(format!(
                "a temperature in °C is in [−50, 250], got {}",
                s.trim()
            ))
        }
    }
}

/// A flag set at SIGTERM, SIGINT (Ctrl-C) or SIGHUP (the terminal or the SSH session the verb
/// runs in has closed): a long-running verb checks it and ends cleanly — its outputs and logs
/// closed, readable — where the signal's default would kill it. A SIGHUP the process was
/// started ignoring (`nohup physid …`) stays ignored.
pub fn stop_on_signal() -> miette::Result<std::sync::Arc<std::sync::atomic::AtomicBool>> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let hangup = (ignored(SIGHUP) == Some(false)).then_some(SIGHUP);
    for sig in [SIGTERM, SIGINT].into_iter().chain(hangup) {
        signal_hook::flag::register(sig, stop.clone())
            .map_err(|e| miette::miette!("installing the signal handler: {e}"))?;
    }
    Ok(stop)
}

/// Whether the process ignores signal `sig` (1–64), from the kernel's `SigIgn` mask in
/// `/proc/self/status`; `None` where that cannot be read (not Linux): the signal's
/// disposition is then left as it is.
fn ignored(sig: i32) -> Option<bool> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let mask = status
        .lines()
        .find_map(|l| l.strip_prefix("SigIgn:"))
        .and_then(|m| u64::from_str_radix(m.trim(), 16).ok())?;
    let bit = u32::try_from(sig - 1).ok().filter(|b| *b < 64)?;
    Some(mask >> bit & 1 == 1)
}
