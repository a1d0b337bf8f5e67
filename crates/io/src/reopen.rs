//! A file gone over in passes ([`FileChunks`]): a [`Reopen`] of [`Recordings`] that opens a
//! [`ChunkReader`] on every pass — memory a chunk's, whatever the file's length.

use crate::{ChunkReader, IoError, ReadOptions};
use physid_core::{Recording, Recordings, Reopen};
use std::path::{Path, PathBuf};

/// A recording file read again on every pass, with the same options ([`ChunkReader::open`]):
/// each chunk as the reader gives it, in the header's channels and units. What the reader
/// noticed (a cut-short last line) is in each chunk's reader, not said here.
#[derive(Debug, Clone)]
pub struct FileChunks {
    path: PathBuf,
    opts: ReadOptions,
    /// The file is not written over by this process between the passes either.
    _reading: crate::lock::Reading,
}

impl FileChunks {
    /// `path`, read with `opts`.
    pub fn new(path: impl AsRef<Path>, opts: ReadOptions) -> Self {
        Self {
            path: path.as_ref().to_path_buf(),
            opts,
            _reading: crate::lock::Reading::new(path.as_ref()),
        }
    }
}

/// A pass's errors — the file's, or the visitor's — in the caller's error type.
impl<E: From<IoError> + 'static> Reopen<Recordings, E> for FileChunks {
    fn pass(&self, visit: &mut dyn for<'c> FnMut(&'c Recording) -> Result<(), E>) -> Result<(), E> {
        for chunk in ChunkReader::open(&self.path, &self.opts)? {
            visit(&chunk?)?;
        }
        Ok(())
    }
}
