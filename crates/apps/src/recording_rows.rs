//! A recording's columns as [`Rows`]: the file read again, a chunk at a time, on every pass an
//! analysis makes (the output's level, the ranking's factors, each Gauss–Newton iteration, the
//! estimator's run) — or held after the first pass when the channels read fit in a limit — so
//! that `identify` and `run` keep memory independent of the recording's length: at most the
//! limit, or one reader chunk. A recording already in memory (simulated) is one chunk.

use crate::error::AppError;
use physid_core::{Recording, Reopen};
use physid_ident::{Data, DataRows, IdentError, Rows};
use physid_io::{ChunkReader, ReadOptions};
use std::borrow::Cow;
use std::cell::RefCell;
use std::path::{Path, PathBuf};

/// How much a [`RecordingRows`] over a file holds after its first pass by default: 256 MiB of
/// channels (11 M rows of three); beyond it, every pass reads the file again.
pub const DEFAULT_HOLD_BYTES: usize = 256 << 20;

/// A data column: a channel as recorded, or converted to `unit` (`CHANNEL:UNIT`).
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    /// The channel's name.
    pub channel: String,
    /// The unit wanted, if a conversion is asked for.
    pub unit: Option<String>,
}

impl Column {
    /// A channel as recorded.
    pub fn named(channel: &str) -> Self {
        Self {
            channel: channel.to_string(),
            unit: None,
        }
    }

    /// `CHANNEL` or `CHANNEL:UNIT`.
    pub fn parse(spec: &str) -> Self {
        match spec.split_once(':') {
            Some((c, u)) => Self {
                channel: c.trim().to_string(),
                unit: Some(u.trim().to_string()),
            },
            None => Self {
                channel: spec.trim().to_string(),
                unit: None,
            },
        }
    }

    /// The column's values in a recording (or one chunk of it).
    pub fn values<'r>(&self, rec: &'r Recording) -> Result<Cow<'r, [f64]>, String> {
        match &self.unit {
            Some(u) => rec
                .values_in(&self.channel, u)
                .map(Cow::Owned)
                .map_err(|e| e.to_string()),
            None => rec
                .values(&self.channel)
                .map(Cow::Borrowed)
                .map_err(|e| e.to_string()),
        }
    }
}

enum Held {
    /// Not yet read to the end.
    NotYet,
    /// The channels read, whole.
    Whole(Recording),
    /// More than the limit: every pass reads the file.
    TooLarge,
}

/// A file, read again on each pass unless held.
struct FileSource {
    path: PathBuf,
    options: ReadOptions,
    hold_bytes: usize,
    held: RefCell<Held>,
    warning: RefCell<Option<String>>,
}

enum Source<'a> {
    File(Box<FileSource>),
    /// A recording in memory (simulated): one chunk.
    Memory(&'a Recording),
}

/// A chunk's model columns: the inputs, and the output.
pub type ModelColumns<'r> = (Vec<Cow<'r, [f64]>>, Option<Cow<'r, [f64]>>);

/// A recording's columns — one per model input, and the measured output — gone over in passes,
/// a chunk at a time; its other channels read with them ([`chunks`](Self::chunks)).
pub struct RecordingRows<'a> {
    source: Source<'a>,
    inputs: Vec<Column>,
    y: Option<Column>,
    header: Recording,
}

impl<'a> RecordingRows<'a> {
    /// The columns `inputs` (in the model's input order) and `y` of the file `path`, and the
    /// channels `also` that it has, read with `options` (its channel selection is replaced by
    /// these); held after the first pass if they take at most `hold_bytes`. The file's header is
    /// read here: a missing column's channel is an error now.
    pub fn file(
        path: &Path,
        options: &ReadOptions,
        inputs: Vec<Column>,
        y: Option<Column>,
        also: &[&str],
        hold_bytes: usize,
    ) -> Result<Self, AppError> {
        let mut channels: Vec<String> = Vec::new();
        for c in inputs.iter().chain(&y) {
            if !channels.contains(&c.channel) {
                channels.push(c.channel.clone());
            }
        }
        if !also.is_empty() {
            let all = ChunkReader::open(path, options)?;
            for a in also {
                if all.header().channel(a).is_ok() && !channels.iter().any(|c| c == a) {
                    channels.push(a.to_string());
                }
            }
        }
        let options = ReadOptions {
            channels: Some(channels),
            ..options.clone()
        };
        let header = ChunkReader::open(path, &options)?.header().clone();
        Ok(Self {
            source: Source::File(Box::new(FileSource {
                path: path.to_path_buf(),
                options,
                hold_bytes,
                held: RefCell::new(Held::NotYet),
                warning: RefCell::new(None),
            })),
            inputs,
            y,
            header,
        })
    }

    /// The columns of a recording in memory.
    pub fn memory(rec: &'a Recording, inputs: Vec<Column>, y: Option<Column>) -> Self {
        let mut header = Recording::new(rec.basis);
        header.meta = rec.meta.clone();
        for c in rec.channels() {
            // The channels' names and units; no samples.
            let _ = header.push(physid_core::Channel {
                name: c.name.clone(),
                unit: c.unit.clone(),
                values: Vec::new(),
            });
        }
        Self {
            source: Source::Memory(rec),
            inputs,
            y,
            header,
        }
    }

    /// The channels read, without samples (names, units, and where the samples are in the
    /// file, for messages).
    pub fn header(&self) -> &Recording {
        &self.header
    }

    /// Whether a file's channels are held (after a first pass, within the limit); a recording
    /// in memory is.
    pub fn held(&self) -> bool {
        match &self.source {
            Source::File(f) => matches!(*f.held.borrow(), Held::Whole(_)),
            Source::Memory(_) => true,
        }
    }

    /// What the reader noticed but read all the same (a cut-short last line), once the file
    /// has been read to its end.
    pub fn warning(&self) -> Option<String> {
        match &self.source {
            Source::File(f) => f.warning.borrow().clone(),
            Source::Memory(_) => None,
        }
    }

    /// The model's columns in a chunk: the inputs, and the output.
    pub fn columns<'r>(&self, chunk: &'r Recording) -> Result<ModelColumns<'r>, IdentError> {
        let at = |e: String| match &self.source {
            Source::File(f) => IdentError::Read(format!("{}: {e}", f.path.display())),
            Source::Memory(_) => IdentError::Read(e),
        };
        let inputs = self
            .inputs
            .iter()
            .map(|c| c.values(chunk))
            .collect::<Result<_, _>>()
            .map_err(at)?;
        let y = match &self.y {
            Some(c) => Some(c.values(chunk).map_err(at)?),
            None => None,
        };
        Ok((inputs, y))
    }

    /// Go over every chunk of the channels read, in order, once; an error of `visit` ends the
    /// pass and is returned.
    pub fn chunks<E: From<IdentError>>(
        &self,
        visit: &mut dyn FnMut(&Recording) -> Result<(), E>,
    ) -> Result<(), E> {
        let FileSource {
            path,
            options,
            hold_bytes,
            held,
            warning,
        } = match &self.source {
            Source::Memory(rec) => return visit(rec),
            Source::File(f) => f.as_ref(),
        };
        let hold_bytes = *hold_bytes;
        if let Held::Whole(rec) = &*held.borrow() {
            return visit(rec);
        }
        let first = matches!(*held.borrow(), Held::NotYet);
        // A reading error names the file already.
        let read = |e: physid_io::IoError| IdentError::Read(e.to_string());
        let mut reader = ChunkReader::open(path, options).map_err(read)?;
        // The first pass keeps the chunks while they fit (sized at once when the file says
        // how many rows it has).
        let width = self.header.channels().len();
        let claimed = reader.claimed_rows().and_then(|n| usize::try_from(n).ok());
        let fits = claimed.is_none_or(|n| n.saturating_mul(width * 8) <= hold_bytes);
        let mut keep = (first && fits).then(|| {
            let mut whole = self.header.clone();
            whole.reserve_exact(claimed.unwrap_or(0));
            whole
        });
        let mut order = crate::time_order::TimeOrder::default();
        while let Some(chunk) = reader.next_chunk().map_err(read)? {
            if first {
                if let Ok(t) = chunk.values("t") {
                    order.push(t);
                }
            }
            visit(&chunk)?;
            if let Some(whole) = &mut keep {
                if (whole.len() + chunk.len()).saturating_mul(width * 8) > hold_bytes {
                    keep = None;
                } else {
                    whole
                        .append(&chunk)
                        .map_err(|e| IdentError::Read(format!("{}: {e}", path.display())))?;
                }
            }
        }
        if first {
            let notes: Vec<String> = reader
                .header()
                .meta
                .get("warning")
                .cloned()
                .into_iter()
                .chain(order.note())
                .collect();
            *warning.borrow_mut() = (!notes.is_empty()).then(|| notes.join("; "));
            *held.borrow_mut() = keep.map_or(Held::TooLarge, Held::Whole);
        }
        Ok(())
    }
}

impl Rows for RecordingRows<'_> {
    fn has_y(&self) -> bool {
        self.y.is_some()
    }
}

impl Reopen<DataRows, IdentError> for RecordingRows<'_> {
    fn pass(
        &self,
        visit: &mut dyn for<'c> FnMut(&'c Data<'c>) -> Result<(), IdentError>,
    ) -> Result<(), IdentError> {
        self.chunks(&mut |chunk| {
            let (inputs, y) = self.columns(chunk)?;
            visit(&Data {
                inputs: inputs.iter().map(|c| c.as_ref()).collect(),
                y: y.as_deref(),
            })
        })
    }
}
