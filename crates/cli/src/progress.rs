//! Progress on stderr for work that may take longer than a second: a bar when the total is
//! known (a Parquet or MDF4 file's rows, a simulation's duration), a running count when it is
//! not (a CSV file). Drawn only when stderr is a terminal and `--quiet` is not given, only once
//! the work has taken a second (`PHYSID_PROGRESS_AFTER_MS` sets another delay), and cleared when
//! it ends — so piped output and JSON on stdout see nothing of it.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// `--quiet`: no progress at all.
static QUIET: AtomicBool = AtomicBool::new(false);

/// Work shorter than this shows nothing (`PHYSID_PROGRESS_AFTER_MS`, default 1000).
fn after() -> Duration {
    let ms = std::env::var("PHYSID_PROGRESS_AFTER_MS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1000);
    Duration::from_millis(ms)
}

/// Set by `--quiet`.
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// A progress display (see the module docs).
pub struct Progress {
    bar: ProgressBar,
    start: Instant,
    after: Duration,
    shown: bool,
}

impl Progress {
    /// `what` is under way; `total` units of it when known.
    pub fn new(what: &str, total: Option<u64>) -> Self {
        let style = match total {
            Some(_) => ProgressStyle::with_template("{msg} [{bar:40}] {percent}% ({elapsed})")
                .map(|s| s.progress_chars("=> ")),
            None => ProgressStyle::with_template("{msg}: {human_pos} ({elapsed})"),
        }
        .unwrap_or_else(|_| ProgressStyle::default_bar());
        let bar = ProgressBar::with_draw_target(total, ProgressDrawTarget::hidden())
            .with_style(style)
            .with_message(what.to_string());
        Self {
            bar,
            start: Instant::now(),
            after: after(),
            shown: false,
        }
    }

    /// The work has reached `position` (of the total).
    pub fn set(&mut self, position: u64) {
        self.bar.set_position(position);
        if !self.shown && self.start.elapsed() >= self.after && !QUIET.load(Ordering::Relaxed) {
            // `stderr()` draws nothing when stderr is not a terminal.
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
            self.shown = true;
        }
    }

    /// What is under way now.
    pub fn message(&self, what: &str) {
        self.bar.set_message(what.to_string());
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

/// Work of unknown length under way (an analysis, a fit): a spinner with the elapsed time,
/// drawn by a watcher thread once the work has taken the delay (the same rules as
/// [`Progress`]), cleared when this is dropped.
pub struct Working {
    bar: ProgressBar,
    done: std::sync::Arc<AtomicBool>,
    watcher: Option<std::thread::JoinHandle<()>>,
}

impl Working {
    /// `what` is under way.
    pub fn new(what: &str) -> Self {
        let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden())
            .with_style(
                ProgressStyle::with_template("{spinner} {msg} ({elapsed})")
                    .unwrap_or_else(|_| ProgressStyle::default_spinner()),
            )
            .with_message(what.to_string());
        let done = std::sync::Arc::new(AtomicBool::new(false));
        let watcher = (!QUIET.load(Ordering::Relaxed)).then(|| {
            let (bar, done, after) = (bar.clone(), done.clone(), after());
            let start = Instant::now();
            std::thread::spawn(move || {
                while !done.load(Ordering::Relaxed) {
                    if start.elapsed() >= after {
                        bar.set_draw_target(ProgressDrawTarget::stderr());
                        bar.enable_steady_tick(Duration::from_millis(100));
                        return;
                    }
                    std::thread::sleep(Duration::from_millis(20));
                }
            })
        });
        Self { bar, done, watcher }
    }
}

impl Drop for Working {
    fn drop(&mut self) {
        self.done.store(true, Ordering::Relaxed);
        if let Some(w) = self.watcher.take() {
            let _ = w.join();
        }
        self.bar.finish_and_clear();
    }
}

/// A file read a chunk at a time, with its progress in rows (of the rows the file claims, when
/// it says).
pub struct Reading<'a> {
    reader: &'a mut physid_io::ChunkReader,
    progress: Progress,
}

impl<'a> Reading<'a> {
    /// Read `reader` (the file `path`) with progress.
    pub fn new(reader: &'a mut physid_io::ChunkReader, path: &std::path::Path) -> Self {
        let total = reader.claimed_rows().and_then(|n| u64::try_from(n).ok());
        let progress = Progress::new(&format!("reading {}", path.display()), total);
        Self { reader, progress }
    }
}

impl Iterator for Reading<'_> {
    type Item = Result<physid_core::Recording, physid_io::IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        let next = self.reader.next();
        self.progress.set(self.reader.rows_read() as u64);
        next
    }
}
