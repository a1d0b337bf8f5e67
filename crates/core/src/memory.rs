//! How much memory this machine can still give: a run or a reader refuses work whose size it
//! can tell in advance would not fit, instead of growing until the allocator aborts.

/// Memory available to new allocations [bytes] (`MemAvailable` of `/proc/meminfo`), if known.
pub fn available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb.saturating_mul(1024))
}

/// Work that would not fit in the available memory.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{what} would {}, and this machine has {:.1} GB free", needed(*.bytes), *.available as f64 / 1e9)]
pub struct TooLarge {
    /// What would take it.
    pub what: String,
    /// Its size [bytes] (possibly infinite).
    pub bytes: f64,
    /// The memory available [bytes].
    pub available: u64,
}

fn needed(bytes: f64) -> String {
    if bytes.is_finite() && bytes < 1e18 {
        format!("take about {:.3} GB", bytes / 1e9)
    } else if bytes.is_finite() {
        // Not a number of 300 digits.
        format!("take about {:.3e} GB", bytes / 1e9)
    } else {
        "not fit in any memory".into()
    }
}

/// Refuse `bytes` (a size known in advance, possibly infinite) when it would not fit in the
/// available memory; `what` says what would take it.
pub fn check_fits(bytes: f64, what: &str) -> Result<(), TooLarge> {
    match available() {
        Some(free) if !bytes.is_finite() || bytes > free as f64 => Err(TooLarge {
            what: what.to_string(),
            bytes,
            available: free,
        }),
        _ => Ok(()),
    }
}

/// A small text file (a token, a layout) read whole, but never more than `max` bytes of it: a
/// path to a large file by mistake, or to `/dev/zero`, is refused at `max` instead of read
/// until the memory is gone.
pub fn read_small(path: &std::path::Path, max: u64) -> std::io::Result<String> {
    use std::io::Read;
    let mut text = String::new();
    std::fs::File::open(path)?
        .take(max + 1)
        .read_to_string(&mut text)?;
    if text.len() as u64 > max {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("longer than {max} bytes: not the small text file expected"),
        ));
    }
    Ok(text)
}

/// Space available to this user on the file system that holds `path` (an existing directory
/// or file) [bytes], if known.
pub fn disk_available(path: &std::path::Path) -> Option<u64> {
    #[cfg(unix)]
    {
        let s = rustix::fs::statvfs(path).ok()?;
        Some(s.f_bavail.saturating_mul(s.f_frsize))
    }
    #[cfg(not(unix))]
    {
        let _ = path;
        None
    }
}

/// A file that would not fit on its disk.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{what} would take at least {:.3} GB, and {} has {:.3} GB free", *.bytes / 1e9, .place, *.available as f64 / 1e9)]
pub struct DiskFull {
    /// What would take it.
    pub what: String,
    /// Its size, at least [bytes] (possibly infinite).
    pub bytes: f64,
    /// Where it would go.
    pub place: String,
    /// The space available [bytes].
    pub available: u64,
}

/// Refuse writing at least `bytes` into directory `dir` when its file system has less free.
pub fn check_disk(bytes: f64, dir: &std::path::Path, what: &str) -> Result<(), DiskFull> {
    match disk_available(dir) {
        Some(free) if !bytes.is_finite() || bytes > free as f64 => Err(DiskFull {
            what: what.to_string(),
            bytes,
            place: dir.display().to_string(),
            available: free,
        }),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_that_cannot_fit_are_refused() {
        if available().is_none() {
            return; // no /proc here: nothing to check against
        }
        assert!(check_fits(1e3, "a kilobyte").is_ok());
        let e = check_fits(1e30, "a recording").unwrap_err().to_string();
        assert!(
            e.starts_with("a recording would take about 1.000e21 GB"),
            "{e}"
        );
        assert!(check_fits(f64::INFINITY, "x")
            .unwrap_err()
            .to_string()
            .contains("would not fit in any memory"));
        assert!(check_fits(f64::NAN, "x").is_err());
    }

    /// A small file is read whole; one past the bound (`/dev/zero`, which never ends) is
    /// refused at it.
    #[cfg(unix)]
    #[test]
    fn a_small_file_is_read_and_an_endless_one_refused() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("token");
        std::fs::write(&f, "secret-token\n").unwrap();
        assert_eq!(read_small(&f, 64).unwrap(), "secret-token\n");
        let e = read_small(&f, 5).unwrap_err().to_string();
        assert_eq!(e, "longer than 5 bytes: not the small text file expected");
        // /dev/zero's zeros are valid UTF-8 (NUL): refused by length, not by a decoding error.
        let e = read_small(std::path::Path::new("/dev/zero"), 1 << 16)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("longer than 65536 bytes"), "{e}");
    }

    /// The free space of the current directory's file system is known (on Unix), a petabyte
    /// file is refused naming the place, a kilobyte is not.
    #[cfg(unix)]
    #[test]
    fn files_that_cannot_fit_on_the_disk_are_refused() {
        let here = std::path::Path::new(".");
        assert!(disk_available(here).is_some_and(|b| b > 0));
        assert!(check_disk(1e3, here, "a kilobyte").is_ok());
        let e = check_disk(1e18, here, "a recording")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("a recording would take at least") && e.contains(" . has "),
            "{e}"
        );
        assert!(disk_available(std::path::Path::new("/no/such/dir")).is_none());
    }
}
