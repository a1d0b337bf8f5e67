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

use crate::{read_csv, read_mdf, read_parquet, write_csv, write_mdf, write_parquet};
use crate::{CsvOptions, IoError, MdfCompression};
use physid_core::{Basis, Channel, Recording};
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

    fn name(self) -> &'static str {
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

    fn file_name<'a>(&'a self, name: &'a str) -> &'a str {
        self.map
            .iter()
            .find(|m| m.name == name)
            .map_or(name, |m| m.column.as_str())
    }
}

/// Read a recording in any supported format.
pub fn read(path: impl AsRef<Path>, opts: &ReadOptions) -> Result<Recording, IoError> {
    let path = path.as_ref();
    let format = detect(path)?;
    let file_channels: Option<Vec<String>> = opts
        .channels
        .as_ref()
        .map(|v| v.iter().map(|n| opts.file_name(n).to_string()).collect());
    // A broken file (often truncated by an interrupted copy or logger) is reported with its
    // length, so one can see where it ends.
    let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    let with_size = |e: IoError| match e {
        IoError::Malformed { path, detail } => IoError::Malformed {
            path,
            detail: format!("{detail} (the file ends at byte {size})"),
        },
        other => other,
    };
    let mut rec = match format {
        Format::Csv => {
            let mut r = read_csv(
                path,
                &CsvOptions {
                    units_row: opts.units_row,
                    crank_angle: opts.crank_angle,
                },
            )?;
            // The basis by the columns is decided on the whole file, before a selection.
            r.basis = basis_by_channels(&r);
            match &file_channels {
                Some(names) => select(r, names, path)?,
                None => r,
            }
        }
        Format::Parquet => read_parquet(path, file_channels.as_deref()).map_err(with_size)?,
        Format::Mdf4 => read_mdf(path, file_channels.as_deref()).map_err(with_size)?,
    };
    if !opts.map.is_empty() {
        rec = rename(rec, &opts.map, path)?;
    }
    rec.basis = basis_by_channels(&rec);
    if !opts.keep_units {
        let done = rec
            .to_standard_units()
            .map_err(|source| IoError::Recording {
                path: path.display().to_string(),
                source,
            })?;
        if !done.is_empty() {
            rec.meta.insert(
                "units_converted".into(),
                done.iter()
                    .map(|(n, from, to)| format!("{n}: {from} → {to}"))
                    .collect::<Vec<_>>()
                    .join(", "),
            );
        }
    }
    Ok(rec)
}

/// Keep only `names` (in that order).
fn select(rec: Recording, names: &[String], path: &Path) -> Result<Recording, IoError> {
    let mut out = Recording::new(rec.basis);
    out.meta = rec.meta.clone();
    for n in names {
        let ch = rec.channel(n).map_err(|source| IoError::Recording {
            path: path.display().to_string(),
            source,
        })?;
        out.push(ch.clone()).map_err(|source| IoError::Recording {
            path: path.display().to_string(),
            source,
        })?;
    }
    Ok(out)
}

/// Rename the file's columns to physid names per the map, with the units it states.
fn rename(rec: Recording, map: &[MapItem], path: &Path) -> Result<Recording, IoError> {
    let p = path.display().to_string();
    for m in map {
        if rec.channel(&m.column).is_err() && rec.channel(&m.name).is_err() {
            return Err(IoError::Recording {
                path: p,
                source: physid_core::RecordingError::MissingChannel {
                    name: format!("{} (mapped to {})", m.column, m.name),
                    available: rec.names().join(", "),
                },
            });
        }
    }
    let mut out = Recording::new(rec.basis);
    out.meta = rec.meta.clone();
    for ch in rec.channels() {
        let item = map.iter().find(|m| m.column == ch.name).or_else(|| {
            map.iter()
                .find(|m| m.name == ch.name && rec.channel(&m.column).is_err())
        });
        let mut unit = ch.unit.clone();
        if let Some(stated) = item.and_then(|m| m.unit.as_ref()) {
            if !unit.is_empty() && &unit != stated {
                return Err(IoError::Malformed {
                    path: p,
                    detail: format!(
                        "--map gives column '{}' the unit '{stated}', but the file says '{unit}'",
                        ch.name
                    ),
                });
            }
            unit = stated.clone();
        }
        out.push(Channel {
            name: item.map_or(ch.name.clone(), |m| m.name.clone()),
            unit,
            values: ch.values.clone(),
        })
        .map_err(|source| IoError::Recording {
            path: p.clone(),
            source,
        })?;
    }
    Ok(out)
}

/// How to write.
#[derive(Debug, Clone, Copy, Default)]
pub struct WriteOptions {
    /// MDF4 data-block compression.
    pub mdf_compression: MdfCompression,
}

/// Write a recording in the format its extension names.
pub fn write(path: impl AsRef<Path>, rec: &Recording, opts: &WriteOptions) -> Result<(), IoError> {
    let path = path.as_ref();
    match Format::from_extension(path) {
        Some(Format::Csv) => write_csv(path, rec),
        Some(Format::Parquet) => write_parquet(path, rec),
        Some(Format::Mdf4) => write_mdf(path, rec, opts.mdf_compression, None),
        None => Err(IoError::Malformed {
            path: path.display().to_string(),
            detail: "unknown extension: expected .csv, .parquet or .mf4".into(),
        }),
    }
}

/// Rows per Parquet row group when a recording is written as it comes: the writer holds at
/// most this many rows (≈ 18 MB at 35 channels).
pub const STREAM_ROWS_PER_GROUP: usize = 65_536;

/// A recording written chunk by chunk in the format its extension names (`physid simulate`'s
/// output, the live service's logs): CSV and MDF4 byte for byte what [`write`] writes for the
/// whole (MDF4 uncompressed), Parquet the same values in row groups of
/// [`STREAM_ROWS_PER_GROUP`]. Memory stays bounded however long it writes.
pub enum ChunkWriter {
    /// CSV.
    Csv(Box<crate::CsvWriter>),
    /// Parquet.
    Parquet(Box<crate::ParquetWriter>),
    /// MDF4, uncompressed.
    Mdf(crate::MdfWriter),
}

impl ChunkWriter {
    /// Create `path` for recordings with `like`'s channels, units, basis and metadata (the
    /// metadata where the format keeps it: Parquet).
    pub fn create(
        path: impl AsRef<Path>,
        like: &Recording,
        opts: &WriteOptions,
    ) -> Result<Self, IoError> {
        let path = path.as_ref();
        match Format::from_extension(path) {
            Some(Format::Csv) => Ok(Self::Csv(Box::new(crate::CsvWriter::create(path, like)?))),
            Some(Format::Parquet) => Ok(Self::Parquet(Box::new(crate::ParquetWriter::create(
                path,
                like,
                STREAM_ROWS_PER_GROUP,
            )?))),
            Some(Format::Mdf4) if opts.mdf_compression == MdfCompression::None => {
                Ok(Self::Mdf(crate::MdfWriter::create(path, like, None)?))
            }
            Some(Format::Mdf4) => Err(IoError::Malformed {
                path: path.display().to_string(),
                detail: "an MDF4 file written as the samples come is uncompressed; compress it afterwards (physid convert)".into(),
            }),
            None => Err(IoError::Malformed {
                path: path.display().to_string(),
                detail: "unknown extension: expected .csv, .parquet or .mf4".into(),
            }),
        }
    }

    /// Append `rec`'s samples (the file's channels, in its order).
    pub fn append(&mut self, rec: &Recording) -> Result<(), IoError> {
        match self {
            Self::Csv(w) => w.append(rec),
            Self::Parquet(w) => w.append(rec),
            Self::Mdf(w) => w.append(rec),
        }
    }

    /// Samples written so far.
    pub fn rows(&self) -> usize {
        match self {
            Self::Csv(w) => w.rows(),
            Self::Parquet(w) => w.rows(),
            Self::Mdf(w) => w.rows(),
        }
    }

    /// Bytes so far (written, and for Parquet buffered for the next row group).
    pub fn bytes(&self) -> usize {
        match self {
            Self::Csv(w) => w.bytes(),
            Self::Parquet(w) => w.bytes(),
            Self::Mdf(w) => w.bytes(),
        }
    }

    /// Finish the file.
    pub fn close(self) -> Result<(), IoError> {
        match self {
            Self::Csv(w) => w.close(),
            Self::Parquet(w) => w.close(),
            Self::Mdf(w) => w.close(),
        }
    }
}
