//! CSV recordings: a header row of channel names, optionally a second row of units, then one
//! row per sample. Numbers in Rust/Python float syntax (`1.5`, `-2e-3`, `NaN`, `inf`).

use crate::IoError;
use physid_core::{Basis, Channel, Recording};
use std::path::Path;

/// How to read a CSV file.
#[derive(Debug, Clone, Default)]
pub struct CsvOptions {
    /// The second row holds units (`s`, `rad/s`, `N*m`, …) rather than data.
    pub units_row: bool,
    /// Samples are on a crank-angle basis (default: time).
    pub crank_angle: bool,
}

fn malformed(path: &str, e: csv::Error) -> IoError {
    match e.kind() {
        csv::ErrorKind::UnequalLengths {
            pos,
            expected_len,
            len,
        } => IoError::Ragged {
            path: path.into(),
            line: pos.as_ref().map_or(0, |p| p.line()),
            expected: *expected_len as usize,
            got: *len as usize,
        },
        _ => IoError::Malformed {
            path: path.into(),
            detail: e.to_string(),
        },
    }
}

/// Read a CSV file into a [`Recording`].
pub fn read_csv(path: impl AsRef<Path>, opts: &CsvOptions) -> Result<Recording, IoError> {
    let p = path.as_ref().display().to_string();
    let file = std::fs::File::open(path.as_ref()).map_err(|source| IoError::Os {
        path: p.clone(),
        source,
    })?;
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(std::io::BufReader::new(file));
    let headers: Vec<String> = rdr
        .headers()
        .map_err(|e| malformed(&p, e))?
        .iter()
        .map(str::to_string)
        .collect();
    if headers.is_empty() || headers.iter().all(String::is_empty) {
        return Err(IoError::Empty {
            path: p,
            what: "no header row (expected channel names on the first line)",
        });
    }
    let mut units = vec![String::new(); headers.len()];
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); headers.len()];
    let mut record = csv::StringRecord::new();
    let mut first = true;
    loop {
        match rdr.read_record(&mut record) {
            Ok(false) => break,
            Ok(true) => {}
            Err(e) => return Err(malformed(&p, e)),
        }
        let line = record.position().map_or(0, |q| q.line());
        if first && opts.units_row {
            first = false;
            for (u, cell) in units.iter_mut().zip(record.iter()) {
                *u = cell.to_string();
            }
            continue;
        }
        first = false;
        for (j, cell) in record.iter().enumerate() {
            let v: f64 = cell.parse().map_err(|_| IoError::NotNumeric {
                path: p.clone(),
                line,
                column: headers[j].clone(),
                value: cell.to_string(),
            })?;
            columns[j].push(v);
        }
    }
    if columns[0].is_empty() {
        return Err(IoError::Empty {
            path: p,
            what: "no data rows after the header",
        });
    }
    let mut rec = Recording::new(if opts.crank_angle {
        Basis::CrankAngle
    } else {
        Basis::Time
    });
    rec.meta.insert("source".into(), p.clone());
    for ((name, unit), values) in headers.into_iter().zip(units).zip(columns) {
        rec.push(Channel { name, unit, values })
            .map_err(|source| IoError::Recording {
                path: p.clone(),
                source,
            })?;
    }
    Ok(rec)
}

/// Write a [`Recording`] as CSV (header row, then a units row when any channel has a unit).
/// Numbers are written in the shortest form that reads back to the same `f64`.
pub fn write_csv(path: impl AsRef<Path>, rec: &Recording) -> Result<(), IoError> {
    let p = path.as_ref().display().to_string();
    let os = |source| IoError::Os {
        path: p.clone(),
        source,
    };
    let file = std::fs::File::create(path.as_ref()).map_err(os)?;
    let mut w = csv::Writer::from_writer(std::io::BufWriter::new(file));
    let werr = |e: csv::Error| IoError::Malformed {
        path: p.clone(),
        detail: e.to_string(),
    };
    w.write_record(rec.channels().iter().map(|c| c.name.as_str()))
        .map_err(werr)?;
    if rec.channels().iter().any(|c| !c.unit.is_empty()) {
        w.write_record(rec.channels().iter().map(|c| c.unit.as_str()))
            .map_err(werr)?;
    }
    let mut row: Vec<String> = vec![String::new(); rec.channels().len()];
    for i in 0..rec.len() {
        for (cell, c) in row.iter_mut().zip(rec.channels()) {
            cell.clear();
            use std::fmt::Write;
            let _ = write!(cell, "{}", c.values[i]);
        }
        w.write_record(&row).map_err(werr)?;
    }
    w.flush().map_err(os)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str, text: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("physid-io-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn reads_units_row_and_round_trips_exactly() {
        let p = tmp("a.csv", "t,omega\ns,rad/s\n0,1.5\n0.001,0.1\n");
        let r = read_csv(
            &p,
            &CsvOptions {
                units_row: true,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(r.values("omega").unwrap(), &[1.5, 0.1]);
        assert_eq!(r.channel("omega").unwrap().unit, "rad/s");
        let q = p.with_file_name("b.csv");
        write_csv(&q, &r).unwrap();
        let back = read_csv(
            &q,
            &CsvOptions {
                units_row: true,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(back.channels(), r.channels());
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let p = tmp("bad.csv", "a,b\n1,2\n3,x7\n");
        let e = read_csv(&p, &CsvOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.ends_with("bad.csv, line 3, column 'b': 'x7' is not a number"),
            "{e}"
        );
        let p = tmp("empty.csv", "");
        let e = read_csv(&p, &CsvOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("no header row"), "{e}");
        let p = tmp("hdr.csv", "a,b\n");
        let e = read_csv(&p, &CsvOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("no data rows"), "{e}");
        let p = tmp("ragged.csv", "a,b\n1,2\n3\n");
        let e = read_csv(&p, &CsvOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 3: 1 cells, but the header has 2"), "{e}");
        let p = tmp("dup.csv", "a,a\n1,2\n");
        let e = read_csv(&p, &CsvOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("channel 'a' appears twice"), "{e}");
        let e = read_csv("/nonexistent/x.csv", &CsvOptions::default()).unwrap_err();
        assert!(matches!(e, IoError::Os { .. }));
    }
}
