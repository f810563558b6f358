//! Units and identities.
//!
//! A **unit** is one process of a stage: one matrix expansion times one shard. Its key is the
//! expansion name plus `#SHARD` when the stage is sharded (`simulate#1`,
//! `train[algorithm=3]`). A unit's **identity** is blake3 over a canonical JSON document of
//! everything that can change its output:
//!
//! ```text
//! identity = blake3(json{ protocol, unit, exe_blake3, args, arg_files{arg: blake3},
//!                         params (sorted keys), inputs{name: [upstream output hashes]},
//!                         shard: [index, count] })
//! ```
//!
//! Inputs enter through the upstream outputs' *content* hashes, not their identities, so an
//! upstream rerun that reproduces the same bytes leaves everything downstream fresh.

use crate::hash::HashCache;
use crate::spec::{Pipeline, Stage};
use crate::store::{LockEntry, PROTOCOL_VERSION};
use crate::Result;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// One process of a stage.
#[derive(Debug, Clone)]
pub struct Unit {
    /// Index of the stage in [`Pipeline::stages`].
    pub stage: usize,
    /// Index of the matrix expansion.
    pub expansion: usize,
    /// Shard index.
    pub shard: usize,
    /// The unit's key (lock record, messages).
    pub key: String,
}

/// All units of stage `idx`, expansions outer, shards inner (the order inputs are listed in).
pub fn units_of(p: &Pipeline, idx: usize) -> Vec<Unit> {
    let s = &p.stages[idx];
    let mut v = Vec::new();
    for (e, ex) in s.expansions.iter().enumerate() {
        for shard in 0..s.shards {
            let key = if s.shards > 1 {
                format!("{}#{shard}", ex.name)
            } else {
                ex.name.clone()
            };
            v.push(Unit {
                stage: idx,
                expansion: e,
                shard,
                key,
            });
        }
    }
    v
}

/// A stage's resolved code: executable and script arguments with their hashes.
#[derive(Debug, Clone)]
pub struct Code {
    /// The executable's path.
    pub exe: PathBuf,
    /// Its blake3.
    pub exe_hash: String,
    /// Arguments naming files in the workspace -> their blake3.
    pub arg_files: BTreeMap<String, String>,
}

/// Resolves and hashes a stage's executable (bad input when missing).
pub fn code_of(p: &Pipeline, stage: &Stage, cache: &HashCache) -> Result<Code> {
    let exe = p.resolve_executable(stage)?;
    let exe_hash = cache.hash(&exe)?.blake3;
    let mut arg_files = BTreeMap::new();
    for f in p.file_args(stage) {
        let rel = f
            .strip_prefix(&p.workspace)
            .unwrap_or(&f)
            .to_string_lossy()
            .into_owned();
        arg_files.insert(rel, cache.hash(&f)?.blake3);
    }
    Ok(Code {
        exe,
        exe_hash,
        arg_files,
    })
}

#[derive(Serialize)]
struct IdentityDoc<'a> {
    protocol: u32,
    unit: &'a str,
    exe_blake3: &'a str,
    args: &'a [String],
    arg_files: &'a BTreeMap<String, String>,
    params: &'a serde_json::Value,
    inputs: &'a BTreeMap<String, Vec<String>>,
    shard: [usize; 2],
}

/// The lock entry (with its identity) that unit `u` would have given upstream output hashes
/// `inputs` (input name -> hashes in upstream unit order). `output_hash` is left empty.
pub fn entry_for(
    p: &Pipeline,
    u: &Unit,
    code: &Code,
    inputs: BTreeMap<String, Vec<String>>,
) -> LockEntry {
    let stage = &p.stages[u.stage];
    let params = stage.expansions[u.expansion].params.clone();
    let args = stage.cmd[1..].to_vec();
    let shard = [u.shard, stage.shards];
    let doc = IdentityDoc {
        protocol: PROTOCOL_VERSION,
        unit: &u.key,
        exe_blake3: &code.exe_hash,
        args: &args,
        arg_files: &code.arg_files,
        params: &params,
        inputs: &inputs,
        shard,
    };
    let identity = blake3::hash(&serde_json::to_vec(&doc).expect("serialisable"))
        .to_hex()
        .to_string();
    LockEntry {
        identity,
        output_hash: String::new(),
        exe: code.exe.to_string_lossy().into_owned(),
        exe_hash: code.exe_hash.clone(),
        args,
        arg_files: code.arg_files.clone(),
        params,
        inputs,
        shard,
        overrides: stage.overrides.clone(),
    }
}
