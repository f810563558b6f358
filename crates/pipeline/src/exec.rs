//! Starting one stage process and reading the stage protocol from it.
//!
//! The process gets the argument list (no shell), the workspace as working directory, stdin
//! closed, and `PINO_STAGE_CONTEXT` pointing at `context.json` in its working directory under
//! `tmp/`. Its stdout is parsed line by line with [`stage_protocol::parse_line`]:
//! `::progress DONE TOTAL [MSG]` and `::summary TEXT` are protocol, everything else is log. stdout and stderr both go to
//! `log.txt`; the last lines of stderr are kept to show when the stage fails.
//!
//! On Linux the child is started with `PR_SET_PDEATHSIG = SIGKILL`, so when `pipeline` is
//! killed (even with `kill -9`) its stage processes die with it instead of writing into a
//! `tmp/` directory that the next run is about to delete.

use crate::{Error, Result};
use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Mutex;

/// Environment variable carrying the context file's path (from [`stage_protocol`]).
pub use stage_protocol::CONTEXT_ENV;
/// Lines of stderr kept for the failure message.
pub const TAIL_LINES: usize = 20;

/// What a finished stage process did.
#[derive(Debug)]
pub struct Outcome {
    /// Exit status 0.
    pub success: bool,
    /// How it ended, for messages (`exit status: 3`, `signal: 9`).
    pub status: String,
    /// The last `::summary` text.
    pub summary: Option<String>,
    /// The last [`TAIL_LINES`] lines of stderr.
    pub stderr_tail: Vec<String>,
    /// The log file.
    pub log: PathBuf,
}

/// A parsed `::progress` line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ProgressLine {
    /// Units done.
    pub done: u64,
    /// Units in all.
    pub total: u64,
    /// Optional message.
    pub message: String,
}

/// Parses `::progress DONE TOTAL [MSG]` ([`stage_protocol::parse_line`]); anything else is
/// `None`.
pub fn parse_progress(line: &str) -> Option<ProgressLine> {
    match stage_protocol::parse_line(line) {
        stage_protocol::Line::Progress {
            done,
            total,
            message,
        } => Some(ProgressLine {
            done,
            total,
            message: message.to_owned(),
        }),
        _ => None,
    }
}

/// Runs `exe args...` as a stage in `work` (which holds `context.json` and `out/`).
pub fn run_stage(
    exe: &Path,
    args: &[String],
    workspace: &Path,
    work: &Path,
    on_progress: &(dyn Fn(&ProgressLine) + Sync),
) -> Result<Outcome> {
    let log_path = work.join("log.txt");
    let log = Mutex::new(std::fs::File::create(&log_path).map_err(|e| Error::io(&log_path, e))?);
    let mut cmd = Command::new(exe);
    cmd.args(args)
        .current_dir(workspace)
        .env(CONTEXT_ENV, work.join(stage_protocol::CONTEXT_FILE))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::process::CommandExt;
        let parent = std::process::id() as libc::pid_t;
        // SAFETY: between fork and exec only async-signal-safe calls are made (prctl,
        // getppid, _exit); no allocation, no locks.
        unsafe {
            cmd.pre_exec(move || {
                libc::prctl(
                    libc::PR_SET_PDEATHSIG,
                    libc::SIGKILL as libc::c_ulong,
                    0,
                    0,
                    0,
                );
                // The parent may have died before prctl took effect.
                if libc::getppid() != parent {
                    libc::_exit(137);
                }
                Ok(())
            });
        }
    }
    let mut child = cmd.spawn().map_err(|e| Error::io(exe, e))?;
    let stdout = child.stdout.take().expect("piped");
    let stderr = child.stderr.take().expect("piped");
    let mut summary = None;
    let mut tail = VecDeque::new();
    std::thread::scope(|s| {
        let log = &log;
        let tail = &mut tail;
        s.spawn(move || {
            for line in BufReader::new(stderr).split(b'\n').map_while(|l| l.ok()) {
                let line = String::from_utf8_lossy(&line).into_owned();
                let _ = writeln!(log.lock().unwrap_or_else(|e| e.into_inner()), "{line}");
                if tail.len() == TAIL_LINES {
                    tail.pop_front();
                }
                tail.push_back(line);
            }
        });
        for line in BufReader::new(stdout).split(b'\n').map_while(|l| l.ok()) {
            let line = String::from_utf8_lossy(&line).into_owned();
            match stage_protocol::parse_line(&line) {
                stage_protocol::Line::Progress {
                    done,
                    total,
                    message,
                } => on_progress(&ProgressLine {
                    done,
                    total,
                    message: message.to_owned(),
                }),
                stage_protocol::Line::Summary(text) => summary = Some(text.to_owned()),
                stage_protocol::Line::Log(_) | stage_protocol::Line::Work(_) => {}
            }
            let _ = writeln!(log.lock().unwrap_or_else(|e| e.into_inner()), "{line}");
        }
    });
    let status = child.wait().map_err(|e| Error::io(exe, e))?;
    Ok(Outcome {
        success: status.success(),
        status: status.to_string(),
        summary,
        stderr_tail: tail.into(),
        log: log_path,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn progress_lines_parse() {
        assert_eq!(
            parse_progress("::progress 3 10 loss 0.5"),
            Some(ProgressLine {
                done: 3,
                total: 10,
                message: "loss 0.5".into()
            })
        );
        assert_eq!(parse_progress("::progress 0 4").unwrap().total, 4);
        assert_eq!(parse_progress("::progress x 4"), None);
        assert_eq!(parse_progress("progress 1 2"), None);
    }

    #[test]
    fn runs_a_shell_stage_and_keeps_stderr_tail() {
        let dir = tempfile::tempdir().unwrap();
        let seen = Mutex::new(Vec::new());
        let script = "echo '::progress 1 2 half'; echo '::summary all good'; for i in $(seq 1 30); do echo err$i >&2; done; exit 3";
        let out = run_stage(
            Path::new("/bin/sh"),
            &["-c".into(), script.into()],
            dir.path(),
            dir.path(),
            &|p| seen.lock().unwrap().push(p.done),
        )
        .unwrap();
        assert!(!out.success);
        assert_eq!(out.summary.as_deref(), Some("all good"));
        assert_eq!(out.stderr_tail.len(), TAIL_LINES);
        assert_eq!(out.stderr_tail.last().unwrap(), "err30");
        assert_eq!(*seen.lock().unwrap(), vec![1]);
        let log = std::fs::read_to_string(out.log).unwrap();
        assert!(log.contains("err1\n") && log.contains("::summary all good"));
    }
}
