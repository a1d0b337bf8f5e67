//! A file in use is left alone.
//!
//! **Being read.** A file this process reads (a [`ChunkReader`](crate::ChunkReader) open on it,
//! a [`FileChunks`](crate::FileChunks) going over it in passes) is not written over or
//! replaced by it ([`Reading`]): `physid convert run.parquet run.parquet`, `physid filter
//! a.csv a.csv` would empty the recording they read (the output is created first) — they are
//! refused before a byte is written. Files are told apart by device and inode, so another
//! name for the same file (a link, `./`, a relative path) is the same file.
//!
//! **Being written.** A file being written is its writer's alone: every file physid writes as
//! it comes (a live log, `simulate`'s and `convert`'s output, a verb's tracks) is locked by its
//! writer for as long as it writes (an exclusive `flock`, released by the close or by the
//! process's end, a `kill -9` too), and nothing physid does to a path destroys a file whose
//! writer holds it:
//!
//! - a writer refuses to create over it ([`create`]) — truncating it would lose the log;
//! - a whole write refuses to rename over it ([`refuse_if_in_use`]) — the writer would go on
//!   into a file no longer in the directory, lost when it closes;
//! - `physid recover` and the salvage of a failed write refuse to mend it
//!   ([`open_to_mend`]) — cutting its torn end would cut what its writer is writing;
//! - a reader that cannot read it says why ([`while_written`]): its footer or its record
//!   count comes when it is closed or committed, it is not damaged.
//!
//! A file system that does not lock (some network and FUSE file systems) is written unlocked,
//! as before: the lock protects, it never stops a write.

use crate::IoError;
use std::fs::{File, OpenOptions, TryLockError};
use std::os::unix::fs::MetadataExt;
use std::path::Path;
use std::sync::Mutex;

/// The error for `path`, locked by its writer, which cannot be `doing`.
fn busy(path: &Path, doing: &str) -> IoError {
    IoError::InUse {
        path: path.display().to_string(),
        detail: format!("is being written (another program holds it locked): {doing}"),
    }
}

/// A file's identity: its device and inode.
type FileId = (u64, u64);

fn file_id(path: &Path) -> Option<FileId> {
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

/// The files this process is reading, each with its readers' count.
static READING: Mutex<Vec<(FileId, usize)>> = Mutex::new(Vec::new());

fn reading() -> std::sync::MutexGuard<'static, Vec<(FileId, usize)>> {
    // A reader that panicked leaves the list as consistent as before its push or pop.
    READING
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A reader of a file, counted while it lives: the file is not written over or replaced by
/// this process meanwhile (module docs).
#[derive(Debug)]
pub(crate) struct Reading(Option<FileId>);

impl Reading {
    /// `path` being read (nothing, if it cannot be found: its reader says so).
    pub(crate) fn new(path: &Path) -> Self {
        let id = file_id(path);
        if let Some(id) = id {
            let mut r = reading();
            match r.iter_mut().find(|(f, _)| *f == id) {
                Some((_, n)) => *n += 1,
                None => r.push((id, 1)),
            }
        }
        Self(id)
    }
}

impl Clone for Reading {
    fn clone(&self) -> Self {
        if let Some(id) = self.0 {
            if let Some((_, n)) = reading().iter_mut().find(|(f, _)| *f == id) {
                *n += 1;
            }
        }
        Self(self.0)
    }
}

impl Drop for Reading {
    fn drop(&mut self) {
        let Some(id) = self.0 else { return };
        let mut r = reading();
        if let Some(k) = r.iter().position(|(f, _)| *f == id) {
            r[k].1 -= 1;
            if r[k].1 == 0 {
                r.swap_remove(k);
            }
        }
    }
}

/// Refuse to write `path` while this process reads it.
fn refuse_if_read(path: &Path) -> Result<(), IoError> {
    let Some(id) = file_id(path) else {
        return Ok(());
    };
    if reading().iter().any(|(f, _)| *f == id) {
        return Err(IoError::InUse {
            path: path.display().to_string(),
            detail: "is also what this command reads: writing it would destroy the recording \
                     being read; give the output another name"
                .into(),
        });
    }
    Ok(())
}

/// Whether another open file holds `path` locked for writing (`false` when it does not
/// exist, cannot be opened, or its file system does not lock).
pub(crate) fn is_being_written(path: &Path) -> bool {
    let Ok(f) = File::open(path) else {
        return false;
    };
    // The file is closed at once, and the shared lock with it.
    matches!(f.try_lock_shared(), Err(TryLockError::WouldBlock))
}

/// `path` created for writing (emptied if it exists) and locked for as long as the file is
/// open — refused, the file untouched, when another writer holds it.
pub(crate) fn create(path: &Path) -> Result<File, IoError> {
    refuse_if_read(path)?;
    let os = |source| IoError::Os {
        path: path.display().to_string(),
        source,
    };
    // Not truncated on opening: a file another writer holds must be left as it is.
    let f = OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(false)
        .open(path)
        .map_err(os)?;
    match f.try_lock() {
        Ok(()) | Err(TryLockError::Error(_)) => {}
        Err(TryLockError::WouldBlock) => {
            return Err(busy(
                path,
                "not written over (that would lose what it holds): give another name, or wait \
                 until its writer closes it",
            ))
        }
    }
    f.set_len(0).map_err(os)?;
    Ok(f)
}

/// Refuse to replace `path` (a whole write's rename) while this process reads it or another
/// writer holds it.
pub(crate) fn refuse_if_in_use(path: &Path) -> Result<(), IoError> {
    refuse_if_read(path)?;
    if is_being_written(path) {
        return Err(busy(
            path,
            "not replaced (its writer would go on into a file no longer there, lost when it \
             closes): give another name, or wait until its writer closes it",
        ));
    }
    Ok(())
}

/// A file a writer was killed while writing, opened to be mended in place (read and write)
/// and locked while it is: refused when its writer is still writing it (nothing to mend).
pub(crate) fn open_to_mend(path: &Path) -> Result<File, IoError> {
    let f = OpenOptions::new()
        .read(true)
        .write(true)
        .open(path)
        .map_err(|source| IoError::Os {
            path: path.display().to_string(),
            source,
        })?;
    match f.try_lock() {
        Ok(()) | Err(TryLockError::Error(_)) => Ok(f),
        Err(TryLockError::WouldBlock) => Err(busy(path, NOTHING_TO_RECOVER)),
    }
}

/// Why a file being written is not mended.
const NOTHING_TO_RECOVER: &str = "its writer has not stopped, so there is nothing to recover: \
     it is made readable as its writer closes it (a live log: the `record` control with \
     \"stop\": true, or the run's end). Run `physid recover` only on a file whose writer was \
     killed";

/// Refuse to recover `path` while its writer holds it (a file `physid recover` only reads: an
/// uncompressed MDF4 log, readable as it is).
pub fn refuse_to_recover_while_written(path: &Path) -> Result<(), IoError> {
    if is_being_written(path) {
        return Err(busy(path, NOTHING_TO_RECOVER));
    }
    Ok(())
}

/// `e`, an error reading `path`, said as a file still being written when another writer holds
/// it locked: its footer (Parquet) comes when its writer closes it.
pub(crate) fn while_written(path: &Path, e: IoError) -> IoError {
    if matches!(e, IoError::Os { .. } | IoError::InUse { .. }) || !is_being_written(path) {
        return e;
    }
    busy(
        path,
        &format!(
            "it is readable once its writer closes it (a live log: the `record` control with \
             \"stop\": true, or the run's end); it is not damaged — do not run `physid recover` \
             on it while it is written. The reader said: {e}"
        ),
    )
}
