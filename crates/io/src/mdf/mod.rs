//! ASAM MDF4 recordings through `falcon_mdf` (DESIGN.md: the crate that reads asammdf's
//! compressed files and angle masters).
//!
//! Reading: one channel group's time base makes one [`Recording`]. With a channel list, the
//! channels asked for (they must share a master); without, every channel of every group on the
//! same master as the first group with data (the others are named in `meta["skipped"]`). A time
//! master (sync type 1) becomes channel `t` [s] on a time basis; an angle master (sync type 2)
//! becomes `theta` [rad] on a crank-angle basis — MDF4 angle masters are in radians whatever
//! their unit label says (asammdf labels them "deg"; the label is kept in
//! `meta["master_unit_label"]`). Values are physical: the channel conversions are applied.
//! Uncompressed, deflate (DZ) and transposed-deflate data blocks are read.
//!
//! Writing: one group, every channel as float64, the time master from the recording's `t`
//! channel (MDF4 files carry a time master; a crank-angle recording keeps its angle in
//! `theta`, its `cycle` and `crank_deg` as ordinary channels). Optional deflate or
//! transposed-deflate compression: [`write_mdf`] (`falcon_mdf`) deflates a whole recording into
//! one `##DZ` block; [`MdfWriter`] writes as the samples come, in blocks of at most
//! [`MDF_BLOCK_BYTES`] of records each deflated into a `##DZ`, listed at the end by a
//! `##HL`/`##DL` pair.
//!
//! `read.rs`: reading; `write.rs`: writing (the streaming writer's block-level work included).

use crate::IoError;
use falcon_mdf::blocks::channel::SyncType;
use falcon_mdf::write::WriteCodec;
use falcon_mdf::{Mf4File, Mf4Writer};
use physid_core::{Basis, Channel, Recording};
use std::path::Path;

mod read;
mod write;

pub use read::*;
pub use write::*;

/// Data-block compression when writing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MdfCompression {
    /// Plain data blocks.
    #[default]
    None,
    /// Deflate (`##DZ`, zip type 0).
    Deflate,
    /// Transposed deflate (zip type 1; asammdf's `compression=2`).
    TransposedDeflate,
}

fn mdf_err(path: &str, e: impl std::fmt::Display) -> IoError {
    IoError::Malformed {
        path: path.into(),
        detail: format!("MDF4: {e}"),
    }
}
