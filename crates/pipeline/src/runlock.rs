//! The workspace's run lock: one `pipeline run` at a time.
//!
//! `artifacts/run.lock` is locked with `flock` (std's `File::lock`), an advisory lock the
//! kernel drops when the holding process dies, however it dies, so a `kill -9` can never
//! leave a stale lock behind. The file's text is the holder's PID, for the waiting message
//! and for [`probe`]; the lock itself is the kernel's. Rust opens files close-on-exec, so
//! stage processes do not inherit the lock.
//!
//! Readers (`pipeline status`, [`crate::progress`]) ask whether a run is live with [`probe`]:
//! a non-blocking *shared* lock that is released at once. Two probes never conflict; a run
//! that tries to take the lock during that instant sees it busy, so [`RunLock::acquire`]
//! retries for a short while before it reports another run or starts waiting.

use crate::{Error, Result};
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The run lock's file name under the store root.
pub const LOCK_FILE: &str = "run.lock";

/// How often, and how far apart, [`RunLock::acquire`] retries a busy lock before it believes
/// that another run holds it (a [`probe`] holds a shared lock for microseconds).
const BUSY_RETRIES: u32 = 20;
const BUSY_RETRY_PAUSE: Duration = Duration::from_millis(5);

/// What [`probe`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LockState {
    /// No process holds the run lock (or the lock file does not exist): no run is live.
    Free,
    /// A live process holds it; its PID as the holder wrote it (`None` while unreadable).
    Held(Option<u32>),
}

/// Whether a run holds the lock at `path`, without disturbing it: takes a shared lock without
/// blocking and releases it at once. Never creates the file.
pub fn probe(path: &Path) -> Result<LockState> {
    let mut file = match File::open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(LockState::Free),
        Err(e) => return Err(Error::io(path, e)),
    };
    match file.try_lock_shared() {
        Ok(()) => {
            let _ = file.unlock();
            Ok(LockState::Free)
        }
        Err(TryLockError::WouldBlock) => Ok(LockState::Held(holder(&mut file).parse().ok())),
        Err(TryLockError::Error(e)) => Err(Error::io(path, e)),
    }
}

/// Tries the exclusive lock a few times: `Ok(false)` when it stayed busy.
fn try_lock_patiently(file: &File) -> std::io::Result<bool> {
    for attempt in 0..BUSY_RETRIES {
        match file.try_lock() {
            Ok(()) => return Ok(true),
            Err(TryLockError::WouldBlock) if attempt + 1 < BUSY_RETRIES => {
                std::thread::sleep(BUSY_RETRY_PAUSE)
            }
            Err(TryLockError::WouldBlock) => return Ok(false),
            Err(TryLockError::Error(e)) => return Err(e),
        }
    }
    Ok(false)
}

/// A held run lock; released on drop (or by the kernel on death).
#[derive(Debug)]
pub struct RunLock {
    _file: File,
}

fn holder(file: &mut File) -> String {
    let mut s = String::new();
    let _ = file.rewind().and_then(|_| file.read_to_string(&mut s));
    let s = s.trim();
    if s.is_empty() {
        "?".into()
    } else {
        s.to_owned()
    }
}

impl RunLock {
    /// The workspace's run lock (`run.lock` under the store root `root`), saying on `ui`
    /// that it waits for another run while it does: what `run` and `gc` take.
    pub fn acquire_for_workspace(root: &Path, wait: bool, ui: &crate::ui::Ui) -> Result<Self> {
        let lock_path = root.join(LOCK_FILE);
        Self::acquire(&lock_path, wait, |pid| {
            ui.line(&format!(
                "waiting for another `pipeline run` (pid {pid}) to finish ({})...",
                lock_path.display()
            ))
        })
    }

    /// Takes the lock at `path`. When another run holds it: with `wait`, calls `on_wait` with
    /// the holder's PID once and blocks; without, fails with [`Error::Busy`].
    pub fn acquire(path: &Path, wait: bool, on_wait: impl FnOnce(&str)) -> Result<Self> {
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)
            .map_err(|e| Error::io(path, e))?;
        match try_lock_patiently(&file) {
            Ok(true) => {}
            Ok(false) => {
                let pid = holder(&mut file);
                if !wait {
                    return Err(Error::Busy {
                        pid,
                        lock: PathBuf::from(path),
                    });
                }
                on_wait(&pid);
                file.lock().map_err(|e| Error::io(path, e))?;
            }
            Err(e) => return Err(Error::io(path, e)),
        }
        file.set_len(0)
            .and_then(|_| file.rewind())
            .and_then(|_| write!(file, "{}", std::process::id()))
            .map_err(|e| Error::io(path, e))?;
        Ok(Self { _file: file })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn second_holder_is_refused_then_admitted_after_release() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("run.lock");
        let first = RunLock::acquire(&p, false, |_| {}).unwrap();
        match RunLock::acquire(&p, false, |_| {}) {
            Err(Error::Busy { pid, .. }) => assert_eq!(pid, std::process::id().to_string()),
            other => panic!("expected Busy, got {other:?}"),
        }
        drop(first);
        RunLock::acquire(&p, false, |_| {}).unwrap();
    }

    #[test]
    fn probe_sees_the_holder_and_does_not_keep_the_lock() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(LOCK_FILE);
        assert_eq!(probe(&p).unwrap(), LockState::Free);
        assert!(!p.exists(), "a probe creates nothing");
        let held = RunLock::acquire(&p, false, |_| {}).unwrap();
        assert_eq!(
            probe(&p).unwrap(),
            LockState::Held(Some(std::process::id()))
        );
        drop(held);
        assert_eq!(probe(&p).unwrap(), LockState::Free);
        // The free probe released its shared lock: a run takes the lock at once.
        let _again = RunLock::acquire(&p, false, |_| {}).unwrap();
    }
}
