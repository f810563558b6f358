//! `pipeline gc`: removes the objects of the store that nothing needs.
//!
//! An object is **needed** when an entry of the lock record points to it (any pipeline file
//! of the workspace: `pipeline.yaml`, `configs/paper.yaml`, ...). With `--keep N` the `N` most
//! recently committed other objects of each unit (by the modification time of their
//! `manifest.json`, written once at commit) are kept too: that much of the run-cache survives,
//! so going back that many changes stays instant. Every other object is removed; all of them
//! are recomputable. `--dry-run` prints the same list and removes nothing.
//!
//! **Safe against a concurrent run.** `gc` holds the workspace's run lock ([`RunLock`]) from
//! before it reads the lock record until the last object is gone, so a `pipeline run` is
//! either finished (its lock-record entries name what it committed or reused) or has not yet
//! started (it will recompute or re-find what it needs). Without the lock, an object that a
//! run has just committed or taken from the run-cache, but not yet recorded, could be deleted
//! under it. Like `run`, `gc` waits for the lock (or fails with `--no-wait`), and it deletes
//! the debris of killed runs (`tmp/`, `trash/`, `running/`) as `run` does at its start.
//! Resumable state in `scratch/` is left alone: it belongs to units that have not committed
//! yet.

use crate::runlock::RunLock;
use crate::store::{list_files, Manifest, Store};
use crate::ui::{table, Ui};
use crate::{Error, Result};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::time::SystemTime;

/// Options of `pipeline gc`.
#[derive(Debug, Clone, Default)]
pub struct GcOptions {
    /// Print what would be removed; remove nothing.
    pub dry_run: bool,
    /// Per unit, how many of the most recent objects the lock record does not point to are
    /// kept.
    pub keep: usize,
    /// Wait for another run's lock instead of failing.
    pub wait: bool,
}

/// Why an object is kept or removed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// The lock record points to it.
    Locked,
    /// Among the `--keep N` most recent objects of its unit.
    Recent,
    /// Nothing needs it.
    Garbage,
}

/// One object of the store as `gc` sees it.
#[derive(Debug, Clone)]
pub struct ObjectInfo {
    /// Its identity (directory name).
    pub identity: String,
    /// The unit of its manifest (`?` when the manifest is unreadable).
    pub unit: String,
    /// Bytes of all its files.
    pub bytes: u64,
    /// When it was committed (its manifest's modification time).
    pub committed: SystemTime,
    /// What `gc` does with it.
    pub verdict: Verdict,
}

/// What `gc` did (or, with `--dry-run`, would do).
#[derive(Debug, Clone, Default)]
pub struct GcReport {
    /// Every object, sorted by unit then most recent first.
    pub objects: Vec<ObjectInfo>,
    /// Whether anything was removed (false for a dry run).
    pub removed: bool,
}

impl GcReport {
    fn count_bytes(&self, v: Verdict) -> (usize, u64) {
        self.objects
            .iter()
            .filter(|o| o.verdict == v)
            .fold((0, 0), |(n, b), o| (n + 1, b + o.bytes))
    }

    /// The removed objects as a table and a summary line.
    pub fn render(&self) -> String {
        let rows: Vec<Vec<String>> = self
            .objects
            .iter()
            .filter(|o| o.verdict == Verdict::Garbage)
            .map(|o| {
                vec![
                    o.unit.clone(),
                    o.identity.chars().take(16).collect(),
                    fmt_bytes(o.bytes),
                ]
            })
            .collect();
        let mut s = String::new();
        if !rows.is_empty() {
            s.push_str(&table(&["UNIT", "OBJECT", "SIZE"], &rows));
        }
        let (gn, gb) = self.count_bytes(Verdict::Garbage);
        let (ln, lb) = self.count_bytes(Verdict::Locked);
        let (rn, rb) = self.count_bytes(Verdict::Recent);
        let verb = if self.removed {
            "removed"
        } else {
            "would remove (dry run)"
        };
        s.push_str(&format!(
            "{verb} {gn} object(s), {}; kept {ln} in the lock record ({}) and {rn} recent ({})\n",
            fmt_bytes(gb),
            fmt_bytes(lb),
            fmt_bytes(rb)
        ));
        s
    }
}

/// `1.5 MB` (decimal units).
fn fmt_bytes(b: u64) -> String {
    const UNITS: [&str; 5] = ["B", "kB", "MB", "GB", "TB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1000.0 && u + 1 < UNITS.len() {
        v /= 1000.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

fn tree_bytes(dir: &Path) -> u64 {
    list_files(dir)
        .unwrap_or_default()
        .iter()
        .filter_map(|rel| std::fs::symlink_metadata(dir.join(rel)).ok())
        .map(|m| m.len())
        .sum()
}

/// Every object under `objects/` with its unit, size and commit time (verdicts not yet set).
fn scan(store: &Store) -> Result<Vec<ObjectInfo>> {
    let dir = store.root.join("objects");
    let rd = match std::fs::read_dir(&dir) {
        Ok(rd) => rd,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(Error::io(&dir, e)),
    };
    let mut out = Vec::new();
    for entry in rd {
        let entry = entry.map_err(|e| Error::io(&dir, e))?;
        let identity = entry.file_name().to_string_lossy().into_owned();
        let path = entry.path();
        let mpath = path.join("manifest.json");
        let manifest: Option<Manifest> = std::fs::read(&mpath)
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok());
        let committed = std::fs::metadata(&mpath)
            .or_else(|_| std::fs::symlink_metadata(&path))
            .and_then(|m| m.modified())
            .unwrap_or(SystemTime::UNIX_EPOCH);
        out.push(ObjectInfo {
            unit: manifest.map_or_else(|| "?".to_owned(), |m| m.unit),
            bytes: tree_bytes(&path),
            identity,
            committed,
            verdict: Verdict::Garbage,
        });
    }
    Ok(out)
}

/// Sets each object's verdict: [`Verdict::Locked`] when `locked` holds its identity, else
/// [`Verdict::Recent`] for the `keep` most recent of its unit (ties: by identity), else
/// [`Verdict::Garbage`]. Sorts by unit, then most recent first.
pub fn classify(objects: &mut [ObjectInfo], locked: &BTreeSet<String>, keep: usize) {
    objects.sort_by(|a, b| {
        (&a.unit, b.committed, &a.identity).cmp(&(&b.unit, a.committed, &b.identity))
    });
    let mut kept: BTreeMap<String, usize> = BTreeMap::new();
    for o in objects.iter_mut() {
        o.verdict = if locked.contains(&o.identity) {
            Verdict::Locked
        } else {
            let n = kept.entry(o.unit.clone()).or_default();
            if *n < keep {
                *n += 1;
                Verdict::Recent
            } else {
                Verdict::Garbage
            }
        };
    }
}

/// Runs `gc` on the store of `workspace` (see the module doc).
pub fn gc(workspace: &Path, opts: &GcOptions, ui: &Ui) -> Result<GcReport> {
    let workspace = std::path::absolute(workspace).map_err(|e| Error::io(workspace, e))?;
    let store = Store::open_read(&workspace);
    if !store.root.join("objects").is_dir() {
        return Ok(GcReport::default());
    }
    let _lock = RunLock::acquire_for_workspace(&store.root, opts.wait, ui)?;
    let locked: BTreeSet<String> = store
        .read_lock_record()?
        .pipelines
        .values()
        .flat_map(|units| units.values().map(|e| e.identity.clone()))
        .collect();
    let mut objects = scan(&store)?;
    classify(&mut objects, &locked, opts.keep);
    if !opts.dry_run {
        store.clean_debris()?;
        for o in objects.iter().filter(|o| o.verdict == Verdict::Garbage) {
            store.discard(&o.identity)?;
        }
        store.cache.save()?;
    }
    Ok(GcReport {
        objects,
        removed: !opts.dry_run,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn obj(id: &str, unit: &str, age_s: u64) -> ObjectInfo {
        ObjectInfo {
            identity: id.into(),
            unit: unit.into(),
            bytes: 10,
            committed: SystemTime::UNIX_EPOCH + Duration::from_secs(1000 - age_s),
            verdict: Verdict::Garbage,
        }
    }

    fn verdicts(objects: &[ObjectInfo]) -> Vec<(&str, Verdict)> {
        objects
            .iter()
            .map(|o| (o.identity.as_str(), o.verdict))
            .collect()
    }

    #[test]
    fn lock_record_first_then_the_most_recent_per_unit() {
        let mut v = vec![
            obj("a-old", "a", 30),
            obj("a-cur", "a", 20),
            obj("a-new", "a", 10),
            obj("a-mid", "a", 15),
            obj("b-cur", "b", 50),
            obj("b-old", "b", 60),
        ];
        let locked: BTreeSet<String> = ["a-cur", "b-cur"].map(String::from).into();
        classify(&mut v, &locked, 0);
        use Verdict::*;
        assert_eq!(
            verdicts(&v),
            [
                ("a-new", Garbage),
                ("a-mid", Garbage),
                ("a-cur", Locked),
                ("a-old", Garbage),
                ("b-cur", Locked),
                ("b-old", Garbage)
            ]
        );
        // --keep 1: the newest unlocked object of each unit survives, whatever its age
        // relative to the locked one.
        classify(&mut v, &locked, 1);
        assert_eq!(
            verdicts(&v),
            [
                ("a-new", Recent),
                ("a-mid", Garbage),
                ("a-cur", Locked),
                ("a-old", Garbage),
                ("b-cur", Locked),
                ("b-old", Recent)
            ]
        );
        classify(&mut v, &locked, 5);
        assert!(v.iter().all(|o| o.verdict != Garbage));
    }

    #[test]
    fn sizes_read_in_decimal_units() {
        assert_eq!(fmt_bytes(999), "999 B");
        assert_eq!(fmt_bytes(1500), "1.5 kB");
        assert_eq!(fmt_bytes(2_340_000_000), "2.3 GB");
    }
}
