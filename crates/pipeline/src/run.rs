//! `pipeline run`: select units, take the run lock, and execute stale units in dependency
//! order with up to `jobs` processes at once.
//!
//! Scheduling: a unit is ready when every unit of every upstream stage is done (downstream
//! stages see all shards and expansions of an input as one artifact). Ready units start
//! longest first, by how long each ran the last time it ran in this workspace (the manifest of
//! its lock-record entry's object): with more ready units than free slots, the longest one no
//! longer starts last and alone while the other slots idle (a rerun of the default job's five
//! trainings on two slots: 21 -> 18 minutes by their recorded times). A unit without a record
//! (never run, or its object collected) counts as the longest: what is new starts early; among
//! those, the bigger work its stage's check announced (`::work`, [`crate::check`]) starts
//! first, so a first run of the default job starts algorithm 5 (five Fourier layers against
//! three) first too. Ties keep the pipeline's unit order. A ready unit's identity
//! is computed from its upstream outputs' content hashes; if a verified object with that
//! identity exists it is reused (that is also the run-cache: earlier parameters map to
//! earlier identities), otherwise the stage runs in `tmp/` and its output is committed. A
//! failed unit caches nothing; units downstream of it are skipped, independent units go on.
//! The lock record is rewritten (atomically) after every unit that changes it, so a killed
//! run keeps everything it finished. Every running unit's progress is also kept in a file
//! under `artifacts/running/` for other processes ([`crate::progress`]). Where a unit's
//! process runs (this machine or a Slurm job) is the [`crate::executor`]'s business;
//! verification and commit happen here for both.

use crate::executor::{Executor, ExecutorKind, Job, Ticket};
use crate::plan::{code_of, entry_for, units_of, Code, Unit};
use crate::progress::Board;
use crate::spec::Pipeline;
use crate::store::{Cached, LockEntry, LockRecord, Manifest, Store, PROTOCOL_VERSION};
use crate::ui::{fmt_duration, table, Ui};
use crate::{runlock::RunLock, Error, Result};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::time::{Duration, Instant};

/// Options of `pipeline run`.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Stages or expansions to run (empty: all).
    pub targets: Vec<String>,
    /// Rerun the targets even when fresh.
    pub force: bool,
    /// Units run at once (at least 1).
    pub jobs: usize,
    /// Wait for another run's lock instead of failing.
    pub wait: bool,
    /// `--executor`: overrides the pipeline file's `executor:`.
    pub executor: Option<ExecutorKind>,
}

/// Units to consider, in dependency order, and the keys of those to force.
pub fn select(
    p: &Pipeline,
    targets: &[String],
    force: bool,
) -> Result<(Vec<Unit>, BTreeSet<String>)> {
    let n = p.stages.len();
    let mut whole = vec![targets.is_empty(); n];
    let mut partial: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n];
    let mut forced = BTreeSet::new();
    for t in targets {
        let stage_name = t.split('[').next().unwrap_or(t);
        let idx = p.index(stage_name).ok_or_else(|| {
            let known: Vec<&str> = p.stages.iter().map(|s| s.name.as_str()).collect();
            Error::Usage(format!(
                "{}: unknown stage `{t}` (stages: {})",
                p.file,
                known.join(", ")
            ))
        })?;
        let exps: Vec<usize> = if t.contains('[') {
            let e = p.stages[idx]
                .expansions
                .iter()
                .position(|e| e.name == *t)
                .ok_or_else(|| {
                    let known: Vec<&str> = p.stages[idx]
                        .expansions
                        .iter()
                        .map(|e| e.name.as_str())
                        .collect();
                    Error::Usage(format!(
                        "{}: stage `{stage_name}` has no expansion `{t}` (expansions: {})",
                        p.file,
                        known.join(", ")
                    ))
                })?;
            partial[idx].insert(e);
            vec![e]
        } else {
            whole[idx] = true;
            (0..p.stages[idx].expansions.len()).collect()
        };
        if force {
            for u in units_of(p, idx)
                .into_iter()
                .filter(|u| exps.contains(&u.expansion))
            {
                forced.insert(u.key);
            }
        }
    }
    if force && targets.is_empty() {
        // `pipeline run --force`: everything.
        forced = (0..n).flat_map(|i| units_of(p, i)).map(|u| u.key).collect();
    }
    // Upstream closure: stages are topologically ordered, so one backward pass suffices.
    for i in (0..n).rev() {
        if whole[i] || !partial[i].is_empty() {
            for up in p.stages[i].inputs.values().flatten() {
                whole[p.index(up).expect("validated")] = true;
            }
        }
    }
    let units = (0..n)
        .flat_map(|i| units_of(p, i))
        .filter(|u| whole[u.stage] || partial[u.stage].contains(&u.expansion))
        .collect();
    Ok((units, forced))
}

#[derive(Debug, Clone)]
enum State {
    Pending,
    Running,
    Done {
        identity: String,
        output_hash: String,
    },
    Failed,
    Skipped,
}

enum Outcome {
    Cached(LockEntry, Manifest),
    Ran(LockEntry, Manifest, Duration),
    Failed(String, Duration),
}

struct Ctx<'a> {
    p: &'a Pipeline,
    store: &'a Store,
    ui: &'a Ui,
    codes: &'a HashMap<usize, Code>,
    executor: &'a Executor,
    board: &'a Board,
}

fn safe_name(key: &str) -> String {
    key.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_=.,".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Computes or reuses one unit.
fn work(
    cx: &Ctx,
    u: &Unit,
    inputs: BTreeMap<String, Vec<String>>,
    dirs: BTreeMap<String, Vec<String>>,
    force: bool,
    ticket: Ticket,
) -> Outcome {
    let t0 = Instant::now();
    let entry = entry_for(cx.p, u, &cx.codes[&u.stage], inputs);
    let id = entry.identity.clone();
    if !force {
        match cx.store.verify(&id) {
            Cached::Valid(m) => return Outcome::Cached(entry, m),
            Cached::Corrupt(why) => {
                cx.ui.line(&format!(
                    "[{}] cached output is corrupted ({why}); discarding it and recomputing",
                    u.key
                ));
                if let Err(e) = cx.store.discard(&id) {
                    return Outcome::Failed(
                        format!("cannot discard corrupted object: {e}"),
                        t0.elapsed(),
                    );
                }
            }
            Cached::Missing => {}
        }
    }
    match compute(cx, u, &entry, dirs, ticket) {
        Ok(Ok(m)) => Outcome::Ran(entry, m, t0.elapsed()),
        Ok(Err(msg)) => Outcome::Failed(msg, t0.elapsed()),
        Err(e) => Outcome::Failed(e.to_string(), t0.elapsed()),
    }
}

/// Runs the stage process for `u`; `Ok(Err(message))` when the stage failed.
fn compute(
    cx: &Ctx,
    u: &Unit,
    entry: &LockEntry,
    dirs: BTreeMap<String, Vec<String>>,
    ticket: Ticket,
) -> Result<std::result::Result<Manifest, String>> {
    let stage = &cx.p.stages[u.stage];
    let placed = cx.executor.work_dir(cx.store, &entry.identity, &u.key)?;
    let work = placed.dir.clone();
    let scratch = cx.store.scratch_dir(&entry.identity)?;
    let context = stage_protocol::Context {
        protocol: PROTOCOL_VERSION,
        stage: stage.expansions[u.expansion].name.clone(),
        params: entry.params.clone(),
        inputs: dirs
            .into_iter()
            .map(|(name, ds)| (name, ds.into_iter().map(std::path::PathBuf::from).collect()))
            .collect(),
        output: work.join("out"),
        scratch: Some(scratch),
        shard: stage_protocol::Shard {
            index: u.shard,
            count: stage.shards,
        },
        check: false,
    };
    match &placed.attached {
        // An earlier run's job for this very identity: its context is already there.
        Some(job) => cx.ui.line(&format!(
            "[{}] re-attaching to Slurm job {job} of an earlier run",
            u.key
        )),
        None => {
            atomic_file::write_atomic(&work.join(stage_protocol::CONTEXT_FILE), &context.to_json())?
        }
    }
    let view = cx.ui.start(&u.key);
    // Removed when this function returns, however the unit ended.
    let record = cx.board.start(&u.key, &stage.name);
    let t0 = Instant::now();
    let job = Job {
        unit: &u.key,
        name: &stage.expansions[u.expansion].name,
        exe: &cx.codes[&u.stage].exe,
        args: &entry.args,
        workspace: &cx.p.workspace,
        resources: &stage.resources,
        shard: u.shard,
        sharded: stage.shards > 1,
    };
    let outcome = cx.executor.execute(&placed, ticket, &job, &|pl| {
        view.progress(pl);
        record.update(pl);
    })?;
    let took = t0.elapsed();
    if outcome.success {
        match cx.store.commit(
            &work,
            &entry.identity,
            &u.key,
            outcome.summary,
            took.as_millis() as u64,
        ) {
            Ok(m) => {
                cx.store.drop_scratch(&entry.identity)?;
                view.finish(&format!("ran in {}", fmt_duration(took)));
                Ok(Ok(m))
            }
            Err(e) => {
                view.finish("FAILED");
                let _ = crate::store::remove_tree(&work);
                Ok(Err(format!("output rejected: {e}")))
            }
        }
    } else {
        view.finish("FAILED");
        let kept = cx
            .store
            .root
            .join("logs")
            .join(format!("{}.failed.log", safe_name(&u.key)));
        let _ = std::fs::rename(&outcome.log, &kept);
        let _ = crate::store::remove_tree(&work);
        let mut msg = format!(
            "{} ({}); last lines of stderr:\n",
            stage.cmd.join(" "),
            outcome.status
        );
        for l in &outcome.stderr_tail {
            msg.push_str(&format!("    | {l}\n"));
        }
        msg.push_str(&format!("  full log: {}", kept.display()));
        Ok(Err(msg))
    }
}

fn prune(rec: &mut LockRecord, p: &Pipeline, entries: &BTreeMap<String, LockEntry>) {
    let all: BTreeSet<String> = (0..p.stages.len())
        .flat_map(|i| units_of(p, i))
        .map(|u| u.key)
        .collect();
    let mut e = entries.clone();
    e.retain(|k, _| all.contains(k));
    rec.pipelines.insert(p.key.clone(), e);
}

/// Runs the pipeline. `Ok(())` when every selected unit is done; [`Error::StageFailed`] when
/// some failed (the others still ran).
pub fn run(p: &Pipeline, opts: &RunOptions, ui: &Ui) -> Result<()> {
    let (units, forced) = select(p, &opts.targets, opts.force)?;
    // Resolve all code before touching the store: bad input leaves no trace.
    let store = Store::open_read(&p.workspace);
    let mut codes = HashMap::new();
    for u in &units {
        if let std::collections::hash_map::Entry::Vacant(v) = codes.entry(u.stage) {
            v.insert(code_of(p, &p.stages[u.stage], &store.cache)?);
        }
    }
    let announced_work = crate::check::run_checks(p, &units)?;
    let executor = Executor::new(opts.executor.unwrap_or(p.executor), &store, &p.workspace)?;
    store.create_dirs()?;
    let _lock = RunLock::acquire_for_workspace(&store.root, opts.wait, ui)?;
    store.clean_debris()?;
    // Declared after the lock, so dropped (its records removed) before the lock is released.
    let board = Board::open(&store.root, &p.key)?;
    executor.start();
    let mut rec = store.read_lock_record()?;
    let entries = rec.pipelines.get(&p.key).cloned().unwrap_or_default();
    let t_run = Instant::now();

    let expected = recorded_durations(&store, &units, &entries);
    let announced = units
        .iter()
        .map(|u| announced_work.get(&(u.stage, u.expansion)).copied())
        .collect();
    let mut ledger = Ledger::new(p, &units, entries, expected, announced);
    let cx = Ctx {
        p,
        store: &store,
        ui,
        codes: &codes,
        executor: &executor,
        board: &board,
    };
    let jobs = executor.parallelism(opts.jobs);
    let mut save_error = None;

    std::thread::scope(|s| {
        let (tx, rx) = std::sync::mpsc::channel::<(usize, Outcome)>();
        let mut running = 0;
        loop {
            let dispatch = ledger.dispatch(&store, jobs.saturating_sub(running));
            // Units of one stage expansion dispatched together form a batch (one Slurm
            // array job); the local executor ignores batches.
            let groups: Vec<(usize, usize)> = dispatch
                .iter()
                .map(|d| (units[d.unit].stage, units[d.unit].expansion))
                .collect();
            let tickets = executor.tickets(&groups);
            for (d, ticket) in dispatch.into_iter().zip(tickets) {
                running += 1;
                let tx = tx.clone();
                let u = &units[d.unit];
                let force = forced.contains(&u.key);
                let cx = &cx;
                s.spawn(move || {
                    let _ = tx.send((d.unit, work(cx, u, d.inputs, d.dirs, force, ticket)));
                });
            }
            if running == 0 {
                break;
            }
            let (i, outcome) = rx.recv().expect("a worker is running");
            running -= 1;
            if ledger.record(i, outcome, ui) {
                prune(&mut rec, p, &ledger.entries);
                if let Err(err) = store.write_lock_record(&rec) {
                    save_error.get_or_insert(err);
                }
            }
        }
    });
    store.cache.save()?;
    if let Some(e) = save_error {
        return Err(e);
    }
    ledger.report(&p.file, t_run.elapsed())
}

/// Per unit, how long it ran the last time it ran here: the duration in the manifest of its
/// lock-record entry's object (`None` without an entry or with the object gone).
fn recorded_durations(
    store: &Store,
    units: &[Unit],
    entries: &BTreeMap<String, LockEntry>,
) -> Vec<Option<Duration>> {
    units
        .iter()
        .map(|u| {
            let entry = entries.get(&u.key)?;
            store.recorded_duration(&entry.identity)
        })
        .collect()
}

/// A ready unit handed to a worker: its upstream outputs' content hashes (for its identity)
/// and directories (for its context), by input name.
struct Dispatch {
    unit: usize,
    inputs: BTreeMap<String, Vec<String>>,
    dirs: BTreeMap<String, Vec<String>>,
}

/// The run's account of its units: what each waits for, where each stands, the rows of the
/// final table and the lock-record entries as they change.
struct Ledger<'a> {
    units: &'a [Unit],
    /// Per unit, per input name: the positions of the upstream units it reads.
    deps: Vec<Vec<(String, Vec<usize>)>>,
    state: Vec<State>,
    rows: Vec<Option<Vec<String>>>,
    failures: Vec<String>,
    /// Per unit, how long it ran last time (the dispatch order: longest first, unknown first).
    expected: Vec<Option<Duration>>,
    /// Per unit, the work its check announced (orders the units without a record).
    work: Vec<Option<f64>>,
    /// This pipeline's lock-record entries, updated as units finish.
    entries: BTreeMap<String, LockEntry>,
    changed: bool,
    ran: usize,
}

impl<'a> Ledger<'a> {
    fn new(
        p: &Pipeline,
        units: &'a [Unit],
        entries: BTreeMap<String, LockEntry>,
        expected: Vec<Option<Duration>>,
        work: Vec<Option<f64>>,
    ) -> Self {
        let pos: HashMap<&str, usize> = units
            .iter()
            .enumerate()
            .map(|(i, u)| (u.key.as_str(), i))
            .collect();
        let deps = units
            .iter()
            .map(|u| {
                p.stages[u.stage]
                    .inputs
                    .iter()
                    .map(|(name, ups)| {
                        let ups = ups
                            .iter()
                            .flat_map(|up| units_of(p, p.index(up).expect("validated")))
                            .map(|x| pos[x.key.as_str()])
                            .collect();
                        (name.clone(), ups)
                    })
                    .collect()
            })
            .collect();
        Self {
            units,
            deps,
            state: vec![State::Pending; units.len()],
            rows: vec![None; units.len()],
            failures: Vec::new(),
            expected,
            work,
            entries,
            changed: false,
            ran: 0,
        }
    }

    /// Marks the pending units whose upstream failed as skipped, and takes up to `free` ready
    /// ones (every upstream unit done) as running, in [`Ledger::start_order`].
    fn dispatch(&mut self, store: &Store, free: usize) -> Vec<Dispatch> {
        let mut ready = Vec::new();
        for i in 0..self.units.len() {
            if !matches!(self.state[i], State::Pending) {
                continue;
            }
            let mut upstream = self.deps[i].iter().flat_map(|(_, v)| v);
            if let Some(&d) =
                upstream.find(|&&d| matches!(self.state[d], State::Failed | State::Skipped))
            {
                self.state[i] = State::Skipped;
                self.rows[i] = Some(vec![
                    self.units[i].key.clone(),
                    "skipped".into(),
                    "-".into(),
                    format!("upstream {} did not finish", self.units[d].key),
                ]);
                continue;
            }
            if self.deps[i]
                .iter()
                .flat_map(|(_, v)| v)
                .all(|&d| matches!(self.state[d], State::Done { .. }))
            {
                ready.push(i);
            }
        }
        // Stable: ties keep unit order.
        ready.sort_by(|&a, &b| self.start_order(a, b));
        ready
            .into_iter()
            .take(free)
            .map(|i| self.start(store, i))
            .collect()
    }

    /// Which of two ready units starts first: the longer by recorded duration; a unit without
    /// a record before any with one; among those, the bigger announced work first, then one
    /// that announced none.
    fn start_order(&self, a: usize, b: usize) -> std::cmp::Ordering {
        use std::cmp::Ordering::{Equal, Greater, Less};
        match (self.expected[a], self.expected[b]) {
            (Some(x), Some(y)) => y.cmp(&x),
            (None, Some(_)) => Less,
            (Some(_), None) => Greater,
            (None, None) => match (self.work[a], self.work[b]) {
                (Some(x), Some(y)) => y.total_cmp(&x),
                (Some(_), None) => Less,
                (None, Some(_)) => Greater,
                (None, None) => Equal,
            },
        }
    }

    /// Takes ready unit `i` as running: its upstream outputs' hashes and directories.
    fn start(&mut self, store: &Store, i: usize) -> Dispatch {
        let mut inputs = BTreeMap::new();
        let mut dirs = BTreeMap::new();
        for (name, ups) in &self.deps[i] {
            let mut hashes = Vec::new();
            let mut ds = Vec::new();
            for &d in ups {
                if let State::Done {
                    identity,
                    output_hash,
                } = &self.state[d]
                {
                    hashes.push(output_hash.clone());
                    ds.push(store.out_dir(identity).to_string_lossy().into_owned());
                }
            }
            inputs.insert(name.clone(), hashes);
            dirs.insert(name.clone(), ds);
        }
        self.state[i] = State::Running;
        Dispatch {
            unit: i,
            inputs,
            dirs,
        }
    }

    /// Books a finished unit; true when the lock-record entries changed (to be saved).
    fn record(&mut self, i: usize, outcome: Outcome, ui: &Ui) -> bool {
        let key = self.units[i].key.clone();
        let (mut entry, manifest, row) = match outcome {
            Outcome::Cached(e, m) => {
                let summary = m.summary.clone().unwrap_or_default();
                (
                    e,
                    m,
                    vec![key.clone(), "cached".into(), "-".into(), summary],
                )
            }
            Outcome::Ran(e, m, took) => {
                self.ran += 1;
                let summary = m.summary.clone().unwrap_or_default();
                let row = vec![key.clone(), "ran".into(), fmt_duration(took), summary];
                (e, m, row)
            }
            Outcome::Failed(msg, took) => {
                ui.line(&format!(
                    "[{key}] FAILED after {}: {msg}",
                    fmt_duration(took)
                ));
                self.state[i] = State::Failed;
                self.rows[i] = Some(vec![
                    key.clone(),
                    "FAILED".into(),
                    fmt_duration(took),
                    String::new(),
                ]);
                self.failures.push(key);
                return false;
            }
        };
        entry.output_hash = manifest.output_hash.clone();
        self.state[i] = State::Done {
            identity: entry.identity.clone(),
            output_hash: manifest.output_hash,
        };
        self.rows[i] = Some(row);
        if self.entries.get(&key) == Some(&entry) {
            return false;
        }
        self.entries.insert(key, entry);
        self.changed = true;
        true
    }

    /// Prints the run's table and totals (or that nothing was to do); the failures as the
    /// error.
    fn report(self, file: &str, elapsed: Duration) -> Result<()> {
        let rows: Vec<Vec<String>> = self.rows.into_iter().flatten().collect();
        if self.ran == 0 && self.failures.is_empty() && !self.changed {
            println!(
                "Nothing to do: all {} units of {file} are up to date.",
                rows.len()
            );
            return Ok(());
        }
        print!("{}", table(&["UNIT", "RESULT", "TIME", "SUMMARY"], &rows));
        let cached = rows.iter().filter(|r| r[1] == "cached").count();
        let skipped = rows.iter().filter(|r| r[1] == "skipped").count();
        println!(
            "{} ran, {cached} cached, {} failed, {skipped} skipped in {}",
            self.ran,
            self.failures.len(),
            fmt_duration(elapsed)
        );
        if self.failures.is_empty() {
            Ok(())
        } else {
            Err(Error::StageFailed {
                count: self.failures.len(),
                names: self.failures.join(", "),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::LoadOptions;

    fn keys(units: &[Unit]) -> Vec<&str> {
        units.iter().map(|u| u.key.as_str()).collect()
    }

    #[test]
    fn targets_pull_in_their_upstream_and_force_only_themselves() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("p.yaml");
        let text = "stages:\n  a:\n    cmd: [x]\n    shards: 2\n  b:\n    cmd: [x]\n    inputs: {i: a}\n    matrix: {k: [1, 2]}\n  c:\n    cmd: [x]\n    inputs: {i: b}\n  d:\n    cmd: [x]\n";
        std::fs::write(&f, text).unwrap();
        let p = Pipeline::load(dir.path(), &f, &LoadOptions::default()).unwrap();
        let (u, forced) = select(&p, &["b[k=2]".into()], true).unwrap();
        assert_eq!(keys(&u), ["a#0", "a#1", "b[k=2]"]);
        assert_eq!(forced.into_iter().collect::<Vec<_>>(), ["b[k=2]"]);
        let (u, forced) = select(&p, &["c".into()], false).unwrap();
        assert_eq!(keys(&u), ["a#0", "a#1", "b[k=1]", "b[k=2]", "c"]);
        assert!(forced.is_empty());
        let (u, forced) = select(&p, &[], true).unwrap();
        assert_eq!(u.len(), 6);
        assert_eq!(forced.len(), 6);
        assert!(matches!(
            select(&p, &["b[k=3]".into()], false),
            Err(Error::Usage(_))
        ));
        assert!(matches!(
            select(&p, &["zz".into()], false),
            Err(Error::Usage(_))
        ));
    }

    #[test]
    fn ready_units_start_longest_first_unknown_first_then_by_announced_work() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("p.yaml");
        let text = "stages:\n  a:\n    cmd: [x]\n  b:\n    cmd: [x]\n    inputs: {i: a}\n    matrix: {k: [1, 2, 3, 4, 5]}\n";
        std::fs::write(&f, text).unwrap();
        let p = Pipeline::load(dir.path(), &f, &LoadOptions::default()).unwrap();
        let (units, _) = select(&p, &[], false).unwrap();
        let store = Store::open_read(dir.path());
        let minutes = |m: u64| Some(Duration::from_secs(60 * m));
        // a, then b[k=1..5]: k=2 has no record, k=1 and k=4 tie.
        let expected = vec![None, minutes(5), None, minutes(6), minutes(5), minutes(9)];
        let work = vec![None; units.len()];
        let mut ledger = Ledger::new(&p, &units, BTreeMap::new(), expected, work);
        // Nothing of b is ready before a is done.
        let first: Vec<usize> = ledger.dispatch(&store, 2).iter().map(|d| d.unit).collect();
        assert_eq!(first, [0]);
        assert!(ledger.dispatch(&store, 2).is_empty());
        ledger.state[0] = State::Done {
            identity: "ia".into(),
            output_hash: "ha".into(),
        };
        let order = |ledger: &mut Ledger, free| -> Vec<&str> {
            let taken: Vec<usize> = ledger
                .dispatch(&store, free)
                .iter()
                .map(|d| d.unit)
                .collect();
            taken.into_iter().map(|i| units[i].key.as_str()).collect()
        };
        assert_eq!(order(&mut ledger, 2), ["b[k=2]", "b[k=5]"]);
        assert_eq!(order(&mut ledger, 1), ["b[k=3]"]);
        assert_eq!(order(&mut ledger, 5), ["b[k=1]", "b[k=4]"]);
        // Without any record: the pipeline's unit order.
        let (unrecorded, unannounced) = (vec![None; units.len()], vec![None; units.len()]);
        let mut fresh = Ledger::new(&p, &units, BTreeMap::new(), unrecorded.clone(), unannounced);
        fresh.state[0] = State::Done {
            identity: "ia".into(),
            output_hash: "ha".into(),
        };
        assert_eq!(order(&mut fresh, 3), ["b[k=1]", "b[k=2]", "b[k=3]"]);
        // A first run with the checks' announced work: the biggest first, then in unit order
        // those that announced none.
        let work = vec![None, Some(3.0), None, Some(3.0), Some(5.0), None];
        let mut announced = Ledger::new(&p, &units, BTreeMap::new(), unrecorded, work);
        announced.state[0] = State::Done {
            identity: "ia".into(),
            output_hash: "ha".into(),
        };
        assert_eq!(
            order(&mut announced, 5),
            ["b[k=4]", "b[k=1]", "b[k=3]", "b[k=2]", "b[k=5]"]
        );
    }

    #[test]
    fn the_recorded_duration_is_the_manifests_and_none_without_one() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open_read(dir.path());
        assert_eq!(store.recorded_duration("nope"), None);
        let object = store.object_dir("id1");
        std::fs::create_dir_all(&object).unwrap();
        let manifest = Manifest {
            format: crate::store::MANIFEST_VERSION,
            identity: "id1".into(),
            unit: "b[k=1]".into(),
            files: Vec::new(),
            output_hash: String::new(),
            summary: None,
            duration_ms: 83_500,
        };
        std::fs::write(
            object.join("manifest.json"),
            serde_json::to_vec(&manifest).unwrap(),
        )
        .unwrap();
        assert_eq!(
            store.recorded_duration("id1"),
            Some(Duration::from_millis(83_500))
        );
        std::fs::write(object.join("manifest.json"), b"{ not json").unwrap();
        assert_eq!(store.recorded_duration("id1"), None);
    }
}
