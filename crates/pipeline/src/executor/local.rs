//! The local executor: the stage as a child process of `pipeline` (see [`crate::exec`]),
//! in a `tmp/` directory that the next run deletes if this one is killed.

use super::{Job, Work};
use crate::exec::{run_stage, Outcome, ProgressLine};
use crate::Result;

/// Runs `job` in `work.dir` and waits for it.
pub fn execute(
    work: &Work,
    job: &Job,
    on_progress: &(dyn Fn(&ProgressLine) + Sync),
) -> Result<Outcome> {
    run_stage(job.exe, job.args, job.workspace, &work.dir, on_progress)
}
