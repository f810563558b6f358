//! Where stage processes run: this machine ([`local`]) or a Slurm cluster ([`slurm`]).
//!
//! The scheduler in [`crate::run`] decides *what* runs (identities, the run-cache, dependency
//! order); an executor only decides *where*. For each unit it provides a working directory
//! (holding `context.json` and an empty `out/`), runs the stage there under the unchanged
//! stage protocol, and reports an [`crate::exec::Outcome`]. Verification and commit (hash, manifest,
//! atomic rename into `objects/`) stay in `run`, so both executors share one crash-safety
//! argument: nothing enters the store unless the stage exited 0 and its files were hashed.
//!
//! Units of one stage expansion that become ready together form a *batch*: the scheduler
//! hands each of them a [`Ticket`]. The Slurm executor submits the members of a batch as one
//! `sbatch --array` job; a ticket dropped unused (the unit was cached) just leaves the batch.
//! The local executor ignores tickets.

pub mod local;
pub mod resources;
pub mod slurm;

use crate::exec::{Outcome, ProgressLine};
use crate::store::Store;
use crate::Result;
pub use resources::Resources;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The `executor:` key of the pipeline file and `run --executor`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum ExecutorKind {
    /// Stage processes on this machine (`-j` at once).
    #[default]
    Local,
    /// One Slurm job per unit; shards of a stage as one array job.
    Slurm,
}

/// What one unit runs: the stage command and where its job may go.
#[derive(Debug)]
pub struct Job<'a> {
    /// The unit's key (`simulate#1`), for messages.
    pub unit: &'a str,
    /// The expansion's name (`train[algorithm=3]`), the Slurm job name.
    pub name: &'a str,
    /// The resolved executable.
    pub exe: &'a Path,
    /// Its arguments.
    pub args: &'a [String],
    /// The workspace (the stage's working directory).
    pub workspace: &'a Path,
    /// The stage's `resources:`.
    pub resources: &'a Resources,
    /// Shard index (the array task id on Slurm).
    pub shard: usize,
    /// Whether the stage is sharded (its batch is an array job).
    pub sharded: bool,
}

/// A unit's working directory, chosen by the executor.
#[derive(Debug)]
pub struct Work {
    /// Holds `context.json`, `out/` and the log; committed by renaming it into `objects/`.
    pub dir: PathBuf,
    /// A job found from an earlier, killed run that is still running or has finished: the
    /// directory already holds its context and the executor waits for that job.
    pub attached: Option<String>,
}

/// A unit's place in its batch (see the module doc). Dropping it unused leaves the batch.
pub struct Ticket(Option<Arc<slurm::Batch>>);

impl Drop for Ticket {
    fn drop(&mut self) {
        if let Some(b) = self.0.take() {
            b.leave();
        }
    }
}

/// The executor of one `pipeline run`.
pub enum Executor {
    /// This machine.
    Local,
    /// A Slurm cluster.
    Slurm(slurm::Slurm),
}

impl Executor {
    /// Creates the executor; for Slurm, checks that the client commands exist and the
    /// controller answers (bad input, exit 2, when not: nothing is run).
    pub fn new(kind: ExecutorKind, store: &Store, workspace: &Path) -> Result<Self> {
        Ok(match kind {
            ExecutorKind::Local => Executor::Local,
            ExecutorKind::Slurm => Executor::Slurm(slurm::Slurm::connect(&store.root, workspace)?),
        })
    }

    /// Units in flight at once: `-j` locally; on Slurm every ready unit is submitted and the
    /// cluster's scheduler decides what runs.
    pub fn parallelism(&self, jobs: usize) -> usize {
        match self {
            Executor::Local => jobs.max(1),
            Executor::Slurm(_) => usize::MAX,
        }
    }

    /// Called once the run lock is held: on Slurm, starts cancelling jobs on SIGINT/SIGTERM.
    pub fn start(&self) {
        if let Executor::Slurm(s) = self {
            s.install_cancel_on_signal();
        }
    }

    /// One ticket per dispatched unit; `groups[i]` is unit i's (stage, expansion).
    pub fn tickets(&self, groups: &[(usize, usize)]) -> Vec<Ticket> {
        match self {
            Executor::Local => groups.iter().map(|_| Ticket(None)).collect(),
            Executor::Slurm(s) => s.tickets(groups),
        }
    }

    /// The working directory for computing `identity` (or the one of a job to re-attach to).
    pub fn work_dir(&self, store: &Store, identity: &str, unit: &str) -> Result<Work> {
        match self {
            Executor::Local => Ok(Work {
                dir: store.tmp_dir(identity)?,
                attached: None,
            }),
            Executor::Slurm(s) => s.work_dir(identity, unit),
        }
    }

    /// Runs the unit (or waits for its attached job) and reports how it ended. The log is
    /// `work.dir/log.txt`; `out/` is left for the caller to verify and commit.
    pub fn execute(
        &self,
        work: &Work,
        ticket: Ticket,
        job: &Job,
        on_progress: &(dyn Fn(&ProgressLine) + Sync),
    ) -> Result<Outcome> {
        match self {
            Executor::Local => {
                drop(ticket);
                local::execute(work, job, on_progress)
            }
            Executor::Slurm(s) => s.execute(work, ticket, job, on_progress),
        }
    }
}
