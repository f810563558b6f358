//! Checks before a run: a stage declared with `check: true` is started in check mode
//! (`"check": true` in its context: no inputs, a scratch output directory) once per matrix
//! expansion about to run, before the run lock is taken or anything runs. A stage validates
//! there what it can know without its inputs (its parameters, a file its command names: a
//! system description) and exits nonzero with the reason on stderr when the unit could not run;
//! any failure stops `pipeline run` with exit status 2 and the checker's message, and nothing
//! runs. Fresh units are not checked, so a run with nothing to do stays as fast as before.
//!
//! The orchestrator stays physics-free: what a check means is the stage's business.

use crate::plan::Unit;
use crate::spec::Pipeline;
use crate::status::unit_states;
use crate::{Error, Result};
use std::collections::BTreeSet;
use std::path::Path;
use std::process::{Command, Stdio};

/// Lines of the checker's stderr kept in the error.
const MESSAGE_LINES: usize = 40;

/// Runs the checks of the selected units' stages that declare one, one per expansion whose
/// units are not all fresh, in pipeline order.
pub fn run_checks(p: &Pipeline, units: &[Unit]) -> Result<()> {
    if !units.iter().any(|u| p.stages[u.stage].check) {
        return Ok(());
    }
    let states = unit_states(p)?;
    let stale: BTreeSet<&str> = states
        .iter()
        .filter(|s| s.state != "fresh")
        .map(|s| s.key.as_str())
        .collect();
    let mut done = BTreeSet::new();
    for u in units {
        let stage = &p.stages[u.stage];
        if !stage.check || !stale.contains(u.key.as_str()) || !done.insert((u.stage, u.expansion)) {
            continue;
        }
        check_one(p, u)?;
    }
    Ok(())
}

fn check_one(p: &Pipeline, u: &Unit) -> Result<()> {
    let stage = &p.stages[u.stage];
    let exe = p.resolve_executable(stage)?;
    let name = &stage.expansions[u.expansion].name;
    let dir = std::env::temp_dir().join(format!(
        "pino-check-{}-{}",
        std::process::id(),
        blake3::hash(name.as_bytes()).to_hex()
    ));
    let io = |e| Error::io(&dir, e);
    std::fs::create_dir_all(dir.join("out")).map_err(io)?;
    let context = stage_protocol::Context {
        protocol: stage_protocol::PROTOCOL_VERSION,
        stage: name.clone(),
        params: stage.expansions[u.expansion].params.clone(),
        inputs: Default::default(),
        output: dir.join("out"),
        scratch: None,
        shard: stage_protocol::Shard {
            index: 0,
            count: stage.shards,
        },
        check: true,
    };
    let context_path = dir.join(stage_protocol::CONTEXT_FILE);
    std::fs::write(&context_path, context.to_json()).map_err(io)?;
    let output = Command::new(&exe)
        .args(&stage.cmd[1..])
        .current_dir(&p.workspace)
        .env(stage_protocol::CONTEXT_ENV, &context_path)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| Error::io(&exe, e));
    let _ = std::fs::remove_dir_all(&dir);
    let output = output?;
    if output.status.success() {
        return Ok(());
    }
    Err(Error::Check {
        unit: name.clone(),
        message: message(&output.stderr, &exe),
    })
}

/// The checker's own words: its stderr without the `error:` prefix stage binaries print, or
/// its exit status when it said nothing.
fn message(stderr: &[u8], exe: &Path) -> String {
    let text = String::from_utf8_lossy(stderr);
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    if lines.is_empty() {
        return format!("{} refused in check mode without a message", exe.display());
    }
    let start = lines.len().saturating_sub(MESSAGE_LINES);
    lines[start..]
        .iter()
        .map(|l| l.strip_prefix("error: ").unwrap_or(l))
        .collect::<Vec<_>>()
        .join("\n")
}
