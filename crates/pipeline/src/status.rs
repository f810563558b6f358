//! `pipeline status`, `pipeline show` and `pipeline dag`: read-only views.
//!
//! Status recomputes every unit's identity from the current pipeline file, code and the
//! upstream outputs it can know (those of fresh upstream units, or of upstream objects already
//! in the run-cache), and compares it with the lock record. A stale unit's reason is the
//! difference between its recorded entry and its current one: code, command, parameter
//! (old -> new), input, shard layout, or a cached output that is missing or corrupted. A unit
//! whose Slurm job is queued or running shows as `submitted` with the job id. A unit that a
//! live `pipeline run` is computing shows as `running` with its last progress
//! ([`crate::progress`]), whatever its state before.

use crate::executor::slurm;
use crate::plan::{code_of, entry_for, units_of};
use crate::progress::{self, RunningUnit};
use crate::spec::Pipeline;
use crate::store::{Cached, LockEntry, Store};
use crate::ui::table;
use crate::{Error, Result};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write;

/// Why `new` differs from the recorded `old`.
fn reasons(old: &LockEntry, new: &LockEntry) -> String {
    let mut r = Vec::new();
    if old.exe_hash != new.exe_hash {
        r.push(format!("code changed ({})", new.exe));
    }
    if old.args != new.args {
        r.push(format!(
            "command changed ({:?} -> {:?})",
            old.args, new.args
        ));
    }
    if old.arg_files != new.arg_files {
        r.push("script changed".to_owned());
    }
    let empty = serde_json::Map::new();
    let po = old.params.as_object().unwrap_or(&empty);
    let pn = new.params.as_object().unwrap_or(&empty);
    let keys: BTreeSet<&String> = po.keys().chain(pn.keys()).collect();
    for k in keys {
        match (po.get(k), pn.get(k)) {
            (Some(a), Some(b)) if a != b => r.push(format!("parameter `{k}` changed: {a} -> {b}")),
            (Some(_), None) => r.push(format!("parameter `{k}` removed")),
            (None, Some(b)) => r.push(format!("parameter `{k}` added: {b}")),
            _ => {}
        }
    }
    let names: BTreeSet<&String> = old.inputs.keys().chain(new.inputs.keys()).collect();
    for n in names {
        if old.inputs.get(n) != new.inputs.get(n) {
            r.push(format!("input `{n}` changed"));
        }
    }
    if old.shard != new.shard {
        r.push(format!(
            "shard layout changed ({}/{} -> {}/{})",
            old.shard[0], old.shard[1], new.shard[0], new.shard[1]
        ));
    }
    if r.is_empty() {
        r.push("identity changed (protocol or unit name)".to_owned());
    }
    r.join("; ")
}

/// One unit's state as `pipeline status` reports it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnitState {
    /// The unit's key.
    pub key: String,
    /// Index of its stage.
    pub stage: usize,
    /// Index of its matrix expansion.
    pub expansion: usize,
    /// `fresh`, `stale`, `never run`, `submitted` or `running`.
    pub state: &'static str,
    /// Why (for stale units), the job (submitted), the progress (running: `42/100 (loss
    /// 0.3)`), or empty.
    pub detail: String,
    /// The live progress record while a `pipeline run` computes the unit.
    pub progress: Option<RunningUnit>,
}

/// The units of pipeline `p` that a live run is computing, by unit key. Best effort: a
/// status view does not fail because progress cannot be read.
fn live_units(p: &Pipeline, store: &Store) -> BTreeMap<String, RunningUnit> {
    progress::running(&store.root)
        .unwrap_or_default()
        .into_iter()
        .filter(|r| r.pipeline == p.key)
        .map(|r| (r.unit.clone(), r))
        .collect()
}

/// A unit's state and detail once its progress record is known: `running` wins, except that
/// a Slurm job still waiting for its first progress line stays `submitted` (with its job).
fn with_progress(
    state: &'static str,
    detail: String,
    record: Option<&RunningUnit>,
) -> (&'static str, String) {
    match record {
        Some(r) if state != "submitted" || r.has_progress() => ("running", r.describe()),
        _ => (state, detail),
    }
}

/// The status table of every unit, plus a count line.
pub fn status(p: &Pipeline) -> Result<String> {
    let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
    let rows: Vec<Vec<String>> = unit_states(p)?
        .into_iter()
        .map(|u| {
            *counts.entry(u.state).or_default() += 1;
            vec![u.key, u.state.to_owned(), u.detail]
        })
        .collect();
    let mut out = table(&["UNIT", "STATE", "REASON"], &rows);
    let summary: Vec<String> = counts.iter().map(|(k, v)| format!("{v} {k}")).collect();
    let _ = writeln!(out, "{}", summary.join(", "));
    Ok(out)
}

/// Every unit's state, in pipeline order: its identity recomputed from the current file, code
/// and known upstream outputs, against the lock record.
pub fn unit_states(p: &Pipeline) -> Result<Vec<UnitState>> {
    let store = Store::open_read(&p.workspace);
    let rec = store.read_lock_record()?;
    let empty = BTreeMap::new();
    let recorded = rec.pipelines.get(&p.key).unwrap_or(&empty);
    let live = live_units(p, &store);
    // Unit key -> output hash, for units whose current output is known.
    let mut known: BTreeMap<String, String> = BTreeMap::new();
    let mut rows = Vec::new();
    for (si, stage) in p.stages.iter().enumerate() {
        let code = code_of(p, stage, &store.cache);
        for u in units_of(p, si) {
            let old = recorded.get(&u.key);
            let (state, detail) = match &code {
                Err(e) => ("stale", format!("cannot resolve code: {e}")),
                Ok(code) => {
                    let mut inputs = BTreeMap::new();
                    let mut missing_up = None;
                    for (name, ups) in &stage.inputs {
                        let ups: Vec<_> = ups
                            .iter()
                            .flat_map(|up| units_of(p, p.index(up).expect("validated")))
                            .collect();
                        let hashes: Vec<Option<&String>> =
                            ups.iter().map(|x| known.get(&x.key)).collect();
                        if let Some(pos) = hashes.iter().position(Option::is_none) {
                            missing_up.get_or_insert(ups[pos].key.clone());
                        }
                        inputs.insert(
                            name.clone(),
                            hashes.into_iter().flatten().cloned().collect::<Vec<_>>(),
                        );
                    }
                    match (missing_up, old) {
                        (Some(up), Some(_)) => {
                            ("stale", format!("upstream `{up}` is not up to date"))
                        }
                        (Some(_), None) => ("never run", String::new()),
                        (None, old) => {
                            let entry = entry_for(p, &u, code, inputs);
                            let cached = store.verify(&entry.identity);
                            let in_cache = if let Cached::Valid(m) = &cached {
                                known.insert(u.key.clone(), m.output_hash.clone());
                                true
                            } else {
                                false
                            };
                            let note = if in_cache {
                                " (in the run-cache: restores without running)"
                            } else {
                                ""
                            };
                            // Queued or running on Slurm (`pipeline run --executor slurm`).
                            let job = (!in_cache)
                                .then(|| slurm::describe(&store.root, &entry.identity))
                                .flatten();
                            match old {
                                _ if job.is_some() => ("submitted", job.unwrap_or_default()),
                                Some(o) if o.identity == entry.identity => match cached {
                                    Cached::Valid(_) => ("fresh", String::new()),
                                    Cached::Missing => {
                                        ("stale", "cached output is missing".to_owned())
                                    }
                                    Cached::Corrupt(why) => {
                                        ("stale", format!("cached output is corrupted: {why}"))
                                    }
                                },
                                Some(o) => ("stale", format!("{}{note}", reasons(o, &entry))),
                                None => ("never run", note.trim().to_owned()),
                            }
                        }
                    }
                }
            };
            let progress = live.get(&u.key).cloned();
            let (state, detail) = with_progress(state, detail, progress.as_ref());
            rows.push(UnitState {
                key: u.key,
                stage: si,
                expansion: u.expansion,
                state,
                detail,
                progress,
            });
        }
    }
    if store.root.is_dir() {
        // Best effort: a read-only view must not fail because the cache cannot be written.
        let _ = store.cache.save();
    }
    Ok(rows)
}

/// Paths of the current output files of `target` (a stage or one expansion), one per line.
pub fn show(p: &Pipeline, target: &str) -> Result<String> {
    let stage_name = target.split('[').next().unwrap_or(target);
    let idx = p.index(stage_name).ok_or_else(|| {
        let known: Vec<&str> = p.stages.iter().map(|s| s.name.as_str()).collect();
        Error::Usage(format!(
            "{}: unknown stage `{target}` (stages: {})",
            p.file,
            known.join(", ")
        ))
    })?;
    let store = Store::open_read(&p.workspace);
    let rec = store.read_lock_record()?;
    let mut out = String::new();
    let units: Vec<_> = units_of(p, idx)
        .into_iter()
        .filter(|u| !target.contains('[') || p.stages[idx].expansions[u.expansion].name == target)
        .collect();
    if units.is_empty() {
        return Err(Error::Usage(format!(
            "{}: stage `{stage_name}` has no expansion `{target}`",
            p.file
        )));
    }
    let no_outputs = |unit: &str| Error::NoOutputs {
        unit: unit.to_owned(),
        stage: if target.contains('[') {
            format!("'{target}'")
        } else {
            target.to_owned()
        },
        workspace: p.workspace.clone(),
        file: p.key.clone(),
    };
    for u in units {
        let entry = rec
            .pipelines
            .get(&p.key)
            .and_then(|m| m.get(&u.key))
            .ok_or_else(|| no_outputs(&u.key))?;
        match store.verify(&entry.identity) {
            Cached::Valid(m) => {
                for f in &m.files {
                    let _ = writeln!(
                        out,
                        "{}",
                        store.out_dir(&entry.identity).join(&f.path).display()
                    );
                }
            }
            Cached::Missing => return Err(no_outputs(&u.key)),
            Cached::Corrupt(why) => {
                return Err(Error::Store {
                    path: store.object_dir(&entry.identity),
                    message: format!(
                        "output of `{}` is corrupted ({why}); `pipeline run {}` recomputes it",
                        u.key, stage_name
                    ),
                })
            }
        }
    }
    Ok(out)
}

/// The stage graph as text (one line per stage with its inputs) or Graphviz dot.
pub fn dag(p: &Pipeline, dot: bool) -> String {
    let mut out = String::new();
    if dot {
        out.push_str("digraph pipeline {\n  rankdir=LR;\n  node [shape=box];\n");
        for s in &p.stages {
            let mut label = s.name.clone();
            if s.shards > 1 {
                label.push_str(&format!("\\n{} shards", s.shards));
            }
            if s.expansions.len() > 1 {
                label.push_str(&format!("\\nmatrix x{}", s.expansions.len()));
            }
            let _ = writeln!(out, "  \"{}\" [label=\"{label}\"];", s.name);
        }
        for s in &p.stages {
            for (name, ups) in &s.inputs {
                for up in ups {
                    let _ = writeln!(out, "  \"{up}\" -> \"{}\" [label=\"{name}\"];", s.name);
                }
            }
        }
        out.push_str("}\n");
        return out;
    }
    for s in &p.stages {
        let mut head = s.name.clone();
        if s.shards > 1 {
            head.push_str(&format!(" ({} shards)", s.shards));
        }
        if s.expansions.len() > 1 {
            let names: Vec<&str> = s.expansions.iter().map(|e| e.name.as_str()).collect();
            head.push_str(&format!(" (matrix: {})", names.join(" ")));
        }
        if s.inputs.is_empty() {
            let _ = writeln!(out, "{head}");
        } else {
            let ins: Vec<String> = s
                .inputs
                .iter()
                .map(|(n, u)| format!("{n}: {}", u.join(" + ")))
                .collect();
            let _ = writeln!(out, "{head} <- {}", ins.join(", "));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(done: u64, total: u64, message: &str) -> RunningUnit {
        RunningUnit {
            unit: "train[algorithm=5]".into(),
            stage: "train".into(),
            pipeline: "pipeline.yaml".into(),
            pid: 1,
            host: "h".into(),
            started: 0,
            updated: 0,
            done,
            total,
            message: message.into(),
        }
    }

    #[test]
    fn a_live_record_makes_a_unit_running() {
        let r = record(42, 100, "2.0 s/epoch");
        for state in ["fresh", "stale", "never run", "submitted"] {
            assert_eq!(
                with_progress(state, "why".into(), Some(&r)),
                ("running", "42/100 (2.0 s/epoch)".to_owned())
            );
        }
        assert_eq!(
            with_progress("stale", "why".into(), None),
            ("stale", "why".to_owned())
        );
        // A Slurm job that has not reported anything yet is still just submitted.
        let queued = record(0, 0, "started");
        assert_eq!(
            with_progress("submitted", "pending on Slurm: job 7".into(), Some(&queued)),
            ("submitted", "pending on Slurm: job 7".to_owned())
        );
        assert_eq!(
            with_progress("never run", String::new(), Some(&queued)),
            ("running", "started".to_owned())
        );
    }
}
