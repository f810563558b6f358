//! The content-addressed store under `artifacts/` and the lock record.
//!
//! Layout (all under the workspace's `artifacts/`):
//!
//! ```text
//! objects/<identity>/out/...        the unit's output files (the object is read-only)
//! objects/<identity>/manifest.json  every output file with size and blake3, the output hash
//! objects/<identity>/context.json   the context the stage was started with
//! objects/<identity>/log.txt        the stage's stdout and stderr
//! tmp/<identity>-<pid>/             a unit being computed (removed at the next run's start)
//! scratch/<identity>/               resumable state of a unit; survives failed attempts, dropped on commit
//! trash/                            objects being replaced or deleted
//! logs/<unit>.failed.log            the log of the last failed attempt of a unit
//! pipeline.lock.json                lock record: pipeline file -> unit -> current identity
//! hash-cache.json                   (path, stamp) -> blake3, see `hash`
//! run.lock                          the run lock (flock), holding the holder's PID as text
//! running/<hash>-<unit>.json        progress of a unit being computed (see `progress`)
//! ```
//!
//! Commit protocol (crash safety): a stage writes into `tmp/<identity>-<pid>/out`; after it
//! exits 0 the orchestrator makes the files read-only, hashes them, writes `manifest.json`
//! (tmp + rename), fsyncs, and renames the whole directory to `objects/<identity>`. The rename
//! is the commit point: `objects/<identity>` either does not exist or holds a complete output
//! with its manifest. A killed run leaves only `tmp/` debris, which the next run deletes.
//! Before an object is used it is verified against its manifest (file set, sizes, hashes via
//! the hash cache); a mismatch deletes it and the unit is recomputed.
//!
//! Committed objects are sealed: every file mode 0444, every directory (the object's own
//! included) 0555, so a tool that opens an artifact for writing, replaces it by a rename or
//! adds a file next to it is refused by the kernel. Root is not stopped by permission bits;
//! what it changes is still caught by the verification above. The store removes its own
//! sealed trees with [`remove_tree`], which makes directories writable first.

use crate::hash::{hash_file, HashCache, Stamp};
use crate::{Error, Result};
use atomic_file::write_atomic;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};

/// Stage protocol version written into every context file and hashed into every identity
/// (defined once, in [`stage_protocol`]).
pub use stage_protocol::PROTOCOL_VERSION;
/// Format version of `manifest.json` (independent of the stage protocol: the store's layout
/// can change without any stage noticing). Version 1 manifests called this field `protocol`.
pub const MANIFEST_VERSION: u32 = 1;

/// One output file in a manifest.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ManifestFile {
    /// Path relative to `out/`, `/`-separated.
    pub path: String,
    /// Size in bytes.
    pub size: u64,
    /// Hex blake3 of the content.
    pub blake3: String,
}

/// What a stored object contains.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Manifest {
    /// [`MANIFEST_VERSION`] of the run that wrote it.
    #[serde(alias = "protocol")]
    pub format: u32,
    /// The unit's identity (the object's directory name).
    pub identity: String,
    /// The unit that produced it (`simulate#1`, `train[algorithm=3]`).
    pub unit: String,
    /// Output files, sorted by path.
    pub files: Vec<ManifestFile>,
    /// Hash of the file list (paths, sizes, hashes): the content hash of this output.
    pub output_hash: String,
    /// The stage's `::summary` line, if it printed one.
    pub summary: Option<String>,
    /// How long the stage ran, milliseconds.
    pub duration_ms: u64,
}

/// The content hash of an output: blake3 over its sorted (path, size, hash) list.
pub fn output_hash(files: &[ManifestFile]) -> String {
    let mut h = blake3::Hasher::new();
    for f in files {
        h.update(f.path.as_bytes());
        h.update(b"\0");
        h.update(f.size.to_string().as_bytes());
        h.update(b"\0");
        h.update(f.blake3.as_bytes());
        h.update(b"\n");
    }
    h.finalize().to_hex().to_string()
}

/// State of a cached object.
#[derive(Debug)]
pub enum Cached {
    /// No object for this identity.
    Missing,
    /// A complete object whose files match its manifest.
    Valid(Manifest),
    /// An object that no longer matches its manifest (the reason).
    Corrupt(String),
}

/// One unit's entry in the lock record: what it was last run (or restored) with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LockEntry {
    /// The unit's identity.
    pub identity: String,
    /// Content hash of its output.
    pub output_hash: String,
    /// The resolved executable.
    pub exe: String,
    /// blake3 of the executable.
    pub exe_hash: String,
    /// Arguments after the executable.
    pub args: Vec<String>,
    /// blake3 of files named by arguments (scripts).
    pub arg_files: BTreeMap<String, String>,
    /// Resolved parameters.
    pub params: Value,
    /// Input name -> output hashes of the upstream units.
    pub inputs: BTreeMap<String, Vec<String>>,
    /// `[index, count]`.
    pub shard: [usize; 2],
    /// `--set` overrides in effect (`KEY=VALUE`).
    pub overrides: Vec<String>,
}

/// The lock record: pipeline file (relative to the workspace) -> unit -> entry.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct LockRecord {
    /// Format version.
    pub version: u32,
    /// Entries per pipeline file.
    pub pipelines: BTreeMap<String, BTreeMap<String, LockEntry>>,
}

/// The store rooted at `artifacts/`.
#[derive(Debug)]
pub struct Store {
    /// The `artifacts/` directory.
    pub root: PathBuf,
    /// The persistent hash cache.
    pub cache: HashCache,
}

fn walk(dir: &Path, rel: &str, out: &mut Vec<String>) -> Result<()> {
    let rd = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    for entry in rd {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let rel_name = if rel.is_empty() {
            name
        } else {
            format!("{rel}/{name}")
        };
        let ft = entry.file_type().map_err(|e| Error::io(entry.path(), e))?;
        if ft.is_dir() {
            walk(&entry.path(), &rel_name, out)?;
        } else if ft.is_file() {
            out.push(rel_name);
        } else {
            return Err(Error::Store {
                path: entry.path(),
                message: "outputs may only hold regular files and directories (no symlinks)".into(),
            });
        }
    }
    Ok(())
}

/// Every regular file under `dir`, relative and sorted.
pub fn list_files(dir: &Path) -> Result<Vec<String>> {
    let mut v = Vec::new();
    walk(dir, "", &mut v)?;
    v.sort();
    Ok(v)
}

impl Store {
    /// Opens (and creates) the store under `workspace/artifacts`.
    pub fn open(workspace: &Path) -> Result<Self> {
        let store = Self::open_read(workspace);
        store.create_dirs()?;
        Ok(store)
    }

    /// Creates the store's directories.
    pub fn create_dirs(&self) -> Result<()> {
        for d in ["objects", "tmp", "trash", "logs"] {
            let p = self.root.join(d);
            std::fs::create_dir_all(&p).map_err(|e| Error::io(&p, e))?;
        }
        Ok(())
    }

    /// Opens the store for reading only (nothing is created).
    pub fn open_read(workspace: &Path) -> Self {
        let root = workspace.join("artifacts");
        let cache = HashCache::load(&root.join("hash-cache.json"));
        Self { root, cache }
    }

    /// `objects/<identity>`.
    pub fn object_dir(&self, identity: &str) -> PathBuf {
        self.root.join("objects").join(identity)
    }

    /// `objects/<identity>/out`.
    pub fn out_dir(&self, identity: &str) -> PathBuf {
        self.object_dir(identity).join("out")
    }

    /// How long the stage that made the object for `identity` ran (its manifest's
    /// `duration_ms`), without checking its files; `None` when there is no readable manifest.
    /// A scheduling estimate, never trusted for content.
    pub fn recorded_duration(&self, identity: &str) -> Option<std::time::Duration> {
        let bytes = std::fs::read(self.object_dir(identity).join("manifest.json")).ok()?;
        let manifest: Manifest = serde_json::from_slice(&bytes).ok()?;
        Some(std::time::Duration::from_millis(manifest.duration_ms))
    }

    /// Checks the object for `identity` against its manifest.
    pub fn verify(&self, identity: &str) -> Cached {
        let dir = self.object_dir(identity);
        let mpath = dir.join("manifest.json");
        let bytes = match std::fs::read(&mpath) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound && !dir.exists() => {
                return Cached::Missing
            }
            Err(_) => return Cached::Corrupt("manifest.json is missing".into()),
        };
        let manifest: Manifest = match serde_json::from_slice(&bytes) {
            Ok(m) => m,
            Err(e) => return Cached::Corrupt(format!("manifest.json is unreadable: {e}")),
        };
        if manifest.format != MANIFEST_VERSION {
            // Another store format: recomputed, never trusted.
            return Cached::Corrupt(format!(
                "manifest.json has format {}, this pipeline writes {MANIFEST_VERSION}",
                manifest.format
            ));
        }
        let out = dir.join("out");
        let found = match list_files(&out) {
            Ok(f) => f,
            Err(e) => return Cached::Corrupt(e.to_string()),
        };
        let expected: Vec<&str> = manifest.files.iter().map(|f| f.path.as_str()).collect();
        if found != expected {
            let missing: Vec<&&str> = expected
                .iter()
                .filter(|p| !found.iter().any(|f| f == **p))
                .collect();
            let extra: Vec<&String> = found
                .iter()
                .filter(|f| !expected.contains(&f.as_str()))
                .collect();
            return Cached::Corrupt(format!(
                "file set changed (missing {missing:?}, unexpected {extra:?})"
            ));
        }
        let paths: Vec<PathBuf> = manifest.files.iter().map(|f| out.join(&f.path)).collect();
        for (f, h) in manifest.files.iter().zip(self.cache.hash_all(&paths)) {
            match h {
                Ok(h) if h.blake3 == f.blake3 && h.size == f.size => {}
                Ok(_) => {
                    return Cached::Corrupt(format!("{} no longer matches its manifest", f.path))
                }
                Err(e) => return Cached::Corrupt(e.to_string()),
            }
        }
        Cached::Valid(manifest)
    }

    /// Moves an object out of the way and deletes it.
    pub fn discard(&self, identity: &str) -> Result<()> {
        let dir = self.object_dir(identity);
        if !dir.exists() {
            return Ok(());
        }
        let trash = self
            .root
            .join("trash")
            .join(format!("{identity}-{}", std::process::id()));
        // A sealed directory cannot be moved to another parent: unseal its top first.
        set_mode(&dir, 0o755)?;
        std::fs::rename(&dir, &trash).map_err(|e| Error::io(&dir, e))?;
        self.cache.forget_under(&dir);
        remove_tree(&trash)
    }

    /// A fresh working directory for computing `identity`: `tmp/<identity>-<pid>/` with an
    /// empty `out/`.
    pub fn tmp_dir(&self, identity: &str) -> Result<PathBuf> {
        let dir = self
            .root
            .join("tmp")
            .join(format!("{identity}-{}", std::process::id()));
        if dir.exists() {
            remove_tree(&dir)?;
        }
        let out = dir.join("out");
        std::fs::create_dir_all(&out).map_err(|e| Error::io(&out, e))?;
        Ok(dir)
    }

    /// `scratch/<identity>/`: the unit's persistent scratch directory, created if missing. It
    /// survives a failed or killed run (a stage keeps resumable state there, such as training
    /// checkpoints) and is deleted once the unit's output is committed. Keyed by identity, so a
    /// unit never sees the scratch of another configuration.
    pub fn scratch_dir(&self, identity: &str) -> Result<PathBuf> {
        let dir = self.root.join("scratch").join(identity);
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        Ok(dir)
    }

    /// Deletes the scratch directory of `identity` (after its output was committed).
    pub fn drop_scratch(&self, identity: &str) -> Result<()> {
        let dir = self.root.join("scratch").join(identity);
        if dir.exists() {
            remove_tree(&dir)?;
        }
        Ok(())
    }

    /// Deletes debris of killed runs (`tmp/`, `trash/`, the progress records of `running/`).
    /// Call only under the run lock.
    pub fn clean_debris(&self) -> Result<()> {
        for d in ["tmp", "trash", crate::progress::RUNNING_DIR] {
            let p = self.root.join(d);
            remove_tree(&p)?;
            std::fs::create_dir_all(&p).map_err(|e| Error::io(&p, e))?;
        }
        Ok(())
    }

    /// Commits a finished unit: hashes `tmp/.../out`, writes the manifest and renames the
    /// directory to `objects/<identity>` (replacing an existing object).
    pub fn commit(
        &self,
        tmp: &Path,
        identity: &str,
        unit: &str,
        summary: Option<String>,
        duration_ms: u64,
    ) -> Result<Manifest> {
        let out = tmp.join("out");
        let rels = list_files(&out)?;
        use rayon::prelude::*;
        let hashed: Vec<Result<(ManifestFile, Stamp)>> = rels
            .par_iter()
            .map(|rel| {
                let p = out.join(rel);
                let f = std::fs::File::open(&p).map_err(|e| Error::io(&p, e))?;
                // Read-only: a stage reading it as input cannot modify it by accident.
                f.set_permissions(std::fs::Permissions::from_mode(FILE_MODE))
                    .map_err(|e| Error::io(&p, e))?;
                f.sync_all().map_err(|e| Error::io(&p, e))?;
                let before = Stamp::of(&f.metadata().map_err(|e| Error::io(&p, e))?);
                let (blake3, size) = hash_file(&p)?;
                Ok((
                    ManifestFile {
                        path: rel.clone(),
                        size,
                        blake3,
                    },
                    before,
                ))
            })
            .collect();
        let mut files = Vec::new();
        let mut stamps = Vec::new();
        for h in hashed {
            let (f, s) = h?;
            files.push(f);
            stamps.push(s);
        }
        let manifest = Manifest {
            format: MANIFEST_VERSION,
            identity: identity.to_owned(),
            unit: unit.to_owned(),
            output_hash: output_hash(&files),
            files,
            summary,
            duration_ms,
        };
        write_atomic(
            &tmp.join("manifest.json"),
            &serde_json::to_vec_pretty(&manifest).expect("serialisable"),
        )?;
        // Seal everything but the top directory, which must stay writable to be renamed
        // (moving a directory to another parent rewrites its `..` entry).
        seal(tmp, false)?;
        sync_dir(tmp)?;
        self.discard(identity)?;
        let dest = self.object_dir(identity);
        std::fs::rename(tmp, &dest).map_err(|e| Error::io(&dest, e))?;
        set_mode(&dest, DIR_MODE)?;
        sync_dir(&self.root.join("objects"))?;
        // The files kept their inodes and stamps through the rename: seed the cache.
        let new_out = dest.join("out");
        for (f, s) in manifest.files.iter().zip(stamps) {
            self.cache
                .insert(&new_out.join(&f.path), s, f.blake3.clone());
        }
        Ok(manifest)
    }

    /// `pipeline.lock.json`.
    pub fn lock_record_path(&self) -> PathBuf {
        self.root.join("pipeline.lock.json")
    }

    /// Reads the lock record (empty when absent).
    pub fn read_lock_record(&self) -> Result<LockRecord> {
        let p = self.lock_record_path();
        match std::fs::read(&p) {
            Ok(b) => serde_json::from_slice(&b).map_err(|e| Error::Store {
                path: p,
                message: e.to_string(),
            }),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(LockRecord::default()),
            Err(e) => Err(Error::io(p, e)),
        }
    }

    /// Writes the lock record atomically.
    pub fn write_lock_record(&self, rec: &LockRecord) -> Result<()> {
        let mut rec = rec.clone();
        rec.version = 1;
        Ok(write_atomic(
            &self.lock_record_path(),
            &serde_json::to_vec_pretty(&rec).expect("serialisable"),
        )?)
    }
}

/// Mode of every file of a committed object.
pub const FILE_MODE: u32 = 0o444;
/// Mode of every directory of a committed object.
pub const DIR_MODE: u32 = 0o555;

fn set_mode(p: &Path, mode: u32) -> Result<()> {
    std::fs::set_permissions(p, std::fs::Permissions::from_mode(mode)).map_err(|e| Error::io(p, e))
}

/// Makes the tree under `dir` read-only: files [`FILE_MODE`], directories [`DIR_MODE`]
/// (`dir` itself too when `top`). Symlinks are never followed (outputs hold none).
fn seal(dir: &Path, top: bool) -> Result<()> {
    let rd = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    for entry in rd {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let p = entry.path();
        let ft = entry.file_type().map_err(|e| Error::io(&p, e))?;
        if ft.is_dir() {
            seal(&p, true)?;
        } else if ft.is_file() {
            // Only when needed: a chmod changes the ctime, which the hash cache's stamps of
            // the outputs (made read-only before hashing) include.
            let mode = entry
                .metadata()
                .map_err(|e| Error::io(&p, e))?
                .permissions()
                .mode();
            if mode & 0o7777 != FILE_MODE {
                set_mode(&p, FILE_MODE)?;
            }
        }
    }
    if top {
        set_mode(dir, DIR_MODE)?;
    }
    Ok(())
}

/// Gives the owner write access to every directory under `p` (and `p`), without following
/// symlinks, so that their entries can be removed.
fn unseal_dirs(p: &Path) -> std::io::Result<()> {
    let meta = std::fs::symlink_metadata(p)?;
    if !meta.is_dir() {
        return Ok(());
    }
    if meta.permissions().mode() & 0o700 != 0o700 {
        std::fs::set_permissions(p, std::fs::Permissions::from_mode(0o755))?;
    }
    for entry in std::fs::read_dir(p)? {
        let entry = entry?;
        if entry.file_type()?.is_dir() {
            unseal_dirs(&entry.path())?;
        }
    }
    Ok(())
}

/// Removes the tree `p` (absent is fine), sealed objects included: read-only directories are
/// made writable first, which a plain `remove_dir_all` would trip over (unless run as root).
pub fn remove_tree(p: &Path) -> Result<()> {
    match unseal_dirs(p) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(Error::io(p, e)),
    }
    match std::fs::remove_dir_all(p) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(Error::io(p, e)),
    }
}

fn sync_dir(p: &Path) -> Result<()> {
    atomic_file::sync_dir(p).map_err(|e| Error::io(e.path, e.source))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commit_then_verify_then_detect_corruption() {
        let ws = tempfile::tempdir().unwrap();
        let store = Store::open(ws.path()).unwrap();
        let tmp = store.tmp_dir("abc").unwrap();
        std::fs::create_dir_all(tmp.join("out/sub")).unwrap();
        std::fs::write(tmp.join("out/a.txt"), b"A").unwrap();
        std::fs::write(tmp.join("out/sub/b.txt"), b"B").unwrap();
        let m = store
            .commit(&tmp, "abc", "u", Some("ok".into()), 5)
            .unwrap();
        assert_eq!(m.files.len(), 2);
        assert!(!tmp.exists());
        assert!(matches!(store.verify("abc"), Cached::Valid(_)));
        assert!(matches!(store.verify("nope"), Cached::Missing));
        let f = store.out_dir("abc").join("sub/b.txt");
        std::fs::set_permissions(&f, std::fs::Permissions::from_mode(0o644)).unwrap();
        std::fs::write(&f, b"C").unwrap();
        match store.verify("abc") {
            Cached::Corrupt(why) => assert!(why.contains("sub/b.txt"), "{why}"),
            other => panic!("corruption not detected: {other:?}"),
        }
        let out = store.out_dir("abc");
        std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o755)).unwrap();
        std::fs::write(out.join("extra"), b"x").unwrap();
        assert!(matches!(store.verify("abc"), Cached::Corrupt(_)));
        store.discard("abc").unwrap();
        assert!(matches!(store.verify("abc"), Cached::Missing));
    }

    /// Every path under `dir` with its permission bits.
    fn modes(dir: &Path) -> Vec<(PathBuf, bool, u32)> {
        let mut v = Vec::new();
        let meta = std::fs::symlink_metadata(dir).unwrap();
        v.push((
            dir.to_owned(),
            meta.is_dir(),
            meta.permissions().mode() & 0o7777,
        ));
        if meta.is_dir() {
            for e in std::fs::read_dir(dir).unwrap() {
                v.extend(modes(&e.unwrap().path()));
            }
        }
        v
    }

    #[test]
    fn committed_objects_are_read_only_and_writes_are_refused_or_detected() {
        let ws = tempfile::tempdir().unwrap();
        let store = Store::open(ws.path()).unwrap();
        let tmp = store.tmp_dir("abc").unwrap();
        std::fs::create_dir_all(tmp.join("out/sub")).unwrap();
        std::fs::write(tmp.join("out/a.txt"), b"A").unwrap();
        std::fs::write(tmp.join("out/sub/b.txt"), b"B").unwrap();
        std::fs::write(tmp.join("log.txt"), b"log").unwrap();
        store.commit(&tmp, "abc", "u", None, 1).unwrap();
        let all = modes(&store.object_dir("abc"));
        assert_eq!(all.len(), 7, "{all:?}"); // 3 directories, 2 outputs, manifest, log
        for (p, is_dir, mode) in &all {
            let want = if *is_dir { DIR_MODE } else { FILE_MODE };
            assert_eq!(*mode, want, "{}", p.display());
        }
        // A tool opening an artifact for writing: the kernel refuses it; where it cannot
        // (root ignores permission bits) the change is caught by verification.
        let f = store.out_dir("abc").join("a.txt");
        match std::fs::OpenOptions::new().write(true).open(&f) {
            Err(e) => assert_eq!(e.kind(), std::io::ErrorKind::PermissionDenied),
            Ok(mut h) => {
                std::io::Write::write_all(&mut h, b"Z").unwrap();
                drop(h);
                assert!(matches!(store.verify("abc"), Cached::Corrupt(_)));
                store.discard("abc").unwrap();
                return;
            }
        }
        // Nor can a file be added beside the outputs or replace one by a rename.
        let extra = store.out_dir("abc").join("extra");
        let e = std::fs::write(&extra, b"x").unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::PermissionDenied);
        let e = std::fs::rename(store.object_dir("abc").join("log.txt"), &f).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::PermissionDenied);
        assert!(matches!(store.verify("abc"), Cached::Valid(_)));
        // The store itself still removes its sealed objects.
        store.discard("abc").unwrap();
        assert!(!store.object_dir("abc").exists());
    }

    #[test]
    fn remove_tree_removes_sealed_trees() {
        let dir = tempfile::tempdir().unwrap();
        let t = dir.path().join("t");
        std::fs::create_dir_all(t.join("a/b")).unwrap();
        std::fs::write(t.join("a/b/f"), b"f").unwrap();
        seal(&t, true).unwrap();
        remove_tree(&t).unwrap();
        assert!(!t.exists());
        remove_tree(&t).unwrap(); // absent is fine
    }

    #[test]
    fn manifest_format_is_versioned_apart_from_the_protocol() {
        let ws = tempfile::tempdir().unwrap();
        let store = Store::open(ws.path()).unwrap();
        let tmp = store.tmp_dir("abc").unwrap();
        std::fs::create_dir_all(tmp.join("out")).unwrap();
        std::fs::write(tmp.join("out/a.txt"), b"A").unwrap();
        store.commit(&tmp, "abc", "u", None, 1).unwrap();
        let mpath = store.object_dir("abc").join("manifest.json");
        // Rewritten by hand below: unseal the object's directory first.
        std::fs::set_permissions(
            store.object_dir("abc"),
            std::fs::Permissions::from_mode(0o755),
        )
        .unwrap();
        let text = std::fs::read_to_string(&mpath).unwrap();
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["format"], MANIFEST_VERSION);
        // A version-1 manifest of before the split (field `protocol`) still reads.
        let obj = v.as_object_mut().unwrap();
        let format = obj.remove("format").unwrap();
        obj.insert("protocol".into(), format);
        write_atomic(&mpath, v.to_string().as_bytes()).unwrap();
        assert!(matches!(store.verify("abc"), Cached::Valid(_)));
        // Another manifest format is never trusted.
        v["protocol"] = (MANIFEST_VERSION + 1).into();
        write_atomic(&mpath, v.to_string().as_bytes()).unwrap();
        match store.verify("abc") {
            Cached::Corrupt(why) => assert!(why.contains("format 2"), "{why}"),
            other => panic!("foreign manifest format trusted: {other:?}"),
        }
        store.discard("abc").unwrap(); // sealed: a plain TempDir drop could not remove it
    }

    #[test]
    fn output_hash_depends_on_names_and_content() {
        let f = |p: &str, h: &str| ManifestFile {
            path: p.into(),
            size: 1,
            blake3: h.into(),
        };
        assert_ne!(output_hash(&[f("a", "1")]), output_hash(&[f("b", "1")]));
        assert_ne!(output_hash(&[f("a", "1")]), output_hash(&[f("a", "2")]));
        assert_eq!(output_hash(&[f("a", "1")]), output_hash(&[f("a", "1")]));
    }
}
