//! End-to-end tests of the `pipeline` orchestrator: the real binary on fixture pipelines
//! (tests/pipeline/fixtures) made of the `test-stage` binary (tests/src/bin/test-stage.rs).
//!
//! Which units really ran is read from the stages' own log (env `TEST_STAGE_LOG`), not only
//! from the orchestrator's output, so a cache that lies about running cannot pass.

mod harness;

mod bad_input;
mod cache;
mod concurrency;
mod failure;
mod progress;
mod shards_and_matrix;
mod slurm;
mod store;
mod views;
