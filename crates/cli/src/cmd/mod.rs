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
    /// Read the file's column COLUMN as channel NAME (repeatable), e.g. --map omega_en=EngSpeed.
    #[arg(long = "map", value_name = "NAME=COLUMN")]
    pub map: Vec<String>,
    /// CSV: the file's second row holds units.
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
                crank_angle: false,
            },
        )
        .into_diagnostic()
    }

    /// Where sample `i` of `path` is, for error messages: the CSV line, else the index.
    pub fn locate(&self, path: &Path, i: usize) -> String {
        match physid_io::Format::from_extension(path) {
            Some(physid_io::Format::Csv) => {
                format!("line {} (sample {i})", i + 2 + usize::from(self.units_row))
            }
            _ => format!("sample {i}"),
        }
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
