//! Reading a recording file, a chunk at a time ([`ChunkReader`]) or whole ([`read`]): each
//! format's own reader ([`ChunkSource`]), then the channel map, the calibrations and the units
//! as adapters over it (see [`crate::format`] for what they do).

use crate::format::{basis_by_channels, claimed_fits, detect, Format, MapItem, ReadOptions};
use crate::source::ChunkSource;
use crate::{CsvOptions, IoError};
use physid_core::{Channel, Recording};
use std::path::Path;

/// A recording read a chunk of rows at a time, in any format: only the channels asked for,
/// mapped and brought to SI exactly as [`read`] does — [`read`] is this reader, drained. The
/// channels, units, basis and metadata are known on opening ([`header`](Self::header)); each
/// chunk (up to [`CHUNK_ROWS`](crate::CHUNK_ROWS) rows) is a [`Recording`] with those
/// channels. Memory is that of a chunk or two, however long the file: what the file verbs
/// stream through their stages.
///
/// Opening is four steps, each its own function: the format's own reader ([`ChunkSource`],
/// `open_source`), the channel map (`map_channels`), the calibrations' units
/// (`calibrated_units`), and the conversion of each channel's values into its unit in the
/// header (`conversions`: SI, then `--scale`).
pub struct ChunkReader {
    path: String,
    size: u64,
    format: Format,
    header: Recording,
    /// Per channel, `value · scale + offset` into its unit in the header.
    convert: Vec<(f64, f64)>,
    source: Box<dyn ChunkSource>,
    claimed: Option<i64>,
    rows: usize,
    /// The file is not written over by this process while it is read.
    _reading: crate::lock::Reading,
}

impl ChunkReader {
    /// Open `path` (any format, by [`detect`]) for `opts`' channels and map.
    pub fn open(path: impl AsRef<Path>, opts: &ReadOptions) -> Result<Self, IoError> {
        let path = path.as_ref();
        let format = detect(path)?;
        let p = path.display().to_string();
        let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
        if opts.columns.is_some() && format != Format::Csv {
            return Err(IoError::Malformed {
                path: p,
                detail: "--columns names the columns of a text file without a header row; Parquet and MDF4 files name their own".into(),
            });
        }
        let source = open_source(path, format, opts)
            .map_err(|e| match format {
                Format::Csv => e,
                _ => with_file_size(e, size),
            })
            .map_err(|e| crate::lock::while_written(path, e))?;
        let header = source.header()?;
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
        let header = map_channels(header, opts, path)?;
        let header = calibrated_units(header, opts, &p)?;
        let (header, convert) = conversions(header, opts, &p)?;
        Ok(Self {
            path: p,
            size,
            format,
            claimed: source.claimed_rows(),
            header,
            convert,
            source,
            rows: 0,
            _reading: crate::lock::Reading::new(path),
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
        let next = match self.format {
            Format::Csv => self.source.next_columns()?,
            _ => (self.source.next_columns()).map_err(|e| with_file_size(e, self.size))?,
        };
        if let Some(w) = self.source.warning() {
            self.header.meta.insert("warning".into(), w);
        }
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

/// Step 1 of [`ChunkReader::open`]: the format's own reader of the file's channels (those
/// `opts` asks for, by the file's names), its header as the file has it.
fn open_source(
    path: &Path,
    format: Format,
    opts: &ReadOptions,
) -> Result<Box<dyn ChunkSource>, IoError> {
    let file_channels: Option<Vec<String>> = opts
        .channels
        .as_ref()
        .map(|v| v.iter().map(|n| opts.file_name(n).to_string()).collect());
    Ok(match format {
        Format::Csv => Box::new(crate::csv_file::CsvChunks::open(
            path,
            &CsvOptions {
                units_row: opts.units_row,
                crank_angle: opts.crank_angle,
                columns: opts.columns.clone(),
            },
            file_channels.as_deref(),
        )?),
        Format::Parquet => Box::new(crate::parquet_file::ParquetChunks::open(
            path,
            file_channels.as_deref(),
        )?),
        Format::Mdf4 => Box::new(crate::mdf::MdfChunks::open(path, file_channels.as_deref())?),
    })
}

/// Step 2: the channel map — with a selection, only the map items of the channels asked for
/// apply (a map made for a whole log serves a verb that reads part of it) — and the basis by
/// the channels.
fn map_channels(
    mut header: Recording,
    opts: &ReadOptions,
    path: &Path,
) -> Result<Recording, IoError> {
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
    Ok(header)
}

/// Step 3: sensor calibrations (`--scale`) map the file's values into the channel's unit,
/// then that unit goes to SI. A standard channel calibrated from no unit, or from its sensor's
/// own (V, mV, counts — one that does not convert to the channel's SI unit), is calibrated into
/// its SI unit, and says so (`meta["calibrated"]`).
fn calibrated_units(
    mut header: Recording,
    opts: &ReadOptions,
    p: &str,
) -> Result<Recording, IoError> {
    let into_si = |c: &Channel| {
        opts.scale.iter().any(|(n, ..)| n == &c.name)
            && physid_core::standard_unit(&c.name).is_some_and(|si| {
                c.unit.is_empty() || physid_core::units::conversion(&c.unit, si).is_none()
            })
    };
    if !header.channels().iter().any(into_si) {
        return Ok(header);
    }
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
                path: p.into(),
                source,
            })?;
    }
    if !said.is_empty() {
        relabelled.meta.insert("calibrated".into(), said.join(", "));
    }
    Ok(relabelled)
}

/// Step 4: per channel, `value · scale + offset` into its unit in the header — the channel
/// table's SI units (unless `keep_units`; said in `meta["units_converted"]`), after the
/// `--scale` calibrations. A calibration of a channel the file does not have is refused when
/// every channel is read.
fn conversions(
    mut header: Recording,
    opts: &ReadOptions,
    p: &str,
) -> Result<(Recording, Vec<(f64, f64)>), IoError> {
    let mut convert = vec![(1.0, 0.0); header.channels().len()];
    if !opts.keep_units {
        let before: Vec<String> = header.channels().iter().map(|c| c.unit.clone()).collect();
        let done = header
            .to_standard_units()
            .map_err(|source| IoError::Recording {
                path: p.into(),
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
                    path: p.into(),
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
    Ok((header, convert))
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
