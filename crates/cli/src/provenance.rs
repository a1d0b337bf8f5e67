//! Where a result came from, stated in every report and every JSON result: physid's version,
//! the date, the command line, each input file with its size and SHA-256, and the `--map`
//! settings it was read with.
//!
//! Every recording a verb reads goes through [`crate::cmd::InputArgs`], which records it here;
//! its checksum is computed on a thread of its own from then on, beside the verb's work (a
//! one-hour recording of 7.7 GB takes seconds to hash), and waited for when the result is
//! written.

use serde::Serialize;
use sha2::{Digest, Sha256};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::thread::JoinHandle;

/// An input file: its path as given, its size and its SHA-256 (hex), or why it could not be
/// read again.
#[derive(Debug, Clone, Serialize)]
pub struct InputFile {
    /// The path as given on the command line.
    pub path: String,
    /// Its size [bytes].
    pub bytes: Option<u64>,
    /// Its SHA-256, hex.
    pub sha256: Option<String>,
    /// Why the checksum is missing (the file could not be read again).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The provenance of a result (see the module docs).
#[derive(Debug, Clone, Serialize)]
pub struct Provenance {
    /// physid's version.
    pub physid: &'static str,
    /// When the result was written (UTC, RFC 3339).
    pub date: String,
    /// The command line, each argument quoted where a shell would need it.
    pub command: String,
    /// The recordings read.
    pub inputs: Vec<InputFile>,
    /// The `--map` settings they were read with (empty: the file's own names).
    pub map: Vec<String>,
}

type Hashing = JoinHandle<Result<(u64, String), String>>;

struct Recorded {
    inputs: Vec<(PathBuf, Option<Hashing>, Option<InputFile>)>,
    map: Vec<String>,
}

static RECORDED: Mutex<Recorded> = Mutex::new(Recorded {
    inputs: Vec::new(),
    map: Vec::new(),
});

fn recorded() -> std::sync::MutexGuard<'static, Recorded> {
    // A panic elsewhere while holding the lock leaves plain data behind: still usable.
    RECORDED
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The size and SHA-256 of `path`, read in 1 MiB blocks.
fn sha256(path: &Path) -> Result<(u64, String), String> {
    let mut f = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut bytes = 0u64;
    loop {
        let n = f.read(&mut buf).map_err(|e| e.to_string())?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
        bytes += n as u64;
    }
    let hex = h
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect::<String>();
    Ok((bytes, hex))
}

/// Record that `path` is read, with the `--map` settings `map`; its checksum starts on a
/// thread of its own (once per path).
pub fn record_input(path: &Path, map: &[String]) {
    let mut r = recorded();
    for m in map {
        if !r.map.contains(m) {
            r.map.push(m.clone());
        }
    }
    if r.inputs.iter().any(|(p, _, _)| p == path) {
        return;
    }
    let owned = path.to_path_buf();
    let hashing = std::thread::Builder::new()
        .name("physid-sha256".into())
        .spawn(move || sha256(&owned))
        .ok();
    r.inputs.push((path.to_path_buf(), hashing, None));
}

/// The provenance of the result being written now (waits for the checksums).
pub fn current() -> Provenance {
    let mut r = recorded();
    let inputs = r
        .inputs
        .iter_mut()
        .map(|(path, hashing, done)| {
            if let Some(h) = hashing.take() {
                let result = h
                    .join()
                    .unwrap_or_else(|_| Err("the checksum thread failed".into()));
                let path = path.display().to_string();
                *done = Some(match result {
                    Ok((bytes, hex)) => InputFile {
                        path,
                        bytes: Some(bytes),
                        sha256: Some(hex),
                        error: None,
                    },
                    Err(e) => InputFile {
                        path,
                        bytes: None,
                        sha256: None,
                        error: Some(e),
                    },
                });
            }
            done.clone().unwrap_or_else(|| InputFile {
                path: path.display().to_string(),
                bytes: None,
                sha256: None,
                error: Some("the checksum could not be started".into()),
            })
        })
        .collect();
    Provenance {
        physid: env!("CARGO_PKG_VERSION"),
        date: chrono::Utc::now().to_rfc3339_opts(chrono::SecondsFormat::Secs, true),
        command: command_line(std::env::args()),
        inputs,
        map: r.map.clone(),
    }
}

/// The arguments as one line a shell would split the same way.
fn command_line(args: impl Iterator<Item = String>) -> String {
    args.enumerate()
        .map(|(i, a)| {
            // The program as `physid`, wherever it was run from.
            let a = if i == 0 {
                Path::new(&a)
                    .file_name()
                    .map_or(a.clone(), |f| f.to_string_lossy().into_owned())
            } else {
                a
            };
            let plain = !a.is_empty()
                && a.chars()
                    .all(|c| c.is_alphanumeric() || "-_./=:,@%+".contains(c));
            if plain {
                a
            } else {
                format!("'{}'", a.replace('\'', r"'\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// `value` as JSON with the provenance added (as `"provenance"` when it is an object; an
/// array or a plain value is wrapped as `{"result": …, "provenance": …}`).
pub fn with(value: &impl Serialize) -> serde_json::Value {
    with_value(serde_json::to_value(value).unwrap_or(serde_json::Value::Null))
}

/// [`with`] on JSON made already, without copying it.
pub fn with_value(mut v: serde_json::Value) -> serde_json::Value {
    let p = serde_json::to_value(current()).unwrap_or(serde_json::Value::Null);
    match v.as_object_mut() {
        Some(o) => {
            o.insert("provenance".into(), p);
            v
        }
        None => serde_json::json!({ "result": v, "provenance": p }),
    }
}

/// Print `value` as pretty JSON on stdout, with the provenance.
pub fn print_json(value: &impl Serialize) -> miette::Result<()> {
    print_json_value(
        serde_json::to_value(value).map_err(|e| miette::miette!("writing the JSON result: {e}"))?,
    )
}

/// [`print_json`] of JSON made already, without copying it.
pub fn print_json_value(value: serde_json::Value) -> miette::Result<()> {
    let text = serde_json::to_string_pretty(&with_value(value))
        .map_err(|e| miette::miette!("writing the JSON result: {e}"))?;
    crate::out::outln!("{text}");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The checksum against the FIPS 180-2 example ("abc") and a file of 3 MiB (over several
    /// blocks) against the same bytes hashed whole.
    #[test]
    fn checksums_are_sha256() {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let p = dir.path().join("abc");
        std::fs::write(&p, b"abc").unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            sha256(&p),
            Ok((
                3,
                "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad".into()
            ))
        );
        let big: Vec<u8> = (0..3 * (1 << 20) + 17).map(|i| (i % 251) as u8).collect();
        std::fs::write(&p, &big).unwrap_or_else(|e| panic!("{e}"));
        let whole: String = Sha256::digest(&big)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        assert_eq!(sha256(&p), Ok((big.len() as u64, whole)));
    }

    #[test]
    fn the_command_line_reads_back_in_a_shell() {
        let args = [
            "/x/target/debug/physid",
            "identify",
            "--expr",
            "A*x + B",
            "--params",
            "A=1",
        ];
        assert_eq!(
            command_line(args.iter().map(|s| s.to_string())),
            "physid identify --expr 'A*x + B' --params A=1"
        );
        assert_eq!(
            command_line(["physid", "it's"].iter().map(|s| s.to_string())),
            r"physid 'it'\''s'"
        );
    }
}
