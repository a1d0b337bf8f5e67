//! One entry point for every format: the extension says which (`.csv`, `.parquet`, `.mf4` /
//! `.mdf`), the first bytes must agree (a file that is not what its extension says is named
//! as such), and a channel map renames the file's columns to physid's channel names on the
//! way in (`--map omega_en=EngSpeed`) — the file itself is never changed.

use crate::{read_csv, read_mdf, read_parquet, write_csv, write_mdf, write_parquet};
use crate::{CsvOptions, IoError, MdfCompression};
use physid_core::{Channel, Recording};
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

/// The file's format from its extension, checked against its first bytes.
pub fn detect(path: &Path) -> Result<Format, IoError> {
    let p = path.display().to_string();
    let by_ext = Format::from_extension(path).ok_or_else(|| IoError::Malformed {
        path: p.clone(),
        detail: "unknown extension: expected .csv, .parquet or .mf4".into(),
    })?;
    let mut head = [0u8; 512];
    let n = std::fs::File::open(path)
        .and_then(|mut f| f.read(&mut head))
        .map_err(|source| IoError::Os {
            path: p.clone(),
            source,
        })?;
    match sniff(&head[..n]) {
        Some(f) if f == by_ext => Ok(f),
        Some(f) => Err(IoError::Malformed {
            path: p,
            detail: format!(
                "the extension says {} but the file is {}",
                by_ext.name(),
                match f {
                    Format::Csv => "text (CSV?)".to_string(),
                    other => format!("{} (by its first bytes)", other.name()),
                }
            ),
        }),
        None => Err(IoError::Malformed {
            path: p,
            detail: format!(
                "the extension says {} but the file is neither {0}, CSV, Parquet nor MDF4 by its first bytes",
                by_ext.name()
            ),
        }),
    }
}

/// How to read.
#[derive(Debug, Clone, Default)]
pub struct ReadOptions {
    /// Only these channels (physid names, after the map); all if `None`.
    pub channels: Option<Vec<String>>,
    /// `(physid name, file column)` pairs.
    pub map: Vec<(String, String)>,
    /// CSV: the second row holds units.
    pub units_row: bool,
    /// CSV: samples are on a crank-angle basis.
    pub crank_angle: bool,
}

impl ReadOptions {
    /// Parse `name=column` items (the `--map` option).
    pub fn parse_map(items: &[String]) -> Result<Vec<(String, String)>, String> {
        items
            .iter()
            .map(|s| {
                s.split_once('=')
                    .map(|(a, b)| (a.trim().to_string(), b.trim().to_string()))
                    .filter(|(a, b)| !a.is_empty() && !b.is_empty())
                    .ok_or_else(|| {
                        format!("--map '{s}': expected NAME=COLUMN, e.g. omega_en=EngSpeed")
                    })
            })
            .collect()
    }

    fn file_name<'a>(&'a self, name: &'a str) -> &'a str {
        self.map
            .iter()
            .find(|(n, _)| n == name)
            .map_or(name, |(_, c)| c.as_str())
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
            let r = read_csv(
                path,
                &CsvOptions {
                    units_row: opts.units_row,
                    crank_angle: opts.crank_angle,
                },
            )?;
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

/// Rename the file's columns to physid names per the map.
fn rename(rec: Recording, map: &[(String, String)], path: &Path) -> Result<Recording, IoError> {
    let p = path.display().to_string();
    for (name, column) in map {
        if rec.channel(column).is_err() && rec.channel(name).is_err() {
            return Err(IoError::Recording {
                path: p,
                source: physid_core::RecordingError::MissingChannel {
                    name: format!("{column} (mapped to {name})"),
                    available: rec.names().join(", "),
                },
            });
        }
    }
    let mut out = Recording::new(rec.basis);
    out.meta = rec.meta.clone();
    for ch in rec.channels() {
        let name = map
            .iter()
            .find(|(_, c)| *c == ch.name)
            .map_or(ch.name.clone(), |(n, _)| n.clone());
        out.push(Channel {
            name,
            unit: ch.unit.clone(),
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
