//! CSV recordings: a header row of channel names, optionally a row of units, then one row per
//! sample.
//!
//! **What physid writes** (and so reads back with no option): the header row, then — when any
//! channel has a unit — a units row (`s,rad/s,N*m,…`), then the samples with `,` separators and
//! `.` decimals, each number in the shortest form that reads back to the same `f64`. The units
//! get a row of their own rather than `name [unit]` headers so that a column is still called by
//! its channel name elsewhere: pandas reads the file with `pd.read_csv(path, skiprows=[1])`
//! (or `header=[0, 1]` to keep the units as a second column level). A crank-angle recording
//! is one with `cycle` and `crank_deg` columns (the channels only a crank-angle recording has,
//! DESIGN.md's channel table; [`crate::format::basis_by_channels`]); nothing else marks the
//! basis, so the file stays plain CSV.
//!
//! **What physid reads**, so that test-cell exports open as they are:
//! - the separator from the first line: `;`, tab or `,` (in that order of preference), or runs
//!   of spaces (columns of numbers aligned with spaces, as `.txt`/`.dat` exports of lab
//!   systems); with any but `,`, decimal commas (`1,5`) are read as well as points;
//! - a file without a header row when its columns are named ([`CsvOptions::columns`],
//!   `--columns t,enc,p_cyl`); a first line of numbers where names should be is refused with
//!   that hint;
//! - a units row found by its content (no number in it), or forced by
//!   [`CsvOptions::units_row`]; units in the header as `name [unit]`;
//! - `\n` or `\r\n` line ends, a last line without one (read, with a warning in
//!   `meta["warning"]`), lines numbered as an editor numbers them;
//! - numbers in Rust/Python float syntax (`1.5`, `-2e-3`, `NaN`, `inf`); an empty cell is a
//!   missing sample, read as NaN.

use crate::IoError;
use physid_core::{Basis, Recording};
use std::io::{BufRead, Read};
use std::path::Path;

/// How to read a CSV file.
#[derive(Debug, Clone, Default)]
pub struct CsvOptions {
    /// The second row holds units (it is also found without this, by its content).
    pub units_row: bool,
    /// Samples are on a crank-angle basis (also found without this by [`crate::read`]:
    /// `cycle` and `crank_deg` columns).
    pub crank_angle: bool,
    /// The file has no header row: its columns are these (a lab recording of bare numbers).
    pub columns: Option<Vec<String>>,
}

/// How a line separates its cells.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sep {
    /// `,` (decimal points only).
    Comma,
    /// `;`.
    Semicolon,
    /// One tab.
    Tab,
    /// Runs of spaces or tabs (a `.txt`/`.dat` export of columns of numbers).
    Whitespace,
}

impl Sep {
    /// The separator the first line uses: `;` or tab when present; else `,` when the cells are
    /// separated by commas (with or without a space after them); else runs of whitespace when
    /// the line has more than one cell; else `,`.
    fn of(line: &str) -> Self {
        if line.contains(';') {
            return Self::Semicolon;
        }
        if line.contains('\t') {
            return Self::Tab;
        }
        let cells: Vec<&str> = line.split_whitespace().collect();
        let by_commas = line.contains(',')
            && cells[..cells.len().saturating_sub(1)]
                .iter()
                .all(|c| c.ends_with(','));
        if !by_commas && cells.len() > 1 {
            Self::Whitespace
        } else {
            Self::Comma
        }
    }

    /// The byte the CSV parser splits on (whitespace runs are collapsed to one tab first).
    fn byte(self) -> u8 {
        match self {
            Self::Comma => b',',
            Self::Semicolon => b';',
            Self::Tab | Self::Whitespace => b'\t',
        }
    }
}

/// A text stream in which each run of spaces and tabs between two cells of a line becomes one
/// tab followed by spaces (those at a line's ends become spaces): columns of numbers aligned with
/// spaces, as the CSV parser splits them on tabs (and trims the spaces). Every byte keeps its
/// place, so a record's offset is its offset in the file and lines are counted as in any other
/// file.
struct Collapse<R> {
    inner: R,
    line: Vec<u8>,
    at: usize,
}

impl<R: BufRead> Read for Collapse<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.at == self.line.len() {
            self.line.clear();
            self.at = 0;
            if self.inner.read_until(b'\n', &mut self.line)? == 0 {
                return Ok(0);
            }
            let blank = |b: u8| b == b' ' || b == b'\t';
            let end = self
                .line
                .iter()
                .rposition(|&b| !blank(b) && b != b'\n' && b != b'\r')
                .map_or(0, |i| i + 1);
            let start = self.line.iter().position(|&b| !blank(b)).unwrap_or(end);
            let mut gap = false;
            for (i, b) in self.line.iter_mut().enumerate() {
                if !blank(*b) {
                    gap = false;
                    continue;
                }
                *b = if (start..end).contains(&i) && !gap {
                    gap = true;
                    b'\t'
                } else {
                    b' '
                };
            }
        }
        let n = buf.len().min(self.line.len() - self.at);
        buf[..n].copy_from_slice(&self.line[self.at..self.at + n]);
        self.at += n;
        Ok(n)
    }
}

/// A cell as a number: float syntax, or with a decimal comma where the separator allows one.
fn number(cell: &str, decimal_comma: bool) -> Option<f64> {
    if let Ok(v) = cell.parse::<f64>() {
        return Some(v);
    }
    if decimal_comma && cell.matches(',').count() == 1 && !cell.contains('.') {
        return cell.replace(',', ".").parse().ok();
    }
    None
}

/// Whether a row is a units row: nothing in it is a number (a dimensionless unit written
/// `1` is therefore not recognised: `--units-row` says so).
fn is_units_row(cells: &[String], decimal_comma: bool) -> bool {
    cells
        .iter()
        .all(|c| c.is_empty() || number(c, decimal_comma).is_none())
}

/// `name [unit]` → (`name`, `unit`); anything else is a name without a unit.
fn split_header(cell: &str) -> (String, String) {
    if let Some(stripped) = cell.strip_suffix(']') {
        if let Some((name, unit)) = stripped.rsplit_once('[') {
            let name = name.trim_end();
            if !name.is_empty() {
                return (name.to_string(), unit.trim().to_string());
            }
        }
    }
    (cell.to_string(), String::new())
}

/// Read a CSV file into a [`Recording`] (module docs). `meta["first_data_line"]` is the file
/// line of sample 0, so that sample `i` is on line `first_data_line + i`.
pub fn read_csv(path: impl AsRef<Path>, opts: &CsvOptions) -> Result<Recording, IoError> {
    let mut chunks = CsvChunks::open(path, opts, None)?;
    let (names, units, p) = (chunks.names.clone(), chunks.units.clone(), chunks.p.clone());
    let mut rec = crate::drain(
        Recording::new(chunks.basis),
        &names,
        &units,
        0,
        || chunks.next_columns(usize::MAX),
        &p,
    )?;
    // The metadata once the last row is read (a warning about it).
    rec.meta = chunks.header().meta;
    Ok(rec)
}

type CsvSource = Box<dyn Read + Send>;

/// A CSV file read a chunk of rows at a time: the header (and units row) on opening, then the
/// rows as they are asked for — [`read_csv`] is this, drained. Only the columns asked for are
/// parsed as numbers; every row's width is checked.
pub struct CsvChunks {
    p: String,
    path: std::path::PathBuf,
    rdr: csv::Reader<CsvSource>,
    record: csv::StringRecord,
    /// The columns read, in the order asked (all, in the file's order, by default).
    pub(crate) names: Vec<String>,
    pub(crate) units: Vec<String>,
    /// All of the file's columns (basis by columns is decided on them).
    all_names: Vec<String>,
    keep: Vec<usize>,
    width: usize,
    /// The columns are named by the user (`--columns`), not by a header row.
    named: bool,
    sep: Sep,
    basis: Basis,
    /// Records read so far (the header is record 1; blank lines count).
    row: usize,
    /// `record` holds a data row not yet taken.
    pending: bool,
    first_data_line: u64,
    /// The byte the last data row starts at.
    last_start: u64,
    warning: Option<String>,
}

impl CsvChunks {
    /// Open `path`: read its header, its units row (when there is one) and up to its first data
    /// row. `channels`: the file columns to read, in that order (all if `None`).
    pub fn open(
        path: impl AsRef<Path>,
        opts: &CsvOptions,
        channels: Option<&[String]>,
    ) -> Result<Self, IoError> {
        let path = path.as_ref();
        let p = path.display().to_string();
        let os = |source| IoError::Os {
            path: p.clone(),
            source,
        };
        let mut file = std::io::BufReader::new(std::fs::File::open(path).map_err(&os)?);
        // The header line decides the separator; it is read again by the CSV parser.
        let mut first = Vec::new();
        (&mut file)
            .take(1 << 20)
            .read_until(b'\n', &mut first)
            .map_err(&os)?;
        let sep = Sep::of(&String::from_utf8_lossy(&first));
        let text = std::io::Cursor::new(first).chain(file);
        let source: CsvSource = match sep {
            Sep::Whitespace => Box::new(Collapse {
                inner: std::io::BufReader::new(text),
                line: Vec::new(),
                at: 0,
            }),
            _ => Box::new(text),
        };
        let rdr = csv::ReaderBuilder::new()
            .has_headers(false)
            .delimiter(sep.byte())
            .flexible(true)
            .trim(csv::Trim::All)
            .from_reader(source);
        let mut s = Self {
            p,
            path: path.to_path_buf(),
            rdr,
            record: csv::StringRecord::new(),
            names: Vec::new(),
            units: Vec::new(),
            all_names: Vec::new(),
            keep: Vec::new(),
            width: 0,
            named: opts.columns.is_some(),
            sep,
            basis: if opts.crank_angle {
                Basis::CrankAngle
            } else {
                Basis::Time
            },
            row: 0,
            pending: false,
            first_data_line: 0,
            last_start: 0,
            warning: None,
        };
        let (names, mut units): (Vec<String>, Vec<String>) = match &opts.columns {
            // No header row: the columns are named by the user, the first line is data.
            Some(columns) => (columns.clone(), vec![String::new(); columns.len()]),
            None => {
                if !s.next_record()? || s.record.iter().all(str::is_empty) {
                    return Err(IoError::Empty {
                        path: s.p,
                        what: "no header row (expected channel names on the first line)",
                    });
                }
                s.row = 1;
                let decimal_comma = s.decimal_comma();
                if s.record.iter().all(|c| number(c, decimal_comma).is_some()) {
                    return Err(IoError::Malformed {
                        path: s.p,
                        detail: format!(
                            "line 1 holds {} numbers, not channel names: a file without a header row? Name its columns with --columns NAME,… (e.g. --columns t,enc,p_cyl)",
                            s.record.len()
                        ),
                    });
                }
                s.record.iter().map(split_header).unzip()
            }
        };
        s.width = names.len();
        s.advance()?;
        if s.pending && s.row == 2 && opts.columns.is_none() {
            let cells: Vec<String> = s.record.iter().map(str::to_string).collect();
            if opts.units_row || is_units_row(&cells, s.decimal_comma()) {
                for (u, cell) in units.iter_mut().zip(cells) {
                    if !cell.is_empty() {
                        *u = cell;
                    }
                }
                s.advance()?;
            }
        }
        if !s.pending {
            return Err(IoError::Empty {
                path: s.p,
                what: "no data rows after the header",
            });
        }
        s.first_data_line = s.line_here();
        s.keep = crate::positions(&names, channels, &s.p)?;
        s.names = s.keep.iter().map(|&j| names[j].clone()).collect();
        s.units = s.keep.iter().map(|&j| units[j].clone()).collect();
        s.all_names = names;
        Ok(s)
    }

    fn decimal_comma(&self) -> bool {
        self.sep != Sep::Comma
    }

    fn next_record(&mut self) -> Result<bool, IoError> {
        self.rdr
            .read_record(&mut self.record)
            .map_err(|e| IoError::Malformed {
                path: self.p.clone(),
                detail: e.to_string(),
            })
    }

    /// The line of the record just read. The parser's own line count is one short after `\r\n`
    /// ends (csv 1.3): lines are counted from the record's byte offset, when a line is needed
    /// (an error, the first data row), by counting the line ends up to it.
    fn line_here(&self) -> u64 {
        self.record
            .position()
            .map_or(0, |q| line_at(&self.path, q.byte()))
    }

    /// Read the next row that is not blank into `record` (`pending`), checking its width.
    fn advance(&mut self) -> Result<(), IoError> {
        self.pending = false;
        while self.next_record()? {
            self.row += 1;
            if self.record.len() == 1 && self.record.get(0) == Some("") {
                continue; // a blank line
            }
            if self.record.len() != self.width {
                return Err(IoError::Ragged {
                    path: self.p.clone(),
                    line: self.line_here(),
                    expected: self.width,
                    got: self.record.len(),
                    hint: if self.named {
                        " (the names --columns gives: name every column of the file)"
                    } else if self.sep == Sep::Comma && self.record.len() > self.width {
                        " (decimal commas? use ';' or tab separators with them)"
                    } else {
                        ""
                    },
                });
            }
            self.pending = true;
            return Ok(());
        }
        Ok(())
    }

    /// The recording's basis, metadata and (after the last chunk) warning, with no channels.
    pub fn header(&self) -> Recording {
        let mut rec = Recording::new(self.basis);
        rec.meta.insert("source".into(), self.p.clone());
        rec.meta
            .insert("first_data_line".into(), self.first_data_line.to_string());
        let sep = match self.sep {
            Sep::Comma => None,
            Sep::Semicolon => Some(";"),
            Sep::Tab => Some("tab"),
            Sep::Whitespace => Some("whitespace"),
        };
        if let Some(sep) = sep {
            rec.meta.insert("csv_separator".into(), sep.into());
        }
        if let Some(w) = &self.warning {
            rec.meta.insert("warning".into(), w.clone());
        }
        rec
    }

    /// Every column of the file, whether read or not.
    pub fn file_columns(&self) -> &[String] {
        &self.all_names
    }

    /// Up to `max_rows` rows of the columns read (`None` after the last row). An empty cell is a
    /// missing sample: NaN, which the integrity check reports and every consumer refuses or
    /// skips (`--on-bad`), never takes as a number.
    pub fn next_columns(&mut self, max_rows: usize) -> Result<Option<Vec<Vec<f64>>>, IoError> {
        if !self.pending {
            return Ok(None);
        }
        let mut columns: Vec<Vec<f64>> = vec![Vec::new(); self.keep.len()];
        let mut rows = 0;
        while self.pending && rows < max_rows {
            self.last_start = self.record.position().map_or(0, |q| q.byte());
            for (k, &j) in self.keep.iter().enumerate() {
                let cell = &self.record[j];
                if cell.is_empty() {
                    columns[k].push(f64::NAN);
                    continue;
                }
                let v = number(cell, self.decimal_comma()).ok_or_else(|| IoError::NotNumeric {
                    path: self.p.clone(),
                    line: self.line_here(),
                    column: self.all_names[j].clone(),
                    value: cell.to_string(),
                })?;
                columns[k].push(v);
            }
            rows += 1;
            self.advance()?;
        }
        if !self.pending
            && !ends_with_newline(&self.path).map_err(|source| IoError::Os {
                path: self.p.clone(),
                source,
            })?
        {
            self.warning = Some(format!(
                "the last line (line {}) has no line end: the file may have been cut short",
                line_at(&self.path, self.last_start)
            ));
        }
        Ok(Some(columns))
    }
}

/// The 1-based line of the file on which byte `at` lies (0 when the file cannot be read again:
/// the error that asked for the line is reported all the same).
fn line_at(path: &Path, at: u64) -> u64 {
    let Ok(f) = std::fs::File::open(path) else {
        return 0;
    };
    let mut n = 1;
    let mut buf = [0u8; 1 << 16];
    // After a `\r\n` the parser's record offset is that of the `\n` (it ended the line at
    // the `\r`), so the byte at `at` itself is counted too.
    let mut rest = f.take(at + 1);
    while let Ok(k) = rest.read(&mut buf) {
        if k == 0 {
            break;
        }
        n += buf[..k].iter().filter(|&&b| b == b'\n').count() as u64;
    }
    n
}

/// Whether the file's last byte is a line end (an empty file counts as ended).
fn ends_with_newline(path: &Path) -> std::io::Result<bool> {
    use std::io::{Seek, SeekFrom};
    let mut f = std::fs::File::open(path)?;
    if f.seek(SeekFrom::End(0))? == 0 {
        return Ok(true);
    }
    f.seek(SeekFrom::End(-1))?;
    let mut b = [0u8; 1];
    f.read_exact(&mut b)?;
    Ok(b[0] == b'\n')
}

/// Write a [`Recording`] as CSV (module docs: header row, then a units row when any channel
/// has a unit). Numbers are written in the shortest form that reads back to the same `f64`.
pub fn write_csv(path: impl AsRef<Path>, rec: &Recording) -> Result<(), IoError> {
    let mut w = CsvWriter::create(path, rec)?;
    w.append(rec)?;
    w.close()
}

/// Cut a torn last line (one without its line end: the writer was killed while writing it)
/// off a CSV file; the number of bytes cut.
pub fn recover_csv(path: impl AsRef<Path>) -> Result<u64, IoError> {
    use std::io::{Read, Seek, SeekFrom};
    let p = path.as_ref().display().to_string();
    let (mut f, size, os) = crate::open_torn(path.as_ref())?;
    // Back from the end a block at a time to the last line end.
    let mut end = size;
    let mut buf = vec![0u8; 64 * 1024];
    while end > 0 {
        let lo = end.saturating_sub(buf.len() as u64);
        let part = &mut buf[..(end - lo) as usize];
        f.seek(SeekFrom::Start(lo)).map_err(&os)?;
        f.read_exact(part).map_err(&os)?;
        if let Some(k) = part.iter().rposition(|&b| b == b'\n') {
            let keep = lo + k as u64 + 1;
            if keep < size {
                f.set_len(keep).map_err(&os)?;
                f.sync_all().map_err(&os)?;
            }
            return Ok(size - keep);
        }
        end = lo;
    }
    Err(IoError::Malformed {
        path: p,
        detail: "no whole line: not a CSV recording physid wrote".into(),
    })
}

/// A CSV file written chunk by chunk: the header (and units) row from the first recording,
/// then each chunk's rows as they come — the same bytes as [`write_csv`] of the whole. Each
/// chunk's rows reach the file whole, in one write: a writer killed leaves whole lines.
pub struct CsvWriter {
    path: String,
    names: Vec<String>,
    w: csv::Writer<Lines>,
    row: Vec<String>,
    rows: usize,
}

/// The file under a [`CsvWriter`]: bytes gathered until a flush, then written in one go.
struct Lines {
    file: std::fs::File,
    pending: Vec<u8>,
    bytes: usize,
}

impl std::io::Write for Lines {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.pending.extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.write_all(&self.pending)?;
        self.bytes += self.pending.len();
        self.pending.clear();
        Ok(())
    }
}

impl CsvWriter {
    /// Create `path` for recordings with `like`'s channels and units.
    pub fn create(path: impl AsRef<Path>, like: &Recording) -> Result<Self, IoError> {
        let p = path.as_ref().display().to_string();
        let file = crate::lock::create(path.as_ref())?;
        let mut w = csv::Writer::from_writer(Lines {
            file,
            pending: Vec::new(),
            bytes: 0,
        });
        let werr = |e: csv::Error| IoError::Malformed {
            path: p.clone(),
            detail: e.to_string(),
        };
        w.write_record(like.channels().iter().map(|c| c.name.as_str()))
            .map_err(werr)?;
        if like.channels().iter().any(|c| !c.unit.is_empty()) {
            w.write_record(like.channels().iter().map(|c| c.unit.as_str()))
                .map_err(werr)?;
        }
        let mut me = Self {
            names: like.channels().iter().map(|c| c.name.clone()).collect(),
            row: vec![String::new(); like.channels().len()],
            path: p,
            w,
            rows: 0,
        };
        me.write_out()?;
        Ok(me)
    }

    /// The lines gathered, to the file in one write.
    fn write_out(&mut self) -> Result<(), IoError> {
        self.w.flush().map_err(|source| IoError::Os {
            path: self.path.clone(),
            source,
        })
    }

    /// Append `rec`'s rows (the file's channels, in its order).
    pub fn append(&mut self, rec: &Recording) -> Result<(), IoError> {
        crate::check_appended(&self.path, &self.names, rec)?;
        for i in 0..rec.len() {
            for (cell, c) in self.row.iter_mut().zip(rec.channels()) {
                cell.clear();
                use std::fmt::Write;
                let _ = write!(cell, "{}", c.values[i]);
            }
            self.w
                .write_record(&self.row)
                .map_err(|e| IoError::Malformed {
                    path: self.path.clone(),
                    detail: e.to_string(),
                })?;
        }
        self.rows += rec.len();
        self.write_out()
    }

    /// Make every row appended so far survive a power loss too (they are in the file already).
    pub fn commit(&mut self) -> Result<(), IoError> {
        self.w
            .get_ref()
            .file
            .sync_data()
            .map_err(|source| IoError::Os {
                path: self.path.clone(),
                source,
            })
    }

    /// Rows written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Bytes written so far.
    pub fn bytes(&self) -> usize {
        self.w.get_ref().bytes
    }

    /// Finish the file.
    pub fn close(mut self) -> Result<(), IoError> {
        self.write_out()
    }
}
