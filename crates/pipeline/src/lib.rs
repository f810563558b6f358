//! `pipeline`: the content-hashed orchestrator of pino-mbd.
//!
//! A pipeline file (YAML, see [`spec`]) declares stages: an executable, parameters, inputs
//! (upstream stages), optional shards and matrix. `pipeline run` executes every stale unit
//! (one process per matrix expansion and shard) in dependency order and stores its output
//! content-addressed under `artifacts/` ([`store`]). A unit's identity is
//!
//! ```text
//! identity = blake3(protocol, unit, blake3(executable), args, params (canonical JSON),
//!                   blake3 content hashes of the upstream outputs, shard index/count)
//! ```
//!
//! so a unit is fresh exactly when an object with its identity exists and still matches its
//! manifest. Going back to earlier parameters finds the earlier object (run-cache). File
//! hashes are cached by (device, inode, size, mtime, ctime) ([`hash`]), so checking gigabytes
//! of outputs costs one `stat` per file. Stages talk to the orchestrator through the stage
//! protocol ([`exec`]; the stage side is the `stage-kit` crate). Outputs enter the store only
//! complete (tmp directory, hash, manifest, rename); one run at a time holds a kernel `flock`
//! ([`runlock`]), which dies with its holder; [`gc`] removes, under the same lock, the
//! objects that no lock-record entry needs. The progress of running units is kept in files that
//! other processes read ([`progress`]; `pipeline status` shows it). Exit status: 0 success, 1 a stage failed,
//! 2 bad input (nothing run).
#![warn(missing_docs)]

pub mod check;
pub mod cli;
pub mod constants;
mod error;
pub mod exec;
pub mod executor;
pub mod gc;
pub mod hash;
pub mod locate;
pub mod plan;
pub mod progress;
pub mod run;
pub mod runlock;
pub mod spec;
pub mod status;
pub mod store;
pub mod ui;

pub use error::{Error, Result};
