//! A plain progress bar on stderr for long calls (`progress=False` turns it off): counted from
//! the worker threads with an atomic counter, drawn at most ten times a second and only once
//! the call has run for half a second, so short calls print nothing.

use std::io::Write;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Calls slower than this get a bar.
const QUIET: Duration = Duration::from_millis(500);
/// Time between redraws.
const EVERY: Duration = Duration::from_millis(100);

/// One call's bar.
pub struct Progress {
    label: &'static str,
    total: usize,
    done: AtomicUsize,
    enabled: bool,
    started: Instant,
    drawn: Mutex<Option<Instant>>,
}

impl Progress {
    /// A bar of `total` items labelled `label` (silent unless `enabled`).
    pub fn new(label: &'static str, total: usize, enabled: bool) -> Self {
        Self {
            label,
            total,
            done: AtomicUsize::new(0),
            enabled,
            started: Instant::now(),
            drawn: Mutex::new(None),
        }
    }

    /// One more item done.
    pub fn inc(&self) {
        let done = self.done.fetch_add(1, Ordering::Relaxed) + 1;
        if !self.enabled || self.started.elapsed() < QUIET {
            return;
        }
        let Ok(mut drawn) = self.drawn.try_lock() else {
            return;
        };
        if drawn.is_some_and(|d| d.elapsed() < EVERY) && done < self.total {
            return;
        }
        *drawn = Some(Instant::now());
        self.draw(done);
    }

    fn draw(&self, done: usize) {
        let frac = done as f64 / self.total.max(1) as f64;
        let width = 30;
        let filled = (frac * width as f64).round() as usize;
        let _ = write!(
            std::io::stderr(),
            "\r{}: [{}{}] {done}/{} ({:.1} s)",
            self.label,
            "#".repeat(filled.min(width)),
            " ".repeat(width - filled.min(width)),
            self.total,
            self.started.elapsed().as_secs_f64()
        );
    }

    /// Ends the bar's line (when one was drawn).
    pub fn finish(&self) {
        let drawn = self.drawn.lock().map(|d| d.is_some()).unwrap_or(false);
        if drawn {
            self.draw(self.done.load(Ordering::Relaxed));
            let _ = writeln!(std::io::stderr());
        }
    }
}
