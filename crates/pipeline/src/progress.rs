//! Progress of running units, readable by other processes.
//!
//! While `pipeline run` computes a unit it keeps one small JSON file for it under the store:
//! `artifacts/running/<name>.json`, where `<name>` is the first 16 hex digits of the blake3
//! hash of the unit key followed by a readable, escaped copy of the key ([`file_name`]); the
//! real key is inside. The record ([`RunningUnit`]) says which unit of which pipeline file
//! runs, in which `pipeline` process (PID and host), since when, and its last `::progress`
//! line (`done`, `total`, `message`).
//!
//! Lifetime. The file is written when the unit starts (0 of 0, message `started`) and
//! rewritten for `::progress` lines, at most once per [`WRITE_INTERVAL`] per unit: a stage's
//! progress lines only update the record in memory, and a background thread of the run (the
//! *flusher*) writes the records that changed, so a slow disk never slows the reading of a
//! stage's output. A line that reports completion (`done >= total`) is written at the next
//! tick, whatever the interval. Every write is atomic ([`atomic_file`]: temporary sibling,
//! rename), so a reader sees a whole record or the previous one. The file is removed when the
//! unit ends (committed, failed or errored: the handle's `Drop`), the run removes what is
//! left when it ends, and a run clears the directory when it takes the run lock.
//!
//! Liveness. A `pipeline run` killed with `kill -9` leaves its records behind. A reader
//! ([`running`]) therefore trusts a record only while the run lock is held
//! ([`crate::runlock::probe`]: a non-blocking shared lock, released at once), the record's
//! PID is the lock holder's PID, and, when the record was written on this host, that process
//! exists (`kill(pid, 0)`). Readers never delete records: only the holder of the run lock
//! does.

use crate::exec::ProgressLine;
use crate::runlock::{self, LockState};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// The directory of the records under the store root.
pub const RUNNING_DIR: &str = "running";
/// The least time between two writes of one unit's record (the first and a completing one
/// excepted).
pub const WRITE_INTERVAL: Duration = Duration::from_millis(250);
/// How many characters of the unit key the file name keeps readable.
const READABLE_CHARS: usize = 48;

/// One running unit, as its record file holds it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RunningUnit {
    /// The unit's key (`simulate#1`, `train[algorithm=3]`).
    pub unit: String,
    /// Its stage's name (`simulate`, `train`).
    pub stage: String,
    /// The pipeline file it belongs to, relative to the workspace (the lock record's key).
    pub pipeline: String,
    /// PID of the `pipeline run` process computing it.
    pub pid: u32,
    /// Host name of the machine that process runs on.
    pub host: String,
    /// When the unit started, Unix seconds.
    pub started: u64,
    /// When the record last changed (start or last `::progress` line), Unix seconds.
    pub updated: u64,
    /// Work done, from the last `::progress` line (0 until the first).
    pub done: u64,
    /// Work in all, from the last `::progress` line (0 until the first).
    pub total: u64,
    /// The last `::progress` line's message (`started` until the first line).
    pub message: String,
}

impl RunningUnit {
    /// Whether the stage has reported progress yet.
    pub fn has_progress(&self) -> bool {
        self.total > 0 || self.done > 0
    }

    /// Short text for a status table: `42/100 (2.0 s/epoch)`, `42/100`, or the message
    /// (`started`) before the first progress line.
    pub fn describe(&self) -> String {
        if !self.has_progress() {
            return if self.message.is_empty() {
                "started".to_owned()
            } else {
                self.message.clone()
            };
        }
        let counts = format!("{}/{}", self.done, self.total);
        if self.message.is_empty() {
            counts
        } else {
            format!("{counts} ({})", self.message)
        }
    }
}

/// The record file's name for `unit`: 16 hex digits of blake3 of the key, then the key with
/// every character but ASCII letters, digits, `-`, `_`, `=` and `,` replaced by `_` (at most
/// 48 of them), then `.json`. Never starts with a dot, never holds a `/`.
pub fn file_name(unit: &str) -> String {
    let hash = blake3::hash(unit.as_bytes()).to_hex();
    let readable: String = unit
        .chars()
        .take(READABLE_CHARS)
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_=,".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("{}-{readable}.json", &hash[..16])
}

/// `<store root>/running`.
pub fn running_dir(store_root: &Path) -> PathBuf {
    store_root.join(RUNNING_DIR)
}

/// The units that are running now in the workspace whose store root (`artifacts/`) is
/// `store_root`, of every pipeline file, oldest first. Empty when no run holds the run lock;
/// records that are not live (see the module doc) or not readable are left out, never
/// deleted.
pub fn running(store_root: &Path) -> Result<Vec<RunningUnit>> {
    let holder = match runlock::probe(&store_root.join(runlock::LOCK_FILE))? {
        LockState::Free => return Ok(Vec::new()),
        LockState::Held(pid) => pid,
    };
    let this_host = hostname();
    let mut live: Vec<RunningUnit> = read_records(&running_dir(store_root))?
        .into_iter()
        .filter(|r| is_live(r, holder, &this_host))
        .collect();
    live.sort_by(|a, b| (a.started, &a.unit).cmp(&(b.started, &b.unit)));
    Ok(live)
}

/// Every parseable record in `dir` (none when it does not exist).
fn read_records(dir: &Path) -> Result<Vec<RunningUnit>> {
    let rd = match std::fs::read_dir(dir) {
        Ok(rd) => rd,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(Error::io(dir, e)),
    };
    let mut out = Vec::new();
    for entry in rd.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        // Dot-files are temporary files of atomic writes.
        if name.starts_with('.') || !name.ends_with(".json") {
            continue;
        }
        // A record removed or replaced since the listing is simply skipped.
        let Ok(bytes) = std::fs::read(entry.path()) else {
            continue;
        };
        if let Ok(r) = serde_json::from_slice::<RunningUnit>(&bytes) {
            out.push(r);
        }
    }
    Ok(out)
}

/// Whether a record belongs to the run that holds the lock (PID `holder`, if known).
fn is_live(r: &RunningUnit, holder: Option<u32>, this_host: &str) -> bool {
    holder.is_none_or(|h| h == r.pid) && (r.host != this_host || pid_alive(r.pid))
}

/// Whether a process with this PID exists (on this host).
fn pid_alive(pid: u32) -> bool {
    // PID 0 and values beyond pid_t would address process groups or nothing.
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    if pid <= 0 {
        return false;
    }
    // SAFETY: signal 0 only checks that the process exists; nothing is sent.
    let rc = unsafe { libc::kill(pid, 0) };
    rc == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// This machine's host name (empty when unknown).
fn hostname() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: the buffer is valid for its length; gethostname writes at most that many bytes.
    let rc = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) };
    if rc != 0 {
        return String::new();
    }
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    String::from_utf8_lossy(&buf[..end]).into_owned()
}

fn now_secs() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Removes every file in `dir` (records and temporary files of a killed run).
fn clear_dir(dir: &Path) -> Result<()> {
    let rd = match std::fs::read_dir(dir) {
        Ok(rd) => rd,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(Error::io(dir, e)),
    };
    for entry in rd.flatten() {
        let p = entry.path();
        match std::fs::remove_file(&p) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(Error::io(&p, e)),
        }
    }
    Ok(())
}

/// Writes a record atomically. Progress is best effort: callers ignore the error.
fn write_record(path: &Path, r: &RunningUnit) -> Result<()> {
    let bytes = serde_json::to_vec_pretty(r).map_err(|e| Error::Store {
        path: path.to_owned(),
        message: e.to_string(),
    })?;
    Ok(atomic_file::write_atomic(path, &bytes)?)
}

/// What the run knows of one unit's record.
struct SlotState {
    record: RunningUnit,
    /// Changed since the last write.
    dirty: bool,
    /// Write at the next tick even if the interval has not passed (completion).
    urgent: bool,
    /// The unit ended: never write again.
    closed: bool,
    /// When the record was last written.
    written: Instant,
}

/// One unit's record file. `io` is held across a write or the removal, so a flusher's write
/// can never recreate a file its unit has removed.
struct Slot {
    path: PathBuf,
    io: Mutex<()>,
    state: Mutex<SlotState>,
}

/// The records of one run, shared by the run, its units and the flusher.
struct Shared {
    dir: PathBuf,
    pipeline: String,
    pid: u32,
    host: String,
    interval: Duration,
    slots: Mutex<BTreeMap<u64, Arc<Slot>>>,
    next_id: AtomicU64,
}

impl Shared {
    /// Writes every record that changed and is due.
    fn flush(&self) {
        let slots: Vec<Arc<Slot>> = lock(&self.slots).values().cloned().collect();
        for slot in slots {
            self.write_if_due(&slot);
        }
    }

    fn write_if_due(&self, slot: &Slot) {
        let _io = lock(&slot.io);
        let record = {
            let mut st = lock(&slot.state);
            let due = st.urgent || st.written.elapsed() >= self.interval;
            if st.closed || !st.dirty || !due {
                return;
            }
            st.dirty = false;
            st.urgent = false;
            st.written = Instant::now();
            st.record.clone()
        };
        let _ = write_record(&slot.path, &record);
    }
}

/// The progress records of one `pipeline run`: create it while holding the run lock, hand
/// every running unit a [`UnitProgress`]. Dropping it stops its flusher thread and removes
/// every record left.
pub struct Board {
    shared: Arc<Shared>,
    stop: Option<mpsc::Sender<()>>,
    flusher: Option<JoinHandle<()>>,
}

impl Board {
    /// The board of a run of pipeline file `pipeline` (its lock-record key) in the store at
    /// `store_root`: creates `running/`, deletes the records of earlier (killed) runs and
    /// starts the flusher. Call only while holding the run lock.
    pub fn open(store_root: &Path, pipeline: &str) -> Result<Self> {
        let mut board = Self::without_flusher(store_root, pipeline, WRITE_INTERVAL)?;
        let (tx, rx) = mpsc::channel();
        let shared = Arc::clone(&board.shared);
        let tick = (WRITE_INTERVAL / 2).max(Duration::from_millis(10));
        let handle = std::thread::Builder::new()
            .name("progress-flusher".into())
            .spawn(move || {
                while let Err(RecvTimeoutError::Timeout) = rx.recv_timeout(tick) {
                    shared.flush();
                }
            })
            .map_err(|e| Error::io(&board.shared.dir, e))?;
        board.stop = Some(tx);
        board.flusher = Some(handle);
        Ok(board)
    }

    /// A board whose records are written only by [`Board::flush`] (tests).
    fn without_flusher(store_root: &Path, pipeline: &str, interval: Duration) -> Result<Self> {
        let dir = running_dir(store_root);
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        clear_dir(&dir)?;
        Ok(Self {
            shared: Arc::new(Shared {
                dir,
                pipeline: pipeline.to_owned(),
                pid: std::process::id(),
                host: hostname(),
                interval,
                slots: Mutex::new(BTreeMap::new()),
                next_id: AtomicU64::new(0),
            }),
            stop: None,
            flusher: None,
        })
    }

    /// Writes the records that changed and are due (what the flusher does every tick).
    #[cfg(test)]
    fn flush(&self) {
        self.shared.flush();
    }

    /// Unit `unit` of stage `stage` starts: writes its record (0 of 0, `started`) at once.
    /// Write errors are ignored: progress never fails a unit.
    pub fn start(&self, unit: &str, stage: &str) -> UnitProgress {
        let now = now_secs();
        let record = RunningUnit {
            unit: unit.to_owned(),
            stage: stage.to_owned(),
            pipeline: self.shared.pipeline.clone(),
            pid: self.shared.pid,
            host: self.shared.host.clone(),
            started: now,
            updated: now,
            done: 0,
            total: 0,
            message: "started".to_owned(),
        };
        let slot = Arc::new(Slot {
            path: self.shared.dir.join(file_name(unit)),
            io: Mutex::new(()),
            state: Mutex::new(SlotState {
                record: record.clone(),
                dirty: false,
                urgent: false,
                closed: false,
                written: Instant::now(),
            }),
        });
        {
            let _io = lock(&slot.io);
            let _ = write_record(&slot.path, &record);
        }
        let id = self.shared.next_id.fetch_add(1, Ordering::Relaxed);
        lock(&self.shared.slots).insert(id, Arc::clone(&slot));
        UnitProgress {
            shared: Arc::clone(&self.shared),
            slot,
            id,
        }
    }
}

impl Drop for Board {
    fn drop(&mut self) {
        // Closing the channel wakes the flusher, which then ends.
        drop(self.stop.take());
        if let Some(h) = self.flusher.take() {
            let _ = h.join();
        }
        let _ = clear_dir(&self.shared.dir);
    }
}

/// The record of one running unit; removed when dropped.
pub struct UnitProgress {
    shared: Arc<Shared>,
    slot: Arc<Slot>,
    id: u64,
}

impl UnitProgress {
    /// A `::progress` line arrived: updates the record in memory; the flusher writes it.
    pub fn update(&self, p: &ProgressLine) {
        let mut st = lock(&self.slot.state);
        st.record.done = p.done;
        st.record.total = p.total;
        st.record.message.clone_from(&p.message);
        st.record.updated = now_secs();
        st.dirty = true;
        if p.total > 0 && p.done >= p.total {
            st.urgent = true;
        }
    }
}

impl Drop for UnitProgress {
    fn drop(&mut self) {
        lock(&self.slot.state).closed = true;
        {
            let _io = lock(&self.slot.io);
            let _ = std::fs::remove_file(&self.slot.path);
        }
        lock(&self.shared.slots).remove(&self.id);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runlock::RunLock;

    fn line(done: u64, total: u64, message: &str) -> ProgressLine {
        ProgressLine {
            done,
            total,
            message: message.into(),
        }
    }

    fn hold_lock(root: &Path) -> RunLock {
        RunLock::acquire(&root.join(runlock::LOCK_FILE), false, |_| {}).unwrap()
    }

    fn files(root: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(running_dir(root))
            .map(|rd| {
                rd.flatten()
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default();
        v.sort();
        v
    }

    #[test]
    fn records_round_trip_while_the_run_holds_the_lock() {
        let dir = tempfile::tempdir().unwrap();
        let _lock = hold_lock(dir.path());
        let board = Board::without_flusher(dir.path(), "pipeline.yaml", Duration::ZERO).unwrap();
        let unit = board.start("train[algorithm=5]", "train");
        let r = running(dir.path()).unwrap();
        assert_eq!(r.len(), 1);
        assert_eq!(
            (
                r[0].unit.as_str(),
                r[0].stage.as_str(),
                r[0].pipeline.as_str()
            ),
            ("train[algorithm=5]", "train", "pipeline.yaml")
        );
        assert_eq!(
            (r[0].done, r[0].total, r[0].message.as_str()),
            (0, 0, "started")
        );
        assert_eq!(r[0].pid, std::process::id());
        assert_eq!(r[0].describe(), "started");
        assert!(r[0].updated >= r[0].started);

        unit.update(&line(42, 100, "2.0 s/epoch"));
        board.flush();
        let r = running(dir.path()).unwrap();
        assert_eq!((r[0].done, r[0].total), (42, 100));
        assert_eq!(r[0].describe(), "42/100 (2.0 s/epoch)");
    }

    #[test]
    fn writes_are_throttled_except_the_first_and_the_completing_one() {
        let dir = tempfile::tempdir().unwrap();
        let _lock = hold_lock(dir.path());
        let hour = Duration::from_secs(3600);
        let board = Board::without_flusher(dir.path(), "p.yaml", hour).unwrap();
        let unit = board.start("a", "a");
        for k in 1..50 {
            unit.update(&line(k, 100, ""));
            board.flush();
        }
        let r = running(dir.path()).unwrap();
        assert_eq!((r[0].done, r[0].message.as_str()), (0, "started"));
        unit.update(&line(100, 100, "done"));
        board.flush();
        let r = running(dir.path()).unwrap();
        assert_eq!(r[0].describe(), "100/100 (done)");
        // A later line within the interval waits again.
        unit.update(&line(7, 8, ""));
        board.flush();
        assert_eq!(running(dir.path()).unwrap()[0].done, 100);
    }

    #[test]
    fn records_are_removed_when_units_end_and_by_the_board() {
        let dir = tempfile::tempdir().unwrap();
        let _lock = hold_lock(dir.path());
        let board = Board::without_flusher(dir.path(), "p.yaml", Duration::ZERO).unwrap();
        let a = board.start("a", "a");
        let b = board.start("b", "b");
        a.update(&line(1, 2, ""));
        assert_eq!(files(dir.path()).len(), 2);
        drop(a);
        // A pending change of an ended unit is never written back.
        board.flush();
        assert_eq!(files(dir.path()), vec![file_name("b")]);
        let r = running(dir.path()).unwrap();
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].unit, "b");
        std::mem::forget(b); // as if the unit's thread never returned
        drop(board);
        assert!(files(dir.path()).is_empty());
    }

    #[test]
    fn records_without_a_live_run_are_ignored_not_deleted() {
        let dir = tempfile::tempdir().unwrap();
        let lock = hold_lock(dir.path());
        let board = Board::without_flusher(dir.path(), "p.yaml", Duration::ZERO).unwrap();
        let unit = board.start("simulate#1", "simulate");
        assert_eq!(running(dir.path()).unwrap().len(), 1);
        // The run dies: its lock is gone, its record stays behind.
        drop(lock);
        assert!(running(dir.path()).unwrap().is_empty());
        assert_eq!(files(dir.path()).len(), 1, "a reader deletes nothing");
        // A new run takes the lock: the old record is not its own.
        let _lock = hold_lock(dir.path());
        assert_eq!(running(dir.path()).unwrap().len(), 1);
        let mut foreign: RunningUnit = serde_json::from_slice(
            &std::fs::read(running_dir(dir.path()).join(file_name("simulate#1"))).unwrap(),
        )
        .unwrap();
        foreign.pid = std::process::id().wrapping_add(1);
        foreign.unit = "simulate#0".into();
        write_record(
            &running_dir(dir.path()).join(file_name("simulate#0")),
            &foreign,
        )
        .unwrap();
        let r = running(dir.path()).unwrap();
        assert_eq!(r.len(), 1, "{r:?}");
        assert_eq!(r[0].unit, "simulate#1");
        // A new board (the next run) clears the directory.
        std::mem::forget(unit);
        let _next = Board::without_flusher(dir.path(), "p.yaml", Duration::ZERO).unwrap();
        assert!(files(dir.path()).is_empty());
    }

    #[test]
    fn dead_pids_and_junk_are_not_running() {
        assert!(pid_alive(std::process::id()));
        assert!(!pid_alive(0));
        assert!(!pid_alive(u32::MAX));
        let mut r = RunningUnit {
            unit: "a".into(),
            stage: "a".into(),
            pipeline: "p".into(),
            pid: std::process::id(),
            host: hostname(),
            started: 0,
            updated: 0,
            done: 0,
            total: 0,
            message: String::new(),
        };
        assert!(is_live(&r, None, &hostname()));
        assert!(!is_live(&r, Some(r.pid.wrapping_add(1)), &hostname()));
        r.pid = 0;
        assert!(!is_live(&r, None, &hostname()));
        // On another host the PID cannot be checked here: the lock holder's PID decides.
        assert!(is_live(&r, Some(0), "elsewhere"));

        let dir = tempfile::tempdir().unwrap();
        let _lock = hold_lock(dir.path());
        let d = running_dir(dir.path());
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join("junk.json"), b"{not json").unwrap();
        std::fs::write(d.join(".x.json.tmp-1-0"), b"{}").unwrap();
        assert!(running(dir.path()).unwrap().is_empty());
    }

    #[test]
    fn odd_unit_keys_get_safe_distinct_names() {
        let keys = [
            "train[algorithm=5]",
            "simulate#1/2",
            "simulate#1_2",
            ".hidden",
            "",
            "ünïcode stage",
            &"x".repeat(300),
        ];
        let names: Vec<String> = keys.iter().map(|k| file_name(k)).collect();
        for n in &names {
            assert!(!n.contains('/') && !n.starts_with('.') && n.ends_with(".json"));
            assert!(n.len() <= 16 + 1 + READABLE_CHARS + 5, "{n}");
        }
        assert!(
            names[0].ends_with("-train_algorithm=5_.json"),
            "{}",
            names[0]
        );
        let distinct: std::collections::BTreeSet<&String> = names.iter().collect();
        assert_eq!(distinct.len(), names.len());

        let dir = tempfile::tempdir().unwrap();
        let _lock = hold_lock(dir.path());
        let board = Board::without_flusher(dir.path(), "p.yaml", Duration::ZERO).unwrap();
        let held: Vec<UnitProgress> = keys.iter().map(|k| board.start(k, "s")).collect();
        let mut found: Vec<String> = running(dir.path())
            .unwrap()
            .into_iter()
            .map(|r| r.unit)
            .collect();
        found.sort();
        let mut want: Vec<String> = keys.iter().map(|k| k.to_string()).collect();
        want.sort();
        assert_eq!(found, want);
        drop(held);
        assert!(files(dir.path()).is_empty());
    }

    #[test]
    fn the_flusher_writes_changes_and_stops_with_the_board() {
        let dir = tempfile::tempdir().unwrap();
        let _lock = hold_lock(dir.path());
        let board = Board::open(dir.path(), "p.yaml").unwrap();
        let unit = board.start("a", "a");
        unit.update(&line(3, 3, "all"));
        let t0 = Instant::now();
        while running(dir.path()).unwrap()[0].done != 3 {
            assert!(t0.elapsed() < Duration::from_secs(60), "never flushed");
            std::thread::sleep(Duration::from_millis(10));
        }
        drop(unit);
        drop(board);
        assert!(files(dir.path()).is_empty());
    }
}
