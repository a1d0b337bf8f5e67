//! One module per verb.

pub mod bench;
pub mod estimate;
pub mod example;
pub mod friction;
pub mod identify;

use miette::{miette, Result};

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
