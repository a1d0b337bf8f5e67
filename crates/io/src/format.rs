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

use crate::{write_csv, write_mdf, write_parquet};
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

    fn file_name<'a>(&'a self, name: &'a str) -> &'a str {
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

/// Where a [`ChunkReader`]'s rows come from.
enum Source {
    Csv(Box<crate::csv_file::CsvChunks>),
    Parquet(Box<crate::parquet_file::ParquetChunks>),
    Mdf(crate::mdf::MdfChunks),
}

/// A recording read a chunk of rows at a time, in any format: only the channels asked for,
/// mapped and brought to SI exactly as [`read`] does — [`read`] is this reader, drained. The
/// channels, units, basis and metadata are known on opening ([`header`](Self::header)); each
/// chunk (up to [`CHUNK_ROWS`] rows) is a [`Recording`] with those channels. Memory is that of
/// a chunk or two, however long the file: what the file verbs stream through their stages.
pub struct ChunkReader {
    path: String,
    size: u64,
    header: Recording,
    /// Per channel, `value · scale + offset` into its unit in the header.
    convert: Vec<(f64, f64)>,
    source: Source,
    claimed: Option<i64>,
    rows: usize,
}

impl ChunkReader {
    /// Open `path` (any format, by [`detect`]) for `opts`' channels and map.
    pub fn open(path: impl AsRef<Path>, opts: &ReadOptions) -> Result<Self, IoError> {
        let path = path.as_ref();
        let format = detect(path)?;
        let p = path.display().to_string();
        let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
        let file_channels: Option<Vec<String>> = opts
            .channels
            .as_ref()
            .map(|v| v.iter().map(|n| opts.file_name(n).to_string()).collect());
        let with_size = |e| with_file_size(e, size);
        // The file's channels, units, basis and metadata: the header as the file has it.
        let empty = |names: &[String], units: &[String], rec: &mut Recording| {
            for (n, u) in names.iter().zip(units) {
                rec.push(Channel {
                    name: n.clone(),
                    unit: u.clone(),
                    values: Vec::new(),
                })
                .map_err(|source| IoError::Recording {
                    path: p.clone(),
                    source,
                })?;
            }
            Ok::<_, IoError>(())
        };
        if opts.columns.is_some() && format != Format::Csv {
            return Err(IoError::Malformed {
                path: p,
                detail: "--columns names the columns of a text file without a header row; Parquet and MDF4 files name their own".into(),
            });
        }
        let (mut header, source, claimed) = match format {
            Format::Csv => {
                let c = crate::csv_file::CsvChunks::open(
                    path,
                    &CsvOptions {
                        units_row: opts.units_row,
                        crank_angle: opts.crank_angle,
                        columns: opts.columns.clone(),
                    },
                    file_channels.as_deref(),
                )?;
                let mut h = c.header();
                // The basis by the columns is decided on the whole file, before a selection.
                let all = c.file_columns();
                if all.iter().any(|n| n == "cycle") && all.iter().any(|n| n == "crank_deg") {
                    h.basis = Basis::CrankAngle;
                }
                empty(&c.names, &c.units, &mut h)?;
                (h, Source::Csv(Box::new(c)), None)
            }
            Format::Parquet => {
                let c = crate::parquet_file::ParquetChunks::open(path, file_channels.as_deref())
                    .map_err(with_size)?;
                let mut h = c.header();
                empty(&c.names, &c.units, &mut h)?;
                let claimed = c.claimed_rows();
                (h, Source::Parquet(Box::new(c)), Some(claimed))
            }
            Format::Mdf4 => {
                let c = crate::mdf::MdfChunks::open(path, file_channels.as_deref())
                    .map_err(with_size)?;
                let h = c.header().clone();
                let claimed = i64::try_from(c.claimed_rows()).unwrap_or(i64::MAX);
                (h, Source::Mdf(c), Some(claimed))
            }
        };
        if header.channels().len() > crate::MAX_CHANNELS {
            return Err(IoError::Malformed {
                path: p,
                detail: format!(
                    "{} channels: physid reads at most {} at once; name the ones wanted \
                     (--channels, or a map)",
                    header.channels().len(),
                    crate::MAX_CHANNELS
                ),
            });
        }
        // With a selection, only the map items of the channels asked for apply (a map made
        // for a whole log serves a verb that reads part of it).
        let map: Vec<MapItem> = opts
            .map
            .iter()
            .filter(|m| {
                opts.channels
                    .as_ref()
                    .is_none_or(|list| list.contains(&m.name))
            })
            .cloned()
            .collect();
        if !map.is_empty() {
            header = rename(header, &map, path)?;
        }
        header.basis = basis_by_channels(&header);
        // Sensor calibrations (`--scale`) map the file's values into the channel's unit, then
        // that unit goes to SI. A standard channel calibrated from no unit, or from its sensor's
        // own (V, mV, counts — one that does not convert to the channel's SI unit), is
        // calibrated into its SI unit, and says so.
        let into_si = |c: &Channel| {
            opts.scale.iter().any(|(n, ..)| n == &c.name)
                && physid_core::standard_unit(&c.name).is_some_and(|si| {
                    c.unit.is_empty() || physid_core::units::conversion(&c.unit, si).is_none()
                })
        };
        if header.channels().iter().any(into_si) {
            let mut relabelled = Recording::new(header.basis);
            relabelled.meta = std::mem::take(&mut header.meta);
            let mut said = Vec::new();
            for c in header.channels() {
                let mut unit = c.unit.clone();
                if into_si(c) {
                    let si = physid_core::standard_unit(&c.name).unwrap_or_default();
                    if !unit.is_empty() {
                        said.push(format!("{}: {unit} → {si} by --scale", c.name));
                    }
                    unit = si.to_string();
                }
                relabelled
                    .push(Channel {
                        name: c.name.clone(),
                        unit,
                        values: Vec::new(),
                    })
                    .map_err(|source| IoError::Recording {
                        path: p.clone(),
                        source,
                    })?;
            }
            if !said.is_empty() {
                relabelled.meta.insert("calibrated".into(), said.join(", "));
            }
            header = relabelled;
        }
        let mut convert = vec![(1.0, 0.0); header.channels().len()];
        if !opts.keep_units {
            let before: Vec<String> = header.channels().iter().map(|c| c.unit.clone()).collect();
            let done = header
                .to_standard_units()
                .map_err(|source| IoError::Recording {
                    path: p.clone(),
                    source,
                })?;
            for ((c, from), k) in header.channels().iter().zip(&before).zip(&mut convert) {
                if &c.unit != from {
                    *k = physid_core::units::conversion(from, &c.unit).unwrap_or((1.0, 0.0));
                }
            }
            if !done.is_empty() {
                header.meta.insert(
                    "units_converted".into(),
                    done.iter()
                        .map(|(n, from, to)| format!("{n}: {from} → {to}"))
                        .collect::<Vec<_>>()
                        .join(", "),
                );
            }
        }
        for (name, gain, offset) in &opts.scale {
            match header.channels().iter().position(|c| &c.name == name) {
                Some(k) => {
                    let (s, o) = convert[k];
                    convert[k] = (gain * s, offset * s + o);
                }
                None if opts.channels.is_none() => {
                    return Err(IoError::Recording {
                        path: p,
                        source: physid_core::RecordingError::MissingChannel {
                            name: format!("{name} (in --scale)"),
                            available: header.names().join(", "),
                        },
                    })
                }
                // A channel the verb does not read.
                None => {}
            }
        }
        Ok(Self {
            path: p,
            size,
            header,
            convert,
            source,
            claimed,
            rows: 0,
        })
    }

    /// The channels (with no samples), units, basis and metadata. A CSV file's warning about
    /// its last line is here once the last chunk has been read.
    pub fn header(&self) -> &Recording {
        &self.header
    }

    /// The rows the file claims to hold (Parquet's footer, MDF4's channel group; none for
    /// CSV). A claim: a corrupt file can claim anything.
    pub fn claimed_rows(&self) -> Option<i64> {
        self.claimed
    }

    /// Rows read so far.
    pub fn rows_read(&self) -> usize {
        self.rows
    }

    /// The next chunk's columns, in the header's order and units (`None` after the last).
    pub fn next_columns(&mut self) -> Result<Option<Vec<Vec<f64>>>, IoError> {
        let size = self.size;
        let next = match &mut self.source {
            Source::Csv(c) => {
                let next = c.next_columns(CHUNK_ROWS)?;
                if let Some(w) = c.header().meta.get("warning") {
                    self.header.meta.insert("warning".into(), w.clone());
                }
                next
            }
            Source::Parquet(c) => c.next_columns().map_err(|e| with_file_size(e, size))?,
            Source::Mdf(c) => c.next_columns().map_err(|e| with_file_size(e, size))?,
        };
        let Some(mut cols) = next else {
            // A count the file claimed that its data do not bear out is said (MDF4's cycle
            // count, Parquet's footer): the rows read are what there is.
            if let Some(claimed) = self.claimed.filter(|&c| c != self.rows as i64) {
                self.header.meta.entry("warning".into()).or_insert(format!(
                    "the file claims {claimed} rows but holds {}: its count is wrong (a writer \
                     stopped before it finished, or a corrupt file); the {} rows there are were read",
                    self.rows, self.rows
                ));
            }
            return Ok(None);
        };
        if cols.len() != self.convert.len() {
            return Err(IoError::Malformed {
                path: self.path.clone(),
                detail: format!(
                    "a chunk of {} channels, the file's header has {}",
                    cols.len(),
                    self.convert.len()
                ),
            });
        }
        for (v, &(scale, offset)) in cols.iter_mut().zip(&self.convert) {
            if (scale, offset) != (1.0, 0.0) {
                for x in v.iter_mut() {
                    *x = *x * scale + offset;
                }
            }
        }
        self.rows += cols.first().map_or(0, Vec::len);
        Ok(Some(cols))
    }

    /// The next chunk as a recording with the header's channels and basis (`None` after the
    /// last).
    pub fn next_chunk(&mut self) -> Result<Option<Recording>, IoError> {
        let Some(cols) = self.next_columns()? else {
            return Ok(None);
        };
        let mut rec = Recording::new(self.header.basis);
        for (c, values) in self.header.channels().iter().zip(cols) {
            rec.push(Channel {
                name: c.name.clone(),
                unit: c.unit.clone(),
                values,
            })
            .map_err(|source| IoError::Recording {
                path: self.path.clone(),
                source,
            })?;
        }
        Ok(Some(rec))
    }
}

impl Iterator for ChunkReader {
    type Item = Result<Recording, IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_chunk().transpose()
    }
}

/// A broken file (often truncated by an interrupted copy or logger) is reported with its
/// length, so one can see where it ends.
fn with_file_size(e: IoError, size: u64) -> IoError {
    match e {
        IoError::Malformed { path, detail } if !detail.contains("(the file ends at byte") => {
            IoError::Malformed {
                path,
                detail: format!("{detail} (the file ends at byte {size})"),
            }
        }
        other => other,
    }
}

/// Read a recording in any supported format: a [`ChunkReader`] drained into one recording.
/// A row count the file claims is checked against free memory before anything is sized by it.
pub fn read(path: impl AsRef<Path>, opts: &ReadOptions) -> Result<Recording, IoError> {
    let mut r = ChunkReader::open(path, opts)?;
    let width = r.header.channels().len();
    let rows = match r.claimed {
        Some(n) => claimed_fits(&r.path, n, width).map_err(|e| with_file_size(e, r.size))?,
        None => 0,
    };
    let names: Vec<String> = r.header.channels().iter().map(|c| c.name.clone()).collect();
    let units: Vec<String> = r.header.channels().iter().map(|c| c.unit.clone()).collect();
    let path = r.path.clone();
    let mut rec = crate::drain(
        Recording::new(r.header.basis),
        &names,
        &units,
        rows,
        || r.next_columns(),
        &path,
    )?;
    // The metadata once the last row is read (a CSV file's warning about it).
    rec.meta = r.header.meta.clone();
    Ok(rec)
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
/// output, `convert`'s, the live service's logs): CSV and MDF4 byte for byte what [`write`]
/// writes for the whole (MDF4 uncompressed; compressed, the same values in deflated blocks of
/// [`crate::MDF_BLOCK_BYTES`]), Parquet the same values in row groups of
/// [`STREAM_ROWS_PER_GROUP`]. Memory stays bounded however long it writes.
pub enum ChunkWriter {
    /// CSV.
    Csv(Box<crate::CsvWriter>),
    /// Parquet.
    Parquet(Box<crate::ParquetWriter>),
    /// MDF4.
    Mdf(Box<crate::MdfWriter>),
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
            Some(Format::Mdf4) => Ok(Self::Mdf(Box::new(crate::MdfWriter::create_compressed(
                path,
                like,
                None,
                opts.mdf_compression,
                crate::MDF_BLOCK_BYTES,
            )?))),
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

    /// Make every sample appended so far survive a crash or a power loss: a writer killed
    /// from now on leaves a file readable up to here (CSV and uncompressed MDF4 as they are,
    /// Parquet through [`crate::recover_parquet`]); a compressed MDF4 file is only flushed.
    pub fn commit(&mut self) -> Result<(), IoError> {
        match self {
            Self::Csv(w) => w.commit(),
            Self::Parquet(w) => w.commit(),
            Self::Mdf(w) => w.commit(),
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
            Self::Mdf(w) => (*w).close(),
        }
    }
}
