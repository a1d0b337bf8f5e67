//! One module per verb.

pub mod bench;
pub mod convert;
pub mod demo;
pub mod estimate;
pub mod example;
pub mod filter;
pub mod friction;
pub mod identify;
pub mod inspect;
pub mod monitor;
pub mod run;
pub mod simulate;
pub mod torque;

use miette::{miette, IntoDiagnostic, Result};
use physid_core::Recording;
use std::path::Path;

/// How to read a recording file (every format: CSV, Parquet, MDF4 by extension).
#[derive(clap::Args, Clone, Debug, Default)]
pub struct InputArgs {
    /// Read the file's column COLUMN as channel NAME (repeatable), e.g. --map omega_en=EngSpeed;
    /// state its unit where the file gives none with :UNIT, e.g. --map omega_en=EngSpeed:rpm.
    /// Standard channels are converted to SI on reading (rpm → rad/s, deg → rad, °C → K, bar → Pa).
    #[arg(long = "map", value_name = "NAME=COLUMN[:UNIT]")]
    pub map: Vec<String>,
    /// CSV: the file's second row holds units (found without this flag when the row has no
    /// numbers).
    #[arg(long)]
    pub units_row: bool,
}

impl InputArgs {
    /// Read `path`, optionally only `channels` (physid names).
    pub fn read(&self, path: &Path, channels: Option<Vec<String>>) -> Result<Recording> {
        let map = physid_io::ReadOptions::parse_map(&self.map).map_err(|e| miette!("{e}"))?;
        physid_io::read(
            path,
            &physid_io::ReadOptions {
                channels,
                map,
                units_row: self.units_row,
                ..Default::default()
            },
        )
        .into_diagnostic()
    }
}

/// Where sample `i` of a recording read from a file is, for error messages: the CSV line
/// (from the reader's `first_data_line`), else the index.
pub fn locate(rec: &Recording, i: usize) -> String {
    match rec
        .meta
        .get("first_data_line")
        .and_then(|l| l.parse::<usize>().ok())
    {
        Some(l) => format!("line {} (sample {i})", l + i),
        None => format!("sample {i}"),
    }
}

/// `NAME=VALUE,…` into names and values.
pub fn named_values(items: &[String], flag: &str) -> Result<(Vec<String>, Vec<f64>)> {
    let mut names = Vec::new();
    let mut values = Vec::new();
    for item in items {
        let (n, v) = item
            .split_once('=')
            .ok_or_else(|| miette!("{flag} '{item}': expected NAME=VALUE"))?;
        let v: f64 = v
            .trim()
            .parse()
            .map_err(|_| miette!("{flag} '{item}': '{v}' is not a number"))?;
        names.push(n.trim().to_string());
        values.push(v);
    }
    Ok((names, values))
}
