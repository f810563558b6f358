//! The workspace's run lock: one `pipeline run` at a time.
//!
//! `artifacts/run.lock` is locked with `flock` (std's `File::lock`), an advisory lock the
//! kernel drops when the holding process dies, however it dies, so a `kill -9` can never
//! leave a stale lock behind. The file's text is the holder's PID, for the waiting message
//! only; the lock itself is the kernel's. Rust opens files close-on-exec, so stage processes
//! do not inherit the lock.

use crate::{Error, Result};
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

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
        let lock_path = root.join("run.lock");
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
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
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
            Err(TryLockError::Error(e)) => return Err(Error::io(path, e)),
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
}
