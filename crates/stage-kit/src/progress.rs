//! Progress and summary lines: how a stage tells the orchestrator how far it is.
//!
//! Lines are `::progress DONE TOTAL [MESSAGE]` and `::summary TEXT` on stdout, formatted by
//! [`stage_protocol`] (the orchestrator parses them with the same crate). Progress is
//! thread-safe (rayon workers call [`Progress::inc`]) and rate-limited to about ten lines a
//! second, plus a final line at completion.

use std::io::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use stage_protocol::{progress_line, summary_line, work_line};
pub use stage_protocol::{PROGRESS_PREFIX, SUMMARY_PREFIX};

const MIN_INTERVAL: Duration = Duration::from_millis(100);

/// A thread-safe progress counter that prints protocol lines.
#[derive(Debug)]
pub struct Progress {
    total: u64,
    done: AtomicU64,
    last: Mutex<Option<Instant>>,
}

impl Progress {
    /// A counter for `total` units of work; prints `::progress 0 TOTAL` at once.
    pub fn new(total: u64) -> Self {
        let p = Self {
            total,
            done: AtomicU64::new(0),
            last: Mutex::new(None),
        };
        p.emit(0, None);
        p
    }

    /// Adds `n` finished units.
    pub fn inc(&self, n: u64) {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        self.maybe_emit(done, None);
    }

    /// Sets the finished count and a short message (for example the current loss).
    pub fn set(&self, done: u64, message: &str) {
        self.done.store(done, Ordering::Relaxed);
        self.maybe_emit(done, Some(message));
    }

    /// Units finished so far.
    pub fn done(&self) -> u64 {
        self.done.load(Ordering::Relaxed)
    }

    fn maybe_emit(&self, done: u64, message: Option<&str>) {
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        let now = Instant::now();
        let due = last.is_none_or(|t| now.duration_since(t) >= MIN_INTERVAL);
        if due || done >= self.total {
            *last = Some(now);
            self.emit(done, message);
        }
    }

    fn emit(&self, done: u64, message: Option<&str>) {
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{}", progress_line(done, self.total, message));
        let _ = out.flush();
    }
}

/// Prints the stage's one-line result (shown in the pipeline's final summary).
pub fn summary(text: &str) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{}", summary_line(text));
    let _ = out.flush();
}

/// Prints, in check mode, the unit's work relative to the other units of its stage (any
/// positive scale: epochs x layers, samples x steps): the orchestrator starts the biggest
/// first when it has no recorded duration of them.
pub fn work(amount: f64) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{}", work_line(amount));
    let _ = out.flush();
}

/// Ends a stage process: on success prints the `::summary` line and exits 0; on error prints
/// the error with its causes (`{:#}`, as anyhow shows a chain) on stderr and exits 1, which the
/// orchestrator reports as a failed stage.
pub fn finish<E: std::fmt::Display>(result: std::result::Result<String, E>) -> ! {
    match result {
        Ok(text) => {
            summary(&text);
            std::process::exit(0)
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::exit(1)
        }
    }
}
