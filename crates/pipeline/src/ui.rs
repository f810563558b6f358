//! What the user sees while a run goes: a progress bar per running unit on a terminal
//! (indicatif), plain log lines otherwise, and the final summary table.
//!
//! Plain mode prints a unit's progress at most once per 10 % step, so logs stay short.

use crate::exec::ProgressLine;
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::Duration;

/// The run's display.
pub struct Ui {
    multi: Option<MultiProgress>,
}

/// The display of one running unit.
pub struct UnitView<'a> {
    ui: &'a Ui,
    name: String,
    bar: Option<ProgressBar>,
    last_decile: Mutex<Option<u64>>,
}

impl Ui {
    /// Bars when stderr is a terminal, plain lines otherwise.
    pub fn new() -> Self {
        let tty = std::io::stderr().is_terminal();
        Self {
            multi: tty.then(|| MultiProgress::with_draw_target(ProgressDrawTarget::stderr())),
        }
    }

    /// Prints a line on stderr without tearing the bars.
    pub fn line(&self, text: &str) {
        match &self.multi {
            Some(m) => {
                let _ = m.println(text);
            }
            None => eprintln!("{text}"),
        }
    }

    /// A unit starts running.
    pub fn start(&self, name: &str) -> UnitView<'_> {
        let bar = self.multi.as_ref().map(|m| {
            // A spinner until the stage reports its first `::progress` total.
            let b = m.add(ProgressBar::new_spinner());
            b.set_style(
                ProgressStyle::with_template("{prefix:>24.bold} {spinner} {elapsed:>4} {wide_msg}")
                    .expect("valid template"),
            );
            b.set_prefix(name.to_owned());
            b.enable_steady_tick(Duration::from_millis(200));
            b
        });
        if bar.is_none() {
            self.line(&format!("[{name}] started"));
        }
        UnitView {
            ui: self,
            name: name.to_owned(),
            bar,
            last_decile: Mutex::new(None),
        }
    }
}

impl Default for Ui {
    fn default() -> Self {
        Self::new()
    }
}

impl UnitView<'_> {
    /// A `::progress` line arrived.
    pub fn progress(&self, p: &ProgressLine) {
        match &self.bar {
            Some(b) => {
                if b.length() != Some(p.total) {
                    b.set_style(
                        ProgressStyle::with_template(
                            "{prefix:>24.bold} [{bar:30}] {pos}/{len} {elapsed:>4} {wide_msg}",
                        )
                        .expect("valid template")
                        .progress_chars("=> "),
                    );
                }
                b.set_length(p.total);
                b.set_position(p.done);
                b.set_message(p.message.clone());
            }
            None => {
                let decile = (p.done * 10).checked_div(p.total).unwrap_or(0);
                let mut last = self.last_decile.lock().unwrap_or_else(|e| e.into_inner());
                if *last != Some(decile) {
                    *last = Some(decile);
                    let msg = if p.message.is_empty() {
                        String::new()
                    } else {
                        format!(" {}", p.message)
                    };
                    self.ui
                        .line(&format!("[{}] {}/{}{msg}", self.name, p.done, p.total));
                }
            }
        }
    }

    /// The unit ended; `outcome` is a short word and detail (`ran in 1.2 s`).
    pub fn finish(self, outcome: &str) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
            if let Some(m) = &self.ui.multi {
                m.remove(b);
            }
        }
        self.ui.line(&format!("[{}] {outcome}", self.name));
    }
}

/// Formats a duration as `850 ms`, `12.3 s` or `4 m 05 s`.
pub fn fmt_duration(d: Duration) -> String {
    let ms = d.as_millis();
    if ms < 1000 {
        format!("{ms} ms")
    } else if ms < 60_000 {
        format!("{:.1} s", d.as_secs_f64())
    } else {
        format!("{} m {:02} s", ms / 60_000, (ms / 1000) % 60)
    }
}

/// A left-aligned text table (the last column is not padded).
pub fn table(header: &[&str], rows: &[Vec<String>]) -> String {
    let n = header.len();
    let mut width = vec![0; n];
    for (i, h) in header.iter().enumerate() {
        width[i] = h.chars().count();
    }
    for r in rows {
        for (i, c) in r.iter().enumerate().take(n) {
            width[i] = width[i].max(c.chars().count());
        }
    }
    let fmt_row = |cells: Vec<&str>| -> String {
        let mut s = String::new();
        for (i, c) in cells.iter().enumerate() {
            if i + 1 == cells.len() {
                s.push_str(c);
            } else {
                s.push_str(&format!("{c:<w$}  ", w = width[i]));
            }
        }
        s.trim_end().to_owned()
    };
    let mut out = fmt_row(header.to_vec());
    out.push('\n');
    for r in rows {
        out.push_str(&fmt_row(r.iter().map(String::as_str).collect()));
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_and_tables() {
        assert_eq!(fmt_duration(Duration::from_millis(850)), "850 ms");
        assert_eq!(fmt_duration(Duration::from_millis(12_340)), "12.3 s");
        assert_eq!(fmt_duration(Duration::from_secs(245)), "4 m 05 s");
        let t = table(&["a", "bb"], &[vec!["xyz".into(), "1".into()]]);
        assert_eq!(t, "a    bb\nxyz  1\n");
    }
}
