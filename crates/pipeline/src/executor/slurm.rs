//! The Slurm executor: every unit is a Slurm job; the shards of a stage expansion that are
//! still to do are one `sbatch --array` job.
//!
//! **Where units run.** A unit's working directory is `artifacts/slurm/<identity>.<pid>/`
//! on the shared filesystem (the workspace must be shared with the nodes). It holds
//! `context.json` and `out/` as locally; the job writes the stage's stdout and stderr there,
//! and, when the stage has ended, its exit status to `exit` (written to `exit.tmp` and
//! renamed). The orchestrator tails `stdout` for `::progress` lines, polls for `exit`, and then
//! verifies and commits `out/` exactly like a local unit. Nothing else reads `out/`.
//!
//! **Dependencies.** Jobs are submitted when their inputs are committed, never with
//! `--dependency=afterok`: a unit's identity (and so whether it must run at all) depends on the
//! *content hash* of its upstream outputs, which exists only once the orchestrator has
//! verified and committed them; and a downstream job must never read an output that has not
//! been verified. The cost is one scheduling round trip per stage boundary (about a second).
//!
//! **Crash safety.** The job id is written to `job` in the unit's directory right after
//! `sbatch` returns. A killed orchestrator leaves the jobs running; the next run finds the
//! directory by identity and [`classify`]s it: a finished job with exit 0 is adopted (verified
//! and committed), a queued or running job is waited for (no second submission), anything else
//! (no job id, the job gone without exit status, a failed attempt) is deleted and the unit
//! submitted again. On SIGINT/SIGTERM the orchestrator `scancel`s its jobs, deletes their
//! directories, and exits; a job that failed or vanished is reported with its stderr tail and
//! nothing of it is cached.

use super::{Job, Resources, Ticket, Work};
use crate::exec::{parse_progress, Outcome, ProgressLine, CONTEXT_ENV, TAIL_LINES};
use crate::store::remove_tree;
use crate::{Error, Result};
use atomic_file::write_atomic;
use std::collections::{BTreeMap, HashMap, VecDeque};
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicI32, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// How often a waiting unit looks at its job's files.
const POLL: Duration = Duration::from_millis(250);
/// How old the shared `squeue` snapshot may get.
const QUEUE_REFRESH: Duration = Duration::from_secs(2);
/// How long a job may be absent from `squeue` without an exit status before it counts as
/// vanished (covers shared-filesystem lag between the node's write and our read).
const GRACE: Duration = Duration::from_secs(5);

/// Quotes `s` for a POSIX shell (single quotes; `'` as `'\''`).
pub fn shell_quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// `--array` index list: sorted, runs compressed (`0-3,5,7-8`).
pub fn array_spec(indices: &[usize]) -> String {
    let mut v = indices.to_vec();
    v.sort_unstable();
    v.dedup();
    let mut parts = Vec::new();
    let mut i = 0;
    while i < v.len() {
        let mut j = i;
        while j + 1 < v.len() && v[j + 1] == v[j] + 1 {
            j += 1;
        }
        parts.push(if j == i {
            v[i].to_string()
        } else {
            format!("{}-{}", v[i], v[j])
        });
        i = j + 1;
    }
    parts.join(",")
}

/// The batch script of one submission: picks the unit directory by array task id (0 for a
/// plain job), runs the stage with the unchanged protocol, and records its exit status.
pub fn batch_script(
    workspace: &Path,
    exe: &Path,
    args: &[String],
    members: &[(usize, PathBuf)],
) -> String {
    let mut s = String::from(
        "#!/bin/sh\n# Written by `pipeline run --executor slurm`: one stage unit per array task.\n",
    );
    s.push_str("case \"${SLURM_ARRAY_TASK_ID:-0}\" in\n");
    for (i, d) in members {
        s.push_str(&format!(
            "  {i}) d={} ;;\n",
            shell_quote(&d.to_string_lossy())
        ));
    }
    s.push_str("  *) echo \"pipeline: no unit for array task ${SLURM_ARRAY_TASK_ID:-0}\" >&2; exit 97 ;;\nesac\n");
    s.push_str(&format!(
        "cd {} || exit 97\n",
        shell_quote(&workspace.to_string_lossy())
    ));
    let mut cmd = vec![shell_quote(&exe.to_string_lossy())];
    cmd.extend(args.iter().map(|a| shell_quote(a)));
    s.push_str(&format!(
        "{CONTEXT_ENV}=\"$d/context.json\" {} </dev/null >\"$d/stdout\" 2>\"$d/stderr\"\n",
        cmd.join(" ")
    ));
    s.push_str(
        "rc=$?\necho \"$rc\" >\"$d/exit.tmp\" && mv \"$d/exit.tmp\" \"$d/exit\"\nexit \"$rc\"\n",
    );
    s
}

/// The `sbatch` arguments of one submission (`array`: the task ids of a sharded stage).
pub fn sbatch_args(
    name: &str,
    workspace: &Path,
    log_dir: &Path,
    res: &Resources,
    array: Option<&[usize]>,
    script: &Path,
) -> Vec<String> {
    let log = log_dir.join(if array.is_some() {
        "%A_%a.log"
    } else {
        "%j.log"
    });
    let mut v = vec![
        "--parsable".to_owned(),
        format!("--job-name=pino:{name}"),
        format!("--chdir={}", workspace.display()),
        format!("--output={}", log.display()),
        format!("--error={}", log.display()),
    ];
    v.extend(res.sbatch_options());
    if let Some(a) = array {
        v.push(format!("--array={}", array_spec(a)));
    }
    v.push(script.to_string_lossy().into_owned());
    v
}

/// `squeue -h -r -o '%i|%T'` output -> job id (`123`, `123_4`) -> state.
pub fn parse_squeue(text: &str) -> HashMap<String, String> {
    text.lines()
        .filter_map(|l| l.trim().split_once('|'))
        .map(|(id, st)| (id.trim().to_owned(), st.trim().to_owned()))
        .collect()
}

/// What to do with a unit directory found from an earlier run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Disposition {
    /// Its job finished with exit 0: verify and commit it.
    Adopt(String),
    /// Its job is queued or running: wait for it.
    Attach(String),
    /// Anything else: delete it and submit again.
    Discard,
}

/// The recovery rule. `job`: the recorded job id; `exit`: the recorded exit status; `live`:
/// whether `squeue` lists the job.
pub fn classify(job: Option<&str>, exit: Option<i32>, live: impl Fn(&str) -> bool) -> Disposition {
    match (job, exit) {
        (Some(j), Some(0)) => Disposition::Adopt(j.to_owned()),
        (Some(j), None) if live(j) => Disposition::Attach(j.to_owned()),
        _ => Disposition::Discard,
    }
}

fn read_trimmed(p: &Path) -> Option<String> {
    std::fs::read_to_string(p)
        .ok()
        .map(|s| s.trim().to_owned())
        .filter(|s| !s.is_empty())
}

fn read_exit(dir: &Path) -> Option<i32> {
    read_trimmed(&dir.join("exit")).and_then(|s| s.parse().ok())
}

/// Finds the directories of `identity` under `base` and decides about each: at most one is
/// kept (adopted or attached to), the others are deleted. Returns the kept one.
pub fn recover(
    base: &Path,
    identity: &str,
    live: impl Fn(&str) -> bool,
) -> Result<Option<(PathBuf, Disposition)>> {
    let prefix = format!("{identity}.");
    let mut found: Vec<PathBuf> = match std::fs::read_dir(base) {
        Ok(rd) => rd
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
            .map(|e| e.path())
            .collect(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        Err(e) => return Err(Error::io(base, e)),
    };
    found.sort();
    let mut kept = None;
    for dir in found {
        let d = classify(
            read_trimmed(&dir.join("job")).as_deref(),
            read_exit(&dir),
            &live,
        );
        if kept.is_none() && d != Disposition::Discard {
            kept = Some((dir, d));
        } else {
            remove_tree(&dir)?;
        }
    }
    Ok(kept)
}

/// `pipeline status`: the Slurm job of `identity` that is queued or running, as
/// `job 123_4 (RUNNING)`; `None` when there is none. Asks `squeue` when it can.
pub fn describe(store_root: &Path, identity: &str) -> Option<String> {
    let base = store_root.join("slurm");
    let prefix = format!("{identity}.");
    let rd = std::fs::read_dir(&base).ok()?;
    for e in rd.filter_map(|e| e.ok()) {
        if !e.file_name().to_string_lossy().starts_with(&prefix) {
            continue;
        }
        let dir = e.path();
        let Some(job) = read_trimmed(&dir.join("job")) else {
            continue;
        };
        if read_exit(&dir).is_some() {
            return Some(format!(
                "Slurm job {job} finished; the next `pipeline run` commits it"
            ));
        }
        let state = squeue().ok().and_then(|q| q.get(&job).cloned());
        return Some(match state {
            Some(s) => format!("{} on Slurm: job {job}", s.to_lowercase()),
            None => format!(
                "Slurm job {job} recorded but not in the queue (resubmitted by the next run)"
            ),
        });
    }
    None
}

fn squeue() -> std::result::Result<HashMap<String, String>, String> {
    let out = Command::new("squeue")
        .args(["-h", "-r", "-o", "%i|%T"])
        .output()
        .map_err(|e| format!("squeue: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "squeue: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    Ok(parse_squeue(&String::from_utf8_lossy(&out.stdout)))
}

#[derive(Default)]
struct Snapshot {
    taken: Option<Instant>,
    live: HashMap<String, String>,
}

/// State shared by the units of a run and the signal watcher.
struct Shared {
    workspace: PathBuf,
    dir: PathBuf,
    jobs: PathBuf,
    queue: Mutex<Snapshot>,
    /// Jobs submitted or attached to by this run and not yet finished -> unit directory.
    active: Mutex<BTreeMap<String, PathBuf>>,
    counter: AtomicUsize,
}

impl Shared {
    /// Whether `squeue` lists `job`, from a snapshot taken after `after` (`None`: unknown).
    fn state(&self, job: &str, after: Instant) -> Option<Option<String>> {
        let mut q = self.queue.lock().unwrap_or_else(|e| e.into_inner());
        let stale = q
            .taken
            .is_none_or(|t| t < after || t.elapsed() > QUEUE_REFRESH);
        if stale {
            match squeue() {
                Ok(live) => {
                    q.live = live;
                    q.taken = Some(Instant::now());
                }
                Err(_) => return None,
            }
        }
        Some(q.live.get(job).cloned())
    }

    fn submit(&self, members: &[Member]) -> std::result::Result<String, String> {
        let first = &members[0];
        let n = self.counter.fetch_add(1, Ordering::Relaxed);
        let safe: String = first
            .name
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        let script = self
            .jobs
            .join(format!("{safe}-{}-{n}.sh", std::process::id()));
        let list: Vec<(usize, PathBuf)> =
            members.iter().map(|m| (m.shard, m.dir.clone())).collect();
        let text = batch_script(&self.workspace, &first.exe, &first.args, &list);
        write_atomic(&script, text.as_bytes()).map_err(|e| e.to_string())?;
        let shards: Vec<usize> = members.iter().map(|m| m.shard).collect();
        let args = sbatch_args(
            &first.name,
            &self.workspace,
            &self.jobs,
            &first.resources,
            first.sharded.then_some(&shards[..]),
            &script,
        );
        let out = Command::new("sbatch")
            .args(&args)
            .output()
            .map_err(|e| format!("sbatch: {e}"))?;
        if !out.status.success() {
            return Err(format!(
                "sbatch {} failed: {}",
                args.join(" "),
                String::from_utf8_lossy(&out.stderr).trim()
            ));
        }
        let stdout = String::from_utf8_lossy(&out.stdout);
        let base = stdout
            .trim()
            .split(';')
            .next()
            .filter(|s| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()))
            .ok_or_else(|| format!("sbatch printed no job id: {stdout:?}"))?
            .to_owned();
        let mut active = self.active.lock().unwrap_or_else(|e| e.into_inner());
        for m in members {
            let id = member_id(&base, m.sharded, m.shard);
            write_atomic(&m.dir.join("job"), id.as_bytes()).map_err(|e| e.to_string())?;
            active.insert(id, m.dir.clone());
        }
        Ok(base)
    }

    fn cancel_all(&self) {
        let active = self.active.lock().unwrap_or_else(|e| e.into_inner());
        if active.is_empty() {
            return;
        }
        let ids: Vec<&String> = active.keys().collect();
        eprintln!(
            "pipeline: cancelling {} Slurm job(s): {}",
            ids.len(),
            ids.iter().map(|s| s.as_str()).collect::<Vec<_>>().join(" ")
        );
        let _ = Command::new("scancel").args(&ids).status();
        for d in active.values() {
            let _ = remove_tree(d);
        }
    }
}

fn member_id(base: &str, sharded: bool, shard: usize) -> String {
    if sharded {
        format!("{base}_{shard}")
    } else {
        base.to_owned()
    }
}

struct Member {
    shard: usize,
    dir: PathBuf,
    exe: PathBuf,
    args: Vec<String>,
    resources: Resources,
    name: String,
    sharded: bool,
}

#[derive(Default)]
struct BatchState {
    outstanding: usize,
    members: Vec<Member>,
    result: Option<std::result::Result<String, String>>,
}

/// The units of one stage expansion dispatched together: submitted as one job once every
/// member has either joined or left (see [`Ticket`]).
pub struct Batch {
    shared: Arc<Shared>,
    st: Mutex<BatchState>,
    cv: Condvar,
}

impl Batch {
    fn arrive(&self, st: &mut BatchState) {
        st.outstanding -= 1;
        if st.outstanding == 0 && !st.members.is_empty() && st.result.is_none() {
            st.result = Some(self.shared.submit(&st.members));
            self.cv.notify_all();
        }
    }

    /// A member that needs no job (cached, re-attached, or failed before submission).
    pub(super) fn leave(&self) {
        let mut st = self.st.lock().unwrap_or_else(|e| e.into_inner());
        self.arrive(&mut st);
    }

    fn join(&self, m: Member) -> std::result::Result<String, String> {
        let mut st = self.st.lock().unwrap_or_else(|e| e.into_inner());
        st.members.push(m);
        self.arrive(&mut st);
        loop {
            if let Some(r) = &st.result {
                return r.clone();
            }
            st = self.cv.wait(st).unwrap_or_else(|e| e.into_inner());
        }
    }
}

/// The Slurm executor of one run.
pub struct Slurm {
    shared: Arc<Shared>,
}

/// Set by the signal handler; read by the watcher thread.
static SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_signal(sig: libc::c_int) {
    SIGNAL.store(sig, Ordering::SeqCst);
}

/// `name` on PATH.
fn which(name: &str) -> Option<PathBuf> {
    std::env::var_os("PATH")
        .iter()
        .flat_map(std::env::split_paths)
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

/// Checks that the Slurm client commands exist and the controller answers.
fn check_cluster() -> std::result::Result<(), String> {
    for c in ["sbatch", "squeue", "scancel", "sinfo"] {
        if which(c).is_none() {
            return Err(format!(
                "`{c}` not found on PATH: Slurm's client commands are needed for `executor: slurm` (install them, or run with --executor local)"
            ));
        }
    }
    let out = Command::new("sinfo")
        .args(["-h", "-o", "%P"])
        .output()
        .map_err(|e| format!("sinfo: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "the Slurm controller is not reachable (`sinfo` failed: {})",
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    Ok(())
}

impl Slurm {
    /// Checks the cluster (bad input when unusable) and prepares `artifacts/slurm/`.
    pub fn connect(store_root: &Path, workspace: &Path) -> Result<Self> {
        check_cluster().map_err(|m| Error::Usage(format!("executor slurm: {m}")))?;
        let dir = store_root.join("slurm");
        let jobs = dir.join("jobs");
        Ok(Self {
            shared: Arc::new(Shared {
                workspace: workspace.to_path_buf(),
                dir,
                jobs,
                queue: Mutex::new(Snapshot::default()),
                active: Mutex::new(BTreeMap::new()),
                counter: AtomicUsize::new(0),
            }),
        })
    }

    /// SIGINT/SIGTERM: cancel this run's jobs, delete their directories, exit 130/143.
    pub fn install_cancel_on_signal(&self) {
        let handler = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
        // SAFETY: the handler only stores to an atomic (async-signal-safe).
        unsafe {
            libc::signal(libc::SIGINT, handler);
            libc::signal(libc::SIGTERM, handler);
        }
        let shared = Arc::clone(&self.shared);
        std::thread::spawn(move || loop {
            let sig = SIGNAL.load(Ordering::SeqCst);
            if sig != 0 {
                shared.cancel_all();
                eprintln!("pipeline: interrupted; nothing unfinished was cached");
                std::process::exit(128 + sig);
            }
            std::thread::sleep(Duration::from_millis(50));
        });
    }

    /// One ticket per unit; units of the same (stage, expansion) share a batch.
    pub fn tickets(&self, groups: &[(usize, usize)]) -> Vec<Ticket> {
        let mut batches: HashMap<(usize, usize), Arc<Batch>> = HashMap::new();
        for g in groups {
            let b = batches.entry(*g).or_insert_with(|| {
                Arc::new(Batch {
                    shared: Arc::clone(&self.shared),
                    st: Mutex::new(BatchState::default()),
                    cv: Condvar::new(),
                })
            });
            b.st.lock().unwrap_or_else(|e| e.into_inner()).outstanding += 1;
        }
        groups
            .iter()
            .map(|g| Ticket(Some(Arc::clone(&batches[g]))))
            .collect()
    }

    /// The directory of an earlier run's job for `identity` (adopted or attached), or a new
    /// empty one.
    pub fn work_dir(&self, identity: &str, _unit: &str) -> Result<Work> {
        let sh = &self.shared;
        for d in [&sh.dir, &sh.jobs] {
            std::fs::create_dir_all(d).map_err(|e| Error::io(d, e))?;
        }
        let now = Instant::now();
        let kept = recover(&sh.dir, identity, |job| {
            // Unknown (squeue failed) counts as live: never submit twice.
            sh.state(job, now).is_none_or(|s| s.is_some())
        })?;
        if let Some((dir, Disposition::Adopt(job) | Disposition::Attach(job))) = kept {
            return Ok(Work {
                dir,
                attached: Some(job),
            });
        }
        let dir = sh.dir.join(format!("{identity}.{}", std::process::id()));
        remove_tree(&dir)?;
        let out = dir.join("out");
        std::fs::create_dir_all(&out).map_err(|e| Error::io(&out, e))?;
        Ok(Work {
            dir,
            attached: None,
        })
    }

    /// Submits the unit with its batch (or attaches to its earlier job) and waits for it.
    pub fn execute(
        &self,
        work: &Work,
        mut ticket: Ticket,
        job: &Job,
        on_progress: &(dyn Fn(&ProgressLine) + Sync),
    ) -> Result<Outcome> {
        let since = Instant::now();
        let id = match &work.attached {
            Some(id) => {
                drop(ticket);
                self.shared
                    .active
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .insert(id.clone(), work.dir.clone());
                id.clone()
            }
            None => {
                let batch = ticket.0.take().expect("a Slurm ticket");
                let joined = batch.join(Member {
                    shard: job.shard,
                    dir: work.dir.clone(),
                    exe: job.exe.to_path_buf(),
                    args: job.args.to_vec(),
                    resources: job.resources.clone(),
                    name: job.name.to_owned(),
                    sharded: job.sharded,
                });
                match joined {
                    Ok(base) => member_id(&base, job.sharded, job.shard),
                    Err(msg) => {
                        let log = work.dir.join("log.txt");
                        write_atomic(&log, msg.as_bytes())?;
                        return Ok(Outcome {
                            success: false,
                            status: "submission failed".into(),
                            summary: None,
                            stderr_tail: vec![msg],
                            log,
                        });
                    }
                }
            }
        };
        let outcome = self.wait(&work.dir, &id, since, on_progress);
        self.shared
            .active
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&id);
        outcome
    }

    fn wait(
        &self,
        dir: &Path,
        id: &str,
        since: Instant,
        on_progress: &(dyn Fn(&ProgressLine) + Sync),
    ) -> Result<Outcome> {
        let mut out = Tail::new(dir.join("stdout"));
        let mut summary = None;
        let mut absent: Option<Instant> = None;
        let handle = |lines: Vec<String>, summary: &mut Option<String>| {
            for line in lines {
                if let Some(p) = parse_progress(&line) {
                    on_progress(&p);
                } else if let Some(t) = line.strip_prefix("::summary ") {
                    *summary = Some(t.trim().to_owned());
                }
            }
        };
        let status = loop {
            handle(out.lines(false), &mut summary);
            if let Some(rc) = read_exit(dir) {
                handle(out.lines(true), &mut summary);
                break Ok(rc);
            }
            match self.shared.state(id, since) {
                Some(Some(_)) => absent = None,
                Some(None) => {
                    let t = *absent.get_or_insert_with(Instant::now);
                    if t.elapsed() > GRACE {
                        break Err(job_state(id));
                    }
                }
                None => {}
            }
            std::thread::sleep(POLL);
        };
        // One log like the local executor's: stdout, then stderr.
        let stdout = std::fs::read(dir.join("stdout")).unwrap_or_default();
        let stderr = std::fs::read(dir.join("stderr")).unwrap_or_default();
        let job_log = self.job_log(id);
        let mut log = stdout;
        log.extend_from_slice(&stderr);
        log.extend_from_slice(&job_log);
        let log_path = dir.join("log.txt");
        write_atomic(&log_path, &log)?;
        for f in ["stdout", "stderr", "exit", "job"] {
            let _ = std::fs::remove_file(dir.join(f));
        }
        let mut tail: VecDeque<String> = VecDeque::new();
        for l in String::from_utf8_lossy(&stderr)
            .lines()
            .chain(String::from_utf8_lossy(&job_log).lines())
        {
            if tail.len() == TAIL_LINES {
                tail.pop_front();
            }
            tail.push_back(l.to_owned());
        }
        let (success, status) = match status {
            Ok(0) => (true, format!("Slurm job {id}: exit status 0")),
            Ok(rc) => (false, format!("Slurm job {id}: exit status {rc}")),
            Err(state) => (
                false,
                format!("Slurm job {id} ended without an exit status: {state}"),
            ),
        };
        Ok(Outcome {
            success,
            status,
            summary,
            stderr_tail: tail.into(),
            log: log_path,
        })
    }

    /// Slurm's own messages about the job (from `--output`), e.g. `CANCELLED`.
    fn job_log(&self, id: &str) -> Vec<u8> {
        std::fs::read(self.shared.jobs.join(format!("{id}.log"))).unwrap_or_default()
    }
}

/// `JobState=... Reason=...` from `scontrol show job`, or why it is unknown.
fn job_state(id: &str) -> String {
    let out = Command::new("scontrol")
        .args(["show", "job", "-o", id])
        .output();
    match out {
        Ok(o) if o.status.success() => {
            let text = String::from_utf8_lossy(&o.stdout);
            let keep: Vec<&str> = text
                .split_whitespace()
                .filter(|w| {
                    w.starts_with("JobState=")
                        || w.starts_with("Reason=")
                        || w.starts_with("ExitCode=")
                })
                .collect();
            keep.join(" ")
        }
        _ => "the job is no longer known to Slurm".to_owned(),
    }
}

/// Reads complete lines appended to a file since the last call.
struct Tail {
    path: PathBuf,
    pos: u64,
    partial: Vec<u8>,
}

impl Tail {
    fn new(path: PathBuf) -> Self {
        Self {
            path,
            pos: 0,
            partial: Vec::new(),
        }
    }

    /// New complete lines; with `last`, also a final line without newline.
    fn lines(&mut self, last: bool) -> Vec<String> {
        let mut buf = Vec::new();
        if let Ok(mut f) = std::fs::File::open(&self.path) {
            if f.seek(SeekFrom::Start(self.pos)).is_ok() {
                if let Ok(n) = f.read_to_end(&mut buf) {
                    self.pos += n as u64;
                }
            }
        }
        self.partial.extend_from_slice(&buf);
        let mut out = Vec::new();
        while let Some(i) = self.partial.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = self.partial.drain(..=i).collect();
            out.push(String::from_utf8_lossy(&line[..i]).into_owned());
        }
        if last && !self.partial.is_empty() {
            out.push(String::from_utf8_lossy(&self.partial).into_owned());
            self.partial.clear();
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn array_specs_compress_runs() {
        assert_eq!(array_spec(&[0, 1, 2, 3]), "0-3");
        assert_eq!(array_spec(&[5, 0, 1, 7, 8, 3]), "0-1,3,5,7-8");
        assert_eq!(array_spec(&[4]), "4");
        assert_eq!(array_spec(&[2, 2, 3]), "2-3");
    }

    #[test]
    fn quoting_survives_the_shell() {
        let nasty = "it's a $HOME `x` \"q\"";
        let out = Command::new("/bin/sh")
            .args(["-c", &format!("printf %s {}", shell_quote(nasty))])
            .output()
            .unwrap();
        assert_eq!(String::from_utf8_lossy(&out.stdout), nasty);
    }

    #[test]
    fn sbatch_arguments_for_an_array_and_a_plain_job() {
        let res = Resources {
            cpus: Some(2),
            mem: Some("4G".into()),
            partition: Some("gpu".into()),
            gpus: Some(1),
            sbatch_args: vec!["--qos=long".into()],
            ..Resources::default()
        };
        let a = sbatch_args(
            "simulate",
            Path::new("/ws"),
            Path::new("/ws/artifacts/slurm/jobs"),
            &res,
            Some(&[3, 0, 1]),
            Path::new("/s.sh"),
        );
        assert_eq!(
            a,
            [
                "--parsable",
                "--job-name=pino:simulate",
                "--chdir=/ws",
                "--output=/ws/artifacts/slurm/jobs/%A_%a.log",
                "--error=/ws/artifacts/slurm/jobs/%A_%a.log",
                "--cpus-per-task=2",
                "--mem=4G",
                "--gpus=1",
                "--partition=gpu",
                "--qos=long",
                "--array=0-1,3",
                "/s.sh"
            ]
        );
        let p = sbatch_args(
            "train[algorithm=3]",
            Path::new("/ws"),
            Path::new("/j"),
            &Resources::default(),
            None,
            Path::new("/s.sh"),
        );
        assert!(p.contains(&"--output=/j/%j.log".to_owned()), "{p:?}");
        assert!(!p.iter().any(|x| x.starts_with("--array")), "{p:?}");
    }

    /// The script runs the stage with the context of its array task, keeps its streams and
    /// records the exit status; an unknown task id fails without touching any unit.
    #[test]
    fn batch_script_runs_the_right_unit_and_records_exit() {
        let ws = tempfile::tempdir().unwrap();
        let d0 = ws.path().join("u0");
        let d2 = ws.path().join("u 2's");
        for d in [&d0, &d2] {
            std::fs::create_dir_all(d).unwrap();
        }
        let script = batch_script(
            ws.path(),
            Path::new("/bin/sh"),
            &[
                "-c".into(),
                "echo ctx=$PINO_STAGE_CONTEXT pwd=$(pwd); echo oops >&2; exit 3".into(),
            ],
            &[(0, d0.clone()), (2, d2.clone())],
        );
        let path = ws.path().join("job.sh");
        std::fs::write(&path, &script).unwrap();
        let run = |task: &str| {
            Command::new("/bin/sh")
                .arg(&path)
                .env("SLURM_ARRAY_TASK_ID", task)
                .status()
                .unwrap()
                .code()
        };
        assert_eq!(run("2"), Some(3));
        let so = std::fs::read_to_string(d2.join("stdout")).unwrap();
        assert_eq!(
            so.trim(),
            format!(
                "ctx={}/context.json pwd={}",
                d2.display(),
                ws.path().display()
            )
        );
        assert_eq!(
            std::fs::read_to_string(d2.join("stderr")).unwrap(),
            "oops\n"
        );
        assert_eq!(read_exit(&d2), Some(3));
        assert!(!d2.join("exit.tmp").exists());
        assert!(!d0.join("exit").exists());
        assert_eq!(run("7"), Some(97));
        assert!(!d0.join("stdout").exists());
    }

    #[test]
    fn squeue_output_parses() {
        let q = parse_squeue("12_0|RUNNING\n12_1|PENDING\n 13|COMPLETING \n\n");
        assert_eq!(q.len(), 3);
        assert_eq!(q["12_1"], "PENDING");
        assert_eq!(q["13"], "COMPLETING");
    }

    #[test]
    fn recovery_rule() {
        let live = |j: &str| j == "5_1";
        assert_eq!(
            classify(Some("5_0"), Some(0), live),
            Disposition::Adopt("5_0".into())
        );
        assert_eq!(
            classify(Some("5_1"), None, live),
            Disposition::Attach("5_1".into())
        );
        // Gone without an exit status (killed node, scancel): submit again.
        assert_eq!(classify(Some("5_2"), None, live), Disposition::Discard);
        // A failed attempt is retried, like a failed local unit.
        assert_eq!(classify(Some("5_1"), Some(1), live), Disposition::Discard);
        // Killed between mkdir and sbatch: no job id, nothing to wait for.
        assert_eq!(classify(None, None, live), Disposition::Discard);
        assert_eq!(classify(None, Some(0), live), Disposition::Discard);
    }

    #[test]
    fn recover_keeps_one_directory_and_deletes_the_rest() {
        let base = tempfile::tempdir().unwrap();
        let mk = |name: &str, job: Option<&str>, exit: Option<&str>| {
            let d = base.path().join(name);
            std::fs::create_dir_all(d.join("out")).unwrap();
            if let Some(j) = job {
                std::fs::write(d.join("job"), j).unwrap();
            }
            if let Some(e) = exit {
                std::fs::write(d.join("exit"), e).unwrap();
            }
            d
        };
        let dead = mk("abc.10", Some("7"), None);
        let running = mk("abc.11", Some("8_2"), None);
        let other = mk("abd.12", Some("9"), Some("0\n"));
        let live = |j: &str| j == "8_2";
        let (dir, d) = recover(base.path(), "abc", live).unwrap().unwrap();
        assert_eq!(
            (dir, d),
            (running.clone(), Disposition::Attach("8_2".into()))
        );
        assert!(!dead.exists());
        assert!(other.exists(), "another identity is left alone");
        // Finished while nobody watched: adopted.
        std::fs::write(running.join("exit"), "0\n").unwrap();
        let (_, d) = recover(base.path(), "abc", |_| false).unwrap().unwrap();
        assert_eq!(d, Disposition::Adopt("8_2".into()));
        assert_eq!(recover(base.path(), "zzz", live).unwrap(), None);
    }

    #[test]
    fn tail_yields_complete_lines_only() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("f");
        let mut t = Tail::new(p.clone());
        assert!(t.lines(false).is_empty(), "a missing file is no lines");
        std::fs::write(&p, "a\nb").unwrap();
        assert_eq!(t.lines(false), ["a"]);
        std::fs::write(&p, "a\nbc\nd").unwrap();
        assert_eq!(t.lines(false), ["bc"]);
        assert_eq!(t.lines(true), ["d"]);
    }
}
