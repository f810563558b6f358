//! Crash-safe replacement of a file, the one way every crate of pino-mbd writes a file that
//! someone else may read.
//!
//! The mechanism: the bytes go to a fresh temporary sibling of the target
//! (`.NAME.tmp-PID-N`, created exclusively, in the same directory so the rename cannot cross
//! a file system), the temporary file is fsynced, renamed over the target, and the directory
//! is fsynced so the rename itself survives a power cut. A reader therefore sees either the
//! old file or the complete new one, never a prefix. Every failure path removes the
//! temporary file: an error returned by the writer, a failed fsync or rename, or a
//! [`TempFile`] dropped without [`TempFile::commit`] (a panic unwinding through the writer
//! included). Only a killed process leaves a temporary file behind; its name starts with a
//! dot and ends in `.tmp-PID-N`, so it is never mistaken for the target.
//!
//! ```
//! # let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("answer.txt");
//! atomic_file::write_atomic(&path, b"42\n")?;
//! assert_eq!(std::fs::read(&path).unwrap(), b"42\n");
//! # Ok::<(), atomic_file::Error>(())
//! ```
#![warn(missing_docs)]

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// An I/O failure on a named path (the temporary file, the target or its directory).
#[derive(Debug)]
pub struct Error {
    /// The path the operation failed on.
    pub path: PathBuf,
    /// What the operating system said.
    pub source: std::io::Error,
}

impl std::fmt::Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.source)
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.source)
    }
}

fn err(path: &Path, source: std::io::Error) -> Error {
    Error {
        path: path.to_owned(),
        source,
    }
}

/// Distinguishes temporary files of concurrent writers of one process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// A temporary sibling of a target path that becomes the target on [`TempFile::commit`] and
/// is removed when dropped uncommitted.
#[derive(Debug)]
pub struct TempFile {
    target: PathBuf,
    tmp: PathBuf,
    armed: bool,
}

impl TempFile {
    /// Creates the temporary sibling of `target` and returns it with its open file handle.
    /// The handle may be moved into a writer that gives it back when finished (as Parquet's
    /// does); pass it back to [`TempFile::commit`].
    pub fn create(target: &Path) -> Result<(Self, File), Error> {
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let tmp = target.with_file_name(format!(".{name}.tmp-{}-{n}", std::process::id()));
        let file = File::options()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .map_err(|e| err(&tmp, e))?;
        Ok((
            Self {
                target: target.to_owned(),
                tmp,
                armed: true,
            },
            file,
        ))
    }

    /// The temporary file's path.
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// Flushes and fsyncs `file` (the handle [`TempFile::create`] returned), renames the
    /// temporary file over the target and fsyncs the directory. On error the temporary file
    /// is removed and the target is untouched.
    pub fn commit(mut self, mut file: File) -> Result<(), Error> {
        file.flush().map_err(|e| err(&self.tmp, e))?;
        file.sync_all().map_err(|e| err(&self.tmp, e))?;
        drop(file);
        std::fs::rename(&self.tmp, &self.target).map_err(|e| err(&self.target, e))?;
        self.armed = false;
        sync_parent(&self.target)
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if self.armed {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Fsyncs the directory holding `path`, so a rename into it is durable. File systems that
/// cannot fsync a directory (they answer "invalid input" or "unsupported") are accepted.
pub fn sync_parent(path: &Path) -> Result<(), Error> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    sync_dir(dir)
}

/// Fsyncs a directory (see [`sync_parent`] for the tolerated failures).
pub fn sync_dir(dir: &Path) -> Result<(), Error> {
    let d = File::open(dir).map_err(|e| err(dir, e))?;
    match d.sync_all() {
        Ok(()) => Ok(()),
        Err(e)
            if matches!(
                e.kind(),
                std::io::ErrorKind::InvalidInput | std::io::ErrorKind::Unsupported
            ) =>
        {
            Ok(())
        }
        Err(e) => Err(err(dir, e)),
    }
}

/// Replaces `path` with whatever `write` puts into the file it is given, atomically. An error
/// of `write` (any error type that can hold an [`Error`]) is returned as is, after the
/// temporary file is removed.
pub fn write_atomic_with<E, F>(path: &Path, write: F) -> Result<(), E>
where
    E: From<Error>,
    F: FnOnce(&mut File) -> Result<(), E>,
{
    let (tmp, mut file) = TempFile::create(path)?;
    write(&mut file)?;
    tmp.commit(file)?;
    Ok(())
}

/// Replaces `path` with `bytes`, atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    write_atomic_with(path, |f: &mut File| {
        f.write_all(bytes).map_err(|e| err(path, e))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Names in `dir`, sorted.
    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn writes_complete_content_and_leaves_only_the_target() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        let bytes: Vec<u8> = (0..100_000u32).map(|i| (i % 251) as u8).collect();
        write_atomic(&p, &bytes).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), bytes);
        assert_eq!(names(dir.path()), ["a.bin"]);
    }

    #[test]
    fn replaces_an_existing_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        std::fs::write(&p, b"an old and longer content").unwrap();
        write_atomic(&p, b"new").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"new");
        assert_eq!(names(dir.path()), ["a.txt"]);
    }

    #[test]
    fn an_error_of_the_writer_removes_the_temporary_and_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        std::fs::write(&p, b"old").unwrap();
        let r: Result<(), Error> = write_atomic_with(&p, |f: &mut File| {
            f.write_all(b"half of the new").unwrap();
            Err(err(&p, std::io::Error::other("writer gave up")))
        });
        assert!(r.unwrap_err().to_string().contains("writer gave up"));
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        assert_eq!(names(dir.path()), ["a.txt"]);
    }

    #[test]
    fn a_failed_rename_removes_the_temporary() {
        let dir = tempfile::tempdir().unwrap();
        // A non-empty directory at the target: the rename of a file over it fails.
        let p = dir.path().join("target");
        std::fs::create_dir(&p).unwrap();
        std::fs::write(p.join("inside"), b"x").unwrap();
        let e = write_atomic(&p, b"content").unwrap_err();
        assert_eq!(e.path, p);
        assert_eq!(names(dir.path()), ["target"]);
    }

    #[test]
    fn a_dropped_temp_file_is_removed() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        let (tmp, mut file) = TempFile::create(&p).unwrap();
        file.write_all(b"never committed").unwrap();
        assert!(tmp.path().exists());
        assert!(tmp
            .path()
            .file_name()
            .unwrap()
            .to_string_lossy()
            .starts_with(".a.txt.tmp-"));
        drop(tmp);
        assert!(names(dir.path()).is_empty());
    }

    #[test]
    fn a_missing_directory_is_an_error_naming_the_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("no/such/dir/a.txt");
        let e = write_atomic(&p, b"x").unwrap_err();
        assert!(e.path.starts_with(dir.path().join("no/such/dir")), "{e}");
        assert_eq!(e.source.kind(), std::io::ErrorKind::NotFound);
    }

    #[test]
    fn concurrent_writers_of_one_path_never_collide() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        std::thread::scope(|s| {
            for i in 0..8u8 {
                let p = &p;
                s.spawn(move || write_atomic(p, &[i; 4096]).unwrap());
            }
        });
        let back = std::fs::read(&p).unwrap();
        assert_eq!(back.len(), 4096);
        assert!(
            back.iter().all(|&b| b == back[0]),
            "one writer's bytes, whole"
        );
        assert_eq!(names(dir.path()), ["a.txt"]);
    }
}
