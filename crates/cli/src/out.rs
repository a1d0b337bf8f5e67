//! Standard output that treats a closed pipe (`physid … | head`) as the end of the run instead of
//! a panic, and any other write failure as a reported error.

use std::io::Write;

/// Write formatted text to stdout; exit 0 quietly if the reader has gone away.
pub fn write(args: std::fmt::Arguments, newline: bool) {
    let mut h = std::io::stdout().lock();
    let r = h
        .write_fmt(args)
        .and_then(|_| if newline { h.write_all(b"\n") } else { Ok(()) })
        .and_then(|_| h.flush());
    if let Err(e) = r {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("physid: writing to standard output: {e}");
        std::process::exit(1);
    }
}

/// Write one line to stdout, returning the failure instead of exiting: for a verb that must
/// finish its own work (close a log) when its reader goes away.
pub fn try_line(line: &str) -> std::io::Result<()> {
    let mut h = std::io::stdout().lock();
    h.write_all(line.as_bytes())
        .and_then(|_| h.write_all(b"\n"))
        .and_then(|_| h.flush())
}

/// `eprintln!` that never panics: stderr may be gone too (a terminal that hung up).
pub fn write_note(args: std::fmt::Arguments) {
    let mut h = std::io::stderr().lock();
    let _ = h.write_fmt(args).and_then(|_| h.write_all(b"\n"));
}

/// `println!` that survives a closed pipe.
macro_rules! outln {
    () => { $crate::out::write(format_args!(""), true) };
    ($($t:tt)*) => { $crate::out::write(format_args!($($t)*), true) };
}

/// `print!` that survives a closed pipe.
macro_rules! out {
    ($($t:tt)*) => { $crate::out::write(format_args!($($t)*), false) };
}

/// `eprintln!` that never panics ([`write_note`]).
macro_rules! note {
    ($($t:tt)*) => { $crate::out::write_note(format_args!($($t)*)) };
}

pub(crate) use {note, out, outln};
