//! The CRC-32 of every column chunk of the Parquet files physid writes, and their check when a
//! file is read: a byte changed on a disk, a copy cut short or patched, is an error naming the
//! column and the rows, never values read as if nothing had happened.
//!
//! The `parquet` crate writes no page checksums (its writer leaves the page header's `crc`
//! unset; its reader checks the ones other writers set — pyarrow's `write_page_checksum`,
//! parquet-mr's — with the `crc` feature, which physid enables). So [`ParquetWriter`] hashes
//! each column chunk as the crate splices its pages into the file ([`ChunkCrcs`], a page store
//! that hashes what is taken from it, in the file's order) and writes the sums in the file's
//! key-value metadata under [`KEY`]: row group after row group, `START:crc,crc,…` (`START` the
//! row group's first byte, then the standard CRC-32 of each column chunk's bytes in column
//! order, 8 hex digits), separated by `;`. Each journal entry carries its own row group's, so a
//! file [`recover_parquet`] restores keeps them.
//!
//! A reader checks a row group's chunks of the columns it reads before it hands out any of its
//! rows ([`Checks`]). The sums are checked only where they describe this file's layout (the
//! same row groups starting at the same bytes, one sum per column): a tool that rewrites the
//! file and carries the metadata along (pyarrow keeps it) leaves sums that are not this file's,
//! and they are passed over, not taken for damage.
//!
//! [`ParquetWriter`]: crate::parquet_file::ParquetWriter
//! [`recover_parquet`]: crate::parquet_file::recover_parquet

use crate::parquet_file::group_span;
use crate::IoError;
use bytes::Bytes;
use parquet::arrow::arrow_writer::{
    InMemoryPageStore, PageKey, PageStore, PageStoreArgs, PageStoreFactory,
};
use parquet::file::metadata::{KeyValue, ParquetMetaData};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::sync::{Arc, Mutex, PoisonError};

/// The key-value metadata entry holding the column chunks' sums.
pub(crate) const KEY: &str = "physid.chunk_crc32";

/// The page stores of an `ArrowWriter`, each hashing its column chunk's pages as the writer
/// takes them back to splice them into the file (header and data, in the file's order): after
/// a row group is flushed, [`take`](Self::take) gives each column chunk's CRC-32.
#[derive(Debug, Clone, Default)]
pub(crate) struct ChunkCrcs(Arc<Mutex<Vec<crc32fast::Hasher>>>);

impl ChunkCrcs {
    /// The sums of the column chunks flushed since the last call, in column order (`columns`
    /// of them), and fresh hashers for the next row group.
    pub(crate) fn take(&self, columns: usize) -> Vec<u32> {
        let mut h = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        h.resize_with(columns, crc32fast::Hasher::new);
        h.iter_mut().map(|h| std::mem::take(h).finalize()).collect()
    }
}

impl PageStoreFactory for ChunkCrcs {
    fn create(&self, args: &PageStoreArgs<'_>) -> parquet::errors::Result<Box<dyn PageStore>> {
        Ok(Box::new(HashingStore {
            pages: InMemoryPageStore::default(),
            crcs: self.0.clone(),
            column: args.column_index(),
        }))
    }
}

/// One column chunk's pages, held in memory as the crate's default store holds them, hashed
/// as they are taken out to be written.
struct HashingStore {
    pages: InMemoryPageStore,
    crcs: Arc<Mutex<Vec<crc32fast::Hasher>>>,
    column: usize,
}

impl PageStore for HashingStore {
    fn put(&mut self, value: Bytes) -> parquet::errors::Result<PageKey> {
        self.pages.put(value)
    }

    fn take(&mut self, key: PageKey) -> parquet::errors::Result<Bytes> {
        let page = self.pages.take(key)?;
        let mut h = self.crcs.lock().unwrap_or_else(PoisonError::into_inner);
        if h.len() <= self.column {
            h.resize_with(self.column + 1, crc32fast::Hasher::new);
        }
        h[self.column].update(&page);
        Ok(page)
    }

    fn memory_size(&self) -> usize {
        self.pages.memory_size()
    }
}

/// One row group's entry under [`KEY`]: `START:crc,crc,…`.
pub(crate) fn entry(start: u64, crcs: &[u32]) -> String {
    let sums: Vec<String> = crcs.iter().map(|c| format!("{c:08x}")).collect();
    format!("{start}:{}", sums.join(","))
}

/// The [`KEY`] entry of a key-value list, if it has one.
pub(crate) fn find(kv: Option<&Vec<KeyValue>>) -> Option<&str> {
    kv?.iter()
        .find(|e| e.key == KEY)
        .and_then(|e| e.value.as_deref())
}

/// `kv` without its [`KEY`] entry, with `value` under [`KEY`] if given.
pub(crate) fn with_entry(
    kv: Option<&Vec<KeyValue>>,
    value: Option<String>,
) -> Option<Vec<KeyValue>> {
    let mut out: Vec<KeyValue> = kv
        .map(|kv| kv.iter().filter(|e| e.key != KEY).cloned().collect())
        .unwrap_or_default();
    if let Some(v) = value {
        out.push(KeyValue::new(KEY.to_string(), v));
    }
    (!out.is_empty()).then_some(out)
}

/// One column chunk to check: its column's name, its bytes and the sum written with it.
#[derive(Debug)]
struct Chunk {
    name: String,
    start: u64,
    len: u64,
    crc: u32,
}

/// The row groups of a file to check, as they are reached.
#[derive(Debug)]
struct Group {
    rows: std::ops::Range<u64>,
    chunks: Vec<Chunk>,
}

/// The column chunks of the columns read and the sums physid wrote with them; each row group
/// is checked once, before any of its rows is handed out ([`before`](Self::before)).
#[derive(Debug, Default)]
pub(crate) struct Checks {
    groups: Vec<Group>,
    /// Row groups checked so far.
    done: usize,
    buf: Vec<u8>,
    /// The file, opened anew: the crate's reader reads through handles that share one offset.
    file: Option<File>,
}

impl Checks {
    /// The checks of the chunks of `leaves` (leaf column indices) in the file at `path`, whose
    /// metadata is `meta`: none when the file has no sums of physid's, or sums that do not
    /// describe its layout.
    pub(crate) fn new(
        meta: &ParquetMetaData,
        leaves: &[usize],
        path: &std::path::Path,
    ) -> std::io::Result<Self> {
        let mut checks = Self::of(meta, leaves);
        if !checks.groups.is_empty() {
            checks.file = Some(File::open(path)?);
        }
        Ok(checks)
    }

    fn of(meta: &ParquetMetaData, leaves: &[usize]) -> Self {
        let Some(sums) = find(meta.file_metadata().key_value_metadata()) else {
            return Self::default();
        };
        let entries: Vec<&str> = sums.split(';').collect();
        if entries.len() != meta.num_row_groups() {
            return Self::default();
        }
        let mut groups = Vec::with_capacity(entries.len());
        let mut row = 0u64;
        for (g, e) in meta.row_groups().iter().zip(entries) {
            let Some((start, crcs)) = e.split_once(':') else {
                return Self::default();
            };
            let crcs: Option<Vec<u32>> = crcs
                .split(',')
                .map(|c| u32::from_str_radix(c, 16).ok())
                .collect();
            let (Some(crcs), Ok(start)) = (crcs, start.parse::<u64>()) else {
                return Self::default();
            };
            if crcs.len() != g.num_columns() || group_span(g).map(|s| s.0) != Some(start) {
                return Self::default();
            }
            let rows = u64::try_from(g.num_rows()).unwrap_or(0);
            let chunks = leaves
                .iter()
                .filter_map(|&leaf| {
                    let c = g.columns().get(leaf)?;
                    Some(Chunk {
                        name: c.column_path().string(),
                        start: u64::try_from(
                            c.dictionary_page_offset().unwrap_or(c.data_page_offset()),
                        )
                        .ok()?,
                        len: u64::try_from(c.compressed_size()).ok()?,
                        crc: crcs[leaf],
                    })
                })
                .collect();
            groups.push(Group {
                rows: row..row + rows,
                chunks,
            });
            row += rows;
        }
        Self {
            groups,
            ..Self::default()
        }
    }

    /// Check every row group not yet checked that holds a row before `end` (the rows about to
    /// be read end there).
    pub(crate) fn before(&mut self, end: u64, path: &str) -> Result<(), IoError> {
        const WINDOW: usize = 1 << 20;
        let Some(f) = self.file.as_mut() else {
            return Ok(());
        };
        while let Some(g) = self.groups.get(self.done) {
            if g.rows.start >= end {
                break;
            }
            for c in &g.chunks {
                let mut h = crc32fast::Hasher::new();
                let read = f.seek(SeekFrom::Start(c.start)).and_then(|_| {
                    let mut left = c.len;
                    while left > 0 {
                        let n = WINDOW.min(usize::try_from(left).unwrap_or(WINDOW));
                        self.buf.resize(n, 0);
                        f.read_exact(&mut self.buf)?;
                        h.update(&self.buf);
                        left -= n as u64;
                    }
                    Ok(())
                });
                let found = read.map(|()| h.finalize());
                if found.as_ref().ok() != Some(&c.crc) {
                    let what = match found {
                        Ok(crc) => format!("its CRC-32 is {crc:08x}, physid wrote {:08x}", c.crc),
                        Err(e) => format!("it cannot be read: {e}"),
                    };
                    return Err(IoError::Malformed {
                        path: path.into(),
                        detail: format!(
                            "corrupt Parquet: column '{}' of row group {} (rows {} to {}, bytes \
                             {} to {}) is not what physid wrote: {what}; the file was damaged or \
                             changed after it was written",
                            c.name,
                            self.done,
                            g.rows.start,
                            g.rows.end.saturating_sub(1),
                            c.start,
                            c.start + c.len,
                        ),
                    });
                }
            }
            self.done += 1;
        }
        Ok(())
    }
}
