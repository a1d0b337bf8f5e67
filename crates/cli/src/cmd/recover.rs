//! `physid recover FILE`: make a recording whose writer was killed (`kill -9`, a power loss)
//! readable up to its last commit — a live log, `simulate`'s or `convert`'s output. Parquet:
//! the footer written from the journal entries ([`physid_io::recover_parquet`]); CSV: a torn
//! last line cut off; MDF4 (uncompressed): readable as it is, its record count says how many
//! samples were committed.

use crate::out::outln;
use miette::{miette, Result};
use physid_io::{Format, Recovered};
use std::path::PathBuf;

/// Arguments of `physid recover`.
#[derive(clap::Args)]
pub struct Args {
    /// The file (changed in place: the torn end after the last commit is cut off).
    pub file: PathBuf,
}

/// Run `physid recover`.
pub fn run(a: &Args) -> Result<()> {
    let path = &a.file;
    let shown = path.display();
    match Format::from_extension(path) {
        Some(Format::Parquet) => {
            match physid_io::recover_parquet(path).map_err(|e| miette!("{e}"))? {
                Recovered::Closed => outln!("{shown}: closed properly: nothing to recover"),
                Recovered::Restored {
                    rows,
                    groups,
                    dropped,
                } => outln!(
                "{shown}: recovered {rows} samples in {groups} row groups; {dropped} bytes after \
                 the last commit cut off"
            ),
            }
        }
        Some(Format::Csv) => {
            let cut = physid_io::recover_csv(path).map_err(|e| miette!("{e}"))?;
            if cut == 0 {
                outln!("{shown}: every line is whole: nothing to recover");
            } else {
                outln!("{shown}: a torn last line of {cut} bytes cut off");
            }
        }
        Some(Format::Mdf4) => {
            physid_io::refuse_to_recover_while_written(path).map_err(|e| miette!("{e}"))?;
            // Read through, a chunk at a time: what a reader finds.
            let mut reader = physid_io::ChunkReader::open(path, &Default::default())
                .map_err(|e| miette!("{e}"))?;
            let mut samples = 0;
            while let Some(chunk) = reader.next_chunk().map_err(|e| miette!("{e}"))? {
                samples += chunk.len();
            }
            outln!(
                "{shown}: readable as it is: {samples} samples (an MDF4 log says how many \
                 records it holds at each commit)"
            );
        }
        None => {
            return Err(miette!(
                "{shown}: unknown extension: expected .csv, .parquet or .mf4"
            ))
        }
    }
    Ok(())
}
