//! A source gone over again and again ([`Reopen`]): a file read again on every pass, a
//! recording in memory, the windows a first pass gathered — the one shape of every analysis
//! that needs more than one pass (a Gauss–Newton fit is a pass per iteration, a raw angle
//! sensor a pass to calibrate and one to decode), so its memory is a chunk's, not the file's.
//!
//! A pass *hands* each chunk to a visitor rather than returning an iterator (arrow-rs's
//! `RecordBatchReader` is the latter), because a chunk may borrow the pass's own buffers —
//! an identifiability pass's rows are slices of the chunk just read. [`ChunkKind`] says what a
//! chunk is, for any lifetime of those buffers: [`Recordings`] (a [`Recording`]'s chunk, its
//! channels and samples) here, the model rows of `physid_ident` there.

use crate::Recording;

/// What one pass hands over at a time, for each lifetime `'c` of the pass's buffers.
pub trait ChunkKind: 'static {
    /// One chunk.
    type Chunk<'c>;
}

/// Chunks of a [`Recording`]: each one the recording's channels with some of its samples (a
/// first chunk may be the header alone, without samples).
#[derive(Debug, Clone, Copy)]
pub struct Recordings;

impl ChunkKind for Recordings {
    type Chunk<'c> = &'c Recording;
}

/// A source gone over more than once, in the same order each time, a chunk at a time (see the
/// module docs). `E`: what goes wrong in a pass.
pub trait Reopen<K: ChunkKind, E: 'static> {
    /// Go over the source once: `visit` every chunk in order. An error of `visit` ends the pass
    /// and is returned.
    fn pass(&self, visit: &mut dyn for<'c> FnMut(K::Chunk<'c>) -> Result<(), E>) -> Result<(), E>;
}

/// A recording in memory: one chunk, itself.
impl<E: 'static> Reopen<Recordings, E> for Recording {
    fn pass(&self, visit: &mut dyn for<'c> FnMut(&'c Recording) -> Result<(), E>) -> Result<(), E> {
        visit(self)
    }
}
