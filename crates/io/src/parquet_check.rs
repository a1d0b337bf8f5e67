//! A Parquet file's claims checked against its bytes before the `parquet` crate decodes it:
//! the footer and the page header of every page of the columns read are walked with
//! [`crate::thrift_walk`], and each page must lie inside its column chunk and the file. Every
//! loop here advances by at least one byte, so the check is linear in the bytes it reads (the
//! footer, and the page headers: a seek and a small read per page).

use crate::thrift_walk::{page_header, Walk, WalkError};
use crate::IoError;
use parquet::file::metadata::ParquetMetaData;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};

/// A page header is read in windows of this many bytes (doubled while it does not fit, up to
/// the end of its column chunk).
const HEADER_WINDOW: usize = 1024;

fn corrupt(path: &str, detail: String) -> IoError {
    IoError::Malformed {
        path: path.into(),
        detail: format!("corrupt Parquet: {detail}"),
    }
}

fn read_at(f: &mut File, at: u64, buf: &mut Vec<u8>, len: usize) -> std::io::Result<()> {
    buf.resize(len, 0);
    f.seek(SeekFrom::Start(at))?;
    f.read_exact(buf)
}

/// The footer (the `FileMetaData` before the last 8 bytes) is one complete Thrift struct
/// whose every count its bytes bear. A file that does not end in `PAR1` is left to the crate
/// (which says so).
pub(crate) fn footer(f: &mut File, path: &str) -> Result<(), IoError> {
    let os = |source| IoError::Os {
        path: path.into(),
        source,
    };
    let len = f.metadata().map_err(os)?.len();
    if len < 12 {
        return Ok(());
    }
    let mut tail = Vec::new();
    read_at(f, len - 8, &mut tail, 8).map_err(os)?;
    if &tail[4..] != b"PAR1" {
        return Ok(());
    }
    let n = u64::from(u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]));
    if n + 12 > len {
        return Ok(());
    }
    let at = len - 8 - n;
    let mut buf = Vec::new();
    read_at(f, at, &mut buf, n as usize).map_err(os)?;
    Walk::new(&buf).structure(|_, _, _| Ok(())).map_err(|e| {
        corrupt(
            path,
            format!("the footer ({n} bytes from byte {at}) is not Parquet metadata: {e}"),
        )
    })?;
    Ok(())
}

/// The pages of the column chunks of `leaves` (leaf column indices) in every row group: each
/// header a complete Thrift struct whose counts its bytes bear, each page inside its chunk,
/// each chunk inside the file.
pub(crate) fn pages(
    f: &mut File,
    path: &str,
    meta: &ParquetMetaData,
    leaves: &[usize],
) -> Result<(), IoError> {
    let os = |source| IoError::Os {
        path: path.into(),
        source,
    };
    let file_len = f.metadata().map_err(os)?.len();
    let mut buf = Vec::new();
    for (g, group) in meta.row_groups().iter().enumerate() {
        for &leaf in leaves {
            let Some(col) = group.columns().get(leaf) else {
                continue;
            };
            let name = col.column_path().string();
            let start = col
                .dictionary_page_offset()
                .unwrap_or_else(|| col.data_page_offset());
            let size = col.compressed_size();
            let end = start.checked_add(size).unwrap_or(i64::MAX);
            if start < 0 || size < 0 || end as u64 > file_len {
                return Err(corrupt(
                    path,
                    format!(
                        "column '{name}' of row group {g} claims bytes {start} to {end} of a file of {file_len}"
                    ),
                ));
            }
            let (mut at, end) = (start as u64, end as u64);
            while at < end {
                let room = (end - at) as usize;
                let mut window = HEADER_WINDOW.min(room);
                let (len, page) = loop {
                    read_at(f, at, &mut buf, window).map_err(os)?;
                    match page_header(&buf) {
                        Err(WalkError::Short(_)) if window < room => window = (2 * window).min(room),
                        Err(e) => {
                            return Err(corrupt(
                                path,
                                format!(
                                    "the page header at byte {at} of column '{name}' (row group {g}) is not one: {e}"
                                ),
                            ))
                        }
                        Ok(h) => break h,
                    }
                };
                let next = at + len as u64 + page as u64;
                if next > end {
                    return Err(corrupt(
                        path,
                        format!(
                            "the page at byte {at} of column '{name}' (row group {g}) runs to byte {next}, past its column's end at {end}"
                        ),
                    ));
                }
                at = next;
            }
        }
    }
    Ok(())
}
