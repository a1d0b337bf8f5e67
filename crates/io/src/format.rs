//! One entry point for every format: the extension says which (`.csv`, `.parquet`, `.mf4` /
//! `.mdf`), the first bytes must agree (a file that is not what its extension says is named
//! as such; any other extension — `.txt`, `.dat`, `.asc` — is read by its first bytes), and a
//! channel map renames the file's columns to physid's channel names on the way in
//! (`--map omega_en=EngSpeed`, or `--map omega_en=EngSpeed:rpm` to state the unit of a column
//! the file gives none) — the file itself is never changed.
//!
//! On the way in, every channel of DESIGN.md's table is brought to its SI unit
//! ([`Recording::to_standard_units`]): a log with `omega_en` in rpm and `T_oil` in °C reaches
//! the applications in rad/s and K, and a unit physid cannot convert is refused naming the
//! channel. The conversions made are listed in `meta["units_converted"]`. A recording with
//! `cycle` and `crank_deg` channels is on a crank-angle basis in every format
//! ([`basis_by_channels`]).
//!
//! Here: the formats, their detection and the reading options. `reader.rs` reads
//! ([`ChunkReader`](crate::ChunkReader), [`read`](crate::read)) over each format's own reader
//! (`source.rs`, [`ChunkSource`](crate::ChunkSource)); `writer.rs` writes.

use crate::IoError;
use physid_core::{Basis, Recording};
use std::io::Read;
use std::path::Path;

/// A recording file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Comma-separated values.
    Csv,
    /// Apache Parquet.
    Parquet,
    /// ASAM MDF 4.
    Mdf4,
}

impl Format {
    /// The format an extension names.
    pub fn from_extension(path: &Path) -> Option<Self> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("csv") => Some(Format::Csv),
            Some("parquet" | "pq") => Some(Format::Parquet),
            Some("mf4" | "mdf") => Some(Format::Mdf4),
            _ => None,
        }
    }

    pub(crate) fn name(self) -> &'static str {
        match self {
            Format::Csv => "CSV",
            Format::Parquet => "Parquet",
            Format::Mdf4 => "MDF4",
        }
    }
}

/// What the first bytes say the file is.
fn sniff(head: &[u8]) -> Option<Format> {
    if head.starts_with(b"MDF     3") {
        return None; // MDF 3: refused by `detect` with what to do
    }
    if head.starts_with(b"PAR1") {
        Some(Format::Parquet)
    } else if head.starts_with(b"MDF ") || head.starts_with(b"UnFinMF") {
        Some(Format::Mdf4)
    } else if !head.contains(&0) {
        // Text (a UTF-8 sequence may be cut at the end of the probe): CSV is the candidate.
        Some(Format::Csv)
    } else {
        None
    }
}

/// The file's format from its extension, checked against its first bytes; a file with another
/// extension (`.txt`, `.dat`, …) by its first bytes alone.
pub fn detect(path: &Path) -> Result<Format, IoError> {
    let p = path.display().to_string();
    let by_ext = Format::from_extension(path);
    let mut head = [0u8; 512];
    let n = std::fs::File::open(path)
        .and_then(|mut f| f.read(&mut head))
        .map_err(|source| IoError::Os {
            path: p.clone(),
            source,
        })?;
    let head = &head[..n];
    if head.starts_with(b"MDF     3") {
        return Err(IoError::Malformed {
            path: p,
            detail: "an MDF version 3 file: physid reads MDF 4 (convert it first, e.g. asammdf's MDF(path).convert('4.10').save(...))".into(),
        });
    }
    match (sniff(head), by_ext) {
        (Some(f), Some(e)) if f == e => Ok(f),
        (Some(f), None) => Ok(f),
        (Some(f), Some(e)) => Err(IoError::Malformed {
            path: p,
            detail: format!(
                "the extension says {} but the file is {}",
                e.name(),
                match f {
                    Format::Csv => "text (CSV?)".to_string(),
                    other => format!("{} (by its first bytes)", other.name()),
                }
            ),
        }),
        (None, Some(e)) => Err(IoError::Malformed {
            path: p,
            detail: format!(
                "the extension says {} but the file is neither {0}, CSV, Parquet nor MDF4 by its first bytes",
                e.name()
            ),
        }),
        (None, None) => Err(IoError::Malformed {
            path: p,
            detail: "neither CSV text, Parquet nor MDF4 by its first bytes (physid reads .csv, .parquet and .mf4 files, and text files of any extension)".into(),
        }),
    }
}

/// A crank-angle recording is one with `cycle` and `crank_deg` channels (DESIGN.md's channel
/// table: only a crank-angle recording has them). The convention that keeps the basis in
/// formats with no place for it (CSV) or where physid writes a time master (MDF4).
pub fn basis_by_channels(rec: &Recording) -> Basis {
    if rec.channel("cycle").is_ok() && rec.channel("crank_deg").is_ok() {
        Basis::CrankAngle
    } else {
        rec.basis
    }
}

/// How to read.
#[derive(Debug, Clone, Default)]
pub struct ReadOptions {
    /// Only these channels (physid names, after the map); all if `None`.
    pub channels: Option<Vec<String>>,
    /// The channel map (`--map`).
    pub map: Vec<MapItem>,
    /// CSV: the second row holds units.
    pub units_row: bool,
    /// CSV: samples are on a crank-angle basis.
    pub crank_angle: bool,
    /// Keep every channel in the file's units (default: channels of the channel table are
    /// brought to SI).
    pub keep_units: bool,
    /// A text file without a header row: its columns' names (`--columns t,enc,p_cyl`).
    pub columns: Option<Vec<String>>,
    /// Linear sensor calibrations (`--scale NAME=GAIN,OFFSET`): the file's value `v` of
    /// channel NAME is read as `GAIN·v + OFFSET`, in the channel's unit (the file's, or the one
    /// `--map` states; a standard channel with none: its SI unit).
    pub scale: Vec<(String, f64, f64)>,
}

/// One `--map` item: read the file's `column` as channel `name`, optionally stating its unit.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MapItem {
    /// physid's channel name.
    pub name: String,
    /// The file's column.
    pub column: String,
    /// The column's unit, when the user states it (`NAME=COLUMN:UNIT`).
    pub unit: Option<String>,
}

impl ReadOptions {
    /// Parse `NAME=COLUMN` or `NAME=COLUMN:UNIT` items (the `--map` option). A `:UNIT`
    /// suffix is taken as a unit only when it is one physid knows, so a column whose own name
    /// has a colon still maps.
    pub fn parse_map(items: &[String]) -> Result<Vec<MapItem>, String> {
        items
            .iter()
            .map(|s| {
                let (name, column) = s
                    .split_once('=')
                    .map(|(a, b)| (a.trim(), b.trim()))
                    .filter(|(a, b)| !a.is_empty() && !b.is_empty())
                    .ok_or_else(|| {
                        format!("--map '{s}': expected NAME=COLUMN or NAME=COLUMN:UNIT, e.g. omega_en=EngSpeed:rpm")
                    })?;
                let (column, unit) = match column.rsplit_once(':') {
                    Some((c, u)) if physid_core::units::lookup(u).is_some() && !c.is_empty() => {
                        (c.trim(), Some(u.trim().to_string()))
                    }
                    _ => (column, None),
                };
                Ok(MapItem {
                    name: name.to_string(),
                    column: column.to_string(),
                    unit,
                })
            })
            .collect()
    }

    /// Parse `NAME=GAIN,OFFSET` items (the `--scale` option).
    pub fn parse_scale(items: &[String]) -> Result<Vec<(String, f64, f64)>, String> {
        items
            .iter()
            .map(|s| {
                let bad = || {
                    format!("--scale '{s}': expected NAME=GAIN,OFFSET with numbers, e.g. p_cyl=2.5e5,1e5")
                };
                let (name, rest) = s.split_once('=').ok_or_else(bad)?;
                let (g, o) = rest.split_once(',').ok_or_else(bad)?;
                let (g, o): (f64, f64) = (
                    g.trim().parse().map_err(|_| bad())?,
                    o.trim().parse().map_err(|_| bad())?,
                );
                if !(g.is_finite() && o.is_finite()) || g == 0.0 || name.trim().is_empty() {
                    return Err(format!(
                        "--scale '{s}': the gain must be a finite number other than 0, the offset finite"
                    ));
                }
                Ok((name.trim().to_string(), g, o))
            })
            .collect()
    }

    pub(crate) fn file_name<'a>(&'a self, name: &'a str) -> &'a str {
        self.map
            .iter()
            .find(|m| m.name == name)
            .map_or(name, |m| m.column.as_str())
    }
}

/// Rows per chunk when a file is read as it comes (≈ 18 MB at 35 channels).
pub const CHUNK_ROWS: usize = 65_536;

/// A row count a file claims, checked before anything is sized from it: refused when the
/// `channels` asked for would not fit in free memory (a corrupt footer can claim 2⁶⁰ rows);
/// returned as a capacity hint no larger than the file's size could hold in plain values.
pub(crate) fn claimed_fits(path: &str, claimed: i64, channels: usize) -> Result<usize, IoError> {
    let rows = usize::try_from(claimed).map_err(|_| IoError::Malformed {
        path: path.into(),
        detail: format!("corrupt file: it claims {claimed} rows"),
    })?;
    let need = (rows as u128) * (channels.max(1) as u128) * 8;
    if let Some(free) = physid_core::memory::available() {
        if need > u128::from(free) {
            return Err(IoError::Malformed {
                path: path.into(),
                detail: format!(
                    "the file claims {rows} rows: {channels} channels of them would take {:.1} GB, and this machine has {:.1} GB free (read fewer channels, or the file is corrupt)",
                    need as f64 / 1e9,
                    free as f64 / 1e9
                ),
            });
        }
    }
    let size = std::fs::metadata(path).map_or(0, |m| m.len()) as usize;
    Ok(rows.min(size / 8 + 1))
}
